r"""Damping of the reduced model: Rayleigh damping and Kelvin–Voigt axial strain-rate damping.

**Rayleigh** (linear): C_R = α M + β K₀ with M the consistent mass (:mod:`.mass`) and K₀ the stiffness of the
linearisation about the start state (the tangent ∇²Π under the start loads, plus k JᵀJ of tendons held
by length; the matrix :func:`ancf.dynamics.modes` uses).  About that state the modal damping ratios are
exactly ζ_k = α / (2 ω_k) + β ω_k / 2.  C_R is constant, so its force C_R q̇ has the exact tangents
∂/∂q̇ = C_R, ∂/∂q = 0.

**Kelvin–Voigt axial damping** (objective: zero for any rigid motion).  Dissipation potential over the
reference arc length x,

    𝒟 = ½ ∫ c_a ε̇² dx,    ε = ½(|r_x|² − 1),   ε̇ = r_x · ṙ_x,

so the generalized damping force is Q_d = ∂𝒟/∂q̇ = ∫ c_a ε̇ S_xᵀ r_x dx (an axial force c_a ε̇ [N], like the
elastic EA ε), with the exact tangents

    ∂Q_d/∂q̇ = ∫ c_a S_xᵀ r_x r_xᵀ S_x dx,    ∂Q_d/∂q = ∫ c_a S_xᵀ (ε̇ I + r_x ṙ_xᵀ) S_x dx,

S_x = [s_1' I, …, s_4' I] the slope shape matrix of an element (:func:`ancf.kinematics.shape_table`).  The
power it takes from the motion is q̇ᵀ Q_d = ∫ c_a ε̇² dx ≥ 0.  A bending strain-rate damping is not included:
bending modes are damped through β (docs/dynamics.md).
"""

from __future__ import annotations

import numpy as np


def element_dofs(n_elements: int) -> np.ndarray:
    """(n, 12) indices of each element's coordinates in the full vector q."""
    return 6 * np.arange(n_elements)[:, None] + np.arange(12)[None, :]


def axial_damping(q: np.ndarray, v: np.ndarray, n_elements: int, N: np.ndarray, wq: np.ndarray,
                  c_a: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Kelvin–Voigt axial damping force and its tangents (module docstring).

    q, v (ndof,) coordinates [m, -] and velocities; N (nq, 3, 4) shape table, wq (nq,) Gauss weights [m] of
    one element; c_a [N s].  Returns (Q_d (ndof,) [N], ∂Q_d/∂q (ndof, ndof) [N/m·1/s], ∂Q_d/∂q̇ (ndof, ndof)
    [N s/m])."""
    ndof = 6 * (n_elements + 1)
    idx = element_dofs(n_elements)
    s1 = N[:, 1, :]                                                     # (nq, 4) slopes s_j'
    qe = q[idx].reshape(n_elements, 4, 3)
    ve = v[idx].reshape(n_elements, 4, 3)
    rx = np.einsum("kj,ejc->ekc", s1, qe)                               # (n, nq, 3)
    vx = np.einsum("kj,ejc->ekc", s1, ve)
    edot = np.einsum("ekc,ekc->ek", rx, vx)                             # ε̇ (n, nq)
    w = c_a * wq[None, :]                                               # (1, nq)
    f = np.einsum("ek,kj,ekc->ejc", w * edot, s1, rx).reshape(n_elements, 12)
    ss = np.einsum("kj,kl->kjl", s1, s1)                                # (nq, 4, 4)
    Cv = np.einsum("ek,kjl,ekc,ekd->ejcld", w + 0 * edot, ss, rx, rx).reshape(n_elements, 12, 12)
    I3 = np.eye(3)
    Kq = (np.einsum("ek,kjl,cd->ejcld", w * edot, ss, I3)
          + np.einsum("ek,kjl,ekc,ekd->ejcld", w + 0 * edot, ss, rx, vx)).reshape(n_elements, 12, 12)
    Q = np.zeros(ndof)
    np.add.at(Q, idx, f)
    Dq = np.zeros((ndof, ndof))
    Dv = np.zeros((ndof, ndof))
    for e in range(n_elements):
        sl = slice(6 * e, 6 * e + 12)
        Dq[sl, sl] += Kq[e]
        Dv[sl, sl] += Cv[e]
    return Q, Dq, Dv
