"""``bellows paper compare``: every headline number for several presets beside the paper's."""

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from ancf import StiffnessLaw, presets
from validation.commands.paper import app
from validation.paper import comparison
from validation.paper.convergence import element_convergence
from validation.paper.loads import hold_payload, locked_drift

runner = CliRunner()


def test_verdicts_follow_the_stated_criteria():
    v = comparison.verdict
    assert v("workspace_increase_percent", 108.6) and v("workspace_increase_percent", 82.0)
    assert not v("workspace_increase_percent", 512.0) and not v("workspace_increase_percent", 70.0)
    assert v("stiffness_ratio", 2.1) and not v("stiffness_ratio", 3.0)
    assert v("locked_drift_110g_mm", 25.0) and not v("locked_drift_110g_mm", 4.5)
    assert v("table1_upward_lacc_mm", 0.02) and not v("table1_upward_lacc_mm", 0.4)
    assert v("EA1_N", 123.0) is None and v("workspace_increase_percent", float("nan")) is None
    assert v("workspace_increase_percent", "not run") is None


def test_compare_two_presets_small(tmp_path):
    """Tiny run (60 samples, no controller studies): the ordering of the readings must show — the
    length-scaled law is ~6× softer, so it drifts further under 110 g, converges more slowly in n, and its
    workspace gain is smaller than the unscaled law's."""
    res = runner.invoke(app, ["compare", "--presets", "paper_unscaled,paper_scaled", "--samples", "60",
                              "--seeds", "0", "--workers", "1", "--no-control", "--no-progress",
                              "--out", str(tmp_path)])
    assert res.exit_code == 0, res.output
    assert "paper_unscaled" in res.output and "reproduced" in res.output
    data = json.loads((tmp_path / "compare.json").read_text())
    a, b = (p["numbers"] for p in data["presets"])
    assert a["EA1_N"] == pytest.approx(767.2) and b["EA1_N"] == pytest.approx(0.16 * 767.2)
    assert b["locked_drift_110g_mm"] > 4 * a["locked_drift_110g_mm"]
    assert b["convergence_n1_mm"] > 5 * a["convergence_n1_mm"]
    assert b["workspace_increase_percent"] < a["workspace_increase_percent"]
    assert b["stretch_at_max_pressure"] > a["stretch_at_max_pressure"] > 1
    assert data["paper"]["workspace_increase_percent"] == 108.6
    for p in data["presets"]:
        assert p["judged"] >= 4 and 0 <= p["reproduced"] <= p["judged"]
    assert (tmp_path / "compare.png").stat().st_size > 10_000
    assert (tmp_path / "workspace_paper_scaled_seed0" / "workspace_samples.csv").exists()
    again = runner.invoke(app, ["compare", "--presets", "paper_unscaled", "--seeds", "0", "--out", str(tmp_path),
                                "--no-progress"])
    assert again.exit_code == 2 and "--force" in again.output            # nothing overwritten unasked
    bad = runner.invoke(app, ["compare", "--presets", "paper_nonesuch", "--out", str(tmp_path / "x")])
    assert bad.exit_code == 2 and "unknown preset" in bad.output


def test_failed_study_is_reported_not_fatal_but_a_bug_propagates(monkeypatch):
    from ancf.errors import ConfigError
    from validation import paper

    def typed(**kw):
        raise ConfigError("no rig")

    def bug(**kw):
        raise RuntimeError("no rig")
    monkeypatch.setitem(paper.CONTROL_STUDIES, "table1", typed)
    row, notes = {}, {}
    comparison._control_numbers("table1", None, row, notes)
    assert notes["table1"].startswith("not run: ConfigError: no rig") and row == {}
    monkeypatch.setitem(paper.CONTROL_STUDIES, "table1", bug)
    with pytest.raises(RuntimeError, match="no rig"):
        comparison._control_numbers("table1", None, {}, {})


def test_convergence_rate_on_a_uniform_beam():
    """Constant law, no gravity: the tip error falls monotonically with n at an algebraic rate ≥ 1."""
    prm = presets.paper_unscaled().replace(stiffness=StiffnessLaw.constant(EA=767.2, EI=0.0839), line_mass=0.0,
                                           tip_mass=0.0, tool_offset=0.0)
    r = element_convergence(prm, n_values=(1, 2, 4, 8), n_ref=16)
    e = np.asarray(r["tip_error_m"])
    assert np.all(np.diff(e) < 0) and r["rate"] > 1.0


def test_holding_is_a_statics_limit():
    """A tendon at distance d carries at most T_max d of moment: halving d (tendons at 13.75 mm) must need
    more tension to hold the same payload."""
    cfg = {"downward": ((0.8, 3.0, 3.0), 60e3)}
    a = hold_payload("paper_unscaled", configurations=cfg)["configurations"]["downward"]
    b = hold_payload("paper_diameter", configurations=cfg)["configurations"]["downward"]
    assert a["held"] and a["max_tension_needed_N"] <= 5.0
    assert b["max_tension_needed_N"] > a["max_tension_needed_N"] + 1.0 and not b["held"]


def test_locked_drift_is_linear_in_a_small_payload():
    d1 = locked_drift("paper_unscaled", mass=0.02)["drift_m"]
    d2 = locked_drift("paper_unscaled", mass=0.01)["drift_m"]
    assert d1 / d2 == pytest.approx(2.0, rel=0.05)


def test_convergence_and_loads_commands(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)                     # the default --out (bellows_out/paper) in a folder of its own
    res = runner.invoke(app, ["convergence", "--n-values", "1,6", "--n-ref", "8", "--preset", "paper_unscaled",
                              "--json"])
    assert res.exit_code == 0, res.output
    data = json.loads(res.stdout)
    assert data["n"] == [1, 6] and data["tip_error_m"][0] > 3 * data["tip_error_m"][1] > 0
    res = runner.invoke(app, ["loads", "--preset", "paper_unscaled"])
    assert res.exit_code == 0, res.output
    assert "locked drift under 110 g: 4.5" in res.output and "IK time" in res.output
