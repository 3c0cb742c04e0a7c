r"""Structured 27-node hexahedral mesh of the bellows wall (exactly curved, revolved profile).

The wall is the image of the box lattice :math:`(\zeta, \tau, \theta)` under
:meth:`BellowsGeometry.map_points`.  ``n_s`` elements along the axis (``n_collar`` per end collar,
``n_per_conv`` per convolution), ``n_t`` through the thickness and ``n_theta`` around.  Every node of the
``MeshHex2`` (vertices, edge mid-nodes, face centres, cell centres) sits on the *fine lattice*
``(2 n_s + 1) × (2 n_t + 1) × 2 n_theta`` (θ periodic) and is placed at the exact mapped point, so
the geometry is curved to the accuracy of the quadratic iso-parametric map (the volume converges at
:math:`O(h^4)`, tested).  ``BellowsMesh.lattice`` keeps the fine-lattice index of every node, which is
how the inner surface, the cap faces and the tendon guide rings are selected (geometric lambdas on
facet "midpoints" are fragile on curved surfaces, see ``docs/fem.md`` §2).

Construction: ``MeshHex1`` from the coarse lattice → ``MeshHex2.from_mesh`` (straight mid-nodes) →
each local DOF ``j`` of the Hex2 element is the average of a fixed subset of the element's 8 vertices
(found once, numerically, on a single reference element), hence its fine-lattice index is the
average of the vertices' (θ-unwrapped) lattice indices → overwrite ``doflocs`` with the mapped point.
This makes the builder independent of skfem's vertex/edge ordering conventions.

Signed-Jacobian check: skfem's reference hexahedron is the point reflection of the vertex order in
its docstring, so valid skfem meshes have ``detDF < 0`` everywhere; only a *single* sign matters
(``Basis.dx`` uses ``|detDF|``).  :func:`check_jacobians` evaluates ``detDF`` at the 27 Gauss points
and raises :class:`ancf.errors.ConfigError` on mixed signs or a vanishing Jacobian.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from .errors import ConfigError, InputError

from .geometry import BellowsGeometry
from .profile import check_resolution

__all__ = ["MAX_ELEMENTS", "MESH_LEVELS", "BellowsMesh", "MeshLevel", "build_mesh", "check_jacobians"]

#: Bounds of the element counts of a :class:`MeshLevel` (inclusive) and of the whole mesh.  The largest
#: mesh, MAX_ELEMENTS Hex2 elements (≈ 36 DOFs each: ≈ 1.4 M DOFs), is about the most a 24 GiB machine can
#: factorise (the 5 376-element mesh, 194 k DOFs, needs ≈ 2 GiB); counts beyond these are typing mistakes.
LEVEL_BOUNDS = {"n_per_conv": (1, 64), "n_thick": (1, 16), "n_theta": (3, 256), "n_collar": (0, 32)}
MAX_ELEMENTS = 40_000


@dataclass(frozen=True)
class MeshLevel:
    """Element counts of the structured mesh.

    ``n_per_conv`` elements along each convolution, ``n_collar`` along each end collar (0 allowed
    only when ``collar_length == 0``), ``n_thick`` through the wall, ``n_theta`` around (a multiple of
    3 keeps the default tendon angles on nodes; the guides interpolate otherwise).
    """

    n_per_conv: int
    n_thick: int
    n_theta: int
    n_collar: int = 1

    def __post_init__(self):
        for k, (lo, hi) in LEVEL_BOUNDS.items():
            v = getattr(self, k)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or not lo <= v <= hi:
                raise ConfigError(f"MeshLevel.{k} must be an integer in {lo} … {hi}, got {v!r}")


MESH_LEVELS: dict[str, MeshLevel] = {
    "coarse": MeshLevel(n_per_conv=4, n_thick=2, n_theta=12, n_collar=1),
    "medium": MeshLevel(n_per_conv=6, n_thick=2, n_theta=18, n_collar=1),
    "reference": MeshLevel(n_per_conv=8, n_thick=2, n_theta=24, n_collar=2),
}


@lru_cache(maxsize=1)
def _local_vertex_subsets() -> tuple[tuple[int, ...], ...]:
    """For each of the 27 local DOFs of ElementHex2: the local vertices it is the average of."""
    from skfem import MeshHex1, MeshHex2

    rng = np.random.default_rng(0)
    m1 = MeshHex1.init_tensor(np.array([0.0, 1.0]), np.array([0.0, 1.0]), np.array([0.0, 1.0]))
    p = m1.p + 0.05 * rng.standard_normal(m1.p.shape) * 0  # exact unit cube is enough
    # use irrational-ish weights to identify subsets uniquely: vertex k gets coordinate code 4**k
    codes = np.array([[4.0 ** k for k in range(8)]])
    verts = m1.t[:, 0]
    q = np.zeros((1, m1.p.shape[1]))
    q[0, verts] = codes[0]
    m1c = MeshHex1(np.vstack([q, q, q]), m1.t)
    m2 = MeshHex2.from_mesh(m1c)
    from skfem import ElementHex2
    from skfem.assembly import Dofs

    ed = Dofs(m2, ElementHex2()).element_dofs[:, 0]
    out = []
    for j in range(27):
        val = m2.doflocs[0, ed[j]]
        for size in (1, 2, 4, 8):
            code = int(round(val * size))
            members = tuple(k for k in range(8) if code & (1 << (2 * k)))
            if len(members) == size and abs(sum(4.0 ** k for k in members) / size - val) < 1e-9:
                out.append(members)
                break
        else:  # pragma: no cover - would mean skfem changed its Hex2 DOF definition
            raise RuntimeError(f"cannot identify the vertex subset of Hex2 local DOF {j}")
    del p
    return tuple(out)


@dataclass
class BellowsMesh:
    """A ``skfem.MeshHex2`` of the wall plus its structured lattice bookkeeping.

    Attributes
    ----------
    mesh : skfem.MeshHex2
        Reference configuration [m]; ``mesh.doflocs`` has shape ``(3, n_nodes)``.
    lattice : ndarray (3, n_nodes) of int
        Fine-lattice index ``(i_s, i_t, i_theta)`` of every node, ``0 <= i_s <= 2 n_s``,
        ``0 <= i_t <= 2 n_t`` (0 = inner surface), ``0 <= i_theta < 2 n_theta``.
    shape : (int, int, int)
        ``(n_s, n_t, n_theta)`` element counts.
    zeta : ndarray (2 n_s + 1,)
        Axial lattice coordinate of the fine-lattice rows [m].
    geometry : BellowsGeometry or None
    """

    mesh: object
    lattice: np.ndarray
    shape: tuple[int, int, int]
    zeta: np.ndarray
    geometry: BellowsGeometry | None = None

    @property
    def n_nodes(self) -> int:
        return self.mesh.doflocs.shape[1]

    @property
    def n_elements(self) -> int:
        return self.mesh.t.shape[1]

    @property
    def X(self) -> np.ndarray:
        """Reference node positions, shape ``(3, n_nodes)`` [m]."""
        return self.mesh.doflocs

    def nodes_where(self, i_s=None, i_t=None, i_theta=None) -> np.ndarray:
        """Node ids whose fine-lattice index matches the given values (None = any)."""
        mask = np.ones(self.n_nodes, bool)
        for k, v in enumerate((i_s, i_t, i_theta)):
            if v is not None:
                mask &= self.lattice[k] == v
        return np.flatnonzero(mask)

    def inner_facets(self) -> np.ndarray:
        """Boundary facet ids of the inner (pressurised) surface ``τ = -t/2``."""
        m = self.mesh
        bf = m.boundary_facets()
        vert_it = self.lattice[1, : m.p.shape[1]]
        on = np.all(vert_it[m.facets[:, bf]] == 0, axis=0)
        return bf[on]

    def volume(self) -> float:
        """Volume of the meshed wall [m³] (27-point Gauss on the curved Hex2 geometry)."""
        from skfem import CellBasis, ElementHex2

        b = CellBasis(self.mesh, ElementHex2(), intorder=4)
        return float(b.dx.sum())

    # ------------------------------------------------------------------ I/O
    def save(self, path: str | Path, point_data: dict | None = None) -> Path:
        """Write the mesh (hex27) with its lattice indices as point data, via meshio."""
        import meshio
        from skfem.io.meshio import to_meshio

        pdata = {"lattice": self.lattice.T.astype(np.int64)}
        if point_data:
            pdata.update(point_data)
        mm = to_meshio(self.mesh, point_data=pdata)
        mm.field_data = {}
        path = Path(path)
        meshio.write(path, mm)
        return path

    @classmethod
    def load(cls, path: str | Path, geometry: BellowsGeometry | None = None) -> BellowsMesh:
        """Read a mesh written by :meth:`save` (the lattice indices are restored from point data)."""
        import meshio
        from skfem.io.meshio import from_meshio

        mm = meshio.read(Path(path))
        if "lattice" not in mm.point_data:
            raise InputError(f"{path}: no 'lattice' point data; not written by BellowsMesh.save")
        import contextlib
        import io

        with contextlib.redirect_stdout(io.StringIO()):  # skfem prints a tag warning for hex27
            m = from_meshio(mm)
        lat_pts = np.asarray(mm.point_data["lattice"]).T
        # from_meshio may renumber nodes: match by coordinates
        order = _match_points(np.asarray(mm.points).T, m.doflocs)
        lattice = lat_pts[:, order]
        n_s = int(lattice[0].max()) // 2
        n_t = int(lattice[1].max()) // 2
        n_th = (int(lattice[2].max()) + 1) // 2
        zeta = np.zeros(2 * n_s + 1)
        # rows of constant i_s on the mid-surface ray θ = 0 give ζ only approximately if t > 0;
        # recover ζ from the mid-wall node at θ = 0 of each row when possible
        for i in range(2 * n_s + 1):
            ids = np.flatnonzero((lattice[0] == i) & (lattice[1] == n_t) & (lattice[2] == 0))
            zeta[i] = m.doflocs[0, ids[0]] if ids.size else np.nan
        check_jacobians(m)
        return cls(m, lattice.astype(np.int64), (n_s, n_t, n_th), zeta, geometry)


def _match_points(src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    """Index ``k`` with ``src[:, k[j]] == dst[:, j]`` (to 1e-9 relative)."""
    from scipy.spatial import cKDTree

    scale = max(np.abs(src).max(), 1e-300)
    d, k = cKDTree(src.T).query(dst.T)
    if np.any(d > 1e-9 * scale):
        raise InputError("mesh file points do not match the cell nodes")
    return k


def check_jacobians(mesh) -> tuple[float, float]:
    """Return (min, max) of ``detDF`` at the 27 Gauss points; raise ConfigError on mixed signs.

    A valid mesh has one sign everywhere (skfem's own meshes are all negative, see module doc).
    """
    from skfem.quadrature import get_quadrature

    X, _ = get_quadrature(mesh.elem.refdom, 4)
    det = mesh._mapping().detDF(X) if hasattr(mesh, "_mapping") else mesh.mapping().detDF(X)
    lo, hi = float(det.min()), float(det.max())
    npos = int(np.count_nonzero(np.any(det > 0, axis=1)))
    nneg = int(np.count_nonzero(np.any(det < 0, axis=1)))
    nel = det.shape[0]
    if lo * hi <= 0 or (npos and nneg):
        raise ConfigError(
            f"mesh has inverted or degenerate elements: detDF in [{lo:.3e}, {hi:.3e}], "
            f"{npos} of {nel} elements have positive and {nneg} negative Jacobians at Gauss points")
    return lo, hi


def lattice_rows(geo: BellowsGeometry, level: MeshLevel) -> np.ndarray:
    """Fine-lattice axial coordinates ζ [m] of the mesh of ``geo`` at ``level``: shape ``(2 n_s + 1,)``
    (vertices and mid-nodes; the rows every node of :func:`build_mesh` sits on)."""
    nc = level.n_collar if geo.collar_length > 0 else 0
    segs = []
    c = geo.collar_length
    if nc:
        segs.append(np.linspace(0.0, c, 2 * nc + 1))
    for k in range(geo.n_convolutions):
        a = c + k * geo.pitch
        segs.append(np.linspace(a, a + geo.pitch, 2 * level.n_per_conv + 1))
    if nc:
        segs.append(np.linspace(geo.length - c, geo.length, 2 * nc + 1))
    return np.concatenate([segs[0]] + [s[1:] for s in segs[1:]])


def build_mesh(geo: BellowsGeometry, level: str | MeshLevel = "coarse") -> BellowsMesh:
    """Build the structured ``MeshHex2`` of the bellows wall.

    Parameters
    ----------
    geo : BellowsGeometry
    level : {"coarse", "medium", "reference"} or MeshLevel

    Returns
    -------
    BellowsMesh
    """
    from skfem import ElementHex2, MeshHex1, MeshHex2
    from skfem.assembly import Dofs

    if isinstance(level, str):
        if level not in MESH_LEVELS:
            raise ConfigError(f"unknown mesh level {level!r}; choose from {sorted(MESH_LEVELS)}")
        level = MESH_LEVELS[level]
    nc = level.n_collar if geo.collar_length > 0 else 0
    nconv, npc = geo.n_convolutions, level.n_per_conv
    n_s = 2 * nc + nconv * npc
    n_t, n_th = level.n_thick, level.n_theta
    if min(npc, n_t) < 1 or n_th < 3:
        raise ConfigError(f"invalid mesh level {level}")
    if n_s * n_t * n_th > MAX_ELEMENTS:
        raise ConfigError(f"mesh of {n_s} × {n_t} × {n_th} = {n_s * n_t * n_th} elements (this design at {level}) "
                          f"exceeds {MAX_ELEMENTS}: it would not fit in memory; choose a coarser level")

    zeta = lattice_rows(geo, level)
    assert zeta.size == 2 * n_s + 1
    if geo.is_table:
        check_resolution(geo.profile, zeta[::2], n_t)
    tau = np.linspace(-geo.wall_thickness / 2, geo.wall_thickness / 2, 2 * n_t + 1)
    nth2 = 2 * n_th
    theta = 2 * np.pi * np.arange(nth2) / nth2

    # coarse (vertex) lattice
    Zv, Tv, Hv = np.meshgrid(zeta[::2], tau[::2], theta[::2], indexing="ij")
    pv = geo.map_points(Zv, Tv, Hv).reshape(3, -1)
    vid = np.arange(pv.shape[1]).reshape(n_s + 1, n_t + 1, n_th)
    I, J, K = np.meshgrid(np.arange(n_s), np.arange(n_t), np.arange(n_th), indexing="ij")
    I, J, K = I.ravel(), J.ravel(), K.ravel()
    # vertex order of the MeshHex1 docstring: (0,0,0),(0,0,1),(0,1,0),(1,0,0),(0,1,1),(1,0,1),(1,1,0),(1,1,1)
    corners = [(0, 0, 0), (0, 0, 1), (0, 1, 0), (1, 0, 0), (0, 1, 1), (1, 0, 1), (1, 1, 0), (1, 1, 1)]
    t = np.array([vid[I + a, J + b, (K + cc) % n_th] for (a, b, cc) in corners])
    # unwrapped fine-lattice index of each element vertex, shape (3, 8, nel)
    vlat = np.array([[2 * (I + a), 2 * (J + b), 2 * (K + cc)] for (a, b, cc) in corners]).transpose(1, 0, 2)

    m1 = MeshHex1(pv, t)
    m2 = MeshHex2.from_mesh(m1)
    ed = Dofs(m2, ElementHex2()).element_dofs  # (27, nel)
    subsets = _local_vertex_subsets()
    n_nodes = m2.doflocs.shape[1]
    lattice = -np.ones((3, n_nodes), np.int64)
    for j, sub in enumerate(subsets):
        lat = vlat[:, list(sub), :].mean(axis=1)
        lat = np.rint(lat).astype(np.int64)
        lat[2] %= nth2
        lattice[:, ed[j]] = lat
    if np.any(lattice < 0):  # pragma: no cover
        raise RuntimeError("internal error: some Hex2 nodes were not placed on the lattice")
    doflocs = geo.map_points(zeta[lattice[0]], tau[lattice[1]], theta[lattice[2]])
    m2 = MeshHex2(doflocs, m2.t)
    if m2.doflocs.shape[1] != n_nodes:  # pragma: no cover
        raise RuntimeError("internal error: node count changed when rebuilding MeshHex2")
    check_jacobians(m2)
    return BellowsMesh(m2, lattice, (n_s, n_t, n_th), zeta, geo)
