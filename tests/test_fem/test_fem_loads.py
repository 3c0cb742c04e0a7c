"""Loads: follower pressure and its load stiffness, gravity, tendon routing, the full reduced tangent."""

import numpy as np
import pytest

from fem_reference import BellowsGeometry, BellowsModel, MeshLevel, presets
from fem_reference.assembly import HexAssembler, PressureAssembler
from fem_reference.loads.caps import expm_so3, log_so3
from fem_reference.mesh import build_mesh

TINY = MeshLevel(2, 1, 12, 1)


@pytest.fixture(scope="module")
def tube_mesh():
    return build_mesh(BellowsGeometry.straight_tube(0.08, 0.015, 0.004, n_segments=4), TINY)


@pytest.fixture(scope="module")
def small_model():
    geo = BellowsGeometry(0.08, 4, 0.012, 0.018, 0.004, collar_length=0.004, cap_mass=0.01,
                          cap_com_offset=0.003, tip_offset=0.01)
    return BellowsModel(geo, presets.paper_material(), TINY)


def test_pressure_load_stiffness_matches_central_fd(tube_mesh):
    bm = tube_mesh
    pa = PressureAssembler(bm.mesh, bm.inner_facets())
    rng = np.random.default_rng(3)
    U = 5e-4 * rng.standard_normal((3, bm.n_nodes))
    p = 3e4
    f, K = pa.assemble(U, p)
    d = rng.standard_normal(U.shape)
    h = 1e-7
    fd = (pa.assemble(U + h * d, p, False)[0] - pa.assemble(U - h * d, p, False)[0]) / (2 * h)
    an = K @ d.T.ravel()
    assert np.linalg.norm(fd - an) < 1e-6 * np.linalg.norm(an)
    # non-symmetric on an open surface (docs/fem.md §2)
    assert abs(K - K.T).max() > 1e-3 * abs(K).max()


def test_pressure_resultant_equals_p_times_projected_area(tube_mesh):
    """Half of the inner cylinder (y > 0) at u = 0 pushes with p · 2 r_i L along +y."""
    bm = tube_mesh
    geo = bm.geometry
    m = bm.mesh
    f_all = bm.inner_facets()
    mid = m.p[:, m.facets[:, f_all]].mean(axis=1)
    half = f_all[mid[1] > 0]
    pa = PressureAssembler(m, half)
    f, _ = pa.assemble(np.zeros((3, bm.n_nodes)), 1.0)
    F = f.reshape(-1, 3).sum(axis=0)
    assert F[1] == pytest.approx(2 * geo.root_radius * geo.length, rel=1e-6)
    assert abs(F[0]) < 1e-12 and abs(F[2]) < 1e-6 * F[1]
    f_all_, _ = PressureAssembler(m, f_all).assemble(np.zeros((3, bm.n_nodes)), 1.0)
    assert np.abs(f_all_.reshape(-1, 3).sum(axis=0)).max() < 1e-12  # closed ring, open ends: zero net


def test_internal_tangent_matches_central_fd(tube_mesh):
    asm = HexAssembler(tube_mesh.mesh, presets.paper_material())
    rng = np.random.default_rng(4)
    U = 3e-4 * rng.standard_normal((3, tube_mesh.n_nodes))
    f, K, jmin = asm.assemble(U)
    assert jmin > 0
    d = rng.standard_normal(U.shape)
    h = 1e-8
    fd = (asm.assemble(U + h * d, False)[0] - asm.assemble(U - h * d, False)[0]) / (2 * h)
    an = K @ d.T.ravel()
    assert np.linalg.norm(fd - an) < 1e-6 * np.linalg.norm(an)


def test_gravity_load_is_the_weight(small_model):
    M = small_model
    F = M.f_gravity.reshape(-1, 3).sum(axis=0)
    W = M.material.density * M.bmesh.volume() * 9.81
    assert F[2] == pytest.approx(-W, rel=1e-12) and abs(F[0]) < 1e-15


def test_tendon_straight_length_and_routing(small_model):
    M = small_model
    st = M.zero_state()
    L = M.tendon_lengths(st)
    assert np.allclose(L, M.geometry.length, rtol=1e-12)
    x = M.bmesh.X
    for tp in M.tendons:
        pts = tp.points(x, M.X_c, np.eye(3))
        r = np.hypot(pts[:, 1], pts[:, 2])
        assert np.allclose(r, M.geometry.tendon_radius, rtol=1e-12)


def test_reduced_tangent_matches_fd_of_reduced_residual(small_model):
    """Exact Newton matrix: internal + follower pressure + cap pressure + tendons + tip + cap weight,
    with every rigid-link geometric term, at a rotated, deformed, non-equilibrium state."""
    M = small_model
    rng = np.random.default_rng(5)
    res = M.solve(tensions=(4.0, 0.0, 1.0), pressure=1e4, tip_force=(0, 0.5, 0))
    assert np.linalg.norm(res.cap_rotation_vector) > 0.05
    st = M._apply(res.state, 2e-5 * rng.standard_normal(M.n_dofs))
    st.T[:] = [1.5, 0.4, 0.0]
    lc = M._loadcase(st.T, 2e4, (0.3, -0.2, -0.5), True, None)
    ev = M.evaluate(st, lc)
    K = ev["K"]
    d = rng.standard_normal(M.n_dofs)
    d[M.caps.n_free + 3:] *= 10.0
    h = 1e-7
    rp = M.evaluate(M._apply(st, d, h), lc, tangent=False)["r"]
    rm = M.evaluate(M._apply(st, d, -h), lc, tangent=False)["r"]
    fd = (rp - rm) / (2 * h)
    an = K @ d
    assert np.linalg.norm(fd - an) < 1e-6 * np.linalg.norm(an)
    # tendon gradient = d(length)/dq
    Lp = M.tendon_lengths(M._apply(st, d, h))
    Lm = M.tendon_lengths(M._apply(st, d, -h))
    assert np.allclose((Lp - Lm) / (2 * h), ev["g"].T @ d, rtol=1e-6, atol=1e-12)


def test_tendon_hessian_blocks_match_fd_of_the_length_gradient(small_model):
    """Each tendon's Hessian (the dense blocks added in place into the model-wide pattern) equals the
    central difference of its length gradient, at a rotated, deformed state, cap rotation included."""
    M = small_model
    rng = np.random.default_rng(11)
    res = M.solve(tensions=(3.0, 1.0, 0.0), pressure=1e4)
    st = M._apply(res.state, 2e-5 * rng.standard_normal(M.n_dofs))
    h = 1e-7
    for k in range(M.m):
        H = M._tendon_hessian(st, k)
        d = rng.standard_normal(M.n_dofs)
        d[M.caps.n_free + 3:] *= 10.0
        gp = M._tendon_terms(M._apply(st, d, h), k, False)[1]
        gm = M._tendon_terms(M._apply(st, d, -h), k, False)[1]
        fd = (gp - gm) / (2 * h)
        an = H @ d
        assert np.linalg.norm(fd - an) < 1e-6 * np.linalg.norm(an), k
        A = (H - H.T).tocoo()  # symmetric but in the cap rotation block (the rigid link's geometric term)
        rot = M.caps.n_free + 3
        off = (A.row < rot) | (A.col < rot)
        assert np.abs(A.data[off]).max(initial=0.0) < 1e-9 * abs(H).max()
        # and the whole reduced tangent carries it: K(T_k = 1) − K(T_k = 0) is this Hessian
        lc = M._loadcase(np.zeros(M.m), 1e4, (0, 0, 0), False, None)
        s0, s1 = st.copy(), st.copy()
        s0.T[:], s1.T[:] = 0.0, 0.0
        s1.T[k] = 1.0
        dK = M.evaluate(s1, lc)["K"] - M.evaluate(s0, lc)["K"]
        assert abs(dK - H).max() < 1e-9 * abs(H).max()


def test_so3_maps():
    w = np.array([0.3, -1.1, 0.7])
    R = expm_so3(w)
    assert np.allclose(R @ R.T, np.eye(3), atol=1e-14) and np.isclose(np.linalg.det(R), 1.0)
    assert np.allclose(log_so3(R), w, atol=1e-12)
