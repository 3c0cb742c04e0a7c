"""Generalized tendon force Q_c,i (paper eq. 1) and the tendon length l_c,i (paper eq. 5).

Tendon i runs at distance d_i from the centreline at angle θ_i (from the reference direction, about the
base axis).  Its path is carried by the section frame R(t) (Rodrigues, taking the base axis to the local
tangent t = r_x/|r_x|):

    r_c(x) = r(x) + d_i R(t(x)) o_i,     o_i = cos θ_i e2 + sin θ_i e3,
    l_c,i  = ∫ |r_c,x| dx,               r_c,x = r_x + d_i (∂g/∂a)(r_x) r_xx,   g(a) = R(a/|a|) o_i.

With constant tension T_i the tendon's potential is T_i l_c,i, so Q_c,i = T_i ∂l_c,i/∂q: the same row
∂l_c,i/∂q is the constraint Jacobian J_A of the locked-length problems and ∂Q/∂T_i.  At a quadrature
point the density is w = |u| = √(A² + B²) with A, B short rational functions of (a, b) in the tendon's own
frame (e1, o_i, e1 × o_i) (derivation: :mod:`._tendon_codegen`; generated: :mod:`._tendon_generated`):

    ∂w = (A ∂A + B ∂B)/w,     ∂²w = (∂A ∂Aᵀ + ∂B ∂Bᵀ + A ∂²A + B ∂²B − ∂w ∂wᵀ)/w.

The tendon frame is F = E Rₓ(θ) = [e1, cos θ e2 + sin θ e3, −sin θ e2 + cos θ e3] (E = [e1 e2 e3] the
actuator frame: e1 = base axis, e2 = reference direction, e3 = e1 × e2); a_loc = Fᵀ a and the derivatives
rotate back blockwise (g = F g_loc, H = F H_loc Fᵀ).  The vector form u (slack tendons' paths) is generated
in the actuator frame.

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

from ._tendon_generated import tendon_ab, tendon_ab_grad, tendon_u_value


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
def tendon_work():
    """Work arrays of the density kernels, allocated once per assembly (none per call): the tendon frame F
    (3, 3), A and B's gradients (2, 6) and Hessians (2, 6, 6), ∂A (6,), a 6 × 6 scratch, the world-frame
    gradient (6,) and Hessian (6, 6) of the density."""
    return (np.empty((3, 3)), np.empty((2, 6)), np.empty((2, 6, 6)), np.empty(6), np.empty((6, 6)), np.empty(6),
            np.empty((6, 6)))


@njit(cache=True, inline="always")
def _frame_terms(a0, a1, a2):
    """(defined, 1/|a|, 1/(1 + c)) with the divisors |a|² and 1 + a0/|a| computed as :func:`_frame_defined`
    does; defined is False (and the others 0) unless both are > 0."""
    x6 = a0 ** 2 + a1 ** 2 + a2 ** 2
    if not (x6 > 0.0):
        return False, 0.0, 0.0
    il = 1.0 / np.sqrt(x6)
    c1 = a0 * il + 1.0
    if not (c1 > 0.0):
        return False, 0.0, 0.0
    return True, il, 1.0 / c1


@njit(cache=True, inline="always")
def _local(a, b, E, d, co, so, want_H, ws):
    """w with ws[1][0] = ∂w and (when ``want_H``) ws[2][0] = ∂²w in the tendon frame ws[0] = F = E Rₓ(θ)
    (columns e1, cos θ e2 + sin θ e3, −sin θ e2 + cos θ e3); NaN outside the domain (module docstring)."""
    F, gab, Hab, gA = ws[0], ws[1], ws[2], ws[3]
    for c in range(3):
        F[c, 0] = E[c, 0]
        F[c, 1] = co * E[c, 1] + so * E[c, 2]
        F[c, 2] = -so * E[c, 1] + co * E[c, 2]
    a0 = F[0, 0] * a[0] + F[1, 0] * a[1] + F[2, 0] * a[2]
    a1 = F[0, 1] * a[0] + F[1, 1] * a[1] + F[2, 1] * a[2]
    a2 = F[0, 2] * a[0] + F[1, 2] * a[1] + F[2, 2] * a[2]
    b0 = F[0, 0] * b[0] + F[1, 0] * b[1] + F[2, 0] * b[2]
    b1 = F[0, 1] * b[0] + F[1, 1] * b[1] + F[2, 1] * b[2]
    b2 = F[0, 2] * b[0] + F[1, 2] * b[1] + F[2, 2] * b[2]
    ok, il, ic = _frame_terms(a0, a1, a2)
    if not ok:
        return np.nan
    if want_H:
        A, B = tendon_ab(a0, a1, a2, b0, b1, b2, d, il, ic, gab, Hab)
    else:
        A, B = tendon_ab_grad(a0, a1, a2, b0, b1, b2, d, il, ic, gab)
    w = np.sqrt(A * A + B * B)
    if not (w > 0.0):
        return np.nan
    for i in range(6):
        gA[i] = gab[0, i]
        gab[0, i] = (A * gab[0, i] + B * gab[1, i]) / w
    if want_H:
        for i in range(6):
            for j in range(i, 6):
                v = (A * Hab[0, i, j] + B * Hab[1, i, j] + gA[i] * gA[j] + gab[1, i] * gab[1, j]
                     - gab[0, i] * gab[0, j]) / w
                Hab[0, i, j] = v
                Hab[0, j, i] = v
    return w


@njit(cache=True, inline="always")
def density_into(a, b, E, d, co, so, want_H, ws):
    """Length density w of one tendon; its world-frame gradient into ws[5] (6,) and, when ``want_H``, its
    Hessian into ws[6] (6, 6) (g = F g_loc, H = F H_loc Fᵀ blockwise).  ``ws``: :func:`tendon_work`.  NaN
    (ws[5], ws[6] undefined) outside the domain."""
    w = _local(a, b, E, d, co, so, want_H, ws)
    if np.isnan(w):
        return w
    F, gl, Hl, T1, g, H = ws[0], ws[1][0], ws[2][0], ws[4], ws[5], ws[6]
    for I in range(2):
        for c in range(3):
            g[3 * I + c] = F[c, 0] * gl[3 * I] + F[c, 1] * gl[3 * I + 1] + F[c, 2] * gl[3 * I + 2]
    if want_H:
        for i in range(6):          # T1 = Hl F^T (blockwise on columns)
            for J in range(2):
                for c in range(3):
                    T1[i, 3 * J + c] = (Hl[i, 3 * J] * F[c, 0] + Hl[i, 3 * J + 1] * F[c, 1]
                                        + Hl[i, 3 * J + 2] * F[c, 2])
        for I in range(2):          # H = F T1 (blockwise on rows)
            for c in range(3):
                for j in range(6):
                    H[3 * I + c, j] = (F[c, 0] * T1[3 * I, j] + F[c, 1] * T1[3 * I + 1, j]
                                       + F[c, 2] * T1[3 * I + 2, j])
    return w


@njit(cache=True)
def tendon_density(a, b, E, d, co, so):
    """Length density |r_c,x| of one tendon, its gradient (6,) and Hessian (6, 6) w.r.t. (a, b) = (r_x, r_xx),
    all in the world frame.  E (3, 3): actuator frame as columns.  NaN outside the domain (module
    docstring)."""
    ws = tendon_work()
    w = density_into(a, b, E, d, co, so, True, ws)
    if np.isnan(w):
        return np.nan, np.full(6, np.nan), np.full((6, 6), np.nan)
    return w, ws[5], ws[6]


@njit(cache=True)
def tendon_length_gradient(a, b, E, d, co, so):
    """Length density |r_c,x| and its gradient (6,) w.r.t. (a, b), world frame (no second derivatives).
    NaN outside the domain (module docstring)."""
    ws = tendon_work()
    w = density_into(a, b, E, d, co, so, False, ws)
    if np.isnan(w):
        return np.nan, np.full(6, np.nan)
    return w, ws[5]


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
    The Hessian kernel runs only when ``want_H`` and T ≠ 0.  Allocates its work arrays: loops over quadrature
    points call :func:`add_tendon_ws` with one :func:`tendon_work`."""
    return add_tendon_ws(a, b, E, d, co, so, T, scale, g, H, gl, want_H, tendon_work())


@njit(cache=True, inline="always")
def add_tendon_ws(a, b, E, d, co, so, T, scale, g, H, gl, want_H, ws):
    """:func:`add_tendon` with the work arrays ``ws`` (:func:`tendon_work`); nothing is added (and NaN
    returned) outside the domain."""
    hess = want_H and T != 0.0
    w = density_into(a, b, E, d, co, so, hess, ws)
    if np.isnan(w):
        return w
    gw, Hw = ws[5], ws[6]
    if hess:
        for i in range(6):
            for j in range(6):
                H[3 + i, 3 + j] += T * scale * Hw[i, j]
    for i in range(6):
        gl[3 + i] += scale * gw[i]
        g[3 + i] += T * scale * gw[i]
    return w
