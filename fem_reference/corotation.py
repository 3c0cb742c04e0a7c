r"""Finite rotation of each ring of nodes in a Newton update (a corotational correction of the increment).

A Newton step gives nodal displacement increments :math:`\delta u_i`; adding them rotates every material line
by the *linearised* rotation :math:`\delta\theta\times r`, which lengthens it by the factor
:math:`\sqrt{1 + |\delta\theta|^2}`.  In a bending bellows whole cross-sections turn by 0.05–0.2 rad per load
step, so the linear update stretches every ring by 0.1–2 % — in a nearly incompressible wall (κ/μ = 50) a large
spurious stress, which the next Newton iteration has to undo (measured on the default design: the residual of
the first iterate of a bending load step was ×100–400 its start, and a bend took 40–50 iterations).

The correction.  The free nodes are grouped into *rings*: the nodes of one lattice row along the axis (all
through the wall and around, ``BellowsMesh.lattice[0]``).  For ring :math:`k` with current positions
:math:`x_i`, centroid :math:`\bar x`, :math:`r_i = x_i - \bar x`, and increments with mean :math:`\bar u`,
:math:`v_i = \delta u_i - \bar u`, the best-fit rigid rotation increment solves the 3×3 least-squares system

.. math::  \Big(\sum_i |r_i|^2 I - r_i r_i^T\Big)\,\delta\theta_k = \sum_i r_i \times v_i,

and each node's increment becomes :math:`\delta u_i + (R(\delta\theta_k) - I - [\delta\theta_k]_\times)\,r_i`
with :math:`R = \exp([\delta\theta]_\times)`: the ring turns by the finite rotation, the rest of the increment
(its deformation) is added as before.  The correction is :math:`\tfrac12[\delta\theta]_\times^2 r + O(|\delta
\theta|^3)`, second order in the step, so Newton's quadratic convergence and the converged equilibrium are
unchanged — only the path of the iterates is (tests: a rigid ring rotation is carried exactly, the correction
scales with the square of the step).  The same idea as the rotation update of the distal cap
(``expm_so3`` in ``BellowsModel._apply``) and as the director update of shell elements.

Measured (``docs/fem.md`` §8): four cold bends of the default design took 106 factorisations against 163
(T = 2/0/0 N: 23 against 53), and the 25 cases of the quick report's sweep 244 s of worker time against 320 s.
A rigid fit per through-the-wall line instead of per ring was worse than none (the wall's own bending is
not a rigid rotation of those short lines).
"""

from __future__ import annotations

import numpy as np

from .errors import InputError

from .loads.caps import expm_so3

__all__ = ["ring_rotation_correction", "MIN_ANGLE"]

#: rings turning by less than this [rad] in a step get no correction: the tail of a Newton solve stays plain
#: Newton (the correction's own second-order term, ½|δθ|² r, would set the constant of its quadratic convergence:
#: measured 69/m against 8.5/m, i.e. 1/r of the rings)
MIN_ANGLE = 1e-3


def ring_rotation_correction(x: np.ndarray, du: np.ndarray, rings: np.ndarray,
                             min_angle: float = MIN_ANGLE) -> np.ndarray:
    """The second-order correction of the increments ``du`` (3, n) of nodes at positions ``x`` (3, n) [m],
    grouped by ``rings`` (n,) — ring index 0 … n_r − 1 of each node, every ring with ≥ 3 nodes not on one line
    — that turns each ring by its best-fit finite rotation (module docstring) → (3, n) [m], to add to ``du``;
    zero on rings turning by less than ``min_angle`` [rad].  InputError on mismatched shapes or ring indices."""
    x, du, rings = np.asarray(x, float), np.asarray(du, float), np.asarray(rings)
    if x.ndim != 2 or x.shape[0] != 3 or du.shape != x.shape or rings.shape != x.shape[1:] or rings.size == 0 \
            or rings.dtype.kind not in "iu" or rings.min() < 0:
        raise InputError(f"ring_rotation_correction: x and du must be (3, n) and rings (n,) non-negative integers, "
                         f"got {x.shape}, {du.shape}, {rings.shape} {rings.dtype}")
    n_r = int(rings.max()) + 1
    cnt = np.bincount(rings, minlength=n_r)

    def ring_sum(w):
        return np.bincount(rings, weights=w, minlength=n_r)

    xb = np.stack([ring_sum(x[i]) for i in range(3)]) / cnt
    ub = np.stack([ring_sum(du[i]) for i in range(3)]) / cnt
    r = x - xb[:, rings]
    v = du - ub[:, rings]
    r2 = (r * r).sum(axis=0)
    A = np.empty((n_r, 3, 3))
    for i in range(3):
        for j in range(i, 3):
            A[:, i, j] = A[:, j, i] = ring_sum(r2 * (i == j) - r[i] * r[j])
    b = np.stack([ring_sum(w) for w in np.cross(r, v, axis=0)], axis=1)          # (n_r, 3)
    th = np.linalg.solve(A, b[:, :, None])[:, :, 0]                                # (n_r, 3)
    th[np.linalg.norm(th, axis=1) < min_angle] = 0.0
    R = np.array([expm_so3(t) for t in th])                                        # (n_r, 3, 3)
    tn = th[rings].T                                                               # (3, n)
    return np.einsum("nij,jn->in", R[rings], r) - r - np.cross(tn, r, axis=0)
