"""The compiled Newton loops (ancf.compiled_solvers) against the Python solvers they replace in the common
case: same iterates within round-off, same failures, the stability check still refuses saddles, and the
values the loops hand on (energy, lengths, the tangent kept for the compliances) equal a fresh assembly."""

import numpy as np
import pytest

from ancf import Model, StiffnessLaw, compliance as cp, presets
from ancf import compiled_solvers as cs
from ancf.errors import ConvergenceError, UnstableEquilibriumError
from ancf.solvers import minimize_newton, solve_root

MODELS = {"paper": Model(presets.paper()), "four_tendon": Model(presets.four_tendon()),
          "free_base": Model(presets.paper().replace(n_elements=3, free_base_stretch=True)),
          # a pressure-dependent law: the compiled loops get the law at the solve's pressure
          "pressure_law": Model(presets.paper().replace(
              stiffness=presets.paper().stiffness.with_pressure(EA=(0.3,), EI=(0.9, -0.25))))}
LOADS = [((0, 0, 0), 0.0, (0, 0, -0.3)), ((3.0, 0.5, 1.0), 40e3, (0, 0.2, -0.2)), ((1.0, 1.0, 1.0), 90e3, (0, 0, 0))]


def _T(m, T):
    return np.resize(np.asarray(T, float), m.m)


@pytest.mark.parametrize("name", sorted(MODELS))
@pytest.mark.parametrize("load", LOADS)
def test_compiled_fk_newton_follows_the_python_newton(name, load):
    m = MODELS[name]
    T, p, F = _T(m, load[0]), load[1], np.asarray(load[2], float)
    z0 = m.to_free(m.q_ref)
    z_c, info_c = m._fk_newton(z0, T, p, F, m.default_tol, 25)
    z_p, info_p = minimize_newton(m._fk_fun(T, p, F), z0, tol=m.default_tol, max_iter=25)
    assert info_c.iterations == info_p.iterations
    np.testing.assert_allclose(info_c.history, info_p.history, rtol=1e-6, atol=10 * m.default_tol)
    np.testing.assert_allclose(z_c, z_p, rtol=0, atol=1e-12)
    np.testing.assert_allclose(info_c.matrix, info_p.matrix, rtol=1e-9, atol=1e-9 * np.abs(info_p.matrix).max())
    # the energy and lengths it hands on are the assembly's at the solution
    ev = m.evaluate(m.to_full(z_c), T, p, F, hessian=False, lengths=True)
    energy, lengths = info_c.values
    assert energy == pytest.approx(ev.energy, rel=1e-12, abs=1e-15)
    np.testing.assert_allclose(lengths, ev.lengths, rtol=1e-14, atol=1e-15)
    assert info_c.positive_definite is True


def test_compiled_fk_fails_like_the_python_newton():
    m = MODELS["paper"]
    T, F = np.array([4.0, 0.0, 0.0]), np.zeros(3)
    z0 = m.to_free(m.q_ref)
    with pytest.raises(ConvergenceError) as c:
        m._fk_newton(z0, T, 100e3, F, m.default_tol, 2)
    with pytest.raises(ConvergenceError) as p:
        minimize_newton(m._fk_fun(T, 100e3, F), z0, tol=m.default_tol, max_iter=2)
    assert c.value.iterations == p.value.iterations == 2
    np.testing.assert_allclose(c.value.history, p.value.history, rtol=1e-9)
    bad = z0.copy()
    bad[:] = 0.0                                          # every slope zero: inadmissible start
    with pytest.raises(ConvergenceError, match="inadmissible"):
        m._fk_newton(bad, T, 0.0, F, m.default_tol, 25)


@pytest.mark.parametrize("name", ["paper", "free_base", "pressure_law"])
def test_compiled_ik_newton_follows_the_python_newton(name):
    m = MODELS[name]
    ref = m.fk((2.0, 0.5, 1.0), 30e3, (0, 0, -0.2))
    pd = ref.tip + np.array([0.0, 2e-3, -1e-3])
    nz = m.nz
    w = np.concatenate([np.ones(nz), np.full(3, m._kscale)])
    tol = min(m.default_tol, m._kscale * 1e-9)
    x0 = np.concatenate([m.to_free(ref.q), ref.tensions])
    F = m.total_tip_load(np.array([0, 0, -0.2]))
    status, x, it, hist, J, pdef, energy, lengths = cs.ik_newton(
        x0, nz, pd, w, m._q_fix, m._P_c, m._P is not None, m.n, m._N, m._wq, *m.stiffness_coefficients(30e3),
        30e3 * m._vc, m._mg,
        m._E, m._d, m._co, m._so, m.params.tool_offset, F, tol, 60)
    assert status == cs.CONVERGED and pdef

    def fun(xx):
        q = m.to_full(xx[:nz])
        ev = m.evaluate(q, xx[nz:], 30e3, (0, 0, -0.2))
        R = np.concatenate([m.reduce_vec(ev.Q), m.tip(q) - pd])
        Jp = np.zeros((nz + 3, nz + m.m))
        Jp[:nz, :nz] = m.reduce_mat(ev.K)
        Jp[:nz, nz:] = m.reduce_vec(ev.J_l).T
        Jp[nz:, :nz] = m.reduce_vec(m.tip_jacobian(q))
        return R, Jp
    xp, info = solve_root(fun, x0, tol=tol, max_iter=60, weights=w)
    assert it == info.iterations
    np.testing.assert_allclose(x, xp, rtol=0, atol=1e-11)
    np.testing.assert_allclose(J, info.matrix, rtol=1e-9, atol=1e-9 * np.abs(info.matrix).max())


@pytest.mark.parametrize("name", ["paper", "pressure_law"])
def test_the_tangent_the_ik_hands_to_the_compliances_is_the_assembled_one(name):
    m = MODELS[name]
    ref = m.fk((2.0, 0.5, 1.0), 30e3, (0, 0, -0.2))
    eq = m.ik(ref.tip + 1e-4, 30e3, (0, 0, -0.2), q0=ref.q, tensions0=ref.tensions)
    assert m._tangent_parts(eq) is not None                  # kept by the compiled IK
    kept = (cp.tension(m, eq).C_p, cp.locked(m, eq).C_p, cp.locked(m, eq, method="ik").C_p)
    for attr in ("_compliance_parts", "_compliance_solves"):
        eq.__dict__.pop(attr, None)
    fresh = (cp.tension(m, eq).C_p, cp.locked(m, eq).C_p, cp.locked(m, eq, method="ik").C_p)
    for a, b in zip(kept, fresh):
        np.testing.assert_allclose(a, b, rtol=1e-10, atol=0)
    eq.tensions = eq.tensions + 0.1                           # another state: the kept parts no longer apply
    assert m._tangent_parts(eq) is None


def test_buckled_column_still_raises_through_the_compiled_loop():
    EI, L = 0.0839, 0.16
    m = Model(presets.paper().replace(stiffness=StiffnessLaw.constant(EA=767.2, EI=EI), line_mass=0.0,
                                      tip_mass=0.0, tool_offset=0.0, n_elements=6))
    P = 1.2 * np.pi ** 2 * EI / (4 * L ** 2)
    _, info = m._fk_newton(m.to_free(m.q_ref), np.zeros(3), 0.0, np.array([-P, 0, 0]), m.default_tol, 25)
    assert info.positive_definite is False                   # the straight branch: a saddle
    with pytest.raises(UnstableEquilibriumError):
        m.fk((0, 0, 0), 0.0, (-P, 0, 0), check_limits=False)


@pytest.mark.parametrize("name", ["paper", "four_tendon"])
def test_slack_tendon_lengths_from_the_shared_terms_equal_each_tendons_own(name):
    """Three or more slack tendons take their densities from two evaluations per point
    (forces.tendon.slack_terms); the gradient path still evaluates each tendon: the lengths must agree."""
    m = MODELS[name]
    rng = np.random.default_rng(1)
    for _ in range(5):
        eq = m.fk(rng.uniform(0, 4, m.m), rng.uniform(0, 100e3), rng.normal(0, 0.3, 3))
        shared = m.evaluate(eq.q, None, 0.0, hessian=False, lengths="values").lengths
        own = m.evaluate(eq.q, None, 0.0, hessian=False, lengths=True).lengths
        np.testing.assert_allclose(shared, own, rtol=1e-14, atol=0)
        np.testing.assert_allclose(eq.tendon_lengths, own, rtol=1e-14, atol=0)


def test_the_compiled_solvers_release_the_gil():
    """A long FK/IK solve must not stall the other threads of the process (a rig's CANopen callbacks, its run
    log writer): the compiled Newton loops run with the GIL released (``nogil=True``).  A thread that ticks every
    0.5 ms keeps ticking during a solve of tens of milliseconds; with the GIL held its longest gap is the solve."""
    import threading
    import time
    m = Model(presets.paper().replace(n_elements=64))
    m.fk((1.0, 0.0, 0.0), 30e3)                                 # compiled
    loads = [((4.0 - 0.3 * k, 0.2 * k, 0.0), 100e3, (0.0, 0.0, -0.5)) for k in range(4)]     # each a cold solve
    ticks, stop = [], threading.Event()

    def tick():
        while not stop.is_set():
            ticks.append(time.perf_counter())
            time.sleep(0.0005)
    t = threading.Thread(target=tick, daemon=True)
    t.start()
    time.sleep(0.02)
    spans = []
    for T, p, F in loads:
        t0 = time.perf_counter()
        m.fk(T, p, F)
        spans.append((t0, time.perf_counter()))
    stop.set()
    t.join()
    tt = np.array(ticks)
    t0, t1 = max(spans, key=lambda s: s[1] - s[0])             # the longest solve
    inside = tt[(tt > t0) & (tt < t1)]
    longest = np.diff(np.concatenate([[t0], inside, [t1]])).max()
    assert t1 - t0 > 0.015 and longest < 0.5 * (t1 - t0), (t1 - t0, longest)
