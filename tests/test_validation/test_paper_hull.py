"""Convex-hull volume and distance helpers of validation.paper, against exact volumes of known shapes."""

import math

import numpy as np
import pytest

from validation.paper import hull_distance, hull_volume


def test_cube_corners_exact():
    corners = np.array([[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1)], float) * 0.02
    assert hull_volume(corners) == pytest.approx(0.02 ** 3, rel=1e-12)


def test_tetrahedron_exact_and_interior_points_do_not_count():
    tet = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    rng = np.random.default_rng(1)
    w = rng.dirichlet(np.ones(4), 500)          # convex combinations: all inside
    assert hull_volume(np.vstack([tet, w @ tet])) == pytest.approx(1 / 6, rel=1e-12)


def test_sampled_cube_converges_from_below():
    rng = np.random.default_rng(0)
    vols = [hull_volume(rng.uniform(-1, 1, (n, 3))) for n in (200, 2000, 20000)]
    assert all(v <= 8.0 for v in vols)
    assert vols[0] < vols[1] < vols[2]
    assert vols[2] == pytest.approx(8.0, rel=0.02)


def test_sphere_surface_samples():
    rng = np.random.default_rng(2)
    u = rng.normal(size=(4000, 3))
    r = 0.05
    P = r * u / np.linalg.norm(u, axis=1, keepdims=True) + np.array([0.16, 0.0, -0.01])
    exact = 4 / 3 * math.pi * r ** 3
    v = hull_volume(P)
    assert v < exact
    assert v == pytest.approx(exact, rel=0.01)


def test_degenerate_clouds_give_zero_and_nan_rows_are_ignored():
    flat = np.column_stack([np.random.default_rng(3).uniform(size=(50, 2)), np.zeros(50)])
    assert hull_volume(flat) == 0.0
    assert hull_volume(np.zeros((3, 3))) == 0.0
    cube = np.array([[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1)], float)
    assert hull_volume(np.vstack([cube, np.full((5, 3), np.nan)])) == pytest.approx(1.0)


def test_hull_distance_signs_and_values():
    cube = np.array([[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1)], float)
    d = hull_distance([[0.5, 0.5, 0.5], [0.5, 0.5, 1.3], [0.1, 0.5, 0.5]], cube)
    assert d[0] == pytest.approx(-0.5)
    assert d[1] == pytest.approx(0.3)
    assert d[2] == pytest.approx(-0.1)
