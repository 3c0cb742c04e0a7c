"""Sparse direct solvers and the Newton / load-stepping driver.

Linear solver choice (measured in ``docs/fem.md`` §4 and ``benchmarks/bench_fem.py``):
``pypardiso`` (MKL PARDISO) when importable: the reduced tangent is symmetric to round-off (≤ 1e-9 of its largest
entry: the follower pressure on the closed cavity is conservative) except in the six rows and columns of the
cap's rigid motion, where the dead loads' rotational stiffness is not — so the symmetric part is factorised by
LDLᵀ (``mtype=-2``, ≈ 0.55–0.6 × the LU's numeric factorisation on the default mesh) and the cap block's asymmetry
is corrected exactly (:class:`_NearlySymmetricFactor`; Newton steps skip the correction), and a matrix that is not
nearly symmetric gets the LU (``mtype=11``).  Else ``scipy.sparse.linalg.splu(A, permc_spec="MMD_AT_PLUS_A")``.
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
- a step whose residual is still above its start after ``STALL_ITERATIONS`` (4) iterations fails at once (the
  load stepper cuts the increment), intermediate load steps of tension-held solves are converged to
  ``STEP_RTOL`` (1e-2 of the load), the last one to ``rtol`` (``fem_reference.model``);
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

from .errors import ConfigError

__all__ = ["NewtonStats", "StepFailed", "available_solvers", "bordered_step", "factorize", "symmetric_inertia"]


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


class _Slot:
    """One shared ``PyPardisoSolver`` of a matrix type per process, the sparsity pattern it last analysed and
    the factor object whose numeric factorisation it holds.

    Creating a ``PyPardisoSolver`` globs the file system for the MKL library (0.5–0.8 s measured; avoided
    where :func:`_mkl_rt_hint` finds it), more than a whole factorisation of the test meshes.  Sharing is
    safe: a factor re-factorises when the instance holds another's factorisation (``owner``)."""

    def __init__(self, mtype: int):
        self.mtype = mtype
        self.solver = None
        self.pattern: tuple | None = None
        self.owner = 0

    def instance(self):
        if self.solver is None:
            pypardiso = _import_pypardiso()
            with _mkl_rt_hint():
                self.solver = pypardiso.PyPardisoSolver(mtype=self.mtype)
        return self.solver

    def forget(self) -> None:
        self.solver, self.pattern, self.owner = None, None, 0


#: iterative refinement steps of PARDISO's symmetric indefinite solves (``iparm(8)``), set after the first
#: factorisation has filled ``iparm`` with oneMKL's defaults (METIS ordering, pivot perturbation, Bunch–Kaufman
#: pivoting: kept as they are).  0: refinement only where pivots were perturbed.  The default (2, every solve)
#: measured on the default design's reduced tangent (12 398 unknowns): a solve 0.051–0.070 s against 0.017–0.020 s,
#: the relative residual 1.0e-10 against 9.4e-11, the factorisation and its fill unchanged.
SYMMETRIC_REFINEMENTS = 0

#: real non-symmetric LU (mtype 11) and real symmetric indefinite LDLᵀ (mtype −2)
_SLOTS = {11: _Slot(11), -2: _Slot(-2)}


def _forget_pardiso_in_child() -> None:
    """A forked worker must not use the parent's PARDISO handles: their internal memory and the analyses they
    refer to belong to the parent (reusing them crashed forked FEM workers with a segmentation fault when the
    parent had factorised a matrix of the same pattern before the fork, e.g. the rod estimate of a sweep).
    The child starts with fresh instances and fresh analyses."""
    for slot in _SLOTS.values():
        slot.forget()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_forget_pardiso_in_child)
#: diagnostics: number of PARDISO symbolic analyses (phase 12) and numeric-only refactorisations (22)
PARDISO_COUNTS = {"analysis": 0, "refactorization": 0, "symmetric": 0}


class _PardisoFactor:
    """PARDISO: LU (real non-symmetric, ``mtype=11``) or LDLᵀ (real symmetric indefinite, ``mtype=-2``, the
    upper triangle of a symmetric matrix), METIS ordering, MKL defaults for scaling/matching/pivoting.

    - The symbolic analysis (ordering + symbolic factorisation: ~60 % of a phase-12 call, 3.8 of
      5.7 s on the 97k-DOF reference tangent) is reused when the sparsity pattern equals the last one
      analysed by the shared solver instance (Newton iterations of a load case): phase 22 only.
    - pypardiso's own ``solve`` hashes the whole matrix (SHA-1 of data, indices, indptr) on every
      call to decide whether it is factorised (~1 s per factorisation on the reference mesh); we
      track ownership of the shared instance instead and call phase 33 directly.
    """

    _counter = 0

    def __init__(self, A, reuse_analysis: bool = True, mtype: int = 11):
        self.A = A.tocsr()
        self.A.sort_indices()
        self.slot = _SLOTS[mtype]
        self.ps = self.slot.instance()
        _PardisoFactor._counter += 1
        self.token = _PardisoFactor._counter
        self.reuse_analysis = reuse_analysis
        self._factor()

    def _factor(self):
        ps, A, slot = self.ps, self.A, self.slot
        try:
            ps._check_A(A)
            last = slot.pattern
            reuse = (self.reuse_analysis and last is not None
                     and np.array_equal(last[0], A.indptr) and np.array_equal(last[1], A.indices))
            PARDISO_COUNTS["refactorization" if reuse else "analysis"] += 1
            ps.factorized_A = None
            ps.set_phase(22 if reuse else 12)
            ps._call_pardiso(A, np.zeros((A.shape[0], 1)))
            if slot.mtype == -2:         # iparm now holds MKL's defaults (iparm(1) = 1): refinement only if perturbed
                ps.iparm[7] = SYMMETRIC_REFINEMENTS
            self._fast = True
        except AttributeError:  # pragma: no cover - pypardiso internals changed: public path
            ps.factorize(A)
            self._fast = False
        slot.pattern = (A.indptr.copy(), A.indices.copy())
        slot.owner = self.token

    def solve(self, b):
        b = np.asarray(b, float)
        if not self._fast:  # pragma: no cover
            return self.ps.solve(self.A, np.ascontiguousarray(b)).reshape(b.shape)
        if self.slot.owner != self.token:  # another factor used the shared instance meanwhile
            self._factor()
        bb = np.asfortranarray(b if b.ndim == 2 else b[:, None])
        self.ps.set_phase(33)
        x = self.ps._call_pardiso(self.A, bb)
        return x.reshape(b.shape)


#: at most this many rows/columns may carry the antisymmetric part for the symmetric factorisation (Woodbury)
MAX_ASYMMETRIC_ROWS = 24
#: iterative refinements tried before the Woodbury correction (:meth:`_NearlySymmetricFactor.solve`)
REFINEMENTS = 4
#: a refinement whose correction is below this fraction of |x| ends it (LU's own error is ~1e-10 here)
REFINED = 1e-9
#: antisymmetric entries below this fraction of the largest |entry| of A are round-off (dropped)
ASYMMETRY_ROUNDOFF = 1e-14


class _SymmetricMaps:
    """Index maps of one structurally symmetric CSR pattern (sorted indices): ``perm`` with
    ``Aᵀ.data == A.data[perm]`` and the CSR arrays of the upper triangle (the entries on and above the
    diagonal).  Built once per pattern (the Newton iterations of a solve share one pattern)."""

    def __init__(self, A: sp.csr_matrix):
        n = A.shape[0]
        rows = np.repeat(np.arange(n, dtype=np.int64), np.diff(A.indptr))
        cols = A.indices.astype(np.int64)
        key = rows * n + cols                         # sorted (CSR with sorted indices)
        tkey = cols * n + rows
        pos = np.searchsorted(key, tkey)
        ok = (pos < key.size) & (key[np.minimum(pos, key.size - 1)] == tkey)
        self.symmetric_pattern = bool(ok.all())
        self.perm = pos if self.symmetric_pattern else None
        upper = cols >= rows
        self.indptr_u = np.concatenate(([0], np.cumsum(np.bincount(rows[upper], minlength=n)))).astype(
            A.indptr.dtype)
        self.indices_u = A.indices[upper].copy()
        self.pattern = (A.indptr.copy(), A.indices.copy())
        self._splitter = None

    def splitter(self):
        """The compiled pass giving S's upper triangle and the asymmetric rows (:mod:`._sparse_kernels`), built
        and checked once per pattern."""
        if self._splitter is None:
            from ._sparse_kernels import SymmetricSplit
            self._splitter = SymmetricSplit(self.pattern[0], self.pattern[1], self.perm, self.indices_u.size)
        return self._splitter

    def matches(self, A) -> bool:
        ip, ix = self.pattern
        if ip.size != A.indptr.size or ix.size != A.indices.size:
            return False
        return np.array_equal(ip, A.indptr) and np.array_equal(ix, A.indices)


#: index maps of the last few patterns, the most recent first: a solve alternates between the full tangent
#: and its symmetric-subspace reductions (with one slot, measured: the maps of a 4-case chain were rebuilt 8
#: times, 0.3 s each, 7 % of the chain)
_SYM_MAPS: list = []
SYM_MAPS_KEPT = 3


def _symmetric_maps(K: sp.csr_matrix) -> "_SymmetricMaps":
    for i, maps in enumerate(_SYM_MAPS):
        if maps.matches(K):
            if i:
                _SYM_MAPS.insert(0, _SYM_MAPS.pop(i))
            return maps
    maps = _SymmetricMaps(K)
    _SYM_MAPS.insert(0, maps)
    del _SYM_MAPS[SYM_MAPS_KEPT:]
    return maps


class _NearlySymmetricFactor:
    """Solve ``K x = b`` for a matrix that is symmetric except in a few rows and columns ``E`` (the FEM tangent:
    the hyperelastic, pressure and tendon parts are symmetric; the rotational stiffness of dead loads on the
    rigid cap is not) with a symmetric factorisation, exactly.

    ``K = S + A`` with ``S = (K + Kᵀ)/2`` and ``A = (K − Kᵀ)/2 = P a Pᵀ`` (``P`` selects ``E``, ``a`` dense
    k × k): PARDISO's LDLᵀ of S (half the time of K's LU, measured: 0.3 vs 0.6–0.9 s on the default mesh) and
    the Sherman–Morrison–Woodbury identity

        K⁻¹ b = y − Z (I + a Pᵀ Z)⁻¹ a Pᵀ y,      y = S⁻¹ b,  Z = S⁻¹ P   (k extra solves, once).

    The inertia of S (``n_negative``: PARDISO's count of negative pivots of the Bunch–Kaufman LDLᵀ, exact by
    Sylvester's law unless pivots were perturbed, ``n_perturbed``) is the stability information of a
    tangent whose symmetric part it is.
    """

    def __init__(self, K: sp.csr_matrix, maps: _SymmetricMaps, E: np.ndarray, a: np.ndarray, S_upper: np.ndarray,
                 exact: bool = True):
        U = sp.csr_matrix((S_upper, maps.indices_u, maps.indptr_u), shape=K.shape)
        self.fac = _PardisoFactor(U, mtype=-2)
        PARDISO_COUNTS["symmetric"] += 1
        iparm = self.fac.ps.iparm if hasattr(self.fac.ps, "iparm") else None
        self.n_negative = int(iparm[22]) if iparm is not None else None
        self.n_perturbed = int(iparm[13]) if iparm is not None else None
        self.E, self.a, self.K, self.exact = E, a, K, exact
        self.Z = self.M = None
        self.refinements = 0

    def _woodbury(self, y):
        if self.Z is None:
            P = np.zeros((self.K.shape[0], self.E.size))
            P[self.E, np.arange(self.E.size)] = 1.0
            self.Z = self.fac.solve(P)
            self.M = np.eye(self.E.size) + self.a @ self.Z[self.E]
        return y - self.Z @ np.linalg.solve(self.M, self.a @ y[self.E])

    def solve(self, b):
        """``K⁻¹ b`` (b: (n,) or (n, k)).  With few right-hand sides: iterative refinement with S
        (``x ← x + S⁻¹(b − K x)``, contraction ‖S⁻¹A‖ ≪ 1: one or two solves of one column each) until the
        correction is below :data:`REFINED` of |x|; the Woodbury form (k + |E| solves, then exact) when it contracts slowly or
        for many right-hand sides.  Not ``exact``: ``S⁻¹ b`` (a Newton step with the symmetric part of the
        tangent: its error, ‖S⁻¹A‖ ≈ 1e-4 relative on the FEM tangent, leaves Newton's convergence as it is, and
        the residual that decides convergence is exact)."""
        b = np.asarray(b, float)
        y = self.fac.solve(b)
        if not self.E.size or not self.exact:
            return y
        if self.Z is not None or (b.ndim == 2 and b.shape[1] > 2):
            return self._woodbury(y)
        x, last = y, np.inf
        for _ in range(REFINEMENTS):
            dx = self.fac.solve(b - self.K @ x)
            self.refinements += 1
            x = x + dx
            size = float(np.abs(dx).max())
            if size <= REFINED * float(np.abs(x).max()):
                return x
            if size > 0.1 * last:
                break
            last = size
        return self._woodbury(y)


def _nearly_symmetric(K: sp.csr_matrix, exact: bool = True):
    """The factor of :class:`_NearlySymmetricFactor` if ``K`` qualifies (structurally symmetric pattern, the
    antisymmetric part in at most :data:`MAX_ASYMMETRIC_ROWS` rows), else None."""
    K = K.tocsr()
    if not K.has_canonical_format:           # sorted indices, no duplicate entries (the index maps need both)
        K = K.copy()
        K.sum_duplicates()
    maps = _symmetric_maps(K)
    if not maps.symmetric_pattern:
        return None
    S_upper, rows = maps.splitter().split(K.data, ASYMMETRY_ROUNDOFF)
    if rows.size > MAX_ASYMMETRIC_ROWS:
        return None
    B = K[rows][:, rows].toarray()
    a = 0.5 * (B - B.T)
    return _NearlySymmetricFactor(K, maps, rows, a, S_upper, exact)


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


def symmetric_inertia(K: sp.spmatrix):
    """``(n_negative, solve)`` of the symmetric part ``S = (K + Kᵀ)/2`` from PARDISO's LDLᵀ: the number of negative
    eigenvalues of S (Sylvester's law on the Bunch–Kaufman pivots) and ``solve(b) = S⁻¹ b``; None when PARDISO
    is not installed, S's pattern is not symmetric, K is not nearly symmetric or pivots were perturbed (the count
    is then not exact) — the caller uses another factorisation."""
    if "pardiso" not in available_solvers():
        return None
    f = _nearly_symmetric(sp.csr_matrix(K), exact=False)
    if f is None or f.n_negative is None or f.n_perturbed:
        return None
    return f.n_negative, f.fac.solve


def bordered_step(fac, r: np.ndarray, G: np.ndarray, c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Newton step of ``K dq + G dλ = −r``, ``Gᵀ dq = c`` with the factor ``fac`` of ``K`` (one solve with
    ``1 + k`` right-hand sides and the Schur complement ``(Gᵀ K⁻¹ G) dλ = c − Gᵀ K⁻¹ r``); ``G`` (n, k), ``k`` may
    be 0.  Returns ``(dq, dλ)``."""
    if G.shape[1] == 0:
        return -fac.solve(r), np.zeros(0)
    sol = fac.solve(np.column_stack([r, G]))
    xr, Xg = sol[:, 0], sol[:, 1:]
    dlam = np.linalg.solve(G.T @ Xg, c - G.T @ xr)
    return -xr - Xg @ dlam, dlam


def factorize(A: sp.spmatrix, method: str = "auto", exact: bool = True):
    """Factorise a square sparse matrix; returns an object with ``solve(b)`` (b: (n,) or (n, k)).

    ``method``: ``"auto"`` (pardiso if importable, else splu), ``"pardiso"`` (a symmetric LDLᵀ with a
    low-rank correction when the matrix is symmetric but for a few rows — :class:`_NearlySymmetricFactor` —
    else LU), ``"pardiso_lu"`` (always LU), ``"splu"`` (symmetric
    mode, MMD on AᵀA), ``"splu_partial_pivoting"`` (SuperLU defaults except the ordering; benchmark
    only), ``"umfpack"`` (if scikit-umfpack is installed).  ``exact=False`` lets a nearly symmetric matrix be
    solved with its symmetric part alone (Newton steps; see :class:`_NearlySymmetricFactor`).
    """
    if method == "auto":
        method = available_solvers()[0]
    if method == "pardiso":
        f = _nearly_symmetric(A, exact)
        return f if f is not None else _PardisoFactor(A)
    if method == "pardiso_lu":
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
    #: load steps that failed and were cut back: {"lam", "reason", "residuals"}
    failed_steps: list = field(default_factory=list)
    #: order of the symmetry group whose invariant subspace the Newton steps of the last load step used
    #: (1: the full system; :mod:`fem_reference.symmetry`)
    symmetry_order: int = 1
    #: Newton steps solved in a symmetric subspace (the others: the full system)
    n_symmetric_steps: int = 0

    def as_dict(self) -> dict:
        return dict(t_assembly=self.t_assembly, t_linear=self.t_linear, t_total=self.t_total,
                    n_factorizations=self.n_factorizations, n_iterations=self.n_iterations,
                    n_steps=len(self.steps), n_failed_steps=len(self.failed_steps),
                    symmetry_order=self.symmetry_order, n_symmetric_steps=self.n_symmetric_steps)
