"""Property-based contract of the public API (hypothesis): random and adversarial inputs to FK, IK, locked
FK, the compliance forms and FEM load cases give either a result that passes its own verification —
residual below tolerance (recomputed independently), a stable equilibrium, inside the law's validity range,
the complementarity of the locked tendons — or a :class:`BellowsError` subclass.  Never another exception,
never a hang (each case runs under a wall-clock guard), never a crash of the interpreter (the kernels only
see checked arrays).

Budgets: ``max_examples`` are bounded per test so that the whole file runs in about a minute on 2 cores.
"""

from __future__ import annotations

import contextlib
import signal

import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from ancf import Model, presets
from ancf import compliance as cp
from ancf.errors import BellowsError, InfeasibleTargetError, InputError

SETTINGS = dict(deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
                derandomize=True)
CASE_SECONDS = 60          # a case that takes longer is a hang


class Hang(Exception):
    pass


@contextlib.contextmanager
def bounded(seconds=CASE_SECONDS):
    """Fail the case (``Hang``) if it runs longer than ``seconds`` of wall-clock time."""
    def on_alarm(signum, frame):
        raise Hang(f"case did not finish within {seconds} s")
    old = signal.signal(signal.SIGALRM, on_alarm)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


def contract(call):
    """Run ``call`` under the guard; return its result, or None if it raised a BellowsError."""
    with bounded():
        try:
            out = call()
        except BellowsError as exc:
            event(f"typed error {type(exc).__name__}")
            return None
    event("verified result")
    return out


MODELS = {"paper": Model(presets.paper()), "four_tendon": Model(presets.four_tendon()),
          "coarse": Model(presets.paper().replace(n_elements=2, free_base_stretch=True)),
          "elastic_tendons": Model(presets.paper().replace(tendon_stiffness=310.0))}


def verify_equilibrium(m: Model, eq):
    """Independent verification of a returned equilibrium."""
    Q = m.reduce_vec(m.residual(eq.q, eq.tensions, eq.pressure, eq.tip_force))
    assert np.linalg.norm(Q) < 10 * m.default_tol
    lo, hi = m.params.stiffness.valid_stretch_range
    lam = m.stretches(eq.q)
    assert lo < lam.min() and lam.max() < hi
    # stability from central differences of the residual (the gradient), not the analytic tangent the solver
    # used, and tendon-length gradients from differences of the lengths
    z, h = m.to_free(eq.q), 1e-6
    E = np.eye(len(z)) * h
    grad = lambda zz: m.reduce_vec(m.residual(m.to_full(zz), eq.tensions, eq.pressure, eq.tip_force))
    H = np.array([(grad(z + e) - grad(z - e)) / (2 * h) for e in E])
    H = 0.5 * (H + H.T)
    if eq.active:
        A = list(eq.active)
        JA = np.array([(m.tendon_lengths(m.to_full(z + e))[A] - m.tendon_lengths(m.to_full(z - e))[A]) / (2 * h)
                       for e in E]).T
        if m.params.tendon_stiffness:        # elastic tendons: their energy ½ k_s (l − l₀)² adds k_s ∇l ∇lᵀ
            H = H + m.params.tendon_stiffness * JA.T @ JA
        else:                                # rigid: positive definite on the tangent space of the taut ones
            Z = np.linalg.qr(JA.T, mode="complete")[0][:, len(A):]
            H = Z.T @ H @ Z
    lam_fd, scale = np.linalg.eigvalsh(H)[0], np.abs(H).max()
    assert eq.stable and lam_fd > -1e-6 * scale
    assert abs(eq.min_eigenvalue - lam_fd) < 1e-3 * abs(lam_fd) + 1e-6 * scale
    assert np.allclose(eq.tip, m.tip(eq.q))


models = st.sampled_from(sorted(MODELS))
loads = st.tuples(st.floats(-1.0, 8.0), st.floats(-20e3, 200e3),
                  st.lists(st.floats(-4.0, 4.0), min_size=3, max_size=3))


@settings(max_examples=40, **SETTINGS)
@given(models, loads, st.booleans(), st.booleans())
def test_fk_contract(name, load, check_limits, warm):
    m = MODELS[name]
    t_scale, p, F = load
    T = np.abs(np.sin(np.arange(1, m.m + 1) * t_scale)) * t_scale       # mixed tensions, some < 0 if t < 0
    q0 = m.droop(0.0).q if warm else None
    eq = contract(lambda: m.fk(T, p, F, q0=q0, check_limits=check_limits))
    if eq is not None:
        verify_equilibrium(m, eq)
        if check_limits:
            assert np.all(T >= m.params.tension_min) and np.all(T <= m.params.tension_max)


@settings(max_examples=25, **SETTINGS)
@given(models, st.lists(st.floats(-0.06, 0.06), min_size=3, max_size=3), st.floats(0.0, 120e3))
def test_ik_contract(name, offset, p):
    m = MODELS[name]
    target = m.droop(0.0).tip + np.asarray(offset) + np.array([0.01, 0, 0])
    try:
        with bounded():
            eq = m.ik(target, p)
    except InfeasibleTargetError as exc:
        assert exc.nearest is not None and exc.violated        # says which bound and where it could reach
        return
    except BellowsError:
        return
    verify_equilibrium(m, eq)
    assert np.linalg.norm(eq.tip - target) < 1e-6
    assert np.all(eq.tensions >= m.params.tension_min - 1e-12) and np.all(eq.tensions <= m.params.tension_max + 1e-12)


@settings(max_examples=30, **SETTINGS)
@given(models, st.lists(st.floats(0.55, 1.15), min_size=4, max_size=4), st.floats(0.0, 120e3),
       st.lists(st.floats(-2.0, 2.0), min_size=3, max_size=3), st.sampled_from(["active_set", "gamma"]))
def test_locked_fk_contract(name, ratios, p, F, method):
    m = MODELS[name]
    l0 = m.tendon_lengths(m.q_ref) * np.asarray(ratios[:m.m])
    eq = contract(lambda: m.fk_locked(l0, p, F, method=method))
    if eq is None:
        return
    verify_equilibrium(m, eq)
    tol = 1e-8
    assert np.all(eq.tensions >= 0) and np.all(eq.slack >= 0)
    assert np.all(eq.tensions * eq.slack <= tol * np.maximum(1.0, eq.tensions))      # complementarity
    ks = m.params.tendon_stiffness                # elastic tendons: l − T/k_s + slack = l₀
    assert np.allclose(eq.tendon_lengths - (eq.tensions / ks if ks else 0.0) + eq.slack, l0, atol=1e-8)
    assert set(eq.active) == {i for i in range(m.m) if eq.tensions[i] > 0} | set(eq.active)


@settings(max_examples=15, **SETTINGS)
@given(models, loads)
def test_compliance_contract(name, load):
    """Tension-mode compliance is symmetric positive definite at a stable state; locking tendons can only
    stiffen the tip (C_tension − C_locked is positive semi-definite)."""
    m = MODELS[name]
    t_scale, p, F = load
    eq = contract(lambda: m.fk(np.abs(np.cos(np.arange(m.m) + t_scale)) * abs(t_scale), abs(p), F,
                               check_limits=False))
    if eq is None:
        return
    with bounded():
        Ct = cp.tension(m, eq).C_p
        Cl = contract(lambda: cp.locked(m, eq, "exact", active=tuple(range(m.m))))
    assert np.allclose(Ct, Ct.T, atol=1e-9 * np.abs(Ct).max())
    assert np.linalg.eigvalsh(Ct)[0] > 0
    if Cl is not None:
        D = Ct - Cl.C_p
        assert np.linalg.eigvalsh(0.5 * (D + D.T))[0] > -1e-9 * np.abs(Ct).max()


# ------------------------------------------------------------------------------------------ adversarial
adversarial_arrays = st.one_of(
    hnp.arrays(st.sampled_from([np.float64, np.float32, np.int64, np.bool_, np.complex128]),
               hnp.array_shapes(min_dims=0, max_dims=2, max_side=8),
               elements=None),
    st.lists(st.one_of(st.floats(), st.text(max_size=3), st.none()), max_size=6),
    st.text(max_size=5), st.just(None), st.floats(), st.integers(-10**20, 10**20))


@settings(max_examples=150, **SETTINGS)
@given(st.sampled_from(["q", "tensions", "pressure", "tip_force", "target", "lengths", "q0"]),
       adversarial_arrays)
def test_adversarial_arguments_give_input_errors_or_valid_results(which, value):
    """Any value in any argument slot: InputError (or another BellowsError), never TypeError, ValueError,
    ZeroDivisionError, a hang or garbage from a kernel."""
    m = MODELS["paper"]
    calls = {
        "q": lambda v: m.evaluate(v),
        "tensions": lambda v: m.fk(v, 0.0),
        "pressure": lambda v: m.fk((0.5, 0, 0), v),
        "tip_force": lambda v: m.fk((0.5, 0, 0), 0.0, v),
        "target": lambda v: m.ik(v, 0.0),
        "lengths": lambda v: m.fk_locked(v, 0.0),
        "q0": lambda v: m.fk((0.5, 0, 0), 0.0, q0=v),
    }
    try:
        with bounded():
            out = calls[which](value)
    except BellowsError:
        return
    # accepted: it was a valid value, and the result is verified
    if which == "q":
        assert np.isfinite(out.energy) and np.all(np.isfinite(out.Q))
    else:
        verify_equilibrium(m, out)


@settings(max_examples=40, **SETTINGS)
@given(st.sampled_from(["tensions", "pressure", "tip_force", "locked_lengths", "gravity"]), adversarial_arrays)
def test_fem_load_cases_reject_bad_values_before_solving(fem_tiny, which, value):
    """FEM load cases: a bad value in any slot is an InputError before any load step."""
    # the values are the point here: a valid one runs at most one short load step, unchecked for stability
    kwargs = {which: value, "check_limits": True, "max_steps": 1, "time_limit_s": 5.0, "check_stability": False}
    try:
        with bounded():
            fem_tiny.solve(**kwargs)
    except BellowsError:
        return


@settings(max_examples=3, **SETTINGS)
@given(st.floats(0.0, 0.3), st.floats(0.0, 10e3))
def test_fem_small_loads_converge_and_verify(fem_tiny, T1, p):
    with bounded(120):
        res = fem_tiny.solve(tensions=(T1, 0.0, 0.0), pressure=p)
    ev = fem_tiny.evaluate(res.state, res.loadcase, tangent=False)
    assert np.linalg.norm(ev["r"]) <= max(1e-9, 1e-9 * ev["f_ref"]) * 10
    assert np.all(np.isfinite(res.tip_position))


@pytest.fixture(scope="module")
def fem_tiny():
    from fem_reference import BellowsGeometry, BellowsModel, Material, MeshLevel
    return BellowsModel(BellowsGeometry.straight_tube(0.08, 0.015, 0.004, n_segments=2),
                        Material.neo_hookean(0.8e6, 40e6), MeshLevel(2, 1, 12, 1))


def test_input_errors_are_value_errors_for_generic_handlers():
    """The tree keeps builtin bases so generic handlers still work (documented in docs/errors.md)."""
    assert issubclass(InputError, ValueError) and issubclass(InputError, BellowsError)
