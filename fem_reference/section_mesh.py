r"""A wall profile read from a 2-D mesh of the meridian section (any file :mod:`meshio` reads: ``.msh``,
``.vtk``, ``.vtu``, ``.xdmf``, ``.obj``, …).

**Convention.**  The file holds the half-section of the wall in the plane of its points' first two coordinates,
**x = radius r, y = axial position z** (the axisymmetric convention of most FEM and CAD tools: the axis of
revolution is the y axis), base cap face on ``y = 0``; a third coordinate, if present, must be 0 everywhere.
A mesh file carries no unit, so the unit of its coordinates is stated by the reader (the design key
``profile_unit``: ``m``, ``cm`` or ``mm``).

**What is read.**  The section is given either by area cells (triangles and/or quads: the boundary is the set
of cell edges used by exactly one cell) or, when the file has no area cells, by line cells (the outline drawn
as a polyline).  The boundary must be **one closed loop**: one connected region (area cells joined through
shared edges), no hole, every boundary vertex on exactly two boundary edges, no two boundary edges crossing.
Its lowest points must lie on ``z = 0`` and its highest on one ``z = L``, each end face one straight run of
boundary edges on that line (from the inner to the outer outline).  Removing the two end faces leaves two
chains from ``z = 0`` to ``z = L``: the one that starts at the smaller radius is the inner outline, the other
the outer.  They go on as point tables to :class:`~fem_reference.profile.TableProfile` (same checks, same
spline as a CSV table).  Every refusal is a :class:`~ancf.errors.ConfigError` naming the file and the place.
"""

from __future__ import annotations

import contextlib
import io
import pathlib

import numpy as np

from .errors import ConfigError
from .profile import LENGTH_UNITS, TableProfile

__all__ = ["MESH_SUFFIXES", "read_profile_mesh"]

#: file suffixes read as a section mesh (through meshio)
MESH_SUFFIXES = (".msh", ".vtk", ".vtu", ".xdmf", ".xmf", ".obj", ".off", ".stl", ".ply", ".med", ".inp", ".mesh")
_AREA = {"triangle": 3, "quad": 4}
_LINE = "line"
_TOL = 1e-9              # relative to the section's extent: "on the line z = 0", "the same z", "in the plane"


def _fmt(p, f: float) -> str:
    """A point (r, z) [m] in the file's unit ``f`` (metres per unit) for messages."""
    unit = next(k for k, v in LENGTH_UNITS.items() if v == f)
    return f"(r = {p[0] / f:.6g} {unit}, z = {p[1] / f:.6g} {unit})"


def _read(path: pathlib.Path, src: str):
    import meshio

    if not path.is_file():
        raise ConfigError(f"cannot read profile mesh {src}: no such file")
    said = io.StringIO()
    try:
        with contextlib.redirect_stdout(said), contextlib.redirect_stderr(said):
            return meshio.read(path)
    except (Exception, SystemExit) as exc:  # noqa: BLE001  (meshio raises many kinds on a bad file, exits on some)
        why = " ".join(said.getvalue().split()) or f"{type(exc).__name__}: {exc}"
        raise ConfigError(f"cannot read profile mesh {src}: {why}") from None


def _planar_points(mesh, src: str) -> np.ndarray:
    pts = np.asarray(mesh.points, float)
    if pts.ndim != 2 or pts.shape[1] not in (2, 3) or not pts.size:
        raise ConfigError(f"{src}: not a 2-D section mesh (points of shape {pts.shape})")
    if not np.all(np.isfinite(pts)):
        raise ConfigError(f"{src}: the mesh has points that are not finite numbers")
    extent = float(np.ptp(pts[:, :2], axis=0).max()) or 1.0
    if pts.shape[1] == 3 and np.abs(pts[:, 2]).max() > _TOL * extent:
        raise ConfigError(f"{src}: not a 2-D section: the points leave the plane of the section (third coordinate "
                          f"up to {np.abs(pts[:, 2]).max():g}; the meridian section lies in x = radius, y = axial, "
                          "third coordinate 0)")
    return pts[:, :2]


def _cells(mesh, src: str) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """(area cell blocks, line cell blocks) as vertex index arrays; other 2-D/3-D kinds refused."""
    area, lines = [], []
    for block in mesh.cells:
        kind = block.type
        if kind in _AREA:
            area.append(np.asarray(block.data, np.int64))
        elif kind == _LINE:
            lines.append(np.asarray(block.data, np.int64))
        elif kind == "vertex":
            continue
        elif kind in ("tetra", "hexahedron", "wedge", "pyramid", "tetra10", "hexahedron20", "hexahedron27"):
            raise ConfigError(f"{src}: not a 2-D section mesh: it holds {kind} cells (a volume mesh); give the "
                              "meridian section as triangles or quads")
        else:
            raise ConfigError(f"{src}: cells of kind {kind!r} are not read; give the meridian section as linear "
                              "triangles or quads (or its outline as lines)")
    if not area and not lines:
        raise ConfigError(f"{src}: the mesh has no triangles, quads or lines: no section to read")
    return area, lines


def _boundary_edges(area: list[np.ndarray], n_points: int, src: str, pts, f) -> np.ndarray:
    """Edges (m, 2) used by exactly one area cell; one connected region required."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    edges, owner, n_cells = [], [], 0
    for cells in area:
        k = cells.shape[1]
        for j in range(k):
            edges.append(np.sort(np.stack([cells[:, j], cells[:, (j + 1) % k]], axis=1), axis=1))
            owner.append(n_cells + np.arange(cells.shape[0]))
        n_cells += cells.shape[0]
    edges, owner = np.concatenate(edges), np.concatenate(owner)
    key = edges[:, 0] * n_points + edges[:, 1]
    _, inv, count = np.unique(key, return_inverse=True, return_counts=True)
    if count.max() > 2:
        e = edges[np.flatnonzero(count[inv] > 2)[0]]
        raise ConfigError(f"{src}: more than one region: the edge from {_fmt(pts[e[0]], f)} to {_fmt(pts[e[1]], f)} "
                          f"belongs to {count.max()} cells (overlapping parts); give one region")
    inner = np.flatnonzero(count[inv] == 2)
    order = np.argsort(inv[inner], kind="stable")
    pairs = owner[inner[order]].reshape(-1, 2)
    adj = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n_cells, n_cells))
    n_regions, _ = connected_components(adj, directed=False)
    if n_regions > 1:
        raise ConfigError(f"{src}: more than one region: the cells form {n_regions} parts not joined by shared "
                          "edges; give the wall section as one region")
    return edges[count[inv] == 1]


def _loop(edges: np.ndarray, pts: np.ndarray, src: str, f: float, from_area: bool) -> np.ndarray:
    """The vertices of the one closed boundary loop, in order (first not repeated)."""
    edges = np.unique(np.sort(edges, axis=1), axis=0)
    edges = edges[edges[:, 0] != edges[:, 1]]
    nodes, deg = np.unique(edges, return_counts=True)
    if np.any(deg == 1):
        p = pts[nodes[np.flatnonzero(deg == 1)[0]]]
        raise ConfigError(f"{src}: the boundary does not close: it ends at {_fmt(p, f)}")
    if np.any(deg > 2):
        p = pts[nodes[np.flatnonzero(deg > 2)[0]]]
        raise ConfigError(f"{src}: the boundary touches itself at {_fmt(p, f)} ({deg.max()} boundary edges meet "
                          "there): a self-intersecting outline")
    nbr = {int(n): [] for n in nodes}
    for a, b in edges:
        nbr[int(a)].append(int(b))
        nbr[int(b)].append(int(a))
    start = int(nodes[0])
    loop, prev, cur = [start], None, start
    while True:
        a, b = nbr[cur]
        nxt = b if a == prev else a
        if nxt == start:
            break
        loop.append(nxt)
        prev, cur = cur, nxt
    if len(loop) != nodes.size:
        n_loops = _count_loops(nbr)
        what = "a hole" if from_area else "more than one loop"
        raise ConfigError(f"{src}: the section's boundary is {n_loops} closed loops, not one ({what}); the wall "
                          "section must be one region bounded by one loop")
    return np.array(loop)


def _count_loops(nbr: dict) -> int:
    seen, n = set(), 0
    for s in nbr:
        if s in seen:
            continue
        n += 1
        stack = [s]
        while stack:
            v = stack.pop()
            if v not in seen:
                seen.add(v)
                stack.extend(nbr[v])
    return n


def _check_crossings(P: np.ndarray, src: str, f: float) -> None:
    """Refuse two non-adjacent edges of the closed polygon ``P`` (n, 2) that cross or touch."""
    A, B = P, np.roll(P, -1, axis=0)
    n = len(P)
    tol = _TOL * float(np.ptp(P, axis=0).max())
    for i0 in range(0, n, 256):
        i = np.arange(i0, min(i0 + 256, n))[:, None]
        j = np.arange(n)[None, :]
        a, b, c, d = A[i], B[i], A[j], B[j]

        def cross(o, p, q):
            return (p[..., 0] - o[..., 0]) * (q[..., 1] - o[..., 1]) - (p[..., 1] - o[..., 1]) * (q[..., 0] - o[..., 0])

        d1, d2, d3, d4 = cross(c, d, a), cross(c, d, b), cross(a, b, c), cross(a, b, d)
        hit = (d1 * d2 < -tol ** 2) & (d3 * d4 < -tol ** 2)
        adjacent = (np.abs(i - j) <= 1) | (np.abs(i - j) == n - 1)
        hit &= ~adjacent & (j > i)
        if hit.any():
            ii, jj = np.argwhere(hit)[0]
            raise ConfigError(f"{src}: the outline crosses itself: the boundary edge at {_fmt(A[i0 + ii], f)} crosses "
                              f"the one at {_fmt(A[jj], f)} (a self-intersecting outline)")


def _face_run(loop_z: np.ndarray, on: np.ndarray, src: str, where: str, pts, loop, f) -> tuple[int, int]:
    """First and last loop position of the one contiguous run of vertices flagged ``on`` (cyclic)."""
    n = len(on)
    idx = np.flatnonzero(on)
    starts = [k for k in idx if not on[(k - 1) % n]]
    if len(starts) != 1 or idx.size < 2:
        if idx.size == 1:
            k = int(idx[0])
            nb = (pts[loop[(k - 1) % n]], pts[loop[(k + 1) % n]])
            raise ConfigError(f"{src}: the {where} is not one flat edge: only the point {_fmt(pts[loop[k]], f)} lies "
                              f"on it, its neighbours on the boundary are at {_fmt(nb[0], f)} and {_fmt(nb[1], f)} "
                              "(the inner and the outer outline must end at the same z)")
        raise ConfigError(f"{src}: the {where} is not one straight run of boundary edges ({len(starts)} separate "
                          "pieces lie on it)")
    s = int(starts[0])
    return s, (s + idx.size - 1) % n


def _split(loop: np.ndarray, pts: np.ndarray, src: str, f: float):
    """(inner (z, r), outer (z, r)) point lists [m] of the loop, end faces removed."""
    z = pts[loop, 1]
    L = float(z.max())
    tol = _TOL * max(L, float(np.ptp(pts[loop, 0])))
    if abs(z.min()) > tol:
        raise ConfigError(f"{src}: the base end face is at z = {z.min() / f:.6g}, not at z = 0 (put the base cap "
                          "face on y = 0; x = radius, y = axial)")
    base = _face_run(z, np.abs(z) <= tol, src, "base end face z = 0", pts, loop, f)
    top = _face_run(z, np.abs(z - L) <= tol, src, f"distal end face z = {L / f:.6g}", pts, loop, f)
    n = len(loop)

    def chain(a, b):                 # loop positions from a to b going forwards
        return [loop[(a + k) % n] for k in range(((b - a) % n) + 1)]

    c1 = chain(base[1], top[0])      # leaves the base run at its last vertex
    c2 = chain(top[1], base[0])[::-1]
    for c in (c1, c2):
        pts[c[0], 1], pts[c[-1], 1] = 0.0, L       # on the faces within _TOL: exactly
    (ci, co) = (c1, c2) if pts[c1[0], 0] < pts[c2[0], 0] else (c2, c1)
    return (pts[ci, 1], pts[ci, 0]), (pts[co, 1], pts[co, 0])


def read_profile_mesh(path, length_unit: str) -> TableProfile:
    """Read the wall profile from a 2-D mesh of the meridian section (module docstring).

    Parameters
    ----------
    path : path of a file meshio reads (:data:`MESH_SUFFIXES`)
    length_unit : {"m", "cm", "mm"}
        Unit of the file's coordinates (a mesh file states none).

    Returns
    -------
    TableProfile with ``source = str(path)``; ConfigError on every refusal (module docstring).
    """
    path = pathlib.Path(path)
    src = str(path)
    if length_unit not in LENGTH_UNITS:
        raise ConfigError(f"{src}: the length unit of a profile mesh must be one of {', '.join(LENGTH_UNITS)} "
                          f"(design key profile_unit), got {length_unit!r}")
    f = LENGTH_UNITS[length_unit]
    mesh = _read(path, src)
    pts = _planar_points(mesh, src) * f
    area, lines = _cells(mesh, src)
    if area:
        edges = _boundary_edges(area, len(pts), src, pts, f)
    else:
        edges = np.concatenate([c[:, :2] for c in lines])
    loop = _loop(edges, pts, src, f, bool(area))
    _check_crossings(pts[loop], src, f)
    (zi, ri), (zo, ro) = _split(loop, pts.copy(), src, f)
    return TableProfile(tuple(zi), tuple(ri), tuple(zo), tuple(ro), src, source_unit=length_unit)
