"""Compliance matrices against finite differences of the nonlinear solvers."""

import numpy as np
import pytest

from ancf import InputError, Model, presets
from ancf import compliance as cp

H_FD = 2e-3   # N


@pytest.fixture(scope="module")
def model():
    return Model(presets.paper())


STATES = [((0.0, 0.0, 0.0), 0.0), ((3.0, 0.5, 1.0), 25e3), ((2.0, 0.0, 0.0), 50e3), ((0.5, 4.0, 1.0), 100e3)]


@pytest.mark.parametrize("T, p", STATES)
def test_constant_tension_compliance_matches_fd(model, T, p):
    eq = model.fk(T, p)
    C = cp.tension(model, eq)
    fd = np.column_stack([(model.fk(T, p, H_FD * e, q0=eq.q).tip - model.fk(T, p, -H_FD * e, q0=eq.q).tip)
                          / (2 * H_FD) for e in np.eye(3)])
    assert np.allclose(C.C_p, fd, rtol=1e-5, atol=1e-6 * np.abs(fd).max())
    assert np.allclose(C.C_p, C.C_p.T, atol=1e-12)                  # reciprocity
    assert np.all(np.linalg.eigvalsh(C.C_p) > 0)
    # configuration-space compliance maps to the task-space one through the tip Jacobian
    assert np.allclose(model.tip_jacobian(eq.q) @ C.C_q, C.C_p, atol=1e-14)


def _one_sided_locked(model, eq, u, h=1e-3):
    """Second-order one-sided difference of the locked FK along the load direction u (Richardson)."""
    tip = lambda s: model.fk_locked(eq.tendon_lengths, eq.pressure, s * u, q0=eq.q, tensions0=eq.tensions).tip
    t0 = eq.tip
    return (4 * (tip(h) - t0) / h - (tip(2 * h) - t0) / (2 * h)) / 3


@pytest.mark.parametrize("T, p", STATES)
@pytest.mark.parametrize("u", [(0, 0, -1.0), (0, 1.0, 0), (-1.0, 0, 0), (0.3, -0.5, 0.8)])
def test_exact_locked_compliance_matches_locked_fk(model, T, p, u):
    """The exact KKT form with the active set for the load direction equals the derivative of the
    nonlinear locked FK along that direction (the locked response is piecewise linear in δF)."""
    u = np.asarray(u) / np.linalg.norm(u)
    eq = model.fk(T, p)
    C = cp.locked(model, eq, "exact", load_direction=u)
    fd = _one_sided_locked(model, eq, u)
    assert np.allclose(C.C_p @ u, fd, rtol=2e-4, atol=2e-4 * np.linalg.norm(fd))
    # the predicted tension changes match the multipliers of the nonlinear solve
    h = 1e-3
    lk = model.fk_locked(eq.tendon_lengths, p, h * u, q0=eq.q, tensions0=eq.tensions)
    assert np.allclose(C.dT_dF @ u * h, lk.tensions - eq.tensions, atol=5e-3 * h + 1e-9)


def test_locking_stiffens(model):
    """Sec. V-C: locked tendons are stiffer than constant tension (paper: about twice)."""
    eq = model.fk((2.0, 0.0, 0.0), 0.0)
    kt = cp.directional_stiffness(cp.tension(model, eq).C_p, (0, 0, 1))
    kl = cp.directional_stiffness(cp.locked(model, eq, "exact", load_direction=(0, 0, -1)).C_p, (0, 0, 1))
    assert kl > 1.5 * kt


def test_approximate_forms_are_consistent(model):
    """Paper eq. (13)/(15): with a large constraint weight the least-squares stack enforces J_A δq = 0."""
    eq = model.fk((3.0, 0.5, 1.0), 25e3)
    for method in ("paper", "ik"):
        c1 = cp.locked(model, eq, method)
        assert np.all(np.isfinite(c1.C_p)) and c1.active
        cw = cp.locked(model, eq, method, active=(0, 1, 2), constraint_weight=1e8)
        Jl = model.tendon_jacobian(eq.q)
        assert np.abs(Jl @ cw.C_q).max() < 1e-6 * np.abs(cw.C_q).max()


def test_directional_stiffness_and_ellipsoid(model):
    C = cp.tension(model, model.fk((1.0, 0.0, 0.0), 0.0)).C_p
    ell = cp.stiffness_ellipsoid(C, n=8)
    for k, v in zip(ell["principal_stiffness"], ell["principal_axes"].T):
        assert cp.directional_stiffness(C, v) == pytest.approx(k, rel=1e-10)
    assert ell["points"].shape == (8, 16, 3)
    with pytest.raises(InputError):
        cp.directional_stiffness(C, (0, 0, 0))
    with pytest.raises(InputError):
        cp.locked(model, model.fk((1, 0, 0)), method="svd")


@pytest.mark.parametrize("T, p", [((3.0, 0.5, 1.0), 25e3), ((0.5, 4.0, 1.0), 100e3)])
def test_compliances_of_a_pressure_dependent_law_match_fd(T, p):
    """EI(λ, p) = EI(λ)(1 + 0.9 p̂ − 0.25 p̂²), EA(λ, p) = EA(λ)(1 + 0.3 p̂): the constant-tension and the
    exact locked compliance equal the finite differences of the FK / locked FK under a tip force, and the
    pressure factor makes the bellows stiffer than the stretch-only law at the same loads."""
    law = presets.paper().stiffness.with_pressure(EA=(0.3,), EI=(0.9, -0.25))
    m = Model(presets.paper().replace(stiffness=law))
    eq = m.fk(T, p)
    C = cp.tension(m, eq)
    fd = np.column_stack([(m.fk(T, p, H_FD * e, q0=eq.q).tip - m.fk(T, p, -H_FD * e, q0=eq.q).tip) / (2 * H_FD)
                          for e in np.eye(3)])
    assert np.allclose(C.C_p, fd, rtol=1e-5, atol=1e-6 * np.abs(fd).max())
    u = np.array([0.0, 0.0, -1.0])
    Cl = cp.locked(m, eq, "exact", load_direction=u)
    fdl = _one_sided_locked(m, eq, u)
    assert np.allclose(Cl.C_p @ u, fdl, rtol=2e-4, atol=2e-4 * np.linalg.norm(fdl))
    m0 = Model(presets.paper())
    C0 = cp.tension(m0, m0.fk(T, p))
    assert np.trace(C.C_p) < 0.9 * np.trace(C0.C_p)
