"""Vibration modes of the FEM (fem_reference.dynamics): the consistent mass carries the body's mass, the
straight tube's first bending and axial frequencies agree with the clamped-free beam and rod of its own
equivalent-rod stiffness, and locked tendons raise every frequency (constraints interlace)."""

import numpy as np
import pytest

from ancf.errors import InputError
from fem_reference import BellowsGeometry, BellowsModel, Material, MeshLevel
from fem_reference.dynamics import mass_matrix

L, R, T = 0.16, 0.015, 0.004


def fem_axial(md, length):
    """The first axial mode's frequency: the cap translates along the axis (a torsion mode's translation is
    round-off, hence the size test against its rotation)."""
    return [f for f, s in zip(md.frequencies_hz, md.cap_shapes)
            if abs(s[0]) > 0.9 * np.linalg.norm(s[:3]) and np.linalg.norm(s[:3]) > 0.1 * length * np.linalg.norm(s[3:])][0]


@pytest.fixture(scope="module")
def tube():
    return BellowsModel(BellowsGeometry.straight_tube(L, R, T, n_segments=8), Material.neo_hookean(0.8e6, 40e6),
                        MeshLevel(2, 1, 12, 1))


def test_the_mass_matrix_carries_the_mass(tube):
    M = mass_matrix(tube.asm, 1100.0)
    for axis in np.eye(3):
        u = np.tile(axis, tube.asm.n_nodes)
        assert u @ (M @ u) == pytest.approx(1100.0 * np.pi * ((R + T / 2) ** 2 - (R - T / 2) ** 2) * L, rel=5e-4)   # the quadratic mesh approximates the circle
    assert abs(M - M.T).max() < 1e-15


def test_straight_tube_frequencies_match_the_beam_and_the_rod(tube):
    """Bending f₁ = 1.8751²/(2πL²) √(EI/m'), axial f = √(EA/m')/4L with EA, EI (tip-force, shear included)
    of the FEM's own equivalent rod and m' = ρA: within 3 % and 1 % (rotary inertia and shear make the
    3-D tube's bending mode a little lower)."""
    res = tube.solve()
    rod = tube.equivalent_rod(res)
    md = tube.modes(res, 6)
    mp = 1100.0 * np.pi * ((R + T / 2) ** 2 - (R - T / 2) ** 2)
    f_bend = 1.87510407 ** 2 / (2 * np.pi * L ** 2) * np.sqrt(rod["EI_tip_force"] / mp)
    f_axial = np.sqrt(rod["EA"] / mp) / (4 * L)
    f = md.frequencies_hz
    assert f[0] == pytest.approx(f[1], rel=1e-6)                       # two bending directions
    assert f[0] == pytest.approx(f_bend, rel=0.03)
    assert fem_axial(md, L) == pytest.approx(f_axial, rel=0.01)
    assert md.total_mass == pytest.approx(mp * L, rel=5e-4)


def test_locked_tendons_raise_every_frequency(tube):
    res = tube.solve(tensions=(1.0, 1.0, 1.0))
    held, locked = tube.modes(res, 4), tube.modes(res, 4, tendons="locked")
    assert np.all(locked.frequencies_hz >= held.frequencies_hz * (1 - 1e-9))
    assert locked.frequencies_hz[0] > 1.1 * held.frequencies_hz[0]
    with pytest.raises(InputError, match="tendons"):
        tube.modes(res, 2, tendons="free")


def test_the_reduced_paper_model_against_the_fem_modes():
    """The `paper` design (default mesh, unloaded, no gravity) beside the `paper` preset given the FEM's own
    masses (0.53 kg/m, 18 g cap at 2.5 mm): first bending 2.53 vs 2.53 Hz, axial 19.4 vs 20.0 Hz
    (docs/dynamics.md) — the identified rod is a dynamic model too, within 6 % and 5 %."""
    from ancf import Model, presets
    from validation.reference.designs import load_design
    geo, mat = load_design("paper")
    fem = BellowsModel(geo, mat, "coarse")
    md = fem.modes(fem.solve(), 6)
    line_mass = (md.total_mass - geo.cap_mass) / geo.length
    rod = Model(presets.paper().replace(gravity=(0, 0, 0), line_mass=line_mass, tip_mass=geo.cap_mass,
                                        tool_offset=geo.cap_com_offset))
    r = rod.modes(rod.fk((0, 0, 0), 0.0), 6)
    rod_axial = [f for f, s in zip(r.frequencies_hz, r.tip_shapes) if abs(s[0]) > 0.9 * np.linalg.norm(s)][0]
    assert r.frequencies_hz[0] == pytest.approx(md.frequencies_hz[0], rel=0.06)
    assert rod_axial == pytest.approx(fem_axial(md, geo.length), rel=0.05)


def test_pressure_stiffens_the_fem_bending_mode_but_not_the_rod():
    """The dynamic face of the pressure-dependent bending stiffness (docs/identification.md): from 0 to
    60 kPa the FEM's first bending frequency rises (2.53 → 2.91 Hz) while the stretch-only `paper` rod's
    falls (2.53 → 2.28 Hz: it lengthens, EI(λ) does not follow the pressure)."""
    from ancf import Model, presets
    from validation.reference.designs import load_design
    geo, mat = load_design("paper")
    fem = BellowsModel(geo, mat, "coarse")
    f_fem, f_rod = [], []
    for p in (0.0, 60e3):
        md = fem.modes(fem.solve(pressure=p), 2)
        rod = Model(presets.paper().replace(gravity=(0, 0, 0), line_mass=(md.total_mass - geo.cap_mass) / geo.length,
                                            tip_mass=geo.cap_mass, tool_offset=geo.cap_com_offset))
        f_fem.append(md.frequencies_hz[0])
        f_rod.append(rod.modes(rod.fk((0, 0, 0), p), 1).frequencies_hz[0])
    assert f_fem[1] > 1.1 * f_fem[0]
    assert f_rod[1] < 0.95 * f_rod[0]


@pytest.mark.slow
def test_the_documented_per_pressure_table_is_the_programs_output():
    """docs/dynamics.md's per-pressure table of FEM and rod modes, rerun (coarse mesh, ~40 s)."""
    import pathlib
    import re
    from ancf import Model, presets
    from validation.reference.designs import load_design
    text = (pathlib.Path(__file__).parents[2] / "docs" / "dynamics.md").read_text()
    rows = re.findall(r"^\| (\d+) \| ([\d.]+) \| ([\d.]+) \| ([\d.]+) \| ([\d.]+) \|$", text, re.M)
    assert len(rows) == 4
    geo, mat = load_design("paper")
    fem = BellowsModel(geo, mat, "coarse")
    for pk, fb, rb, fa, ra in rows:
        p = float(pk) * 1e3
        md = fem.modes(fem.solve(pressure=p), 6)
        rod = Model(presets.paper().replace(gravity=(0, 0, 0), line_mass=(md.total_mass - geo.cap_mass) / geo.length,
                                            tip_mass=geo.cap_mass, tool_offset=geo.cap_com_offset))
        r = rod.modes(rod.fk((0, 0, 0), p), 6)
        rod_axial = [x for x, s in zip(r.frequencies_hz, r.tip_shapes) if abs(s[0]) > 0.9 * np.linalg.norm(s)][0]
        assert md.frequencies_hz[0] == pytest.approx(float(fb), abs=0.006)
        assert r.frequencies_hz[0] == pytest.approx(float(rb), abs=0.006)
        assert fem_axial(md, geo.length) == pytest.approx(float(fa), abs=0.06)
        assert rod_axial == pytest.approx(float(ra), abs=0.06)
