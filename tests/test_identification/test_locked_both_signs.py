"""The locked tip compliance of a state with a slack tendon, for both signs of the load direction.

With every tendon locked at its length, a slack tendon is taut for one sign of a small tip load and not for the
other (a −z load stretches the top tendon, a +z load the lower ones): the locked response is piecewise linear,
C(u) u ≠ −C(−u)(−u).  The validation reports, for such states, the locked compliance of each sign with the taut
set that sign makes taut, in both models by the same rule.  Checked here against finite differences: the rod with
its tendon lengths held by the locked solver (``Model.fk_locked``) and a small load ε d, d = ±u; the FEM with its
locked nonlinear solve (``locked_lengths``).
"""

import numpy as np
import pytest

from ancf import Model, presets
from ancf import compliance as cp
from validation.checks.compare import compare_records
from validation.reference.experiments import LoadCase
from validation.reference.fem_sweep import FemRecord

U = np.array([0.0, 0.0, -1.0])          # the validation's load direction


def _rod():
    return Model(presets.paper().replace(gravity=(0.0, 0.0, 0.0)))


def _fd_locked(model, eq, case, d, eps=1e-4):
    """(tip(F + ε d) − tip(F)) / ε [m/N] with the tendon lengths of ``eq`` held, and the taut tendons."""
    l0 = model.tendon_lengths(eq.q)
    F = np.asarray(case.tip_force) + eps * d
    loaded = model.fk_locked(l0, case.pressure, F, q0=eq.q, tensions0=eq.tensions, check_limits=False)
    return (loaded.tip - eq.tip) / eps, [i for i in range(model.m) if loaded.tensions[i] > 1e-9]


def _record_like_fem(model, eq, case) -> FemRecord:
    """A record carrying the rod's own compliances in the FEM's places (the plumbing; the physics is checked by
    finite differences below)."""
    Cu = cp.locked(model, eq, method="exact", load_direction=U)
    Cm = cp.locked(model, eq, method="exact", load_direction=-U)
    s = np.linspace(0.0, model.params.length, 17)
    centre = np.column_stack([s, np.zeros_like(s), np.zeros_like(s)])
    return FemRecord(case, eq.tip, np.eye(3), centre, s, np.asarray(case.tensions), model.tendon_lengths(eq.q),
                     compliance_tension=cp.tension(model, eq).C_p, compliance_locked=Cu.C_p,
                     extra={"locked_active": list(Cu.active), "compliance_locked_opposite": Cm.C_p,
                            "locked_active_opposite": list(Cm.active)})


@pytest.mark.parametrize("tensions, pressure, force", [
    ((2.0, 0.0, 0.0), 25e3, (0.0, 0.0, -0.49)),
    ((0.0, 2.0, 4.0), 37.5e3, (0.0, 0.0, 0.0)),
    ((0.0, 0.0, 0.0), 50e3, (0.0, 0.0, 0.0)),
])
def test_reported_locked_compliance_of_each_sign_matches_finite_differences(tensions, pressure, force):
    model = _rod()
    case = LoadCase(tensions, pressure, force, experiment="heldout", role="heldout")
    eq = model.fk(case.tensions, case.pressure, case.tip_force, check_limits=False)
    row = compare_records(model.params, [_record_like_fem(model, eq, case)]).rows[0]
    signs = {s["sign"]: s for s in row["locked_by_sign"]}
    assert set(signs) == {"u", "-u"}
    along = {}
    for name, d in (("u", U), ("-u", -U)):
        rep = signs[name]
        np.testing.assert_allclose(rep["direction"], d)
        fd, taut = _fd_locked(model, eq, case, d)
        Cd = np.asarray(rep["C_ancf_m_per_N"]) @ d
        assert np.linalg.norm(fd - Cd) < 2e-3 * np.linalg.norm(Cd), (name, fd, Cd)
        assert abs(rep["along_ancf_m_per_N"] - d @ fd) < 2e-3 * abs(d @ fd)
        assert sorted(rep["taut_ancf"]) == sorted(taut)             # the taut set that sign makes taut
        along[name] = rep["along_ancf_m_per_N"]
        assert rep["error_pct"] < 1e-9                              # the record carried the rod's own
    # the two signs differ: one matrix for both (a tendon locked both ways) would be wrong for one of them
    assert sorted(signs["u"]["taut_ancf"]) != sorted(signs["-u"]["taut_ancf"])
    assert abs(along["u"] / along["-u"] - 1) > 0.05


def test_no_sign_split_without_a_slack_tendon():
    model = _rod()
    case = LoadCase((1.0, 1.0, 1.0), 20e3, experiment="heldout", role="heldout")
    eq = model.fk(case.tensions, case.pressure, check_limits=False)
    rec = _record_like_fem(model, eq, case)
    for k in ("compliance_locked_opposite", "locked_active_opposite"):
        rec.extra.pop(k)                         # the sweep stores the opposite sign only with a slack tendon
    val = compare_records(model.params, [rec])
    assert "locked_by_sign" not in val.rows[0] and val.locked_by_sign == {}


def test_summary_reports_both_signs():
    model = _rod()
    recs = []
    for T, p in (((2.0, 0.0, 0.0), 25e3), ((0.0, 2.0, 4.0), 37.5e3)):
        case = LoadCase(T, p, experiment="heldout", role="heldout")
        recs.append(_record_like_fem(model, model.fk(T, p, check_limits=False), case))
    val = compare_records(model.params, recs)
    assert val.locked_by_sign["states"] == [r.case.label for r in recs]
    assert set(val.locked_by_sign["error_pct"]) == {"u", "-u"}
    assert "locked_by_sign" in val.to_dict()


skfem = pytest.importorskip("skfem")


def test_fem_locked_compliance_of_each_sign_matches_a_locked_solve():
    from fem_reference import BellowsModel, MeshLevel, presets as fem_presets
    from validation.reference.fem_sweep import locked_compliance, tip_compliances
    model = BellowsModel(fem_presets.paper_bellows(), fem_presets.paper_material(), MeshLevel(2, 1, 12, 1))
    res = model.solve(tensions=(1.0, 0.0, 0.0), pressure=20e3)
    both = locked_compliance(model, res, (U, -U))
    single = locked_compliance(model, res, U)
    np.testing.assert_allclose(both[0][0], single[0], rtol=1e-12)
    assert both[0][1] == single[1]
    eps = 2e-3
    for (C, active), d in zip(both, (U, -U)):
        loaded = model.solve(tensions=(1.0, 0.0, 0.0), pressure=20e3, tip_force=tuple(eps * d),
                             locked_lengths=[float(x) for x in res.tendon_lengths], initial=res, n_steps=1)
        fd = (loaded.tip_position - res.tip_position) / eps
        assert np.linalg.norm(fd - C @ d) < 2e-3 * np.linalg.norm(C @ d)
        assert sorted(i for i in range(3) if loaded.tensions[i] > 1e-9) == sorted(active)
    assert sorted(both[0][1]) != sorted(both[1][1])
    # the sweep takes the tension-held compliance from the same factorisation: BellowsModel.tip_compliance's
    C_tension, shared = tip_compliances(model, res, (U, -U))
    np.testing.assert_allclose(C_tension, model.tip_compliance(res, mode="tension"), rtol=1e-10, atol=0)
    for (C, active), (C1, active1) in zip(shared, both):
        np.testing.assert_allclose(C, C1, rtol=1e-12)
        assert active == active1


def test_the_report_shows_each_sign_with_the_tendons_it_makes_taut():
    """The validation table's cell for a state with a slack tendon names, per sign of the load direction, the
    locked-compliance error and the taut tendons (numbered from 1), both models' sets when they differ."""
    from validation.report.build import _locked_by_sign_cell
    row = {"locked_by_sign": [
        {"sign": "u", "direction": [0.0, 0.0, -1.0], "taut_fem": [0], "taut_ancf": [0], "error_pct": 2.18},
        {"sign": "-u", "direction": [0.0, 0.0, 1.0], "taut_fem": [0, 1, 2], "taut_ancf": [1, 2], "error_pct": 5.06}]}
    cell = _locked_by_sign_cell(row)
    assert cell == "−z: 2.2 (taut 1) · +z: 5.1 (taut FEM 1,2,3, model 2,3)"
    assert _locked_by_sign_cell({"locked_by_sign": []}) == "" and _locked_by_sign_cell({}) == ""
