r"""The cap's compliance: the locked tip compliance from the tension-held 6×6 cap compliance, and the
rotation-free lateral compliance (the shear term) that a locked tendon cannot hold.

With every taut tendon locked, a small tip load is carried by the tendons' length constraints as well as by
the body; the locked/constant(tension-held) stiffness ratio measures how much.  This module is the theory
(pure functions of compliance matrices, any model); :mod:`validation.checks.locked_gap` measures the gap
between the FEM and the reduced model with it (docs/identification.md, "The locked-compliance gap"), and
identification takes its first shear estimate from :func:`shear_compliance`.

**What a locked tendon constrains (first order, straight tube).**  The FEM tendon is a polyline through guide
points at the roots (:mod:`fem_reference.loads.tendons`); the rod's is the line at distance d from the
centreline (:mod:`ancf.forces.tendon`).  About a straight state every segment of either path is parallel to
the axis, so the first variation of the length telescopes to the axial displacement of the anchor:

.. math::

    \delta L_i = e\cdot(\delta x_{anchor,i} - \delta x_{exit,i}) = e\cdot(\delta u_c + \delta\theta\times r_i),

``e`` the unit chord from the base exit to the anchor, ``r_i = R a_i`` the anchor's offset on the cap.  The
guides (their radial position, the chord between them, the wall deformation at the roots) do not enter:
the constraint row is a function of the six cap unknowns alone, in both models.  Then the locked tip
compliance is a function of the tension-held 6×6 cap compliance ``C6`` (``[δu_c; δθ] = C6 [δF; δM]``)
alone (:func:`locked_from_cap`):

.. math::

    C_l = J C_6 J^T - J C_6 G\,(G^T C_6 G)^{-1} G^T C_6 J^T,
    \qquad J = [I, -[R a_{tip}]_\times],\quad G = [\,e;\ r_i\times e\,]_{i \in A}.

**Where the models differ: the rotation-free lateral compliance.**  An Euler–Bernoulli rod's lateral tip
compliances obey ``c_δF = (4/3) c_θF c_δM / c_θM`` (L³/3EI = (4/3)(L²/2EI)²/(L/EI)).  The remainder

.. math::

    s = c_{\delta F} - \tfrac43\, c_{\theta F}\, c_{\delta M} / c_{\theta M}

is lateral tip motion without cap rotation (:func:`shear_compliance`; for a Timoshenko cantilever it is
exactly L/(k G A)).  A locked tendon constrains the cap's rotation and axial motion only, so ``s`` passes
unlocked into ``C_l``; a rod that matches the FEM's tension-held ``c_δF`` with bending alone puts ``s`` into
its rotation, where the tendons lock it.  Hence, with ``r_EB`` the ratio of the bending part alone,

.. math::

    \frac{k_{locked}}{k_{held}} = \frac{1}{(1 - \sigma)/r_{EB} + \sigma},\qquad \sigma = s / c_{\delta F}.

Units: SI throughout (m, N, Pa, N m²); compliances [m/N], rotations per moment [1/(N m)].
"""

from __future__ import annotations

import numpy as np

from ancf.errors import InputError

__all__ = ["locked_from_cap", "shear_compliance", "lateral_shear", "fit_shear_law", "remove_shear", "ratio_with_shear",
           "point_jacobian"]

_EX = np.array([1.0, 0.0, 0.0])


def _skew(r) -> np.ndarray:
    x, y, z = r
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def point_jacobian(r) -> np.ndarray:
    """∂x/∂[u_c, θ] (3×6) of a cap point at spatial offset ``r`` [m] (δx = δu_c + δθ × r)."""
    return np.hstack([np.eye(3), -_skew(r)])


def locked_from_cap(C6, tip_offset, anchor_offsets, chords=None) -> np.ndarray:
    """Locked tip compliance (3×3) [m/N] from the tension-held 6×6 cap compliance and straight-line tendons.

    Parameters
    ----------
    C6 : (6, 6) ``[δu_c; δθ] = C6 [δF; δM]`` about the cap centre (may be non-symmetric: follower loads).
    tip_offset : (3,) spatial offset R a_tip of the tip point from the cap centre [m].
    anchor_offsets : (k, 3) spatial offsets R a_i of the anchors of the locked tendons [m] (k ≥ 0).
    chords : (k, 3) unit chord of each tendon (exit → anchor); default the axis e_x.

    The tendons' length rows are ``e·(δu_c + δθ × r_i)`` (the module docstring); with no tendon the result
    is the tension-held tip compliance."""
    C6 = np.asarray(C6, float)
    if C6.shape != (6, 6) or not np.all(np.isfinite(C6)):
        raise InputError(f"C6 must be a finite 6×6 matrix, got shape {C6.shape}")
    r = np.atleast_2d(np.asarray(anchor_offsets, float)).reshape(-1, 3)
    e = np.tile(_EX, (len(r), 1)) if chords is None else np.atleast_2d(np.asarray(chords, float)).reshape(-1, 3)
    if len(e) != len(r):
        raise InputError(f"{len(r)} anchors but {len(e)} chords")
    J = point_jacobian(np.asarray(tip_offset, float))
    C = J @ C6 @ J.T
    if len(r) == 0:
        return C
    G = np.column_stack([point_jacobian(ri).T @ ei for ri, ei in zip(r, e)])    # (6, k): δL = Gᵀ δ[u_c; θ]
    return C - (J @ C6 @ G) @ np.linalg.solve(G.T @ C6 @ G, G.T @ C6 @ J.T)


def shear_compliance(C6, lateral, axis=(1.0, 0.0, 0.0)) -> float:
    """Rotation-free lateral tip compliance s [m/N] of the cap along unit ``lateral`` (module docstring).

    ``c_δF = uᵀ C_uF u``, ``c_θF = wᵀ C_θF u``, ``c_δM = uᵀ C_uM w``, ``c_θM = wᵀ C_θM w`` with w = axis × u the
    rotation axis of a bend toward u.  0 for an Euler–Bernoulli cantilever, L/(kGA) for a Timoshenko one."""
    C6 = np.asarray(C6, float)
    u = np.asarray(lateral, float)
    u = u / np.linalg.norm(u)
    w = np.cross(np.asarray(axis, float), u)
    c_dF, c_tF = u @ C6[:3, :3] @ u, w @ C6[3:, :3] @ u
    c_dM, c_tM = u @ C6[:3, 3:] @ w, w @ C6[3:, 3:] @ w
    return float(c_dF - 4.0 / 3.0 * c_tF * c_dM / c_tM)


def lateral_shear(C6) -> float:
    """Rotation-free lateral compliance s [m/N] of a straight tube along e_x: the mean of
    :func:`shear_compliance` toward e_y and e_z (equal on an axisymmetric state)."""
    return 0.5 * (shear_compliance(C6, (0.0, 0.0, 1.0)) + shear_compliance(C6, (0.0, 1.0, 0.0)))


def fit_shear_law(pressures, s, *, degree: int = 1, p_ref: float = 100e3) -> np.ndarray:
    """Coefficients (degree + 1,) [m/N] of s(p) = Σ_k c_k p̂^k, p̂ = p / ``p_ref``, fitted to the measured
    rotation-free compliances ``s`` (n,) [m/N] at ``pressures`` (n,) [Pa] by non-negative least squares
    (every c_k ≥ 0, so s(p) ≥ 0 over p ≥ 0 — the bound of ``ActuatorParams.shear_compliance``).  Needs
    n ≥ degree + 1 finite values at distinct pressures ≥ 0."""
    from scipy.optimize import nnls
    p = np.asarray(pressures, float).ravel()
    s = np.asarray(s, float).ravel()
    if p.shape != s.shape or not (np.all(np.isfinite(p)) and np.all(np.isfinite(s))):
        raise InputError(f"fit_shear_law: pressures and s must be finite and of one length, got {p.size} and {s.size}")
    if int(degree) != degree or degree < 0 or not p_ref > 0:
        raise InputError(f"fit_shear_law: degree must be an integer ≥ 0 and p_ref > 0, got {degree!r}, {p_ref!r}")
    if np.any(p < 0) or np.unique(p).size < degree + 1:
        raise InputError(f"fit_shear_law: a law of degree {degree} needs {degree + 1} distinct pressures ≥ 0, "
                         f"got {sorted(set(p.tolist()))} Pa")
    A = np.vander(p / p_ref, int(degree) + 1, increasing=True)
    return nnls(A, s)[0]


def remove_shear(C6, s_by_direction: dict) -> np.ndarray:
    """C6 with the rotation-free compliance ``s`` [m/N] removed along each given unit lateral direction
    (``{direction tuple: s}``): what an Euler–Bernoulli body with the same rotations would have."""
    out = np.array(C6, float)
    for u, s in s_by_direction.items():
        u = np.asarray(u, float) / np.linalg.norm(u)
        out[:3, :3] -= s * np.outer(u, u)
    return out


def ratio_with_shear(r_eb: float, share: float) -> float:
    """Locked/held stiffness ratio of a body whose held lateral compliance has the rotation-free share
    ``share`` = s/c_δF ∈ [0, 1) and whose bending part alone has the ratio ``r_eb`` (module docstring)."""
    return 1.0 / ((1.0 - share) / r_eb + share)
