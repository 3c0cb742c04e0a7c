r"""Tendons as frictionless sliding cables through guide points (``docs/fem.md`` §5).

A tendon is the polyline :math:`x_0, x_1, \dots, x_n`: ``x_0`` is the fixed exit on the base cap at
distance ``d`` from the axis, ``x_1 … x_{n-1}`` are guide points (one per interior root), ``x_n`` is the
anchor on the distal cap (cap point at offset ``a = (0, d e_r(θ))``).  Its length and derivatives,
with :math:`\ell_k = |x_{k+1} - x_k|`, :math:`e_k = (x_{k+1} - x_k)/\ell_k`:

.. math::

    L = \sum_k \ell_k, \qquad \frac{\partial L}{\partial x_k} = e_{k-1} - e_k, \qquad
    \frac{\partial^2 L}{\partial x \partial x} = \sum_k \begin{bmatrix} H_k & -H_k \\ -H_k & H_k \end{bmatrix},
    \quad H_k = \frac{I - e_k e_k^T}{\ell_k}.

At tension ``T`` the cable's potential is ``T L`` (conservative): it adds ``T ∂L/∂q`` to the residual and
``T ∂²L/∂q²`` to the tangent (plus the rigid-link geometric term of the anchor force).  At locked length
``L₀`` the tension is a Lagrange multiplier of ``L(q) = L₀``.  A cable never pushes: ``T ≥ 0`` always
(prescribed tensions are validated; a locked cable whose multiplier would turn negative goes slack).
With friction at the guides each segment carries its own tension (the capstan law with stick/slip history of
:mod:`fem_reference.loads.tendon_friction`).

**Guide points (modelling choice, flagged).**  The tendon routing distance of the paper's actuator
(27.5 mm) is larger than the bellows wall radius, so the guides are not wall nodes.  Each guide sits
on a (virtual) rigid flange of its root ring: at distance ``d`` from the ring centroid ``c``, in the
direction of the ring's mid-wall point ``x_θ`` at the tendon angle,

.. math::

    x_g = c + d\,n, \qquad n = y/\rho,\ \ y = x_\theta - c = \sum_j a_j x_j,\ \ \rho = |y|,
    \qquad c = \frac1N\sum_{j\in\text{ring}} x_j,

so it follows the translation, tilt and twist of the ring but not its radial growth under pressure
(a linear radial extrapolation was tried first: it made the cable zig-zag outwards under pressure).
Its derivatives, with :math:`P = I - n n^T` and :math:`f` the force conjugate to :math:`x_g`:

.. math::

    \frac{\partial x_g}{\partial x_j} = \frac{1}{N} I + a_j \frac{d}{\rho} P, \qquad
    \frac{\partial^2 (f\cdot x_g)}{\partial x_j \partial x_l} =
        -a_j a_l \frac{d}{\rho^2}\big[(Pf)n^T + n(Pf)^T + (n\cdot f)P\big].
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = [
    "TendonPath",
    "guide_hessian",
    "guide_point",
    "polyline_gradient",
    "polyline_hessian_blocks",
    "polyline_length",
]


def polyline_length(x: np.ndarray) -> float:
    """Length of the polyline through points ``x`` of shape ``(n+1, 3)`` [m]."""
    return float(np.linalg.norm(np.diff(x, axis=0), axis=1).sum())


def polyline_gradient(x: np.ndarray) -> np.ndarray:
    """``∂L/∂x``, shape ``(n+1, 3)``."""
    d = np.diff(x, axis=0)
    e = d / np.linalg.norm(d, axis=1)[:, None]
    g = np.zeros_like(x)
    g[:-1] -= e
    g[1:] += e
    return g


def polyline_hessian_blocks(x: np.ndarray) -> np.ndarray:
    """Segment blocks ``H_k = (I - e_k e_kᵀ)/ℓ_k``, shape ``(n, 3, 3)``."""
    d = np.diff(x, axis=0)
    ell = np.linalg.norm(d, axis=1)
    e = d / ell[:, None]
    return (np.eye(3)[None] - e[:, :, None] * e[:, None, :]) / ell[:, None, None]


def guide_point(xr: np.ndarray, wc: np.ndarray, a: np.ndarray, d: float):
    """Guide position, Jacobian blocks and curvature factors.

    Parameters
    ----------
    xr : (3, N) current ring node positions; wc : (N,) centroid weights; a : (N,) weights of y; d : float

    Returns
    -------
    x_g : (3,); blocks : (N, 3, 3) ``∂x_g/∂x_j``; (n, P, rho) for :func:`guide_hessian`.
    """
    y = xr @ a
    rho = float(np.linalg.norm(y))
    n = y / rho
    P = np.eye(3) - np.outer(n, n)
    xg = xr @ wc + d * n
    blocks = wc[:, None, None] * np.eye(3)[None] + (a * d / rho)[:, None, None] * P[None]
    return xg, blocks, (n, P, rho)


def guide_hessian(f: np.ndarray, n: np.ndarray, P: np.ndarray, rho: float, d: float) -> np.ndarray:
    """``∂²(f·d n)/∂y²`` (3×3) — multiply by ``a_j a_l`` for the node blocks."""
    Pf = P @ f
    return -(d / rho ** 2) * (np.outer(Pf, n) + np.outer(n, Pf) + float(n @ f) * P)


@dataclass
class TendonPath:
    """Routing of one tendon.

    Attributes
    ----------
    theta : float
        Angle about the axis [rad].
    radius : float
        Routing distance ``d`` [m].
    exit_point : ndarray (3,)
        Fixed exit on the base cap [m].
    guide_nodes : list of ndarray of int
        Ring nodes of each guide.
    guide_wc, guide_a : list of ndarray
        Centroid weights and weights of ``y = x_θ − c`` over the ring nodes.
    anchor : ndarray (3,)
        Anchor offset on the distal cap, reference frame, relative to the cap centre [m].
    """

    theta: float
    radius: float
    exit_point: np.ndarray
    guide_nodes: list
    guide_wc: list
    guide_a: list
    anchor: np.ndarray

    @property
    def n_points(self) -> int:
        return len(self.guide_nodes) + 2

    def points(self, x_nodes: np.ndarray, cap_centre: np.ndarray, R: np.ndarray) -> np.ndarray:
        """Current polyline points, shape ``(n+1, 3)``; ``x_nodes`` are current node positions (3, n)."""
        pts = [self.exit_point]
        for nodes, wc, a in zip(self.guide_nodes, self.guide_wc, self.guide_a):
            pts.append(guide_point(x_nodes[:, nodes], wc, a, self.radius)[0])
        pts.append(cap_centre + R @ self.anchor)
        return np.array(pts)
