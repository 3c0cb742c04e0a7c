"""The compiled split of a nearly symmetric CSR matrix (fem_reference._sparse_kernels) against the numpy
formulation it replaced, on random structurally symmetric patterns; its checks of the arrays it is given; and
the caps' reduction written straight onto the model-wide pattern (retarget) against the copy it saves."""

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import given, settings
from hypothesis import strategies as st

from ancf.errors import InputError
from fem_reference._sparse_kernels import SymmetricSplit
from fem_reference.solver import _SymmetricMaps


def _nearly_symmetric(n, density, n_asym, seed):
    rng = np.random.default_rng(seed)
    A = sp.random(n, n, density=density, random_state=rng, format="csr")
    S = (A + A.T + sp.eye(n)).tocsr()                  # a symmetric pattern with its diagonal
    S.sum_duplicates()
    S.sort_indices()
    K = S.copy()
    rows = rng.choice(n, size=min(n_asym, n), replace=False)
    for r in rows:                                      # perturb stored entries of a few rows only
        lo, hi = K.indptr[r], K.indptr[r + 1]
        K.data[lo:hi] += rng.normal(0.0, 1.0, hi - lo)
    return K


def _numpy_split(K, maps, roundoff):
    d, dt = K.data, K.data[maps.perm]
    big = np.abs(0.5 * (d - dt)) > roundoff * max(float(np.abs(d).max(initial=0.0)), 1e-300)
    rows = np.unique(np.searchsorted(K.indptr, np.flatnonzero(big), side="right") - 1)
    n = K.shape[0]
    r = np.repeat(np.arange(n), np.diff(K.indptr))
    return (0.5 * (d + dt))[K.indices >= r], rows


@settings(max_examples=40, deadline=None)
@given(st.integers(1, 60), st.floats(0.0, 0.3), st.integers(0, 5), st.integers(0, 2**31 - 1))
def test_the_split_equals_the_numpy_formulation(n, density, n_asym, seed):
    K = _nearly_symmetric(n, density, n_asym, seed)
    maps = _SymmetricMaps(K)
    assert maps.symmetric_pattern
    upper, rows = maps.splitter().split(K.data, 1e-14)
    ref_upper, ref_rows = _numpy_split(K, maps, 1e-14)
    np.testing.assert_array_equal(upper, ref_upper)
    np.testing.assert_array_equal(rows, ref_rows)
    U = sp.csr_matrix((upper, maps.indices_u, maps.indptr_u), shape=K.shape)
    np.testing.assert_allclose(sp.triu(0.5 * (K + K.T)).toarray(), U.toarray(), rtol=0, atol=1e-15)


def test_the_split_refuses_arrays_that_do_not_fit():
    K = _nearly_symmetric(8, 0.3, 1, 0)
    maps = _SymmetricMaps(K)
    ip, ix, perm, nu = K.indptr, K.indices, maps.perm, maps.indices_u.size
    for args in ((ip[:-1], ix, perm, nu),                       # row pointer short of the entries
                 (ip, ix, perm[:-1], nu),                       # permutation of another size
                 (ip, np.where(ix == ix.max(), 99, ix), perm, nu),   # a column beyond the matrix
                 (ip, ix, perm + 1, nu),                        # a permutation entry out of range
                 (ip, ix, perm, ix.size + 1),                   # more upper entries than entries
                 (ip.astype(float), ix, perm, nu)):             # not integers
        with pytest.raises(InputError):
            SymmetricSplit(*args)
    ok = SymmetricSplit(ip, ix, perm, nu)
    with pytest.raises(InputError, match="float64"):
        ok.split(K.data.astype(np.float32), 1e-14)
    with pytest.raises(InputError, match="float64"):
        ok.split(K.data[:-1], 1e-14)
    with pytest.raises(InputError, match="roundoff"):
        ok.split(K.data, np.nan)


def test_the_reduced_tangent_written_on_the_model_pattern_equals_the_copied_one():
    """After the first tangent the caps' reduction writes on the model-wide pattern (no per-evaluation copy):
    the tangents then are the same numbers as the reduction's own pattern copied into it."""
    from fem_reference import BellowsModel, MeshLevel
    from fem_reference.model import LoadCase
    from fem_reference.presets import paper_bellows, paper_material
    mesh = MeshLevel(2, 1, 12, 1)                      # small: the same code paths as the default mesh
    model = BellowsModel(paper_bellows(), paper_material(), mesh=mesh)
    res = model.solve(tensions=(2.0, 0.5, 0.0), pressure=30e3, check_stability=False)
    lc = LoadCase(np.array([2.0, 0.5, 0.0]), 30e3, np.zeros(3), 0.0, np.full(3, np.nan))
    K1 = model.evaluate(res.state, lc)["K"]
    m = model.caps._map
    assert m.target is model._pattern and K1._written_on is model._pattern           # retargeted
    fresh = BellowsModel(paper_bellows(), paper_material(), mesh=mesh)
    K0 = fresh.evaluate(res.state.copy(), lc)["K"]                                    # first: copied in
    assert not hasattr(K0, "_written_on")                                             # a copy
    assert np.array_equal(K0.indptr, K1.indptr) and np.array_equal(K0.indices, K1.indices)
    np.testing.assert_allclose(K1.data, K0.data, rtol=1e-13, atol=1e-9 * np.abs(K0.data).max())
