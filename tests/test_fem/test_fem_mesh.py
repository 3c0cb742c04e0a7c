"""Geometry validation, structured Hex2 mesh: Jacobian sign check, meshio round trip, convergence rate."""

import numpy as np
import pytest

from ancf.errors import ConfigError
from fem_reference import BellowsGeometry, MeshLevel, build_mesh, presets
from fem_reference.mesh import BellowsMesh, check_jacobians


def test_geometry_validation():
    with pytest.raises(ConfigError, match="metres"):
        BellowsGeometry(length=160.0, n_convolutions=8, root_radius=12.0, crest_radius=18.0, wall_thickness=4.0)
    with pytest.raises(ConfigError, match="too tight"):
        BellowsGeometry(0.16, 30, 0.008, 0.025, 0.004)
    with pytest.raises(ConfigError):
        BellowsGeometry(0.16, 8, 0.012, 0.013, 0.004)  # crest inside the wall
    tube = BellowsGeometry.straight_tube(0.16, 0.015, 0.004)
    assert tube.is_straight and tube.r_root_mid == pytest.approx(0.015)
    r, dr = presets.paper_bellows().profile_mid(np.array([0.0, 0.16]))
    assert np.allclose(dr, 0.0)  # flat end annuli


def test_mesh_nodes_on_exact_geometry_and_jacobians():
    geo = presets.paper_bellows()
    bm = build_mesh(geo, "coarse")
    lo, hi = check_jacobians(bm.mesh)
    assert lo * hi > 0
    n_s, n_t, n_th = bm.shape
    tau = np.linspace(-geo.wall_thickness / 2, geo.wall_thickness / 2, 2 * n_t + 1)
    theta = np.pi * np.arange(2 * n_th) / n_th
    X = geo.map_points(bm.zeta[bm.lattice[0]], tau[bm.lattice[1]], theta[bm.lattice[2]])
    assert np.abs(X - bm.X).max() < 1e-15
    # inner facets lie on the inner surface: radius in [r_root, r_crest - t]
    f = bm.inner_facets()
    assert f.size == n_s * n_th
    # end faces are planar
    assert np.allclose(bm.X[0, bm.nodes_where(i_s=0)], 0.0, atol=1e-15)
    assert np.allclose(bm.X[0, bm.nodes_where(i_s=2 * n_s)], geo.length, atol=1e-15)


def test_mixed_jacobian_signs_raise():
    from skfem import MeshHex2

    bm = build_mesh(BellowsGeometry.straight_tube(0.05, 0.01, 0.002, n_segments=2), MeshLevel(1, 1, 6, 1))
    p = bm.mesh.doflocs.copy()
    from skfem import ElementHex2
    from skfem.assembly import Dofs

    ed = Dofs(bm.mesh, ElementHex2()).element_dofs
    p[:, ed[26, 0]] += np.array([0.0, 0.05, 0.05])  # drag the interior node of element 0 far outside
    with pytest.raises(ConfigError, match="inverted"):
        check_jacobians(MeshHex2(p, bm.mesh.t))


def test_meshio_round_trip(tmp_path):
    geo = BellowsGeometry(0.06, 2, 0.01, 0.014, 0.002, collar_length=0.002)
    bm = build_mesh(geo, MeshLevel(2, 1, 6, 1))
    path = bm.save(tmp_path / "m.vtu")
    bm2 = BellowsMesh.load(path)
    assert bm2.shape == bm.shape and bm2.n_nodes == bm.n_nodes
    # same node set with the same lattice labels
    key = lambda b: np.lexsort(b.lattice)
    assert np.array_equal(bm.lattice[:, key(bm)], bm2.lattice[:, key(bm2)])
    assert np.allclose(bm.X[:, key(bm)], bm2.X[:, key(bm2)], atol=1e-14)
    assert bm2.volume() == pytest.approx(bm.volume(), rel=1e-12)


def test_volume_converges_at_fourth_order():
    """Curved Hex2 geometry: the wall volume converges as O(h^4) to Pappus' value (log-log fit)."""
    geo = presets.paper_bellows()
    V = geo.wall_volume()
    hs, errs = [], []
    for n in (2, 3, 4, 6):
        bm = build_mesh(geo, MeshLevel(n, 1, 3 * n, 1))
        hs.append(1.0 / n)
        errs.append(abs(bm.volume() - V) / V)
    rate = np.polyfit(np.log(hs), np.log(errs), 1)[0]
    assert 3.5 < rate < 4.8, (rate, errs)
