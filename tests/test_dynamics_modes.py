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
