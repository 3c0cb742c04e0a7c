"""Generalized tendon force Q_c,i (paper eq. 1) and the tendon length l_c,i (paper eq. 5).

Tendon i runs at distance d_i from the centreline at angle θ_i (from the reference direction, about the
base axis).  Its path is carried by the section frame R(t) (Rodrigues, taking the base axis to the local
tangent t = r_x/|r_x|):

    r_c(x) = r(x) + d_i R(t(x)) o_i,     o_i = cos θ_i e2 + sin θ_i e3,
    l_c,i  = ∫ |r_c,x| dx,               r_c,x = r_x + d_i (∂g/∂a)(r_x) r_xx,   g(a) = R(a/|a|) o_i.

With constant tension T_i the tendon's potential is T_i l_c,i, so Q_c,i = T_i ∂l_c,i/∂q: the same row
∂l_c,i/∂q is the constraint Jacobian J_A of the locked-length problems and ∂Q/∂T_i.  At a quadrature
point, with u = r_c,x(a, b) (generated: :mod:`._tendon_generated`, derivation in :mod:`._tendon_codegen`),
w = |u|, n = u/|u|:

    ∂w/∂(a,b) = Juᵀ n,     ∂²w/∂(a,b)² = Juᵀ (I − n nᵀ) Ju / |u| + Σ_k n_k ∂²u_k/∂(a,b)².

The generated code works in the actuator frame (e1 = base axis, e2 = reference direction, e3 = e1 × e2);
with E = [e1 e2 e3], a_loc = Eᵀ a and the derivatives rotate back blockwise (g = E g_loc, H = E H_loc Eᵀ).

Domain.  The kernels divide by |a|, by 1 + c (c = t·e1, the Rodrigues frame; singular for a section that
points back along −e1) and by w = |u| (zero where the tendon path folds, the local curvature radius equal to
d on the tendon's side).  :func:`ancf.assembly.assemble` never calls them outside its admissible set
(|a| ≥ 0.2, 1 + c ≥ 0.01, w ≥ 0.2; see :mod:`ancf.assembly`), where all three are bounded away from zero.
As a second line of defence each kernel checks |a| > 0, 1 + c > 0 and w > 0 itself and returns NaN (value
and derivatives) otherwise: never a division by zero (numba raises ZeroDivisionError for a scalar one) and
never a finite number for an undefined state.
"""

import numpy as np
from numba import njit

from ._tendon_generated import tendon_u, tendon_u_value, tendon_uJ


@njit(cache=True)
def _to_frame(a, b, E):
    """Components of a, b in the actuator frame: Eᵀ a, Eᵀ b."""
    al = np.empty(3)
    bl = np.empty(3)
    for i in range(3):
        al[i] = E[0, i] * a[0] + E[1, i] * a[1] + E[2, i] * a[2]
        bl[i] = E[0, i] * b[0] + E[1, i] * b[1] + E[2, i] * b[2]
    return al, bl


@njit(cache=True)
def _frame_defined(al):
    """True when the generated code's divisors |a|² and 1 + a0/|a| (computed exactly as it does) are > 0."""
    x6 = al[0] ** 2 + al[1] ** 2 + al[2] ** 2
    if not (x6 > 0.0):
        return False
    return al[0] * (1.0 / np.sqrt(x6)) + 1.0 > 0.0


@njit(cache=True)
def tendon_density(a, b, E, d, co, so):
    """Length density |r_c,x| of one tendon, its gradient (6,) and Hessian (6, 6) w.r.t. (a, b) = (r_x, r_xx),
    all in the world frame.  E (3, 3): actuator frame as columns.  NaN outside the domain (module
    docstring)."""
    al, bl = _to_frame(a, b, E)
    if not _frame_defined(al):
        return np.nan, np.full(6, np.nan), np.full((6, 6), np.nan)
    u = np.empty(3)
    Ju = np.empty((3, 6))
    Hu = np.zeros((3, 6, 6))
    tendon_u(al[0], al[1], al[2], bl[0], bl[1], bl[2], d, co, so, u, Ju, Hu)
    return _density_from_u(u, Ju, Hu, E)


@njit(cache=True)
def _density_from_u(u, Ju, Hu, E):
    """w = |u|, its gradient (6,) and Hessian (6, 6) in the world frame from u, ∂u, ∂²u (actuator frame)."""
    w = np.sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2])
    if not (w > 0.0):
        return np.nan, np.full(6, np.nan), np.full((6, 6), np.nan)
    n = u / w
    gl = np.empty(6)
    for i in range(6):
        gl[i] = Ju[0, i] * n[0] + Ju[1, i] * n[1] + Ju[2, i] * n[2]
    # Hl = Ju^T (I - n n^T) Ju / w + sum_k n_k Hu[k]
    Hl = np.empty((6, 6))
    for i in range(6):
        for j in range(i, 6):
            v = (Ju[0, i] * Ju[0, j] + Ju[1, i] * Ju[1, j] + Ju[2, i] * Ju[2, j] - gl[i] * gl[j]) / w
            v += n[0] * Hu[0, i, j] + n[1] * Hu[1, i, j] + n[2] * Hu[2, i, j]
            Hl[i, j] = v
            Hl[j, i] = v
    # rotate back to the world frame, blockwise: g = E g_loc, H = E H_loc E^T
    g = np.empty(6)
    Hw = np.empty((6, 6))
    T1 = np.empty((6, 6))
    for I in range(2):
        for c in range(3):
            g[3 * I + c] = E[c, 0] * gl[3 * I] + E[c, 1] * gl[3 * I + 1] + E[c, 2] * gl[3 * I + 2]
    for i in range(6):          # T1 = Hl E^T (blockwise on columns)
        for J in range(2):
            for c in range(3):
                T1[i, 3 * J + c] = (Hl[i, 3 * J] * E[c, 0] + Hl[i, 3 * J + 1] * E[c, 1]
                                    + Hl[i, 3 * J + 2] * E[c, 2])
    for I in range(2):          # Hw = E T1 (blockwise on rows)
        for c in range(3):
            for j in range(6):
                Hw[3 * I + c, j] = (E[c, 0] * T1[3 * I, j] + E[c, 1] * T1[3 * I + 1, j]
                                    + E[c, 2] * T1[3 * I + 2, j])
    return w, g, Hw


@njit(cache=True)
def tendon_length_gradient(a, b, E, d, co, so):
    """Length density |r_c,x| and its gradient (6,) w.r.t. (a, b), world frame (no second derivatives).
    NaN outside the domain (module docstring)."""
    al, bl = _to_frame(a, b, E)
    if not _frame_defined(al):
        return np.nan, np.full(6, np.nan)
    u = np.empty(3)
    Ju = np.empty((3, 6))
    tendon_uJ(al[0], al[1], al[2], bl[0], bl[1], bl[2], d, co, so, u, Ju)
    w = np.sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2])
    if not (w > 0.0):
        return np.nan, np.full(6, np.nan)
    g = np.empty(6)
    for I in range(2):
        gl0 = (Ju[0, 3 * I] * u[0] + Ju[1, 3 * I] * u[1] + Ju[2, 3 * I] * u[2]) / w
        gl1 = (Ju[0, 3 * I + 1] * u[0] + Ju[1, 3 * I + 1] * u[1] + Ju[2, 3 * I + 1] * u[2]) / w
        gl2 = (Ju[0, 3 * I + 2] * u[0] + Ju[1, 3 * I + 2] * u[1] + Ju[2, 3 * I + 2] * u[2]) / w
        for c in range(3):
            g[3 * I + c] = E[c, 0] * gl0 + E[c, 1] * gl1 + E[c, 2] * gl2
    return w, g


@njit(cache=True)
def tendon_length_density(a, b, E, d, co, so):
    """Length density |r_c,x| only (no derivatives); NaN where the frame is undefined (module docstring)."""
    al, bl = _to_frame(a, b, E)
    if not _frame_defined(al):
        return np.nan
    u = np.empty(3)
    tendon_u_value(al[0], al[1], al[2], bl[0], bl[1], bl[2], d, co, so, u)
    return np.sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2])


@njit(cache=True)
def slack_terms(a, b, E):
    """(ok, u_0, V_2, V_3) with u = u_0 + d (cos θ V_2 + sin θ V_3) for every tendon at this point (actuator
    frame; ok False where the frame is undefined).  u = a + d (∂g/∂a) b is affine in (d cos θ, d sin θ), since
    g(a) = R(a/|a|)(cos θ e2 + sin θ e3): two evaluations serve any number of tendons (used for the
    admissibility rule and the lengths of slack tendons, which need no derivatives)."""
    al, bl = _to_frame(a, b, E)
    V2 = np.empty(3)
    V3 = np.empty(3)
    if not _frame_defined(al):
        return False, al, V2, V3
    tendon_u_value(al[0], al[1], al[2], bl[0], bl[1], bl[2], 1.0, 1.0, 0.0, V2)
    tendon_u_value(al[0], al[1], al[2], bl[0], bl[1], bl[2], 1.0, 0.0, 1.0, V3)
    for c in range(3):
        V2[c] -= al[c]
        V3[c] -= al[c]
    return True, al, V2, V3


@njit(cache=True)
def slack_density(ok, u0, V2, V3, d, co, so):
    """|u| of one tendon from :func:`slack_terms` (NaN where the frame is undefined)."""
    if not ok:
        return np.nan
    s = 0.0
    for c in range(3):
        v = u0[c] + d * (co * V2[c] + so * V3[c])
        s += v * v
    return np.sqrt(s)


@njit(cache=True)
def density_lower_bound(a, b, d):
    """A lower bound of the length density |r_c,x| [-] of every tendon at distance ≤ ``d`` [m] (any angle θ)
    at one point, from a = r_x and b = r_xx (3,) only — no tendon kernel:

        |r_c,x| ≥ |a| − d |P b| / |a|,      P = I − t tᵀ,  t = a/|a|.

    Why: g(t) = R(t) o is a unit vector normal to t (R takes e1 to t, o ⊥ e1).  For δ ⊥ t the frame turns by
    ω = t × δ + τ t (τ: its twist about t), so dg = ω × g and t·dg = g·(t × ω) = −g·δ, whatever τ.  With
    u = r_c,x = a + d (∂g/∂t) δ, δ = P b/|a|: |u| ≥ t·u = |a| − d g·δ ≥ |a| − d |P b|/|a|.  Attained (to
    round-off) by a planar bend in the plane of e1 and t towards the tendon (θ on the bending side: g = δ/|δ|,
    τ = 0).  The assembly skips the slack tendons' admissibility rule (|r_c,x| ≥ 0.2) where this bound already
    guarantees it; −inf for a = 0."""
    la2 = a[0] * a[0] + a[1] * a[1] + a[2] * a[2]
    if not (la2 > 0.0):
        return -np.inf
    tb = (a[0] * b[0] + a[1] * b[1] + a[2] * b[2]) / la2          # (t·b)/|a|
    pb2 = 0.0
    for c in range(3):
        v = b[c] - tb * a[c]                                       # (P b)_c
        pb2 += v * v
    return np.sqrt(la2) - d * np.sqrt(pb2 / la2)


@njit(cache=True)
def add_tendon(a, b, E, d, co, so, T, scale, g, H, gl, want_H):
    """Add T × scale × (gradient, Hessian) of the length density into the (a, b) blocks (3:9) of g, H and
    scale × gradient into gl (9,), the tendon's own length gradient.  Returns the density w itself (NaN
    outside the domain; the caller applies the admissibility rule to it).
    The Hessian kernel runs only when ``want_H`` and T ≠ 0."""
    if want_H and T != 0.0:
        w, gw, Hw = tendon_density(a, b, E, d, co, so)
        for i in range(6):
            for j in range(6):
                H[3 + i, 3 + j] += T * scale * Hw[i, j]
    else:
        w, gw = tendon_length_gradient(a, b, E, d, co, so)
    for i in range(6):
        gl[3 + i] += scale * gw[i]
        g[3 + i] += T * scale * gw[i]
    return w
