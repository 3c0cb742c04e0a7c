"""Every analytic derivative against central finite differences.

Densities (9-vector gradients and 9×9 Hessians per generalized force), the assembled Q = ∂Π/∂q and
∂Q/∂q, ∂Q/∂T, ∂Q/∂p, ∂Q/∂F, tendon-length and arc-length gradients, tip position and orientation
Jacobians — at a generic loaded 3-D state, with both stiffness laws and a rotated actuator frame.
"""

import numpy as np
import pytest

from ancf import Model, StiffnessLaw, presets
from ancf import kinematics as kin
from ancf.forces.axial import add_axial
from ancf.forces.bending import add_bending
from ancf.forces.pressure import add_pressure
from ancf.forces.tendon import tendon_density
from conftest import rotation

RNG = np.random.default_rng(7)


def fd_grad(f, x, h=1e-6):
    g = np.zeros_like(x)
    for i in range(x.size):
        e = np.zeros_like(x)
        e[i] = h
        g[i] = (f(x + e) - f(x - e)) / (2 * h)
    return g


def fd_jac(f, x, h=1e-6):
    cols = []
    for i in range(x.size):
        e = np.zeros_like(x)
        e[i] = h
        cols.append((np.asarray(f(x + e)) - np.asarray(f(x - e))) / (2 * h))
    return np.array(cols).T


def density(fn, x):
    g = np.zeros(9)
    H = np.zeros((9, 9))
    e = fn(x, g, H)
    return e, g, H


def random_point():
    r = RNG.normal(size=3) * 0.05
    a = np.array([0.95, 0.1, -0.2]) + RNG.normal(size=3) * 0.05
    b = RNG.normal(size=3) * 2.0
    return np.concatenate([r, a, b])


LAWS = [StiffnessLaw.linear(a=1336.0, b=-568.8, D_a=0.02959), StiffnessLaw.constant(EA=767.2, EI=0.0839)]


@pytest.mark.parametrize("law", LAWS, ids=["linear", "constant"])
@pytest.mark.parametrize("which", ["axial", "bending", "pressure"])
def test_density_derivatives(law, which):
    fns = {
        "axial": lambda x, g, H: add_axial(x[3:6], law.ea, 1.0, g, H),
        "bending": lambda x, g, H: add_bending(x[3:6], x[6:9], law.ei, 1.0, g, H),
        "pressure": lambda x, g, H: add_pressure(x[3:6], np.array([16.0]), 1.0, g, H),
        "pressure_area_law": lambda x, g, H: add_pressure(x[3:6], np.array([12.0, 5.0, -1.5]), 1.0, g, H),
    }
    fn = fns[which]
    for _ in range(3):
        x = random_point()
        e, g, H = density(fn, x)
        g_fd = fd_grad(lambda y: density(fn, y)[0], x, 1e-6)
        H_fd = fd_jac(lambda y: density(fn, y)[1], x, 1e-6)
        scale = max(np.abs(g).max(), 1e-12)
        assert np.allclose(g, g_fd, atol=1e-7 * scale, rtol=1e-6)
        assert np.allclose(H, H_fd, atol=1e-6 * max(np.abs(H).max(), 1e-12), rtol=1e-5)
        assert np.allclose(H, H.T, atol=1e-12 * max(np.abs(H).max(), 1))


def test_axial_energy_matches_law():
    law = LAWS[0]
    for lam in (0.9, 1.0, 1.07):
        a = np.array([lam, 0.0, 0.0])
        e, g, H = density(lambda x, g, H: add_axial(x[3:6], law.ea, 1.0, g, H), np.concatenate([np.zeros(3), a, np.zeros(3)]))
        assert e == pytest.approx(float(law.axial_energy(lam)), abs=1e-12)
        assert g[3] == pytest.approx(float(law.axial_force(lam)), abs=1e-10)


def test_bending_density_is_half_EI_kappa_squared():
    law = LAWS[0]
    x = random_point()
    a, b = x[3:6], x[6:9]
    lam = np.linalg.norm(a)
    kappa = np.linalg.norm(np.cross(a, b)) / lam ** 3
    e, _, _ = density(lambda y, g, H: add_bending(y[3:6], y[6:9], law.ei, 1.0, g, H), x)
    assert e == pytest.approx(0.5 * float(law.EI(lam)) * kappa ** 2, rel=1e-12)


@pytest.mark.parametrize("theta", [0.0, 2.1, 4.2, 0.7])
def test_tendon_density_derivatives(theta):
    E = rotation([0.3, -0.5, 0.8], 0.9)       # a rotated actuator frame
    d = 0.0275
    for _ in range(3):
        a = E @ (np.array([0.97, 0.15, -0.1]) + RNG.normal(size=3) * 0.05)
        b = E @ (RNG.normal(size=3) * 3.0)
        x = np.concatenate([a, b])
        f = lambda y: tendon_density(y[:3], y[3:], E, d, np.cos(theta), np.sin(theta))
        w, g, H = f(x)
        assert np.allclose(g, fd_grad(lambda y: f(y)[0], x), atol=1e-8, rtol=1e-6)
        assert np.allclose(H, fd_jac(lambda y: f(y)[1], x), atol=1e-6, rtol=1e-5)
        assert np.allclose(H, H.T, atol=1e-10)


def test_tendon_density_geometry():
    """Straight actuator: density = |r_x|.  Planar arc bent towards the tendon: λ (1 − d κ); a tendon in
    the neutral plane keeps λ."""
    E = presets.paper().frame          # e1 = +x, θ = 0 towards +z
    d = 0.0275
    w, _, _ = tendon_density(np.array([1.02, 0, 0]), np.zeros(3), E, d, 1.0, 0.0)
    assert w == pytest.approx(1.02)
    lam, kappa = 0.98, 2.0                 # in-plane (x–z) bend toward +z where the θ = 0 tendon runs
    a = np.array([lam, 0.0, 0.0])
    b = np.array([0.0, 0.0, kappa * lam ** 2])
    w, _, _ = tendon_density(a, b, E, d, 1.0, 0.0)
    assert w == pytest.approx(lam * (1 - d * kappa), rel=1e-12)
    w, _, _ = tendon_density(a, b, E, d, -1.0, 0.0)   # opposite tendon: outside of the bend
    assert w == pytest.approx(lam * (1 + d * kappa), rel=1e-12)
    w, _, _ = tendon_density(a, b, E, d, 0.0, 1.0)    # θ = 90°: neutral plane of this bend
    assert w == pytest.approx(lam, rel=1e-12)


def perturbed_state(model):
    q = model.fk((1.5, 0.4, 0.0), 40e3, (0.2, 0.3, -0.3)).q
    return q + RNG.normal(size=q.size) * 1e-3


@pytest.fixture(scope="module", params=["paper", "rotated_constant"])
def model(request):
    p = presets.paper()
    if request.param == "rotated_constant":
        R = rotation([1, 2, 3], 0.7)
        p = p.replace(stiffness=LAWS[1], base_axis=tuple(R @ np.array(p.base_axis)),
                      reference_direction=tuple(R @ np.array(p.reference_direction)), tool_offset=0.012,
                      free_base_stretch=True, pressure_area_slope=-0.7)
    return Model(p)


def test_assembled_gradient_and_tangent(model):
    q = perturbed_state(model)
    T = np.array([1.3, 0.2, 2.2])
    args = (T, 35e3, np.array([0.3, -0.2, -0.4]))
    ev = model.evaluate(q, *args)
    Q_fd = fd_grad(lambda y: model.evaluate(y, *args, hessian=False).energy, q, 1e-7)
    assert np.allclose(ev.Q, Q_fd, atol=1e-6 * np.abs(ev.Q).max())
    K_fd = fd_jac(lambda y: model.evaluate(y, *args, hessian=False).Q, q, 1e-7)
    assert np.allclose(ev.K, K_fd, atol=1e-6 * np.abs(ev.K).max())
    assert np.allclose(ev.K, ev.K.T, atol=1e-10 * np.abs(ev.K).max())   # symmetric tangent


def test_parameter_derivatives(model):
    q = perturbed_state(model)
    T = np.array([1.3, 0.2, 2.2])
    p, F = 35e3, np.array([0.3, -0.2, -0.4])
    dQdT = fd_jac(lambda t: model.residual(q, t, p, F), T, 1e-4)
    assert np.allclose(model.dQ_dT(q), dQdT, atol=1e-8)
    dQdp = (model.residual(q, T, p + 1.0, F) - model.residual(q, T, p - 1.0, F)) / 2.0
    assert np.allclose(model.dQ_dp(q), dQdp, atol=1e-10)
    dQdF = fd_jac(lambda f: model.residual(q, T, p, f), F, 1e-3)
    assert np.allclose(model.dQ_dF(q), dQdF, atol=1e-9)
    # tendon lengths and arc length
    J_fd = fd_jac(lambda y: model.tendon_lengths(y), q, 1e-7)
    assert np.allclose(model.tendon_jacobian(q), J_fd, atol=1e-7)
    arc_fd = fd_grad(lambda y: model.evaluate(y, hessian=False).arc_length, q, 1e-7)
    assert np.allclose(model.evaluate(q, hessian=False).J_arc, arc_fd, atol=1e-7)


def test_tip_jacobians(model):
    q = perturbed_state(model)
    assert np.allclose(model.tip_jacobian(q), fd_jac(model.tip, q, 1e-7), atol=1e-7)
    # δR = [J_ω δq]× R
    Jw = model.tip_angular_jacobian(q)
    R = model.tip_rotation(q)
    for j in range(q.size - 6, q.size):
        e = np.zeros(q.size)
        e[j] = 1e-6
        dR = (model.tip_rotation(q + e) - model.tip_rotation(q - e)) / 2e-6
        W = dR @ R.T
        assert np.allclose(W, -W.T, atol=1e-7)
        assert np.allclose([W[2, 1], W[0, 2], W[1, 0]], Jw[:, j], atol=1e-7)
    # R maps the base axis onto the tip tangent and is a rotation
    a = q[-3:]
    assert np.allclose(R @ model._e1, a / np.linalg.norm(a), atol=1e-14)
    assert np.allclose(R.T @ R, np.eye(3), atol=1e-14) and np.linalg.det(R) == pytest.approx(1.0)


def test_hermite_shape_functions():
    """s_j interpolate nodal values/slopes and reproduce any cubic exactly; derivatives by FD."""
    l0 = 0.03
    xi = np.linspace(0, 1, 7)
    N = kin.hermite(xi, l0)
    cubic = lambda x: 1 + 2 * x - 3 * x ** 2 + 5 * x ** 3
    dcubic = lambda x: 2 - 6 * x + 15 * x ** 2
    nodal = np.array([cubic(0), dcubic(0), cubic(l0), dcubic(l0)])
    assert np.allclose(nodal @ N[0], cubic(xi * l0), atol=1e-14)
    assert np.allclose(nodal @ N[1], dcubic(xi * l0), atol=1e-12)
    h = 1e-6
    dN = (kin.hermite(xi + h, l0)[0] - kin.hermite(xi - h, l0)[0]) / (2 * h * l0)
    assert np.allclose(N[1], dN, atol=1e-6)
