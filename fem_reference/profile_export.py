r"""The built-in (sine) wall profile written as a profile table that reproduces its FEM to round-off.

**Why a plain point table cannot.**  A table's outline between its points is a C² cubic spline
(:mod:`fem_reference.profile`), and the mesh places the outer wall point of a lattice row along the *normal* of
the inner outline, so a node depends on the outline's slope.  The built-in profile is only C¹: its curvature
jumps from 0 to ``±2π²(r_1 − r_0)/p²`` where a collar meets the first and the last convolution.  A C² spline
cannot follow a curvature jump: next to it the spline's second derivative is O(1) off over O(h) of length, its
slope O(h) off, and the outer node slides along the outer outline by ``t · O(h)`` — first-order convergence
(13.8 µm at 0.1 mm spacing, halving with the spacing), while away from the two junctions the nodes converge at
O(h⁴) (``tests/test_fem/test_fem_profile.py``).

**What does.**  The table also carries the outlines' slopes ``dr/dz`` (the ``dr_dz`` column).  Its outlines are
then the cubic Hermite interpolants through points and slopes, which are exact at the points in value and slope
and take a curvature jump that falls on a point without error.  :func:`export_profile` lists, for every row ζ of
the chosen mesh levels (:func:`fem_reference.mesh.lattice_rows`), the exact inner and outer offset points
``map_points(ζ, ∓t/2)`` and their slope ``r_m'(ζ)`` (offset curves are parallel to the mid-curve): at such a row
the table's through-wall segment — the inner point, its normal, the outer point reached along it, and so the
mid-wall coordinate ζ — is the built-in one to round-off, so every node of those meshes is.  Rows spaced at most
``spacing`` apart fill the gaps, so that the table is also a close outline between the rows (the summary numbers
read off it, the checks sampled along it; the node error at a row not listed falls as O(h³), through the slope).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .errors import ConfigError
from .geometry import BellowsGeometry
from .mesh import MESH_LEVELS, MeshLevel, lattice_rows
from .profile import TableProfile

__all__ = ["DEFAULT_SPACING", "export_profile", "export_rows"]

#: default largest gap between exported rows [m]
DEFAULT_SPACING = 1e-4
_MERGE = 1e-9            # a filling row closer than this fraction of L to a mesh row is dropped


def export_rows(geo: BellowsGeometry, levels: Sequence[str | MeshLevel] = tuple(MESH_LEVELS),
                spacing: float = DEFAULT_SPACING) -> np.ndarray:
    """Rows ζ [m] (sorted, from 0 to L) to export: every fine-lattice row of the meshes of ``geo`` at ``levels``
    (names of :data:`~fem_reference.mesh.MESH_LEVELS` or :class:`MeshLevel`), and filling rows at most
    ``spacing`` [m] apart (0 < spacing ≤ L)."""
    if not (isinstance(spacing, (int, float)) and np.isfinite(spacing) and 0 < spacing <= geo.length):
        raise ConfigError(f"spacing must be a number in (0, L = {geo.length * 1e3:g} mm], got {spacing!r} m")
    rows = []
    for level in levels:
        if isinstance(level, str):
            if level not in MESH_LEVELS:
                raise ConfigError(f"unknown mesh level {level!r}; choose from {sorted(MESH_LEVELS)}")
            level = MESH_LEVELS[level]
        rows.append(lattice_rows(geo, level))
    mesh_rows = np.unique(np.concatenate(rows + [np.array([0.0, geo.length])]))
    fill = np.linspace(0.0, geo.length, int(np.ceil(geo.length / spacing)) + 1)
    k = np.clip(np.searchsorted(mesh_rows, fill), 1, mesh_rows.size - 1)
    near = np.minimum(np.abs(fill - mesh_rows[k - 1]), np.abs(fill - mesh_rows[k]))
    return np.union1d(mesh_rows, fill[near > _MERGE * geo.length])


def export_profile(geo: BellowsGeometry, levels: Sequence[str | MeshLevel] = tuple(MESH_LEVELS),
                   spacing: float = DEFAULT_SPACING, source: str = "") -> TableProfile:
    """The built-in profile of ``geo`` as a table with slopes, exact at :func:`export_rows` (module docstring)."""
    if geo.is_table:
        raise ConfigError("this design's profile is already a table (profile_file); only the built-in sine "
                          "profile is exported")
    return TableProfile.exact_at_rows(geo, export_rows(geo, levels, spacing), source)
