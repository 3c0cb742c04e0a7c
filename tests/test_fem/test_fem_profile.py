"""A wall profile given as data (fem_reference.profile): the built-in sine written as a table and read back
reproduces the built-in mesh and an FEM result, converging with the table's spacing; every malformed table is a
ConfigError naming the file and the point, before any solve."""

import numpy as np
import pytest

from ancf.errors import ConfigError
from fem_reference import BellowsGeometry, BellowsModel, MeshLevel, build_mesh, presets
from fem_reference.profile import TableProfile, read_profile_csv, write_profile_csv


def _as_table(geo, n):
    return BellowsGeometry.from_profile(TableProfile.from_geometry(geo, n), geo.n_convolutions, geo.collar_length,
                                        tendon_radius=geo.tendon_radius, tendon_angles=geo.tendon_angles)


def test_sine_as_table_reproduces_the_built_in_mesh():
    """Node error O(h) where the built-in profile's curvature jumps (collar → convolution: the C² spline's slope
    is O(h) off there) and O(h⁴) elsewhere; the summary numbers converge to the built-in ones."""
    geo = presets.paper_bellows()
    bm = build_mesh(geo, "coarse")
    zz = bm.zeta[bm.lattice[0]]
    away = (np.abs(zz - geo.collar_length) > 2e-3) & (np.abs(zz - (geo.length - geo.collar_length)) > 2e-3)
    err, err_away = [], []
    for n in (1601, 3201, 6401):
        g2 = _as_table(geo, n)
        bm2 = build_mesh(g2, "coarse")
        assert np.array_equal(bm2.lattice, bm.lattice) and bm2.shape == bm.shape
        e = np.linalg.norm(bm2.X - bm.X, axis=0)
        err.append(e.max())
        err_away.append(e[away].max())
    assert err[-1] < 5e-6 * 1.0                                 # 3.4 µm on a 160 mm bellows
    assert 1.8 < err[0] / err[1] < 2.2 and 1.8 < err[1] / err[2] < 2.2          # first order: ×2 per 2× points
    assert err_away[2] < 1e-9 and err_away[0] / err_away[2] > 100              # ≈ h⁴ away from the junctions
    assert g2.wall_thickness == pytest.approx(geo.wall_thickness, rel=1e-5)
    assert g2.root_radius == pytest.approx(geo.root_radius, rel=1e-5)
    assert g2.crest_radius == pytest.approx(geo.crest_radius, rel=1e-6)
    assert g2.cap_inner_radius == pytest.approx(geo.cap_inner_radius, rel=1e-12)
    assert g2.wall_volume(4001) == pytest.approx(geo.wall_volume(4001), rel=1e-4)


def test_sine_as_table_reproduces_an_fem_result():
    """Tip position under 1 N on one tendon and 20 kPa (a small bellows, 2 convolutions, the coarsest mesh):
    the table's result converges to the built-in one at first order (the collar junction, above)."""
    geo = BellowsGeometry(0.05, 2, 0.008, 0.014, 0.002, collar_length=0.003, tendon_radius=0.016)
    lvl, mat = MeshLevel(2, 1, 6, 1), presets.paper_material()
    load = {"tensions": (1.0, 0.0, 0.0), "pressure": 20e3}
    ref = BellowsModel(geo, mat, lvl).solve(**load).tip_position
    disp = np.linalg.norm(ref - [geo.length, 0, 0])
    errs = [np.abs(BellowsModel(_as_table(geo, n), mat, lvl).solve(**load).tip_position - ref).max() / disp
            for n in (101, 401)]
    assert errs[1] < 1e-4                                  # measured 5.8e-5 (1601 points: 1.5e-5)
    assert 3.0 < errs[0] / errs[1] < 5.0


def test_csv_round_trip_and_both_layouts(tmp_path):
    prof = TableProfile.from_geometry(presets.paper_bellows("stiff"), 101)
    back = read_profile_csv(write_profile_csv(prof, tmp_path / "p.csv"))
    for a, b in ((prof.z_inner, back.z_inner), (prof.r_outer, back.r_outer)):
        assert np.allclose(a, b, rtol=1e-15, atol=1e-18)
    wide = tmp_path / "w.csv"
    z = np.linspace(0, 60, 31)
    ri = 10 + 2 * (1 - np.cos(2 * np.pi * z / 30))
    wide.write_text("# a comment\nz_mm, r_outer_cm, r_inner_mm\n"
                    + "\n".join(f"{a},{(b + 2) / 10},{b}" for a, b in zip(z, ri)))
    p = read_profile_csv(wide)
    assert p.length == pytest.approx(0.06) and p.r_outer[0] == pytest.approx(0.012)
    assert p.summary()["wall_thickness"] < 0.002 + 1e-12          # 2 mm radially, thinner along the normal


WIDE_OK = "z_mm,r_outer_mm,r_inner_mm\n0,12,10\n10,12,10\n20,14,12\n30,12,10\n40,12,10\n"


@pytest.mark.parametrize("text, message", [
    ("z,r_outer_mm,r_inner_mm\n0,12,10\n", "column 'z' needs a length unit"),
    ("z_in,r_outer_mm,r_inner_mm\n0,12,10\n", "needs a length unit"),
    (WIDE_OK.replace("20,14,12", "20,nan,12"), "line 4: r_outer_mm = 'nan' is not finite"),
    (WIDE_OK.replace("20,14,12", "20,14,abc"), "line 4: r_inner_mm = 'abc' is not a number"),
    ("z_mm,r_outer_mm,r_inner_mm\n0,12,10\n10,12,10\n20,12,10\n", "3 points; at least 4"),
    (WIDE_OK.replace("30,12,10", "15,12,10"), "point 4 .* does not come after point 3"),
    (WIDE_OK.replace("0,12,10\n", "1,12,10\n", 1), "must start on the base cap face"),
    (WIDE_OK.replace("20,14,12", "20,11,12"), "inner outline is not inside the outer one at z = 20"),
    (WIDE_OK.replace("20,14,12", "20,14,-1"), "point 3 has radius -1 mm"),
    (("outline,z_mm,r_mm\ninner,0,10\ninner,10,10\ninner,20,10\ninner,30,10\n"
      "outer,0,12\nouter,10,12\nouter,20,12\nouter,31,12\n"), "does not close"),
    ("outline,z_mm,r_mm\nmiddle,0,10\n", "line 2: outline must be 'inner' or 'outer'"),
    ("", "empty profile file"),
    # a narrow groove (curvature radius 0.17 mm at its bottom): the inner normals cross inside a 2 mm wall
    ("z_mm,r_outer_mm,r_inner_mm\n" + "\n".join(f"{z:.2f},20,{18 - 3 * np.exp(-((z - 20) / 1.0) ** 2):.9f}"
                                               for z in np.linspace(0, 40, 401)), "folds over itself"),
])
def test_bad_tables_are_config_errors_naming_file_and_point(tmp_path, text, message):
    p = tmp_path / "wall.csv"
    p.write_text(text)
    with pytest.raises(ConfigError, match=message) as exc:
        read_profile_csv(p)
    assert "wall.csv" in str(exc.value)


def test_missing_file_is_a_config_error(tmp_path):
    with pytest.raises(ConfigError, match="cannot read profile file"):
        read_profile_csv(tmp_path / "nope.csv")


def test_wall_too_thin_for_the_mesh_is_refused_before_meshing(tmp_path):
    """Rule: element length along the wall ≤ MAX_ASPECT × (local thickness / n_thick)."""
    z = np.linspace(0, 100, 41)
    p = tmp_path / "thin.csv"
    p.write_text("z_mm,r_outer_mm,r_inner_mm\n" + "\n".join(f"{a},10.2,10" for a in z))
    geo = BellowsGeometry.from_profile(read_profile_csv(p), 1, 0.0, tendon_radius=0.012)
    with pytest.raises(ConfigError, match=r"thin.csv: the wall is too thin for the mesh .*\(aspect 250 > 25\)"):
        build_mesh(geo, MeshLevel(2, 1, 6, 0))                       # 50 mm elements over 0.2 mm
    build_mesh(geo, MeshLevel(25, 1, 6, 0))                           # 4 mm over 0.2 mm: aspect 20


def test_table_fields_are_read_off_the_table():
    geo = _as_table(presets.paper_bellows("stiff"), 201)
    with pytest.raises(ConfigError, match="read off the table"):
        geo.replace(wall_thickness=0.005)
    with pytest.raises(ConfigError, match="sine"):
        geo.profile_mid(0.01)
    assert not geo.is_straight and geo.is_table


def test_geometry_counts_and_tendons_bounded():
    base = {"length": 0.16, "root_radius": 0.01, "crest_radius": 0.016, "wall_thickness": 0.002}
    with pytest.raises(ConfigError, match="n_convolutions must be an integer in 1 … 100"):
        BellowsGeometry(n_convolutions=10**9, **base)
    with pytest.raises(ConfigError, match="tendons 1 and 2 coincide"):
        BellowsGeometry(n_convolutions=4, tendon_angles=(0.0, 2 * np.pi, 1.0), **base)
    with pytest.raises(ConfigError, match="list of angles"):
        BellowsGeometry(n_convolutions=4, tendon_angles=0.0, **base)
    with pytest.raises(ConfigError, match="MeshLevel.n_theta must be an integer in 3 … 256"):
        MeshLevel(4, 2, 10**6)
    with pytest.raises(ConfigError, match="would not fit in memory"):
        build_mesh(BellowsGeometry.straight_tube(0.16, 0.015, 0.004, n_segments=100), MeshLevel(64, 16, 256))
