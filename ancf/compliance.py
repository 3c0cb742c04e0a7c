"""Tip compliance matrices (paper Sec. III-C/D, eqs. 7–16) and stiffness along a direction.

Notation at an equilibrium (free coordinates z, see :class:`ancf.Model`): H = ∂Q/∂q (symmetric, includes
the tension, pressure and tip-offset load stiffness), J_p = ∂p_end/∂q (3 × nz), J_l = ∂l_c/∂q (m × nz),
and ∂Q/∂F_e = −J_pᵀ.

Constant tension and pressure (eqs. 7–10)
    H δq = J_pᵀ δF      ⇒   C_q = H⁻¹ J_pᵀ,     C_p = J_p C_q   (symmetric: C_p = J_p H⁻¹ J_pᵀ).

Locked tendon lengths, active set A (Sec. III-D).  The taut tendons are those whose length the load
would increase: δl = J_l δq_est > 0 with δq_est = C_q δF (the paper's rule, for a given load direction).
Three forms of C'_p:

* ``"exact"`` — the linearisation of the locked equilibrium, with the tension changes as multipliers:
      H δq + J_Aᵀ δT_A = J_pᵀ δF,   J_A δq = 0
      ⇒ C'_q = [H⁻¹ − H⁻¹ J_Aᵀ (J_A H⁻¹ J_Aᵀ)⁻¹ J_A H⁻¹] J_pᵀ,   δT_A = (J_A H⁻¹ J_Aᵀ)⁻¹ J_A H⁻¹ J_pᵀ δF.
  Exact for small loads when A is the true set of taut tendons (checked against finite differences of
  the nonlinear locked FK in the tests).  Elastic tendons (series stiffness k_s, locked constraint
  l(q) − T/k_s = l⁰, so J_A δq = δT_A/k_s) add their compliance to the Schur complement:
  (J_A H⁻¹ J_Aᵀ + diag(1/k_s)) replaces J_A H⁻¹ J_Aᵀ; k_s → ∞ is the inextensible case, k_s → 0 constant
  tension.
* ``"paper"`` — eq. (13): δT_A ≈ 0 and the stacked, over-determined system [H; J_A] δq = [J_pᵀ; 0] δF
  solved with the SVD pseudo-inverse (least squares).  The rows are used as the paper writes them
  (force rows in N, length rows dimensionless, no weighting): an approximation.
* ``"ik"`` — eqs. (15)/(16): the stack H_IK = [H; J_p; J_A] (the Jacobian of the IK-with-locked-length
  system (14)), again by pseudo-inverse, δq = H_IK⁺ [J_pᵀ; 0; 0] δF.  An approximation; the paper uses it
  as the gradient of LACC's load observer.

Series shear compliance (:mod:`ancf.shear`).  With s(p) ≠ 0 the tool point is x = p_end(q) + u(q, F),
u = s P⊥ F, and q the rod's equilibrium (unchanged by the term).  For any of the forms above, whose rod
response is δq = C_q δF,

    C_p = (J_p + J_u) C_q + s P⊥,     J_u = ∂u/∂q = s (∂P⊥/∂q) F,

(``C_q`` stays the rod's).  The taut-set rules use the tendon lengths, which the term does not change.

Stiffness along a unit direction u: k(u) = 1 / (uᵀ C u)  [N/m].

Response to the pressure (:func:`pressure_sensitivity`).  With g_p = ∂Q/∂p (:meth:`ancf.Model.dQ_dp`: the
volume term and, for a pressure-dependent stiffness law, the stiffness terms), at an equilibrium

* tensions held (FK):  H δq = −g_p δp;
* tip held (IK, three tendons):  [H J_lᵀ; J_p 0] [δq; δT] = [−g_p; 0] δp;
* lengths held (locked FK, taut set A):  [H J_Aᵀ; J_A −diag(1/k_s)] [δq; δT_A] = [−g_p; 0] δp.

With a shear compliance the tool point moves by δx = (J_p + J_u) δq + (ds/dp) P⊥F δp, and the IK holds the
tool point: its rows read (J_p + J_u) δq = −(ds/dp) P⊥F δp.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional, Sequence

import numpy as np

from .errors import InputError, check_finite
from .model import Equilibrium, Model

METHODS = ("exact", "paper", "ik")


@dataclass
class Compliance:
    """A compliance evaluation.

    C_p : (3, 3) task-space compliance [m/N]
    C_q : (ndof, 3) configuration-space compliance (full coordinates; zero rows for the clamped base)
    active : tuple of tendon indices treated as taut (locked modes; all tendons' tension constant in
             ``tension`` mode: empty)
    dT_dF : (m, 3) tension change per unit tip force [N/N] (``exact`` locked mode), else None
    mode, method : how it was computed
    """
    C_p: np.ndarray
    C_q: np.ndarray
    active: tuple
    mode: str
    method: str
    dT_dF: Optional[np.ndarray] = None

    @property
    def stiffness(self) -> np.ndarray:
        """K_p = C_p⁻¹ [N/m]."""
        return np.linalg.inv(self.C_p)


def _parts(model: Model, eq: Equilibrium):
    """(H, J_p, J_l) in free coordinates at ``eq``, cached on the equilibrium object for this model so
    that several compliance evaluations at one state assemble once."""
    if not isinstance(model, Model) or not isinstance(eq, Equilibrium):
        raise InputError(f"compliance needs (Model, Equilibrium), got ({type(model).__name__}, {type(eq).__name__})")
    if np.shape(eq.q) != (model.ndof,):
        raise InputError(f"the equilibrium has {np.size(eq.q)} coordinates but the model has {model.ndof}: it "
                         "comes from a model with another element count")
    if "_friction_tangent" in eq.__dict__:    # a state of Model.fk_history: its tensions differ per segment
        raise InputError("this equilibrium carries tendon friction (Model.fk_history): its compliance is "
                         "ancf.friction.compliance(model, state); the frictionless forms do not apply to it")
    cached = model._tangent_parts(eq)          # the solver's own, when it ended at this very state
    if cached is not None:
        return cached
    ev = model.evaluate(eq.q, eq.tensions, eq.pressure, eq.tip_force)
    parts = (model.reduce_mat(ev.K), model.reduce_vec(model.tip_jacobian(eq.q)), model.reduce_vec(ev.J_l))
    model._keep_tangent_parts(eq, parts)
    return parts


def _solves(model: Model, eq: Equilibrium):
    """(H, J_p, J_l, H⁻¹J_pᵀ (nz, 3), H⁻¹J_lᵀ (nz, m)) at ``eq``: one factorisation of H for every compliance
    form and active-set iteration at this state (kept with the parts)."""
    H, Jp, Jl = _parts(model, eq)
    cached = getattr(eq, "_compliance_solves", None)
    if cached is not None and cached[0] is H:
        return cached[1]
    X = np.linalg.solve(H, np.hstack([Jp.T, Jl.T]))
    out = (H, Jp, Jl, X[:, :3], X[:, 3:])
    object.__setattr__(eq, "_compliance_solves", (H, out))
    return out


def _shear(model: Model, eq: Equilibrium):
    """(J_u (3, nz) = ∂u/∂z, s P⊥ (3, 3), ∂u/∂p (3,)) of the series shear compliance at ``eq``, or None
    without one (module docstring; :mod:`ancf.shear`)."""
    parts = model._shear_parts(eq.q, float(eq.pressure), eq.tip_force)
    if parts is None:
        return None
    u, Ju, PF, s, ds = parts
    a = eq.q[-3:]
    t = a / np.linalg.norm(a)
    return model.reduce_vec(Ju), s * (np.eye(3) - np.outer(t, t)), ds * PF


def _tool(model: Model, eq: Equilibrium, Jp: np.ndarray, Cq: np.ndarray) -> np.ndarray:
    """Tool-point compliance (3, 3) [m/N] from the rod's response Cq (nz, 3): J_p Cq, plus the shear terms
    (J_u Cq + s P⊥) when the actuator has a shear compliance."""
    sh = _shear(model, eq)
    if sh is None:
        return Jp @ Cq
    Ju, sP, _ = sh
    return (Jp + Ju) @ Cq + sP


def _full(model: Model, Cz: np.ndarray) -> np.ndarray:
    """Map free-coordinate sensitivities (nz, 3) to full coordinates (ndof, 3)."""
    if model._P is None:
        out = np.zeros((model.ndof, Cz.shape[1]))
        out[6:] = Cz
        return out
    return model._P @ Cz


def tension(model: Model, eq: Equilibrium) -> Compliance:
    """Constant-tension, constant-pressure compliance (eqs. 8–10)."""
    _, Jp, _, Cq, _ = _solves(model, eq)
    return Compliance(C_p=_tool(model, eq, Jp, Cq), C_q=_full(model, Cq), active=(), mode="tension", method="exact")


def _kkt(HiJp, JA, HiJA, cs: float = 0.0):
    """Exact locked sensitivities for the taut set with rows JA (k, nz) and series tendon compliance ``cs`` =
    1/k_s [m/N], from H⁻¹J_pᵀ (nz, 3) and H⁻¹J_Aᵀ (nz, k): (δq per δF (nz, 3), δT_A per δF (k, 3)).
    Block elimination of the KKT system [H J_Aᵀ; J_A −cs I] [δq; δT_A] = [J_pᵀ; 0]."""
    if JA.shape[0] == 0:
        return HiJp, np.zeros((0, 3))
    dTA = np.linalg.solve(JA @ HiJA + cs * np.eye(JA.shape[0]), JA @ HiJp)
    return HiJp - HiJA @ dTA, dTA


def active_set(model: Model, eq: Equilibrium, load_direction=None, rule: str = "exact",
               tol: float = 1e-9) -> tuple:
    """Taut tendons under a small extra tip load along ``load_direction`` (3,) (default: gravity).

    * ``rule="paper"`` (Sec. III-D): i ∈ A iff δl_i = J_l,i C_q δF > 0 with the constant-tension response.
    * ``rule="exact"``: the solution of the linear complementarity problem of the locked linearisation —
      tendons with T_i > tol stay taut; a slack one (T_i = 0) is taut iff it would otherwise be stretched
      (δl_i > 0) and its tension increment is ≥ 0.  Found by an active-set loop started from the paper's
      rule (a slack tendon can become taut only after another one is constrained).
    """
    _, Jp, Jl, HiJp, HiJl = _solves(model, eq)
    dF = np.asarray(model.params.gravity if load_direction is None else load_direction, float)
    if dF.shape != (3,) or not np.all(np.isfinite(dF)) or np.linalg.norm(dF) == 0:
        raise InputError(f"load_direction must be a finite non-zero 3-vector, got {dF}")
    u = dF / np.linalg.norm(dF)
    dl = Jl @ (HiJp @ u)
    paper = tuple(int(i) for i in np.flatnonzero(dl > 0))
    if rule == "paper":
        return paper
    if rule != "exact":
        raise InputError(f"active-set rule must be 'paper' or 'exact', got {rule!r}")
    return exact_active_set(HiJp, Jl, HiJl, eq.tensions, u, paper, model._cs, tol)


def exact_active_set(HiJp, Jl, HiJl, tensions, u, start, cs: float = 0.0, tol: float = 1e-9) -> tuple:
    """The exact rule of :func:`active_set` from its parts (any model: one segment or a chain): H⁻¹J_pᵀ (nz, 3),
    J_l (m, nz), H⁻¹J_lᵀ (nz, m), tensions (m,) [N], the unit load direction u (3,), the paper rule's set
    ``start``, the series tendon compliance cs [m/N]."""
    m = len(tensions)
    taut = {i for i in range(m) if tensions[i] > tol}
    A = sorted(taut | set(start))
    seen = set()
    while tuple(A) not in seen:
        seen.add(tuple(A))
        dq, dTA = _kkt(HiJp, Jl[A], HiJl[:, A], cs)
        dT = dict(zip(A, dTA @ u))
        dl = Jl @ (dq @ u)
        drop = [i for i in A if i not in taut and dT[i] < -1e-12 * max(1.0, abs(dT[i]))]
        add = [i for i in range(m) if i not in A and dl[i] > 1e-14]
        if not drop and not add:
            return tuple(A)
        if drop:
            A.remove(min(drop, key=lambda i: dT[i]))
        else:
            A = sorted(A + [max(add, key=lambda i: dl[i])])
    raise InputError("active-set iteration of the locked compliance cycled (degenerate state)")


def locked(model: Model, eq: Equilibrium, method: str = "exact", active: Optional[Sequence[int]] = None,
           load_direction=None, constraint_weight: float = 1.0) -> Compliance:
    """Locked-tendon-length compliance C'_p by the ``method`` "exact" | "paper" | "ik" (module docstring).

    ``active``: indices of taut tendons; default from :func:`active_set` along ``load_direction`` with
    the paper's rule for the paper/ik forms and the exact complementarity rule for the exact form.
    ``constraint_weight`` [N/m] scales the constraint rows (J_A, and J_p for "ik") of the stacked
    least-squares forms; 1.0 is the paper's literal, unweighted stack.  (Flagged interpretation: the paper
    does not state a weighting; unweighted, the force rows dominate and the locked forms come out close to
    the constant-tension compliance.)
    """
    if method not in METHODS:
        raise InputError(f"compliance method must be one of {METHODS}, got {method!r}")
    if active is None:
        active = active_set(model, eq, load_direction, rule="exact" if method == "exact" else "paper")
    A = sorted(int(i) for i in active)
    if any(i < 0 or i >= model.m for i in A):
        raise InputError(f"active tendon indices must be in 0..{model.m - 1}, got {A}")
    H, Jp, Jl, HiJp, HiJl = _solves(model, eq)
    JA = Jl[A]
    dT = None
    if method == "exact":
        Cq, dTA = _kkt(HiJp, JA, HiJl[:, A], model._cs)
        dT = np.zeros((model.m, 3))
        dT[A] = dTA
    elif method == "paper":
        stack = np.vstack([H, constraint_weight * JA])
        rhs = np.vstack([Jp.T, np.zeros((len(A), 3))])
        Cq = np.linalg.pinv(stack) @ rhs
    else:  # "ik"
        stack = np.vstack([H, constraint_weight * Jp, constraint_weight * JA])
        rhs = np.vstack([Jp.T, np.zeros((3 + len(A), 3))])
        Cq = np.linalg.pinv(stack) @ rhs
    return Compliance(C_p=_tool(model, eq, Jp, Cq), C_q=_full(model, Cq), active=tuple(A), mode="locked", method=method,
                      dT_dF=dT)


@dataclass
class PressureSensitivity:
    """Derivatives of an equilibrium with respect to the pressure, other inputs held (``hold``).

    dq_dp : (ndof,) [m/Pa] (full coordinates);  dtip_dp : (3,) [m/Pa];  dT_dp : (m,) [N/Pa] (zero for the
    tendons whose tension is held or that are slack);  hold : "tensions" | "tip" | "lengths"
    """
    dq_dp: np.ndarray
    dtip_dp: np.ndarray
    dT_dp: np.ndarray
    hold: str


HOLDS = ("tensions", "tip", "lengths")


def pressure_sensitivity(model: Model, eq: Equilibrium, hold: str = "tensions",
                         active: Optional[Sequence[int]] = None) -> PressureSensitivity:
    """d(q, tip, T)/dp at ``eq`` with the tensions (FK), the tip (IK; three tendons) or the tendon lengths
    (locked FK; taut set ``active``, default ``eq.active`` or the tendons with T > 0) held (module docstring).

    ``hold="tip"`` is the derivative of the square IK system with all three tensions free: at a state where
    the IK holds a tension at its bound, the bounded IK's response differs.  Units: dq/dp and dtip/dp [m/Pa],
    dT/dp [N/Pa]."""
    if hold not in HOLDS:
        raise InputError(f"hold must be one of {HOLDS}, got {hold!r}")
    H, Jp, Jl, _, _ = _solves(model, eq)
    gp = model.reduce_vec(model.dQ_dp(eq.q, eq.pressure))
    nz, m = H.shape[0], model.m
    sh = _shear(model, eq)
    Jx, dx_p = (Jp, None) if sh is None else (Jp + sh[0], sh[2])     # tool point: J, ∂x/∂p at fixed q
    dT = np.zeros(m)
    if hold == "tensions":
        dz = -np.linalg.solve(H, gp)
    elif hold == "tip":
        if m != 3:
            raise InputError(f"hold='tip' needs exactly 3 tendons (a square IK system), the actuator has {m}")
        K = np.zeros((nz + 3, nz + 3))
        K[:nz, :nz], K[:nz, nz:], K[nz:, :nz] = H, Jl.T, Jx
        x = np.linalg.solve(K, np.concatenate([-gp, np.zeros(3) if dx_p is None else -dx_p]))
        dz, dT = x[:nz], x[nz:]
    else:
        if active is None:
            active = eq.active if eq.active is not None else np.flatnonzero(eq.tensions > 0)
        A = sorted(int(i) for i in active)
        if any(i < 0 or i >= m for i in A):
            raise InputError(f"active tendon indices must be in 0..{m - 1}, got {A}")
        k = len(A)
        K = np.zeros((nz + k, nz + k))
        K[:nz, :nz], K[:nz, nz:], K[nz:, :nz] = H, Jl[A].T, Jl[A]
        K[nz:, nz:] = -model._cs * np.eye(k)
        x = np.linalg.solve(K, np.concatenate([-gp, np.zeros(k)]))
        dz = x[:nz]
        dT[A] = x[nz:]
    dq = _full(model, dz[:, None])[:, 0]
    dtip = Jx @ dz if dx_p is None else Jx @ dz + dx_p
    return PressureSensitivity(dq_dp=dq, dtip_dp=dtip, dT_dp=dT, hold=hold)


def directional_stiffness(C: np.ndarray, direction) -> float:
    """k(u) = 1 / (uᵀ C u) [N/m] along the unit vector of ``direction`` (3,)."""
    u = check_finite("direction", direction, (3,))
    nu = np.linalg.norm(u)
    if nu == 0:
        raise InputError("direction must be non-zero")
    u = u / nu
    c = float(u @ check_finite("C", C, (3, 3)) @ u)
    if c <= 0:
        raise InputError(f"compliance along {u} is not positive ({c:g} m/N)")
    return 1.0 / c


def stiffness_ellipsoid(C: np.ndarray, n: int = 24):
    """Surface of directional stiffness: points k(u) u [N/m] on a (n, 2n) grid of directions u, plus the
    principal stiffnesses and axes of the symmetric part of C (for plots)."""
    C = check_finite("C", C, (3, 3))
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or not 2 <= n <= 1000:
        raise InputError(f"n must be an integer in [2, 1000], got {n!r}")
    Cs = 0.5 * (C + C.T)
    th = np.linspace(0, np.pi, n)
    ph = np.linspace(0, 2 * np.pi, 2 * n)
    U = np.stack([np.outer(np.sin(th), np.cos(ph)), np.outer(np.sin(th), np.sin(ph)),
                  np.outer(np.cos(th), np.ones_like(ph))], axis=-1)
    k = 1.0 / np.einsum("...i,ij,...j->...", U, Cs, U)
    w, V = np.linalg.eigh(Cs)
    return {"points": U * k[..., None], "principal_stiffness": 1.0 / w, "principal_axes": V}
