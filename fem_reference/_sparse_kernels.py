r"""Compiled (numba) pass over a nearly symmetric CSR matrix for :func:`fem_reference.solver.factorize`.

The FEM tangent ``K`` is symmetric but for a few rows and columns (the rotational stiffness of dead loads on
the rigid cap).  The solver factorises its symmetric part ``S = (K + Kᵀ)/2`` and corrects for the
antisymmetric part ``A = (K − Kᵀ)/2`` in the rows where it is not round-off (:class:`~fem_reference.solver.
_NearlySymmetricFactor`).  With ``perm`` the permutation of the data array for which ``Kᵀ.data ==
K.data[perm]`` (a structurally symmetric pattern), one pass gives both:

.. math::

    S_{ij} = \tfrac12 (K_{ij} + K_{ji}) \quad (j \ge i,\ \text{the upper triangle PARDISO's LDLᵀ reads}), \qquad
    \text{row } i \text{ flagged} \iff \max_j \tfrac12 |K_{ij} - K_{ji}| > \epsilon \max |K| .

The numpy form of the same (five passes over the ≈ 4 M entries of the default mesh's tangent: 35–40 ms per
factorisation, 6 % of a sweep) is kept in the tests as the reference.  :func:`symmetric_split` checks the
arrays before the kernel sees them.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .errors import InputError


@njit(cache=True)
def _split(indptr, indices, data, perm, roundoff, n_upper):
    amax = 0.0
    for j in range(data.size):
        a = abs(data[j])
        if a > amax:
            amax = a
    thr = roundoff * max(amax, 1e-300)
    n = indptr.size - 1
    upper = np.empty(n_upper)
    flag = np.zeros(n, np.bool_)
    k = 0
    for r in range(n):
        for j in range(indptr[r], indptr[r + 1]):
            dt = data[perm[j]]
            if abs(0.5 * (data[j] - dt)) > thr:
                flag[r] = True
            if indices[j] >= r:
                upper[k] = 0.5 * (data[j] + dt)
                k += 1
    return upper, flag


class SymmetricSplit:
    """The pass of the module docstring for one CSR pattern: ``SymmetricSplit(indptr, indices, perm, n_upper)``
    checks the pattern once (a CSR row pointer, column indices in range, ``perm`` a permutation of the data with
    ``Kᵀ.data == data[perm]``, ``n_upper`` entries with column ≥ row); ``split(data, roundoff)`` then checks
    only the data (float64, one value per entry) → ``(S_upper (n_upper,), rows (k,))``: the upper triangle of
    ``(K + Kᵀ)/2`` in CSR order and the rows whose antisymmetric part exceeds ``roundoff`` × max |K|.
    InputError on arrays that do not fit together."""

    def __init__(self, indptr: np.ndarray, indices: np.ndarray, perm: np.ndarray, n_upper: int):
        indptr = np.ascontiguousarray(indptr)
        indices = np.ascontiguousarray(indices)
        perm = np.ascontiguousarray(perm, dtype=np.int64)
        if indptr.dtype.kind != "i" or indices.dtype.kind != "i":
            raise InputError("SymmetricSplit: indptr and indices must be integer arrays")
        nnz = indices.size
        if indptr.ndim != 1 or indptr.size < 1 or indptr[0] != 0 or indptr[-1] != nnz or np.any(np.diff(indptr) < 0):
            raise InputError("SymmetricSplit: indptr is not a CSR row pointer for the indices")
        n = indptr.size - 1
        if indices.ndim != 1 or perm.shape != (nnz,):
            raise InputError(f"SymmetricSplit: perm {perm.shape} must have the {nnz} entries of the indices")
        if nnz and (indices.min() < 0 or indices.max() >= n or perm.min() < 0 or perm.max() >= nnz):
            raise InputError("SymmetricSplit: a column index or a permutation entry is out of range")
        if isinstance(n_upper, bool) or not 0 <= int(n_upper) <= nnz:
            raise InputError(f"SymmetricSplit: n_upper must be in [0, {nnz}], got {n_upper}")
        self.indptr, self.indices, self.perm, self.n_upper = indptr, indices, perm, int(n_upper)

    def split(self, data: np.ndarray, roundoff: float) -> tuple[np.ndarray, np.ndarray]:
        data = np.ascontiguousarray(data)
        if data.dtype != np.float64 or data.shape != self.indices.shape:
            raise InputError(f"SymmetricSplit.split: data must be float64 of shape {self.indices.shape}, got "
                             f"{data.dtype} {data.shape}")
        if not (np.isfinite(roundoff) and roundoff >= 0):
            raise InputError(f"SymmetricSplit.split: roundoff must be finite and >= 0, got {roundoff}")
        upper, flag = _split(self.indptr, self.indices, data, self.perm, float(roundoff), self.n_upper)
        return upper, np.flatnonzero(flag)
