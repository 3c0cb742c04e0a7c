"""Generalized pneumatic force Q_p (paper eq. 1) as the virtual work of the pressure on the volume change.

V(q) = A_eff ∫ |r_x| dx  (A_eff = π D_eff² / 4), potential −p V.  At a quadrature point the density is

    w = −p A_eff λ,   ∂w/∂a = −p A_eff t,   ∂²w/∂a² = −(p A_eff / λ)(I − t tᵀ),

i.e. a pure axial tension p A_eff at every section — and, correctly, no bending of a curved closed tube
(a tip follower force would wrongly bend a curved actuator).  ∂Q/∂p = −A_eff ∂(∫λ dx)/∂q.
"""

from numba import njit

from .axial import add_stretch_function


@njit(cache=True)
def add_pressure(a, pA, scale, g, H):
    """Add −pA·|a| × scale into (g, H); returns the energy contribution."""
    lam = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]) ** 0.5
    return add_stretch_function(a, -pA * lam, -pA, 0.0, scale, g, H)


@njit(cache=True)
def add_stretch_length(a, scale, g):
    """Add ∂|a|/∂a × scale into g (the arc-length gradient used for ∂Q/∂p); returns scale·|a|."""
    lam = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]) ** 0.5
    for i in range(3):
        g[3 + i] += scale * a[i] / lam
    return scale * lam
