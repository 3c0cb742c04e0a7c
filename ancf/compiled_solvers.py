"""Compiled (numba) Newton loops of the FK and the IK: the same algorithms as :mod:`ancf.solvers`, with the
model's assembly called from inside the loop.

Why: at n = 6 one assembly costs ≈ 0.03 ms, while the Python loop around it (closures, reductions to free
coordinates, finiteness checks, norms, small numpy calls) cost 2–3× that per iteration — a 1 kHz control loop
needs the whole LACC step (an IK and two compliances) under 1 ms.  Here each iteration is one call of
:func:`ancf.assembly.assemble` plus the linear algebra, without leaving compiled code.

What is the same as the Python solvers (and tested against them, ``tests/test_compiled_solvers.py``):

* :func:`fk_newton` is :func:`ancf.solvers.minimize_newton` on Π(z) — Newton direction by Cholesky, shifted
  (Levenberg–Marquardt) until positive definite, Armijo backtracking on the energy (30 halvings), accepted
  at round-off-level energy changes when the gradient norm decreases; converged when ‖∇Π‖₂ < tol.
* :func:`ik_newton` is the Newton phase of :func:`ancf.solvers.solve_root` on the IK system
  R(z, T) = [Q(z, T); p_end(z) − p_d] with the weighted norm ‖W R‖₂ and 12 halvings.
  :func:`ik_newton_reuse` is the same loop given the evaluation at the start (Q, ∂R/∂x, Π, lengths — they do
  not depend on the target): a caller that starts again where a previous solve started or ended, at the same
  pressure and tip force, skips that assembly (the same numbers, to the bit).

What is not here: the LM phase of ``solve_root`` and the FK's load stepping.  A loop that needs them returns a
status other than ``CONVERGED``; the caller then runs the Python solver (:class:`ancf.Model` does), so every
result a user sees comes from the same algorithm, and the compiled loop only removes interpreter overhead
from the common case.  Inputs come from :class:`ancf.Model`, which has checked them (shapes, dtypes,
finiteness) at its public boundary.

Free coordinates: q = q_fix + P z (``use_P``; the free-base-stretch variant) or q = [q_fix[:6], z] (the
clamped base), as in ``Model._to_full``.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .assembly import assemble, tendon_lengths
from .kinematics import _rodrigues
from .solvers import _chol_solve_kernel

#: Status codes of the compiled loops.
CONVERGED, NOT_CONVERGED, BAD_START, NEEDS_LM = 0, 1, 2, 3


@njit(cache=True, nogil=True)
def to_full(z, q_fix, P, use_P):
    """Full coordinates (ndof,) of free ones (nz,)."""
    if use_P:
        return q_fix + P @ z
    q = q_fix.copy()
    q[6:] = z
    return q


@njit(cache=True, nogil=True)
def reduce_vec(v, P, use_P):
    """Pᵀ v for a vector (ndof,)."""
    if use_P:
        return P.T @ v
    return v[6:].copy()


@njit(cache=True, nogil=True)
def reduce_rows(M, P, use_P):
    """M P for rows (k, ndof) → (k, nz)."""
    if use_P:
        return M @ P
    return np.ascontiguousarray(M[:, 6:])


@njit(cache=True, nogil=True)
def reduce_mat(K, P, use_P):
    """Pᵀ K P (nz, nz)."""
    if use_P:
        return P.T @ K @ P
    return np.ascontiguousarray(K[6:, 6:])


@njit(cache=True, nogil=True)
def _all_finite(a):
    for v in a.ravel():
        if not np.isfinite(v):
            return False
    return True


@njit(cache=True, nogil=True)
def _norm(v):
    s = 0.0
    for x in v:
        s += x * x
    return np.sqrt(s)


@njit(cache=True, nogil=True)
def is_positive_definite(H):
    """Cholesky succeeds on H (n, n) (the stability test of a returned state)."""
    ok, _ = _chol_solve_kernel(H, np.zeros(H.shape[0]), 0.0)
    return ok


@njit(cache=True, nogil=True)
def _fk_eval(z, q_fix, P, use_P, n, N, wq, ea, ei, pa, mg, E, d, co, so, T, h, F):
    """(Π, ∇Π (nz,), ∇²Π (nz, nz), usable) at free coordinates z (no tendon lengths: the loop computes them
    once, at the solution)."""
    q = to_full(z, q_fix, P, use_P)
    En, Q, K, _, _, _, _ = assemble(q, n, N, wq, ea, ei, pa, mg, E, d, co, so, T, h, F, True, 0)
    nz = z.size
    if not np.isfinite(En):
        return np.inf, np.zeros(nz), np.zeros((nz, nz)), False
    g = reduce_vec(Q, P, use_P)
    H = reduce_mat(K, P, use_P)
    return En, g, H, _all_finite(g) and _all_finite(H)


@njit(cache=True, nogil=True)
def fk_newton(z0, q_fix, P, use_P, n, N, wq, ea, ei, pa, mg, E, d, co, so, T, h, F, tol, max_iter):
    """Newton on Π(z) from z0 (module docstring).

    Returns (status, z (nz,), iterations, history (k,) of ‖∇Π‖₂, ∇²Π (nz, nz) at z, positive definite, Π [J]
    and tendon lengths (m,) [m] at z; the lengths are zero unless CONVERGED)."""
    x = z0.copy()
    hist = np.empty(max_iter + 1)
    En, g, H, ok = _fk_eval(x, q_fix, P, use_P, n, N, wq, ea, ei, pa, mg, E, d, co, so, T, h, F)
    no_lengths = np.zeros(d.size)
    if not ok:
        hist[0] = np.inf
        return BAD_START, x, 0, hist[:1], H, False, En, no_lengths
    hist[0] = _norm(g)
    nh = 1
    for it in range(max_iter):
        gn = hist[nh - 1]
        if gn < tol:
            lc = tendon_lengths(to_full(x, q_fix, P, use_P), n, N, wq, E, d, co, so)
            return CONVERGED, x, it, hist[:nh], H, is_positive_definite(H), En, lc
        scale = 1e-12
        for i in range(H.shape[0]):
            scale = max(scale, abs(H[i, i]))
        good, dx = _chol_solve_kernel(H, -g, 0.0)
        shift = 0.0
        while not good:
            shift = max(shift * 10.0, 1e-8 * scale) if shift else 1e-8 * scale
            if shift > 1e8 * scale:
                break
            good, dx = _chol_solve_kernel(H, -g, shift)
        if not good:
            break
        slope = g @ dx
        alpha = 1.0
        accepted = False
        for _ in range(30):
            xn = x + alpha * dx
            Et, gt, Ht, okt = _fk_eval(xn, q_fix, P, use_P, n, N, wq, ea, ei, pa, mg, E, d, co, so, T, h, F)
            if okt and (Et <= En + 1e-4 * alpha * slope or
                        (abs(Et - En) <= 1e-14 * max(1.0, abs(En)) and _norm(gt) < hist[nh - 1])):
                accepted = True
                break
            alpha *= 0.5
        if not accepted:
            break
        x, En, g, H = xn, Et, gt, Ht
        hist[nh] = _norm(g)
        nh += 1
    return NOT_CONVERGED, x, nh - 1, hist[:nh], H, False, En, no_lengths


@njit(cache=True, nogil=True)
def stretch_range(q, n, N):
    """(min, max) of the local stretch |r_x| over the quadrature points of the n elements (N: shape table)."""
    lo, hi = np.inf, -np.inf
    for e in range(n):
        off = 6 * e
        for k in range(N.shape[0]):
            s = 0.0
            for c in range(3):
                v = (N[k, 1, 0] * q[off + c] + N[k, 1, 1] * q[off + 3 + c] + N[k, 1, 2] * q[off + 6 + c]
                     + N[k, 1, 3] * q[off + 9 + c])
                s += v * v
            s = np.sqrt(s)
            lo, hi = min(lo, s), max(hi, s)
    return lo, hi


@njit(cache=True, nogil=True)
def tip_position(q, h):
    """p_end = r_{n+1} + h t (as :func:`ancf.kinematics.tip_position`)."""
    a = q[-3:]
    return q[-6:-3] + h * a / _norm(a)


@njit(cache=True, nogil=True)
def tip_pose(q, h, e1):
    """(p_end (3,) [m], frame defined, tip rotation R (3, 3)) — :func:`ancf.kinematics.tip_position` and
    :func:`ancf.kinematics.tip_rotation` in one compiled call (q: an admissible state, |r_x| > 0 at the tip)."""
    a = q[-3:]
    t = a / _norm(a)
    ok, R = _rodrigues(t, e1)
    return q[-6:-3] + h * t, ok, R


@njit(cache=True, nogil=True)
def tip_jacobian(q, h):
    """∂p_end/∂q (3, ndof) (as :func:`ancf.kinematics.tip_position_jacobian`)."""
    a = q[-3:]
    lam = _norm(a)
    t = a / lam
    J = np.zeros((3, q.size))
    o = q.size - 6
    for i in range(3):
        J[i, o + i] = 1.0
        for j in range(3):
            J[i, o + 3 + j] = h * ((1.0 if i == j else 0.0) - t[i] * t[j]) / lam
    return J


@njit(cache=True, nogil=True)
def _ik_eval(x, nz, pd, q_fix, P, use_P, n, N, wq, ea, ei, pa, mg, E, d, co, so, h, F):
    """(R (nz + 3,), J (nz + 3, nz + m), usable, Π, tendon lengths (m,)) of the IK system at x = (z, T)."""
    m = x.size - nz
    z = x[:nz]
    T = np.ascontiguousarray(x[nz:])
    q = to_full(z, q_fix, P, use_P)
    En, Q, K, lc, Jl, _, _ = assemble(q, n, N, wq, ea, ei, pa, mg, E, d, co, so, T, h, F, True, 2)
    R = np.empty(nz + 3)
    J = np.zeros((nz + 3, nz + m))
    if not np.isfinite(En):
        R[:] = np.nan
        return R, J, False, En, lc
    R[:nz] = reduce_vec(Q, P, use_P)
    R[nz:] = tip_position(q, h) - pd
    J[:nz, :nz] = reduce_mat(K, P, use_P)
    J[:nz, nz:] = reduce_rows(Jl, P, use_P).T
    J[nz:, :nz] = reduce_rows(tip_jacobian(q, h), P, use_P)
    return R, J, _all_finite(R) and _all_finite(J), En, lc


@njit(cache=True, nogil=True)
def _lu_solve(A, b):
    """Solve A x = b by Gaussian elimination with partial pivoting; (ok, x), ok False when a pivot is
    exactly zero (where ``np.linalg.solve`` raises LinAlgError)."""
    n = A.shape[0]
    M = A.copy()
    x = b.copy()
    for k in range(n):
        p = k
        for i in range(k + 1, n):
            if abs(M[i, k]) > abs(M[p, k]):
                p = i
        if M[p, k] == 0.0:
            return False, x
        if p != k:
            for j in range(n):
                M[k, j], M[p, j] = M[p, j], M[k, j]
            x[k], x[p] = x[p], x[k]
        for i in range(k + 1, n):
            f = M[i, k] / M[k, k]
            if f != 0.0:
                for j in range(k + 1, n):
                    M[i, j] -= f * M[k, j]
                x[i] -= f * x[k]
    for i in range(n - 1, -1, -1):
        s = x[i]
        for j in range(i + 1, n):
            s -= M[i, j] * x[j]
        x[i] = s / M[i, i]
    return True, x


@njit(cache=True, nogil=True)
def ik_newton(x0, nz, pd, w, q_fix, P, use_P, n, N, wq, ea, ei, pa, mg, E, d, co, so, h, F, tol, max_iter):
    """Damped Newton on the IK system from x0 = (z0, T0) (module docstring).

    Returns (status, x, iterations, history (k,) of ‖W R‖₂, J at x, K block positive definite, Π [J] and
    tendon lengths (m,) [m] at x)."""
    m = x0.size - nz
    out = ik_newton_reuse(x0, nz, pd, w, q_fix, P, use_P, n, N, wq, ea, ei, pa, mg, E, d, co, so, h, F, tol,
                          max_iter, np.zeros(nz), np.zeros((nz + 3, nz + m)), 0.0, np.zeros(m), False)
    return out[0], out[1], out[2], out[3], out[4], out[5], out[6], out[7]


@njit(cache=True, nogil=True)
def ik_newton_reuse(x0, nz, pd, w, q_fix, P, use_P, n, N, wq, ea, ei, pa, mg, E, d, co, so, h, F, tol, max_iter,
                    Q0, J0, En0, lc0, have0):
    """:func:`ik_newton`, given (when ``have0``) the evaluation at x0 of an earlier call with the same x0,
    pressure and tip force: Q0 (nz,) = R[:nz], J0 (nz + 3, nz + m), Π0 [J], lengths lc0 (m,) [m].

    Returns ik_newton's eight results, then (Q (nz,) = R[:nz] at the returned x, and the evaluation at x0:
    Q0, J0, Π0, lc0, usable)."""
    x = x0.copy()
    hist = np.empty(max_iter + 1)
    if have0:
        R = np.empty(nz + 3)
        R[:nz] = Q0
        R[nz:] = tip_position(to_full(x[:nz], q_fix, P, use_P), h) - pd
        J, En, lc = J0.copy(), En0, lc0.copy()
        ok = _all_finite(R)
    else:
        R, J, ok, En, lc = _ik_eval(x, nz, pd, q_fix, P, use_P, n, N, wq, ea, ei, pa, mg, E, d, co, so, h, F)
    first = (R[:nz].copy(), J.copy(), En, lc.copy(), ok)
    if not ok:
        hist[0] = np.inf
        return (BAD_START, x, 0, hist[:1], J, False, En, lc, R[:nz].copy(), first[0], first[1], first[2], first[3],
                first[4])
    r = _norm(w * R)
    hist[0] = r
    nh = 1
    for it in range(max_iter):
        if r < tol:
            return (CONVERGED, x, it, hist[:nh], J, is_positive_definite(np.ascontiguousarray(J[:nz, :nz])), En,
                    lc, R[:nz].copy(), first[0], first[1], first[2], first[3], first[4])
        Jw = np.empty_like(J)
        for i in range(J.shape[0]):
            Jw[i] = w[i] * J[i]
        good, dx = _lu_solve(Jw, -(w * R))
        if not good:
            return (NEEDS_LM, x, nh - 1, hist[:nh], J, False, En, lc, R[:nz].copy(), first[0], first[1], first[2],
                    first[3], first[4])
        alpha = 1.0
        step_ok = False
        for _ in range(12):
            Rn, Jn, okn, Et, lt = _ik_eval(x + alpha * dx, nz, pd, q_fix, P, use_P, n, N, wq, ea, ei, pa, mg, E, d, co,
                                   so, h, F)
            rn = _norm(w * Rn) if okn else np.inf
            if rn < (1 - 1e-4 * alpha) * r:
                step_ok = True
                break
            alpha *= 0.5
        if not step_ok:
            return (NEEDS_LM, x, nh - 1, hist[:nh], J, False, En, lc, R[:nz].copy(), first[0], first[1], first[2],
                    first[3], first[4])
        x = x + alpha * dx
        R, J, r, En, lc = Rn, Jn, rn, Et, lt
        hist[nh] = r
        nh += 1
    return (NOT_CONVERGED, x, nh - 1, hist[:nh], J, False, En, lc, R[:nz].copy(), first[0], first[1], first[2],
            first[3], first[4])
