"""Dynamics of a multi-segment actuator (ancf.chain_dynamics, docs/multisegment.md "Dynamics"): one segment is
ancf.Model's mass, modes and simulate to round-off; the mass matrix is the kinetic energy of finite-difference
velocities; the inertia force is Lagrange's d/dt ∂T/∂ż − ∂T/∂z by finite differences, its tangents too; two
identical halves are one rod of double length; a cap's mass, offset and rotary inertia lower the first frequency
as the closed form of a cantilever carrying a rigid body; an undamped run conserves energy at second order."""

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from ancf import Model, StiffnessLaw, Tendon, presets
from ancf.chain import Cap, ChainParams
from ancf.chain_dynamics import ChainInertia
from ancf.chain_model import ChainModel
from ancf.dynamics.mass import consistent_mass, tip_mass_matrix
from ancf.errors import InputError

PAPER = presets.paper()
TWO = ChainModel(presets.two_segment())


def _tendons(degrees, d=0.0275):
    return tuple(Tendon(distance=d, angle=math.radians(a)) for a in degrees)


def _pair(base, n, junction="free", cap=None):
    """Two segments of ``base`` at half length, n elements each; segment 2 owns the tip mass and tool."""
    s1 = base.replace(length=base.length / 2, n_elements=n, tip_mass=0.0, tool_offset=0.0,
                      tendons=_tendons((60, 180, 300)))
    s2 = base.replace(length=base.length / 2, n_elements=n, tendons=_tendons((0, 120, 240)))
    return ChainModel(ChainParams(segments=(s1, s2), caps=(cap or Cap(),), junction_stretch=junction))


def _bent(chain):
    """An equilibrium of ``chain`` bent by both segments' tendons, different chamber pressures."""
    T = np.zeros(chain.m)
    T[0], T[-2] = 1.5, 0.8
    return chain.fk(T, np.linspace(20e3, 60e3, chain.n_segments))


# ------------------------------------------------------------------------------------------ one segment = Model
@pytest.mark.parametrize("params", [PAPER, PAPER.replace(free_base_stretch=True)], ids=["clamped", "free_base"])
def test_one_segment_mass_and_modes_are_model(params):
    model, chain = Model(params), ChainModel(params)
    ref, eq = model.fk((2.0, 0.0, 0.5), 30e3), chain.fk((2.0, 0.0, 0.5), [30e3])
    M = consistent_mass(model.n, model._N, model._wq, params.line_mass)
    M = M + tip_mass_matrix(ref.q, params.tool_offset, params.tip_mass)
    np.testing.assert_allclose(chain.mass_matrix(eq.z), model.reduce_mat(M), rtol=0, atol=1e-15)
    locked_ref = model.fk_locked(model.fk((1.0, 1.0, 1.0), 30e3).tendon_lengths, 30e3)
    locked = chain.fk_locked(locked_ref.tendon_lengths, [30e3])
    for a_eq, b_eq in ((ref, eq), (locked_ref, locked)):
        a, b = model.modes(a_eq, 6, damping=0.0), chain.modes(b_eq, 6)
        np.testing.assert_allclose(b.frequencies, a.frequencies, rtol=1e-9)
        np.testing.assert_allclose(np.abs(b.tip_shapes), np.abs(a.tip_shapes), rtol=0, atol=1e-8)
        np.testing.assert_allclose(b.axial_share, a.axial_share, rtol=0, atol=1e-9)
        assert b.locked == tuple(a.locked)
        mz = chain.mass_matrix(b_eq.z)
        np.testing.assert_allclose(np.einsum("ki,ij,kj->k", b.shapes_z, mz, b.shapes_z), 1.0, rtol=1e-10)


# ------------------------------------------------------------------------------------------ the mass
def _positions(chain, z):
    """Every point the kinetic energy sees, by the model's own kinematics only: full q, each cap's centre of
    mass and tangent, the tool point."""
    sys = chain.sys
    caps = []
    for k, c in enumerate(chain.chain.caps):
        s = sys.segments[k]
        node = z[s.zo + s.nz - 6:s.zo + s.nz]
        t = node[3:] / np.linalg.norm(node[3:])
        caps.append((node[:3] + c.mass_offset * t, t))
    return sys.to_full(z), caps, sys.tip(z)


@pytest.mark.parametrize("junction", ["free", "continuous"])
def test_mass_matrix_is_the_kinetic_energy_of_finite_difference_velocities(junction):
    chain = ChainModel(presets.two_segment().model_copy(update={"junction_stretch": junction}))
    eq = _bent(chain)
    I_cap = [3e-6]
    rng = np.random.default_rng(1)
    v = rng.normal(size=chain.nz) * 0.05
    eps = 1e-6
    (qp, cp, tp), (qm, cm, tm) = (_positions(chain, eq.z + s * eps * v) for s in (1, -1))
    qd = (qp - qm) / (2 * eps)
    M = np.zeros((chain.sys.ndof, chain.sys.ndof))
    for s in chain.sys.segments:
        M[s.qo:s.qo + s.ndof, s.qo:s.qo + s.ndof] = consistent_mass(s.params.n_elements, s.N, s.wq, s.params.line_mass)
    T = 0.5 * qd @ M @ qd
    for c, (pa, ta), (pb, tb) in zip(chain.chain.caps, cp, cm):
        T += 0.5 * c.mass * np.sum(((pa - pb) / (2 * eps)) ** 2) + 0.5 * I_cap[0] * np.sum(((ta - tb) / (2 * eps)) ** 2)
    T += 0.5 * chain.chain.segments[-1].tip_mass * np.sum(((tp - tm) / (2 * eps)) ** 2)
    Mz = chain.mass_matrix(eq.z, I_cap)
    assert 0.5 * v @ Mz @ v == pytest.approx(T, rel=1e-8)
    assert np.allclose(Mz, Mz.T) and np.linalg.eigvalsh(Mz)[0] > 0
    assert not np.allclose(Mz, chain.mass_matrix(eq.z)), "the cap's rotary inertia enters"


def test_inertia_force_is_lagrange_of_the_kinetic_energy_and_its_tangents_are_exact():
    """f(z, ż, z̈) = d/dt(M_z ż) − ∂/∂z(½ żᵀ M_z ż) along z(t) = z + ż t + ½ z̈ t², by central differences of
    the mass matrix alone (so the velocity terms of the nonlinear cap map, the caps' and the tool's are all
    checked); ∂f/∂z and ∂f/∂ż against differences of f."""
    eq = _bent(TWO)
    inert = ChainInertia(TWO, [2e-6])
    rng = np.random.default_rng(7)
    z, v, acc = eq.z, rng.normal(size=TWO.nz) * 5.0, rng.normal(size=TWO.nz)
    f, Mz, Kt, Ct = inert.inertia_force(z, v, acc)
    h = 1e-5
    ddt = (inert.mass_matrix(z + h * v + 0.5 * h * h * acc) @ (v + h * acc)
           - inert.mass_matrix(z - h * v + 0.5 * h * h * acc) @ (v - h * acc)) / (2 * h)
    dTdz = np.array([(inert.kinetic_energy(z + h * e, v) - inert.kinetic_energy(z - h * e, v)) / (2 * h)
                     for e in np.eye(TWO.nz)])
    lag = ddt - dTdz
    np.testing.assert_allclose(f, lag, rtol=0, atol=1e-6 * np.abs(lag).max())
    assert np.abs(f - Mz @ acc).max() > 1e-3 * np.abs(f).max(), "the velocity terms are not negligible here"
    for D, arg in ((Kt, 0), (Ct, 1)):
        fd = np.empty_like(D)
        for j, e in enumerate(np.eye(TWO.nz)):
            xp, xm = [z, v, acc], [z, v, acc]
            xp[arg], xm[arg] = xp[arg] + h * e, xm[arg] - h * e
            fd[:, j] = (inert.inertia_force(*xp)[0] - inert.inertia_force(*xm)[0]) / (2 * h)
        np.testing.assert_allclose(D, fd, rtol=0, atol=1e-6 * np.abs(fd).max())


# ------------------------------------------------------------------------------------------ modes
def test_two_identical_halves_are_one_rod_of_double_length():
    """Zero-mass, zero-length cap.  Continuous junction: the same node chain as one rod of 2n elements — the
    same frequencies to round-off.  Free junction (segment 2's base stretch one more coordinate): the same
    first six frequencies in the limit, the difference shrinking with the elements."""
    T, p = np.array([1.0, 0.5, 0.0]), 40e3
    diff = {}
    for n in (2, 3, 6):
        rod = Model(PAPER.replace(n_elements=2 * n, tendons=_tendons((0, 120, 240))))
        ref = rod.modes(rod.fk(T, p), 6, damping=0.0).frequencies
        for junction in ("continuous", "free"):
            chain = _pair(PAPER, n, junction)
            f = chain.modes(chain.fk(np.r_[0.0, 0.0, 0.0, T], [p, p]), 6).frequencies
            diff[n, junction] = np.abs(f / ref - 1).max()
    assert max(diff[n, "continuous"] for n in (2, 3, 6)) < 1e-9
    assert diff[2, "free"] < 2e-4 and diff[3, "free"] < 1e-5 and diff[6, "free"] < 1e-8
    assert diff[6, "free"] < diff[3, "free"] < diff[2, "free"]


EI, L, MP = 0.0839, 0.16, 0.2


def _body_on_cantilever(M, c, inertia):
    """First frequency [Hz] of a clamped-free Euler–Bernoulli beam (EI, m', L) carrying at x = L a rigid body of
    mass M, centre of mass c beyond the end, moment of inertia I about it: W = A(cos − cosh) + B(sin − sinh),
    EI W''' = −ω² M (W + c W'), EI W'' = ω² (M c W + (M c² + I) W') at L, ω² = β⁴ EI/m'."""
    def det(bL):
        b = bL / L
        w = b ** 4 / MP
        co, si, ch, sh = math.cos(bL), math.sin(bL), math.cosh(bL), math.sinh(bL)
        basis = [(co - ch, -b * (si + sh), -b * b * (co + ch), b ** 3 * (si - sh)),
                 (si - sh, b * (co - ch), -b * b * (si + sh), -b ** 3 * (co + ch))]
        rows = [[f[3] + w * M * (f[0] + c * f[1]) for f in basis],
                [f[2] - w * (M * c * f[0] + (M * c * c + inertia) * f[1]) for f in basis]]
        return rows[0][0] * rows[1][1] - rows[0][1] * rows[1][0]
    xs = np.linspace(0.3, 3.0, 300)
    i = next(i for i in range(len(xs) - 1) if det(xs[i]) * det(xs[i + 1]) < 0)
    bL = brentq(det, xs[i], xs[i + 1], xtol=1e-14)
    return (bL / L) ** 2 * math.sqrt(EI / MP) / (2 * math.pi)


def _tip_mass_equation(M):
    """β L of the point-mass form 1 + cos βL cosh βL + r βL (cos βL sinh βL − sin βL cosh βL) = 0, r = M/(m'L)."""
    r = M / (MP * L)
    g = lambda b: 1 + math.cos(b) * math.cosh(b) + r * b * (math.cos(b) * math.sinh(b) - math.sin(b) * math.cosh(b))
    return brentq(g, 0.3, 1.875)


def _capped(n, cap):
    """Segment 1: the straight, unloaded beam (EI, m', L, no gravity); the cap; segment 2 a 1 cm stub of
    negligible mass (1e-6 kg) whose own modes are far above (its law EA = 10 N, EI = 1e-4 N m²)."""
    base = PAPER.replace(gravity=(0, 0, 0), tip_mass=0.0, tool_offset=0.0)
    s1 = base.replace(stiffness=StiffnessLaw.constant(EA=1e5, EI=EI), length=L, n_elements=n, line_mass=MP,
                      tendons=_tendons((0, 120, 240)))
    s2 = base.replace(stiffness=StiffnessLaw.constant(EA=10.0, EI=1e-4), length=0.01, n_elements=1, line_mass=1e-4,
                      tendons=_tendons((60, 180, 300)))
    return ChainModel(ChainParams(segments=(s1, s2), caps=(cap,)))


@pytest.mark.parametrize("M, h, c, inertia", [(0.05, 0.0, 0.0, 0.0), (0.05, 0.02, 0.01, 0.05 * 0.02 ** 2)],
                         ids=["point_mass", "offset_and_rotary_inertia"])
def test_a_cap_lowers_the_first_frequency_as_the_closed_form(M, h, c, inertia):
    exact = _body_on_cantilever(M, c, inertia)
    if c == 0 and inertia == 0:
        beta = _tip_mass_equation(M) / L
        assert exact == pytest.approx(beta ** 2 * math.sqrt(EI / MP) / (2 * math.pi), rel=1e-12)
    bare = _capped(8, Cap())
    f_bare = bare.modes(bare.fk(np.zeros(6), [0.0, 0.0]), 1).frequencies[0]
    assert f_bare == pytest.approx(1.87510406871 ** 2 / L ** 2 * math.sqrt(EI / MP) / (2 * math.pi), rel=1e-4)
    err = {}
    for n in (2, 8):
        chain = _capped(n, Cap(mass=M, length=h, mass_offset=c))
        r = chain.modes(chain.fk(np.zeros(6), [0.0, 0.0]), 2, cap_inertia=[inertia])
        assert r.frequencies[0] == pytest.approx(r.frequencies[1], rel=1e-6)         # the y and z bending
        err[n] = abs(r.frequencies[0] / exact - 1)
    assert err[8] < 3e-5 and exact < 0.4 * f_bare                                     # the body matters: 63 %


def test_modes_refuse_what_is_not_an_equilibrium_of_this_chain():
    eq = _bent(TWO)
    with pytest.raises(InputError, match="not an equilibrium"):
        TWO.modes(type(eq)(**{**eq.__dict__, "z": eq.z + 1e-4, "q": TWO.to_full(eq.z + 1e-4)}), 2)
    with pytest.raises(InputError, match="not an equilibrium"):
        TWO.modes(type(eq)(**{**eq.__dict__, "tensions": eq.tensions * 1.5}), 2)
    with pytest.raises(InputError, match="another actuator"):
        ChainModel(PAPER).modes(eq, 2)
    with pytest.raises(InputError, match="ChainEquilibrium|equilibrium of this chain"):
        TWO.modes(Model(PAPER).fk((0, 0, 0), 0.0), 2)
    with pytest.raises(InputError, match="count"):
        TWO.modes(eq, 0)
    with pytest.raises(InputError, match="cap_inertia"):
        TWO.modes(eq, 2, cap_inertia=[-1.0])


# ------------------------------------------------------------------------------------------ simulate
def test_one_segment_simulate_is_model_simulate():
    model, chain = Model(PAPER), ChainModel(PAPER)
    ref0, eq0 = model.fk((2.0, 0.0, 0.0), 30e3), chain.fk((2.0, 0.0, 0.0), [30e3])
    a = model.simulate(0.1, 2e-3, q0=ref0, tensions=(0.5, 0.0, 0.0), pressure=30e3, damping=0.0, rho_inf=0.9)
    b = chain.simulate(0.1, 2e-3, eq0, tensions=(0.5, 0.0, 0.0), pressures=[30e3], damping=0.0, rho_inf=0.9)
    np.testing.assert_allclose(b.t, a.t, rtol=0, atol=1e-15)
    np.testing.assert_allclose(b.q, a.q, rtol=0, atol=1e-10)
    np.testing.assert_allclose(b.energy, a.energy, rtol=0, atol=1e-10)
    assert np.ptp(a.tip[:, 0]) > 1e-3                                                  # it moves


def test_undamped_free_vibration_conserves_energy_at_second_order():
    """Two segments, a cap with mass, offset and rotary inertia, released from a bent equilibrium with the
    tendons slack, ρ∞ = 1 (no numerical dissipation): the energy error shrinks like h² and stays within 1 % of
    the motion's kinetic energy at h = 1 ms (without the cap map's velocity term it does not converge)."""
    eq = _bent(TWO)
    drift = {}
    for dt in (2e-3, 1e-3):
        s = TWO.simulate(0.3, dt, eq, tensions=np.zeros(TWO.m), pressures=eq.pressures, damping=0.0, rho_inf=1.0,
                         cap_inertia=[2e-6])
        drift[dt] = np.abs(s.energy - s.energy[0]).max()
        assert np.ptp(s.tip, axis=0).max() > 0.01                                     # a large swing
    assert drift[1e-3] < drift[2e-3] / 3.0 and drift[1e-3] < 0.01 * s.kinetic.max()


def test_simulate_checks_its_inputs_and_damping_dissipates():
    eq = _bent(TWO)
    with pytest.raises(InputError):
        TWO.simulate(0.0, 1e-3, eq, tensions=eq.tensions, pressures=eq.pressures)
    with pytest.raises(InputError, match="tensions"):
        TWO.simulate(0.01, 1e-3, eq, tensions=(1.0, 0.0), pressures=eq.pressures)
    with pytest.raises(InputError, match="not an equilibrium"):
        TWO.simulate(0.01, 1e-3, type(eq)(**{**eq.__dict__, "tensions": eq.tensions * 2}),
                     tensions=eq.tensions, pressures=eq.pressures)
    s = TWO.simulate(0.02, 2e-3, eq, tensions=np.zeros(TWO.m), pressures=eq.pressures, damping=0.05)
    assert s.dissipated[-1] > 0 and s.damping["beta"] > 0                           # a ratio: β = 2ζ/ω₁
    s = TWO.simulate(0.1, 1e-3, eq, tensions=np.zeros(TWO.m), pressures=eq.pressures, damping={"alpha": 5.0},
                     rho_inf=1.0)
    balance = (s.energy + s.dissipated) - (s.energy[0] + s.dissipated[0])          # measured: 6 % of D
    assert s.dissipated[-1] > 0.3 * s.kinetic.max() and np.abs(balance).max() < 0.1 * s.dissipated[-1]
    at_rest = TWO.simulate(0.02, 2e-3, eq, tensions=eq.tensions, pressures=eq.pressures, damping=0.0)
    assert np.abs(at_rest.z - eq.z).max() < 1e-9                                      # an equilibrium stays


def test_the_documented_preset_frequencies():
    """docs/multisegment.md's two_segment frequencies (tensions held at 0 N, 30/30 kPa) are the program's."""
    import pathlib
    import re
    text = (pathlib.Path(__file__).parents[1] / "docs" / "multisegment.md").read_text()
    found = re.search(r"\*\*([\d.]+), ([\d.]+), ([\d.]+), ([\d.]+) Hz\*\* \(bending\) and \*\*([\d.]+) Hz\*\* \(axial\)",
                      text)
    assert found, "the sentence with the preset's frequencies"
    r = TWO.modes(TWO.fk(np.zeros(TWO.m), [30e3, 30e3]), 5)
    np.testing.assert_allclose(r.frequencies, [float(x) for x in found.groups()], rtol=0, atol=0.006)
    assert r.kinds == ("bending",) * 4 + ("axial",)
