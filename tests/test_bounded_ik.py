"""The compiled bounded IK (ancf.compiled_bounded: projected Gauss–Newton for the nearest reachable tip)
against the scipy path it replaces (``least_squares``, ``Model.fast_bounded_ik = False``), against finite
differences of cold FK solves (its Jacobian and the optimality of its answer) and against scipy's bounded
linear least squares (its box subproblem); the errors stay the same, and the state it hands on is verified."""

import numpy as np
import pytest
from scipy.optimize import lsq_linear

from ancf import InfeasibleTargetError, Model, presets
from ancf import compiled_bounded as cb
from ancf import compiled_solvers as cs

P = 30e3
MODELS = {"paper": Model(presets.paper()), "four_tendon": Model(presets.four_tendon())}


def _targets(m, count, seed):
    """Targets around the tip at 2 N per tendon, most of them out of reach (deterministic)."""
    rng = np.random.default_rng(seed)
    ref = m.fk(np.full(m.m, 2.0), P, (0, 0, 0))
    return [(ref.tip + rng.normal(size=3) * np.array([0.01, 0.03, 0.03]), rng.normal(size=3) * 0.2)
            for _ in range(count)], ref


def _solve(m, target, F, fast, **kw):
    """("ok", equilibrium) or ("out", InfeasibleTargetError) with the compiled loop on or off."""
    m.fast_bounded_ik = fast
    try:
        return "ok", m.ik(target, P, F, **kw)
    except InfeasibleTargetError as exc:
        return "out", exc
    finally:
        del m.fast_bounded_ik                        # back to the class default


def _careful_least_squares(m, target, F, x0):
    """The nearest reachable tensions by scipy's least_squares (TRF) with a cold FK per evaluation (no warm start
    that could leave a solve unchanged) and the Jacobian −J_p H⁻¹ J_lᵀ from the public API — the reference."""
    from scipy.optimize import least_squares
    lo, hi = np.full(m.m, m.params.tension_min), np.full(m.m, m.params.tension_max)

    def fk(T):
        return m.fk(T, P, F, check_limits=False)

    def jac(T):
        eq = fk(T)
        H = m.reduce_mat(m.tangent(eq.q, T, P, F))
        return -m.reduce_vec(m.tip_jacobian(eq.q)) @ np.linalg.solve(H, m.reduce_vec(m.tendon_jacobian(eq.q)).T)
    res = least_squares(lambda T: fk(T).tip - target, np.clip(x0, lo, hi), jac=jac, bounds=(lo, hi),
                        method="trf", xtol=1e-15, ftol=1e-15, gtol=1e-15, max_nfev=400)
    return res.x, fk(res.x).tip


@pytest.mark.parametrize("name", sorted(MODELS))
@pytest.mark.parametrize("warm", [False, True])
def test_nearest_reachable_point_is_the_least_squares_one(name, warm):
    """Several targets out of reach (3 and 4 tendons, cold and warm-started):

    * the same nearest tensions and tip as least_squares to ~1e-6 (the reference above, started from the
      product's scipy answer: today's path, whose warm-started FK solves can return unchanged, so it may stop
      short of the minimum along a flat direction — 4e-4 N on one four-tendon target);
    * never a worse objective than the product's scipy path, the same violated bounds and message."""
    m = MODELS[name]
    targets, ref = _targets(m, 6, seed=4)
    kw = {"q0": ref.q, "tensions0": ref.tensions} if warm else {}
    span = m.params.tension_max - m.params.tension_min
    out = 0
    for target, F in targets:
        kind_f, fast = _solve(m, target, F, True, **kw)
        kind_s, slow = _solve(m, target, F, False, **kw)
        assert kind_f == kind_s
        if kind_f == "ok":
            np.testing.assert_allclose(fast.tensions, slow.tensions, rtol=0, atol=1e-6 * span)
            continue
        out += 1
        T_ref, tip_ref = _careful_least_squares(m, target, F, slow.tensions)
        np.testing.assert_allclose(fast.tensions, T_ref, rtol=0, atol=1e-6 * span)
        gap = np.linalg.norm(tip_ref - target)
        np.testing.assert_allclose(fast.nearest, tip_ref, rtol=0, atol=max(1e-6 * gap, 1e-9))
        f_fast, f_slow = (np.sum((e.nearest - target) ** 2) for e in (fast, slow))
        assert f_fast <= f_slow * (1 + 1e-9)
        assert fast.violated == slow.violated and fast.violated
        assert str(fast).split("nearest reachable tip")[0] == str(slow).split("nearest reachable tip")[0]
    assert out >= 4                                  # the targets really test the bounded solve


@pytest.mark.parametrize("name", sorted(MODELS))
def test_nearest_point_is_optimal_by_finite_differences_of_cold_fk_solves(name):
    """Independent of both solvers: at the returned tensions the gradient of ½|p_end(T) − p_d|², by central
    differences of cold FK solves, vanishes along the free tensions and points out of the box at the bounded
    ones (first-order optimality of the nearest reachable point)."""
    m = MODELS[name]
    lo, hi = m.params.tension_min, m.params.tension_max
    targets, _ = _targets(m, 3, seed=11)
    checked = 0
    for target, F in targets:
        kind, exc = _solve(m, target, F, True)
        if kind == "ok":
            continue
        T = exc.tensions

        def tip(TT, F=F):
            return m.fk(TT, P, F, check_limits=False).tip

        def f(TT, target=target):
            r = tip(TT) - target
            return 0.5 * r @ r
        h = 1e-4
        g, jnorm = np.empty(m.m), 0.0
        for i in range(m.m):
            e = np.zeros(m.m)
            e[i] = h
            if T[i] - h < lo:                                   # one-sided at the lower bound
                g[i] = (f(T + e) - f(T)) / h
            elif T[i] + h > hi:
                g[i] = (f(T) - f(T - e)) / h
            else:
                g[i] = (f(T + e) - f(T - e)) / (2 * h)
            jnorm = max(jnorm, np.linalg.norm(tip(T + e) - tip(T)) / h)
        scale = jnorm * np.linalg.norm(exc.nearest - target)    # |J| |r|: the gradient's size away from optimum
        for i in range(m.m):
            if lo + 1e-9 < T[i] < hi - 1e-9:
                assert abs(g[i]) < 1e-3 * scale                 # one-sided FD error ~ h |J|² ≪ 1e-3 |J||r|
            elif T[i] <= lo + 1e-9:
                assert g[i] > -1e-3 * scale                     # increasing it would not get nearer
            else:
                assert g[i] < 1e-3 * scale
        checked += 1
    assert checked >= 2


def test_tip_sensitivity_is_the_finite_difference_jacobian():
    m = MODELS["four_tendon"]
    T = np.array([2.0, 0.5, 1.5, 0.0])
    F = np.array([0.0, 0.1, -0.2])
    eq = m.fk(T, P, F)
    ea, ei = m.stiffness_coefficients(P)
    ok, _, tip, J, *_ = cb.tip_sensitivity(
        m.to_free(eq.q), T, m._q_fix, m._P_c, m._P is not None, m.n, m._N, m._wq, ea, ei, P * m._vc, m._mg, m._E,
        m._d, m._co, m._so, m.params.tool_offset, m.total_tip_load(F), m.default_tol, 25)
    assert ok
    np.testing.assert_allclose(tip, eq.tip, rtol=0, atol=1e-12)
    h = 1e-5
    for i in range(m.m):
        e = np.zeros(m.m)
        e[i] = h
        fd = (m.fk(T + e, P, F).tip - m.fk(np.maximum(T - e, 0), P, F).tip) / (2 * h if T[i] > 0 else h)
        np.testing.assert_allclose(J[:, i], fd, rtol=1e-5 if T[i] > 0 else 1e-3, atol=1e-9)


@pytest.mark.parametrize("seed", range(12))
def test_box_subproblem_against_scipy_bounded_least_squares(seed):
    """cb.box_least_squares (the Gauss–Newton step over the box) against scipy.optimize.lsq_linear (TRF)
    on random problems with 3 rows and 3–6 columns, bounds around 0, some of them exactly 0."""
    rng = np.random.default_rng(seed)
    m = 3 + seed % 4
    A = rng.normal(size=(3, m)) * 10 ** rng.uniform(-3, 0)
    b = rng.normal(size=3) * 10 ** rng.uniform(-3, 0)
    lo, hi = -rng.uniform(0, 1, m), rng.uniform(0, 1, m)
    lo[rng.uniform(size=m) < 0.3] = 0.0
    hi[rng.uniform(size=m) < 0.2] = 0.0
    mu = 1e-4 * np.max(np.sum(A * A, axis=0))               # well posed, so that the minimiser is unique
    ok, x, state = cb.box_least_squares(A, b, lo, hi, mu)
    assert ok and np.all(x >= lo) and np.all(x <= hi)
    Aa = np.vstack([A, np.sqrt(mu) * np.eye(m)])                 # the same regularised problem
    ref = lsq_linear(Aa, np.concatenate([b, np.zeros(m)]), bounds=(lo, hi + 1e-300 * (hi == lo)),
                     method="trf", tol=1e-15, lsmr_tol="auto")

    def cost(v):
        return np.sum((Aa @ v - np.concatenate([b, np.zeros(m)])) ** 2)
    assert cost(x) <= cost(ref.x) * (1 + 1e-9) + 1e-30
    np.testing.assert_allclose(x, ref.x, rtol=0, atol=1e-7 * (1 + np.abs(ref.x).max()))
    assert np.all(x[state < 0] == lo[state < 0]) and np.all(x[state > 0] == hi[state > 0])


def test_a_failing_compiled_loop_falls_back_to_least_squares(monkeypatch):
    """When the compiled loop reports anything but CONVERGED the answer comes from least_squares — the same
    error as with the fast path off."""
    m = MODELS["paper"]
    targets, _ = _targets(m, 6, seed=4)
    target, F = next((t, F) for t, F in targets if _solve(m, t, F, True)[0] == "out")
    ref = _solve(m, target, F, False)[1]
    real = cb.ik_bounded
    calls = []

    def failing(*a):
        calls.append(1)
        return (cb.FAILED,) + tuple(real(*a)[1:])
    monkeypatch.setattr(cb, "ik_bounded", failing)
    kind, exc = _solve(m, target, F, True)
    assert calls and kind == "out"
    np.testing.assert_array_equal(exc.tensions, ref.tensions)
    assert exc.violated == ref.violated


def test_an_fk_that_cannot_converge_fails_the_compiled_loop():
    m = MODELS["paper"]
    ref = m.fk((2.0, 2.0, 2.0), P)
    ea, ei = m.stiffness_coefficients(P)
    status = cb.ik_bounded(np.array([5.0, 0.0, 0.0]), m.to_free(ref.q), np.zeros(3), np.full(3, 5.0),
                           ref.tip + 0.05, m._q_fix, m._P_c, m._P is not None, m.n, m._N, m._wq, ea, ei, P * m._vc,
                           m._mg, m._E, m._d, m._co, m._so, m.params.tool_offset, m.total_tip_load(np.zeros(3)),
                           m.default_tol, 1, 100, 1e-12)[0]
    assert status != cs.CONVERGED


@pytest.mark.parametrize("name", sorted(MODELS))
def test_the_state_handed_on_is_the_verified_fk_at_the_nearest_tensions(name):
    m = MODELS[name]
    targets, ref = _targets(m, 6, seed=4)
    target, F = next((t, F) for t, F in targets if _solve(m, t, F, True)[0] == "out")
    exc = _solve(m, target, F, True, q0=ref.q, tensions0=ref.tensions)[1]
    eq = exc.state
    assert eq is not None and eq.stable
    np.testing.assert_array_equal(eq.tensions, exc.tensions)
    np.testing.assert_allclose(eq.tip, exc.nearest, rtol=0, atol=1e-12)
    fk = m.fk(exc.tensions, P, F, q0=ref.q)                      # what the controller solved before
    np.testing.assert_allclose(eq.q, fk.q, rtol=0, atol=1e-9)
    np.testing.assert_allclose(eq.tendon_lengths, fk.tendon_lengths, rtol=0, atol=1e-12)
    Q = m.reduce_vec(m.residual(eq.q, eq.tensions, P, F))
    assert np.linalg.norm(Q) < m.default_tol
    # the tangent the bounded solve kept for the compliances is the one assembled at this state
    from ancf import compliance as cp
    assert m._tangent_parts(eq) is not None
    kept = (cp.tension(m, eq).C_p, cp.locked(m, eq).C_p)
    for attr in ("_compliance_parts", "_compliance_solves"):
        eq.__dict__.pop(attr, None)
    fresh = (cp.tension(m, eq).C_p, cp.locked(m, eq).C_p)
    for a, b in zip(kept, fresh, strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-12, atol=0)


def test_reachable_four_tendon_target_gives_the_same_least_total_tension():
    """Four tendons go through the bounded solve even when the target is reachable (least Σ T² by SLSQP from
    its answer): the same tensions with the compiled loop as with least_squares."""
    m = MODELS["four_tendon"]
    ref = m.fk((2.0, 1.0, 0.5, 1.5), P, (0, 0, -0.1))
    for dp in ([0.0, 1e-3, 0.0], [0.0, -2e-3, 1e-3]):
        kind_f, fast = _solve(m, ref.tip + dp, (0, 0, -0.1), True)
        kind_s, slow = _solve(m, ref.tip + dp, (0, 0, -0.1), False)
        assert kind_f == kind_s == "ok"
        np.testing.assert_allclose(fast.tensions, slow.tensions, rtol=0, atol=1e-6)
        np.testing.assert_allclose(fast.tip, ref.tip + dp, rtol=0, atol=1e-8)
