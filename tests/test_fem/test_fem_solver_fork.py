"""A forked worker factorises with a fresh PARDISO handle, not the parent's (fem_reference.solver).

FEM sweeps fork their workers after the parent has factorised (the rod estimate): the workers of
`bellows report --quick` died with a segmentation fault inside PARDISO when they went on with the parent's
handle and analysis.  After a fork the child has no PARDISO state of the parent's and factorises correctly."""

import multiprocessing as mp

import numpy as np
import pytest
import scipy.sparse as sp

import fem_reference.solver as solver
from fem_reference.solver import available_solvers, factorize


def _matrix(n, shift):
    """A 3-D Laplacian on an n³ grid, shifted."""
    t = sp.diags([-np.ones(n - 1), 2.0 * np.ones(n), -np.ones(n - 1)], [-1, 0, 1])
    eye = sp.identity(n)
    L = sp.kron(sp.kron(t, eye), eye) + sp.kron(sp.kron(eye, t), eye) + sp.kron(sp.kron(eye, eye), t)
    return (L + sp.diags(1.0 + shift * np.arange(n ** 3) / n ** 3)).tocsr()


def _child(queue, n):
    state = tuple(x for slot in solver._SLOTS.values() for x in (slot.solver is None, slot.pattern is None))
    A = _matrix(n, 1.0)
    x = factorize(A, "pardiso").solve(np.ones(n ** 3))
    queue.put((state, float(np.abs(A @ x - 1.0).max())))


@pytest.mark.skipif("pardiso" not in available_solvers(), reason="pypardiso is not installed")
def test_a_forked_child_factorises_with_a_fresh_pardiso_handle():
    if "fork" not in mp.get_all_start_methods():
        pytest.skip("no fork on this platform")
    n = 16
    factorize(_matrix(n, 0.0), "pardiso").solve(np.ones(n ** 3))    # the parent's handles and analyses:
    factorize(_matrix(n, 0.0), "pardiso_lu").solve(np.ones(n ** 3))  # symmetric LDLᵀ and LU
    assert all(slot.solver is not None and slot.pattern is not None for slot in solver._SLOTS.values())
    ctx = mp.get_context("fork")
    q = ctx.Queue()
    p = ctx.Process(target=_child, args=(q, n))
    p.start()
    p.join(60)
    assert p.exitcode == 0
    fresh, residual = q.get(timeout=5)
    assert fresh == (True,) * 2 * len(solver._SLOTS)
    assert residual < 1e-10
    assert all(slot.solver is not None for slot in solver._SLOTS.values())          # the parent keeps its own
