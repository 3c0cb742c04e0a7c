"""The rigid intermediate cap as an elimination map (docs/multisegment.md §2).

Segment k ends at its last node (r, a) — a = r_x there, t = a/|a|.  The cap is rigid, of length h along t, and the
model has no torsion (every section frame is R(t), the Rodrigues rotation taking the base axis to t), so the cap
fixes segment k + 1's first node:

    r₀ = r + h t,                 a₀ = μ t   ("free": μ > 0 a free coordinate, segment k + 1's base stretch)
                                  a₀ = a     ("continuous": the slope, stretch included, carries over)

With P = I − t tᵀ the first derivatives are

    ∂r₀/∂r = I,  ∂r₀/∂a = h P/|a|,   ∂a₀/∂a = μ P/|a| (free) or I (continuous),  ∂a₀/∂μ = t,

and for any vector g, with s = g·t,  ∇²_a (g·t) = −[s P + (P g) tᵀ + t (P g)ᵀ]/|a|²,  ∂²(μ g·t)/∂μ∂a = P g/|a|.
A potential Π(…, r₀, a₀, …) then has, in the free coordinates x = (r, a, μ) of the junction,

    ∇_x Π = Jᵀ g,    ∇²_x Π = Jᵀ H J + Σ_i g_i ∇²Φ_i,

g = (g_r, g_a) = ∂Π/∂(r₀, a₀); the last term is :func:`curvature` (the only part that is not a matrix product).
"""

from __future__ import annotations

import math

import numpy as np

_I3 = np.eye(3)


def _frame(a: np.ndarray) -> tuple[np.ndarray, float, np.ndarray]:
    """(t (3,), |a|, P (3, 3)) of a slope a (3,)."""
    lam = math.sqrt(float(a @ a))
    t = a / lam
    return t, lam, _I3 - t[:, None] * t[None, :]


def node(r: np.ndarray, a: np.ndarray, h: float, mu: float, continuous: bool) -> np.ndarray:
    """Segment k + 1's first node (6,) = (r₀, a₀) [m, -] from segment k's last node r (3,) [m], a (3,) [-], the cap
    length h [m] and the base stretch mu [-] (ignored when ``continuous``)."""
    t, _, _ = _frame(a)
    return np.concatenate([r + h * t, a if continuous else mu * t])


def jacobian(a: np.ndarray, h: float, mu: float, continuous: bool) -> np.ndarray:
    """∂(r₀, a₀)/∂(r, a, μ) (6, 7) at slope a (3,) (module docstring; the μ column is zero when continuous)."""
    t, lam, P = _frame(a)
    J = np.zeros((6, 7))
    J[:3, :3] = _I3
    J[:3, 3:6] = h * P / lam
    if continuous:
        J[3:, 3:6] = _I3
    else:
        J[3:, 3:6] = mu * P / lam
        J[3:, 6] = t
    return J


def _hess_dot_t(g: np.ndarray, t: np.ndarray, lam: float, P: np.ndarray) -> np.ndarray:
    """∇²_a (g·t) (3, 3) (module docstring)."""
    Pg = P @ g
    return -(float(g @ t) * P + Pg[:, None] * t[None, :] + t[:, None] * Pg[None, :]) / lam ** 2


def curvature(g: np.ndarray, a: np.ndarray, h: float, mu: float, continuous: bool) -> np.ndarray:
    """Σ_i g_i ∇²Φ_i (7, 7) in (r, a, μ) for the gradient g (6,) = ∂Π/∂(r₀, a₀) of a potential at the junction."""
    t, lam, P = _frame(a)
    C = np.zeros((7, 7))
    C[3:6, 3:6] = h * _hess_dot_t(g[:3], t, lam, P)
    if not continuous:
        C[3:6, 3:6] += mu * _hess_dot_t(g[3:], t, lam, P)
        C[3:6, 6] = C[6, 3:6] = P @ g[3:] / lam
    return C
