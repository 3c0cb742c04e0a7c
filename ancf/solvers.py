"""Small dense nonlinear solvers used by :class:`ancf.Model` (paper Sec. III-A/B).

* :func:`minimize_newton` — Newton on the gradient of a potential with an Armijo line search on the
  potential itself and Levenberg–Marquardt shifting when the Hessian is not positive definite (FK).
* :func:`solve_root` — damped Newton on a square system F(x) = 0 with backtracking on ‖F‖ and an LM
  fallback (IK, locked-length FK); the LM damping follows the paper (initial μ = 0.01, relative).
* :func:`locked_active_set` — the active-set loop of the locked-length FK (paper eqs. 3–4) around
  :func:`solve_root`, shared by :meth:`ancf.Model.fk_locked` and :func:`ancf.chain_locked.fk_locked`.  For a set
  A of taut tendons the caller's KKT system [∇Π₀ + J_Aᵀ T_A; l_A − (…) − l⁰_A] = 0 is solved in x = (z, T_A);
  the set then loses the most negative multiplier (T_j < 0) and gains the most over-long slack tendon
  (l_j > l⁰_j + tol_length) until neither exists, i.e. T ≥ 0, β = l⁰ − l ≥ 0, T β = 0.  A set met twice
  means the loop cycles: ConvergenceError.

Both raise :class:`ancf.errors.ConvergenceError` with the residual history on failure: a non-converged
state is never returned as a result.

Inadmissible states (:mod:`ancf.assembly`) come back as an infinite/NaN energy or residual and no
derivatives.  A trial step into one is rejected like any non-decreasing step (the line search halves it);
an inadmissible *starting* point raises ConvergenceError at once (callers check user-given starts first and
raise InputError).  Only finite matrices and vectors reach the compiled Cholesky kernel.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Optional

import numpy as np
from numba import njit

from .errors import ConvergenceError


@dataclass
class SolveInfo:
    iterations: int
    residual_norm: float
    history: list[float] = field(default_factory=list)
    matrix: Optional[np.ndarray] = None     # Hessian (minimize_newton) / Jacobian (solve_root) at the solution
    positive_definite: Optional[bool] = None  # Cholesky of the (K block of the) matrix succeeded; None: not tried
    values: Optional[tuple] = None            # (Π [J], tendon lengths (m,) [m]) at the solution, if known


@njit(cache=True)
def _chol_factor(H, shift):
    """Cholesky factor of H + shift I (H (n, n) symmetric; only its lower triangle is read).

    Returns (ok, L (n, n) lower, first (n,), last (n,)): ``first[i]`` is the first non-zero column of row i of
    H (its envelope; the factor is zero left of it), ``last[j]`` the last row whose envelope reaches column j.
    The loops skip what lies outside the envelope: products with exact zeros, so the factor is the same, bit
    for bit, as the dense loops'; the ANCF tangents are banded (half-bandwidth 11 in free coordinates), which
    makes this several times cheaper than a dense factorisation at n = 6.  ok is False (the rest undefined)
    when the matrix is not positive definite."""
    n = H.shape[0]
    Lm = np.zeros((n, n))
    first = np.empty(n, np.int64)
    for i in range(n):
        f = i
        for j in range(i):
            if H[i, j] != 0.0:
                f = j
                break
        first[i] = f
    last = np.empty(n, np.int64)
    for j in range(n):
        last[j] = j
    for i in range(n):
        for j in range(first[i], i):
            last[j] = max(last[j], i)
    for j in range(n):
        s = H[j, j] + shift
        for k in range(first[j], j):
            s -= Lm[j, k] * Lm[j, k]
        if not (s > 0.0):
            return False, Lm, first, last
        Lm[j, j] = np.sqrt(s)
        for i in range(j + 1, last[j] + 1):
            if first[i] > j:
                continue
            s = H[i, j]
            for k in range(max(first[i], first[j]), j):
                s -= Lm[i, k] * Lm[j, k]
            Lm[i, j] = s / Lm[j, j]
    return True, Lm, first, last


@njit(cache=True)
def _chol_apply(Lm, first, last, g):
    """x (n,) with L Lᵀ x = g for a factor of :func:`_chol_factor`."""
    n = g.size
    x = np.zeros(n)
    y = np.empty(n)
    for i in range(n):
        s = g[i]
        for k in range(first[i], i):
            s -= Lm[i, k] * y[k]
        y[i] = s / Lm[i, i]
    for i in range(n - 1, -1, -1):
        s = y[i]
        for k in range(i + 1, last[i] + 1):
            s -= Lm[k, i] * x[k]
        x[i] = s / Lm[i, i]
    return x


@njit(cache=True)
def _chol_solve_kernel(H, g, shift):
    """Solve (H + shift I) x = g by Cholesky (:func:`_chol_factor`, envelope-aware); returns (ok, x).  ok is
    False if that matrix is not positive definite (x then zero)."""
    ok, Lm, first, last = _chol_factor(H, shift)
    if not ok:
        return False, np.zeros(H.shape[0])
    return True, _chol_apply(Lm, first, last, g)


def _chol_solve(H: np.ndarray, g: np.ndarray, shift: float = 0.0):
    """Solve (H + shift I) x = g by Cholesky; None if that matrix is not positive definite."""
    ok, x = _chol_solve_kernel(np.ascontiguousarray(H), np.ascontiguousarray(g), float(shift))
    return x if ok else None


def _finite_state(E, g, H) -> bool:
    """A usable point of :func:`minimize_newton`: finite energy, gradient and (when given) Hessian."""
    return (g is not None and np.isfinite(E) and bool(np.all(np.isfinite(g)))
            and (H is None or bool(np.all(np.isfinite(H)))))


def minimize_newton(fun: Callable, x0: np.ndarray, *, tol: float, max_iter: int = 60,
                    name: str = "fk") -> tuple[np.ndarray, SolveInfo]:
    """Minimise a smooth potential with Newton steps.

    ``fun(x, hessian: bool) -> (energy, gradient, hessian or None)``; the energy may be ``inf``/``nan``
    where the state is inadmissible (the line search then backtracks).  Converged when ‖gradient‖₂ < tol.
    """
    x = np.array(x0, float)
    E, g, H = fun(x, True)
    if not _finite_state(E, g, H):
        raise ConvergenceError("the starting state is inadmissible (potential or its derivatives not finite)",
                               solver=name, iterations=0, residual_norm=float("inf"), tolerance=tol,
                               history=[float("inf")])
    hist = [float(np.linalg.norm(g))]
    mu = 0.0
    for it in range(max_iter):
        gn = hist[-1]
        if gn < tol:
            return x, SolveInfo(it, gn, hist, H)
        # Newton direction, shifted (LM) until the matrix is positive definite
        scale = max(np.max(np.abs(np.diag(H))), 1e-12)
        dx = _chol_solve(H, -g) if mu == 0.0 else None
        shift = mu
        while dx is None:
            shift = max(shift * 10.0, 1e-8 * scale) if shift else 1e-8 * scale
            if shift > 1e8 * scale:
                break
            dx = _chol_solve(H, -g, shift)
        if dx is None:
            break
        slope = float(g @ dx)
        alpha = 1.0
        accepted = False
        for _ in range(30):
            xn = x + alpha * dx
            En, gn_, Hn = fun(xn, True)
            if _finite_state(En, gn_, Hn) and (En <= E + 1e-4 * alpha * slope or
                                    (abs(En - E) <= 1e-14 * max(1.0, abs(E)) and
                                     np.linalg.norm(gn_) < hist[-1])):
                accepted = True
                break
            alpha *= 0.5
        if not accepted:
            # energy stagnates at round-off level: accept if the gradient norm decreases
            break
        x, E, g, H = xn, En, gn_, Hn
        hist.append(float(np.linalg.norm(g)))
    raise ConvergenceError("Newton on the equilibrium did not converge", solver=name,
                           iterations=len(hist) - 1, residual_norm=hist[-1], tolerance=tol, history=hist)


def _root_norm(w, F, J) -> float:
    """‖W F‖₂ of a trial point of :func:`solve_root`; inf when F or J is missing or not finite."""
    if J is None or not (np.all(np.isfinite(F)) and np.all(np.isfinite(J))):
        return float("inf")
    return float(np.linalg.norm(w * F))


def solve_root(fun: Callable, x0: np.ndarray, *, tol: float, max_iter: int = 60, name: str = "ik",
               weights: np.ndarray | None = None,
               accept: Callable[[np.ndarray], bool] | None = None) -> tuple[np.ndarray, SolveInfo]:
    """Solve a square system F(x) = 0 (``fun(x) -> (F, J)``) by Newton with backtracking on the
    weighted residual norm ‖W F‖₂, switching to Levenberg–Marquardt steps when Newton stalls.

    Converged when ‖W F‖₂ < tol, or when ``accept(F)`` is true (per-block criteria in the rows' own units,
    e.g. forces below their tolerance and lengths below theirs).
    """
    x = np.array(x0, float)
    w = np.ones(len(x)) if weights is None else np.asarray(weights, float)
    F, J = fun(x)
    r = float(np.linalg.norm(w * F)) if np.all(np.isfinite(F)) else np.inf
    if not np.isfinite(r) or J is None or not np.all(np.isfinite(J)):
        raise ConvergenceError("the starting state is inadmissible (residual or Jacobian not finite)",
                               solver=name, iterations=0, residual_norm=r, tolerance=tol, history=[r])
    hist = [r]
    lm = 1e-2                                     # paper: LM damping factor 0.01 (relative here)
    for it in range(max_iter):
        if r < tol or (accept is not None and np.isfinite(r) and accept(F)):
            return x, SolveInfo(it, r, hist, J)
        Jw = w[:, None] * J
        Fw = w * F
        step_ok = False
        try:
            dx = np.linalg.solve(Jw, -Fw)
            alpha = 1.0
            for _ in range(12):
                Fn, Jn = fun(x + alpha * dx)
                rn = _root_norm(w, Fn, Jn)
                if rn < (1 - 1e-4 * alpha) * r:
                    step_ok = True
                    break
                alpha *= 0.5
        except np.linalg.LinAlgError:
            pass
        if not step_ok:  # Levenberg–Marquardt on the normal equations
            A = Jw.T @ Jw
            gr = Jw.T @ Fw
            dscale = np.maximum(np.diag(A), 1e-12 * max(np.max(np.diag(A)), 1e-300))
            for _ in range(25):
                try:
                    dx = np.linalg.solve(A + lm * np.diag(dscale), -gr)
                except np.linalg.LinAlgError:
                    lm *= 10
                    continue
                Fn, Jn = fun(x + dx)
                rn = _root_norm(w, Fn, Jn)
                if rn < r:
                    lm = max(lm / 10, 1e-12)
                    step_ok = True
                    alpha = 1.0
                    break
                lm *= 10
            if not step_ok:
                break
        x = x + alpha * dx
        F, J, r = Fn, Jn, rn
        hist.append(r)
    raise ConvergenceError("Newton/LM did not converge", solver=name, iterations=len(hist) - 1,
                           residual_norm=hist[-1], tolerance=tol, history=hist)


def kkt_accept(nz: int, tol: float, tol_length: float) -> Callable[[np.ndarray], bool]:
    """Convergence test of a locked KKT residual R = [forces (nz,) [N]; length rows [m]] in the rows' own units:
    ‖R[:nz]‖₂ < tol and every |R[nz:]| < tol_length (the weighted norm alone would ask the lengths a scale
    factor more than stated)."""
    def accept(R):
        return bool(np.linalg.norm(R[:nz]) < tol and np.max(np.abs(R[nz:]), initial=0.0) < tol_length)
    return accept


def locked_active_set(system: Callable[[list], Callable], lengths: Callable[[np.ndarray, np.ndarray], np.ndarray],
                      z0: np.ndarray, T0: np.ndarray, l0: np.ndarray, *, tol: float, tol_length: float,
                      max_iter: int, length_scale: float, what: str = "the locked-length FK",
                      name: str = "fk_locked") -> tuple[np.ndarray, np.ndarray, tuple, np.ndarray, SolveInfo]:
    """The active-set loop of a locked-length FK (module docstring).

    ``system(A)`` → the ``fun(x) -> (R, J)`` of :func:`solve_root` for the taut set A (sorted tendon indices),
    x = (z (nz,), T_A); ``lengths(z, T)`` → tendon lengths (m,) [m] at z (T (m,) [N]: the tensions there);
    z0 (nz,) and T0 (m,) [N] the start (the first set: the tendons with T0 > 0 or longer than l⁰ (m,) [m] at
    z0); ``length_scale`` [N/m] weights the length rows.  Returns (z, T (m,) with T[A] the multipliers, A,
    the lengths at z, the last solve's SolveInfo with the total iteration count)."""
    m, nz = len(l0), len(z0)
    l_start = lengths(z0, np.zeros(m))
    A = [j for j in range(m) if T0[j] > 0 or l_start[j] > l0[j]]
    z, T = np.array(z0, float), np.array(T0, float)
    accept = kkt_accept(nz, tol, tol_length)
    seen, total = set(), 0
    for _ in range(4 * m + 4):
        if tuple(A) in seen:
            break
        seen.add(tuple(A))
        w = np.concatenate([np.ones(nz), np.full(len(A), length_scale)])
        x, info = solve_root(system(list(A)), np.concatenate([z, T[A]]), accept=accept,
                             tol=min(tol, length_scale * tol_length), max_iter=max_iter, name=name, weights=w)
        total += info.iterations
        z, T = x[:nz], np.zeros(m)
        T[A] = x[nz:]
        lc = lengths(z, T)
        neg = [j for j in A if T[j] < -1e-10]
        over = [j for j in range(m) if j not in A and lc[j] > l0[j] + tol_length]
        if not neg and not over:
            info.iterations = total
            return z, T, tuple(A), lc, info
        if neg:
            A.remove(min(neg, key=lambda j: T[j]))
        if over:
            A.append(max(over, key=lambda j: lc[j] - l0[j]))
            A.sort()
    raise ConvergenceError(f"active-set loop of {what} cycled", solver=name, iterations=total,
                           residual_norm=float("nan"), tolerance=tol)
