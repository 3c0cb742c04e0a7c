"""Every analytic derivative against central finite differences.

Densities (9-vector gradients and 9×9 Hessians per generalized force), the assembled Q = ∂Π/∂q and
∂Q/∂q, ∂Q/∂T, ∂Q/∂p, ∂Q/∂F, tendon-length and arc-length gradients, tip position and orientation
Jacobians — at a generic loaded 3-D state, with both stiffness laws, a pressure-dependent law and a rotated
actuator frame; the pressure sensitivities of the FK, IK and locked FK against solves at p ± h.
"""

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from ancf import Model, StiffnessLaw, presets
from ancf import compliance as cp
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


#: A pressure-dependent law: EI × (1 + 0.9 p̂ − 0.25 p̂²), EA × (1 + 0.3 p̂), p̂ = p/100 kPa.
PRESSURE_LAW = presets.paper().stiffness.with_pressure(EA=(0.3,), EI=(0.9, -0.25))


@pytest.fixture(scope="module", params=["paper", "rotated_constant", "pressure_law"])
def model(request):
    p = presets.paper()
    if request.param == "pressure_law":
        p = p.replace(stiffness=PRESSURE_LAW, pressure_area_slope=0.4)
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
    assert np.allclose(model.dQ_dp(q, p), dQdp, atol=1e-10)
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


# ------------------------------------------------------------------------------- pressure-dependent stiffness


def test_pressure_law_stiffness_terms_of_dQ_dp():
    """∂Q/∂p of a pressure-dependent law is the volume term plus ∂Q_axial/∂p + ∂Q_bend/∂p: against central
    differences of Q in p at several pressures (the factor is quadratic in p, so ∂Q/∂p changes with p), and
    clearly different from the volume term alone."""
    m = Model(presets.paper().replace(stiffness=PRESSURE_LAW))
    m0 = Model(presets.paper())
    q = perturbed_state(m)
    T, F = np.array([1.3, 0.2, 2.2]), np.array([0.3, -0.2, -0.4])
    for p in (0.0, 40e3, 100e3):
        fd = (m.residual(q, T, p + 5.0, F) - m.residual(q, T, p - 5.0, F)) / 10.0
        g = m.dQ_dp(q, p)
        assert np.abs(g - fd).max() <= 1e-7 * np.abs(fd).max()
        assert np.abs(g - m0.dQ_dp(q, p)).max() > 1e-3 * np.abs(g).max()   # the stiffness terms matter
    # the energy at fixed q follows EI(λ, p) = EI(λ) f_I(p): Π(p) − Π(0) has the factor's shape
    E = [m.evaluate(q, T, p, F, hessian=False).energy - m0.evaluate(q, T, p, F, hessian=False).energy
         for p in (0.0, 50e3, 100e3)]
    assert E[0] == 0.0 and E[1] != 0.0 and E[2] != 0.0


def _fd_in_pressure(solve, p, h=20.0):
    a, b = solve(p + h), solve(p - h)
    return {k: (getattr(a, k) - getattr(b, k)) / (2 * h) for k in ("q", "tip", "tensions")}


@pytest.mark.parametrize("law", ["paper", "pressure_law"])
def test_pressure_sensitivity_of_fk_ik_and_locked_fk(law):
    """d(tip, T)/dp with the tensions, the tip or the tendon lengths held, from ∂Q/∂p (cp.pressure_sensitivity),
    against central differences of the nonlinear FK, IK and locked FK in p."""
    prm = presets.paper() if law == "paper" else presets.paper().replace(stiffness=PRESSURE_LAW)
    m = Model(prm)
    T, p = np.array([2.0, 0.6, 0.4]), 60e3
    eq = m.fk(T, p)
    s = cp.pressure_sensitivity(m, eq, "tensions")
    fd = _fd_in_pressure(lambda pp: m.fk(T, pp, q0=eq.q), p)
    assert np.allclose(s.dtip_dp, fd["tip"], rtol=1e-5, atol=1e-6 * np.abs(fd["tip"]).max())
    assert np.allclose(s.dq_dp, fd["q"], atol=1e-6 * np.abs(fd["q"]).max())
    # IK: the tip held, the tensions follow the pressure
    eq_ik = m.ik(eq.tip, p, q0=eq.q, tensions0=T + 0.2)
    s = cp.pressure_sensitivity(m, eq_ik, "tip")
    fd = _fd_in_pressure(lambda pp: m.ik(eq_ik.tip, pp, q0=eq_ik.q, tensions0=eq_ik.tensions), p)
    assert np.allclose(s.dT_dp, fd["tensions"], rtol=1e-5, atol=1e-6 * np.abs(fd["tensions"]).max())
    assert np.abs(s.dtip_dp).max() < 1e-12
    # locked lengths: the taut tendons' tensions and the tip follow the pressure
    eq_l = m.fk_locked(eq.tendon_lengths, p, q0=eq.q, tensions0=eq.tensions)
    s = cp.pressure_sensitivity(m, eq_l, "lengths")
    fd = _fd_in_pressure(lambda pp: m.fk_locked(eq.tendon_lengths, pp, q0=eq_l.q, tensions0=eq_l.tensions), p)
    assert np.allclose(s.dtip_dp, fd["tip"], rtol=1e-5, atol=1e-6 * np.abs(fd["tip"]).max())
    assert np.allclose(s.dT_dp, fd["tensions"], rtol=1e-5, atol=1e-6 * np.abs(fd["tensions"]).max())



_BASE_Q = None


@settings(max_examples=25, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(cI=st.lists(st.floats(-0.45, 2.0), min_size=1, max_size=3), cA=st.lists(st.floats(-0.45, 1.0), max_size=2),
       p=st.floats(0.0, 120e3), seed=st.integers(0, 2 ** 16))
def test_property_pressure_law_derivatives(cI, cA, p, seed):
    """For any pressure factors positive over 0–120 kPa, at a random state and pressure: Q is the gradient of
    Π, ∂Q/∂p matches central differences of Q in p, and the law equals the stretch-only law scaled by its
    factors."""
    law = PRESSURE_LAW.with_pressure(EA=cA, EI=cI)
    f, _, _ = law.pressure_factor_minimum(0.0, 120e3)
    if not f > 0.05:
        return
    m = Model(presets.paper().replace(stiffness=law))
    global _BASE_Q
    if _BASE_Q is None:
        _BASE_Q = Model(presets.paper()).fk((1.5, 0.4, 0.0), 40e3, (0.2, 0.3, -0.3)).q
    q = _BASE_Q + np.random.default_rng(seed).normal(size=_BASE_Q.size) * 1e-3
    T, F = np.array([1.0, 0.0, 2.0]), np.array([0.1, 0.0, -0.2])
    ev = m.evaluate(q, T, p, F)
    j = np.argsort(np.abs(ev.Q))[-3:]              # the largest entries
    for k in j:
        e = np.zeros(q.size)
        e[k] = 1e-7
        fd = (m.evaluate(q + e, T, p, F, hessian=False).energy - m.evaluate(q - e, T, p, F, hessian=False).energy) / 2e-7
        assert fd == pytest.approx(ev.Q[k], rel=1e-5, abs=1e-6 * np.abs(ev.Q).max())
    h = 10.0
    fd = (m.residual(q, T, p + h, F) - m.residual(q, T, p - h, F)) / (2 * h)
    assert np.abs(m.dQ_dp(q, p) - fd).max() <= 1e-6 * np.abs(fd).max()
    fA, fI = law.pressure_factors(p)
    assert float(law.EI(1.1, p)) == pytest.approx(fI * float(law.EI(1.1)), rel=1e-14)
    assert float(law.EA(0.9, p)) == pytest.approx(fA * float(law.EA(0.9)), rel=1e-14)


def test_zero_pressure_coefficients_reproduce_the_stretch_only_law_bit_for_bit():
    """A law with all pressure coefficients 0 is the stretch-only law (one representation), and its solves
    are identical to the last bit."""
    base = presets.paper()
    law = base.stiffness.with_pressure(EA=(0.0,), EI=(0.0, 0.0))
    assert law == base.stiffness and not law.pressure_dependent
    m0, m1 = Model(base), Model(base.replace(stiffness=law))
    a, b = m0.fk((2.0, 0.3, 0.0), 70e3), m1.fk((2.0, 0.3, 0.0), 70e3)
    assert np.array_equal(a.q, b.q)
    assert np.array_equal(m0.dQ_dp(a.q, 70e3), m1.dQ_dp(a.q, 70e3))
