"""The symmetric factorisation with a low-rank correction (fem_reference.solver._NearlySymmetricFactor).

The FEM tangent is symmetric except in the rows and columns of the rigid cap's rotations (dead loads on a
rotating cap); ``factorize(K, "pardiso")`` factorises the symmetric part with LDLᵀ and corrects the rest by the
Woodbury identity.  Checked against a dense solve of the same matrix, for an indefinite symmetric part, and the
inertia it reports against the dense eigenvalues; a matrix that is not nearly symmetric takes the LU path."""

import numpy as np
import pytest
import scipy.sparse as sp

import fem_reference.solver as solver
from fem_reference.solver import available_solvers, factorize

pytestmark = pytest.mark.skipif("pardiso" not in available_solvers(), reason="pypardiso is not installed")


def _laplacian(n):
    t = sp.diags([-np.ones(n - 1), 2.0 * np.ones(n), -np.ones(n - 1)], [-1, 0, 1])
    eye = sp.identity(n)
    return (sp.kron(sp.kron(t, eye), eye) + sp.kron(sp.kron(eye, t), eye) + sp.kron(sp.kron(eye, eye), t)).tocsr()


def _nearly_symmetric(n, rows, shift, seed=0):
    """Laplacian − shift·I (indefinite for shift > 0) plus a dense non-symmetric block in ``rows``."""
    rng = np.random.default_rng(seed)
    N = n ** 3
    K = (_laplacian(n) - shift * sp.identity(N)).tolil()
    for i in rows:
        for j in rows:
            K[i, j] = K[i, j] + rng.uniform(-0.5, 0.5)
    return K.tocsr()


@pytest.mark.parametrize("shift", [0.0, 1.3])
def test_the_corrected_symmetric_solve_equals_a_dense_solve(shift):
    n, rows = 8, [3, 17, 200, 201, 400, 511]
    K = _nearly_symmetric(n, rows, shift)
    assert abs(K - K.T).max() > 0.1                           # really non-symmetric
    f = factorize(K, "pardiso")
    assert isinstance(f, solver._NearlySymmetricFactor)
    assert sorted(f.E.tolist()) == rows
    rng = np.random.default_rng(1)
    B = rng.standard_normal((n ** 3, 3))
    X = f.solve(B)
    Xd = np.linalg.solve(K.toarray(), B)
    assert np.abs(X - Xd).max() <= 1e-9 * np.abs(Xd).max()
    x1 = f.solve(B[:, 0])
    assert x1.shape == (n ** 3,) and np.allclose(x1, Xd[:, 0], rtol=0, atol=1e-9 * np.abs(Xd).max())
    # the inertia of the symmetric part, as PARDISO's LDLᵀ counts it
    S = 0.5 * (K + K.T).toarray()
    assert f.n_negative == int(np.sum(np.linalg.eigvalsh(S) < 0))
    assert (f.n_negative > 0) == (shift > 0)


def test_a_matrix_that_is_not_nearly_symmetric_is_factorised_by_lu():
    n = 6
    N = n ** 3
    rng = np.random.default_rng(2)
    K = (_laplacian(n) + sp.random(N, N, density=0.01, random_state=3) * 0.1).tocsr()  # asymmetric pattern too
    f = factorize(K, "pardiso")
    assert isinstance(f, solver._PardisoFactor) and f.slot.mtype == 11
    b = rng.standard_normal(N)
    assert np.abs(K @ f.solve(b) - b).max() < 1e-10
    # symmetric pattern but asymmetric values in many rows: LU as well
    K2 = _laplacian(n).tocoo()
    vals = K2.data * (1 + 0.1 * (K2.row > K2.col))
    K2 = sp.csr_matrix((vals, (K2.row, K2.col)), shape=K2.shape)
    f2 = factorize(K2, "pardiso")
    assert isinstance(f2, solver._PardisoFactor)
    assert np.abs(K2 @ f2.solve(b) - b).max() < 1e-10


def test_two_factors_alive_at_once_each_solve_their_own_matrix():
    n = 6
    K1 = _nearly_symmetric(n, [1, 2, 3], 0.0, seed=4)
    K2 = _nearly_symmetric(n, [1, 2, 3], 0.0, seed=5)
    f1, f2 = factorize(K1, "pardiso"), factorize(K2, "pardiso")
    b = np.ones(n ** 3)
    assert np.abs(K1 @ f1.solve(b) - b).max() < 1e-10       # f1 re-factorises: f2 holds the shared instance
    assert np.abs(K2 @ f2.solve(b) - b).max() < 1e-10


def test_duplicate_entries_are_summed_before_the_symmetric_maps():
    """A CSR matrix with every entry stored twice (two halves, indices sorted): its symmetric part and the
    correction are those of the summed matrix."""
    n = 6
    K = _nearly_symmetric(n, [1, 2, 3], 0.0, seed=6).tocsr()
    K.sort_indices()
    counts = np.diff(K.indptr)
    indptr = np.concatenate([[0], np.cumsum(2 * counts)])
    indices = np.repeat(K.indices, 2)                       # each column index twice, still non-decreasing
    data = np.repeat(K.data, 2) / 2
    Kd = sp.csr_matrix((data, indices, indptr), shape=K.shape)
    assert Kd.nnz == 2 * K.nnz and not Kd.has_canonical_format
    b = np.arange(n ** 3, dtype=float)
    x = factorize(Kd, "pardiso").solve(b)
    assert np.abs(K @ x - b).max() < 1e-9 * np.abs(b).max()
