"""Independent reference solutions used by the tests (closed forms and an elastica shooting solver).

Nothing here uses the ANCF model: each function solves the continuum problem by other means.
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq


def eb_tip_load(F: float, L: float, EI: float) -> float:
    """Euler–Bernoulli cantilever tip deflection under a transverse tip force F [m]: F L³ / (3 EI)."""
    return F * L ** 3 / (3 * EI)


def eb_uniform_load(q: float, L: float, EI: float) -> float:
    """Tip deflection under a uniform transverse load q [N/m]: q L⁴ / (8 EI)."""
    return q * L ** 4 / (8 * EI)


def elastica_tip(L: float, EI: float, Fx: float, Fz: float):
    """Inextensible planar elastica (x–z plane), clamped at the origin along +x, dead tip force (Fx, Fz).

    EI θ'' = −(cos θ Fz − sin θ Fx), θ(0) = 0, θ'(L) = 0 (free end), x' = cos θ, z' = sin θ.
    Solved by shooting on θ'(0).  Returns (x_L, z_L, θ_L).
    """
    def rhs(s, y):
        th, dth, x, z = y
        return [dth, -(np.cos(th) * Fz - np.sin(th) * Fx) / EI, np.cos(th), np.sin(th)]

    def end(k0):
        sol = solve_ivp(rhs, (0, L), [0.0, k0, 0.0, 0.0], rtol=1e-12, atol=1e-14)
        return sol.y[:, -1]

    # bracket the initial curvature: |θ'(0)| ≤ |F| L / EI
    kmax = 1.2 * np.hypot(Fx, Fz) * L / EI + 1e-9
    k0 = brentq(lambda k: end(k)[1], -kmax, kmax, xtol=1e-15, rtol=1e-14)
    th, _, x, z = end(k0)
    return x, z, th


def tendon_arc(W1, EI: float, T: float, d: float, L: float):
    """Uniform circular arc of a weightless actuator bent by one tendon at tension T and distance d.

    Per unit reference length the potential is W(λ) + ½ EI κ² + T λ (1 − d κ) (κ per deformed length);
    a uniform state with zero resultants satisfies  EI κ = T d λ  and  W'(λ) + T (1 − d κ) = 0.
    ``W1(λ)`` is W'(λ).  Returns (λ, κ).
    """
    def f(lam):
        kap = T * d * lam / EI
        return W1(lam) + T * (1 - d * kap)

    lam = brentq(f, 0.5, 1.0 + 1e-12, xtol=1e-15)
    return lam, T * d * lam / EI
