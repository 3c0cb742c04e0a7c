r"""The ANCF cable's consistent mass matrix, and the tool-point mass.

Kinetic energy of the rod with line mass m' [kg/m]: T = ½ ∫ m' |ṙ|² dx with r = S q^e on each element, so

    T = ½ q̇ᵀ M q̇,    M = Σ_e ∫ m' Sᵀ S dx   (assembled over the elements' shared nodes),

and S = [s_1 I, s_2 I, s_3 I, s_4 I] (cubic Hermite s_j, :func:`ancf.kinematics.hermite`), so that
M_e[3j + c, 3l + c'] = δ_cc' ∫ m' s_j s_l dx.  M is constant: ANCF's absolute coordinates make the inertia
linear in q̇ (no centrifugal or Coriolis terms).  The Gauss rule of the model integrates s_j s_l (degree 6)
exactly from 4 points on.

A lumped mass m at the tool point p_end = r_{n+1} + h t: T = ½ m |ṗ|², ṗ = J_p q̇, gives m J_pᵀ J_p — exact
for h = 0, and the linearisation about q for h ≠ 0 (the t-dependence of J_p adds velocity-squared terms that
vanish in a linear (modal) analysis).  Its rotary inertia is not included.
"""

from __future__ import annotations

import numpy as np

from .. import kinematics as kin


def consistent_mass(n_elements: int, N: np.ndarray, wq: np.ndarray, line_mass: float) -> np.ndarray:
    """M (ndof, ndof) [kg] of ``n_elements`` cable elements from the shape table N (nq, 3, 4) and the Gauss
    weights wq (nq,) [m] of one element (:func:`ancf.kinematics.shape_table`), line mass m' [kg/m]."""
    s = N[:, 0, :]                                                    # (nq, 4) values of s_j
    me = line_mass * np.einsum("k,kj,kl->jl", wq, s, s)               # (4, 4) ∫ m' s_j s_l dx
    Me = np.kron(me, np.eye(3))                                       # (12, 12)
    ndof = 6 * (n_elements + 1)
    M = np.zeros((ndof, ndof))
    for e in range(n_elements):
        o = 6 * e
        M[o:o + 12, o:o + 12] += Me
    return M


def tip_mass_matrix(q: np.ndarray, tool_offset: float, tip_mass: float) -> np.ndarray:
    """m J_pᵀ J_p (ndof, ndof) [kg] of a point mass ``tip_mass`` [kg] at the tool point of state q."""
    Jp = kin.tip_position_jacobian(q, tool_offset)
    return tip_mass * Jp.T @ Jp
