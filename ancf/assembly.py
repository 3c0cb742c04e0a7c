"""One assembly loop for every distributed generalized force (docs/design.md §3).

Each force is a density w(r, r_x, r_xx) at a quadrature point (modules in :mod:`ancf.forces`).  Since
r = S q^i, r_x = S_x q^i, r_xx = S_xx q^i are linear in the element coordinates, with
B = [S; S_x; S_xx] (9 × 12) the element gradient is Bᵀ ∇w and the Hessian Bᵀ ∇²w B.  ``S`` has the
Kronecker structure [s_j I]_j, so B never needs to be formed: with N[k, α, j] = d^α s_j/dx^α,

    G[block j, c]                += Σ_α N[k,α,j] ∇w[3α + c],
    H[block j, c; block l, c']   += Σ_α Σ_β N[k,α,j] N[k,β,l] ∇²w[3α + c, 3β + c'].

Q(q) = ∂Π/∂q is paper eq. (1) with the signs of the potential
Π = U_axial + U_bend + Σ T_i l_c,i − p ∫ A(λ) λ dx − m' ∫ g·r dx − F · p_end.

Admissible states (the model's domain).  The densities divide by |r_x|, by 1 + t·e1 (the Rodrigues section
frame of :mod:`ancf.forces.tendon` and of the tip rotation, singular for a section pointing back along −e1)
and by the tendon length density |r_c,x| (zero where the tendon path folds: the local curvature radius
equals the tendon distance d on the tendon's side).  Near those points the model has no meaning — a
collapsed section, a frame that flips under an infinitesimal change of the tangent, a tendon path that
reverses — so a state is *inadmissible*, and :func:`assemble` returns an infinite energy for it (the line
searches of :mod:`ancf.solvers` then step back; nothing is divided by zero), when

* q contains NaN or inf (code ``NONFINITE``);
* |r_x| < ``STRETCH_MIN`` = 0.2 at a quadrature point or at the tip slope (``COLLAPSED``);
* 1 + t·e1 < ``FRAME_MIN`` = 0.01 at a quadrature point or at the tip slope, t = r_x/|r_x| (``REVERSED``:
  the section has turned more than ≈172° from the base axis);
* a tendon's length density |r_c,x| < ``TENDON_MIN`` = 0.2 at a quadrature point (``FOLDED``), whether the
  tendon is taut or slack (the rule does not depend on the loads).  For a slack tendon in a Newton loop
  (``need_lengths`` 0, no length wanted) the density is computed only where the cheap lower bound
  :func:`ancf.forces.tendon.density_lower_bound` (|a| − d |P b|/|a|, exact for a bend towards the tendon)
  does not already guarantee the rule — everywhere but near folding; the rule costs ≈ 1/3 of an assembly with
  three slack tendons otherwise.

The thresholds leave a wide margin around the operating range (paper preset at T = 5 N, 0–120 kPa: bends
up to 90°, 1 + t·e1 ≥ 1.02, |r_c,x| ≥ 0.65).  :func:`state_status` applies the same rules and says which
one fails and where (:class:`ancf.Model` turns that into a typed error for a user-given state).
"""

import numpy as np
from numba import njit

from .forces.axial import add_axial
from .forces.bending import add_bending
from .forces.gravity import add_gravity
from .forces.pressure import add_pressure, add_stretch_length
from .forces.tendon import (
    add_tendon_ws,
    density_lower_bound,
    slack_density,
    slack_terms,
    tendon_length_density,
    tendon_work,
)
from .forces.tip_load import add_tip_load

#: Admissibility thresholds and status codes (module docstring).
STRETCH_MIN = 0.2
FRAME_MIN = 0.01
TENDON_MIN = 0.2
OK, NONFINITE, COLLAPSED, REVERSED, FOLDED = 0, 1, 2, 3, 4
#: The slack tendons' rule is taken as satisfied where the density's lower bound exceeds TENDON_MIN by this factor.
SLACK_BOUND_MARGIN = 1.001


@njit(cache=True)
def _interpolate(Nk, q, off, alpha, out):
    """``out`` (3,) = d^α r/dx^α at one quadrature point of the element whose coordinates start at ``off``:
    Σ_j Nk[α, j] q[off + 3 j : off + 3 j + 3] (in place)."""
    for c in range(3):
        out[c] = (Nk[alpha, 0] * q[off + c] + Nk[alpha, 1] * q[off + 3 + c] + Nk[alpha, 2] * q[off + 6 + c]
                  + Nk[alpha, 3] * q[off + 9 + c])


@njit(cache=True)
def slope_status(a, E):
    """(code, value) of the stretch and frame rules for one slope a = r_x: ``COLLAPSED`` with |a|,
    ``REVERSED`` with 1 + t·e1, or ``OK``.  NaN fails every comparison, so it is never admissible."""
    s = a[0] * a[0] + a[1] * a[1] + a[2] * a[2]
    if not (s >= STRETCH_MIN * STRETCH_MIN):
        return COLLAPSED, np.sqrt(s)
    c1 = 1.0 + (E[0, 0] * a[0] + E[1, 0] * a[1] + E[2, 0] * a[2]) / np.sqrt(s)
    if not (c1 >= FRAME_MIN):
        return REVERSED, c1
    return OK, 0.0


@njit(cache=True)
def point_status(a, b, E, d, co, so):
    """(code, tendon index or −1, value) of every admissibility rule at one quadrature point."""
    code, v = slope_status(a, E)
    if code != OK:
        return code, -1, v
    for i in range(d.size):
        w = tendon_length_density(a, b, E, d[i], co[i], so[i])
        if not (w >= TENDON_MIN):
            return FOLDED, i, w
    return OK, -1, 0.0


@njit(cache=True)
def state_status(q, n_el, N, E, d, co, so):
    """First admissibility rule q violates: (code, element (n_el for the tip slope), quadrature point,
    tendon, value); code ``OK`` (0) when q is admissible.  The rules of the module docstring."""
    for j in range(q.size):
        if not np.isfinite(q[j]):
            return NONFINITE, j // 6, -1, -1, q[j]
    nq = N.shape[0]
    a = np.empty(3)
    b = np.empty(3)
    for e in range(n_el):
        off = 6 * e
        for k in range(nq):
            Nk = N[k]
            _interpolate(Nk, q, off, 1, a)
            _interpolate(Nk, q, off, 2, b)
            code, i, v = point_status(a, b, E, d, co, so)
            if code != OK:
                return code, e, k, i, v
    code, v = slope_status(q[q.size - 3:], E)
    return code, n_el, -1, -1, v


@njit(cache=True)
def tendon_lengths(q, n_el, N, wq, E, d, co, so):
    """Tendon lengths l_c (m,) [m] at the full coordinates q, nothing else (the lengths of
    :func:`assemble` with ``need_lengths`` 1, from the shared slack-tendon terms for three or more tendons);
    NaN for a state outside the domain (module docstring's rules).  For Newton loops that assemble without
    lengths and want them only at the solution."""
    m = d.size
    lc = np.zeros(m)
    a = np.empty(3)
    b = np.empty(3)
    for e in range(n_el):
        off = 6 * e
        for k in range(wq.size):
            Nk = N[k]
            _interpolate(Nk, q, off, 1, a)
            _interpolate(Nk, q, off, 2, b)
            if slope_status(a, E)[0] != OK:
                lc[:] = np.nan
                return lc
            if m >= 3:
                s_ok, u0, V2, V3 = slack_terms(a, b, E)
            for i in range(m):
                if m >= 3:
                    wi = slack_density(s_ok, u0, V2, V3, d[i], co[i], so[i])
                else:
                    wi = tendon_length_density(a, b, E, d[i], co[i], so[i])
                if not (wi >= TENDON_MIN):
                    lc[:] = np.nan
                    return lc
                lc[i] += wq[k] * wi
    return lc


@njit(cache=True)
def _scatter(q_off, Nk, g9, H9, G, H, want_H):
    """Add Bᵀ g9 into G and Bᵀ H9 B into the upper block triangle of H (see :func:`_mirror`).

    No density has second derivatives in r (gravity is linear in r, the tip load is added separately),
    so only the (r_x, r_xx) rows/columns of H9 (α, β ∈ {1, 2}) are scattered."""
    for j in range(4):
        for c in range(3):
            G[q_off + 3 * j + c] += Nk[0, j] * g9[c] + Nk[1, j] * g9[3 + c] + Nk[2, j] * g9[6 + c]
    if want_H:
        for j in range(4):
            for l in range(j, 4):
                for al in range(1, 3):
                    for be in range(1, 3):
                        f = Nk[al, j] * Nk[be, l]
                        if f == 0.0:
                            continue
                        for c in range(3):
                            for c2 in range(3):
                                H[q_off + 3 * j + c, q_off + 3 * l + c2] += f * H9[3 * al + c, 3 * be + c2]


@njit(cache=True)
def _mirror(H):
    """Complete H from its upper block triangle (3×3 blocks; diagonal blocks are already full)."""
    n = H.shape[0]
    for i in range(n):
        for k in range(3 * (i // 3 + 1), n):
            H[k, i] = H[i, k]


@njit(cache=True)
def assemble(q, n_el, N, wq, ea, ei, pa, mg, E, d, co, so, T, h, F, want_H, need_lengths):
    """Total potential Π, its gradient Q (ndof,) and Hessian (ndof, ndof) at the full coordinates q.

    Also returns the tendon lengths l_c (m,), their gradients J_l (m, ndof) [= ∂Q/∂T], the deformed
    length ∫λ dx and its gradient (ndof,) [∂Q/∂p = −A_eff × this for a constant pressure area].

    Parameters: N (nq, 3, 4) shape table, wq (nq,) weights in x [m]; ea, ei stiffness coefficients;
    pa = p × coefficients of A(λ) λ = Σ c_k λ^{k+1} [N] (constant area: (p A_eff,)); mg = m' g [N/m];
    E actuator frame (3, 3); d, co, so (m,) tendon distance [m] and
    cos/sin θ; T (m,) tensions [N]; h tool offset [m]; F (3,) total tip load [N].
    ``need_lengths``: 0 — slack tendons (T_i = 0) are skipped and l_c, J_l, J_arc, arc are left at zero
    (Newton loops); 1 — lengths and arc length as values only (J_l, J_arc zero); 2 — values and gradients.
    """
    ndof = q.size
    m = d.size
    for j in range(ndof):
        if not np.isfinite(q[j]):
            return np.inf, np.zeros(ndof), np.zeros((1, 1)), np.zeros(m), np.zeros((m, ndof)), 0.0, np.zeros(ndof)
    G = np.zeros(ndof)
    H = np.zeros((ndof, ndof)) if want_H else np.zeros((1, 1))
    lc = np.zeros(m)
    Jl = np.zeros((m, ndof))
    Jarc = np.zeros(ndof)
    arc = 0.0
    energy = 0.0
    nq = wq.size
    r = np.empty(3)
    a = np.empty(3)
    b = np.empty(3)
    zero9 = np.zeros((9, 9))
    g9 = np.zeros(9)
    H9 = np.zeros((9, 9))
    ga = np.zeros(9)
    gl = np.zeros(9)
    ws = tendon_work()
    has_p = False
    for k in range(pa.size):
        if pa[k] != 0.0:
            has_p = True
    # three or more slack tendons: their densities from two evaluations per point (forces.tendon.slack_terms)
    n_slack = 0
    d_slack = 0.0
    for i in range(m):
        if T[i] == 0.0 and need_lengths < 2:
            n_slack += 1
            d_slack = max(d_slack, abs(d[i]))
    shared = n_slack >= 3
    # without lengths (Newton loops) a slack tendon only needs the admissibility rule: skipped at points where
    # forces.tendon.density_lower_bound already guarantees it for every slack tendon (with a margin for round-off)
    bound_rule = need_lengths == 0 and n_slack > 0
    for e in range(n_el):
        off = 6 * e
        for k in range(nq):
            Nk = N[k]
            _interpolate(Nk, q, off, 0, r)
            _interpolate(Nk, q, off, 1, a)
            _interpolate(Nk, q, off, 2, b)
            sc = wq[k]
            if slope_status(a, E)[0] != OK:
                # inadmissible state (module docstring); line searches back off on inf.  The tendon rule
                # is checked below on the densities the tendon kernels compute anyway (point_status's rule)
                return np.inf, G, H, lc, Jl, arc, Jarc
            g9[:] = 0.0
            if want_H:
                H9[:, :] = 0.0
            energy += add_axial(a, ea, sc, g9, H9)
            energy += add_bending(a, b, ei, sc, g9, H9)
            if has_p:
                energy += add_pressure(a, pa, sc, g9, H9)
            energy += add_gravity(r, mg, sc, g9)
            if need_lengths > 0:
                ga[:] = 0.0
                arc += add_stretch_length(a, sc, ga)
                if need_lengths == 2:
                    _scatter(off, Nk, ga, zero9, Jarc, H, False)
            rule_holds = bound_rule and density_lower_bound(a, b, d_slack) >= SLACK_BOUND_MARGIN * TENDON_MIN
            if shared and not rule_holds:
                s_ok, u0, V2, V3 = slack_terms(a, b, E)
            for i in range(m):
                if T[i] == 0.0 and need_lengths < 2:
                    # a slack tendon: no force, but its path must be admissible too (the rule does not
                    # depend on the loads, and its length is a result)
                    if rule_holds:
                        continue
                    if shared:
                        wi = slack_density(s_ok, u0, V2, V3, d[i], co[i], so[i])
                    else:
                        wi = tendon_length_density(a, b, E, d[i], co[i], so[i])
                    if not (wi >= TENDON_MIN):
                        return np.inf, G, H, lc, Jl, arc, Jarc
                    if need_lengths == 1:
                        lc[i] += sc * wi
                    continue
                gl[:] = 0.0
                wi = add_tendon_ws(a, b, E, d[i], co[i], so[i], T[i], sc, g9, H9, gl, want_H, ws)
                if not (wi >= TENDON_MIN):
                    return np.inf, G, H, lc, Jl, arc, Jarc
                lc[i] += sc * wi
                energy += T[i] * sc * wi
                if need_lengths == 2:
                    _scatter(off, Nk, gl, zero9, Jl[i], H, False)
            _scatter(off, Nk, g9, H9, G, H, want_H)
    if want_H:
        _mirror(H)
    if slope_status(q[ndof - 3:], E)[0] != OK:
        # the tip slope is not a quadrature point: the same rules (the tip load divides by |a|, the tip
        # rotation by 1 + t·e1)
        return np.inf, G, H, lc, Jl, arc, Jarc
    energy += add_tip_load(q, h, F, G, H, want_H)
    return energy, G, H, lc, Jl, arc, Jarc
