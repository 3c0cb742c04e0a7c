"""The tendon density's scalar form w = √(A² + B²) (ancf.forces._tendon_codegen) against the vector form
|a + d (∂g/∂a) b| it replaces for the derivatives, its gradient and Hessian against finite differences of that
independent value, the allocation-free kernels against the allocating ones, and the compiled step's kinetic
energy against ½ q̇ᵀ (M0 + m Jᵀ J) q̇ formed as a matrix."""

import numpy as np
from conftest import rotation
from hypothesis import given, settings
from hypothesis import strategies as st

from ancf.compiled_solvers import tip_jacobian
from ancf.dynamics import compiled_step as cs
from ancf.forces.tendon import (
    add_tendon,
    add_tendon_ws,
    tendon_density,
    tendon_length_density,
    tendon_length_gradient,
    tendon_work,
)

D = 0.0275


def _state(rng, E):
    a = E @ (np.array([0.97, 0.0, 0.0]) + rng.normal(size=3) * 0.25)
    b = E @ (rng.normal(size=3) * 4.0)
    return a, b


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2 ** 31 - 1), theta=st.floats(0.0, 2 * np.pi))
def test_scalar_form_matches_vector_form(seed, theta):
    """w of the scalar form (tendon_density, tendon_length_gradient) equals the vector form's |u|
    (tendon_length_density, generated separately) to round-off, in a rotated actuator frame."""
    rng = np.random.default_rng(seed)
    E = rotation(rng.normal(size=3), rng.uniform(0, np.pi))
    a, b = _state(rng, E)
    co, so = np.cos(theta), np.sin(theta)
    ref = tendon_length_density(a, b, E, D, co, so)
    w, _, _ = tendon_density(a, b, E, D, co, so)
    w2, _ = tendon_length_gradient(a, b, E, D, co, so)
    assert abs(w - ref) <= 1e-14 * ref and abs(w2 - ref) <= 1e-14 * ref


def test_scalar_form_derivatives_against_vector_form_differences():
    """Gradient: central differences of the vector form's value; Hessian: of the vector form's value twice
    (second differences), so no derivative of the scalar form is checked against itself."""
    rng = np.random.default_rng(11)
    E = rotation([0.2, 0.7, -0.4], 1.1)
    h = 1e-4
    for theta in (0.0, 1.3, 3.9):
        co, so = np.cos(theta), np.sin(theta)
        a, b = _state(rng, E)
        x = np.concatenate([a, b])
        def f(y, co=co, so=so):
            return tendon_length_density(y[:3], y[3:], E, D, co, so)
        _, g, H = tendon_density(a, b, E, D, co, so)
        I6 = np.eye(6)
        g_fd = np.array([(f(x + 1e-6 * I6[i]) - f(x - 1e-6 * I6[i])) / 2e-6 for i in range(6)])
        H_fd = np.array([[(f(x + h * (I6[i] + I6[j])) - f(x + h * (I6[i] - I6[j])) - f(x - h * (I6[i] - I6[j]))
                           + f(x - h * (I6[i] + I6[j]))) / (4 * h * h) for j in range(6)] for i in range(6)])
        assert np.allclose(g, g_fd, rtol=1e-7, atol=1e-8)
        assert np.allclose(H, H_fd, rtol=1e-5, atol=1e-5 * np.abs(H).max())
        assert np.abs(H - H.T).max() <= 1e-14 * np.abs(H).max()


def test_work_arrays_change_nothing():
    """add_tendon_ws with one set of work arrays reused over many calls gives add_tendon's sums exactly, and
    nothing is added outside the domain (a = 0)."""
    rng = np.random.default_rng(5)
    E = rotation([0.3, -0.5, 0.8], 0.9)
    ws = tendon_work()
    out = [[np.zeros(9), np.zeros((9, 9)), np.zeros(9)] for _ in range(2)]
    for k in range(20):
        a, b = _state(rng, E)
        th = rng.uniform(0, 2 * np.pi)
        args = (a, b, E, D, np.cos(th), np.sin(th), 1.5 + k, 0.01)
        w1 = add_tendon(*args, *out[0], k % 3 != 0)
        w2 = add_tendon_ws(*args, *out[1], k % 3 != 0, ws)
        assert w1 == w2
    for x, y in zip(*out):
        assert np.array_equal(x, y)
    g, H, gl = np.zeros(9), np.zeros((9, 9)), np.zeros(9)
    w = add_tendon_ws(np.zeros(3), np.ones(3), E, D, 1.0, 0.0, 2.0, 0.01, g, H, gl, True, ws)
    assert np.isnan(w) and not g.any() and not H.any() and not gl.any()


def test_kinetic_energy_without_the_matrix():
    rng = np.random.default_rng(2)
    n = 42
    A = rng.normal(size=(n, n))
    M0 = A @ A.T
    q = np.concatenate([rng.normal(size=n - 3), [0.9, 0.1, -0.2]])
    vq = rng.normal(size=n)
    par = np.zeros(cs.N_PAR)
    par[cs.P_MTIP], par[cs.P_HTOOL] = 0.02, 0.015
    Jp = tip_jacobian(q, 0.015)
    ref = 0.5 * vq @ (M0 + 0.02 * Jp.T @ Jp) @ vq
    assert abs(cs._kinetic(q, vq, M0, par) - ref) <= 1e-13 * abs(ref)
    par[cs.P_MTIP] = 0.0
    assert abs(cs._kinetic(q, vq, M0, par) - 0.5 * vq @ M0 @ vq) <= 1e-13 * abs(ref)
