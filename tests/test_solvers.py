"""FK / IK / locked-length FK: round trips, bounds, complementarity, robustness, error reporting."""

import itertools

import numpy as np
import pytest

from ancf import (ConvergenceError, InfeasibleTargetError, InputError, Model, presets)

RNG = np.random.default_rng(3)


def test_fk_operating_range_cold_start(paper_model):
    """Cold starts over the corners of the operating range: 0–5 N per tendon, 0–120 kPa, 2 N tip loads
    in ±x, ±y, ±z.  Every solve converges and its residual is verified independently."""
    m = paper_model
    loads = [(0, 0, 0)] + [tuple(2.0 * s * np.eye(3)[i]) for i in range(3) for s in (1, -1)]
    for T in itertools.product((0.0, 5.0), repeat=3):
        for p in (0.0, 120e3):
            for F in loads:
                eq = m.fk(T, p, F)
                Q = m.reduce_vec(m.residual(eq.q, eq.tensions, p, F))
                assert np.linalg.norm(Q) < m.default_tol
                assert eq.converged and eq.iterations <= 25


def test_fk_warm_start_is_cheaper(paper_model):
    m = paper_model
    cold = m.fk((2.0, 0.0, 1.0), 40e3, (0, 0, -0.5))
    warm = m.fk((2.05, 0.0, 1.0), 40e3, (0, 0, -0.5), q0=cold.q)
    assert warm.iterations < cold.iterations
    assert np.linalg.norm(warm.tip - cold.tip) < 2e-3


@pytest.mark.parametrize("k", range(6))
def test_ik_fk_round_trip(paper_model, k):
    """FK at random inputs → IK on its tip recovers the tensions (unique for 3 tendons) and the state."""
    m = paper_model
    T = RNG.uniform(0.0, 5.0, 3)
    T[RNG.integers(3)] = 0.0                 # a slack tendon is the normal case
    p = RNG.uniform(0, 120e3)
    F = RNG.normal(size=3) * 0.3
    fk = m.fk(T, p, F)
    ik = m.ik(fk.tip, p, F)
    assert np.linalg.norm(ik.tip - fk.tip) < 1e-9
    assert ik.tensions == pytest.approx(T, abs=1e-6)
    assert np.all(ik.tensions >= 0)
    back = m.fk(ik.tensions, p, F)
    assert np.linalg.norm(back.tip - fk.tip) < 1e-8


def test_ik_infeasible_target_names_bound(paper_model):
    """x = 158 mm at 30 kPa needs net compression beyond 3 × 5 N: a clear error with the nearest point."""
    with pytest.raises(InfeasibleTargetError) as info:
        paper_model.ik((0.158, 0.0, 0.012), 30e3)
    err = info.value
    assert err.violated and "T" in err.violated[0]
    assert err.nearest is not None and np.all(err.tensions >= 0) and np.all(err.tensions <= 5)
    # the nearest point is reachable: FK at the reported tensions lands on it
    back = paper_model.fk(err.tensions, 30e3)
    assert np.linalg.norm(back.tip - err.nearest) < 1e-8
    assert "nearest reachable tip" in str(err)


def test_ik_target_needing_negative_tension(paper_model):
    """A target above the pressure-only extension needs a pushing tendon: T ≥ 0 is named."""
    m = paper_model
    straight = m.fk((0, 0, 0), 60e3)
    with pytest.raises(InfeasibleTargetError, match=r"T\d >= 0 N"):
        m.ik(straight.tip + np.array([0.004, 0.0, 0.0]), 60e3)


@pytest.mark.parametrize("bad", [(np.nan, 0, 0), (0.1, np.inf, 0), (0.1, 0.0)])
def test_ik_bad_target_rejected(paper_model, bad):
    with pytest.raises(InputError):
        paper_model.ik(bad, 0.0)


def test_fk_bad_inputs(paper_model):
    m = paper_model
    with pytest.raises(InputError, match="outside the actuator's limits"):
        m.fk((6.0, 0, 0))
    with pytest.raises(InputError, match="pressure"):
        m.fk((0, 0, 0), 30.0e6)
    with pytest.raises(InputError, match="NaN"):
        m.fk((0, 0, 0), 0.0, (0, np.nan, 0))
    with pytest.raises(InputError, match="3 values"):
        m.fk((1.0, 0.0))


def test_nonconvergence_is_reported_not_returned(paper_model):
    with pytest.raises(ConvergenceError) as info:
        paper_model.fk((5.0, 0, 0), 0.0, (0, 0, -2.0), tol=1e-300)   # below round-off: cannot be met
    e = info.value
    assert e.solver == "fk" and e.residual_norm > e.tolerance and e.iterations >= 1 and e.history
    assert "residual" in str(e) and "iterations" in str(e)


def _locked_case(m, T, p, F_lock, F_load):
    ik_state = m.fk(T, p, F_lock)
    return ik_state, m.fk_locked(ik_state.tendon_lengths, p, F_load, q0=ik_state.q, tensions0=ik_state.tensions)


def test_locked_without_load_change_reproduces_state(paper_model):
    m = paper_model
    base, lk = _locked_case(m, (2.0, 0.5, 0.0), 30e3, (0, 0, 0), (0, 0, 0))
    assert np.linalg.norm(lk.tip - base.tip) < 1e-10
    # slack tendon (T3 = 0) stays slack with zero slack length; the others carry their tensions
    assert lk.tensions == pytest.approx([2.0, 0.5, 0.0], abs=1e-7)


@pytest.mark.parametrize("F", [(0, 0, -0.49), (0, 0.4, 0.49), (-1.0, 0.0, 0.0), (0.0, -0.8, 0.3)])
def test_locked_complementarity_and_methods_agree(paper_model, F):
    m = paper_model
    base, lk = _locked_case(m, (3.0, 0.5, 0.2), 30e3, (0, 0, 0), F)
    assert np.all(lk.tensions >= 0) and np.all(lk.slack >= 0)
    assert np.all(lk.tensions * lk.slack == 0)
    # lengths never exceed the locked values; taut ones are met exactly
    assert np.all(lk.tendon_lengths <= base.tendon_lengths + 1e-10)
    for i in lk.active:
        assert lk.tendon_lengths[i] == pytest.approx(base.tendon_lengths[i], abs=1e-10)
    # equilibrium with the multiplier tensions
    Q = m.reduce_vec(m.residual(lk.q, lk.tensions, 30e3, F))
    assert np.linalg.norm(Q) < 1e-8
    # paper's γ substitution gives the same state
    g = m.fk_locked(base.tendon_lengths, 30e3, F, q0=base.q, tensions0=base.tensions, method="gamma")
    assert np.linalg.norm(g.tip - lk.tip) < 1e-9
    assert g.tensions == pytest.approx(lk.tensions, abs=1e-6)


def test_locked_is_stiffer_than_constant_tension(paper_model):
    """Locking the tendons adds constraints: the tip moves less under the same extra load."""
    m = paper_model
    base = m.fk((2.0, 0.0, 0.0), 0.0)
    free = m.fk((2.0, 0.0, 0.0), 0.0, (0, 0, -0.49), q0=base.q)
    lk = m.fk_locked(base.tendon_lengths, 0.0, (0, 0, -0.49), q0=base.q, tensions0=base.tensions)
    d_free = np.linalg.norm(free.tip - base.tip)
    d_lock = np.linalg.norm(lk.tip - base.tip)
    assert d_lock < 0.8 * d_free


def test_locked_cold_start_and_bad_method(paper_model):
    m = paper_model
    base = m.fk((1.0, 1.0, 1.0), 20e3)
    lk = m.fk_locked(base.tendon_lengths, 20e3, (0, 0, -0.3))
    assert np.all(lk.tensions >= 0)
    with pytest.raises(InputError, match="method"):
        m.fk_locked(base.tendon_lengths, 20e3, method="magic")


def test_four_tendons_ik_is_feasible_and_consistent():
    """More than three tendons: IK picks the least-tension solution inside the bounds."""
    m = Model(presets.four_tendon())
    T_ref = np.array([3.0, 1.5, 1.0, 1.0])          # opposing pairs both pulled: not the least tension
    fk = m.fk(T_ref, 20e3, (0, 0, -0.2))
    ik = m.ik(fk.tip, 20e3, (0, 0, -0.2))
    assert np.linalg.norm(ik.tip - fk.tip) < 1e-8
    assert np.all(ik.tensions >= 0) and np.all(ik.tensions <= 5.0)
    # equal changes in opposite tendons keep force and moments: the solution family is T_ref + s n with
    # n = (−1, 1, −1, 1) for the near-straight state; its least-norm member has s = −(n·T_ref)/|n|²
    n = np.array([-1.0, 1.0, -1.0, 1.0])
    expected = T_ref - (n @ T_ref) / (n @ n) * n
    assert ik.tensions == pytest.approx(expected, abs=2e-3)
    assert np.sum(ik.tensions ** 2) < np.sum(T_ref ** 2)
    Q = m.reduce_vec(m.residual(ik.q, ik.tensions, 20e3, (0, 0, -0.2)))
    assert np.linalg.norm(Q) < 1e-7


def test_free_base_stretch_option():
    p = presets.paper_unscaled().replace(free_base_stretch=True)
    m = Model(p)
    eq = m.fk((0, 0, 0), 120e3)
    assert np.linalg.norm(eq.q[3:6]) > 1.0          # the base section stretches too
    assert np.allclose(np.cross(eq.q[3:6], p.base_axis), 0.0)   # but keeps its direction


def test_random_states_over_operating_range(paper_model):
    """Random T ∈ [0, 5]³ N (with slack tendons), p ∈ [0, 120] kPa, |F| ≤ 2 N in any direction: cold FK
    converges, cold IK on its tip recovers the tensions, and after an extra load both locked-length
    solvers (exact active set, paper's γ substitution) find the same complementary state."""
    m = paper_model
    rng = np.random.default_rng(11)
    for _ in range(40):
        T = rng.uniform(0, 5, 3)
        T[rng.random(3) < 0.3] = 0.0
        p = rng.uniform(0, 120e3)
        F = rng.normal(size=3)
        F *= rng.uniform(0, 2) / np.linalg.norm(F)
        e = m.fk(T, p, F)
        assert m.ik(e.tip, p, F).tensions == pytest.approx(T, abs=1e-5)
        F2 = F + rng.normal(size=3) * 0.5
        a = m.fk_locked(e.tendon_lengths, p, F2, q0=e.q, tensions0=e.tensions)
        g = m.fk_locked(e.tendon_lengths, p, F2, q0=e.q, tensions0=e.tensions, method="gamma")
        assert np.linalg.norm(a.tip - g.tip) < 1e-8
        assert np.all(a.tensions >= 0) and np.all(a.slack >= 0) and np.all(a.tensions * a.slack == 0)


@pytest.mark.parametrize("free", [False, True])
def test_free_coordinate_map_round_trips(free):
    """to_full(to_free(q)) == q for admissible q (the base stays clamped), with and without a free base
    stretch; with the free stretch the reference state is still an equilibrium with no load."""
    model = Model(presets.paper_unscaled().replace(free_base_stretch=free, line_mass=0.0, tip_mass=0.0))
    rng = np.random.default_rng(3)
    q = model.q_ref.copy()
    q[6:] += rng.normal(0, 1e-3, model.ndof - 6)
    if free:
        q[3:6] = 1.07 * model._e1
    np.testing.assert_allclose(model.to_full(model.to_free(q)), q, rtol=0, atol=1e-15)
    eq = model.fk((0.0, 0.0, 0.0), 0.0)
    np.testing.assert_allclose(eq.q, model.q_ref, atol=1e-12)


def test_degenerate_tip_slope_is_inadmissible_not_a_division_by_zero():
    """The tip slope is not a quadrature point: a state with |r_x(L)| = 0 (a trial point of a line search)
    is rejected like any collapsed section — infinite energy for the solvers, a typed error at the API."""
    from ancf.errors import CollapsedStateError
    m = Model(presets.paper_unscaled())
    q = m.q_ref.copy()
    q[-3:] = 0.0
    q[-6] += 0.02
    assert m._fk_fun(np.array([1.0, 0.0, 0.0]), 0.0, np.zeros(3))(m.to_free(q), True)[0] == np.inf
    with pytest.raises(CollapsedStateError):
        m.evaluate(q, (1.0, 0.0, 0.0), 0.0, (0.0, 0.0, 0.0))


def test_envelope_cholesky_solves_like_a_dense_factorisation():
    """solvers._chol_solve_kernel follows the matrix's envelope (skips the zeros left of each row's first
    non-zero): against numpy's dense Cholesky on banded, irregular-envelope and full SPD matrices, with a
    shift, and it still refuses an indefinite matrix whose failing pivot lies inside the envelope."""
    from ancf.solvers import _chol_solve_kernel
    rng = np.random.default_rng(7)
    for n in (1, 2, 7, 36, 43):
        for band in (0, 1, 3, 11, n):
            A = rng.normal(size=(n, n))
            A = A @ A.T + n * np.eye(n)
            A[np.abs(np.subtract.outer(np.arange(n), np.arange(n))) > band] = 0.0
            if n > 7:                                    # an entry far outside the band, and a zero inside it
                A[n - 1, 1] = A[1, n - 1] = 0.3
                A[5, 4] = A[4, 5] = 0.0
            g = rng.normal(size=n)
            for shift in (0.0, 2.5):
                ok, x = _chol_solve_kernel(A, g, shift)
                L = np.linalg.cholesky(A + shift * np.eye(n))
                assert ok
                np.testing.assert_allclose(x, np.linalg.solve(L.T, np.linalg.solve(L, g)), rtol=1e-10,
                                           atol=1e-12 * np.abs(x).max())
            if n > 7:
                B = A.copy()
                B[n - 1, n - 1] = -1.0                   # fails at the last pivot, reached through the far entry
                assert not _chol_solve_kernel(B, g, 0.0)[0]
                assert _chol_solve_kernel(B, g, 1.0 + np.abs(B).sum())[0]
