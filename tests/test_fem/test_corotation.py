"""The ring-wise finite-rotation correction of Newton updates (fem_reference.corotation): a rigid rotation of a ring
is carried exactly, the correction is second order in the step, and solves with and without it reach the same
equilibrium."""

import numpy as np
import pytest

import fem_reference.model as fem_model
from fem_reference import BellowsModel
from fem_reference.corotation import ring_rotation_correction
from fem_reference.loads.caps import expm_so3
from fem_reference.mesh import MeshLevel
from fem_reference.presets import paper_bellows, paper_material


def _rings(seed=0, n_r=4, per=12):
    rng = np.random.default_rng(seed)
    x = rng.standard_normal((3, n_r * per)) * 0.01
    rings = np.repeat(np.arange(n_r), per)
    rng.shuffle(rings)
    return x, rings, rng


def test_a_rigid_rotation_of_each_ring_is_carried_exactly():
    x, rings, rng = _rings()
    th = rng.standard_normal((rings.max() + 1, 3)) * 0.3
    c = rng.standard_normal((rings.max() + 1, 3)) * 1e-3
    xb = np.stack([np.bincount(rings, weights=x[i]) / np.bincount(rings) for i in range(3)])
    r = x - xb[:, rings]
    lin = c[rings].T + np.cross(th[rings].T, r, axis=0)              # the linearised rigid increment
    exact = c[rings].T + np.einsum("nij,jn->in", np.array([expm_so3(t) for t in th])[rings], r) - r
    out = lin + ring_rotation_correction(x, lin, rings)
    assert abs(out - exact).max() < 1e-15
    # small turns are left linear (the tail of a Newton solve)
    small = 0.9e-3 / np.linalg.norm(th, axis=1).max()
    assert not ring_rotation_correction(x, small * lin, rings).any()
    # distances within each ring are kept
    y = x + out
    for k in range(rings.max() + 1):
        idx = np.flatnonzero(rings == k)
        d0 = np.linalg.norm(x[:, idx, None] - x[:, None, idx], axis=0)
        d1 = np.linalg.norm(y[:, idx, None] - y[:, None, idx], axis=0)
        assert abs(d1 - d0).max() < 1e-15


def test_the_correction_is_second_order_in_the_step():
    x, rings, rng = _rings(1)
    du = rng.standard_normal(x.shape) * 1e-3
    eps = np.logspace(-3, 0, 6)
    size = [np.linalg.norm(ring_rotation_correction(x, e * du, rings, min_angle=0.0)) for e in eps]
    slope = np.polyfit(np.log(eps), np.log(size), 1)[0]
    assert slope == pytest.approx(2.0, abs=0.02)


def test_solves_with_and_without_the_correction_reach_the_same_equilibrium(monkeypatch):
    model = BellowsModel(paper_bellows(), paper_material(), mesh=MeshLevel(n_per_conv=4, n_thick=1, n_theta=6))
    loads = dict(tensions=(2.0, 0.0, 0.0), pressure=0.0)
    with_rings = model.solve(**loads)
    monkeypatch.setattr(fem_model, "RING_UPDATE", False)
    without = model.solve(**loads)
    assert np.linalg.norm(with_rings.tip_position - without.tip_position) < 1e-9
    assert with_rings.stats.n_factorizations < without.stats.n_factorizations


def test_mismatched_inputs_are_refused():
    from ancf.errors import InputError
    x, rings, _ = _rings()
    for bad in ((x[:2], x[:2], rings), (x, x[:, :-1], rings), (x, x, rings[:-1]), (x, x, rings.astype(float)),
                (x, x, rings - 1)):
        with pytest.raises(InputError):
            ring_rotation_correction(*bad)
