"""Tendon friction in the validation report: the design key, the option, the check's numbers, the section.

The report's plumbing is tested on an actuator identified from synthetic measured states
(tests/test_identification/test_fit.py) with the FEM's tension cycles replaced by an independent stand-in (the rod
of another actuator, or a rod cycle moved by a known offset); the numbers of the section are checked against
``Model.tension_cycle`` and closed forms computed here.  The real quick report with friction on the ``paper``
design runs with ``pytest -m slow``.
"""

from __future__ import annotations

import json
import math
import pathlib
import sys

import numpy as np
import pytest

import validation
from ancf import ActuatorParams, Model
from ancf.errors import ConfigError, InputError
from validation.checks import hysteresis as hy
from validation.checks.compare import ValidationResult
from validation.reference import designs
from validation.reference.fem_sweep import FemSpec
from validation.report import pipeline

sys.path.insert(0, str(pathlib.Path(__file__).parent / "test_identification"))
from test_fit import BASE  # noqa: E402

IDENTIFIED = pathlib.Path(__file__).resolve().parents[1] / "docs" / "data" / "paper_identified.toml"
OFFSET = np.array([0.0, 0.0, 1e-3])          # a static offset of the stand-in FEM's tips [m]


def _design_file(tmp_path, mu=None, text=None) -> pathlib.Path:
    geo, mat = designs.load_design("paper")
    body = designs.design_to_toml(geo, mat, name="paper with friction", limits=designs.design_limits("paper"))
    if text is not None:
        body = body.replace('mounting = "horizontal"\n', f'mounting = "horizontal"\n{text}\n')
    elif mu is not None:
        body = designs.design_to_toml(geo, mat, name="paper with friction", limits=designs.design_limits("paper"),
                                      tendon_friction=mu)
    p = tmp_path / "design.toml"
    p.write_text(body)
    return p


def rod_stand_in(params: ActuatorParams, offset=OFFSET):
    """An FEM stand-in: the rod ``params`` with the FEM's μ and gravity, its tips moved by ``offset`` [m]."""
    def cycles(spec, plan, mu):
        m = Model(params.replace(tendon_friction=mu, gravity=spec.gravity))
        out = []
        for p in plan["pressures_Pa"]:
            c = m.tension_cycle(plan["peak_N"], p, steps=plan["steps"])
            out.append({"pressure_Pa": p, "scale": c.scale, "tip": c.tip + offset, "loop_area": c.loop_area,
                        "error": "", "seconds": 0.0})
        return out
    return cycles


# ------------------------------------------------------------------------------------------------ the design
def test_a_design_states_its_tendon_friction_and_reads_back(tmp_path):
    assert designs.design_friction("paper") == 0.0
    assert designs.design_friction(_design_file(tmp_path)) == 0.0                 # default: frictionless
    p = _design_file(tmp_path, mu=0.25)
    assert designs.design_friction(p) == 0.25
    geo, mat = designs.load_design(p)                                               # the key is not a geometry key
    assert geo == designs.load_design("paper")[0]
    assert "tendon_friction" not in designs.design_to_toml(geo, mat)


@pytest.mark.parametrize("text", ["tendon_friction = -0.1", "tendon_friction = 1.5", "tendon_friction = nan",
                                  "tendon_friction = inf", 'tendon_friction = "0.2"', "tendon_friction = true",
                                  "tendon_friction_pct = 20"])
def test_a_design_with_a_bad_tendon_friction_is_refused(tmp_path, text):
    p = _design_file(tmp_path, text=text)
    with pytest.raises(ConfigError, match="tendon_friction"):
        designs.load_design(p)
    with pytest.raises(ConfigError, match="tendon_friction"):
        pipeline.run_report(tmp_path / "never", design=str(p), quick=True)
    assert not (tmp_path / "never").exists()


@pytest.mark.parametrize("mu", [-0.1, 1.01, math.nan, math.inf, True, "0.2"])
def test_run_report_refuses_a_bad_tendon_friction_before_any_work(tmp_path, mu):
    with pytest.raises(InputError, match="tendon_friction"):
        pipeline.run_report(tmp_path / "never", quick=True, tendon_friction=mu)
    assert not (tmp_path / "never").exists()


def test_tendon_friction_does_not_apply_to_measurements(tmp_path):
    with pytest.raises(InputError, match="tendon_friction"):
        pipeline.run_report(tmp_path / "never", measurements=IDENTIFIED, base="paper", tendon_friction=0.2)


def test_the_option_overrides_the_design(tmp_path):
    p = str(_design_file(tmp_path, mu=0.3))
    assert pipeline.design_friction_of(p) == 0.3
    assert pipeline.design_friction_of(p, 0.1) == 0.1
    assert pipeline.design_friction_of(p, 0.0) == 0.0           # 0 turns the design's friction off
    assert pipeline.design_friction_of("paper", 0.2) == 0.2


def test_the_cycles_of_the_full_and_the_quick_report():
    lim = designs.design_limits("paper")
    full, quick = hy.cycle_plan(lim, 3, quick=False), hy.cycle_plan(lim, 3, quick=True)
    assert full["peak_N"] == quick["peak_N"] == [3.0, 0.0, 0.0]                 # 0.6 × 5 N on tendon 1
    assert full["pressures_Pa"] == [0.0, 50e3, 100e3] and full["pressures_Pa"][full["fit_index"]] == 50e3
    assert quick["pressures_Pa"] == [50e3] and quick["in_sample"] and not full["in_sample"]


# ------------------------------------------------------------------------------------------------ the numbers
def test_compare_cycle_against_closed_forms():
    """Tips moved by a constant δ: every state's distance is δ/L; loops as given; the polygon's area by hand."""
    L, s = 0.16, 3
    scale = np.r_[np.linspace(0, 1, s + 1), np.linspace(1, 0, s + 1)[1:]]
    tip = np.column_stack([np.full(2 * s + 1, L), np.zeros(2 * s + 1), -0.02 * scale])
    delta = np.array([0.0, 3e-3, 4e-3])                              # |δ| = 5 mm = 3.125 % of L
    fem = {"pressure_Pa": 20e3, "scale": scale, "tip": tip, "loop_area": 2e-3, "error": ""}
    rod = {"pressure_Pa": 20e3, "scale": scale, "tip": tip + delta, "loop_area": 1.6e-3, "error": ""}
    r = hy.compare_cycle(rod, fem, L, 3.0)
    for k in ("tip_loading_mean_pct", "tip_loading_max_pct", "tip_unloading_mean_pct", "tip_unloading_max_pct"):
        assert r[k] == pytest.approx(3.125)
    assert r["loop_ratio"] == pytest.approx(0.8) and r["loop_error_pct"] == pytest.approx(20.0)
    assert r["passes"] is False
    assert r["tension_N"] == pytest.approx(3.0 * scale)
    assert r["u_fem_mm"] == pytest.approx(20.0 * scale)            # along the FEM's loading direction (−z)
    assert r["u_rod_mm"] == pytest.approx(20.0 * scale - 4.0)
    ok = hy.compare_cycle({**rod, "tip": tip + 1e-3 * delta, "loop_area": 1.9e-3}, fem, L, 3.0)
    assert ok["passes"] is True
    bad = hy.compare_cycle({**rod, "error": "ConvergenceError: x"}, fem, L, 3.0)
    assert bad["passes"] is None and "rod: ConvergenceError" in bad["error"]
    assert hy.verdict([{**ok, "role": "validation"}, {**r, "role": "fit"}]) == "passes"
    assert hy.verdict([{**ok, "role": "validation"}, {**r, "role": "validation"}]) == "fails"
    assert hy.verdict([{**bad, "role": "validation"}]) == "incomplete"


@pytest.fixture(scope="module")
def identified():
    return ActuatorParams.from_toml(IDENTIFIED)


def _spec():
    name, geo, mat, _ = pipeline.fem_design("paper")
    return FemSpec(geo, mat, "coarse")


def test_mu_is_identified_from_the_cycle_despite_a_static_offset(identified):
    """The stand-in is the rod itself with μ = 0.2, every tip 1 mm off: the fit recovers 0.2 (a fit to the
    absolute tips gives ≈ 0.15), and the validation cycles pass."""
    lim = designs.design_limits("paper")
    fr = hy.friction_check(identified, _spec(), lim, 0.2, quick=False, fem_cycles=rod_stand_in(identified))
    assert fr["mu_source"] == "identified" and fr["mu_used"] == pytest.approx(0.2, abs=1e-6)
    assert fr["fit"]["interval"][0] <= 0.2 <= fr["fit"]["interval"][1]
    assert [r["role"] for r in fr["rows"]] == ["validation", "fit", "validation"]
    assert fr["status"] == "passes"
    for r in fr["rows"]:
        assert r["tip_loading_mean_pct"] == pytest.approx(1e-3 / identified.length * 100, rel=1e-6)
        assert r["loop_ratio"] == pytest.approx(1.0, abs=1e-6)


def test_mu_from_the_branch_gap_is_not_taken_in_by_a_stiffness_mismatch(identified):
    """An FEM stand-in 4 % softer than the rod (its displacements from the start × 1.04, μ = 0.2): μ from the gap
    between the branches stays within 6 % of 0.2 (the gap scales by 1.04 too) and closer to it than a fit to the
    tool points themselves (fit_tension_cycle), which lets μ take up the stiffness."""
    from validation.identification.friction import fit_tension_cycle
    spec, lim = _spec(), designs.design_limits("paper")
    plan = hy.cycle_plan(lim, 3, quick=True)
    (fem,) = rod_stand_in(identified, offset=np.zeros(3))(spec, plan, 0.2)
    fem["tip"] = fem["tip"][0] + 1.04 * (fem["tip"] - fem["tip"][0])
    model = hy.rod_model(identified, spec.gravity)
    gap = hy.fit_mu(model, plan, fem, 0.1)["mu"]
    points = fit_tension_cycle(model, plan["peak_N"], 50e3, fem["tip"], plan["steps"], mu0=0.1).mu
    assert abs(gap - 0.2) < 0.06 * 0.2
    assert abs(gap - 0.2) < abs(points - 0.2)


def test_branch_gap_by_hand():
    tip = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [1.5, 0, 0], [0.2, 0, 0]], float)   # s = 2
    assert hy.branch_gap(tip) == pytest.approx(np.array([[0.2, 0, 0], [0.5, 0, 0]]))


def test_the_sections_numbers_are_those_of_tension_cycle(identified):
    """Against an FEM stand-in of another actuator (heavier, μ = 0.3): the rod's and the 'FEM''s loop areas and tip
    distances are those Model.tension_cycle gives, recomputed here."""
    lim = designs.design_limits("paper")
    other = identified.replace(line_mass=1.3 * identified.line_mass, tip_mass=identified.tip_mass + 0.01)
    fr = hy.friction_check(identified, _spec(), lim, 0.3, quick=False,
                           fem_cycles=rod_stand_in(other, offset=np.zeros(3)))
    mu = fr["mu_used"]
    assert fr["mu_source"] == "identified" and 0 < mu <= 1
    g = _spec().gravity
    for r, p in zip(fr["rows"], (0.0, 50e3, 100e3)):
        rod = Model(identified.replace(tendon_friction=mu, gravity=g)).tension_cycle([3.0, 0, 0], p, steps=6)
        fem = Model(other.replace(tendon_friction=0.3, gravity=g)).tension_cycle([3.0, 0, 0], p, steps=6)
        assert r["loop_rod_Nmm"] == pytest.approx(1e3 * rod.loop_area, rel=1e-9)
        assert r["loop_fem_Nmm"] == pytest.approx(1e3 * fem.loop_area, rel=1e-9)
        d = np.linalg.norm(rod.tip - fem.tip, axis=1) / identified.length * 100
        assert r["tip_loading_mean_pct"] == pytest.approx(d[:7].mean(), rel=1e-9)
        assert r["tip_unloading_max_pct"] == pytest.approx(d[6:].max(), rel=1e-9)
        assert r["passes"] == (abs(rod.loop_area / fem.loop_area - 1) <= 0.15 and d[:7].mean() <= 2.5
                               and d[6:].mean() <= 2.5)


def test_without_a_fit_cycle_the_rod_takes_the_designs_mu(identified):
    def failing_middle(spec, plan, mu):
        out = rod_stand_in(identified)(spec, plan, mu)
        out[plan["fit_index"]] = {**out[plan["fit_index"]], "tip": None, "error": "ConvergenceError: stand-in"}
        return out
    fr = hy.friction_check(identified, _spec(), designs.design_limits("paper"), 0.2, quick=False,
                           fem_cycles=failing_middle)
    assert fr["mu_source"] == "design" and fr["mu_used"] == 0.2 and fr["fit"] is None
    assert [r["role"] for r in fr["rows"]] == ["validation"] * 3
    assert fr["status"] == "incomplete"


# ------------------------------------------------------------------------------------------------ the report
@pytest.fixture(scope="module")
def measured_identification(tmp_path_factory):
    """An IdentificationResult (from synthetic measured states) for the report's plumbing."""
    from test_api_report import _states
    from hardware.static_states import write_static_states
    d = tmp_path_factory.mktemp("fric")
    states = write_static_states(d / "states.h5", _states())
    return validation.run_report(d / "rep", measurements=states, base=BASE, forms=("paper",)).identification


def _fake_fem(monkeypatch, ident, cycles):
    """run_report on a design with the identification, validation and FEM cycles replaced (plumbing only)."""
    import copy
    calls = []

    def from_fem(fem, names, **kw):
        res = copy.deepcopy(ident)
        return res, ValidationResult(rows=[], length=res.params.length, params=res.params), None

    def run_cycles(spec, plan, mu, **kw):
        calls.append((spec, plan, mu))
        return cycles(spec, plan, mu)
    monkeypatch.setattr(pipeline, "_from_fem", from_fem)
    monkeypatch.setattr(pipeline, "report_modes", lambda *a, **k: None)
    monkeypatch.setattr(hy, "run_fem_cycles", run_cycles)
    return calls


def test_a_design_with_friction_gets_the_section(monkeypatch, tmp_path, measured_identification):
    ident = measured_identification
    calls = _fake_fem(monkeypatch, ident, rod_stand_in(ident.params))
    lines = []
    run = pipeline.run_report(tmp_path / "rep", design=str(_design_file(tmp_path, mu=0.2)), quick=True,
                              log=lines.append)
    assert len(calls) == 1 and calls[0][2] == 0.2 and calls[0][1]["pressures_Pa"] == [50e3]
    fr = run.friction
    assert fr["mu_used"] == pytest.approx(0.2, abs=1e-6) and fr["in_sample"]
    assert ActuatorParams.from_toml(run.out / "actuator.toml").tendon_friction == pytest.approx(fr["mu_used"])
    data = json.loads((run.out / "validation.json").read_text())
    assert data["tendon_friction"]["rows"][0]["loop_ratio"] == pytest.approx(fr["rows"][0]["loop_ratio"])
    html = run.report.read_text()
    assert 'id="sec-friction"' in html and "Tendon friction hysteresis" in html     # section and headline
    assert "in-sample" in html and (run.out / "figures" / "friction.png").is_file()
    assert any("tension cycles" in x for x in lines)


def test_a_failing_friction_check_is_a_headline_failure(monkeypatch, tmp_path, measured_identification):
    ident = measured_identification
    _fake_fem(monkeypatch, ident, rod_stand_in(ident.params, offset=np.array([0.0, 0.0, 6e-3])))   # 3.75 % of L
    run = pipeline.run_report(tmp_path / "rep", design="paper", quick=True, tendon_friction=0.2)
    assert run.friction["status"] == "fails"
    html = run.report.read_text()
    fails = html.split('<ol class="fails">')[1].split("</ol>")[0]
    assert "Tendon friction hysteresis" in fails and "#sec-friction" in fails


def test_a_frictionless_design_gives_the_report_as_before(monkeypatch, tmp_path, measured_identification):
    """μ = 0 (the default and the option's 0): no FEM cycle runs, no section, no key, the actuator frictionless."""
    def never(*a, **k):
        raise AssertionError("an FEM tension cycle ran for a frictionless design")
    _fake_fem(monkeypatch, measured_identification, never)
    for i, kw in enumerate(({}, {"tendon_friction": 0.0})):
        run = pipeline.run_report(tmp_path / f"rep{i}", design="paper", quick=True, **kw)
        assert run.friction is None
        assert "sec-friction" not in run.report.read_text()
        assert "tendon_friction" not in json.loads((run.out / "validation.json").read_text())
        assert "tendon_friction" not in (run.out / "actuator.toml").read_text()
        assert not (run.out / "figures" / "friction.png").exists()


def test_the_command_passes_the_option_and_refuses_it_with_measurements(monkeypatch, tmp_path):
    from typer.testing import CliRunner
    from validation.commands.main import app
    seen = {}

    def fake(out, **kw):
        seen.update(kw)
        raise InputError("stop here")
    monkeypatch.setattr(pipeline, "run_report", fake)
    r = CliRunner().invoke(app, ["report", "--quick", "--tendon-friction", "0.25", "--out", str(tmp_path / "o")])
    assert seen.get("tendon_friction") == 0.25, r.output
    r = CliRunner().invoke(app, ["report", "--measurements", str(IDENTIFIED), "--base", "paper",
                                 "--tendon-friction", "0.2"])
    assert r.exit_code == 2 and "--tendon-friction" in r.output


# ------------------------------------------------------------------------------------------------ the real FEM
@pytest.mark.slow
def test_the_quick_report_with_friction_on_the_paper_design(tmp_path):
    """The real quick report and one FEM cycle (35 min measured on a heavily shared 2-core machine, from an empty
    cache; 2 min with the FEM cached): the FEM's cycle at 50 kPa with μ = 0.2; the
    rod's numbers are Model.tension_cycle's with the μ written to the actuator file; gravity as mounted."""
    run = validation.run_report(tmp_path / "rep", design="paper", quick=True, tendon_friction=0.2,
                                cache_dir=tmp_path / "cache")
    fr = run.friction
    (row,) = fr["rows"]
    assert fr["mu_source"] == "identified" and fr["fit"]["interval"][0] < fr["mu_used"] < fr["fit"]["interval"][1]
    p = ActuatorParams.from_toml(run.out / "actuator.toml")
    assert p.tendon_friction == pytest.approx(fr["mu_used"])
    rod = Model(p).tension_cycle([3.0, 0.0, 0.0], 50e3, steps=hy.STEPS_QUICK)
    assert row["loop_rod_Nmm"] == pytest.approx(1e3 * rod.loop_area, rel=1e-6)
    assert 0.5 < row["loop_ratio"] < 1.5 and row["tip_loading_mean_pct"] < 2.5
    assert 'id="sec-friction"' in run.report.read_text()
