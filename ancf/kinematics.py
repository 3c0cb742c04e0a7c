"""Gradient-deficient ANCF kinematics (paper Sec. II-C) and the tip pose (Sec. III-A).

Node k carries ``q_k = [r_k, r_x,k]`` (6 numbers); element i uses ``q^i = [q_i, q_{i+1}]`` (12) and the
cubic Hermite shape functions over ξ = x / l_0 ∈ [0, 1]:

    s1 = 1 − 3ξ² + 2ξ³,  s2 = l_0 (ξ − 2ξ² + ξ³),  s3 = 3ξ² − 2ξ³,  s4 = l_0 (−ξ² + ξ³),
    r(x) = s1 r_i + s2 r_x,i + s3 r_{i+1} + s4 r_x,{i+1}        (S = [s1 I, s2 I, s3 I, s4 I]).

Derivatives in x are d/dx = (1/l_0) d/dξ.  ``shape_table`` returns N[k, α, j] = d^α s_j / dx^α at the
quadrature points (α = 0, 1, 2), the only data the assembly needs.

Tip (paper eq. 2b and the rigid tool offset h):  p_end = r_{n+1} + h t,  t = r_x,{n+1} / |r_x,{n+1}|,

    ∂p_end/∂r_{n+1} = I,   ∂p_end/∂r_x,{n+1} = h (I − t tᵀ) / λ.

Tip orientation: the Rodrigues rotation taking the base axis e1 to t (no twist; torsion is not modelled),
with v = e1 × t and c = e1 · t,

    R(t) = I + [v]× + [v]×² / (1 + c)   (equivalently R x = c x + v × x + (v·x) v / (1 + c)),

defined for every t except t = −e1 (a 180° fold, outside any physical state of this actuator).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .errors import CollapsedStateError


def gauss_legendre(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Gauss–Legendre points ξ and weights on [0, 1] (n points, exact for degree 2n − 1)."""
    x, w = np.polynomial.legendre.leggauss(n)
    return 0.5 * (x + 1.0), 0.5 * w


def hermite(xi, l0: float) -> np.ndarray:
    """Shape functions and their x-derivatives: array (3, 4, len(xi)) = [value, d/dx, d²/dx²][s1..s4]."""
    xi = np.atleast_1d(np.asarray(xi, float))
    s = np.array([1 - 3 * xi**2 + 2 * xi**3, l0 * (xi - 2 * xi**2 + xi**3),
                  3 * xi**2 - 2 * xi**3, l0 * (-xi**2 + xi**3)])
    ds = np.array([-6 * xi + 6 * xi**2, l0 * (1 - 4 * xi + 3 * xi**2),
                   6 * xi - 6 * xi**2, l0 * (-2 * xi + 3 * xi**2)]) / l0
    dds = np.array([-6 + 12 * xi, l0 * (-4 + 6 * xi), 6 - 12 * xi, l0 * (-2 + 6 * xi)]) / l0**2
    return np.array([s, ds, dds])


def shape_table(n_points: int, l0: float) -> tuple[np.ndarray, np.ndarray]:
    """N[k, α, j] at the Gauss points (shape (n_points, 3, 4)) and weights in x (shape (n_points,)) [m]."""
    xi, w = gauss_legendre(n_points)
    return np.ascontiguousarray(hermite(xi, l0).transpose(2, 0, 1)), w * l0


def reference_q(n_elements: int, length: float, base_axis) -> np.ndarray:
    """Straight undeformed configuration along ``base_axis``: array (6(n+1),)."""
    e1 = np.asarray(base_axis, float)
    x = np.linspace(0.0, length, n_elements + 1)
    q = np.zeros((n_elements + 1, 6))
    q[:, :3] = x[:, None] * e1
    q[:, 3:] = e1
    return q.ravel()


def interpolate(q: np.ndarray, n_elements: int, length: float, per_element: int = 8, order: int = 0):
    """Centreline points (order 0), r_x (1) or r_xx (2) sampled along the actuator: array (m, 3)."""
    l0 = length / n_elements
    xi = np.linspace(0.0, 1.0, per_element + 1)
    N = hermite(xi, l0)[order]                      # (4, m)
    qn = q.reshape(-1, 6)
    pts = []
    for e in range(n_elements):
        blocks = np.array([qn[e, :3], qn[e, 3:], qn[e + 1, :3], qn[e + 1, 3:]])   # (4, 3)
        seg = N.T @ blocks
        pts.append(seg if e == 0 else seg[1:])
    return np.vstack(pts)


# --------------------------------------------------------------------------------------------- tip
def skew(v) -> np.ndarray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def tip_position(q: np.ndarray, tool_offset: float) -> np.ndarray:
    """p_end = r_{n+1} + h t [m]."""
    r, a = q[-6:-3], q[-3:]
    return r + tool_offset * a / np.linalg.norm(a)


def tip_position_jacobian(q: np.ndarray, tool_offset: float) -> np.ndarray:
    """∂p_end/∂q: array (3, len(q)); nonzero only in the last node's 6 columns."""
    a = q[-3:]
    lam = np.linalg.norm(a)
    t = a / lam
    J = np.zeros((3, q.size))
    J[:, -6:-3] = np.eye(3)
    J[:, -3:] = tool_offset * (np.eye(3) - np.outer(t, t)) / lam
    return J


@njit(cache=True)
def _rodrigues(t, e1):
    """(ok, R) of :func:`rodrigues` in compiled form: R = I + V + V²/(1 + c), V = [e1 × t]×, c = e1·t."""
    v0 = e1[1] * t[2] - e1[2] * t[1]
    v1 = e1[2] * t[0] - e1[0] * t[2]
    v2 = e1[0] * t[1] - e1[1] * t[0]
    c = e1[0] * t[0] + e1[1] * t[1] + e1[2] * t[2]
    R = np.eye(3)
    if c <= -1.0 + 1e-12:
        return False, R
    V = np.array([[0.0, -v2, v1], [v2, 0.0, -v0], [-v1, v0, 0.0]])
    R += V + V @ V / (1.0 + c)
    return True, R


def rodrigues(t, e1) -> np.ndarray:
    """Rotation matrix taking unit vector ``e1`` to unit vector ``t`` about e1 × t (3, 3)."""
    ok, R = _rodrigues(np.ascontiguousarray(t, dtype=float), np.ascontiguousarray(e1, dtype=float))
    if not ok:
        raise CollapsedStateError("tip frame undefined: the tip tangent points against the base axis "
                                  "(a 180 degree fold)")
    return R


def rodrigues_derivative(t, e1) -> np.ndarray:
    """dR/dt_k as array (3, 3, 3) [k, i, j] for the Rodrigues rotation of :func:`rodrigues`."""
    v = np.cross(e1, t)
    c = float(np.dot(e1, t))
    V = skew(v)
    out = np.empty((3, 3, 3))
    for k in range(3):
        ek = np.zeros(3)
        ek[k] = 1.0
        dV = skew(np.cross(e1, ek))
        dc = e1[k]
        out[k] = dV + (dV @ V + V @ dV) / (1 + c) - V @ V * dc / (1 + c) ** 2
    return out


def tip_rotation(q: np.ndarray, e1) -> np.ndarray:
    """Tip orientation R(t_{n+1}) (3, 3): columns are the images of the actuator frame axes."""
    a = q[-3:]
    return rodrigues(a / np.linalg.norm(a), np.asarray(e1, float))


def tip_angular_jacobian(q: np.ndarray, e1) -> np.ndarray:
    """J_ω (3, len(q)) such that δR = [J_ω δq]× R: the spatial angular-velocity Jacobian of R(t_{n+1})."""
    e1 = np.asarray(e1, float)
    a = q[-3:]
    lam = np.linalg.norm(a)
    t = a / lam
    R = rodrigues(t, e1)
    dRdt = rodrigues_derivative(t, e1)
    dtda = (np.eye(3) - np.outer(t, t)) / lam
    J = np.zeros((3, q.size))
    for j in range(3):
        dR = np.tensordot(dtda[:, j], dRdt, axes=(0, 0))     # dR/da_j
        W = dR @ R.T                                           # skew-symmetric
        J[:, q.size - 3 + j] = [W[2, 1], W[0, 2], W[1, 0]]
    return J
