"""Fixed sparsity patterns from entry keys (``row * n + col``, int64): the sorted distinct keys and the CSR
index arrays they define.

Every fixed pattern of the FEM (the volume matrix, the cap-reduced tangent, the symmetric-subspace tangent,
the model-wide pattern with the tendons' blocks) is built this way once per model.  ``np.unique`` is not
used for it: on numpy ≥ 2.3 its default path for plain integers is a hash table that took 8.3 s for 8
million keys against 0.09 s for a sort (measured on the 2-core machine, numpy 2.4), which made building
a model's first tangent take seconds.
"""

from __future__ import annotations

import numpy as np

from .errors import InputError

__all__ = ["unique_keys", "csr_index"]


def unique_keys(keys: np.ndarray, return_inverse: bool = False):
    """Sorted distinct values of the int64 array ``keys`` (1-D); with ``return_inverse``, also the index of
    each key's value in them (``out[inverse] == keys``).  InputError for keys that are not integers."""
    keys = np.asarray(keys).ravel()
    if keys.size and keys.dtype.kind not in "iu":
        raise InputError(f"unique_keys: integer keys needed, got {keys.dtype}")
    if not return_inverse:
        s = np.sort(keys)
        return s[np.concatenate(([True], s[1:] != s[:-1]))] if s.size else s
    order = np.argsort(keys, kind="stable")
    s = keys[order]
    first = np.concatenate(([True], s[1:] != s[:-1])) if s.size else np.zeros(0, bool)
    inverse = np.empty(keys.size, np.int64)
    inverse[order] = np.cumsum(first) - 1
    return s[first], inverse


def csr_index(ukeys: np.ndarray, n: int, index_dtype=np.int32) -> tuple[np.ndarray, np.ndarray]:
    """``(indptr, indices)`` of the n × n CSR pattern whose entries are the sorted distinct keys ``ukeys``
    (``row * n + col``); indptr in ``index_dtype`` when it fits (else int64), indices int32."""
    counts = np.bincount(ukeys // n, minlength=n) if ukeys.size else np.zeros(n, np.int64)
    indptr = np.concatenate(([0], np.cumsum(counts)))
    if indptr[-1] >= 2**31:
        index_dtype = np.int64
    return indptr.astype(index_dtype), (ukeys % n).astype(np.int32)
