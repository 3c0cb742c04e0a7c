r"""A bellows wall profile given as data: the inner and outer outline ``r(z)`` of the meridian section.

**Outlines.**  Each outline is a list of points ``(z_k, r_k)`` with ``z`` strictly increasing from the base
cap face ``z = 0`` to the distal cap face ``z = L`` (both outlines end at the same ``L``: the section closes
with the two end faces).  Between the points an outline is the interpolating cubic spline (C², error
O(h⁴) on a smooth outline sampled every h) with slope ``dr/dz = 0`` imposed at ``z = 0`` and ``z = L`` (the
wall meets each cap in a flat annulus, as the built-in profile does).  A spline rings next to a sharp
corner; give corners a fillet of a few points, as a moulded part has (the checks below refuse a ringing that
folds the wall).  A table may also give each point's slope ``dr/dz`` (the ``dr_dz`` column): the outline is then
the cubic Hermite curve through points and slopes — C¹ only, exact at every point, and exact across a curvature
jump placed on a point, which no C² spline is (:mod:`fem_reference.profile_export` exports the built-in profile
so, reproducing its mesh and FEM to round-off).  The outlines may also come from a 2-D mesh of the section
(:func:`read_profile`, :mod:`fem_reference.section_mesh`).

**Through the wall.**  The wall point of lattice row ``ζ`` at the through-wall fraction ``s ∈ [0, 1]`` is

.. math::

    P(\zeta, s) = (1 - s)\,P_i(u) + s\,P_o(u), \qquad
    P_o(u) = P_i(u) + h(u)\,n_i(u), \qquad \tfrac12\,(P_i + P_o)_z = \zeta,

with :math:`P_i(u) = (u, r_i(u))` the inner outline, :math:`n_i = (-r_i', 1)/\sqrt{1 + r_i'^2}` its outward
normal and :math:`h(u)` the distance along that normal to the outer outline (the local wall thickness).
For a wall of constant thickness ``t`` whose outlines are the normal offsets ``±t/2`` of a mid-curve (the
built-in sine profile), the inner and outer normals coincide and ``P(ζ, s)`` is exactly the built-in map
:meth:`BellowsGeometry.map_points` with ``τ = (s - ½) t``; a table sampled from it reproduces the built-in
mesh to the interpolation error of the table (``tests/test_fem/test_fem_profile.py``; ``docs/fem.md`` §3b).

**Rules** (each refused with a :class:`~ancf.errors.ConfigError` naming the source and the point): at least
:data:`MIN_POINTS` points per outline; finite numbers; ``r > 0``; ``z`` strictly increasing; both outlines
start at ``z = 0`` and end at the same ``z`` (closed section); the inner outline strictly inside the outer
one; the inner normals reach the outer outline and do not cross inside the wall: the mid-wall and the outer
ends of the through-wall segments (sampled at 4001 rows) may not fall behind earlier ones in ``z`` by more
than :data:`FOLD_TOLERANCE` (1 %) of the local thickness — beyond that the inner outline bends tighter than
the wall is thick and the meshed wall would fold over itself; a smaller overlap is the spline's ringing at a
curvature jump (the built-in ``paper`` design, whose outer line at a root turns back within 3 % of folding,
shows 5 µm of it on a 3.7 mm wall when sampled every 0.8 mm), and the mesh's Jacobian check at every Gauss
point (:func:`fem_reference.mesh.check_jacobians`) remains the final judge.  The mesh adds one rule, checked before any solve
(:func:`check_resolution`): no element may be more than :data:`MAX_ASPECT` times longer along the wall than
its share of the local thickness.
"""

from __future__ import annotations

import csv
import io
import math
import pathlib
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from .errors import ConfigError

from ._checks import validated

__all__ = ["MAX_ASPECT", "MIN_POINTS", "SLOPE_COLUMN", "TableProfile", "check_resolution", "read_profile",
           "read_profile_csv", "write_profile_csv"]

#: fewest points an outline may have
MIN_POINTS = 4
#: largest element length along the wall over its share of the wall thickness (``thickness / n_thick``)
MAX_ASPECT = 25.0
#: the length units a profile file may use (header suffixes) and their factor to metres
LENGTH_UNITS = {"m": 1.0, "cm": 1e-2, "mm": 1e-3}
#: largest end slope ``|dr/dz|`` a table with slopes may give on a cap face (they must be 0: flat annuli)
SLOPE_END_TOLERANCE = 1e-9
#: largest overlap of the through-wall segments, as a fraction of the local wall thickness (module docstring)
FOLD_TOLERANCE = 0.01
#: the optional fourth column of the two-list layout: the outline's slope dr/dz (a ratio: no unit)
SLOPE_COLUMN = "dr_dz"
_DENSE = 4001            # through-wall segments sampled to check the wall and to invert ζ(u)


def _where(src: str) -> str:
    return src or "profile table"


@dataclass(frozen=True, eq=True)
class TableProfile:
    """Inner and outer outline of the meridian section (module docstring), metres.

    Parameters
    ----------
    z_inner, r_inner : tuple of float, length ≥ MIN_POINTS
        Inner outline points [m], ``z`` strictly increasing from 0.
    z_outer, r_outer : tuple of float, length ≥ MIN_POINTS
        Outer outline points [m], ``z`` strictly increasing from 0 to the inner outline's last ``z``.
    source : str
        Where the table came from (a file path), named in every error message.
    dr_inner, dr_outer : tuple of float, empty or one per point
        Slopes ``dr/dz`` [-] of the outlines at their points (both or neither; 0 at ``z = 0`` and ``z = L``).
        Given, each outline is the cubic Hermite interpolant through the points *and* slopes (exact at the
        points, O(h⁴) between them on an outline that is smooth between its points); empty: the clamped
        cubic spline (module docstring).
    source_unit : str
        Length unit of a source file that states none (a section mesh, :mod:`fem_reference.section_mesh`):
        "m", "cm" or "mm"; empty for a CSV table (units in its header) or no file.
    """

    z_inner: tuple[float, ...]
    r_inner: tuple[float, ...]
    z_outer: tuple[float, ...]
    r_outer: tuple[float, ...]
    source: str = ""
    dr_inner: tuple[float, ...] = ()
    dr_outer: tuple[float, ...] = ()
    source_unit: str = ""

    def __post_init__(self):
        for k in ("z_inner", "r_inner", "z_outer", "r_outer", "dr_inner", "dr_outer"):
            try:
                object.__setattr__(self, k, tuple(float(v) for v in np.ravel(getattr(self, k))))
            except (TypeError, ValueError):
                raise ConfigError(f"{_where(self.source)}: {k} must be a list of numbers") from None
        validated(self, f"{_where(self.source)}")

    # ------------------------------------------------------------------ validation
    def _validate(self):
        src = _where(self.source)
        for name, z, r in (("inner", self.z_inner, self.r_inner), ("outer", self.z_outer, self.r_outer)):
            _check_outline(src, name, np.array(z), np.array(r))
        self._check_slopes(src)
        L_i, L_o = self.z_inner[-1], self.z_outer[-1]
        if abs(L_i - L_o) > 1e-9 * max(L_i, L_o):
            raise ConfigError(f"{src}: the section does not close: the inner outline ends at z = {L_i * 1e3:g} mm, "
                              f"the outer at z = {L_o * 1e3:g} mm (both must end on the distal cap face)")
        self._check_inside(src)
        self._check_wall(src)

    @property
    def has_slopes(self) -> bool:
        """True when the outlines carry their slopes (Hermite interpolation, class docstring)."""
        return bool(self.dr_inner or self.dr_outer)

    def _check_slopes(self, src: str) -> None:
        if not self.has_slopes:
            return
        for name, z, d in (("inner", self.z_inner, self.dr_inner), ("outer", self.z_outer, self.dr_outer)):
            if len(d) != len(z):
                raise ConfigError(f"{src}: the {name} outline has {len(z)} points but {len(d)} slopes dr/dz "
                                  "(give a slope at every point of both outlines, or none)")
            bad = [k for k in range(len(d)) if not math.isfinite(d[k])]
            if bad:
                raise ConfigError(f"{src}: {name} outline point {bad[0] + 1} has slope dr/dz = {d[bad[0]]!r}; "
                                  "slopes must be finite")
            for k, face in ((0, "base cap face z = 0"), (-1, "distal cap face z = L")):
                if abs(d[k]) > SLOPE_END_TOLERANCE:
                    raise ConfigError(f"{src}: the {name} outline has slope dr/dz = {d[k]:g} on the {face}; it must "
                                      "be 0 there (the wall meets each cap in a flat annulus)")

    def _check_inside(self, src: str) -> None:
        z = np.union1d(np.linspace(0.0, self.length, _DENSE), np.r_[self.z_inner, self.z_outer])
        z = z[z <= self.length]
        gap = self._outer(z) - self._inner(z)
        if np.any(gap <= 0):
            k = int(np.argmin(gap))
            raise ConfigError(f"{src}: the inner outline is not inside the outer one at z = {z[k] * 1e3:.6g} mm "
                              f"(r_inner {self._inner(z[k]) * 1e3:.6g} mm >= r_outer {self._outer(z[k]) * 1e3:.6g} mm)")

    def _check_wall(self, src: str) -> None:
        u = np.linspace(0.0, self.length, _DENSE)
        pi, po, ok = self._segments(u)
        if not np.all(ok):
            k = int(np.flatnonzero(~ok)[0])
            raise ConfigError(f"{src}: the normal of the inner outline at z = {u[k] * 1e3:.6g} mm does not reach the "
                              "outer outline inside 0 <= z <= L (wall too thick for its bend there)")
        mid = 0.5 * (pi[0] + po[0])
        h = np.hypot(po[0] - pi[0], po[1] - pi[1])
        for what, zz in (("mid-wall", mid), ("outer", po[0])):
            back = np.maximum.accumulate(zz) - zz               # how far a segment falls behind earlier ones
            bad = np.flatnonzero(back > FOLD_TOLERANCE * h)
            if bad.size:
                k = int(bad[0])
                raise ConfigError(
                    f"{src}: the wall folds over itself near z = {u[k] * 1e3:.6g} mm: the through-wall normals of the "
                    f"inner outline cross before the {what} line, by {back[k] * 1e3:.3g} mm of a {h[k] * 1e3:.3g} mm "
                    f"wall (more than {FOLD_TOLERANCE:.0%}; the outline bends tighter than the wall is thick: a "
                    "self-intersecting wall)")

    # ------------------------------------------------------------------ interpolants
    @cached_property
    def _inner(self):
        return _outline_interpolant(np.array(self.z_inner), np.array(self.r_inner), self.dr_inner)

    @cached_property
    def _outer(self):
        return _outline_interpolant(np.array(self.z_outer), np.array(self.r_outer), self.dr_outer)

    @property
    def length(self) -> float:
        """Axial length ``L`` of the section [m]."""
        return float(self.z_inner[-1])

    def _segments(self, u: np.ndarray):
        """Through-wall segments from the inner outline at ``z = u``: inner points, outer points (each
        shape ``(2,) + u.shape`` as (z, r)) and a mask of the segments that reached the outer outline."""
        u = np.asarray(u, float)
        L = self.length
        ri, di = self._inner(u), self._inner(u, 1)
        s = np.sqrt(1.0 + di * di)
        nz, nr = -di / s, 1.0 / s
        h = (self._outer(u) - ri) * nr
        for _ in range(40):                                 # Newton on r_o(u + h n_z) = r_i + h n_r
            zo = np.clip(u + h * nz, 0.0, L)
            f = self._outer(zo) - ri - h * nr
            df = self._outer(zo, 1) * nz - nr
            step = f / np.where(np.abs(df) > 1e-300, df, 1e-300)
            h = h - step
            if np.all(np.abs(step) <= 1e-14 * L):
                break
        zo = u + h * nz
        ok = (h > 0) & (zo >= -1e-12 * L) & (zo <= L * (1 + 1e-12)) \
            & (np.abs(self._outer(np.clip(zo, 0, L)) - ri - h * nr) <= 1e-11 * L)
        return np.array([u, ri]), np.array([zo, ri + h * nr]), ok

    @cached_property
    def _mid_table(self):
        u = np.linspace(0.0, self.length, _DENSE)
        pi, po, _ = self._segments(u)
        return 0.5 * (pi[0] + po[0]), u

    def wall_points(self, zeta) -> tuple[np.ndarray, np.ndarray]:
        """Inner and outer wall point ``(z, r)`` [m] of the lattice rows ``zeta`` (mid-wall axial coordinate,
        module docstring); each of shape ``(2,) + zeta.shape``."""
        zeta = np.asarray(zeta, float)
        mid, u_tab = self._mid_table
        u = np.interp(zeta, mid, u_tab)
        for _ in range(60):     # Newton on mid(u) = ζ, derivative by a one-sided secant: at a knot of a table with
            # slopes mid'(u) jumps (Hermite outlines are C¹), the secant is off and the convergence only linear
            pi, po, _ = self._segments(u)
            m = 0.5 * (pi[0] + po[0])
            du = 1e-7 * self.length
            pj, qj, _ = self._segments(np.clip(u + du, 0, self.length))
            dm = (0.5 * (pj[0] + qj[0]) - m) / np.where(u + du <= self.length, du, -du)
            step = (m - zeta) / np.where(np.abs(dm) > 1e-12, dm, 1.0)
            u = np.clip(u - step, 0.0, self.length)
            if np.all(np.abs(step) <= 1e-15 * self.length):
                break
        pi, po, _ = self._segments(u)
        return pi, po

    def thickness(self, zeta) -> np.ndarray:
        """Wall thickness along the inner normal at the lattice rows ``zeta`` [m]."""
        pi, po = self.wall_points(zeta)
        return np.hypot(po[0] - pi[0], po[1] - pi[1])

    # ------------------------------------------------------------------ summary numbers (BellowsGeometry fields)
    def summary(self) -> dict:
        """``length``, ``root_radius`` (smallest inner radius), ``crest_radius`` (largest outer radius) and
        ``wall_thickness`` (thinnest wall along the inner normal) [m]: the scalar fields of
        :class:`BellowsGeometry` that the table replaces."""
        return dict(self._summary)

    @cached_property
    def _summary(self) -> dict:
        u = np.linspace(0.0, self.length, _DENSE)
        return {"length": self.length,
                "root_radius": float(min(np.min(self._inner(u)), min(self.r_inner))),
                "crest_radius": float(max(np.max(self._outer(u)), max(self.r_outer))),
                "wall_thickness": float(self.thickness(u).min())}

    def describe(self) -> dict:
        """What names the table in a result's metadata (JSON types): its file, the file's unit if it states none,
        the number of points per outline, whether slopes are given, and the SHA-256 of the point data (the
        outlines in metres as float64 bytes, in the order inner z, r, outer z, r, then the slopes)."""
        import hashlib

        data = np.array(self.z_inner + self.r_inner + self.z_outer + self.r_outer + self.dr_inner + self.dr_outer)
        return {"profile_file": self.source, "profile_unit": self.source_unit, "points_inner": len(self.z_inner),
                "points_outer": len(self.z_outer), "slopes": self.has_slopes,
                "sha256": hashlib.sha256(data.astype("<f8").tobytes()).hexdigest()}

    @property
    def cap_inner_radius(self) -> float:
        """Inner radius where the wall meets the distal cap [m]."""
        return float(self.r_inner[-1])

    @classmethod
    def from_geometry(cls, geo, n_points: int, source: str = "") -> TableProfile:
        """The outlines of a built-in (sine) :class:`BellowsGeometry`, sampled at ``n_points`` rows ζ spread
        evenly over ``[0, L]``: each outline point is the exact offset point ``map_points(ζ, ∓t/2)``."""
        if isinstance(n_points, bool) or not isinstance(n_points, int) or n_points < MIN_POINTS:
            raise ConfigError(f"n_points must be an integer >= {MIN_POINTS}, got {n_points!r}")
        z = np.linspace(0.0, geo.length, n_points)
        xi = geo.map_points(z, -geo.wall_thickness / 2, 0.0)
        xo = geo.map_points(z, geo.wall_thickness / 2, 0.0)
        return cls(tuple(xi[0]), tuple(xi[2]), tuple(xo[0]), tuple(xo[2]), source)

    @classmethod
    def exact_at_rows(cls, geo, zeta, source: str = "") -> TableProfile:
        """The outlines of a built-in (sine) :class:`BellowsGeometry` at the lattice rows ``zeta`` [m] (shape
        ``(n,)``, from 0 to L), each point the exact offset point ``map_points(ζ, ∓t/2)`` *with its exact slope*
        (an offset curve is parallel to its mid-curve: ``dr/dz = r_m'(ζ)``).  At every row ``ζ`` listed, the
        table's through-wall segment is then the built-in one to round-off, so a mesh whose rows are all listed
        is the built-in mesh to round-off (``bellows fem profile --export``)."""
        if geo.is_table:
            raise ConfigError("exact_at_rows samples the built-in sine profile; this design is already a table")
        z = np.unique(np.asarray(zeta, float))
        if z.size < MIN_POINTS or z[0] != 0.0 or z[-1] != geo.length:
            raise ConfigError(f"exact_at_rows needs at least {MIN_POINTS} rows from 0 to L = {geo.length!r} m")
        xi = geo.map_points(z, -geo.wall_thickness / 2, 0.0)
        xo = geo.map_points(z, geo.wall_thickness / 2, 0.0)
        slope = tuple(geo.profile_mid(z)[1])
        return cls(tuple(xi[0]), tuple(xi[2]), tuple(xo[0]), tuple(xo[2]), source, slope, slope)


def _outline_interpolant(z: np.ndarray, r: np.ndarray, dr=()):
    """Cubic spline through the points with the end slopes clamped to 0 (flat annuli at the caps), or, with
    the slopes ``dr`` given, the cubic Hermite interpolant through points and slopes."""
    from scipy.interpolate import CubicHermiteSpline, CubicSpline

    if len(dr):
        return CubicHermiteSpline(z, r, np.asarray(dr, float), extrapolate=True)
    return CubicSpline(z, r, bc_type=((1, 0.0), (1, 0.0)), extrapolate=True)


def _check_outline(src: str, name: str, z: np.ndarray, r: np.ndarray) -> None:
    if z.size != r.size:
        raise ConfigError(f"{src}: the {name} outline has {z.size} z values but {r.size} radii")
    if z.size < MIN_POINTS:
        raise ConfigError(f"{src}: the {name} outline has {z.size} points; at least {MIN_POINTS} are needed")
    for k in range(z.size):
        if not (math.isfinite(z[k]) and math.isfinite(r[k])):
            raise ConfigError(f"{src}: {name} outline point {k + 1} is not finite: z = {z[k]!r}, r = {r[k]!r}")
        if r[k] <= 0:
            raise ConfigError(f"{src}: {name} outline point {k + 1} has radius {r[k] * 1e3:g} mm; radii must be > 0")
    if abs(z[0]) > 1e-12 * max(abs(z[-1]), 1e-300):
        raise ConfigError(f"{src}: the {name} outline starts at z = {z[0] * 1e3:g} mm; it must start on the base cap "
                          "face z = 0 (the section does not close)")
    bad = np.flatnonzero(np.diff(z) <= 0)
    if bad.size:
        k = int(bad[0])
        raise ConfigError(f"{src}: {name} outline point {k + 2} (z = {z[k + 1] * 1e3:g} mm) does not come after point "
                          f"{k + 1} (z = {z[k] * 1e3:g} mm): each outline must be strictly increasing in z")


def check_resolution(profile: TableProfile, zeta: np.ndarray, n_thick: int) -> None:
    """Refuse a mesh whose elements are more than :data:`MAX_ASPECT` times longer along the wall than their
    share ``thickness / n_thick`` of the local wall thickness. ``zeta``: the vertex rows (n_s + 1,) [m]."""
    pi, po = profile.wall_points(zeta)
    mid = 0.5 * (pi + po)
    seg = np.hypot(np.diff(mid[0]), np.diff(mid[1]))
    h = np.hypot(po[0] - pi[0], po[1] - pi[1])
    h_el = np.minimum(h[:-1], h[1:]) / n_thick
    aspect = seg / h_el
    k = int(np.argmax(aspect))
    if aspect[k] > MAX_ASPECT:
        raise ConfigError(
            f"{_where(profile.source)}: the wall is too thin for the mesh near z = {mid[0, k] * 1e3:.4g} mm: an element "
            f"{seg[k] * 1e3:.3g} mm long along the wall over {h_el[k] * 1e3:.3g} mm of thickness (aspect "
            f"{aspect[k]:.3g} > {MAX_ASPECT:g}); use more elements along the profile")


# ---------------------------------------------------------------------------------------------- files
def _column_unit(name: str, src: str, lineno: int) -> tuple[str, float]:
    base, _, unit = name.strip().rpartition("_")
    if base and unit in LENGTH_UNITS:
        return base, LENGTH_UNITS[unit]
    spell = ", ".join(f"{name.strip()}_{u}" for u in LENGTH_UNITS)
    raise ConfigError(f"{src}, line {lineno}: column '{name.strip()}' needs a length unit; write one of: {spell}")


def _rows(text: str, src: str) -> list[tuple[int, list[str]]]:
    out = []
    for lineno, row in enumerate(csv.reader(io.StringIO(text)), start=1):
        if not row or not "".join(row).strip() or row[0].lstrip().startswith("#"):
            continue
        out.append((lineno, [c.strip() for c in row]))
    if not out:
        raise ConfigError(f"{src}: empty profile file (expected a header such as z_mm,r_outer_mm,r_inner_mm)")
    return out


def _number(text: str, src: str, lineno: int, col: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise ConfigError(f"{src}, line {lineno}: {col} = {text!r} is not a number") from None
    if not math.isfinite(v):
        raise ConfigError(f"{src}, line {lineno}: {col} = {text!r} is not finite")
    return v


def read_profile(path, length_unit: str | None = None) -> TableProfile:
    """Read a profile file by its suffix: ``.csv`` a table (:func:`read_profile_csv`, units in its header: then
    ``length_unit`` must be None), any suffix of :data:`fem_reference.section_mesh.MESH_SUFFIXES` a 2-D mesh of
    the meridian section (:func:`fem_reference.section_mesh.read_profile_mesh`; ``length_unit`` "m", "cm" or
    "mm" required: a mesh file states no unit).  ConfigError for any other suffix."""
    from .section_mesh import MESH_SUFFIXES, read_profile_mesh

    path = pathlib.Path(path)
    suffix = path.suffix.lower()
    if suffix == ".csv":
        if length_unit is not None:
            raise ConfigError(f"{path}: a CSV profile states its units in its header (z_mm, r_mm, …); the profile "
                              f"unit {length_unit!r} is for mesh files only")
        return read_profile_csv(path)
    if suffix in MESH_SUFFIXES:
        if length_unit is None:
            raise ConfigError(f"{path}: a mesh file states no unit: give its length unit (design key "
                              f"profile_unit = one of {', '.join(repr(u) for u in LENGTH_UNITS)})")
        return read_profile_mesh(path, length_unit)
    raise ConfigError(f"{path}: a profile file must be a CSV table (.csv) or a 2-D section mesh "
                      f"({', '.join(MESH_SUFFIXES)}), got the suffix {suffix or '(none)'!r}")


def read_profile_csv(path) -> TableProfile:
    """Read a profile file (CSV, ``#`` comment lines allowed) in one of two layouts, units in the header:

    - ``z_mm,r_outer_mm,r_inner_mm``: both outlines sampled at the same ``z`` (columns in any order);
    - ``outline,z_mm,r_mm``: two point lists, each row tagged ``inner`` or ``outer`` (rows of one outline in
      order of increasing ``z``).

    Units: ``m``, ``cm`` or ``mm`` per column.  Raises ConfigError naming the file and line."""
    path = pathlib.Path(path)
    src = str(path)
    try:
        text = path.read_text()
    except (OSError, ValueError, UnicodeDecodeError) as exc:
        raise ConfigError(f"cannot read profile file {src}: {getattr(exc, 'strerror', None) or exc}") from None
    rows = _rows(text, src)
    (hline, header), data = rows[0], rows[1:]
    names = [h.strip() for h in header]
    if names and names[0].lower() == "outline":
        return _read_long(names, data, src, hline)
    return _read_wide(names, data, src, hline)


def _read_wide(names, data, src, hline) -> TableProfile:
    cols = {}
    for j, n in enumerate(names):
        base, fac = _column_unit(n, src, hline)
        if base in cols:
            raise ConfigError(f"{src}, line {hline}: column {base} given twice")
        cols[base] = (j, fac)
    if set(cols) != {"z", "r_outer", "r_inner"}:
        raise ConfigError(f"{src}, line {hline}: expected the columns z, r_outer, r_inner (each with a unit, e.g. "
                          f"z_mm,r_outer_mm,r_inner_mm) or outline,z_mm,r_mm; got {', '.join(names)}")
    vals = {k: [] for k in cols}
    for lineno, row in data:
        if len(row) != len(names):
            raise ConfigError(f"{src}, line {lineno}: {len(row)} values, expected {len(names)}")
        for k, (j, fac) in cols.items():
            vals[k].append(_number(row[j], src, lineno, names[j]) * fac)
    return TableProfile(tuple(vals["z"]), tuple(vals["r_inner"]), tuple(vals["z"]), tuple(vals["r_outer"]), src)


def _read_long(names, data, src, hline) -> TableProfile:
    expected = f"expected the columns outline,z_<unit>,r_<unit> (and optionally {SLOPE_COLUMN}); got {', '.join(names)}"
    if len(names) not in (3, 4) or (len(names) == 4 and names[3] != SLOPE_COLUMN):
        raise ConfigError(f"{src}, line {hline}: {expected}")
    (bz, fz), (br, fr) = _column_unit(names[1], src, hline), _column_unit(names[2], src, hline)
    if (bz, br) != ("z", "r"):
        raise ConfigError(f"{src}, line {hline}: {expected}")
    pts = {"inner": ([], [], []), "outer": ([], [], [])}
    for lineno, row in data:
        if len(row) != len(names):
            raise ConfigError(f"{src}, line {lineno}: {len(row)} values, expected {len(names)}")
        tag = row[0].lower()
        if tag not in pts:
            raise ConfigError(f"{src}, line {lineno}: outline must be 'inner' or 'outer', got {row[0]!r}")
        pts[tag][0].append(_number(row[1], src, lineno, names[1]) * fz)
        pts[tag][1].append(_number(row[2], src, lineno, names[2]) * fr)
        if len(names) == 4:        # a slope dr/dz is a ratio of lengths: unchanged by the units of z and r only
            pts[tag][2].append(_number(row[3], src, lineno, names[3]) * (fr / fz))
    (zi, ri, di), (zo, ro, do) = pts["inner"], pts["outer"]
    return TableProfile(tuple(zi), tuple(ri), tuple(zo), tuple(ro), src, tuple(di), tuple(do))


def write_profile_csv(profile: TableProfile, path, comments: tuple[str, ...] = ()) -> pathlib.Path:
    """Write ``profile`` in the two-list layout (``outline,z_mm,r_mm``, with the column ``dr_dz`` when the
    outlines carry slopes), every number in ``repr`` precision (reads back to round-off, ~1e-16 relative);
    ``comments``: extra ``#`` lines for the head of the file."""
    slopes = profile.has_slopes
    lines = ["# bellows wall profile: inner and outer outline of the meridian section",
             *(f"# {c}" for c in comments), "outline,z_mm,r_mm" + (f",{SLOPE_COLUMN}" if slopes else "")]
    for tag, z, r, d in (("inner", profile.z_inner, profile.r_inner, profile.dr_inner),
                         ("outer", profile.z_outer, profile.r_outer, profile.dr_outer)):
        lines += [f"{tag},{zz * 1e3!r},{rr * 1e3!r}" + (f",{d[k]!r}" if slopes else "")
                  for k, (zz, rr) in enumerate(zip(z, r))]
    path = pathlib.Path(path)
    path.write_text("\n".join(lines) + "\n")
    return path
