"""An equilibrium the model returns is a minimum of the potential (or the call raises a typed error).

Checked against a known critical load: a straight cantilever of the constant law under an axial dead
push P loses stability at Euler's load P_cr = π² EI / (4 L²).  The onset of the first negative reduced
eigenvalue converges to it at the rate of the cubic Hermite elements; the remaining offset is the
extensibility of the rod (of order P/EA) and is made negligible with a stiff EA."""

import numpy as np
import pytest
import scipy.optimize as so

from ancf import Model, StiffnessLaw, presets
from ancf.errors import CollapsedStateError, UnstableEquilibriumError

EI, L = 0.0839, 0.16
P_EULER = np.pi ** 2 * EI / (4 * L ** 2)


def column(n, EA=1e7):
    return Model(presets.paper().replace(stiffness=StiffnessLaw.constant(EA=EA, EI=EI), line_mass=0.0,
                                         tip_mass=0.0, tool_offset=0.0, n_elements=n))


def straight_min_eigenvalue(model, P):
    eq = model.fk((0, 0, 0), 0.0, (-P, 0, 0), check_limits=False, check_stability=False)
    assert np.allclose(eq.tip[1:], 0.0, atol=1e-12)          # the straight (symmetric) branch
    return eq


def onset(model):
    return so.brentq(lambda P: straight_min_eigenvalue(model, P).min_eigenvalue, 0.5 * P_EULER,
                     1.5 * P_EULER, xtol=1e-12 * P_EULER)


def test_buckling_onset_matches_euler_and_converges_with_the_mesh():
    errors = {n: abs(onset(column(n)) / P_EULER - 1) for n in (1, 2, 4, 8)}
    assert errors[8] < 2e-5                                  # within the discretisation error
    rate = np.polyfit(np.log([1, 2, 4]), np.log([errors[1], errors[2], errors[4]]), 1)[0]
    assert rate < -3.0, errors                              # cubic Hermite: ~ h^4 on the eigenvalue


def test_stable_below_and_typed_error_above_the_critical_load():
    m = column(6, EA=767.2)
    below = m.fk((0, 0, 0), 0.0, (-0.9 * P_EULER, 0, 0), check_limits=False)
    assert below.stable and below.min_eigenvalue > 0
    above = straight_min_eigenvalue(m, 1.2 * P_EULER)
    assert not above.stable and above.min_eigenvalue < 0
    with pytest.raises(UnstableEquilibriumError, match="perturb") as info:
        m.fk((0, 0, 0), 0.0, (-1.2 * P_EULER, 0, 0), check_limits=False)
    assert info.value.min_eigenvalue == pytest.approx(above.min_eigenvalue, rel=1e-6)


def reduced(model, q):
    """Free coordinates z of the full coordinates q (the clamp fixes the rest)."""
    z = model.to_free(q)
    assert np.allclose(model.to_full(z), q, atol=1e-14)
    return z


def fd_hessian(f, z, h=2e-5):
    """Central second differences of a scalar function: an independent reference for ∇²f (no analytic
    derivative of the model is used)."""
    n = len(z)
    E = np.eye(n) * h
    H = np.empty((n, n))
    for i in range(n):
        for j in range(i, n):
            H[i, j] = H[j, i] = (f(z + E[i] + E[j]) - f(z + E[i] - E[j]) - f(z - E[i] + E[j])
                                 + f(z - E[i] - E[j])) / (4 * h * h)
    return H


def fd_jacobian(f, z, h=1e-7):
    return np.array([(f(z + h * e) - f(z - h * e)) / (2 * h) for e in np.eye(len(z))]).T


def potential(model, T, p, F, l0=None, ks=None):
    """Total potential in free coordinates: the model's energy with dead tensions T (elastic, pressure,
    gravity, tip load, tendon work T·l), plus ½ k_s Σ max(l − l₀, 0)² for elastic locked tendons."""
    def f(z):
        ev = model.evaluate(model.to_full(z), T, p, F)
        extra = 0.0 if ks is None else 0.5 * ks * np.sum(np.maximum(ev.lengths - l0, 0.0) ** 2)
        return ev.energy + extra
    return f


def test_min_eigenvalue_matches_a_finite_difference_hessian_of_the_potential(paper_model):
    """Free FK at random loads: eq.min_eigenvalue is the smallest eigenvalue of ∇²Π, measured here by
    second differences of the energy alone."""
    m = paper_model
    rng = np.random.default_rng(3)
    for _ in range(3):
        T, p, F = rng.uniform(0, 5, 3), rng.uniform(0, 120e3), rng.normal(0, 0.5, 3)
        eq = m.fk(T, p, F)
        ref = np.linalg.eigvalsh(fd_hessian(potential(m, T, p, F), reduced(m, eq.q)))[0]
        assert eq.stable and ref > 0
        assert eq.min_eigenvalue == pytest.approx(ref, rel=2e-3)


def test_rigid_locked_tendons_test_the_hessian_on_the_constraint_tangent_space(paper_model):
    m = paper_model
    l0 = m.fk((3, 1, 0), 40e3).tendon_lengths - 0.002
    eq = m.fk_locked(l0, 40e3, (0, 0, -0.3))
    z = reduced(m, eq.q)
    A = list(eq.active)
    H = fd_hessian(potential(m, eq.tensions, 40e3, (0, 0, -0.3)), z)
    J = fd_jacobian(lambda zz: m.evaluate(m.to_full(zz), None, 40e3).lengths[A], z)
    Z = np.linalg.qr(J.T, mode="complete")[0][:, len(A):]
    assert eq.min_eigenvalue == pytest.approx(np.linalg.eigvalsh(Z.T @ H @ Z)[0], rel=2e-3)


@pytest.mark.parametrize("method", ["active_set", "gamma"])
def test_elastic_locked_tendons_add_their_own_stiffness_to_the_hessian(method):
    """Elastic tendons (k_s = 310 N/m) are no constraints: the potential gains ½ k_s (l − l₀)² per taut
    tendon and stability is ∇²Π + k_s ∇l ∇lᵀ on all coordinates.  The projection on null(∇l) used before
    gave 0.069 here where the potential's Hessian has 0.043."""
    m = Model(presets.paper().replace(tendon_stiffness=310.0))
    l0 = m.fk((3, 1, 0), 40e3).tendon_lengths - 0.002
    eq = m.fk_locked(l0, 40e3, (0, 0, -0.3), method=method)
    assert eq.active == (0, 1) and eq.stable
    H = fd_hessian(potential(m, (0, 0, 0), 40e3, (0, 0, -0.3), l0, 310.0), reduced(m, eq.q))
    assert eq.min_eigenvalue == pytest.approx(np.linalg.eigvalsh(H)[0], rel=2e-3)


def test_soft_locked_tendons_cannot_hold_a_column_beyond_euler():
    """A straight column under 1.1 × Euler's load with all three tendons locked taut: stiff tendons
    (3000 N/m) brace it, soft ones (20 N/m) cannot, and the finite-difference Hessian of the potential
    agrees.  Projecting ∇²Π on null(∇l), as rigid tendons would, calls the soft case stable: a saddle
    that passed before."""
    def column(ks):
        m = Model(presets.paper().replace(stiffness=StiffnessLaw.constant(EA=767.2, EI=EI), line_mass=0.0,
                                          tip_mass=0.0, tool_offset=0.0, n_elements=4, tendon_stiffness=ks))
        F = (-1.1 * P_EULER, 0, 0)
        free = m.fk((1, 1, 1), 0.0, F, check_limits=False, check_stability=False)
        l0 = free.tendon_lengths - 1.0 / ks                       # 1 N in each tendon
        return m, F, l0, free.q

    m, F, l0, q0 = column(3000.0)
    assert m.fk_locked(l0, 0.0, F, q0=q0, check_limits=False).stable
    m, F, l0, q0 = column(20.0)
    with pytest.raises(UnstableEquilibriumError, match="stiffness") as info:
        m.fk_locked(l0, 0.0, F, q0=q0, check_limits=False)
    eq = m.fk_locked(l0, 0.0, F, q0=q0, check_limits=False, check_stability=False)
    assert np.allclose(eq.tip[1:], 0.0, atol=1e-9) and np.allclose(eq.tensions, 1.0, rtol=1e-6)
    z = reduced(m, eq.q)
    H = fd_hessian(potential(m, (0, 0, 0), 0.0, F, l0, 20.0), z)
    assert np.linalg.eigvalsh(H)[0] < 0
    assert info.value.min_eigenvalue == pytest.approx(np.linalg.eigvalsh(H)[0], rel=5e-3)
    H_T = fd_hessian(potential(m, eq.tensions, 0.0, F), z)
    J = fd_jacobian(lambda zz: m.evaluate(m.to_full(zz), None, 0.0).lengths, z)
    Z = np.linalg.qr(J.T, mode="complete")[0][:, 3:]
    assert np.linalg.eigvalsh(Z.T @ H_T @ Z)[0] > 0                 # what the projection would have said


def test_locked_lengths_far_too_short_give_a_typed_error_from_both_solvers(paper_model):
    """Locked tendons 20 % shorter than the actuator compress it straight: a saddle on the tangent space of
    the constraints.  Both locked solvers used to return it as converged; now both say so."""
    m = paper_model
    l0 = m.tendon_lengths(m.q_ref) * 0.8
    for method in ("active_set", "gamma"):
        with pytest.raises(UnstableEquilibriumError, match="tangent space") as info:
            m.fk_locked(l0, 30e3, method=method)
        assert info.value.min_eigenvalue < 0
        eq = m.fk_locked(l0, 30e3, method=method, check_stability=False)
        assert not eq.stable and eq.min_eigenvalue < 0


def test_locked_solvers_agree_on_stable_states(paper_model):
    m = paper_model
    l_ref = m.tendon_lengths(m.q_ref)
    for f in ([0.95, 1, 1], [0.9, 0.9, 1], [0.97, 1.01, 1.02]):
        a = m.fk_locked(l_ref * np.array(f), 30e3, (0, 0, -0.3))
        g = m.fk_locked(l_ref * np.array(f), 30e3, (0, 0, -0.3), method="gamma")
        assert a.stable and g.stable
        assert np.allclose(a.tip, g.tip, atol=1e-9) and np.allclose(a.tensions, g.tensions, atol=1e-6)


def test_stretch_outside_the_law_is_a_collapsed_state():
    """The paper's law EA = a λ + b is zero at λ = −b/a ≈ 0.43: a solve that ends below it raises."""
    law = presets.paper_unscaled().stiffness
    lo, hi = law.valid_stretch_range
    assert lo == pytest.approx(-law.source["b"] / law.source["a"]) and hi == np.inf
    assert law.EA(lo) == pytest.approx(0.0, abs=1e-9) and law.EA(lo + 1e-6) > 0 and law.EI(lo + 1e-6) > 0
    m = Model(presets.paper_unscaled())
    with pytest.raises(CollapsedStateError) as info:
        m.fk_locked(m.tendon_lengths(m.q_ref) * 0.5, 30e3)
    assert info.value.stretch < lo
    assert StiffnessLaw.constant(EA=1.0, EI=1.0).valid_stretch_range == (0.0, np.inf)
