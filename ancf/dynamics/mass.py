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
from numba import njit

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


# --------------------------------------------------------------------------- the tool point's inertia in time
@njit(cache=True, nogil=True)
def _tip_force_c(s, vs, xr, xs, h, m, t, A, out):
    """m J_pᵀ p̈ on (r_{n+1}, r_x,{n+1}) written to ``out`` (6,) — complex arithmetic for the complex step; t, A (3,)
    complex work arrays (no temporaries: the transient kernels call it every Newton iteration).
    p̈ = x_r + h (Dt x_s + ∇²t[v_s, v_s]), Dt = (I − t tᵀ)/|s|, ∇²t[u, u] = −[2 (t·u)(u − t (t·u))
    + t (|u|² − (t·u)²)] / |s|²."""
    s2 = s[0] * s[0] + s[1] * s[1] + s[2] * s[2]
    sn = np.sqrt(s2)
    for c in range(3):
        t[c] = s[c] / sn
    tx = t[0] * xs[0] + t[1] * xs[1] + t[2] * xs[2]
    tu = t[0] * vs[0] + t[1] * vs[1] + t[2] * vs[2]
    uu = vs[0] * vs[0] + vs[1] * vs[1] + vs[2] * vs[2]
    for c in range(3):
        A[c] = xr[c] + h * ((xs[c] - t[c] * tx) / sn - (2 * tu * (vs[c] - t[c] * tu) + t[c] * (uu - tu * tu)) / s2)
    tA = t[0] * A[0] + t[1] * A[1] + t[2] * A[2]
    for c in range(3):
        out[c] = m * A[c]
        out[3 + c] = m * h * (A[c] - t[c] * tA) / sn


@njit(cache=True, nogil=True)
def tool_point_inertia(s, vs, xr, xs, h, m):
    """The tool-point mass m at offset h in a transient run (:mod:`ancf.dynamics.transient`).

    s, vs (3,): the tip slope r_x,{n+1} and its rate; xr, xs (3,): the accelerations of r_{n+1} and r_x,{n+1}.
    Returns (f (6,) [N] the d'Alembert force m J_pᵀ p̈ on the tip node's 6 coordinates, ∂f/∂s (6, 3),
    ∂f/∂v_s (6, 3) — by the complex step, exact to round-off —, and the mass block m J_locᵀ J_loc (6, 6),
    J_loc = [I, h Dt(s)] = ∂f/∂(x_r, x_s))."""
    eps = 1e-30
    f = np.empty(6, np.complex128)
    t = np.empty(3, np.complex128)
    A = np.empty(3, np.complex128)
    sc = s.astype(np.complex128)
    vc = vs.astype(np.complex128)
    xrc = xr.astype(np.complex128)
    xsc = xs.astype(np.complex128)
    _tip_force_c(sc, vc, xrc, xsc, h, m, t, A, f)
    out = f.real.copy()
    Ds = np.empty((6, 3))
    Dv = np.empty((6, 3))
    for j in range(3):
        sc[j] += 1j * eps
        _tip_force_c(sc, vc, xrc, xsc, h, m, t, A, f)
        sc[j] = s[j]
        for i in range(6):
            Ds[i, j] = f[i].imag / eps
        vc[j] += 1j * eps
        _tip_force_c(sc, vc, xrc, xsc, h, m, t, A, f)
        vc[j] = vs[j]
        for i in range(6):
            Dv[i, j] = f[i].imag / eps
    sn = np.sqrt(s[0] * s[0] + s[1] * s[1] + s[2] * s[2])
    J = np.zeros((3, 6))
    for c in range(3):
        J[c, c] = 1.0
        for d in range(3):
            J[c, 3 + d] = h * ((1.0 if c == d else 0.0) - s[c] * s[d] / (sn * sn)) / sn
    return out, Ds, Dv, m * (J.T @ J)
