"""The FEM error combined over refinement directions: on synthetic records whose results follow Richardson's
model exactly, f_h = f + C_along h_along^p + C_through h_through^p (each direction refined on its own mesh from
the same base), the combined estimate is the exact error of the base result and each direction's number its
own term — closed forms, no FEM solve."""

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from ancf.errors import InputError
from validation.checks.fem_error import ASSUMED_RATE, combine_directions, estimate_fem_error
from validation.reference.experiments import LoadCase
from validation.reference.fem_sweep import FemRecord

L = 0.16
S = np.linspace(0.0, L, 9)
CASE = LoadCase((2.0, 0.0, 0.0), 30e3, (0.0, 0.0, 0.0), False, "bend", "heldout", "T = 2/0/0 N, p = 30 kPa")
#: the exact results: a bent centreline, its tip, two compliance matrices [m/N]
LINE = np.column_stack([S, np.zeros_like(S), 0.05 * (S / L) ** 2])
CT, CL = np.diag([1e-4, 2e-3, 3e-3]), np.diag([1e-4, 1e-3, 1.5e-3])


def _record(h: dict, coeff: dict, rate: dict, ok: bool = True) -> FemRecord:
    """The case solved on a mesh of sizes ``h`` per direction: every result f + Σ_d C_d h_d^p_d."""
    def f(exact, k):
        return exact + sum(np.asarray(coeff[d][k]) * h[d] ** rate[d] for d in h)
    line = f(LINE, "line")
    return FemRecord(CASE, line[-1], np.eye(3), line, S, np.zeros(3), np.zeros(3),
                     compliance_tension=f(CT, "CT"), compliance_locked=f(CL, "CL"), error="" if ok else "diverged")


def _coeffs(rng, scale):
    return {"line": scale * rng.standard_normal((len(S), 3)) * (S / L)[:, None],
            "CT": 1e-4 * scale * rng.standard_normal((3, 3)), "CL": 1e-4 * scale * rng.standard_normal((3, 3))}


def _chains(coeff, rate, levels):
    base = _record({"along": 1.0, "through": 1.0}, coeff, rate)
    refined = {d: [_record({"along": 1.0, "through": 1.0} | {d: 0.5 ** k}, coeff, rate) for k in range(1, levels)]
               for d in ("along", "through")}
    return base, refined


def _check_exact(row, base, coeff, rate_given):
    exact_tip = base.tip_position - LINE[-1]
    assert row["error"] == "" and row["tip_error_m"] == pytest.approx(np.linalg.norm(exact_tip), rel=1e-9)
    assert row["tip_error_pct"] == pytest.approx(100 * np.linalg.norm(exact_tip) / L, rel=1e-9)
    for d in ("along", "through"):
        own = np.asarray(coeff[d]["line"])[-1]                     # the direction's own term at h = 1
        got = row["by_direction"][d]
        assert np.allclose(got["tip_error_vector_m"], own, rtol=1e-9, atol=1e-15)
        assert got["tip_error_pct"] == pytest.approx(100 * np.linalg.norm(own) / L, rel=1e-9)
    shape = np.linalg.norm(base.centreline - LINE, axis=1).max()
    assert row["shape_error_pct"] == pytest.approx(100 * shape / L, rel=1e-9)
    for mode, exact in (("tension", CT), ("locked", CL)):
        C = getattr(base, f"compliance_{mode}")
        assert row[f"C_{mode}_error_pct"] == pytest.approx(100 * np.linalg.norm(C - exact) / np.linalg.norm(C),
                                                           rel=1e-8)


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2 ** 31), along=st.floats(0.01, 1.0), through=st.floats(0.01, 1.0))
def test_two_meshes_per_direction_with_the_right_rate_give_the_exact_error(seed, along, through):
    """With p = 2 (the assumed rate), e_d = (f_h − f_h/2,d) · 4/3 = C_d exactly; the sum is f_h − f."""
    rng = np.random.default_rng(seed)
    coeff = {"along": _coeffs(rng, 1e-3 * along), "through": _coeffs(rng, 1e-3 * through)}
    rate = {"along": ASSUMED_RATE, "through": ASSUMED_RATE}
    base, refined = _chains(coeff, rate, 2)
    row = combine_directions(base, refined, length=L, compliance=True)
    _check_exact(row, base, coeff, True)
    assert row["rate"] == ASSUMED_RATE and not row["rate_observed"]


def test_three_meshes_per_direction_observe_each_directions_own_rate():
    rng = np.random.default_rng(3)
    coeff = {"along": _coeffs(rng, 1e-3), "through": _coeffs(rng, 5e-4)}
    rate = {"along": 3.1, "through": 1.6}
    base, refined = _chains(coeff, rate, 3)
    row = combine_directions(base, refined, length=L, compliance=True)
    _check_exact(row, base, coeff, False)
    assert row["by_direction"]["along"]["rate"] == pytest.approx(3.1, rel=1e-8)
    assert row["by_direction"]["through"]["rate"] == pytest.approx(1.6, rel=1e-8)
    assert row["rate"] == pytest.approx(1.6, rel=1e-8) and row["rate_observed"]


def test_errors_in_the_same_direction_add_and_opposite_ones_cancel():
    """The combination is the vector sum, not the sum of norms: error terms of 0.64 mm (along) and 0.40 mm
    (through) pointing the same way, as measured on the default bellows, give 1.04 mm; opposite ones 0.24 mm."""
    shape = np.outer((S / L) ** 2, [0.0, 0.0, 1.0])             # a bend whose tip term is 1 m along z
    zero = np.zeros((3, 3))
    for sign, want in ((1.0, 1.04e-3), (-1.0, 0.24e-3)):
        coeff = {"along": {"line": 0.64e-3 * shape, "CT": zero, "CL": zero},
                 "through": {"line": sign * 0.40e-3 * shape, "CT": zero, "CL": zero}}
        base, refined = _chains(coeff, {"along": 2.0, "through": 2.0}, 2)
        row = combine_directions(base, refined, length=L)
        assert row["by_direction"]["along"]["tip_error_m"] == pytest.approx(0.64e-3, rel=1e-9)
        assert row["tip_error_m"] == pytest.approx(want, rel=1e-9)


def test_a_failed_or_diverging_direction_gives_no_number():
    rng = np.random.default_rng(1)
    coeff = {"along": _coeffs(rng, 1e-3), "through": _coeffs(rng, 1e-3)}
    rate = {"along": 2.0, "through": 2.0}
    base, refined = _chains(coeff, rate, 2)
    refined["through"] = [_record({"along": 1.0, "through": 0.5}, coeff, rate, ok=False)]
    row = combine_directions(base, refined, length=L)
    assert row["tip_error_m"] is None and "through: diverged" in row["error"]
    base, refined = _chains(coeff, rate, 3)
    # along on h = 0.9 then 0.5: the differences 0.19 C then 0.56 C grow — not converging
    refined["along"] = [_record({"along": h, "through": 1.0}, coeff, rate) for h in (0.9, 0.5)]
    row = combine_directions(base, refined, length=L)
    assert row["tip_error_m"] is None and "not converging" in row["error"] and "along" in row["error"]
    with pytest.raises(InputError):
        combine_directions(base, {}, length=L)


def test_bad_directions_are_refused_before_any_solve():
    pytest.importorskip("skfem")
    from fem_reference import BellowsGeometry, Material, MeshLevel
    from validation.reference.fem_sweep import FemSpec
    spec = FemSpec(BellowsGeometry.straight_tube(0.08, 0.015, 0.004, n_segments=2), Material.neo_hookean(0.8e6, 40e6),
                   MeshLevel(2, 1, 12, 1))
    for bad in ((), ("along", "along"), ("sideways",)):
        with pytest.raises(InputError):
            estimate_fem_error(spec, [CASE], directions=bad, progress=False)
