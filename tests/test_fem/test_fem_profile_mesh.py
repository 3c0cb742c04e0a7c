"""A wall profile read from a 2-D mesh of the meridian section (fem_reference.section_mesh): a triangulated (or
quad, or outline-only) section of the built-in sine wall, written with meshio in several formats, reads back as
the sine's own outline points; every broken section is a ConfigError naming the file, before any mesh or solve."""

import meshio
import numpy as np
import pytest

from ancf.errors import ConfigError
from fem_reference import BellowsGeometry, build_mesh, presets
from fem_reference.profile import TableProfile, read_profile
from validation.reference.designs import design_to_toml, load_design

NZ, NT = 161, 2                  # rows along the axis, layers through the wall


def _section(geo, nz=NZ, nt=NT, unit=1e-3):
    """Points (x = r, y = z) [unit] on the exact offset lines τ_j, shape (nz·(nt+1), 2), and the index grid."""
    z = np.linspace(0.0, geo.length, nz)
    taus = np.linspace(-geo.wall_thickness / 2, geo.wall_thickness / 2, nt + 1)
    X = np.stack([geo.map_points(z, tau, 0.0) for tau in taus], axis=2)       # (3, nz, nt+1)
    pts = np.stack([X[2].ravel(), X[0].ravel()], axis=1) / unit
    return pts, np.arange(pts.shape[0]).reshape(nz, nt + 1)


def _quads(idx):
    a, b = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel()
    c, d = idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    return np.stack([a, b, c, d], axis=1)


def _triangles(idx):
    q = _quads(idx)
    return np.concatenate([q[:, [0, 1, 2]], q[:, [0, 2, 3]]])


def _outline(idx):
    """The boundary polyline as line cells: up the inner line, across the top, down the outer, across the base."""
    loop = list(idx[:, 0]) + list(idx[-1, 1:]) + list(idx[-2::-1, -1]) + list(idx[0, -2:0:-1])
    return np.stack([loop, loop[1:] + loop[:1]], axis=1)


def _write(path, pts, cells, **kw):
    meshio.write(path, meshio.Mesh(np.c_[pts, np.zeros(len(pts))], cells), **kw)
    return path


GEO = presets.paper_bellows("stiff")


@pytest.mark.parametrize("name, kind, kw", [
    ("wall.vtu", "triangle", {}), ("wall.msh", "triangle", {"file_format": "gmsh22"}),
    ("wall.vtk", "quad", {}), ("wall.obj", "triangle", {}), ("wall.xdmf", "quad", {}), ("wall.vtu", "line", {})])
def test_a_section_mesh_reads_as_the_outline_points(tmp_path, name, kind, kw):
    """Triangles, quads or the outline alone, in five formats: the outlines are the exact offset points of the
    rows (what TableProfile.from_geometry samples), to round-off of the mm → m conversion."""
    pts, idx = _section(GEO)
    cells = {"triangle": _triangles, "quad": _quads, "line": _outline}[kind](idx)
    prof = read_profile(_write(tmp_path / name, pts, [(kind, cells)], **kw), "mm")
    ref = TableProfile.from_geometry(GEO, NZ)
    for a, b in ((prof.z_inner, ref.z_inner), (prof.r_inner, ref.r_inner), (prof.z_outer, ref.z_outer),
                 (prof.r_outer, ref.r_outer)):
        assert np.allclose(a, b, rtol=0, atol=1e-15)
    assert prof.source_unit == "mm" and prof.source.endswith(name)


def test_units_and_orientation_do_not_matter(tmp_path):
    """The same section in metres, with the cells' vertex order reversed (the loop runs the other way)."""
    pts, idx = _section(GEO, unit=1.0)
    tri = _triangles(idx)[:, ::-1]
    prof = read_profile(_write(tmp_path / "wall_m.vtu", pts, [("triangle", tri)]), "m")
    ref = TableProfile.from_geometry(GEO, NZ)
    assert np.allclose(prof.r_outer, ref.r_outer, rtol=0, atol=1e-15)
    assert np.allclose(prof.z_inner, ref.z_inner, rtol=0, atol=1e-15)


def test_a_design_names_the_mesh_and_its_unit(tmp_path):
    """profile_file = "wall.msh" with profile_unit = "mm": the design meshes like the same table as a CSV; it
    writes back (design_to_toml) with its unit and reads back equal."""
    pts, idx = _section(GEO)
    _write(tmp_path / "wall.msh", pts, [("triangle", _triangles(idx))], file_format="gmsh22")
    body = ('name = "lab"\nprofile_file = "wall.msh"\nprofile_unit = "mm"\nn_convolutions = 6\n'
            'collar_length_mm = 5\ntendon_radius_mm = 24\n\n[material]\nmu_MPa = 0.8\nkappa_MPa = 40\n')
    (tmp_path / "d.toml").write_text(body)
    geo, mat = load_design(str(tmp_path / "d.toml"))
    assert geo.is_table and geo.length == pytest.approx(GEO.length, rel=1e-15)
    ref = BellowsGeometry.from_profile(TableProfile.from_geometry(GEO, NZ), 6, 0.005, tendon_radius=0.024)
    assert np.abs(build_mesh(geo, "coarse").X - build_mesh(ref, "coarse").X).max() < 1e-15
    (tmp_path / "back.toml").write_text(design_to_toml(geo, mat))
    assert load_design(str(tmp_path / "back.toml"))[0] == geo
    (tmp_path / "nounit.toml").write_text(body.replace('profile_unit = "mm"\n', ""))
    with pytest.raises(ConfigError, match="a mesh file states no unit.*profile_unit"):
        load_design(str(tmp_path / "nounit.toml"))
    (tmp_path / "stray.toml").write_text(body.replace('profile_file = "wall.msh"\n', "")
                                         .replace("n_convolutions", "length_mm = 160\nroot_radius_mm = 12\n"
                                                  "crest_radius_mm = 18\nwall_thickness_mm = 4\nn_convolutions"))
    with pytest.raises(ConfigError, match="profile_unit is the length unit of a profile_file mesh"):
        load_design(str(tmp_path / "stray.toml"))


def _broken(kind):
    """(points, cells) of a section broken in one way."""
    pts, idx = _section(GEO)
    tri = _triangles(idx)
    if kind == "third coordinate":
        return np.c_[pts, np.linspace(0, 1, len(pts))], [("triangle", tri)]
    if kind == "volume":
        return pts, [("tetra", np.array([[0, 1, 2, 3]]))]
    if kind == "two regions":
        other = pts + [30.0, 0.0]
        return np.r_[pts, other], [("triangle", np.r_[tri, tri + len(pts)])]
    if kind == "hole":                       # 4 layers; the middle two removed over rows 80 … 82
        pts, idx = _section(GEO, nt=4)
        q = _quads(idx)
        row, layer = np.divmod(np.arange(len(q)), 4)
        keep = ~((row >= 80) & (row <= 82) & (layer >= 1) & (layer <= 2))
        return pts, [("quad", q[keep])]
    if kind == "open":
        return pts, [("line", _outline(idx)[:-1])]
    if kind == "base off zero":
        return pts + [0.0, 1.0], [("triangle", tri)]
    if kind == "top not flat":               # the outer outline's last point raised by 1 mm
        p = pts.copy()
        p[idx[-1, -1], 1] += 1.0
        return p, [("triangle", tri)]
    if kind == "crossing":                   # an outline (lines) whose outer line dips through the inner one
        p = pts.copy()
        p[idx[80, -1], 0] = p[idx[80, 0], 0] - 1.0
        return p, [("line", _outline(idx))]
    if kind == "quadratic":
        return pts, [("triangle6", np.c_[tri, tri])]
    raise AssertionError(kind)


@pytest.mark.parametrize("kind, message", [
    ("third coordinate", "not a 2-D section: the points leave the plane"),
    ("volume", "not a 2-D section mesh: it holds tetra cells"),
    ("two regions", "more than one region: the cells form 2 parts"),
    ("hole", r"boundary is 2 closed loops, not one \(a hole\)"),
    ("open", r"the boundary does not close: it ends at \(r = "),
    ("base off zero", "the base end face is at z = 1, not at z = 0"),
    ("top not flat", ("distal end face z = 161 is not one flat edge: only the point .* inner and the outer "
                      "outline must end at the same z")),
    ("crossing", "the outline crosses itself"),
    ("quadratic", "cells of kind 'triangle6' are not read"),
])
def test_broken_sections_are_config_errors_naming_the_file(tmp_path, kind, message):
    pts, cells = _broken(kind)
    path = tmp_path / "broken.vtu"
    meshio.write(path, meshio.Mesh(pts if pts.shape[1] == 3 else np.c_[pts, np.zeros(len(pts))], cells))
    with pytest.raises(ConfigError, match=message) as exc:
        read_profile(path, "mm")
    assert "broken.vtu" in str(exc.value)


def test_unreadable_files_and_units_are_config_errors(tmp_path):
    bad = tmp_path / "wall.msh"
    bad.write_text("this is no mesh\n")
    with pytest.raises(ConfigError, match="cannot read profile mesh .*wall.msh"):
        read_profile(bad, "mm")
    with pytest.raises(ConfigError, match="cannot read profile mesh .*nope.vtu: no such file"):
        read_profile(tmp_path / "nope.vtu", "mm")
    with pytest.raises(ConfigError, match="length unit of a profile mesh must be one of m, cm, mm"):
        read_profile(bad, "inch")
    with pytest.raises(ConfigError, match="a mesh file states no unit"):
        read_profile(bad)
    with pytest.raises(ConfigError, match="a CSV profile states its units in its header"):
        read_profile(tmp_path / "wall.csv", "mm")
    with pytest.raises(ConfigError, match=r"must be a CSV table \(.csv\) or a 2-D section mesh"):
        read_profile(tmp_path / "wall.dat")
