"""Generalized external force Q_f (paper eq. 1): a dead load F at the tool point p_end = r_{n+1} + h t.

Potential −F · p_end (F includes the tip mass weight m_tip g).  With λ = |a|, a = r_x,{n+1}, t = a/λ,
P = I − t tᵀ:

    ∂/∂r_{n+1} = −F,        ∂/∂a = −h P F / λ,
    ∂²/∂a² = (h / λ²) [ t (P F)ᵀ + (F·t) P + (P F) tᵀ ]      (all other second derivatives vanish).
"""

import numpy as np
from numba import njit


@njit(cache=True)
def add_tip_load(q, h, F, G, H, want_H):
    """Add the tip-load gradient into G (ndof,) and Hessian into H (ndof, ndof); return its energy."""
    n = q.size
    r = q[n - 6:n - 3]
    a = q[n - 3:]
    lam = np.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])
    if not (lam > 0.0):
        return np.nan        # undefined (|a| = 0; the assembly never gets here: ancf.assembly, admissible states)
    t = a / lam
    Ft = F[0] * t[0] + F[1] * t[1] + F[2] * t[2]
    PF = F - Ft * t
    energy = 0.0
    for i in range(3):
        energy -= F[i] * (r[i] + h * t[i])
        G[n - 6 + i] -= F[i]
        G[n - 3 + i] -= h * PF[i] / lam
    if want_H and h != 0.0:
        for i in range(3):
            for j in range(3):
                Pij = (1.0 if i == j else 0.0) - t[i] * t[j]
                H[n - 3 + i, n - 3 + j] += h / lam ** 2 * (t[i] * PF[j] + Ft * Pij + PF[i] * t[j])
    return energy
