"""Transfer of a solved state to a finer mesh (fem_reference.transfer): the lattice interpolation against closed
forms, an affine displacement field carried exactly across meshes with different reference geometry, the added
nodes, and the finer mesh's solve from the transferred state against its solve from rest."""

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ancf.errors import InputError
from fem_reference import BellowsModel
from fem_reference import transfer as T
from fem_reference.mesh import MeshLevel
from fem_reference.presets import paper_bellows, paper_material
from fem_reference.sparse_keys import csr_index, unique_keys

# one element through the wall keeps the test cheap; 2 per convolution would be too crude for the transfer (its
# tip moves 6 % of L on refinement, outside Newton's basin at full load; the solve then climbs from rest)
SMALL = MeshLevel(n_per_conv=4, n_thick=1, n_theta=6)
FINE = MeshLevel(n_per_conv=8, n_thick=1, n_theta=6, n_collar=2)
LOADS = dict(tensions=(2.0, 0.5, 0.0), pressure=20e3)


@pytest.fixture(scope="module")
def models():
    geo, mat = paper_bellows(), paper_material()
    return BellowsModel(geo, mat, mesh=SMALL), BellowsModel(geo, mat, mesh=FINE)


@pytest.fixture(scope="module")
def coarse_solution(models):
    return models[0].solve(**LOADS)


def test_interpolation_reproduces_piecewise_quadratics_and_their_derivatives():
    rng = np.random.default_rng(1)
    nodes = np.concatenate([[0.0], np.cumsum(rng.uniform(0.5, 1.5, 8))])    # 4 quadratic elements
    x = np.sort(rng.uniform(nodes[0], nodes[-1], 200))
    coef = rng.standard_normal((4, 3))
    f = lambda e, t: coef[e, 0] + coef[e, 1] * t + coef[e, 2] * t ** 2
    for k in range(4):      # element k's own polynomial on its three nodes, zero elsewhere
        local = nodes[2 * k: 2 * k + 3]
        v = np.zeros_like(nodes)
        v[2 * k: 2 * k + 3] = f(k, local)
        inside = (x >= local[0]) & (x <= local[-1])
        P = T.interpolation_matrix(nodes, x[inside])
        D = T.interpolation_matrix(nodes, x[inside], derivative=True)
        assert np.allclose(P @ v, f(k, x[inside]), atol=1e-12)
        assert np.allclose(D @ v, coef[k, 1] + 2 * coef[k, 2] * x[inside], atol=1e-10)
    with pytest.raises(InputError, match="outside"):
        T.interpolation_matrix(nodes, [nodes[-1] + 1.0])
    with pytest.raises(InputError, match="whole quadratic elements"):
        T.interpolation_matrix(nodes[:-1], [0.1])


def test_periodic_interpolation_is_exact_for_a_period_two_quadratic_lattice():
    n = 48
    h = 2 * np.pi * np.arange(n) / n
    v = np.cos(h)
    P = T.interpolation_matrix(h, h + 2 * np.pi * 3, periodic=2 * np.pi)      # whole periods away: the nodes
    assert np.allclose(P @ v, v, atol=1e-14)
    x = np.linspace(-1.0, 8.0, 50)
    assert np.allclose(T.interpolation_matrix(h, x, periodic=2 * np.pi) @ v, np.cos(x), atol=3e-4)     # O(h³)
    P = T.interpolation_matrix(h, x, periodic=2 * np.pi)
    assert np.allclose(P.sum(axis=1), 1.0)


def test_snapshot_on_its_own_mesh_is_the_identity(models, coarse_solution):
    snap = T.snapshot(coarse_solution)
    assert abs(T.interpolate(snap, models[0].bmesh) - coarse_solution.state.U).max() < 1e-15
    assert not T.new_nodes(snap, models[0].bmesh).any()


def test_an_affine_displacement_is_carried_exactly_to_a_mesh_with_other_reference_points(models, coarse_solution):
    coarse, fine = models
    snap = T.snapshot(coarse_solution)
    A = np.array([[0.02, -0.3, 0.1], [0.25, -0.01, 0.05], [-0.1, 0.07, 0.03]])
    c = np.array([1e-3, -2e-3, 5e-4])
    Ulin = np.einsum("ij,jzth->izth", A, snap.X) + c[:, None, None, None]
    moved = dataclasses.replace(snap, U=Ulin)
    out = T.interpolate(moved, fine.bmesh)
    exact = A @ fine.bmesh.X + c[:, None]
    assert abs(out - exact).max() < 1e-14 * max(1.0, abs(exact).max()) * 1e3
    # the coarse mesh's own reference points between its nodes are not the finer mesh's: interpolating the
    # displacement alone would not carry the field exactly (the correction is what the test checks)
    plain = np.einsum("zi,tj,hk,dijk->dzth", T.interpolation_matrix(snap.zeta, T.lattice_coordinates(fine.bmesh)[0]),
                      T.interpolation_matrix(snap.tau, T.lattice_coordinates(fine.bmesh)[1]),
                      T.interpolation_matrix(snap.theta, T.lattice_coordinates(fine.bmesh)[2], periodic=2 * np.pi),
                      Ulin)[:, fine.bmesh.lattice[0], fine.bmesh.lattice[1], fine.bmesh.lattice[2]]
    assert abs(plain - exact).max() > 1e3 * abs(out - exact).max()


def test_added_nodes_of_a_refinement_along_the_profile_are_the_odd_rows(models, coarse_solution):
    snap = T.snapshot(coarse_solution)
    mask = T.new_nodes(snap, models[1].bmesh)
    assert np.array_equal(mask, models[1].bmesh.lattice[0] % 2 == 1)


def test_fine_solve_from_the_transferred_state_is_the_fine_equilibrium(models, coarse_solution):
    coarse, fine = models
    cold = fine.solve(**LOADS)
    start = T.start_from(T.snapshot(coarse_solution), fine)
    warm = fine.solve(**LOADS, initial=start, max_cuts=0)
    assert np.linalg.norm(warm.tip_position - cold.tip_position) < 1e-9
    assert np.allclose(warm.tensions, cold.tensions)
    assert warm.stable
    assert warm.iterations <= cold.iterations // 3          # measured 6 against 26
    assert len(warm.stats.steps) == 1                      # one load step at full load


def test_relaxing_the_added_nodes_lowers_their_residual(models, coarse_solution):
    coarse, fine = models
    snap = T.snapshot(coarse_solution)
    start = T.start_from(snap, fine, relax=False)
    hist = T.relax_new_nodes(fine, start.state, start.loadcase, T.new_nodes(snap, fine.bmesh))
    assert len(hist) >= 2 and hist[-1] < 1e-3 * hist[0]


def test_start_from_refuses_another_design(models, coarse_solution):
    from fem_reference.presets import paper_bellows as pb
    snap = T.snapshot(coarse_solution)
    other = dataclasses.replace(pb(), wall_thickness=pb().wall_thickness * 0.9)
    with pytest.raises(InputError, match="another geometry"):
        T.start_from(dataclasses.replace(snap, geometry=other), models[1])


@settings(max_examples=50, deadline=None)
@given(st.lists(st.integers(0, 40), min_size=0, max_size=60))
def test_unique_keys_match_numpy(values):
    keys = np.array(values, np.int64)
    u = unique_keys(keys)
    assert np.array_equal(u, np.unique(keys))
    u2, inv = unique_keys(keys, return_inverse=True)
    assert np.array_equal(u2, u) and np.array_equal(u2[inv], keys)
    if values:
        with pytest.raises(InputError):
            unique_keys(keys.astype(float))


@settings(max_examples=30, deadline=None)
@given(st.integers(1, 7), st.data())
def test_csr_index_matches_scipy(n, data):
    import scipy.sparse as sp
    pairs = data.draw(st.lists(st.tuples(st.integers(0, n - 1), st.integers(0, n - 1)), max_size=30))
    keys = unique_keys(np.array([r * n + c for r, c in pairs], np.int64))
    indptr, indices = csr_index(keys, n)
    ref = sp.csr_matrix((np.ones(keys.size), (keys // n, keys % n)), shape=(n, n))
    ref.sort_indices()
    assert np.array_equal(indptr, ref.indptr) and np.array_equal(indices, ref.indices)
