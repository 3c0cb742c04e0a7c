"""The FEM reference returns only stable equilibria: the inertia of the reduced tangent (Sylvester, with
Haynsworth's additivity on the tangent space of locked tendons) counts its negative directions.  Checked
on a straight tube under an axial dead push against the Euler load π² E I / (4 L²) of a clamped-free
column."""

import numpy as np
import pytest

from ancf.errors import UnstableEquilibriumError
from fem_reference import BellowsGeometry, BellowsModel, Material, MeshLevel

MU, KAPPA, L, R, T_WALL = 0.8e6, 40e6, 0.08, 0.015, 0.004
E = 9 * KAPPA * MU / (3 * KAPPA + MU)
I_TUBE = np.pi / 4 * ((R + T_WALL / 2) ** 4 - (R - T_WALL / 2) ** 4)
P_EULER = np.pi ** 2 * E * I_TUBE / (4 * L ** 2)


@pytest.fixture(scope="module")
def tube():
    return BellowsModel(BellowsGeometry.straight_tube(L, R, T_WALL, n_segments=2), Material.neo_hookean(MU, KAPPA),
                        MeshLevel(2, 1, 12, 1))


def test_stable_states_are_flagged_and_locked_states_are_checked_on_the_constraint_space(tube):
    res = tube.solve(tensions=(0.5, 0, 0), pressure=10e3)
    assert res.stable is True and res.negative_directions == 0 and res.summary()["stable"] is True
    lk = tube.solve(locked_lengths=[res.tendon_lengths[0], None, None], tip_force=(0, 0, -0.3), initial=res)
    assert lk.tensions[0] > 0 and lk.stable is True


def test_buckling_onset_against_euler(tube):
    """Below the critical push the straight state is a minimum; above it the solve raises (the symmetric
    tube loses stability in two bending directions at once) unless asked not to check."""
    below = tube.solve(tip_force=(-0.5 * P_EULER, 0, 0), check_limits=False)
    assert below.stable
    with pytest.raises(UnstableEquilibriumError, match="perturb"):
        tube.solve(tip_force=(-1.5 * P_EULER, 0, 0), check_limits=False)
    above = tube.solve(tip_force=(-1.5 * P_EULER, 0, 0), check_limits=False, check_stability=False)
    assert above.stable is None and tube.stability(above) == 2 and above.negative_directions == 2
    lo, hi = 0.5 * P_EULER, 1.5 * P_EULER
    for _ in range(5):
        mid = 0.5 * (lo + hi)
        res = tube.solve(tip_force=(-mid, 0, 0), check_limits=False, check_stability=False)
        lo, hi = (mid, hi) if tube.stability(res) == 0 else (lo, mid)
    # coarse mesh and rigid end caps stiffen the column by several percent (straight-tube tests: 3-4 %)
    assert 0.95 < 0.5 * (lo + hi) / P_EULER < 1.15


def test_pardiso_inertia_counts_what_superlu_counts(tube):
    """The stability check's fast path (PARDISO's LDLᵀ of the symmetric part) and its fallback (SuperLU with
    diagonal pivots) give the same count on a stable and on a buckled state."""
    from fem_reference.solver import available_solvers, symmetric_inertia
    if "pardiso" not in available_solvers():
        pytest.skip("pypardiso is not installed")
    for push, expected in ((0.5, 0), (1.5, 2)):
        res = tube.solve(tip_force=(-push * P_EULER, 0, 0), check_limits=False, check_stability=False)
        K = tube.evaluate(res.state, res.loadcase)["K"]
        fast = symmetric_inertia(K)
        assert fast is not None and fast[0] == expected
        tube.linear_solver = "splu"
        try:
            assert tube.stability(res) == expected          # the SuperLU path
        finally:
            tube.linear_solver = "auto"
