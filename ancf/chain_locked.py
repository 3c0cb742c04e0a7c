"""Locked-length FK and the compliances of a chain (docs/multisegment.md §4; the algorithms of
:meth:`ancf.Model.fk_locked` and :mod:`ancf.compliance` on the chain's free coordinates).

Locked FK: min Π₀(z) s.t. l_j(z) ≤ l⁰_j (j = 1 … m, every tendon of every segment), by an active-set loop; for a
set A of taut tendons Newton solves

    ∇Π₀(z) + J_Aᵀ T_A = 0,   l_A(z) − l⁰_A = 0          (J_A = ∂l_A/∂z, T_A the multipliers = tensions),

and the set changes while a multiplier is negative or a slack tendon is too long.  Π₀ includes the pressures and
the tip load; ∇(T·l) = J_lᵀ T, so the KKT matrix is [[H(T), J_Aᵀ], [J_A, 0]] with H(T) = ∇²_z Π at the tensions T.

Compliances at an equilibrium (dp_end/dF, 3 × 3 [m/N]), H = ∇²_z Π, J_p = ∂p_end/∂z:
tensions held C = J_p H⁻¹ J_pᵀ; lengths of the tendons A held (exact KKT)
C' = J_p [H⁻¹ − H⁻¹J_Aᵀ(J_A H⁻¹ J_Aᵀ)⁻¹J_A H⁻¹] J_pᵀ.
"""

from __future__ import annotations

import numpy as np

from .compliance import exact_active_set
from .errors import InputError, check_finite, check_scalar
from .solvers import locked_active_set


def _system(model, A: list, l0, pr, F):
    """(R, J) of the KKT system for the taut set A at x = (z, T_A)."""
    nz, m = model.nz, model.m

    def fun(x):
        z, TA = x[:nz], x[nz:]
        T = np.zeros(m)
        T[A] = TA
        E, g, H, lc, Jl = model.sys.evaluate(z, T, pr, F, hessian=True, lengths=2)
        if not np.isfinite(E):
            return np.full(nz + len(A), np.nan), None
        JA = Jl[A]
        J = np.zeros((nz + len(A), nz + len(A)))
        J[:nz, :nz], J[:nz, nz:], J[nz:, :nz] = H, JA.T, JA
        return np.concatenate([g, lc[A] - l0[A]]), J
    return fun


def fk_locked(model, tendon_lengths, pressures=None, tip_force=(0.0, 0.0, 0.0), z0=None, *, tol=None,
              tol_length: float = 1e-10, max_iter: int = 60, check_limits: bool = True, check_stability: bool = True):
    """Locked-length FK of a chain: l⁰ (m,) [m], p (K,) [Pa], F (3,) [N] → ChainEquilibrium with tensions T ≥ 0,
    slack β = l⁰ − l ≥ 0, T β = 0 (``active``: the taut tendons).  Start: z0, else the FK with every tendon slack.
    Tensions above a segment's tension_max are listed in ``limit_violations``."""
    tol, max_iter = model._options(tol, max_iter)
    tol_length = check_scalar("tol_length", tol_length, low=1e-15, high=1e-3, unit="m")
    if any(s.tendon_stiffness for s in model.chain.segments):
        raise InputError("the chain's locked FK takes inextensible tendons only: remove tendon_stiffness")
    l0 = check_finite("tendon_lengths", tendon_lengths, (model.m,))
    if np.any(l0 <= 0) or np.any(l0 > 3 * model.chain.length):
        raise InputError(f"tendon_lengths must be positive and below 3 × the chain length "
                         f"({3e3 * model.chain.length:g} mm)")
    pressures = np.zeros(model.n_segments) if pressures is None else pressures
    _, pr, F = model._check_inputs(None, pressures, tip_force, check_limits)
    if z0 is None:
        z0 = model.fk(None, pr, F, check_limits=check_limits, check_stability=False).z
    z = model._z0(z0)
    eq = _active_set(model, z, l0, pr, F, tol, tol_length, max_iter, check_stability)
    eq.limit_violations = tuple(
        f"T{j + 1} = {eq.tensions[j]:.3g} N > tension_max = {model.chain.segments[k].tension_max:g} N"
        for j, k in enumerate(model.sys.owner) if eq.tensions[j] > model.chain.segments[k].tension_max * (1 + 1e-9))
    return eq


def _active_set(model, z, l0, pr, F, tol, tol_length, max_iter, check_stability):
    """The active-set loop (:func:`ancf.solvers.locked_active_set`) from z, every tendon slack at the start."""
    m, nz = model.m, model.nz

    def lengths(zz, T):
        return model.sys.evaluate(zz, T, pr, F, hessian=False, lengths=1)[3]

    z, T, A, lc, info = locked_active_set(lambda A: _system(model, A, l0, pr, F), lengths, z, np.zeros(m), l0,
                                          tol=tol, tol_length=tol_length, max_iter=max_iter,
                                          length_scale=model._kscale * model.chain.length,
                                          what="the chain's locked-length FK")
    slack = np.maximum(l0 - lc, 0.0)
    slack[list(A)] = 0.0
    return model._result(z, np.maximum(T, 0.0), pr, F, info, "fk_locked", JA=info.matrix[nz:, :nz],
                         slack=slack, active=A, check_stability=check_stability)


def _parts(model, eq):
    """(H (nz, nz), J_p (3, nz), J_l (m, nz)) at the equilibrium ``eq`` (its tensions held)."""
    _, _, H, _, Jl = model.sys.evaluate(eq.z, eq.tensions, eq.pressures, eq.tip_force, hessian=True, lengths=2)
    if H is None:
        raise InputError("the state is outside the model's domain")
    return H, model.sys.tip_jacobian(eq.z), Jl


def locked_active(model, eq, load_direction=None) -> tuple:
    """Taut tendons of the locked linearisation under a small extra tip load along ``load_direction`` (3,)
    (default: gravity): the exact rule of :func:`ancf.compliance.active_set` — a tendon under tension stays
    taut, a slack one is taut iff it would otherwise be stretched and its tension increment is ≥ 0."""
    dF = np.asarray(model.sys.g if load_direction is None else load_direction, float)
    if dF.shape != (3,) or not np.all(np.isfinite(dF)) or not np.linalg.norm(dF) > 0:
        raise InputError(f"load_direction must be a finite non-zero 3-vector, got {dF}")
    u = dF / np.linalg.norm(dF)
    H, Jp, Jl = _parts(model, eq)
    X = np.linalg.solve(H, np.hstack([Jp.T, Jl.T]))
    HiJp, HiJl = X[:, :3], X[:, 3:]
    start = tuple(int(j) for j in np.flatnonzero(Jl @ (HiJp @ u) > 0))    # the paper's rule: stretched tendons
    return exact_active_set(HiJp, Jl, HiJl, eq.tensions, u, start)


def compliance(model, eq) -> np.ndarray:
    """Tip compliance with the tensions held, C = J_p H⁻¹ J_pᵀ (3, 3) [m/N] (module docstring)."""
    H, Jp, _ = _parts(model, eq)
    X = np.linalg.solve(H, Jp.T)
    C = Jp @ X
    return 0.5 * (C + C.T)


def locked_compliance(model, eq, active=None) -> np.ndarray:
    """Tip compliance with the lengths of the tendons ``active`` held (default: ``eq.active``, else the tendons
    under tension), exact KKT form (3, 3) [m/N]."""
    if active is None:
        active = eq.active if eq.active is not None else tuple(np.nonzero(eq.tensions > 0)[0])
    A = sorted(int(j) for j in active)
    if any(not 0 <= j < model.m for j in A):
        raise InputError(f"active tendons {A} must be indices 0 … {model.m - 1}")
    H, Jp, Jl = _parts(model, eq)
    X = np.linalg.solve(H, Jp.T)
    C = Jp @ X
    if A:
        JA = Jl[A]
        Y = np.linalg.solve(H, JA.T)
        C = C - (Jp @ Y) @ np.linalg.solve(JA @ Y, (JA @ X))
    return 0.5 * (C + C.T)
