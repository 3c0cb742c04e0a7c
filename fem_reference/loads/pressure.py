r"""Cavity pressure: the distal-cap resultant (the wall part is :class:`fem_reference.assembly.PressureAssembler`).

The caps are not meshed.  The pressure on the distal cap's inner disc (radius ``r_i`` where the wall
meets the cap) is a follower force through the cap centre along the deformed cap axis:

.. math::  f = p\,A\,R e_x, \qquad A = \pi r_i^2, \qquad
           \frac{\partial f}{\partial\theta} = -p A\,[R e_x]_\times \quad(\delta(Re_x) = \delta\theta\times Re_x).

The residual gets ``-f`` on the cap translation, the Newton matrix ``+p A [R e_x]_×`` in its
``(u_c, θ)`` block.  The base-cap resultant goes to ground.  Wall + caps form a closed cavity: at
``u = 0`` the wall's net pressure force vanishes (tested) and the cap carries ``p A``.
"""

from __future__ import annotations

import numpy as np

from .caps import skew

__all__ = ["cap_pressure_force"]


def cap_pressure_force(p: float, area: float, R: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Follower cap force ``f = p A R e_x`` [N] and ``∂f/∂θ`` (3×3) [N/rad]."""
    f = p * area * R[:, 0]
    return f, -skew(f)
