"""Generalized tensile (axial) force Q_t (paper eq. 1), from the axial energy U = ∫ W(λ) dx.

Density at a quadrature point, a function of a = r_x only, λ = |a|, t = a/λ:

    w = W(λ),   ∂w/∂a = W'(λ) t,   ∂²w/∂a² = W''(λ) t tᵀ + (W'(λ)/λ)(I − t tᵀ),

with W, W', W'' of :mod:`ancf.stiffness` (Green strain, dW/dε = EA(λ) ε).  EA(λ) = Σ_k c_k λ^k.
"""

from numba import njit
import numpy as np


@njit(cache=True)
def polyval(c, x):
    """Σ_k c[k] x^k and its first two derivatives."""
    v = 0.0
    d1 = 0.0
    d2 = 0.0
    xp = 1.0
    for k in range(c.size):
        v += c[k] * xp
        xp *= x
    xp = 1.0
    for k in range(1, c.size):
        d1 += k * c[k] * xp
        xp *= x
    xp = 1.0
    for k in range(2, c.size):
        d2 += k * (k - 1) * c[k] * xp
        xp *= x
    return v, d1, d2


@njit(cache=True)
def axial_energy_density(lam, ea):
    """W(λ), W'(λ), W''(λ) [N] for EA(λ) = Σ ea[k] λ^k (W(1) = W'(1) = 0)."""
    W = 0.0
    for k in range(ea.size):
        W += 0.5 * ea[k] * ((lam ** (k + 4) - 1.0) / (k + 4) - (lam ** (k + 2) - 1.0) / (k + 2))
    EA, dEA, _ = polyval(ea, lam)
    W1 = 0.5 * EA * (lam ** 3 - lam)
    W2 = 0.5 * dEA * (lam ** 3 - lam) + 0.5 * EA * (3.0 * lam ** 2 - 1.0)
    return W, W1, W2


@njit(cache=True)
def add_stretch_function(a, f0, f1, f2, scale, g, H):
    """Add ``scale`` × (gradient, Hessian) of w = f(|a|) (with f, f', f'' given) into the a-block
    (indices 3:6) of the 9-vector g and 9×9 H; return scale × f."""
    lam = np.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])
    if not (lam > 0.0):
        return np.nan        # undefined (|a| = 0; the assembly never gets here: ancf.assembly, admissible states)
    for i in range(3):
        ti = a[i] / lam
        g[3 + i] += scale * f1 * ti
        for j in range(3):
            tj = a[j] / lam
            Pij = (1.0 if i == j else 0.0) - ti * tj
            H[3 + i, 3 + j] += scale * (f2 * ti * tj + f1 / lam * Pij)
    return scale * f0


@njit(cache=True)
def add_axial(a, ea, scale, g, H):
    """Axial density W(|a|) × scale into (g, H); returns the energy contribution."""
    lam = np.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])
    W, W1, W2 = axial_energy_density(lam, ea)
    return add_stretch_function(a, W, W1, W2, scale, g, H)
