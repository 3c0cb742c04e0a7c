"""Series rotation-free (shear) tip compliance (ancf.shear): closed forms, finite differences of the solvers."""

import numpy as np
import pytest

from ancf import ActuatorParams, ConfigError, InputError, Model, StiffnessLaw, presets
from ancf import compliance as cp
from ancf import shear as sh

S = (0.5e-3, 1.5e-3, 1.8e-3)          # m/N: s(0, 50, 100 kPa) ≈ 0.5 / 1.7 / 3.8 mm/N, like the FEM's
F = np.array([0.1, 0.3, -0.4])         # N
H_FD = 2e-3                            # N


@pytest.fixture(scope="module")
def model():
    return Model(presets.paper().replace(shear_compliance=S))


@pytest.fixture(scope="module")
def rod():
    return Model(presets.paper())


# ----------------------------------------------------------------------------- the pure functions
def test_offset_jacobian_and_pressure_derivative_match_fd():
    rng = np.random.default_rng(3)
    for _ in range(5):
        a, Fv, s = rng.normal(size=3) + np.array([1.5, 0, 0]), rng.normal(size=3), 3e-3
        fd = np.column_stack([(sh.offset(a + 1e-6 * e, s, Fv) - sh.offset(a - 1e-6 * e, s, Fv)) / 2e-6
                              for e in np.eye(3)])
        assert np.allclose(sh.offset_jacobian(a, s, Fv), fd, rtol=1e-7, atol=1e-12)
        t = a / np.linalg.norm(a)
        assert abs(t @ sh.offset(a, s, Fv)) < 1e-15                          # lateral only
        assert np.allclose(sh.offset(a, s, 2.0 * t), 0.0, atol=1e-16)        # axial force: no shear
    for p in (0.0, 37e3, 100e3):
        d = (sh.compliance(S, p + 1.0) - sh.compliance(S, p - 1.0)) / 2.0
        assert sh.compliance_derivative(S, p) == pytest.approx(d, rel=1e-8)


def test_minimum_over_the_pressure_range_is_exact():
    c = (1e-3, -3e-3, 2e-3)                                  # minimum at p̂ = 0.75: 1e-3 − 1.125e-3
    smin, at = sh.minimum(c, 0.0, 120e3)
    grid = np.linspace(0, 120e3, 100001)
    assert smin == pytest.approx(min(sh.compliance(c, p) for p in grid), abs=1e-12)
    assert at == pytest.approx(75e3)


# ----------------------------------------------------------------------------- parameters
def test_default_is_no_shear_bit_for_bit(rod):
    zero = Model(presets.paper().replace(shear_compliance=(0.0, 0.0, 0.0)))
    a, b = rod.fk((2.0, 0.5, 0.0), 50e3, F), zero.fk((2.0, 0.5, 0.0), 50e3, F)
    assert np.array_equal(a.tip, b.tip) and np.array_equal(a.q, b.q)
    assert np.array_equal(cp.tension(rod, a).C_p, cp.tension(zero, b).C_p)
    assert presets.paper().shear_compliance == ()


def test_toml_round_trip_and_units():
    p = presets.paper().replace(shear_compliance=S)
    back = ActuatorParams.from_toml_string(p.to_toml())
    assert back.shear_compliance == S
    text = presets.paper().to_toml().replace("[stiffness]", "shear_compliance_coeffs_mm_per_N_per_100kPa = "
                                             "[0.5, 1.5, 1.8]\n\n[stiffness]")
    got = ActuatorParams.from_toml_string(text).shear_compliance
    assert np.allclose(got, S, rtol=1e-12)


@pytest.mark.parametrize("line, words", [
    ("shear_compliance_coeffs_m_per_N_per_100kPa = [3.8, 0.0]", "implausible"),      # mm/N under m/N
    ("shear_compliance_coeffs_mm_per_N_per_100kPa = [1.0, -2.0]", "s must be ≥ 0"),           # < 0 at 100 kPa
    ("shear_compliance_coeffs_mm_per_N_per_100kPa = 1.0", "list"),
    ("shear_compliance_coeffs_mm_per_N_per_100kPa = ['1.0']", "number"),
    ("shear_compliance_coeffs = [0.001]", "unit"),
])
def test_toml_rejects_bad_shear_keys(line, words):
    text = presets.paper().to_toml().replace("[stiffness]", line + "\n\n[stiffness]")
    with pytest.raises(ConfigError, match=words):
        ActuatorParams.from_toml_string(text)


def test_negative_shear_inside_the_range_is_refused_and_outside_it_at_solve_time():
    with pytest.raises(ConfigError, match="s must be ≥ 0"):
        presets.paper().replace(shear_compliance=(1e-3, -3e-3, 2e-3))      # < 0 at 75 kPa
    m = Model(presets.paper().replace(shear_compliance=(1e-3, -0.5e-3), pressure_max=120e3))
    with pytest.raises(InputError, match="shear compliance"):
        m.fk((0, 0, 0), 300e3, check_limits=False)                          # s(300 kPa) < 0
    with pytest.raises(ConfigError):
        presets.paper().replace(shear_compliance=("1e-3",))


# ----------------------------------------------------------------------------- closed forms
def test_cantilever_tip_deflection_is_bending_plus_shear():
    """A straight cantilever under a small lateral tip force: δ = F L³/(3 EI) + s F (cubic Hermite elements
    represent the linear cantilever exactly); an axial force gives no shear."""
    L, EI, s = 0.16, 0.02, 4e-3
    base = dict(length=L, n_elements=4, stiffness=StiffnessLaw.constant(EA=1e6, EI=EI), D_eff=0.02,
                tendons=presets.paper().tendons, gravity=(0.0, 0.0, 0.0))
    m = Model(ActuatorParams(**base, shear_compliance=(s,)))
    for Fz in (1e-3, -2e-3):
        eq = m.fk((0, 0, 0), 0.0, (0, 0, Fz))
        assert eq.tip[2] == pytest.approx(Fz * L ** 3 / (3 * EI) + s * Fz, rel=1e-5)
    rod = Model(ActuatorParams(**base))
    ax = (0.5, 0, 0)
    assert np.allclose(m.fk((0, 0, 0), 0.0, ax).tip, rod.fk((0, 0, 0), 0.0, ax).tip, atol=1e-15)
    # lateral compliance: C_zz = L³/3EI + s
    C = cp.tension(m, m.fk((0, 0, 0), 0.0, (0, 0, 0))).C_p
    assert C[2, 2] == pytest.approx(L ** 3 / (3 * EI) + s, rel=1e-6)
    assert C[0, 0] == pytest.approx(cp.tension(rod, rod.fk((0, 0, 0), 0.0)).C_p[0, 0], rel=1e-12)


def test_fk_tip_is_the_rod_tip_plus_the_offset(model, rod):
    """The rod's equilibrium is unchanged; the tool point moves by s P⊥ F_tot (tip mass weight included);
    tendon loads alone give no offset."""
    for T, p in (((2.0, 0.5, 0.0), 50e3), ((0.5, 4.0, 1.0), 100e3)):
        a, b = model.fk(T, p, F), rod.fk(T, p, F)
        assert np.array_equal(a.q, b.q)
        t = a.q[-3:] / np.linalg.norm(a.q[-3:])
        Ft = F + model.params.tip_mass * np.asarray(model.params.gravity)
        s = sh.compliance(S, p)
        assert np.allclose(a.tip - b.tip, s * (Ft - t * (t @ Ft)), atol=1e-15)
        assert np.allclose(model.tool_point(a.q, p, F), a.tip, atol=1e-15)
    weightless = Model(presets.paper().replace(shear_compliance=S, tip_mass=0.0))
    eq = weightless.fk((3.0, 0.0, 1.0), 80e3)
    assert np.array_equal(eq.tip, weightless.tip(eq.q))


def test_tool_jacobian_matches_fd(model):
    eq = model.fk((2.0, 0.5, 0.0), 50e3, F)
    J = model.tool_jacobian(eq.q, 50e3, F)
    fd = np.zeros_like(J)
    for k in range(6, model.ndof):
        dq = np.zeros(model.ndof)
        dq[k] = 1e-7
        fd[:, k] = (model.tool_point(eq.q + dq, 50e3, F) - model.tool_point(eq.q - dq, 50e3, F)) / 2e-7
    assert np.allclose(J, fd, atol=1e-7 * np.abs(J).max())


# ----------------------------------------------------------------------------- compliances, pressure
STATES = [((2.0, 0.5, 0.0), 50e3), ((0.5, 4.0, 1.0), 100e3), ((0.0, 0.0, 0.0), 0.0)]


@pytest.mark.parametrize("T, p", STATES)
def test_tension_compliance_with_shear_matches_fd(model, rod, T, p):
    eq = model.fk(T, p, F)
    C = cp.tension(model, eq).C_p
    fd = np.column_stack([(model.fk(T, p, F + H_FD * e, q0=eq.q).tip - model.fk(T, p, F - H_FD * e, q0=eq.q).tip)
                          / (2 * H_FD) for e in np.eye(3)])
    assert np.allclose(C, fd, rtol=1e-5, atol=1e-5 * np.abs(fd).max())
    # the derivative term J_u C_q = s (∂P⊥/∂q · ∂q/∂F) F is needed: s P⊥ alone on the rod's compliance misses
    C0 = cp.tension(rod, rod.fk(T, p, F)).C_p
    t = eq.q[-3:] / np.linalg.norm(eq.q[-3:])
    naive = C0 + sh.compliance(S, p) * (np.eye(3) - np.outer(t, t))
    assert np.abs(naive - fd).max() > 100 * np.abs(C - fd).max()


@pytest.mark.parametrize("T, p", STATES)
@pytest.mark.parametrize("u", [(0, 0, -1.0), (0, 1.0, 0), (0.3, -0.5, 0.8)])
def test_locked_compliance_with_shear_matches_locked_fk(model, T, p, u):
    u = np.asarray(u) / np.linalg.norm(u)
    eq = model.fk(T, p, F)
    C = cp.locked(model, eq, "exact", load_direction=u)
    tip = lambda h: model.fk_locked(eq.tendon_lengths, p, F + h * u, q0=eq.q, tensions0=eq.tensions).tip  # noqa
    h = 1e-3
    fd = (4 * (tip(h) - eq.tip) / h - (tip(2 * h) - eq.tip) / (2 * h)) / 3
    assert np.allclose(C.C_p @ u, fd, rtol=2e-4, atol=2e-4 * np.linalg.norm(fd))


def test_straight_locked_ratio_has_the_series_closed_form():
    """docs §4b: with σ = s/c_δF and r_EB the rod's locked/held ratio, k_locked/k_held = 1/((1 − σ)/r_EB + σ)."""
    par = presets.paper().replace(gravity=(0.0, 0.0, 0.0), tip_mass=0.0)
    rod = Model(par)
    eq = rod.fk((0, 0, 0), 50e3)
    ch = cp.tension(rod, eq).C_p[2, 2]
    cl = cp.locked(rod, eq, "exact", active=(0,)).C_p[2, 2]
    s = 0.06 * ch
    m = Model(par.replace(shear_compliance=(s,)))
    e2 = m.fk((0, 0, 0), 50e3)
    ch2, cl2 = cp.tension(m, e2).C_p[2, 2], cp.locked(m, e2, "exact", active=(0,)).C_p[2, 2]
    assert ch2 == pytest.approx(ch + s, rel=1e-10) and cl2 == pytest.approx(cl + s, rel=1e-10)
    sigma, r_eb = s / ch2, ch / cl
    assert ch2 / cl2 == pytest.approx(1 / ((1 - sigma) / r_eb + sigma), rel=1e-10)


def test_pressure_sensitivity_with_shear_matches_fd(model):
    p, hp = 50e3, 50.0
    eq = model.fk((2.0, 0.5, 0.3), p, F)
    ps = cp.pressure_sensitivity(model, eq, "tensions")
    d = (model.fk((2.0, 0.5, 0.3), p + hp, F, q0=eq.q).tip - model.fk((2.0, 0.5, 0.3), p - hp, F, q0=eq.q).tip) / (2 * hp)
    assert np.allclose(ps.dtip_dp, d, rtol=1e-5, atol=1e-6 * np.abs(d).max())
    ps = cp.pressure_sensitivity(model, eq, "lengths")
    lk = lambda pp: model.fk_locked(eq.tendon_lengths, pp, F, q0=eq.q, tensions0=eq.tensions)  # noqa: E731
    d = (lk(p + hp).tip - lk(p - hp).tip) / (2 * hp)
    assert np.allclose(ps.dtip_dp, d, rtol=1e-5, atol=1e-6 * np.abs(d).max())
    ik = model.ik(model.fk((1.5, 1.0, 0.2), p, F).tip, p, F)
    ps = cp.pressure_sensitivity(model, ik, "tip")
    T = lambda pp: model.ik(ik.tip, pp, F, q0=ik.q, tensions0=ik.tensions, tol_position=1e-12).tensions  # noqa
    d = (T(p + hp) - T(p - hp)) / (2 * hp)
    assert np.allclose(ps.dT_dp, d, rtol=1e-5, atol=1e-5 * np.abs(d).max())
    assert np.allclose(ps.dtip_dp, 0.0, atol=1e-15)
    # the ∂s/∂p term is there: without it the tool-point-held tensions would differ
    rod_like = cp.pressure_sensitivity(Model(presets.paper()), Model(presets.paper()).ik(
        ik.tip, p, F, q0=ik.q, tensions0=ik.tensions), "tip")
    assert not np.allclose(rod_like.dT_dp, ps.dT_dp, rtol=1e-3)


# ----------------------------------------------------------------------------- IK
@pytest.mark.parametrize("T, p, Fv", [((1.5, 1.0, 0.2), 50e3, F), ((0.5, 3.0, 2.0), 100e3, (0.0, -0.6, 0.3)),
                                       ((2.0, 0.0, 0.0), 0.0, (0.0, 0.0, 0.0))])
def test_ik_reaches_the_tool_point(model, T, p, Fv):
    target = model.fk(T, p, Fv).tip
    ik = model.ik(target, p, Fv)
    assert np.linalg.norm(ik.tip - target) <= 1e-9
    assert np.allclose(ik.tensions, T, atol=1e-6)
    again = model.fk(ik.tensions, p, Fv, q0=ik.q)
    assert np.linalg.norm(again.tip - target) < 1e-8


def test_ik_infeasible_names_the_nearest_tool_point(model):
    eq = model.fk((2.0, 0.5, 0.0), 50e3, F)
    from ancf import InfeasibleTargetError
    with pytest.raises(InfeasibleTargetError, match="nearest reachable tool point") as exc:
        model.ik(eq.tip + np.array([0.0, 0.003, -0.002]), 50e3, F)
    near = exc.value.nearest
    assert np.allclose(model.fk(exc.value.tensions, 50e3, F).tip, near, atol=1e-12)


def test_lacc_converges_on_a_shear_compliant_plant(model):
    from controller import LACC, SimulatedPlant, run_iterations
    P, load = 60e3, np.array([0.0, 0.1, -0.45])
    target = model.fk((2.5, 2.2, 2.2), P, (0, 0, 0)).tip
    res = run_iterations(LACC(model, P, compliance="exact"), SimulatedPlant(model, P, load=load), target,
                         iterations=10)
    assert res.errors[0] > 1e-3
    assert res.converged and res.final_error < 2e-4
