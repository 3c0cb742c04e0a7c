"""Vibration modes of the reduced model (ancf.dynamics) against closed forms: the clamped-free Euler–Bernoulli
beam (two bending modes, convergence at the rate of the cubic Hermite elements), the fixed-free axial rod, a tip
mass on a light beam, the total mass, and the interlacing of locked (constrained) and tension-held eigenvalues."""

import numpy as np
import pytest

from ancf import Model, StiffnessLaw, presets
from ancf.dynamics import consistent_mass
from ancf.errors import InputError, UnstableEquilibriumError

EI, L = 0.0839, 0.16
BETA = (1.87510406871, 4.69409113297)          # clamped-free beam: β_k L


def beam(n, *, EA=1e5, line_mass=0.2, tip_mass=0.0, free_base_stretch=False):
    return Model(presets.paper().replace(stiffness=StiffnessLaw.constant(EA=EA, EI=EI), line_mass=line_mass,
                                         tip_mass=tip_mass, tool_offset=0.0, n_elements=n, gravity=(0, 0, 0),
                                         free_base_stretch=free_base_stretch))


def straight(m):
    return m.fk((0, 0, 0), 0.0, (0, 0, 0))


def test_bending_frequencies_converge_to_euler_bernoulli_at_the_hermite_rate():
    mp = 0.2
    exact = [b ** 2 / (2 * np.pi) * np.sqrt(EI / (mp * L ** 4)) for b in BETA]
    err = {}
    for n in (2, 4, 8):
        r = beam(n).modes(straight(beam(n)), 4)
        f = r.frequencies
        assert f[0] == pytest.approx(f[1], rel=1e-9) and f[2] == pytest.approx(f[3], rel=1e-9)   # y and z
        err[n] = abs(f[0] / exact[0] - 1), abs(f[2] / exact[1] - 1)
        tip = r.tip_shapes[0]
        assert abs(tip[0]) < 1e-6 * np.linalg.norm(tip)          # a bending mode: the tip moves sideways
    assert err[8][0] < 1e-5 and err[8][1] < 1e-4
    rate = np.polyfit(np.log([2, 4, 8]), np.log([err[n][0] for n in (2, 4, 8)]), 1)[0]
    assert rate < -3.5, err                                       # cubic Hermite: ~h⁴ on the eigenvalue


def axial_frequencies(m, count=12):
    r = m.modes(straight(m), count)
    return r.frequencies[[k for k in range(count)
                          if abs(r.tip_shapes[k][0]) > 0.99 * np.linalg.norm(r.tip_shapes[k])]]


def test_axial_modes_of_the_fixed_free_rod():
    """f_k = (2k − 1) √(EA/m') / 4L.  The exact rod has u(0) = 0 only; the default clamp also fixes the base
    section's stretch (r_x(0) = e1, so u'(0) = 0) — a stiffer boundary whose error shrinks only like h; with
    ``free_base_stretch`` the ANCF rod converges to the closed form at the Hermite rate."""
    EA, mp = 767.2, 0.2
    f1 = np.sqrt(EA / mp) / (4 * L)
    err = {n: abs(axial_frequencies(beam(n, EA=EA, line_mass=mp, free_base_stretch=True))[:2] / (f1 * np.array([1, 3]))
                  - 1) for n in (2, 4, 8)}
    assert err[8][0] < 1e-8 and err[8][1] < 1e-5
    rate = np.polyfit(np.log([2, 4, 8]), np.log([err[n][1] for n in (2, 4, 8)]), 1)[0]
    assert rate < -4.0, err
    clamped = {n: axial_frequencies(beam(n, EA=EA, line_mass=mp))[0] / f1 - 1 for n in (4, 8, 16)}
    assert all(v > 0 for v in clamped.values())                   # stiffer, and converging like h
    assert clamped[16] == pytest.approx(clamped[8] / 2, rel=0.15) and clamped[8] == pytest.approx(clamped[4] / 2, rel=0.15)


def test_tip_mass_on_a_light_beam():
    mtip = 0.05
    m = beam(4, line_mass=1e-4, tip_mass=mtip)
    f = m.modes(straight(m), 1).frequencies[0]
    assert f == pytest.approx(np.sqrt(3 * EI / (mtip * L ** 3)) / (2 * np.pi), rel=1e-3)


def test_consistent_mass_carries_the_whole_mass_in_translation():
    m = beam(5, line_mass=0.37)
    M = consistent_mass(m.n, m._N, m._wq, 0.37)
    for axis in np.eye(3):
        u = np.zeros(m.ndof)
        u.reshape(-1, 6)[:, :3] = axis                           # every node translated, slopes unchanged
        assert u @ M @ u == pytest.approx(0.37 * L, rel=1e-12)
    assert np.allclose(M, M.T) and np.linalg.eigvalsh(M)[0] > 0


def test_locked_tendons_stiffen_every_mode_by_interlacing():
    """The locked equilibrium at the tension-held state's own lengths is the same state; its modes are the
    tension-held problem constrained by the taut tendons (r constraints), so λ_k ≤ λ_k(locked) ≤ λ_{k+r}."""
    m = Model(presets.paper())
    held = m.fk((2.0, 1.0, 0.5), 30e3)
    locked = m.fk_locked(held.tendon_lengths, 30e3)
    assert np.allclose(locked.q, held.q, atol=1e-9) and locked.active == (0, 1, 2)
    a, b = m.modes(held, 9).omega2, m.modes(locked, 6)
    assert b.locked == (0, 1, 2)
    assert np.all(b.omega2 >= a[:6] * (1 - 1e-9)) and np.all(b.omega2 <= a[3:9] * (1 + 1e-9))
    assert b.frequencies[0] > a[0] ** 0.5 / (2 * np.pi) * 1.2          # locking matters


def test_modes_refuse_what_has_no_modes():
    m = beam(4)
    with pytest.raises(InputError, match="line mass"):
        beam(4, line_mass=0.0).modes(straight(beam(4, line_mass=0.0)), 2)
    with pytest.raises(InputError, match="count"):
        m.modes(straight(m), 0)
    P = 1.2 * np.pi ** 2 * EI / (4 * L ** 2)
    saddle = m.fk((0, 0, 0), 0.0, (-P, 0, 0), check_limits=False, check_stability=False)
    with pytest.raises(UnstableEquilibriumError):
        m.modes(saddle, 2)


def test_the_documented_paper_preset_frequencies():
    """docs/dynamics.md's table is the program's output (within its two decimals)."""
    import pathlib
    import re
    text = (pathlib.Path(__file__).parents[1] / "docs" / "dynamics.md").read_text()
    rows = re.findall(r"^\| (\d+) \| ([\d.]+) \| ([\d.]+) \|$", text, flags=re.M)
    assert len(rows) == 4
    m = Model(presets.paper())
    for p_kpa, held, locked in rows:
        p = float(p_kpa) * 1e3
        f_held = m.modes(m.fk((0, 0, 0), p), 1).frequencies[0]
        f_locked = m.modes(m.fk_locked(m.fk((1, 1, 1), p).tendon_lengths, p), 1).frequencies[0]
        assert f_held == pytest.approx(float(held), abs=0.006) and f_locked == pytest.approx(float(locked), abs=0.006)


def _roots(f, brackets):
    import scipy.optimize as so
    return [so.brentq(f, a, b) for a, b in brackets]


def test_uniform_cantilever_with_a_tip_mass_closed_forms():
    """Bending: 1 + cos β cosh β + r β (cos β sinh β − sin β cosh β) = 0, f = β²/(2π L²) √(EI/m'),
    r = M/(m'L); axial: β tan β = 1/r, f = β √(EA/m') / (2π L) (the axial rod with free_base_stretch)."""
    mp, r, EA = 0.2, 0.5, 767.2
    M = r * mp * L
    bend = _roots(lambda b: 1 + np.cos(b) * np.cosh(b) + r * b * (np.cos(b) * np.sinh(b) - np.sin(b) * np.cosh(b)),
                  [(0.5, 2.5), (3.0, 6.0)])
    f_bend = [b ** 2 / (2 * np.pi * L ** 2) * np.sqrt(EI / mp) for b in bend]
    m = beam(8, EA=1e5, line_mass=mp, tip_mass=M)
    f = m.modes(straight(m), 4).frequencies
    assert f[0] == pytest.approx(f_bend[0], rel=1e-5) and f[2] == pytest.approx(f_bend[1], rel=1e-4)
    ax = _roots(lambda b: b * np.tan(b) - 1 / r, [(0.1, np.pi / 2 - 1e-9)])[0]
    f_ax = ax / (2 * np.pi * L) * np.sqrt(EA / mp)
    ma = beam(8, EA=EA, line_mass=mp, tip_mass=M, free_base_stretch=True)
    assert axial_frequencies(ma)[0] == pytest.approx(f_ax, rel=1e-6)


def test_damping_ratios_of_rayleigh_damping_are_exact():
    """ζ_k = α/(2ω_k) + β ω_k/2 for C = α M + β K; a ratio ζ given alone sets the first mode's."""
    m = Model(presets.paper())
    eq = m.fk((2.0, 0.0, 0.0), 30e3)
    r = m.modes(eq, 4, damping={"alpha": 0.8, "beta": 2e-3})
    w = 2 * np.pi * r.frequencies_hz
    assert np.allclose(r.damping_ratios, 0.8 / (2 * w) + 2e-3 * w / 2, rtol=1e-9)
    r = m.modes(eq, 3, damping=0.04)
    assert r.damping_ratios[0] == pytest.approx(0.04, rel=1e-9) and r.damping_ratios[2] > 0.04
    assert np.all(m.modes(eq, 2, damping=0.0).damping_ratios == 0)
    with pytest.raises(InputError, match="unknown keys"):
        m.modes(eq, 2, damping={"zeta": 0.1})


def _split_by_finite_differences(m, q, phi, amplitude=1e-5):
    """(U_A, U_B) [J] of a shape: ½ d²/dε² of the model's own axial-only and bending-only energies (the
    compiled assembly with the other stiffness zero), by a central second difference."""
    from ancf.assembly import assemble
    z1, z3 = np.zeros(1), np.zeros(3)
    common = (m._E, m._d, m._co, m._so, np.zeros(m.m), 0.0, z3, False, 0)
    eps = amplitude / np.linalg.norm(m.tip_jacobian(q) @ phi)

    def U(x, ea, ei):
        return assemble(x, m.n, m._N, m._wq, ea, ei, z1, z3, *common)[0]

    return [0.5 * (U(q + eps * phi, *c) - 2 * U(q, *c) + U(q - eps * phi, *c)) / eps ** 2
            for c in ((m._ea, z1), (z1, m._ei))]


def test_straight_rod_modes_are_pure_axial_or_pure_bending():
    """On a straight, unstressed rod no mode couples stretch and bending: the axial share of the strain energy
    is 1 exactly at the fixed-free rod's frequencies (2k − 1) √(EA/m') / 4L and 0 at the clamped-free beam's
    β_k² √(EI/(m' L⁴)) / 2π; the split equals the model's own axial and bending energies' second variation
    (finite differences of the compiled assembly) and adds up to ω²/2 (mass-normalised shapes)."""
    EA, mp = 767.2, 0.2
    m = beam(8, EA=EA, line_mass=mp, free_base_stretch=True)
    eq = straight(m)
    r = m.modes(eq, 12)
    f_ax = np.sqrt(EA / mp) / (4 * L) * np.array([1, 3])
    f_b = [b ** 2 / (2 * np.pi) * np.sqrt(EI / (mp * L ** 4)) for b in BETA]
    axial = r.frequencies[np.array(r.kinds) == "axial"]
    bending = r.frequencies[np.array(r.kinds) == "bending"]
    assert np.allclose(axial[:2], f_ax, rtol=1e-4) and np.allclose(bending[[0, 2]], f_b, rtol=1e-3)
    assert np.all((r.axial_share < 1e-9) | (r.axial_share > 1 - 1e-9))
    from ancf.dynamics.modes import strain_energy_split
    U = strain_energy_split(m, eq.q, r.shapes, 0.0)
    assert np.allclose(U.sum(axis=1), r.omega2 / 2, rtol=1e-8)
    for k in (0, 2, 4):
        assert np.allclose(U[k], _split_by_finite_differences(m, eq.q, r.shapes[k]), rtol=1e-5,
                           atol=1e-5 * U[k].sum())      # the FD: O(ε²) axial energy of a lateral shape


def test_a_bent_actuators_axial_mode_is_labelled_axial():
    """At T = (2, 0, 0) N, 30 kPa the actuator is bent ≈ 21° at the tip: its 35.8 Hz mode stretches the body
    (≈ 96 % of its strain energy axial) and moves the tip along the bent axis (the tip tangent), not along
    the base axis x — labelled axial; the modes that move the tip across the tangent are bending."""
    m = Model(presets.paper())
    eq = m.fk((2, 0, 0), 30e3)
    r = m.modes(eq, 8)
    k = int(np.argmin(abs(r.frequencies - 35.8)))
    assert r.frequencies[k] == pytest.approx(35.8, abs=0.05)
    assert r.kinds[k] == "axial" and r.axial_share[k] > 0.9
    tangent = eq.q[-3:] / np.linalg.norm(eq.q[-3:])
    along = abs(r.tip_directions @ tangent)
    assert along[k] > 0.99 and abs(r.tip_directions[k][0]) < 0.95   # the old tip-along-x rule missed it
    for j, kind in enumerate(r.kinds):
        assert (kind == "axial") == (along[j] > 0.9), (j, kind, along[j])
    from ancf.dynamics.modes import strain_energy_split
    U = strain_energy_split(m, eq.q, r.shapes, eq.pressure)            # the split carries the mode's stiffness
    assert np.allclose(U.sum(axis=1), r.omega2 / 2, rtol=0.1)


def test_modes_say_where_their_damping_comes_from():
    """The paper preset states no damping: its ratios are 0 and the result says "none"; an actuator that
    states α has ζ_k = α / (2 ω_k) and says "actuator"; a given ratio says "given"."""
    m = Model(presets.paper())
    eq = m.fk((2.0, 0.0, 0.0), 30e3)
    r = m.modes(eq, 3)
    assert r.damping_source == "none" and np.all(r.damping_ratios == 0)
    assert m.modes(eq, 3, damping=0.02).damping_source == "given"
    md = Model(presets.paper().replace(rayleigh_alpha=1.5))
    rd = md.modes(md.fk((2.0, 0.0, 0.0), 30e3), 3)
    assert rd.damping_source == "actuator"
    assert np.allclose(rd.damping_ratios, 1.5 / (2 * 2 * np.pi * rd.frequencies), rtol=1e-9)
