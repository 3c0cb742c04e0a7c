r"""Self-contact margin of the convolutions and the tendons' routing radius, read off a deformed wall.

The FEM has no contact: two wall surfaces may pass through each other without resistance.  This module
measures how far a solved state is from that, so that a result can be judged (``docs/fem.md``,
"Self-contact and routing radius over the operating range, measured").  Everything here is a pure function
of the deformed node positions ``x = X + U`` (shape ``(3, n_nodes)`` [m]) on the lattice of a
:class:`~fem_reference.mesh.BellowsMesh`; nothing is solved.

**Grooves.**  The wall's outer surface folds into a groove at every interior root ``ζ_k = c + k p``
(``surface="outer"``: the flanks of two adjacent convolutions face each other), its inner surface into a
groove at every crest ``c + (k + ½) p`` (``surface="inner"``: the two flanks of one convolution).  A groove
is centred on its fine-lattice row ``r``; its flank A is the surface layer's rows ``r, r − 1, …, r − h``
and flank B the rows ``r, r + 1, …, r + h`` (``h`` fine rows from a root to a crest, ``2h`` per
convolution), each a polyline per lattice angle θ_j.

**Local frame.**  ``c`` = centroid of the mid-wall ring of row ``r``, ``t`` = unit normal of that ring
(its least-squares plane), oriented from flank A to flank B.  A surface point ``x`` has the axial and radial
coordinates :math:`a = (x - c)\cdot t` and :math:`\rho = |(x - c) - a\,t|`.

**Gap.**  For a node of flank A at level ``i = 1 … h − 1`` (the groove's bottom row ``i = 0`` belongs to both
flanks, the crest ``i = h`` faces the neighbouring groove's flank a whole pitch away) the facing point of
flank B on the same meridian is where B's polyline reaches the node's radius, :math:`\rho_B(s) = \rho_A`
(linear between B's nodes; where B reaches that radius more than once the smallest gap is taken); the gap
is :math:`g = a_B(s) - a_A`, and the same from B's nodes to A's polyline.  Per level and angle the smaller
of the two is kept; NaN where the facing flank does not reach the node's radius.  ``g > 0`` is an open
groove, ``g ≤ 0`` contact (or the surfaces passed through each other).  Properties: ``g`` is invariant
under rigid motions (the frame moves with the wall); on the unloaded sine wall nodes of A and B at level
``i`` are mirror images, so ``g`` is twice the axial distance of the node from the groove's row; a uniform
bend of radius ``R`` (every ring in the normal plane of an arc) gives
:math:`g = 2 (R - \rho_0\cos\theta)\sin(\Delta/R)` for mirror nodes at axial offset ``Δ`` and radius
``ρ₀`` (both tested).

**Routing radius.**  A guide is ``x_g = c + d n`` with ``c`` its root ring's centroid
(:mod:`fem_reference.loads.tendons`), so its distance from the centroid is ``d`` by construction; what
changes is its distance from the local centreline *line*, :math:`|P_t(x_g - c)| = d\sqrt{1 - (n\cdot t)^2}`,
``t`` the centreline's tangent at the root (central difference of the ring centroids of rows ``r ± 1``).
Between two guides the cable is straight; its distance from the centreline in the cross-section plane
half-way (the normal plane of the centreline at the crest row between the guides) is the moment arm there,
e.g. :math:`R - (R - d)\cos(\Delta\varphi/2)` for a tendon inside a uniform bend of radius ``R`` with the
guides ``Δφ`` apart.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import InputError

__all__ = ["FlankGaps", "TendonRadii", "cap_gaps", "flank_gaps", "groove_rows", "tendon_radii"]

#: tolerance on the interpolation parameter (a node of A at exactly the radius of a node of B)
_U_TOL = 1e-9


@dataclass(frozen=True)
class FlankGaps:
    """Gaps between the facing flanks of the grooves of one surface.

    gaps : ndarray (n_grooves, h − 1, 2 n_θ) [m] — per groove, level (fine rows from the groove's bottom, 1 … h − 1)
        and lattice angle; NaN where the facing flank does not reach that radius.
    rows : ndarray (n_grooves,) of int — fine-lattice row of each groove's bottom.
    surface : "outer" or "inner".
    """

    gaps: np.ndarray
    rows: np.ndarray
    surface: str

    @property
    def per_groove(self) -> np.ndarray:
        """Smallest gap of each groove [m], shape (n_grooves,) (NaN for a groove without a facing point)."""
        g = self.gaps.reshape(self.gaps.shape[0], -1)
        out = np.full(g.shape[0], np.nan)
        ok = ~np.all(np.isnan(g), axis=1)
        out[ok] = np.nanmin(g[ok], axis=1)
        return out

    @property
    def minimum(self) -> float:
        """Smallest gap over every groove, level and angle [m]."""
        return float(np.nanmin(self.per_groove))

    def argmin(self) -> tuple[int, int, int]:
        """(groove, level − 1, angle index) of :attr:`minimum`."""
        g = np.where(np.isnan(self.gaps), np.inf, self.gaps)
        return tuple(int(i) for i in np.unravel_index(int(np.argmin(g)), g.shape))


def _rows_per_half(bmesh) -> int:
    geo = bmesh.geometry
    roots = geo.root_positions()
    i = [int(np.argmin(np.abs(bmesh.zeta - z))) for z in roots[:2]]
    two_h = i[1] - i[0]
    if two_h % 2 or not np.allclose(bmesh.zeta[i], roots[:2], atol=1e-9 * geo.length):  # pragma: no cover
        raise InputError("the mesh rows do not fall on the roots")
    return two_h // 2


def groove_rows(bmesh, surface: str = "outer") -> tuple[np.ndarray, int]:
    """Fine-lattice rows of the grooves' bottoms of ``surface`` and ``h`` (fine rows from a root to a crest).

    ``"outer"``: the interior roots (n_convolutions − 1 grooves); ``"inner"``: the crests (n_convolutions)."""
    if surface not in ("outer", "inner"):
        raise InputError(f"surface must be 'outer' or 'inner', got {surface!r}")
    if bmesh.geometry is None:
        raise InputError("flank gaps need the mesh's geometry (BellowsMesh.geometry is None)")
    geo = bmesh.geometry
    h = _rows_per_half(bmesh)
    if h < 2:
        raise InputError("flank gaps need at least 2 elements per convolution along the profile")
    roots = geo.root_positions()
    centres = roots[1:-1] if surface == "outer" else roots[:-1] + geo.pitch / 2
    rows = np.array([int(np.argmin(np.abs(bmesh.zeta - z))) for z in centres], dtype=np.int64)
    return rows, h


def _layer_grid(bmesh, i_t: int) -> np.ndarray:
    """Node ids of lattice layer ``i_t`` as a grid (2 n_s + 1, 2 n_θ) (row, angle)."""
    n_s, _, n_th = bmesh.shape
    grid = -np.ones((2 * n_s + 1, 2 * n_th), np.int64)
    sel = np.flatnonzero(bmesh.lattice[1] == i_t)
    grid[bmesh.lattice[0, sel], bmesh.lattice[2, sel]] = sel
    return grid


def _ring_frame(x: np.ndarray, mid: np.ndarray, r: int) -> tuple[np.ndarray, np.ndarray]:
    """Centroid (3,) and unit normal (3,) of mid-wall ring ``r``, the normal oriented from row r−1 to r+1."""
    ring = x[:, mid[r]]
    c = ring.mean(axis=1)
    t = np.linalg.svd(ring - c[:, None], full_matrices=False)[0][:, 2]
    along = x[:, mid[r + 1]].mean(axis=1) - x[:, mid[r - 1]].mean(axis=1)
    return c, (t if t @ along >= 0 else -t)


def _facing_gap(a_src, rho_src, a_dst, rho_dst, sign: float) -> np.ndarray:
    """Smallest ``sign·(a_dst(ρ_src) − a_src)`` over the segments of the destination polylines.

    a_src, rho_src (L, J): source nodes; a_dst, rho_dst (h + 1, J): destination polylines (bottom first)."""
    a0, a1 = a_dst[:-1, None], a_dst[1:, None]                  # (S, 1, J)
    r0, r1 = rho_dst[:-1, None], rho_dst[1:, None]
    dr = r1 - r0
    with np.errstate(divide="ignore", invalid="ignore"):
        u = (rho_src[None] - r0) / dr                           # (S, L, J)
    ok = (dr != 0) & (u >= -_U_TOL) & (u <= 1 + _U_TOL)
    g = sign * (a0 + u * (a1 - a0) - a_src[None])
    g = np.where(ok, g, np.inf).min(axis=0)
    return np.where(np.isinf(g), np.nan, g)


def flank_gaps(bmesh, x: np.ndarray, surface: str = "outer") -> FlankGaps:
    """Gaps between the facing flanks of every groove of ``surface`` in the configuration ``x`` (module doc).

    bmesh : BellowsMesh (its lattice and geometry); x : (3, n_nodes) deformed node positions [m]
    (``bmesh.X`` for the unloaded wall, ``bmesh.X + result.state.U`` for a solved one)."""
    x = np.asarray(x, float)
    if x.shape != (3, bmesh.n_nodes) or not np.all(np.isfinite(x)):
        raise InputError(f"x must be finite node positions of shape (3, {bmesh.n_nodes}) [m], got {x.shape}")
    rows, h = groove_rows(bmesh, surface)
    n_t = bmesh.shape[1]
    surf = _layer_grid(bmesh, 2 * n_t if surface == "outer" else 0)
    mid = _layer_grid(bmesh, n_t)
    out = np.empty((rows.size, h - 1, surf.shape[1]))
    for k, r in enumerate(rows):
        c, t = _ring_frame(x, mid, r)
        ab = []
        for side in (-1, 1):
            y = x[:, surf[r + side * np.arange(h + 1)]] - c[:, None, None]     # (3, h + 1, J)
            a = np.einsum("i,ilj->lj", t, y)
            ab.append((a, np.linalg.norm(y - t[:, None, None] * a, axis=0)))
        (aA, rA), (aB, rB) = ab
        gA = _facing_gap(aA[1:h], rA[1:h], aB, rB, 1.0)
        gB = _facing_gap(aB[1:h], rB[1:h], aA, rA, -1.0)
        out[k] = np.fmin(gA, gB)
    return FlankGaps(out, rows, surface)


def cap_gaps(bmesh, x: np.ndarray, cap_centre: np.ndarray, R: np.ndarray) -> np.ndarray:
    """Gap between each end cap's face and the flank of the convolution next to it [m], shape (2,): (base, distal).

    The smallest distance from the cap's face plane (base: ``x₀ = 0``, normal ``+x``; distal: through
    ``cap_centre`` (3,) [m] with normal ``−R[:, 0]``, ``R`` (3, 3) the cap's rotation) of the outer-surface nodes
    of levels 1 … h − 1 of the end convolution's flank facing it (the collar is bonded to the cap and left out);
    ≤ 0: the flank touches the cap's plane (the caps are discs wider than the crests)."""
    x = np.asarray(x, float)
    if x.shape != (3, bmesh.n_nodes) or not np.all(np.isfinite(x)):
        raise InputError(f"x must be finite node positions of shape (3, {bmesh.n_nodes}) [m], got {x.shape}")
    _rows, h = groove_rows(bmesh, "outer")
    geo = bmesh.geometry
    ends = [int(np.argmin(np.abs(bmesh.zeta - z))) for z in geo.root_positions()[[0, -1]]]
    surf = _layer_grid(bmesh, 2 * bmesh.shape[1])
    base = x[0, surf[ends[0] + np.arange(1, h)]]
    n = np.asarray(R, float)[:, 0]
    distal = np.einsum("i,ilj->lj", n, np.asarray(cap_centre, float)[:, None, None] - x[:, surf[ends[1] - np.arange(1, h)]])
    return np.array([base.min(), distal.min()])


@dataclass(frozen=True)
class TendonRadii:
    """Distances of the tendons from the local centreline [m].

    guides : (m, n_guides) — each guide point's distance from the centreline's tangent line at its root;
    spans : (m, n_guides − 1) — the straight cable's distance from the mid-wall ring centroid of the crest row
        half-way between two guides, in the normal plane of the centreline there (the cross-section's arm);
    spans_smooth : (m, n_guides − 1) — the same from the smooth centreline through the root rings (the cubic
        Hermite curve through the root centroids with their tangents, at its midpoint): the chord's arm alone,
        without the crest ring's own shift (ovalisation).
    """

    guides: np.ndarray
    spans: np.ndarray
    spans_smooth: np.ndarray


def _centreline(x: np.ndarray, mid: np.ndarray, r: int) -> tuple[np.ndarray, np.ndarray]:
    """Ring centroid of row ``r`` and the centreline's unit tangent there (central difference of rows r ± 1)."""
    c = x[:, mid[r]].mean(axis=1)
    t = x[:, mid[r + 1]].mean(axis=1) - x[:, mid[r - 1]].mean(axis=1)
    return c, t / np.linalg.norm(t)


def _arm(g0: np.ndarray, g1: np.ndarray, c: np.ndarray, t: np.ndarray) -> float:
    """Distance from ``c`` of the point of segment g0–g1 in the plane through ``c`` with normal ``t``."""
    s = ((c - g0) @ t) / ((g1 - g0) @ t)
    return float(np.linalg.norm(g0 + s * (g1 - g0) - c))


def _hermite_mid(f0, f1) -> tuple[np.ndarray, np.ndarray]:
    """Midpoint and unit tangent of the cubic Hermite curve between frames (c, t) ``f0`` and ``f1``."""
    (c0, t0), (c1, t1) = f0, f1
    L = np.linalg.norm(c1 - c0)
    d = 1.5 * (c1 - c0) - 0.25 * L * (t0 + t1)
    return 0.5 * (c0 + c1) + 0.125 * L * (t0 - t1), d / np.linalg.norm(d)


def tendon_radii(bmesh, x: np.ndarray, points: list) -> TendonRadii:
    """Routing radii of the tendons in the configuration ``x`` (module doc).

    bmesh : BellowsMesh; x : (3, n_nodes) [m]; points : per tendon its polyline ``(n + 1, 3)`` [m] (exit, one
    guide per interior root, anchor: :meth:`fem_reference.loads.tendons.TendonPath.points`)."""
    x = np.asarray(x, float)
    if x.shape != (3, bmesh.n_nodes):
        raise InputError(f"x must have shape (3, {bmesh.n_nodes}), got {x.shape}")
    rows, h = groove_rows(bmesh, "outer")
    mid = _layer_grid(bmesh, bmesh.shape[1])
    frames = [_centreline(x, mid, r) for r in rows]
    crests = [_centreline(x, mid, r + h) for r in rows[:-1]]
    smooth = [_hermite_mid(frames[k], frames[k + 1]) for k in range(rows.size - 1)]
    guides, spans, spans_s = [], [], []
    for P in points:
        P = np.asarray(P, float)
        if P.shape != (rows.size + 2, 3):
            raise InputError(f"a tendon polyline must have {rows.size + 2} points (exit, guides, anchor), "
                             f"got shape {P.shape}")
        g = P[1:-1]
        guides.append([np.linalg.norm((gk - c) - ((gk - c) @ t) * t) for gk, (c, t) in zip(g, frames)])
        spans.append([_arm(g[k], g[k + 1], *crests[k]) for k in range(rows.size - 1)])
        spans_s.append([_arm(g[k], g[k + 1], *smooth[k]) for k in range(rows.size - 1)])
    shape = (len(points), max(rows.size - 1, 0))
    return TendonRadii(np.array(guides), np.array(spans).reshape(shape), np.array(spans_s).reshape(shape))
