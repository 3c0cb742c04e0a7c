"""The ANCF model against independent continuum solutions (tests/references.py)."""

import numpy as np
import pytest

from ancf import Model, StiffnessLaw, presets
from conftest import uniform_params
from references import eb_tip_load, eb_uniform_load, elastica_tip, tendon_arc

L, EI, EA = 0.16, 0.0839, 767.2


@pytest.mark.parametrize("n", [1, 3, 6])
def test_small_deflection_tip_load(n):
    """δ = F L³ / 3EI.  Cubic Hermite elements represent the cubic deflection exactly, so what remains is
    the geometric nonlinearity, of order (δ/L)² ≈ 1e-6 here."""
    F = 0.01
    eq = Model(uniform_params(n_elements=n)).fk((0, 0, 0), 0.0, (0, 0, -F))
    delta = eb_tip_load(F, L, EI)
    assert -eq.tip[2] == pytest.approx(delta, rel=2e-5)
    assert abs(eq.tip[1]) < 1e-15


@pytest.mark.parametrize("n", [2, 6])
def test_small_deflection_uniform_gravity(n):
    """Uniform line weight q = m' g: δ = q L⁴ / 8EI (consistent Gauss loads make nodes exact)."""
    m_line = 0.01
    eq = Model(uniform_params(n_elements=n, line_mass=m_line)).fk((0, 0, 0))
    assert -eq.tip[2] == pytest.approx(eb_uniform_load(m_line * 9.81, L, EI), rel=2e-5)


def test_large_deflection_elastica_inextensible_limit():
    """A 10 N tip load bends the cantilever ~57°; with EA = 1e6 N (axial strain ~1e-5) the model approaches
    the inextensible elastica under refinement."""
    F = 10.0
    x, z, th = elastica_tip(L, EI, 0.0, -F)
    assert th < -0.9                                   # genuinely large rotation
    errs = []
    for n in (4, 8, 16):
        p = uniform_params(n_elements=n, stiffness=StiffnessLaw.constant(EA=1e6, EI=EI))
        eq = Model(p).fk((0, 0, 0), 0.0, (0, 0, -F), check_limits=False)
        errs.append(np.hypot(eq.tip[0] - x, eq.tip[2] - z))
    assert errs[-1] < 1e-4 * L
    assert errs[0] > errs[1] > errs[2]


def test_pure_extension_under_pressure_linear_law():
    """Uniform stretch with W'(λ) = p A_eff (closed-form root of the linear law's quartic)."""
    p = presets.paper().replace(line_mass=0.0, tip_mass=0.0, free_base_stretch=True)
    model = Model(p)
    for pr in (30e3, 120e3):
        eq = model.fk((0, 0, 0), pr)
        lam = p.stiffness.stretch_under_force(pr * p.A_eff)
        assert eq.tip == pytest.approx([lam * L + p.tool_offset, 0, 0], abs=1e-12)
        # every node's slope has the same stretch, and the tendons all have length λ L
        assert np.linalg.norm(eq.q.reshape(-1, 6)[1:, 3:], axis=1) == pytest.approx(lam, abs=1e-10)
        assert eq.tendon_lengths == pytest.approx([lam * L] * 3, abs=1e-12)


def _arc_tip(T, d, law, theta):
    lam, kappa = tendon_arc(law.axial_force, float(law.EI(1.0)), T, d, L)
    phi = kappa * lam * L
    inplane = np.array([np.sin(phi) / kappa, (1 - np.cos(phi)) / kappa])
    # the bend goes towards the tendon: direction cos θ e_ref + sin θ e3 (e3 = e1 × e_ref = −y here)
    n = np.array([0.0, -np.sin(theta), np.cos(theta)])
    return inplane[0] * np.array([1.0, 0, 0]) + inplane[1] * n


@pytest.mark.parametrize("tendon", [0, 1, 2])
def test_single_tendon_constant_moment_arc(tendon):
    """Weightless uniform actuator, one tendon: moment T d along the length → a uniform arc with
    EI κ = T d λ and W'(λ) + T (1 − d κ) = 0 (exact continuum solution)."""
    p = uniform_params(n_elements=8, free_base_stretch=True)
    T = np.zeros(3)
    T[tendon] = 5.0
    eq = Model(p).fk(T)
    ref = _arc_tip(5.0, 0.0275, p.stiffness, p.tendon_angles[tendon])
    assert np.linalg.norm(eq.q[-6:-3] - ref) < 1e-8


def test_convergence_rate_under_refinement():
    """Cubic Hermite interpolation of the arc: position error O(h⁴) — measured by a log–log fit."""
    ns = np.array([1, 2, 4, 8])
    errs = []
    for n in ns:
        p = uniform_params(n_elements=int(n), free_base_stretch=True)
        eq = Model(p).fk((5.0, 0, 0))
        errs.append(np.linalg.norm(eq.q[-6:-3] - _arc_tip(5.0, 0.0275, p.stiffness, 0.0)))
    rate = -np.polyfit(np.log(ns), np.log(errs), 1)[0]
    assert rate > 3.7, (rate, errs)


def test_clamped_base_stretch_boundary_layer():
    """With |r_x,1| clamped to 1 (the default) the arc's uniform contraction cannot hold at the base: a
    one-element boundary layer gives O(h) convergence — the reason for ``free_base_stretch``."""
    ns = np.array([2, 4, 8, 16])
    errs = []
    for n in ns:
        p = uniform_params(n_elements=int(n))
        eq = Model(p).fk((5.0, 0, 0))
        errs.append(np.linalg.norm(eq.q[-6:-3] - _arc_tip(5.0, 0.0275, p.stiffness, 0.0)))
    rate = -np.polyfit(np.log(ns), np.log(errs), 1)[0]
    assert 0.7 < rate < 1.5
    assert errs[-1] < 2e-4 * L                          # small in absolute terms at practical n


def test_frame_invariance():
    """Rotating base axis, reference direction, gravity and tip load rotates the whole solution."""
    from conftest import rotation
    p = presets.paper()
    R = rotation([0.2, 1.0, -0.4], 1.1)
    pr = p.replace(base_axis=tuple(R @ np.array(p.base_axis)),
                   reference_direction=tuple(R @ np.array(p.reference_direction)),
                   gravity=tuple(R @ np.array(p.gravity)))
    F = np.array([0.1, 0.4, -0.3])
    e0 = Model(p).fk((2.0, 0.5, 1.0), 50e3, F)
    e1 = Model(pr).fk((2.0, 0.5, 1.0), 50e3, R @ F)
    assert np.allclose(e1.tip, R @ e0.tip, atol=1e-12)
    assert np.allclose(e1.q.reshape(-1, 3), (R @ e0.q.reshape(-1, 3).T).T, atol=1e-12)
    assert np.allclose(e1.tendon_lengths, e0.tendon_lengths, atol=1e-13)
    assert np.allclose(e1.tip_rotation, R @ e0.tip_rotation @ R.T, atol=1e-10)


@pytest.mark.parametrize("beta", [-0.8, 0.0, 0.6])
def test_pressure_area_law_uniform_extension(beta):
    """Straight, weightless actuator under pressure only: uniform stretch λ with the axial force balance
    W'(λ) = p d(A(λ) λ)/dλ = p A_eff (1 + β (2λ − 1)) (stretch-dependent pressure area; β = 0 is the
    paper's constant area)."""
    import scipy.optimize as so
    params = uniform_params(pressure_area_slope=beta, free_base_stretch=True)
    model = Model(params)
    pr = 90e3
    eq = model.fk((0, 0, 0), pr)
    law, A = params.stiffness, params.A_eff
    lam = so.brentq(lambda l: law.axial_force(l) - pr * A * (1 + beta * (2 * l - 1)), 0.8, 1.5, xtol=1e-15)
    assert eq.tip[0] == pytest.approx(lam * params.length, rel=1e-10)
    assert params.pressure_area(lam) == pytest.approx(A * (1 + beta * (lam - 1)))
