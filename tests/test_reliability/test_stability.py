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


def test_stability_flag_agrees_with_the_eigenvalues_at_random_states(paper_model):
    rng = np.random.default_rng(3)
    for _ in range(8):
        eq = paper_model.fk(rng.uniform(0, 5, 3), rng.uniform(0, 120e3), rng.normal(0, 0.5, 3))
        H = eq.__dict__["_stability_matrix"]
        assert eq.stable and np.linalg.eigvalsh(H)[0] == pytest.approx(eq.min_eigenvalue) and eq.min_eigenvalue > 0


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
