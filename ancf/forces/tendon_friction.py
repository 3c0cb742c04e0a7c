"""Tendon friction with hysteresis: a capstan (Coulomb) law at the tendon's routing guides.

Guides.  A bellows routes each tendon through holes in its convolutions; the reduced model puts one guide at
each element node the tendon passes: guide 0 at the base node (where the tendon enters the actuator from the
motor, along the base axis e1), guides 1 … n−1 at the inner nodes, and the tendon's anchor at the tip node
(no friction there).  Segment k of tendon i is the tendon's path over element k (from node k to node k+1);
its length is the model's own path integral

    l_ik(q) = ∫_{element k} |r_c,x| dx,        Σ_k l_ik = l_c,i        (paper eq. 5, split per element),

so the frictionless model is the special case of one tension on every segment.

Wrap angles.  The guide point of node j is P_ij = r_j + d_i g_i(r_x,j) (the tendon path of
:mod:`ancf.forces.tendon` at the node, g = R(t) o_i), the direction of segment k its chord
c_ik = P_i,k+1 − P_ik, and the wrap angle at guide k the angle between the adjacent segments' directions

    α_ik = atan2(|a × b|, a·b),    a = c_i,k−1 (k ≥ 1) or e1 (k = 0: the motor side),   b = c_ik,

    ∂α/∂a = −(b − (a·b) a/|a|²) / |a × b|,     ∂α/∂b = −(a − (a·b) b/|b|²) / |a × b|,

chained to q through ∂P_ij/∂r_j = I, ∂P_ij/∂r_x,j = d_i ∂g_i/∂a (the generated tendon kernel's ∂u/∂b at
d = 1, :mod:`ancf.forces._tendon_generated`).  α is a norm and has no derivative at α = 0 (a straight
section); there its gradient is taken as zero.  On a circular arc of total turning Θ with n equal elements,
the guide points lie on the offset arc (the nodes are exact), every inner chord turns by Θ/n and the first
by Θ/(2n) from the base axis: the guides' total wrap is Θ (1 − 1/(2n)) — the turning of the last
half-segment ends at the anchor — and tends to Θ as the guides get denser.

Capstan law.  Across guide k the segment tension changes by the capstan factor of its wrap angle; static
friction holds any ratio inside the cone

    T_i,k−1 e^{−μ α_ik} ≤ T_ik ≤ T_i,k−1 e^{μ α_ik}        (T_i,−1 = the motor tension T_i).

Quasi-static history (the tension-propagation model of tendon–sheath friction): from the previous segment
tensions H_ik, the new tension of each segment, walking from the motor, is the previous one clipped to the cone,

    T_ik = clip(H_ik, T_i,k−1 e^{−μ α_ik}, T_i,k−1 e^{μ α_ik}),

which is *slip toward the motor* (code +1; the tendon is pulled in: T_ik = T_i,k−1 e^{−μα}) where the held
tension is below the cone, *reverse slip* (−1; the actuator pulls the tendon back out: T_ik = T_i,k−1 e^{μα})
where it is above, and *stick* (0: T_ik = H_ik, held by static friction) inside.  Loading from slack slips
everywhere: T_ik = T_i exp(−μ Σ_{j≤k} α_ij); unloading leaves a stuck zone far from the motor and reverse slip
near it; T_i = 0 makes every segment slack (the cone of a slack segment is {0}), so a cycle 0 → T → 0 closes.
A stuck segment keeps its *tension* (the tendon is held by force, its length change taken up by its
elasticity), not its length: the law of a compliant tendon that slips rather than stretches.

Generalized force and tangent.  The tendon exerts on the actuator the forces of its segments, whatever the
tensions (the guides take up the differences as friction), so

    Q_f = Σ_i Σ_k T_ik ∇l_ik,      ∂Q_f/∂q = Σ_ik T_ik ∇²l_ik + Σ_ik ∇l_ik (∇T_ik)ᵀ,

with ∇T_ik from the profile: slip +1: ∇T_ik = e^{−μα} ∇T_i,k−1 − μ T_ik ∇α_ik; slip −1: e^{μα} ∇T_i,k−1
+ μ T_ik ∇α_ik; stick: 0 (and ∂T_ik/∂T_i likewise: e^{∓μα} ∂T_i,k−1/∂T_i, or 0).  Friction is not
conservative: the tangent is not symmetric.  With μ = 0 every segment carries the motor tension and Q_f is
the frictionless T_i ∇l_c,i.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..assembly import OK, TENDON_MIN, _interpolate, _mirror, _scatter, slope_status
from ._tendon_generated import tendon_uJ
from .tendon import _frame_defined, _to_frame, add_tendon

#: sliding codes of a segment (:func:`tension_profile`)
SLIP_IN, STICK, SLIP_OUT = 1, 0, -1


@njit(cache=True)
def guide_points(q, n_el, E, d, co, so):
    """(ok, P (m, n+1, 3) [m], G (m, n+1, 3, 3)): the tendon path's points at the nodes, P_ij = r_j + d_i g_i(r_x,j),
    and their derivative with respect to the node slope, G_ij = d_i ∂g_i/∂a (world frame).  ok is False where a
    node's section frame is undefined (1 + t·e1 ≤ 0, or a zero slope)."""
    m = d.size
    P = np.zeros((m, n_el + 1, 3))
    G = np.zeros((m, n_el + 1, 3, 3))
    u = np.empty(3)
    Ju = np.empty((3, 6))
    zero = np.zeros(3)
    gl = np.empty(3)
    dgl = np.empty((3, 3))
    for j in range(n_el + 1):
        a = q[6 * j + 3:6 * j + 6]
        al, _ = _to_frame(a, zero, E)
        if not _frame_defined(al):
            return False, P, G
        lam = np.sqrt(al[0] ** 2 + al[1] ** 2 + al[2] ** 2)
        t0, t1, t2 = al[0] / lam, al[1] / lam, al[2] / lam
        v1, v2 = -t2, t1                                          # v = e1 × t (v0 = 0), c = t0
        for i in range(m):
            vo = v1 * co[i] + v2 * so[i]
            # R(t) o = c o + v × o + (v·o) v / (1 + c), o = (0, co, so), in the actuator frame
            gl[0] = v1 * so[i] - v2 * co[i]
            gl[1] = t0 * co[i] + vo * v1 / (1.0 + t0)
            gl[2] = t0 * so[i] + vo * v2 / (1.0 + t0)
            tendon_uJ(al[0], al[1], al[2], 0.0, 0.0, 0.0, 1.0, co[i], so[i], u, Ju)
            for r in range(3):
                for c in range(3):
                    dgl[r, c] = Ju[r, 3 + c]
            for r in range(3):
                P[i, j, r] = q[6 * j + r] + d[i] * (E[r, 0] * gl[0] + E[r, 1] * gl[1] + E[r, 2] * gl[2])
                for c in range(3):
                    s = 0.0
                    for x in range(3):
                        for y in range(3):
                            s += E[r, x] * dgl[x, y] * E[c, y]
                    G[i, j, r, c] = d[i] * s
    return True, P, G


def wrap_angles(P: np.ndarray, G: np.ndarray, e1: np.ndarray, ndof: int) -> tuple[np.ndarray, np.ndarray]:
    """Wrap angles α (m, n) [rad] at the guides and their gradients ∂α/∂q (m, n, ndof) [rad per coordinate] from
    the guide points P (m, n+1, 3) [m] and their slope derivatives G (m, n+1, 3, 3) (:func:`guide_points`);
    ``e1`` (3,) the base axis (the motor side of guide 0).  Formulas: module docstring."""
    m, n = P.shape[0], P.shape[1] - 1
    C = P[:, 1:] - P[:, :-1]                                          # chords (m, n, 3)
    A = np.concatenate([np.broadcast_to(e1, (m, 1, 3)), C[:, :-1]], axis=1)
    B = C
    s = np.linalg.norm(np.cross(A, B), axis=-1)
    p = np.einsum("ikc,ikc->ik", A, B)
    alpha = np.arctan2(s, p)
    na2 = np.einsum("ikc,ikc->ik", A, A)
    nb2 = np.einsum("ikc,ikc->ik", B, B)
    defined = s > 1e-14 * np.sqrt(na2 * nb2)
    safe = np.where(defined, s, 1.0)[..., None]
    ga = np.where(defined[..., None], -(B - (p / na2)[..., None] * A) / safe, 0.0)     # ∂α/∂a
    gb = np.where(defined[..., None], -(A - (p / nb2)[..., None] * B) / safe, 0.0)     # ∂α/∂b
    gP = np.zeros((m, n, n + 1, 3))                                   # ∂α_k/∂P_j
    k = np.arange(n)
    gP[:, k, k + 1] += gb
    gP[:, k, k] -= gb
    gP[:, k[1:], k[1:]] += ga[:, 1:]
    gP[:, k[1:], k[:-1]] -= ga[:, 1:]
    dalpha = np.zeros((m, n, ndof))
    for j in range(n + 1):
        dalpha[:, :, 6 * j:6 * j + 3] = gP[:, :, j]
        dalpha[:, :, 6 * j + 3:6 * j + 6] = np.einsum("irc,ikr->ikc", G[:, j], gP[:, :, j])
    return alpha, dalpha


def tension_profile(motor: np.ndarray, held: np.ndarray, alpha: np.ndarray, mu: float,
                    dalpha: np.ndarray | None = None):
    """Segment tensions under the capstan law with history (module docstring).

    ``motor`` (m,) [N] the motor tensions, ``held`` (m, n) [N] the previous segment tensions, ``alpha`` (m, n)
    [rad] the wrap angles, ``mu`` [-] the friction coefficient, ``dalpha`` (m, n, ndof) their gradients or None.
    Returns (T (m, n) [N], sliding (m, n) int8 codes SLIP_IN / STICK / SLIP_OUT, ∂T/∂q (m, n, ndof) or None,
    ∂T_ik/∂T_i (m, n))."""
    m, n = alpha.shape
    T = np.empty((m, n))
    code = np.zeros((m, n), np.int8)
    dTm = np.zeros((m, n))
    dTq = None if dalpha is None else np.zeros(dalpha.shape)
    f_all = np.exp(mu * alpha)
    for i in range(m):
        t_prev, dm_prev, dq_prev = float(motor[i]), 1.0, None
        for k in range(n):
            f = f_all[i, k]
            lo, hi, h = t_prev / f, t_prev * f, float(held[i, k])
            if h < lo:
                T[i, k], code[i, k], dTm[i, k] = lo, SLIP_IN, dm_prev / f
                if dTq is not None:
                    dTq[i, k] = -mu * lo * dalpha[i, k] + (0.0 if dq_prev is None else dq_prev / f)
            elif h > hi:
                T[i, k], code[i, k], dTm[i, k] = hi, SLIP_OUT, dm_prev * f
                if dTq is not None:
                    dTq[i, k] = mu * hi * dalpha[i, k] + (0.0 if dq_prev is None else dq_prev * f)
            else:
                T[i, k], code[i, k], dTm[i, k] = h, STICK, 0.0
            t_prev, dm_prev = T[i, k], dTm[i, k]
            dq_prev = None if dTq is None else dTq[i, k]
    return T, code, dTq, dTm


@njit(cache=True)
def segment_forces(q, n_el, N, wq, E, d, co, so, Tseg, want_H):
    """(ok, G (ndof,), H (ndof, ndof), l (m, n) [m], J (m, n, ndof)) of the tendons with one tension per segment:
    G = Σ_ik T_ik ∇l_ik, H = Σ_ik T_ik ∇²l_ik (when ``want_H``; else (1, 1) zeros), the segment lengths l_ik and
    their gradients ∇l_ik.  ``Tseg`` (m, n) [N].  ok False outside the model's domain (:mod:`ancf.assembly`'s
    stretch, frame and tendon rules, at the quadrature points)."""
    ndof = q.size
    m = d.size
    G = np.zeros(ndof)
    H = np.zeros((ndof, ndof)) if want_H else np.zeros((1, 1))
    lseg = np.zeros((m, n_el))
    Jseg = np.zeros((m, n_el, ndof))
    a = np.empty(3)
    b = np.empty(3)
    g9 = np.zeros(9)
    H9 = np.zeros((9, 9))
    gl = np.zeros(9)
    zero9 = np.zeros((9, 9))
    for e in range(n_el):
        off = 6 * e
        for k in range(wq.size):
            Nk = N[k]
            _interpolate(Nk, q, off, 1, a)
            _interpolate(Nk, q, off, 2, b)
            if slope_status(a, E)[0] != OK:
                return False, G, H, lseg, Jseg
            g9[:] = 0.0
            if want_H:
                H9[:, :] = 0.0
            for i in range(m):
                gl[:] = 0.0
                w = add_tendon(a, b, E, d[i], co[i], so[i], Tseg[i, e], wq[k], g9, H9, gl, want_H)
                if not (w >= TENDON_MIN):
                    return False, G, H, lseg, Jseg
                lseg[i, e] += wq[k] * w
                _scatter(off, Nk, gl, zero9, Jseg[i, e], H, False)
            _scatter(off, Nk, g9, H9, G, H, want_H)
    if want_H:
        _mirror(H)
    return True, G, H, lseg, Jseg
