"""Compiled bounded IK: the nearest reachable tip over tensions inside their bounds, by projected Gauss–Newton.

The problem :meth:`ancf.Model.ik` solves when no tensions inside [T_min, T_max] reach the target (or the
unconstrained Newton did not converge):

    min_T  ½ |p_end(T) − p_d|²   subject to  T_min ≤ T ≤ T_max,

where p_end(T) is the tool point of the FK equilibrium at the tensions T (pressure and tip load fixed).  Its
Jacobian comes from the FK's own tangent: with Q(z, T) = 0, ∂z/∂T = −H⁻¹ J_lᵀ (H = ∂Q/∂z the reduced
Hessian of the converged FK, J_l the tendon length gradients), so ∂p_end/∂T = −J_p H⁻¹ J_lᵀ — one
factorisation of H per FK and three solves (J_p: the tip Jacobian, 3 rows).

Each iteration solves the bounded Gauss–Newton subproblem min ½|r + J d|² over the box exactly (a primal
active-set method, :func:`box_least_squares`; m ≤ a handful of tendons) and backtracks on the objective
(Armijo, FK warm-started from the last state, predicted to first order).  Converged when the step falls below
This is the problem ``scipy.optimize.least_squares(method="trf")`` solves in the Python path, with the same
Jacobian; it replaces it in the common case (an FK per evaluation from Python cost ≈ 30 ms per saturated
controller step).  A loop that fails (an FK that does not converge or is not stable, a line search that does
not decrease, the iteration limit) returns a status other than ``CONVERGED``; :class:`ancf.Model` then runs
``least_squares`` as before, so the answer a user sees is always the nearest reachable point.

Inputs come from :class:`ancf.Model`, which has checked them at its public boundary.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .assembly import assemble
from .compiled_solvers import (
    CONVERGED,
    NOT_CONVERGED,
    fk_newton,
    reduce_rows,
    reduce_vec,
    tip_jacobian,
    tip_position,
    to_full,
)
from .solvers import _chol_apply, _chol_factor

#: Status of :func:`ik_bounded` besides ``CONVERGED``/``NOT_CONVERGED``: an FK failed or was unstable, the box
#: subproblem did not terminate, or the line search found no decrease above the round-off floor.
FAILED = 4


@njit(cache=True, nogil=True)
def box_least_squares(A, b, lo, hi, mu):
    """min ½ |A x − b|² + ½ μ |x|² subject to lo ≤ x ≤ hi, for lo ≤ 0 ≤ hi (m,), A (k, m), μ ≥ 0 a small
    regularisation (the minimum-norm step where A has fewer rows than free columns).

    Primal active-set method from x = 0 (feasible): solve on the free variables, step to the first bound met
    and fix it, or — at a stationary point of the free variables — release the fixed variable whose
    multiplier has the wrong sign; finite for this strictly convex problem.  Returns (ok, x (m,), state (m,):
    0 free, −1 at lo, +1 at hi); ok False when it did not terminate within 10 m + 10 changes."""
    m = A.shape[1]
    G = A.T @ A
    for i in range(m):
        G[i, i] += mu
    c = -(A.T @ b)
    x = np.zeros(m)
    W = np.zeros(m, np.int64)
    for i in range(m):                      # start with the bounds x already sits on
        if lo[i] == 0.0:
            W[i] = -1
        elif hi[i] == 0.0:
            W[i] = 1
    scale = 0.0
    for i in range(m):
        scale = max(scale, abs(c[i]))
    stationary = False
    for _ in range(10 * m + 10):
        grad = G @ x + c
        if not stationary:
            nf = 0
            for i in range(m):
                if W[i] == 0:
                    nf += 1
            p = np.zeros(m)
            if nf > 0:
                idx = np.empty(nf, np.int64)
                k = 0
                for i in range(m):
                    if W[i] == 0:
                        idx[k] = i
                        k += 1
                Gf = np.empty((nf, nf))
                rhs = np.empty(nf)
                for a in range(nf):
                    rhs[a] = -grad[idx[a]]
                    for bb in range(nf):
                        Gf[a, bb] = G[idx[a], idx[bb]]
                ok, L, first, last = _chol_factor(Gf, 0.0)
                if not ok:
                    return False, x, W
                pf = _chol_apply(L, first, last, rhs)
                for a in range(nf):
                    p[idx[a]] = pf[a]
            alpha, block, side = 1.0, -1, 0
            for i in range(m):
                if W[i] != 0:
                    continue
                if p[i] < 0.0 and x[i] + p[i] < lo[i]:
                    t = (lo[i] - x[i]) / p[i]
                    if t < alpha:
                        alpha, block, side = t, i, -1
                elif p[i] > 0.0 and x[i] + p[i] > hi[i]:
                    t = (hi[i] - x[i]) / p[i]
                    if t < alpha:
                        alpha, block, side = t, i, 1
            for i in range(m):
                x[i] += alpha * p[i]
            if block >= 0:
                x[block] = lo[block] if side < 0 else hi[block]
                W[block] = side
                continue
            stationary = True
            continue
        # stationary on the free variables: every fixed variable's multiplier must push it onto its bound
        worst, j = -1e-13 * scale, -1
        for i in range(m):
            if W[i] != 0:
                lam = grad[i] if W[i] < 0 else -grad[i]
                if lam < worst:
                    worst, j = lam, i
        if j < 0:
            return True, x, W
        W[j] = 0
        stationary = False
    return False, x, W


@njit(cache=True, nogil=True)
def tip_sensitivity(z0, T, q_fix, P, use_P, n, N, wq, ea, ei, pa, mg, E, d, co, so, h, F, tol, fk_iter):
    """FK at tensions T [N] (m,) from z0, then the tip p_end [m] (3,) and ∂p_end/∂T (3, m) [m/N] there.

    Returns (ok, z (nz,), tip, dtip/dT, dz/dT (nz, m), ∇²Π (nz, nz), Π [J], tendon lengths (m,) [m], FK
    iterations); ok False when the FK did not converge or its state is not stable (H not positive definite)."""
    m = d.size
    status, z, it, _, H, pdef, En, lc = fk_newton(z0, q_fix, P, use_P, n, N, wq, ea, ei, pa, mg, E, d, co, so,
                                                  T, h, F, tol, fk_iter)
    dz_dT = np.zeros((z.size, m))
    if status != CONVERGED or not pdef:
        return False, z, np.zeros(3), np.zeros((3, m)), dz_dT, H, En, lc, it
    ok, L, first, last = _chol_factor(H, 0.0)
    if not ok:
        return False, z, np.zeros(3), np.zeros((3, m)), dz_dT, H, En, lc, it
    q = to_full(z, q_fix, P, use_P)
    _, Q, _, _, Jl, _, _ = assemble(q, n, N, wq, ea, ei, pa, mg, E, d, co, so, T, h, F, False, 2)
    # one more Newton correction with the factor at hand: a warm-started FK whose start already meets the
    # tolerance returns it unchanged, and the tip would not follow a small change of T (the objective would
    # stall at the FK's tolerance, |r| · |H⁻¹ Q|, long before the tensions converge)
    dz = _chol_apply(L, first, last, reduce_vec(Q, P, use_P))
    z = z - dz
    q = to_full(z, q_fix, P, use_P)
    Jp = reduce_rows(tip_jacobian(q, h), P, use_P)               # (3, nz)
    Jlr = reduce_rows(Jl, P, use_P)                               # (m, nz)
    for i in range(m):
        dz_dT[:, i] = -_chol_apply(L, first, last, np.ascontiguousarray(Jlr[i]))   # −H⁻¹ ∇l_i
    return True, z, tip_position(q, h), Jp @ dz_dT, dz_dT, H, En, lc, it


@njit(cache=True, nogil=True)
def ik_bounded(T0, z0, lo, hi, pd, q_fix, P, use_P, n, N, wq, ea, ei, pa, mg, E, d, co, so, h, F, tol, fk_iter,
               max_iter, xtol):
    """Projected Gauss–Newton for the nearest reachable tip (module docstring) from tensions T0 (inside
    [lo, hi]) and the FK warm start z0.

    Returns (status, T (m,) [N], z (nz,), ∇²Π (nz, nz) at z, Π [J], lengths (m,) [m], iterations, FK
    evaluations, |p_end − p_d| [m]).  ``status`` ``CONVERGED`` when the step fell below xtol (1 + |T|∞) [N], or
    the decrease it predicts below the objective's round-off (1e-14 f), or — the round-off floor — no decrease
    was found along a step below 1e-7 (1 + |T|∞) N."""
    m = d.size
    T = T0.copy()
    ok, z, tip, J, dz_dT, H, En, lc, _ = tip_sensitivity(z0, T, q_fix, P, use_P, n, N, wq, ea, ei, pa, mg, E, d,
                                                         co, so, h, F, tol, fk_iter)
    nfev = 1
    if not ok:
        return FAILED, T, z, H, En, lc, 0, nfev, np.inf
    r = tip - pd
    f = 0.5 * (r @ r)
    for it in range(max_iter):
        Tn_inf = 0.0
        for i in range(m):
            Tn_inf = max(Tn_inf, abs(T[i]))
        g = J.T @ r
        dmax = 0.0
        for i in range(m):
            dmax = max(dmax, J[0, i] ** 2 + J[1, i] ** 2 + J[2, i] ** 2)
        good, dT, W = box_least_squares(J, -r, lo - T, hi - T, 1e-12 * dmax)
        if not good:
            return FAILED, T, z, H, En, lc, it, nfev, np.sqrt(2 * f)
        step = 0.0
        for i in range(m):
            step = max(step, abs(dT[i]))
        slope = g @ dT
        # converged: a step below xtol, or a decrease it predicts below the objective's own resolution (the tip's
        # round-off times |r|: ≈ 1e-14 f; smaller steps are round-off, their line search would only stall)
        if step <= xtol * (1.0 + Tn_inf) or -slope <= 1e-14 * f:
            return CONVERGED, T, z, H, En, lc, it, nfev, np.sqrt(2 * f)
        alpha = 1.0
        accepted = False
        for _ in range(20):
            Tt = np.empty(m)
            for i in range(m):
                if alpha == 1.0 and W[i] != 0:
                    Tt[i] = lo[i] if W[i] < 0 else hi[i]          # exactly on the bound it was stepped to
                else:
                    Tt[i] = min(max(T[i] + alpha * dT[i], lo[i]), hi[i])
            zp = z + dz_dT @ (Tt - T)                    # first-order predictor of the FK at Tt
            okt, zt, tipt, Jt, dzt, Ht, Et, lct, _ = tip_sensitivity(zp, Tt, q_fix, P, use_P, n, N, wq, ea, ei, pa,
                                                                     mg, E, d, co, so, h, F, tol, fk_iter)
            nfev += 1
            if okt:
                rt = tipt - pd
                ft = 0.5 * (rt @ rt)
                if ft <= f + 1e-4 * alpha * slope:
                    accepted = True
                    break
            alpha *= 0.5
        if not accepted:
            if step <= 1e-7 * (1.0 + Tn_inf):
                return CONVERGED, T, z, H, En, lc, it, nfev, np.sqrt(2 * f)
            return FAILED, T, z, H, En, lc, it, nfev, np.sqrt(2 * f)
        T, z, tip, J, dz_dT, H, En, lc, r, f = Tt, zt, tipt, Jt, dzt, Ht, Et, lct, rt, ft
    return NOT_CONVERGED, T, z, H, En, lc, max_iter, nfev, np.sqrt(2 * f)
