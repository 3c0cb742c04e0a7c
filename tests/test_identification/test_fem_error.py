"""The FEM's discretisation error estimate: the Richardson formula on synthetic numbers of a known rate, the
estimate against the same case solved by hand on the meshes refined along and through the wall (a tiny tube),
the cache, and the three-way verdict."""

import math

import numpy as np
import pytest

pytest.importorskip("skfem")

from ancf.errors import InputError  # noqa: E402
from fem_reference import BellowsGeometry, BellowsModel, Material, MeshLevel  # noqa: E402
from validation.reference.experiments import LoadCase  # noqa: E402
from validation.checks.fem_error import (ASSUMED_RATE, assess, estimate_fem_error, refined_level,  # noqa: E402
                                  richardson, select_cases)
from validation.reference.fem_sweep import FemSpec  # noqa: E402

TINY = MeshLevel(2, 1, 12, 1)
GEO = BellowsGeometry.straight_tube(0.08, 0.015, 0.004, n_segments=2)
MAT = Material.neo_hookean(0.8e6, 40e6)
CASE = LoadCase((2.0, 0.0, 0.0), 0.0, (0.0, 0.0, 0.0), False, "bend", "heldout", "bend 2 N")


def test_richardson_recovers_a_known_rate_and_limit():
    """f_h = f + C h^p on h, h/2, h/4: the observed rate is p and the error of f_h is exact."""
    f, C, p, h = np.array([0.1, -0.02, 0.03]), np.array([0.004, 0.001, -0.002]), 1.7, 1.0
    vals = [f + C * (h / 2 ** k) ** p for k in range(3)]
    est = richardson(vals)
    assert est["rate_observed"] and est["rate"] == pytest.approx(p, rel=1e-10)
    assert np.allclose(est["error"], vals[0] - f, rtol=1e-10, atol=0)
    # two meshes and the right rate given: exact too; the assumed default rate scales by its factor
    two = richardson(vals[:2], rate=p)
    assert np.allclose(two["error"], vals[0] - f, rtol=1e-10) and not two["rate_observed"]
    dflt = richardson(vals[:2])
    q = ASSUMED_RATE
    assert dflt["rate"] == q and dflt["norm"] == pytest.approx(np.linalg.norm(vals[0] - vals[1]) * 2 ** q / (2 ** q - 1))
    # a ratio of 3
    vals3 = [f + C * (h / 3 ** k) ** p for k in range(3)]
    assert richardson(vals3, ratio=3)["rate"] == pytest.approx(p, rel=1e-10)


def test_richardson_refuses_a_diverging_sequence_and_bad_input():
    est = richardson([np.array([1.0]), np.array([1.1]), np.array([1.3])])     # differences grow
    assert not est["converging"] and est["error"] is None and est["rate"] < 0
    for bad in (dict(values=[np.zeros(2)]), dict(values=[np.zeros(2)] * 4), dict(values=[np.zeros(2), np.zeros(3)]),
                dict(values=[np.zeros(2)] * 2, rate=0.0), dict(values=[np.zeros(2)] * 2, ratio=1.0)):
        with pytest.raises(InputError):
            richardson(bad.pop("values"), **bad)


def test_refined_level_doubles_the_profile():
    assert refined_level("coarse") == MeshLevel(8, 2, 12, 2)
    assert refined_level(TINY, 2, ("along", "through")) == MeshLevel(4, 2, 12, 2)
    with pytest.raises(InputError):
        refined_level("nonsense")
    with pytest.raises(InputError):
        refined_level(TINY, 1)
    with pytest.raises(InputError):
        refined_level(TINY, 2, ("sideways",))


@pytest.fixture(scope="module")
def tiny_estimate(tmp_path_factory):
    cache = tmp_path_factory.mktemp("fem_error_cache")
    spec = FemSpec(GEO, MAT, TINY)
    est = estimate_fem_error(spec, [CASE], workers=1, progress=False, cache_dir=cache, compliance=True)
    return est, spec, cache


def test_estimate_matches_a_direct_computation_on_both_meshes(tiny_estimate):
    """Each direction refined on its own mesh from the same base, solved here by hand; Richardson per direction
    with p = 2 and the errors added as vectors."""
    est, spec, _ = tiny_estimate
    coarse_model = BellowsModel(GEO, MAT, TINY)
    coarse = coarse_model.solve(tensions=CASE.tensions, pressure=CASE.pressure)
    fine = {}
    for d, lvl in (("along", MeshLevel(4, 1, 12, 2)), ("through", MeshLevel(2, 2, 12, 1))):
        m = BellowsModel(GEO, MAT, lvl)
        fine[d] = (m, m.solve(tensions=CASE.tensions, pressure=CASE.pressure))
    k = 2 ** ASSUMED_RATE / (2 ** ASSUMED_RATE - 1)
    e = {d: (coarse.tip_position - r.tip_position) * k for d, (_, r) in fine.items()}
    assert min(np.linalg.norm(v) for v in e.values()) > 1e-8          # both directions move the tip measurably
    row = est.rows[0]
    want = np.linalg.norm(e["along"] + e["through"])
    assert row["tip_error_m"] == pytest.approx(want, rel=1e-5)
    assert row["tip_error_pct"] == pytest.approx(100 * want / GEO.length, rel=1e-5)
    for d in ("along", "through"):
        assert row["by_direction"][d]["tip_error_m"] == pytest.approx(np.linalg.norm(e[d]), rel=1e-5)
    assert row["shape_error_pct"] >= 0.99 * row["tip_error_pct"]          # the tip is a point of the shape
    Cc = coarse_model.tip_compliance(coarse, mode="tension")
    eC = sum((Cc - m.tip_compliance(r, mode="tension")) * k for m, r in fine.values())
    assert row["C_tension_error_pct"] == pytest.approx(100 * np.linalg.norm(eC) / np.linalg.norm(Cc), rel=1e-4)
    assert "assumed rate p = 2" in est.method and "along the profile" in est.method and "through the wall" in est.method
    assert row["started_from_coarser"] == [True, True]  # from the coarse equilibrium, and still the fine one
    lv = est.to_dict()["levels"]
    assert lv[1]["mesh"] == {"n_per_conv": 4, "n_thick": 1, "n_theta": 12, "n_collar": 2} and lv[1]["direction"] == "along"
    assert lv[2]["mesh"] == {"n_per_conv": 2, "n_thick": 2, "n_theta": 12, "n_collar": 1} and lv[2]["direction"] == "through"


def test_refined_solves_are_cached(tiny_estimate, monkeypatch):
    est, spec, cache = tiny_estimate
    import validation.reference.fem_sweep as fs
    monkeypatch.setattr(fs, "solve_task", lambda task: pytest.fail("solved again instead of read from the cache"))
    again = estimate_fem_error(spec, [CASE], workers=1, progress=False, cache_dir=cache, compliance=True)
    assert again.rows[0]["tip_error_m"] == est.rows[0]["tip_error_m"]


def test_records_carry_their_state_but_not_into_json(tiny_estimate, tmp_path):
    from validation.reference.fem_sweep import run_cases, start_solve
    _, spec, cache = tiny_estimate
    rec = run_cases(spec, [CASE], workers=1, progress=False, cache_dir=cache)[0]
    assert rec.state is not None and rec.state.U.shape[0] == 3
    assert "state" not in rec.to_dict()
    with pytest.raises(InputError, match="starts for"):
        run_cases(spec, [CASE], workers=1, progress=False, starts=[None, None])
    other = {"tensions": (1.0, 0.0, 0.0), "pressure": 0.0, "tip_force": (0.0, 0.0, 0.0), "gravity": False}
    with pytest.raises(InputError, match="other loads"):
        start_solve(BellowsModel(GEO, MAT, TINY), rec.state, other)


class _Val:
    def __init__(self, rows):
        self.rows = rows


def _fake_estimate(tiny_estimate, tip_pct):
    est, _, _ = tiny_estimate
    import copy
    e = copy.deepcopy(est)
    e.rows[0].update(tip_error_pct=tip_pct, tip_error_m=tip_pct * GEO.length / 100, C_tension_error_pct=None,
                     C_locked_error_pct=None)
    return e


def _rec(label, bend):
    """A record whose centreline bends by ``bend`` [m] at the tip."""
    from validation.reference.fem_sweep import FemRecord
    s = np.linspace(0, GEO.length, 5)
    line = np.column_stack([s, np.zeros(5), bend * (s / GEO.length) ** 2])
    c = LoadCase((0.0, 0.0, 0.0), 0.0, (0.0, 0.0, 0.0), False, "x", "heldout", label)
    return FemRecord(c, line[-1], np.eye(3), line, s, np.zeros(3), np.zeros(3))


def test_every_state_gets_a_fem_error_and_a_three_way_verdict(tiny_estimate):
    """The measured state carries its measured error; the other an estimate (never called a bound): the measured
    error per unit deformation × its own deformation.  Verdicts by the rule, counted per quantity."""
    val = _Val([{"label": CASE.label, "tip_error_pct": 2.0}, {"label": "small", "tip_error_pct": 2.45}])
    recs = [_rec(CASE.label, 0.02), _rec("small", 0.005)]
    fe = assess(val, _fake_estimate(tiny_estimate, 0.4), recs)
    measured, other = fe["rows"]
    assert measured["measured"] and measured["fem_tip_error_pct"] == 0.4
    # 0.4 % of L on a state deformed 20 mm; the other is deformed 5 mm → 0.1 % of L, as an estimate
    assert not other["measured"] and other["fem_tip_error_pct"] == pytest.approx(0.4 * 0.005 / 0.02, rel=1e-6)
    assert "estimate" in other["basis"] and "bound" not in other["basis"]
    # 2.0 + 0.4 ≤ 2.5: passes; 2.45 + 0.1 > 2.5 ≥ 2.45 − 0.1: undecided
    assert measured["verdicts"]["tip"] == "passes" and other["verdicts"]["tip"] == "undecided"
    tip = fe["quantities"]["tip"]
    assert tip["passes"] == [CASE.label] and tip["undecided"] == ["small"] and not tip["fails"]
    text = " ".join(fe["statements"])
    assert "Tip position (target 2.5 % of L): 1 state(s) pass, 0 fail, 1 undecided" in text
    assert "too large" not in text and "a third" not in text
    # a model error beyond the target by more than the FEM's error fails
    val.rows[1]["tip_error_pct"] = 2.7
    assert assess(val, _fake_estimate(tiny_estimate, 0.4), recs)["rows"][1]["verdicts"]["tip"] == "fails"
    # not estimated: the FEM taken as exact, said so; the rule is then pass / fail only
    none = assess(val, None, reason="--no-fem-error")
    assert none["estimated"] is False and "assume the FEM is exact" in none["statements"][0]
    assert [r["verdicts"]["tip"] for r in none["rows"]] == ["passes", "fails"]


def test_select_cases_takes_the_largest_deformation():
    recs = [_rec("a", 0.001), _rec("b", 0.03), _rec("c", 0.01)]
    assert [r.case.label for r in select_cases(recs, 2)] == ["b", "c"]
    with pytest.raises(InputError):
        select_cases(recs, 0)
    with pytest.raises(InputError):
        estimate_fem_error(FemSpec(GEO, MAT, TINY), [CASE], levels=4)
    assert math.isfinite(ASSUMED_RATE)


@pytest.fixture(scope="module")
def report_inputs(tiny_estimate):
    """An identification from synthetic measurements and its 'validation' against records made by a slightly
    stiffer reduced model standing in for the FEM (no FEM solve)."""
    from ancf import Model
    from test_report_cli import _states
    from test_fit import BASE
    from validation.identification import identify
    from validation.checks.compare import compare_records
    from validation.reference.experiments import default_design
    from validation.reference.fem_sweep import FemRecord
    design = default_design()
    ident = identify.from_measurements(_states(design), BASE, forms=("paper",), gravity=False)
    other = Model(ident.params.replace(gravity=(0.0, 0.0, 0.0)))
    L = ident.params.length
    s = np.linspace(0.0, L, 9)
    from validation.identification.forms import position_matrix
    S = position_matrix(ident.params.n_elements, L, s)
    recs = []
    for c in design.heldout:
        eq = other.fk(np.asarray(c.tensions) * 1.1, c.pressure, c.tip_force, check_limits=False)
        line = (S @ eq.q).reshape(-1, 3)
        recs.append(FemRecord(c, eq.tip, np.eye(3), line, s, np.zeros(3), np.zeros(3)))
    val = compare_records(ident.params, recs)
    assert val.rows
    return ident, val, recs


def _estimate_for(tiny_estimate, label, tip_pct):
    e = _fake_estimate(tiny_estimate, tip_pct)
    e.rows[0]["label"] = label
    return e


@pytest.mark.parametrize("tip_pct", [1e-4, 50.0])
def test_report_and_json_carry_the_fem_error(report_inputs, tiny_estimate, tip_pct, tmp_path):
    import copy
    import json
    from validation.report.build import write_report
    ident, val, recs = report_inputs
    val = copy.deepcopy(val)
    worst = select_cases(recs, 1)[0].case.label
    val.fem_error = assess(val, _estimate_for(tiny_estimate, worst, tip_pct), recs)
    html = write_report(tmp_path / "r.html", ident, val).read_text()
    assert "3a. The FEM" in html and "FEM discretisation error, tip [% L]" in html
    assert "FEM error, tip, through the wall [% L]" in html and "FEM error, tip, combined [% L]" in html
    assert "(estimate)" in html and "bound" not in html        # the others carry an estimate, named as such
    d = json.loads(json.dumps(val.to_dict()))
    fe = d["fem_discretisation_error"]
    assert {"tip_error_pct", "shape_error_pct", "targets", "rows"} <= set(d)          # unchanged keys kept
    assert fe["estimated"] and len(fe["rows"]) == len(val.rows)
    assert sum(r["measured"] for r in fe["rows"]) == 1
    # a FEM error of 50 % of L straddles the 2.5 % target on the measured state: undecided, said so in the
    # headline; a negligible one decides every state
    measured = next(r for r in fe["rows"] if r["measured"])
    assert (measured["verdicts"]["tip"] == "undecided") == (tip_pct > 1)
    assert ("own error straddles the target):</p>" in html) == (tip_pct > 1) \
        == bool(fe["undecided_states"])
    assert "too large" not in html
    # skipped: said so, never a number
    val.fem_error = assess(val, None, reason="--no-fem-error")
    html = write_report(tmp_path / "s.html", ident, val).read_text()
    assert "was not estimated (--no-fem-error)" in html and "too large" not in html


@pytest.mark.slow
def test_cli_validate_measures_the_fem_error(tmp_path):
    """`bellows validate` on the straight tube: validation.json carries the measured error of the 4 held-out
    states with the largest deformation and the others' estimates; the terminal shows the table."""
    import json
    from test_report_cli import _bellows
    r = _bellows("validate", "--params", "paper", "--design", "straight_tube", "--workers", "2", "--cache",
                 tmp_path / "cache", "--out", tmp_path / "v", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    fe = json.loads((tmp_path / "v" / "validation.json").read_text())["fem_discretisation_error"]
    assert fe["estimated"] and sum(x["measured"] for x in fe["rows"]) == 4
    assert all(x["fem_tip_error_pct"] >= 0 for x in fe["rows"] if x["measured"])
    assert "FEM discretisation error beside the model-vs-FEM error" in r.stdout
    skip = _bellows("validate", "--params", "paper", "--design", "straight_tube", "--no-fem-error", "--cache",
                    tmp_path / "cache", "--out", tmp_path / "v", "--force", cwd=tmp_path)
    assert skip.returncode == 0, skip.stderr
    fe = json.loads((tmp_path / "v" / "validation.json").read_text())["fem_discretisation_error"]
    assert fe["estimated"] is False and "--no-fem-error" in fe["statements"][0]
