"""Generalized bending force Q_b (paper eq. 1) from U_b = ½ ∫ EI(λ) κ² dx.

κ² = |a × b|² / λ⁶ with a = r_x, b = r_xx, λ = |a| (paper Sec. II-C; κ² rather than κ, whose derivative is
singular at κ = 0).  Write the density as a product

    w = φ(s) f(a, b),   s = a·a,   φ(s) = ½ EI(√s) s⁻³,   f = |a × b|² = (a·a)(b·b) − (a·b)².

Derivatives of f:
    f_a = 2(b·b) a − 2(a·b) b,                 f_b = 2(a·a) b − 2(a·b) a,
    f_aa = 2(b·b) I − 2 b bᵀ,                  f_bb = 2(a·a) I − 2 a aᵀ,
    [f_ab]_ij = 4 a_i b_j − 2 b_i a_j − 2(a·b) δ_ij.
Derivatives of φ(s(a)):  φ_a = 2φ' a,  φ_aa = 4φ'' a aᵀ + 2φ' I, with (λ = √s, E = EI(λ))
    φ'  = ½ [E'/(2λ) s⁻³ − 3 E s⁻⁴],
    φ'' = ½ [(E'' λ − E')/(4λ³) s⁻³ − 3 E'/λ s⁻⁴ + 12 E s⁻⁵].
Then  w_a = φ_a f + φ f_a,  w_b = φ f_b,
      w_aa = φ_aa f + φ_a f_aᵀ + f_a φ_aᵀ + φ f_aa,  w_ab = φ_a f_bᵀ + φ f_ab,  w_bb = φ f_bb.
"""

from numba import njit
import numpy as np

from .axial import polyval


@njit(cache=True)
def add_bending(a, b, ei, scale, g, H):
    """Add ½ EI(λ) κ² × scale into the (a, b) blocks (3:9) of g (9,) and H (9, 9); return the energy."""
    s = a[0] * a[0] + a[1] * a[1] + a[2] * a[2]
    bb = b[0] * b[0] + b[1] * b[1] + b[2] * b[2]
    ab = a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
    if not (s > 0.0):
        return np.nan        # undefined (|a| = 0; the assembly never gets here: ancf.assembly, admissible states)
    lam = np.sqrt(s)
    E, E1, E2 = polyval(ei, lam)
    phi = 0.5 * E * s ** -3
    p1 = 0.5 * (E1 / (2.0 * lam) * s ** -3 - 3.0 * E * s ** -4)
    p2 = 0.5 * ((E2 * lam - E1) / (4.0 * lam ** 3) * s ** -3 - 3.0 * E1 / lam * s ** -4 + 12.0 * E * s ** -5)
    f = s * bb - ab * ab
    fa = np.empty(3)
    fb = np.empty(3)
    pa = np.empty(3)
    for i in range(3):
        fa[i] = 2.0 * bb * a[i] - 2.0 * ab * b[i]
        fb[i] = 2.0 * s * b[i] - 2.0 * ab * a[i]
        pa[i] = 2.0 * p1 * a[i]
    for i in range(3):
        g[3 + i] += scale * (pa[i] * f + phi * fa[i])
        g[6 + i] += scale * phi * fb[i]
        for j in range(3):
            dij = 1.0 if i == j else 0.0
            faa = 2.0 * bb * dij - 2.0 * b[i] * b[j]
            fbb = 2.0 * s * dij - 2.0 * a[i] * a[j]
            fab = 4.0 * a[i] * b[j] - 2.0 * b[i] * a[j] - 2.0 * ab * dij
            paa = 4.0 * p2 * a[i] * a[j] + 2.0 * p1 * dij
            H[3 + i, 3 + j] += scale * (paa * f + pa[i] * fa[j] + fa[i] * pa[j] + phi * faa)
            H[3 + i, 6 + j] += scale * (pa[i] * fb[j] + phi * fab)
            H[6 + j, 3 + i] += scale * (pa[i] * fb[j] + phi * fab)
            H[6 + i, 6 + j] += scale * phi * fbb
    return scale * phi * f
