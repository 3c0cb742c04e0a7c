"""Generalized gravity force Q_g (paper eq. 1): a dead load of the line mass m' [kg/m].

Potential −m' ∫ g · r dx; density w = −m' g · r, ∂w/∂r = −m' g, no Hessian.  The lumped tip mass is a dead
load m_tip g at the tool point and is handled with the tip load (:mod:`ancf.forces.tip_load`).
"""

from numba import njit


@njit(cache=True)
def add_gravity(r, mg, scale, g):
    """Add the line-weight density (mg = m' g [N/m], (3,)) × scale into the r block (0:3) of g; return
    the energy contribution."""
    e = 0.0
    for i in range(3):
        g[i] -= scale * mg[i]
        e -= scale * mg[i] * r[i]
    return e
