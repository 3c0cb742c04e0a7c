"""The exact motor-length Jacobian of the locked friction step (ancf.friction.locked_length_jacobian) and the
Newton IK with friction built on it (controller.friction_aware.friction_ik).

The Jacobian is checked against finite differences of ``fk_locked_history`` itself: at μ = 0 central differences
of the smooth frictionless locked FK (``Model.fk_locked``); at μ > 0 one-sided second-order differences in a
direction that keeps the step's stick/slip pattern (the step's own motor motion continued; the test asserts the
pattern is kept, else the difference quotient would measure another branch).
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from ancf import Model, presets
from ancf import friction as fr
from ancf.errors import InputError
from controller.friction_aware import friction_ik

P = 20e3
F = np.array([0.0, 0.0, -0.05])


def _step(mu: float, move, stiffness=None):
    """(model, S, l_S, the state after moving the motors by ``move`` (m,) [m] from S)."""
    m = Model(presets.paper().replace(tendon_friction=mu, tendon_stiffness=stiffness))
    S = fr.fk_locked_history(m, m.fk_history([3.0, 1.0, 0.5], P), None, P, (0.0, 0.0, 0.0))
    l_S = S.locked_lengths
    return m, S, l_S, fr.fk_locked_history(m, S, l_S + np.asarray(move, float), P, F)


def _one_sided(f, x0, d, e):
    """Second-order one-sided difference of f along d from x0 (steps e, 2e): (−3 f0 + 4 f1 − f2) / (2e)."""
    f0, f1, f2 = f(x0), f(x0 + e * d), f(x0 + 2 * e * d)
    return (-3 * f0 + 4 * f1 - f2) / (2 * e)


def test_mu0_is_the_derivative_of_the_frictionless_locked_fk():
    """μ = 0: ∂tip/∂l and ∂T/∂l equal central differences of Model.fk_locked (a different solver and path)."""
    m, S, l_S, st = _step(0.0, [-0.4e-3, 0.2e-3, 0.1e-3])
    Jl, dT = fr.locked_length_jacobian(m, st)
    l = l_S + np.array([-0.4e-3, 0.2e-3, 0.1e-3])
    h = 1e-6
    for j in range(m.m):
        dl = np.zeros(m.m)
        dl[j] = h
        a, b = m.fk_locked(l + dl, P, F, q0=st.q), m.fk_locked(l - dl, P, F, q0=st.q)
        np.testing.assert_allclose(Jl[:, j], (a.tip - b.tip) / (2 * h), rtol=1e-5, atol=1e-9)
        np.testing.assert_allclose(dT[:, j], (a.tensions - b.tensions) / (2 * h), rtol=1e-5, atol=1e-3)


@pytest.mark.parametrize("stiffness", [None, 2e4])
@pytest.mark.parametrize("move", [[-1e-3, 0.4e-3, 0.2e-3],          # every guide slipping
                                  [0.05e-3, 0.0, 0.0],              # stuck guides on tendons 2 and 3
                                  [0.05e-3, -0.02e-3, 0.01e-3]])
def test_friction_jacobian_against_one_sided_differences(move, stiffness):
    """μ = 0.3: J d equals the one-sided difference of the step's tip (and motor tensions) along the motion d it
    made, the pattern held along the difference's steps."""
    m, S, l_S, st = _step(0.3, move, stiffness)
    d = np.asarray(move, float)
    states = {}

    def f(x):
        s = fr.fk_locked_history(m, S, x, P, F)
        states[float(np.linalg.norm(x - l_S))] = s
        return np.concatenate([s.tip, s.motor_tensions])
    fd = _one_sided(f, l_S + d, d, 1e-3)
    for s in states.values():          # the difference stayed on the step's branch
        assert np.array_equal(s.sliding, st.sliding) and s.equilibrium.active == st.equilibrium.active
    Jl, dT = fr.locked_length_jacobian(m, st)
    np.testing.assert_allclose(Jl @ d, fd[:3], rtol=1e-6, atol=1e-12)
    np.testing.assert_allclose(dT @ d, fd[3:], rtol=1e-5, atol=1e-9)
    if abs(move[0]) < 1e-3:
        assert np.any(st.sliding == 0)            # the mixed cases do have stuck guides


@settings(max_examples=8, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.floats(-0.5e-3, 0.5e-3), min_size=3, max_size=3).filter(lambda v: max(map(abs, v)) > 1e-5))
def test_friction_jacobian_property(move):
    """Any motor move d from a friction state: where continuing d keeps the step's pattern, J d is the one-sided
    difference of the step along d."""
    m, S, l_S, st_ = _step(0.3, move)
    d = np.asarray(move, float)
    e = 1e-3
    s1, s2 = (fr.fk_locked_history(m, S, l_S + (1 + k * e) * d, P, F) for k in (1, 2))
    assume(all(np.array_equal(s.sliding, st_.sliding) and s.equilibrium.active == st_.equilibrium.active
               for s in (s1, s2)))
    fd = (-3 * st_.tip + 4 * s1.tip - s2.tip) / (2 * e)
    np.testing.assert_allclose(fr.locked_length_jacobian(m, st_)[0] @ d, fd, rtol=1e-5, atol=1e-12)


def test_jacobian_re_evaluated_without_the_kept_tangent_is_the_same():
    """A state that lost the solve's kept tangent (e.g. copied) gives the same Jacobian from its own data."""
    m, _S, _l, st = _step(0.3, [0.05e-3, -0.02e-3, 0.01e-3])
    J1 = fr.locked_length_jacobian(m, st)
    st.equilibrium.__dict__.pop("_locked_friction")
    J2 = fr.locked_length_jacobian(m, st)
    np.testing.assert_allclose(J2[0], J1[0], rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(J2[1], J1[1], rtol=1e-12, atol=1e-12)


def test_jacobian_refuses_a_state_without_locked_lengths():
    m = Model(presets.paper().replace(tendon_friction=0.3))
    with pytest.raises(InputError, match="fk_locked_history"):
        fr.locked_length_jacobian(m, m.fk_history([3.0, 1.0, 0.5], P))
    with pytest.raises(InputError):
        fr.locked_length_jacobian(m, None)


def test_newton_ik_converges_in_few_locked_solves():
    """The IK with friction reaches 0.1 µm in at most 3 locked friction solves on cases where Broyden's steps
    (with the frictionless ∂tip/∂l as first Jacobian) needed up to 8, and its tip is the locked step's."""
    free = Model(presets.paper())
    fric = Model(presets.paper().replace(tendon_friction=0.3))
    prev = fric.fk_history((2.0, 0.5, 0.0), 30e3)
    target = free.fk((2.05, 0.52, 0.0), 30e3).tip
    lengths, st, _eq, its = friction_ik(fric, free, prev, target, 30e3, np.zeros(3), tol=1e-7)
    assert its <= 3
    assert np.linalg.norm(fr.fk_locked_history(fric, prev, lengths, 30e3, np.zeros(3)).tip - target) < 1e-7
    s2 = fric.fk_history((3.0, 1.0, 1.0), 30e3, (0, 0, -0.2))
    target2 = free.fk((2.5, 1.3, 1.2), 30e3, (0, 0, -0.3)).tip
    _l, st2, _e, its2 = friction_ik(fric, free, s2, target2, 30e3, (0, 0, -0.3), tol=1e-7)
    assert its2 <= 3 and np.linalg.norm(st2.tip - target2) < 1e-7
