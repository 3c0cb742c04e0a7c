"""Sparse direct solvers and the Newton / load-stepping driver.

Linear solver choice (measured in ``docs/fem.md`` §4 and ``benchmarks/bench_fem.py``):
``pypardiso`` (MKL PARDISO, real non-symmetric ``mtype=11`` because the follower-pressure tangent is
non-symmetric) when importable, else ``scipy.sparse.linalg.splu(A, permc_spec="MMD_AT_PLUS_A")``.
Plain ``spsolve`` is never used (it ignores ``permc_spec`` and is 3–5× slower).  Measured by
``benchmarks/bench_fem.py`` on the tangent of the combined load case (2 cores), factorisation +
one solve: 14k DOFs — PARDISO with the analysis reused 0.11 s, PARDISO with a fresh analysis 0.22 s,
SuperLU symmetric mode 0.44 s, SuperLU default pivoting 4.4 s; 97k DOFs (reference mesh) —
2.2 s, 5.3 s, 11.3 s (SuperLU default pivoting not run: minutes).  SuperLU is run in
symmetric mode with a small diagonal pivot threshold (see :class:`_SpluFactor`; 20× faster than its
default partial pivoting on this structurally symmetric tangent).

Newton (``BellowsModel._newton`` in :mod:`fem_reference.model`): full Newton on the reduced system with

- a backtracking line search on the step length α: halve α while the trial iterate has ``det F <= 0``
  at any Gauss point (inadmissible), is not finite, or its residual exceeds ``growth × ‖r‖``;
- optional bordered (KKT) solve for length constraints via the Schur complement
  ``(gᵀ K⁻¹ g) Δλ = c − gᵀ K⁻¹ r`` with one factorisation;
- convergence when ``‖r‖ <= max(atol, rtol · f_ref)`` and ``|c| <= ctol``;
- on failure a :class:`StepFailed` carrying the residual history; the load stepper in
  :mod:`fem_reference.model` cuts the increment and finally raises :class:`ancf.errors.ConvergenceError`.
"""

from __future__ import annotations

import glob
import os
import sys
from contextlib import contextmanager
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ancf.errors import ConfigError

__all__ = ["NewtonStats", "StepFailed", "available_solvers", "factorize"]


@contextmanager
def _mkl_rt_hint():
    """Within the block, ``PYPARDISO_MKL_RT`` names the mkl wheel's ``sys.prefix/lib/libmkl_rt*`` if there is one.

    Importing pypardiso creates a solver, and each ``PyPardisoSolver()`` looks for MKL's runtime by a
    recursive glob of ``sys.prefix/lib*`` (0.5–1.2 s measured on this machine, more than a coarse
    factorisation) unless that variable names it.  A variable set by the user is left alone; without a
    library in the usual place pypardiso searches as before.
    """
    if "PYPARDISO_MKL_RT" in os.environ:
        yield
        return
    cands = sorted(glob.glob(os.path.join(sys.prefix, "lib", "libmkl_rt.so*"))
                   + glob.glob(os.path.join(sys.prefix, "lib", "libmkl_rt*.dylib")), key=len)
    if cands:
        os.environ["PYPARDISO_MKL_RT"] = cands[0]
    try:
        yield
    finally:
        if cands:
            os.environ.pop("PYPARDISO_MKL_RT", None)


def _import_pypardiso():
    """``import pypardiso`` (see :func:`_mkl_rt_hint`)."""
    with _mkl_rt_hint():
        import pypardiso
    return pypardiso


def available_solvers() -> list[str]:
    """Names accepted by :func:`factorize` that work in this environment."""
    out = ["splu"]
    try:
        _import_pypardiso()

        out.insert(0, "pardiso")
    except Exception:  # pragma: no cover
        pass
    try:
        import scikits.umfpack  # noqa: F401

        out.append("umfpack")
    except Exception:
        pass
    return out


class _SpluFactor:
    """SuperLU with the minimum-degree ordering of ``A + Aᵀ`` and *symmetric mode*.

    The tangent is structurally symmetric and nearly symmetric in value, so diagonal pivots are
    preferred (``diag_pivot_thresh=0.1``, ``SymmetricMode``): with SuperLU's default partial
    pivoting (threshold 1.0) the row exchanges destroy the fill-reducing order — measured on the
    7.6k-DOF test bellows: fill 14.9 M → 2.8 M and factorisation 4.2 s → 0.19 s, same accuracy.
    """

    def __init__(self, A, symmetric_mode: bool = True):
        kw = dict(diag_pivot_thresh=0.1, options=dict(SymmetricMode=True)) if symmetric_mode else {}
        self.lu = spla.splu(A.tocsc(), permc_spec="MMD_AT_PLUS_A", **kw)

    def solve(self, b):
        return self.lu.solve(np.asarray(b, float))


_PARDISO_SOLVER = None


def _pardiso_instance():
    """One shared ``PyPardisoSolver(mtype=11)`` per process.

    Creating a ``PyPardisoSolver`` globs the file system for the MKL library (0.5–0.8 s measured; avoided
    where :func:`_mkl_rt_hint` finds it), more than a whole factorisation of the test meshes.  Sharing is safe: ``solve`` re-factorises if it
    is handed a matrix other than the one last factorised (pypardiso compares a hash).
    """
    global _PARDISO_SOLVER
    if _PARDISO_SOLVER is None:
        pypardiso = _import_pypardiso()
        with _mkl_rt_hint():
            _PARDISO_SOLVER = pypardiso.PyPardisoSolver(mtype=11)
    return _PARDISO_SOLVER


_LAST_PATTERN: tuple | None = None  # (indptr, indices) of the last analysed matrix
_OWNER = [0]  # id of the factor object whose numeric factorisation the shared instance holds


def _forget_pardiso_in_child() -> None:
    """A forked worker must not use the parent's PARDISO handle: its internal memory and the analysis it
    refers to belong to the parent (reusing them crashed forked FEM workers with a segmentation fault when the
    parent had factorised a matrix of the same pattern before the fork, e.g. the rod estimate of a sweep).
    The child starts with a fresh instance and a fresh analysis."""
    global _PARDISO_SOLVER, _LAST_PATTERN
    _PARDISO_SOLVER = None
    _LAST_PATTERN = None
    _OWNER[0] = 0


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_forget_pardiso_in_child)
#: diagnostics: number of PARDISO symbolic analyses (phase 12) and numeric-only refactorisations (22)
PARDISO_COUNTS = {"analysis": 0, "refactorization": 0}


class _PardisoFactor:
    """PARDISO LU (real non-symmetric, METIS ordering, MKL defaults for scaling/matching/pivoting).

    - The symbolic analysis (ordering + symbolic factorisation: ~60 % of a phase-12 call, 3.8 of
      5.7 s on the 97k-DOF reference tangent) is reused when the sparsity pattern equals the last one
      analysed by the shared solver instance (Newton iterations of a load case): phase 22 only.
    - pypardiso's own ``solve`` hashes the whole matrix (SHA-1 of data, indices, indptr) on every
      call to decide whether it is factorised (~1 s per factorisation on the reference mesh); we
      track ownership of the shared instance instead and call phase 33 directly.
    """

    _counter = 0

    def __init__(self, A, reuse_analysis: bool = True):
        self.A = A.tocsr()
        self.A.sort_indices()
        self.ps = _pardiso_instance()
        _PardisoFactor._counter += 1
        self.token = _PardisoFactor._counter
        self.reuse_analysis = reuse_analysis
        self._factor()

    def _factor(self):
        global _LAST_PATTERN
        ps, A = self.ps, self.A
        try:
            ps._check_A(A)
            reuse = (self.reuse_analysis and _LAST_PATTERN is not None
                     and np.array_equal(_LAST_PATTERN[0], A.indptr) and np.array_equal(_LAST_PATTERN[1], A.indices))
            PARDISO_COUNTS["refactorization" if reuse else "analysis"] += 1
            ps.factorized_A = None
            ps.set_phase(22 if reuse else 12)
            ps._call_pardiso(A, np.zeros((A.shape[0], 1)))
            self._fast = True
        except AttributeError:  # pragma: no cover - pypardiso internals changed: public path
            ps.factorize(A)
            self._fast = False
        _LAST_PATTERN = (A.indptr.copy(), A.indices.copy())
        _OWNER[0] = self.token

    def solve(self, b):
        b = np.asarray(b, float)
        if not self._fast:  # pragma: no cover
            return self.ps.solve(self.A, np.ascontiguousarray(b)).reshape(b.shape)
        if _OWNER[0] != self.token:  # another factor used the shared instance meanwhile
            self._factor()
        bb = np.asfortranarray(b if b.ndim == 2 else b[:, None])
        self.ps.set_phase(33)
        x = self.ps._call_pardiso(self.A, bb)
        return x.reshape(b.shape)


class _UmfpackFactor:  # pragma: no cover - optional
    def __init__(self, A):
        try:
            import scikits.umfpack as um
        except ImportError as exc:
            raise ConfigError("the 'umfpack' linear solver needs scikit-umfpack (pip install scikit-umfpack); "
                              f"available here: {available_solvers()}") from exc
        self.lu = um.splu(A.tocsc())

    def solve(self, b):
        b = np.asarray(b, float)
        if b.ndim == 1:
            return self.lu.solve(b)
        return np.column_stack([self.lu.solve(b[:, j]) for j in range(b.shape[1])])


def factorize(A: sp.spmatrix, method: str = "auto"):
    """Factorise a square sparse matrix; returns an object with ``solve(b)`` (b: (n,) or (n, k)).

    ``method``: ``"auto"`` (pardiso if importable, else splu), ``"pardiso"``, ``"splu"`` (symmetric
    mode, MMD on AᵀA), ``"splu_partial_pivoting"`` (SuperLU defaults except the ordering; benchmark
    only), ``"umfpack"`` (if scikit-umfpack is installed).
    """
    if method == "auto":
        method = available_solvers()[0]
    if method == "pardiso":
        return _PardisoFactor(A)
    if method == "pardiso_no_reuse":
        return _PardisoFactor(A, reuse_analysis=False)
    if method == "splu":
        return _SpluFactor(A)
    if method == "splu_partial_pivoting":
        return _SpluFactor(A, symmetric_mode=False)
    if method == "umfpack":
        return _UmfpackFactor(A)
    raise ConfigError(f"unknown linear solver {method!r}; available: {available_solvers()}")


class StepFailed(Exception):
    """A Newton solve at fixed load failed (internal; carries the residual history)."""

    def __init__(self, reason: str, history: list[float], iterations: int):
        super().__init__(reason)
        self.reason = reason
        self.history = list(history)
        self.iterations = iterations


@dataclass
class NewtonStats:
    """Accumulated timings [s] and counts of a solve."""

    t_assembly: float = 0.0
    t_linear: float = 0.0
    t_total: float = 0.0
    n_factorizations: int = 0
    n_iterations: int = 0
    steps: list = field(default_factory=list)

    def as_dict(self) -> dict:
        return dict(t_assembly=self.t_assembly, t_linear=self.t_linear, t_total=self.t_total,
                    n_factorizations=self.n_factorizations, n_iterations=self.n_iterations,
                    n_steps=len(self.steps))
