"""The built-in profile as a table with slopes (fem_reference.profile_export, the ``dr_dz`` column): exact at the
rows it lists, so meshes and FEM results of the table and of the built-in design agree to round-off; between
the rows the Hermite outline converges at O(h³) in the nodes where the slope-free C² spline converges at O(h)
(the collar/convolution curvature jump, the reason given in profile_export's docstring)."""

import math

import numpy as np
import pytest
import typer

from ancf import clitools
from ancf.errors import ConfigError
from fem_reference import BellowsGeometry, BellowsModel, MeshLevel, build_mesh, presets
from fem_reference.mesh import lattice_rows
from fem_reference.profile import TableProfile, read_profile_csv, write_profile_csv
from fem_reference.profile_export import export_profile, export_rows
from validation.commands.fem_profile import profile as profile_command
from validation.reference.designs import load_design


def _table_geometry(geo, prof):
    return BellowsGeometry.from_profile(prof, geo.n_convolutions, geo.collar_length, tendon_radius=geo.tendon_radius,
                                        tendon_angles=geo.tendon_angles, cap_mass=geo.cap_mass,
                                        cap_com_offset=geo.cap_com_offset, tip_offset=geo.tip_offset)


def _through_csv(prof, tmp_path):
    return read_profile_csv(write_profile_csv(prof, tmp_path / "wall.csv"))


def test_exported_table_reproduces_every_built_in_mesh_to_round_off(tmp_path):
    """All three built-in levels of the paper design, through the CSV file: node distance ≤ 1e-15 m (measured
    4e-17 m), where the slope-free table of the same rows is micrometres off."""
    geo = presets.paper_bellows()
    prof = _through_csv(export_profile(geo, ("coarse", "medium")), tmp_path)
    g2 = _table_geometry(geo, prof)
    for level in ("coarse", "medium"):
        a, b = build_mesh(geo, level), build_mesh(g2, level)
        assert np.array_equal(a.lattice, b.lattice)
        assert np.abs(a.X - b.X).max() <= 1e-15
    plain = TableProfile(prof.z_inner, prof.r_inner, prof.z_outer, prof.r_outer)      # the same points, no slopes
    assert np.abs(build_mesh(_table_geometry(geo, plain), "coarse").X - build_mesh(geo, "coarse").X).max() > 1e-7
    assert g2.cap_inner_radius == geo.cap_inner_radius
    assert g2.wall_thickness == pytest.approx(geo.wall_thickness, rel=1e-6)


def test_exported_table_reproduces_an_fem_tip_to_round_off(tmp_path):
    """A small bellows (2 convolutions, the coarsest mesh), 1 N on one tendon and 20 kPa: the tip of the design
    and of its exported table agree to ≤ 1e-9 of the tip displacement."""
    geo = BellowsGeometry(0.05, 2, 0.008, 0.014, 0.002, collar_length=0.003, tendon_radius=0.016)
    lvl, mat = MeshLevel(2, 1, 6, 1), presets.paper_material()
    load = {"tensions": (1.0, 0.0, 0.0), "pressure": 20e3}
    ref = BellowsModel(geo, mat, lvl).solve(**load).tip_position
    g2 = _table_geometry(geo, _through_csv(export_profile(geo, [lvl], spacing=1e-3), tmp_path))
    tip = BellowsModel(g2, mat, lvl).solve(**load).tip_position
    assert np.abs(tip - ref).max() <= 1e-9 * np.linalg.norm(ref - [geo.length, 0, 0])


@pytest.mark.slow
def test_paper_design_and_its_exported_table_give_the_same_fem_tip(tmp_path):
    """The paper design on the coarse mesh, 1 N and 20 kPa (measured: 3.5e-13 relative; 23 s for the two solves)."""
    geo, mat = presets.paper_bellows(), presets.paper_material()
    g2 = _table_geometry(geo, _through_csv(export_profile(geo, ("coarse",)), tmp_path))
    load = {"tensions": (1.0, 0.0, 0.0), "pressure": 20e3}
    a = BellowsModel(geo, mat, "coarse").solve(**load).tip_position
    b = BellowsModel(g2, mat, "coarse").solve(**load).tip_position
    assert np.abs(a - b).max() <= 1e-9 * np.linalg.norm(a - [geo.length, 0, 0])


def test_with_slopes_the_wall_converges_at_third_order_without_at_first():
    """Rows: the collar/convolution junctions and a uniform fill of spacing h; the wall points of 3001 rows ζ
    (mostly between table points) against the built-in map.  Halving h: the largest error ÷ ≈ 8 with slopes (the
    Hermite slope is O(h³) off; measured 7.9, 8.2), ÷ ≈ 2 without (the C² spline's slope next to the curvature
    jump is O(h) off; measured 2.2, 2.5; 29 µm at 0.25 mm)."""
    geo = presets.paper_bellows()
    ends = lattice_rows(geo, MeshLevel(1, 1, 6, 1))[::2]
    zz = np.linspace(0, geo.length, 3001)
    xi = geo.map_points(zz, -geo.wall_thickness / 2, 0.0)[[0, 2]]
    xo = geo.map_points(zz, geo.wall_thickness / 2, 0.0)[[0, 2]]
    errs = {True: [], False: []}
    for n in (321, 641, 1281):
        fill = np.linspace(0, geo.length, n)
        p = TableProfile.exact_at_rows(geo, np.union1d(ends, fill[np.abs(fill[:, None] - ends).min(axis=1) > 1e-9]))
        for slopes, t in ((True, p), (False, TableProfile(p.z_inner, p.r_inner, p.z_outer, p.r_outer))):
            pi, po = t.wall_points(zz)
            errs[slopes].append(max(np.abs(pi - xi).max(), np.abs(po - xo).max()))
    with_s, without = np.array(errs[True]), np.array(errs[False])
    assert np.all((6.5 < with_s[:-1] / with_s[1:]) & (with_s[:-1] / with_s[1:] < 10))
    assert np.all((1.6 < without[:-1] / without[1:]) & (without[:-1] / without[1:] < 2.8))
    assert with_s[-1] < 1e-7 < without[-1]


def test_export_rows_and_refusals():
    geo = presets.paper_bellows()
    rows = export_rows(geo, ("coarse",), spacing=1e-3)
    assert set(build_mesh(geo, "coarse").zeta) <= set(rows)
    assert np.diff(rows).max() <= 1e-3 + 1e-15 and rows[0] == 0.0 and rows[-1] == geo.length
    assert np.diff(rows).min() > 1e-9 * geo.length
    for bad in (0.0, -1.0, float("nan"), 1.0):
        with pytest.raises(ConfigError, match="spacing must be a number in"):
            export_rows(geo, ("coarse",), spacing=bad)
    with pytest.raises(ConfigError, match="unknown mesh level 'fine'"):
        export_rows(geo, ("fine",))
    table = _table_geometry(geo, export_profile(geo, ("coarse",), spacing=1e-3))
    with pytest.raises(ConfigError, match="already a table"):
        export_profile(table)


def test_slope_column_reads_with_units_and_is_checked(tmp_path):
    """dr_dz is a ratio: z in mm and r in cm scale it by 10; a slope off zero at a cap face, a missing slope or a
    wrongly named slope column is a ConfigError naming the file."""
    prof = TableProfile.exact_at_rows(presets.paper_bellows("stiff"), np.linspace(0, 0.16, 201))
    back = _through_csv(prof, tmp_path)
    assert back.dr_inner == prof.dr_inner and back.has_slopes
    f = tmp_path / "s.csv"
    rows = [("inner", z, 1.0 + 0.1 * math.sin(math.pi * z / 40) ** 2, 0.1 * math.pi / 40 * math.sin(math.pi * z / 20))
            for z in np.linspace(0, 40, 9).tolist()]
    rows += [("outer", z, r + 0.2, d * 10) for (_, z, r, d) in rows]          # outer: the inner + 2 mm (r in cm)
    text = "outline,z_mm,r_cm,dr_dz\n" + "\n".join(f"{o},{z!r},{r!r},{d!r}" for o, z, r, d in rows[:9]) + "\n"
    text += "\n".join(f"{o},{z!r},{r!r},{d / 10!r}" for o, z, r, d in rows[9:])
    f.write_text(text)
    p = read_profile_csv(f)
    assert p.dr_inner[2] == pytest.approx(10 * rows[2][3], rel=1e-15)
    assert p._inner(p.z_inner[2], 1) == pytest.approx(p.dr_inner[2], rel=1e-12)         # Hermite: exact slope
    for bad_text, message in [
        (text.replace("outline,z_mm,r_cm,dr_dz", "outline,z_mm,r_cm,slope"), "optionally dr_dz"),
        (text.replace("inner,0.0,1.0,0.0", "inner,0.0,1.0,0.01"), "slope dr/dz = 0.1 on the base cap face"),
        ("outline,z_mm,r_mm,dr_dz\ninner,0,1\n", "line 2: 3 values, expected 4"),
    ]:
        f.write_text(bad_text)
        with pytest.raises(ConfigError, match=message) as exc:
            read_profile_csv(f)
        assert "s.csv" in str(exc.value)
    with pytest.raises(ConfigError, match="4 points but 3 slopes"):
        TableProfile((0, 1, 2, 3), (1, 1, 1, 1), (0, 1, 2, 3), (2, 2, 2, 2), "t", (0, 0, 0), (0, 0, 0, 0))


def _run(capsys, argv):
    app = typer.Typer(add_completion=False)
    app.command("profile")(profile_command)
    app.command("other", hidden=True)(lambda: None)                # a group: the command is named on the line
    with pytest.raises(SystemExit) as info:
        clitools.run(typer.main.get_command(app), ["profile", *argv])
    return info.value.code, capsys.readouterr()


def test_command_writes_a_table_a_design_reads_and_refuses_to_overwrite(tmp_path, capsys):
    out = tmp_path / "wall.csv"
    code, io = _run(capsys, ["--export", str(out), "--mesh", "coarse", "--spacing-mm", "1"])
    assert code in (0, None) and f"wrote {out}" in io.out
    (tmp_path / "d.toml").write_text('profile_file = "wall.csv"\nn_convolutions = 8\ncollar_length_mm = 5\n'
                                     'tendon_radius_mm = 27.5\n\n[material]\nmu_MPa = 0.8\nkappa_MPa = 40\n')
    geo, _ = load_design(str(tmp_path / "d.toml"))
    ref = presets.paper_bellows()
    assert np.abs(build_mesh(geo, "coarse").X - build_mesh(ref, "coarse").X).max() <= 1e-15
    for argv, message in [(["--export", str(out)], "exists; add --force"),
                          (["--export", str(tmp_path / "w.txt")], "ending in .csv"),
                          (["--export", str(tmp_path / "w2.csv"), "--mesh", "fine"], "--mesh must be 'all'"),
                          (["--export", str(tmp_path / "w2.csv"), "--spacing-mm", "0"], "--spacing-mm"),
                          (["--export", str(tmp_path / "w2.csv"), "--design", str(tmp_path / "d.toml")],
                           "already a table")]:
        code, io = _run(capsys, argv)
        lines = [ln for ln in io.err.splitlines() if ln.strip()]
        assert code == 2 and len(lines) == 1 and lines[0].startswith("error: ") and message in lines[0], io.err
    code, io = _run(capsys, ["--export", str(out), "--mesh", "coarse", "--spacing-mm", "1", "--force"])
    assert code in (0, None)


def test_calibrate_refuses_a_table_design_s_dimensions_up_front():
    """A table design's wall_thickness / radii / collar are not free numbers (the table is the shape): refused
    before any FEM solve, naming the table; the material stays adjustable (design_to_toml keeps the table)."""
    from ancf.errors import InputError
    from validation.identification.calibrate import calibrate

    geo = presets.paper_bellows()
    table = _table_geometry(geo, TableProfile.exact_at_rows(geo, np.linspace(0, geo.length, 401)))
    for name in ("wall_thickness", "collar_length"):
        with pytest.raises(InputError, match=f"cannot adjust {name} of a design whose wall profile is a table"):
            calibrate({"EA": 100.0}, table, presets.paper_material(), {name: (1e-3, 1e-2)}, progress=False)


def test_a_table_design_s_metadata_is_json_naming_the_file():
    """Result metadata (identify's meta, saved as JSON by the report) names the table by file and data hash."""
    import json

    from ancf.export import to_jsonable
    from validation.identification.identify import _geometry_meta

    geo = presets.paper_bellows()
    prof = TableProfile.exact_at_rows(geo, np.linspace(0, geo.length, 401), source="/x/wall.csv")
    meta = json.loads(json.dumps(to_jsonable(_geometry_meta(_table_geometry(geo, prof)))))
    assert meta["profile"]["profile_file"] == "/x/wall.csv" and meta["profile"]["points_inner"] == 401
    assert meta["profile"]["slopes"] is True and meta["length"] == geo.length
    other = TableProfile(prof.z_inner, prof.r_inner, prof.z_outer, prof.r_outer[:-1] + (prof.r_outer[-1] * 1.001,),
                         prof.source, prof.dr_inner, prof.dr_outer)
    assert other.describe()["sha256"] != prof.describe()["sha256"]
    assert json.dumps(to_jsonable(_geometry_meta(geo)))              # the built-in profile: unchanged fields
