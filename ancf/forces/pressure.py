"""Generalized pneumatic force Q_p (paper eq. 1) as the virtual work of the pressure on the volume change.

The chamber volume per unit reference length is A(λ) λ, with A(λ) the effective pressure area at the local
stretch λ = |r_x|; V(q) = ∫ A(λ) λ dx and the potential is −p V.  The paper's form has a constant area
A(λ) = A_eff = π D_eff² / 4; a stretch-dependent area A(λ) = A_eff (1 + β (λ − 1)) (``pressure_area_slope``
β of :class:`ancf.ActuatorParams`) keeps the potential form.  With A(λ) λ = Σ_k c_k λ^{k+1} (coefficients
``c`` [m²]) and a_p = p c [N], the density at a quadrature point, a function of a = r_x only (t = a/λ), is

    w = −Σ_k a_p,k λ^{k+1},   ∂w/∂a = f'(λ) t,   ∂²w/∂a² = f''(λ) t tᵀ + (f'(λ)/λ)(I − t tᵀ),
    f'(λ) = −Σ_k (k+1) a_p,k λ^k,   f''(λ) = −Σ_k (k+1) k a_p,k λ^{k−1}:

a pure axial tension p dV/dλ at every section (p A_eff for the constant area) and, correctly, no bending
of a curved closed tube (a tip follower force would wrongly bend a curved actuator).
∂Q/∂p = −∂V/∂q (:meth:`ancf.Model.dQ_dp`).
"""

import numpy as np
from numba import njit

from .axial import add_stretch_function


@njit(cache=True)
def pressure_density(lam, pa):
    """f(λ) = −Σ pa_k λ^{k+1} and its first two derivatives (pa = p × area coefficients [N])."""
    f0 = 0.0
    f1 = 0.0
    f2 = 0.0
    for k in range(pa.size):
        f0 -= pa[k] * lam ** (k + 1)
        f1 -= (k + 1) * pa[k] * lam ** k
        if k > 0:
            f2 -= (k + 1) * k * pa[k] * lam ** (k - 1)
    return f0, f1, f2


@njit(cache=True)
def add_pressure(a, pa, scale, g, H):
    """Add the pressure density −Σ pa_k |a|^{k+1} × scale into (g, H); returns the energy contribution."""
    lam = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]) ** 0.5
    f0, f1, f2 = pressure_density(lam, pa)
    return add_stretch_function(a, f0, f1, f2, scale, g, H)


@njit(cache=True)
def add_stretch_length(a, scale, g):
    """Add ∂|a|/∂a × scale into g (the arc-length gradient); returns scale·|a|."""
    lam = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]) ** 0.5
    if not (lam > 0.0):
        return np.nan        # undefined (|a| = 0; the assembly never gets here: ancf.assembly, admissible states)
    for i in range(3):
        g[3 + i] += scale * a[i] / lam
    return scale * lam
