"""The loading experiments on a plant with tendon friction (docs/friction.md, "Loading experiments with friction";
``validation.paper.control.loading(friction=…)``, ``bellows paper loading --plant-friction … --friction-aware``).

Checked here on short load profiles: μ = 0 is the frictionless plant (its uncontrolled drift is the frictionless
study's), the friction changes the plant (μ = 0.3 drifts differently), both controllers stay below the
uncontrolled drift, the runs repeat exactly (fixed compute times), the inputs are refused before anything runs,
the command's options; and the documented table against the program (``-m slow``: the whole default run).
"""

from __future__ import annotations

import json
import pathlib
import re

import pytest

from ancf.errors import InputError
from validation.paper import control as pc

DOC = pathlib.Path(__file__).resolve().parents[2] / "docs" / "friction.md"
QUICK = {"ramp_up": 2.0, "ramp_down": 1.0, "cycles": 1, "frequency": 0.5, "sample_dt": 0.1}


@pytest.fixture(scope="module")
def quick():
    """μ = 0 and 0.3 with the friction-aware LACC, both controllers at 10 ms per correction."""
    return pc.loading(friction=(0.0, 0.3), friction_aware=True, friction_compute=(0.01, 0.01), **QUICK)


def test_mu0_plant_is_the_frictionless_plant(quick):
    """The μ = 0 runs' uncontrolled drift is the frictionless study's (the same plant, profile and lengths)."""
    free = pc.loading(compare=None, loop_periods=(), **QUICK)
    for case in ("continuous", "cyclic"):
        assert quick["friction"]["0"][case]["uncontrolled_max_drift"] == pytest.approx(
            free[case]["uncontrolled_max_drift"], rel=1e-9)
        assert "aware" not in quick["friction"]["0"][case]           # μ = 0: the friction-aware LACC is LACC


def test_friction_in_the_plant_and_the_friction_aware_lacc(quick):
    for case in ("continuous", "cyclic"):
        c0, c3 = quick["friction"]["0"][case], quick["friction"]["0.3"][case]
        assert c3["uncontrolled_max_drift"] != pytest.approx(c0["uncontrolled_max_drift"], rel=1e-3)
        for c in (c0, c3):
            assert c["lacc"]["max_error"] < c["uncontrolled_max_drift"] and c["lacc"]["corrections"] > 0
        a = c3["aware"]
        assert a["corrections"] > 0 and a["max_error"] < c3["uncontrolled_max_drift"]
        duration = {"continuous": QUICK["ramp_up"] + QUICK["ramp_down"], "cyclic": QUICK["cycles"] / QUICK["frequency"]}
        assert len(a["t"]) == len(a["error_norm"]) and a["t"][-1] >= duration[case] - QUICK["sample_dt"]
    s = quick["settings"]
    assert s["friction"] == [0.0, 0.3] and s["compute_s"] == {"lacc": 0.01, "friction_aware": 0.01}
    assert "plant μ" in quick["table"] and "10 ms" in quick["table"]


def test_runs_repeat_exactly_and_write_json_and_png(tmp_path, quick):
    """Fixed compute times: the same call gives the same numbers (the frictionless study's wall-clock timing
    does not); the results go to loading.json and loading.png."""
    again = pc.loading(friction=(0.0, 0.3), friction_aware=True, friction_compute=(0.01, 0.01), out=tmp_path,
                       **QUICK)
    assert again["table"] == quick["table"]
    data = json.loads((tmp_path / "loading.json").read_text())
    assert data["friction"]["0.3"]["cyclic"]["aware"]["max_error_mm"] == pytest.approx(
        quick["friction"]["0.3"]["cyclic"]["aware"]["max_error_mm"])
    assert (tmp_path / "loading.png").stat().st_size > 0


@pytest.mark.parametrize("kw", [{"friction": ()}, {"friction": (1.5,)}, {"friction": (-0.1,)}, {"friction": "x"},
                                {"friction_aware": True}, {"friction_compute": (0.1, 0.1)},
                                {"friction": (0.1,), "friction_compute": (0.1,)},
                                {"friction": (0.1,), "friction_compute": (-1.0, 0.1)},
                                {"friction": (0.1,), "friction_compute": (0.01, float("nan"))},
                                {"friction": (0.1,), "friction_compute": (0.01, 11.0)}])
def test_inputs_are_refused_before_anything_runs(monkeypatch, kw):
    def no_run(*a, **k):
        raise AssertionError("a run started")
    monkeypatch.setattr(pc, "configurations", no_run)
    monkeypatch.setattr(pc, "_loading_run", no_run)
    with pytest.raises(InputError):
        pc.loading(tensions=(2.2, 1.6, 1.6), **kw)


def test_cli_options_need_their_partners():
    from typer.testing import CliRunner
    from validation.commands.main import app
    r = CliRunner().invoke(app, ["paper", "loading", "--friction-aware"])
    assert r.exit_code == 2 and "--plant-friction" in r.output
    r = CliRunner().invoke(app, ["paper", "loading", "--plant-friction", "0.1", "--aware-compute-ms", "100"])
    assert r.exit_code == 2 and "--friction-aware" in r.output


def test_cli_passes_the_options(monkeypatch, tmp_path):
    """``--plant-friction 0,0.1 --friction-aware --aware-compute-ms 250`` reach the study as friction, friction_aware
    and friction_compute = (LACC's default, 0.25 s)."""
    from typer.testing import CliRunner
    from validation.commands.main import app
    seen = {}

    def fake(**kw):
        seen.update(kw)
        return {"table": "t", "friction": {}}
    monkeypatch.setattr(pc, "loading", fake)
    r = CliRunner().invoke(app, ["paper", "loading", "--plant-friction", "0,0.1", "--friction-aware",
                                 "--aware-compute-ms", "250", "--out", str(tmp_path)])
    assert r.exit_code == 0, r.output
    assert seen["friction"] == [0.0, 0.1] and seen["friction_aware"] is True
    assert seen["friction_compute"] == (None, 0.25)


def _doc_rows() -> list:
    text = DOC.read_text()
    sec = text[text.index("## Loading experiments with friction"):]
    sec = sec[:sec.index("\n## ", 1)] if "\n## " in sec[1:] else sec
    rows = []
    for line in sec.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) >= 6 and re.fullmatch(r"[0-9.]+", cells[0]):
            rows.append(cells)
    return rows


def _program_rows(table: str) -> list:
    return [re.split(r"\s{2,}", line.strip()) for line in table.splitlines()
            if re.match(r"^[0-9.]+\s", line)]


def test_the_documented_table_has_every_row():
    rows = _doc_rows()
    assert [(r[0], r[1]) for r in rows] == [(mu, c) for mu in ("0", "0.1", "0.3") for c in ("continuous", "cyclic")]


@pytest.mark.slow
def test_documented_table_is_the_programs(tmp_path):
    """The documented command (≈ 10 min on a shared 2-core machine) prints the documented table, digit for digit."""
    from typer.testing import CliRunner
    from validation.commands.main import app
    r = CliRunner().invoke(app, ["paper", "loading", "--plant-friction", "0,0.1,0.3", "--friction-aware",
                                 "--out", str(tmp_path)])
    assert r.exit_code == 0, r.output
    table = json.loads((tmp_path / "loading.json").read_text())["table"]
    assert _doc_rows() == _program_rows(table)
