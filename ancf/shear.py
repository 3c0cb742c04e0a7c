r"""Series rotation-free ("shear") tip compliance: small pure functions with analytic Jacobians.

Why (docs/identification.md §4b).  The FEM bellows has a lateral tip compliance that moves the cap without
rotating it, s(p) ≈ 0.5 / 2.4 / 3.8 mm/N at 0 / 50 / 100 kPa (0.5 / 3 / 6 % of its lateral compliance).  An
Euler–Bernoulli rod puts all lateral compliance into rotation, which locked tendons hold; the FEM's
rotation-free part passes unlocked into the locked compliance.  A rod with the same bending and s in series
reproduces the FEM's locked compliance within 0.5 %.

The term.  With p̂ = p / 100 kPa,

    s(p) = s₀ + s₁ p̂ + s₂ p̂² + …          [m/N]  (``ActuatorParams.shear_compliance``; () or zeros: none)

and a dead load F [N] acting at the tool point (the external tip force plus the tip mass's weight: every
load that acts at the tip; tendon and pressure loads and the distributed self-weight do not), the tool point is

    x = p_end(q) + u,      u(t, F) = s(p) P⊥ F,   P⊥ = I − t tᵀ,   t = a / |a|,  a = r_x(L)  (the tip slope),

where q is the rod's equilibrium under the same loads (unchanged by the term).  A lumped shear spring in
series at the tip: a force along the tangent (axial) gives no shear, a lateral one moves the tool point by
s F⊥ without rotating the cap; a pure tendon moment carries no shear force and gives none.

Derivatives.  With λ = |a|, ∂t/∂a = P⊥/λ and ∂P⊥/∂t · δt = −(δt tᵀ + t δtᵀ), so

    ∂u/∂a = −s [(t·F) I + t Fᵀ] P⊥ / λ                    (3, 3)  (``offset_jacobian``)
    ∂u/∂F = s P⊥                                            (3, 3)
    ∂u/∂s = P⊥ F,   ∂s/∂p = (s₁ + 2 s₂ p̂ + …) / 100 kPa     (``compliance_derivative``)

(∂u/∂a P⊥ = ∂u/∂a: a change of |a| alone does not move t.)  For a response δq = C_q δF of the rod
(tension-held or locked; :mod:`ancf.compliance`), the tool point's compliance is therefore

    C = (J_p + J_u) C_q + s P⊥,      J_u = ∂u/∂q (the last node's slope columns of ∂u/∂a),

whose term J_u C_q = s (∂P⊥/∂q · ∂q/∂F) F is the exact derivative of the projector's turning.  On a straight
state loaded along its axis (F ∥ t) J_u = 0 and C gains exactly s P⊥.

Approximation (stated, not hidden).  The lumped spring's offset also shifts the line of action of F: the rod
tip carries the extra moment u × F = −s (t·F)(t × F), of relative size s |t·F| / L against the lateral
load's own moment (2.5 % for s = 4 mm/N, 1 N axial, L = 0.16 m).  The term here is kinematic — the rod's
equilibrium is that of F at p_end — so this second-order moment is left out (it vanishes for a lateral load
and on straight states; it would need the potential term −½ s Fᵀ P⊥ F in the assembly).
"""

from __future__ import annotations

import numpy as np

from .stiffness import P_REF


def compliance(coeffs, pressure: float) -> float:
    """s(p) = Σ_j coeffs[j] p̂^j [m/N] at ``pressure`` [Pa], p̂ = p / 100 kPa (0 for no coefficients)."""
    x = float(pressure) / P_REF
    return float(sum(float(c) * x ** j for j, c in enumerate(coeffs)))


def compliance_derivative(coeffs, pressure: float) -> float:
    """ds/dp [m/N/Pa] at ``pressure`` [Pa]."""
    x = float(pressure) / P_REF
    return float(sum(j * float(c) * x ** (j - 1) for j, c in enumerate(coeffs) if j > 0)) / P_REF


def minimum(coeffs, p_lo: float, p_hi: float) -> tuple[float, float]:
    """(min s [m/N], the pressure [Pa] where it is taken) of s(p) over [p_lo, p_hi]: the ends and the real
    stationary points inside (exact for a polynomial)."""
    cand = [float(p_lo), float(p_hi)]
    c = [float(v) for v in coeffs]
    if len(c) > 2:
        d = np.polynomial.polynomial.polyder(np.asarray(c))
        for r in np.polynomial.polynomial.polyroots(d):
            if abs(r.imag) < 1e-12 and p_lo <= r.real * P_REF <= p_hi:
                cand.append(float(r.real) * P_REF)
    vals = [compliance(c, p) for p in cand]
    k = int(np.argmin(vals))
    return vals[k], cand[k]


def projector(a) -> np.ndarray:
    """P⊥ = I − t tᵀ (3, 3), t = a/|a| the unit tangent of the tip slope ``a`` (3,)."""
    t = np.asarray(a, float) / np.linalg.norm(a)
    return np.eye(3) - np.outer(t, t)


def offset(a, s: float, F) -> np.ndarray:
    """u = s P⊥ F [m] (3,): the tool point's rotation-free displacement for the tip slope ``a`` (3,), the
    compliance ``s`` [m/N] and the dead tip load ``F`` (3,) [N]."""
    F = np.asarray(F, float)
    t = np.asarray(a, float) / np.linalg.norm(a)
    return s * (F - t * (t @ F))


def offset_jacobian(a, s: float, F) -> np.ndarray:
    """∂u/∂a (3, 3) [m per unit slope] = −s [(t·F) I + t Fᵀ] P⊥ / |a| (module docstring)."""
    a = np.asarray(a, float)
    F = np.asarray(F, float)
    lam = np.linalg.norm(a)
    t = a / lam
    P = np.eye(3) - np.outer(t, t)
    return -s * ((t @ F) * np.eye(3) + np.outer(t, F)) @ P / lam
