r"""Gravity: dead weight of the wall (consistent nodal body load) and of the distal cap (point load).

Wall: :math:`f^g_{a} = \rho\,g \int N_a\,dX` in the reference configuration — a dead load, no tangent
(:func:`fem_reference.assembly.gravity_load`).  Distal cap: force ``m_cap g`` at its centre of mass
``X_c + R a_com``; as a cap point load it contributes the rigid-link geometric stiffness
``r ρᵀ − (ρ·r) I`` with ``r = R a_com``, ``ρ = −m g`` (see :mod:`.caps`).
"""

from __future__ import annotations

import numpy as np

from ..assembly import gravity_load

__all__ = ["cap_weight", "gravity_load"]


def cap_weight(mass: float, g, scale: float = 1.0) -> np.ndarray:
    """Weight of the cap [N] (``scale`` ramps it with the load parameter)."""
    return scale * float(mass) * np.asarray(g, float)
