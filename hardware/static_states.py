"""Static states: the one file format for measured (or simulated) equilibria of an actuator.

A *static state* is an equilibrium held long enough to be measured: the tendon tensions, the chamber
pressure, the tip load if it is known, the tip position and, optionally, marker positions along the
body — each with its uncertainty.  The rig layer writes them (a run log holds them in its
``/static_states`` group) and :func:`validation.identification.identify.from_measurements` fits the reduced model to
them.  The format is documented in ``docs/data-formats.md``; in short:

HDF5 (canonical).  A group (the file root or ``/static_states``) with attributes
``format = "bellows-static-states"``, ``format_version = 1`` and optional ``description``,
``actuator_toml`` (the actuator file the states were recorded with), and datasets (N states, m tendons,
k markers), each with a ``units`` attribute:

=====================  ==========  ======  ==========================================================
dataset                shape       units   meaning
=====================  ==========  ======  ==========================================================
``tensions``           (N, m)      N       tendon tensions (required)
``pressure``           (N,)        Pa      chamber gauge pressure (required)
``tip_position``       (N, 3)      m       tool point in the actuator's world frame (required)
``tip_force``          (N, 3)      N       external tip load; NaN rows = unknown (optional, default 0)
``markers``            (N, k, 3)   m       marker positions on the centreline (optional)
``marker_arclength``   (k,)        m       undeformed arc length of each marker from the base
``*_std``              as above    same    one standard deviation of the quantity (optional)
``time``               (N,)        s       when the state was recorded (optional)
``label``              (N,)        —       free text per state (optional)
=====================  ==========  ======  ==========================================================

CSV (accepted).  One row per state; every numeric column names its unit as a suffix, as in actuator
files, and the unit must be one of its quantity's (:data:`CSV_UNITS`): ``tension1_N`` …,
``pressure_kPa`` | ``_Pa`` | ``_MPa`` | ``_bar``, ``tip_x_mm`` | ``tip_x_m`` (and ``_y``, ``_z``),
``force_x_N`` …, ``tip_std_mm`` | ``tip_std_m`` (isotropic), ``tension_std_N``, ``pressure_std_kPa``,
``time_s``, ``label``.  A unit of the wrong quantity, an unknown unit or an unknown column is a
:class:`ConfigError` naming the column and the accepted units.  Markers are HDF5-only.
"""

from __future__ import annotations

import csv
import math
import pathlib
import re
from dataclasses import dataclass, field
from typing import Optional

import numpy as np

from ancf.errors import ConfigError, InputError

FORMAT = "bellows-static-states"
FORMAT_VERSION = 1


@dataclass
class StaticStates:
    """A set of N measured static states (SI units; see the module docstring for shapes).

    Required: ``tensions`` (N, m) [N], ``pressure`` (N,) [Pa], ``tip_position`` (N, 3) [m].
    Optional: ``tip_force`` (N, 3) [N] (NaN = unknown), ``markers`` (N, k, 3) [m] with
    ``marker_arclength`` (k,) [m], standard deviations ``*_std``, ``time`` (N,) [s], ``label`` (N,).
    """

    tensions: np.ndarray
    pressure: np.ndarray
    tip_position: np.ndarray
    tip_force: Optional[np.ndarray] = None
    markers: Optional[np.ndarray] = None
    marker_arclength: Optional[np.ndarray] = None
    tensions_std: Optional[np.ndarray] = None
    pressure_std: Optional[np.ndarray] = None
    tip_position_std: Optional[np.ndarray] = None
    tip_force_std: Optional[np.ndarray] = None
    markers_std: Optional[np.ndarray] = None
    time: Optional[np.ndarray] = None
    label: Optional[list] = None
    description: str = ""
    actuator_toml: str = ""
    meta: dict = field(default_factory=dict)

    def __post_init__(self):
        T = _arr("tensions", self.tensions, 2)
        N, m = T.shape
        if N == 0:
            raise InputError("static states: no state given")
        self.tensions = T
        self.pressure = _arr("pressure", self.pressure, 1, (N,))
        self.tip_position = _arr("tip_position", self.tip_position, 2, (N, 3))
        if np.any(T < 0):
            r, c = np.argwhere(T < 0)[0]
            raise InputError(f"static states: tensions must be >= 0 N (a tendon cannot push); state {r} (row {r} "
                             f"of the dataset, counted from 0), tendon {c + 1}: {T[r, c]:g} N")
        if self.tip_force is not None:
            self.tip_force = _arr("tip_force", self.tip_force, 2, (N, 3), allow_nan=True)
        if self.markers is not None:
            mk = _arr("markers", self.markers, 3)
            if mk.shape[0] != N or mk.shape[2] != 3:
                raise InputError(f"static states: markers must have shape (N={N}, k, 3), got {mk.shape}")
            self.markers = mk
            if self.marker_arclength is None:
                raise InputError("static states: markers need marker_arclength (k,) [m]")
            self.marker_arclength = _arr("marker_arclength", self.marker_arclength, 1, (mk.shape[1],))
        elif self.marker_arclength is not None:
            raise InputError("static states: marker_arclength given without markers")
        for name, like in (("tensions_std", T), ("pressure_std", self.pressure),
                           ("tip_position_std", self.tip_position), ("tip_force_std", self.tip_force),
                           ("markers_std", self.markers)):
            v = getattr(self, name)
            if v is None:
                continue
            if like is None:
                raise InputError(f"static states: {name} given without {name[:-4]}")
            a = np.broadcast_to(_arr(name, v, None), like.shape).astype(float).copy()
            if np.any(a < 0):
                raise InputError(f"static states: {name} must be >= 0")
            setattr(self, name, a)
        if self.time is not None:
            self.time = _arr("time", self.time, 1, (N,))
        if self.label is not None:
            if len(self.label) != N:
                raise InputError(f"static states: label needs {N} entries, got {len(self.label)}")
            self.label = [str(x) for x in self.label]

    @property
    def n_states(self) -> int:
        return self.tensions.shape[0]

    @property
    def n_tendons(self) -> int:
        return self.tensions.shape[1]

    def subset(self, index) -> "StaticStates":
        """The states selected by ``index`` (indices or boolean mask)."""
        idx = np.arange(self.n_states)[index]
        kw = {}
        for name in ("tensions", "pressure", "tip_position", "tip_force", "markers", "tensions_std",
                     "pressure_std", "tip_position_std", "tip_force_std", "markers_std", "time"):
            v = getattr(self, name)
            kw[name] = None if v is None else v[idx]
        kw["label"] = None if self.label is None else [self.label[i] for i in idx]
        return StaticStates(marker_arclength=self.marker_arclength, description=self.description,
                            actuator_toml=self.actuator_toml, meta=dict(self.meta), **kw)


def _arr(name, v, ndim, shape=None, allow_nan=False) -> np.ndarray:
    try:
        a = np.array(v, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"static states: {name} must be numeric, got {type(v).__name__}") from None
    if ndim is not None and a.ndim != ndim:
        raise InputError(f"static states: {name} must be {ndim}-D, got shape {a.shape}")
    if shape is not None and a.shape != shape:
        raise InputError(f"static states: {name} must have shape {shape}, got {a.shape}")
    bad = ~np.isfinite(a)
    if allow_nan:
        bad &= ~np.isnan(a)
    if np.any(bad):
        first = tuple(int(i) for i in np.argwhere(bad)[0])
        where = (f" (state {first[0]} — row {first[0]} of the dataset, counted from 0"
                 + (f", column {first[1]}" if len(first) > 1 else "") + f": {a[first]})") if first else ""
        raise InputError(f"static states: {name} contains {'inf' if allow_nan else 'NaN or inf'}{where}")
    return a


_DATASETS = {"tensions": "N", "pressure": "Pa", "tip_position": "m", "tip_force": "N", "markers": "m",
             "marker_arclength": "m", "tensions_std": "N", "pressure_std": "Pa", "tip_position_std": "m",
             "tip_force_std": "N", "markers_std": "m", "time": "s"}


# ------------------------------------------------------------------------------------------------ HDF5
def write_static_states(target, states: StaticStates, *, group: str = "static_states", overwrite: bool = False):
    """Write ``states`` to an HDF5 file path (creates ``/<group>``; refuses to overwrite an existing file
    unless ``overwrite``) or into an open ``h5py.Group`` (its subgroup ``group``).  Returns the path or
    the group."""
    import h5py
    if isinstance(target, (str, pathlib.Path)):
        path = pathlib.Path(target)
        if path.exists() and not overwrite:
            raise InputError(f"{path} exists; pass overwrite=True (CLI: --force) to replace it")
        path.parent.mkdir(parents=True, exist_ok=True)
        with h5py.File(path, "w") as f:
            _write_group(f.create_group(group), states)
        return path
    return _write_group(target.create_group(group), states)


def _write_group(g, states: StaticStates):
    g.attrs["format"] = FORMAT
    g.attrs["format_version"] = FORMAT_VERSION
    g.attrs["description"] = states.description
    g.attrs["actuator_toml"] = states.actuator_toml
    for name, unit in _DATASETS.items():
        v = getattr(states, name)
        if v is not None:
            ds = g.create_dataset(name, data=np.asarray(v, float))
            ds.attrs["units"] = unit
    if states.label is not None:
        import h5py
        g.create_dataset("label", data=np.array(states.label, dtype=object), dtype=h5py.string_dtype())
    return g


def check_data_file(path, what: str = "data file") -> pathlib.Path:
    """``path`` as a Path if it names an existing regular file; :class:`InputError` if nothing is there,
    :class:`ConfigError` naming the path if it is a folder (or another non-file)."""
    path = pathlib.Path(path)
    if not path.exists():
        raise InputError(f"{what} {path} does not exist")
    if path.is_dir():
        raise ConfigError(f"{path}: is a folder; expected a file ({what})")
    if not path.is_file():
        raise ConfigError(f"{path}: is not a regular file; expected a file ({what})")
    return path


def read_csv_rows(path, what: str = "CSV file") -> list[tuple[int, list[str]]]:
    """(line number in the file, 1-based; cells) of each row of a text CSV file (UTF-8, a byte-order mark
    allowed), comment lines (``#``) and empty rows dropped.  :class:`ConfigError` naming the file — and the
    byte or line — when it is not text (binary content, a NUL byte, an encoding other than UTF-8) or not
    readable as CSV."""
    path = check_data_file(path, what)
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read the {what} ({exc.strerror or exc})") from None
    nul = raw.find(b"\x00")
    if nul >= 0:
        raise ConfigError(f"{path}: not a text {what}: binary content (a NUL byte at byte {nul})")
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise ConfigError(f"{path}: not a text {what}: byte {exc.start} is not UTF-8 text (binary content, or "
                          "a file saved in another encoding)") from None
    out = []
    reader = csv.reader(text.splitlines())
    try:
        for r in reader:
            if r and any(c.strip() for c in r) and not r[0].lstrip().startswith("#"):
                out.append((reader.line_num, r))
    except csv.Error as exc:
        raise ConfigError(f"{path}: line {reader.line_num}: not a readable {what} ({exc})") from None
    return out


def csv_number(path, text: str, row: int, column: str, fac: float = 1.0, *, nan_ok: bool = False) -> float:
    """The finite number in one CSV cell (``row``: the line number in the file, 1-based, header = 1) times
    ``fac``; :class:`ConfigError` naming file, row and column for text or a non-finite value (nan, inf;
    ``nan_ok``: NaN, an unknown value, is returned)."""
    try:
        v = float(text)
    except ValueError:
        raise ConfigError(f"{path}: row {row}, column {column}: not a number: {text!r}") from None
    if not (math.isfinite(v) or (nan_ok and math.isnan(v))):
        raise ConfigError(f"{path}: row {row}, column {column}: {text!r} is not a finite number")
    return v * fac


def read_static_states(path, *, group: Optional[str] = None) -> StaticStates:
    """Read static states from an HDF5 file (``/static_states`` of a run log, or a file whose root has the
    format attributes) or from a CSV file (by suffix).  Raises :class:`ConfigError` on a malformed file: one
    that is not what its name says (binary content in a .csv, a folder, a truncated HDF5 file), a value that
    is not a finite number (naming its row and column), a missing or unknown column."""
    path = check_data_file(path, "static-states file")
    if path.suffix.lower() == ".csv":
        return _read_csv(path)
    f = open_hdf5(path)
    with f:
        try:
            return _read_group(f, path, group)
        except (ConfigError, InputError):
            raise
        except (OSError, KeyError, ValueError, TypeError, RuntimeError, AttributeError) as exc:
            raise ConfigError(f"{path}: damaged static states ({type(exc).__name__}: {exc})") from None


def _superblock_eof(path: pathlib.Path) -> Optional[int]:
    """End-of-file address the HDF5 superblock (version 2/3, the one SWMR files have) records, or None."""
    import struct
    with open(path, "rb") as fh:
        for base in (0, 512, 1024, 2048, 4096, 8192):
            fh.seek(base)
            head = fh.read(12)
            if len(head) < 12:
                return None
            if head[:8] == b"\x89HDF\r\n\x1a\n":
                if head[8] < 2:
                    return None
                o = head[9]
                rest = fh.read(3 * o)
                if o not in (4, 8) or len(rest) < 3 * o:
                    return None
                fmt = "<I" if o == 4 else "<Q"
                base_addr = struct.unpack(fmt, rest[:o])[0]
                eof = struct.unpack(fmt, rest[2 * o:3 * o])[0]
                return base_addr + eof
    return None


def open_hdf5(path) -> "h5py.File":  # noqa: F821
    """Open an HDF5 file (a run log or a static-states file) for reading, without hanging on a damaged one.

    A finished file — and every file that no writer holds open — is opened *without* SWMR, so HDF5 checks
    it: a truncated file is a :class:`ConfigError` at once.  Only when the file is marked as open by a
    (SWMR) writer — a run still going on, or one whose writer was killed — is it opened with ``swmr=True``,
    and then only after the recorded end of file was checked against the file's size (a SWMR reader
    does not check it, and blocks inside the first read of a truncated file)."""
    import re
    import h5py
    path = check_data_file(path, "HDF5 file")
    try:
        return h5py.File(path, "r")
    except OSError as exc:
        msg = str(exc)
    size = path.stat().st_size
    m = re.search(r"truncated file: eof = (\d+).*stored_eof = (\d+)", msg)
    if m or "truncated" in msg:
        got, want = (int(m.group(1)), int(m.group(2))) if m else (size, None)
        raise ConfigError(f"{path}: truncated HDF5 file ({got} of {want if want is not None else '?'} bytes): the "
                          f"file was cut short (an interrupted copy or a full disk?); copy it again from where it "
                          f"was written") from None
    if "already open for write" not in msg and "lock" not in msg.lower():
        raise ConfigError(f"{path}: not a readable HDF5 file ({msg})")
    eof = _superblock_eof(path)                   # a writer holds (or held) it: a live or killed run
    if eof is not None and size < eof:
        raise ConfigError(f"{path}: truncated HDF5 file ({size} of {eof} bytes): the file was cut short (an "
                          f"interrupted copy or a full disk?); copy it again from where it was written")
    try:
        return _swmr_open(path)
    except OSError as exc:
        raise ConfigError(f"{path}: not a readable HDF5 file ({exc})") from None


#: metadata read attempts of a SWMR reader.  HDF5's default (100, with a delay doubling from 1 µs up to an
#: hour) makes a reader of a damaged file block for hours inside one read; 20 attempts are about 2 s at
#: most — ample for a read racing the writer's flush.
SWMR_READ_ATTEMPTS = 20


def _swmr_open(path: pathlib.Path):
    """``h5py.File(path, "r", libver="latest", swmr=True)`` with at most :data:`SWMR_READ_ATTEMPTS` metadata
    read attempts (set through the HDF5 library h5py loaded — h5py does not expose the property; where that
    library cannot be found the HDF5 default applies)."""
    import ctypes
    import re
    import h5py
    fn = None
    try:
        with open("/proc/self/maps") as fh:                 # the libhdf5 h5py is linked with (Linux)
            libs = sorted(set(re.findall(r"(/\S*/libhdf5(?:-[0-9a-f]+)?\.so[.\d]*)\s*$", fh.read(), flags=re.M)))
        if libs:
            fn = ctypes.CDLL(libs[0]).H5Pset_metadata_read_attempts
            fn.argtypes, fn.restype = [ctypes.c_int64, ctypes.c_uint], ctypes.c_int
    except (OSError, AttributeError):
        fn = None
    if fn is None:
        return h5py.File(path, "r", libver="latest", swmr=True)
    fapl = h5py.h5p.create(h5py.h5p.FILE_ACCESS)
    fapl.set_libver_bounds(h5py.h5f.LIBVER_LATEST, h5py.h5f.LIBVER_LATEST)
    if fn(fapl.id, SWMR_READ_ATTEMPTS) < 0:
        return h5py.File(path, "r", libver="latest", swmr=True)
    fid = h5py.h5f.open(str(path).encode(), h5py.h5f.ACC_RDONLY | h5py.h5f.ACC_SWMR_READ, fapl=fapl)
    return h5py.File(fid)


#: the per-state datasets that must be finite in a finished row (a torn row reads NaN: the fill value)
_FINITE = ("tensions", "pressure", "tip_position", "time")


def _read_group(f, path: pathlib.Path, group: Optional[str]) -> StaticStates:
    if group is not None:
        if group not in f:
            raise ConfigError(f"{path}: no group '{group}'")
        g = f[group]
    elif f.attrs.get("format") == FORMAT:
        g = f
    elif "static_states" in f:
        g = f["static_states"]
    else:
        raise ConfigError(f"{path}: no static states (neither a '/static_states' group nor a file with "
                          f"format = '{FORMAT}')")
    if g.attrs.get("format") != FORMAT:
        raise ConfigError(f"{path}: group {g.name} is not in the '{FORMAT}' format")
    version = int(g.attrs.get("format_version", 0))
    if version > FORMAT_VERSION:
        raise ConfigError(f"{path}: format version {version} is newer than this reader ({FORMAT_VERSION})")
    kw = {}
    for name, unit in _DATASETS.items():
        if name in g:
            got = g[name].attrs.get("units")
            if got != unit:
                raise ConfigError(f"{path}: dataset {name} has units {got!r}; expected {unit!r}")
            kw[name] = g[name][()]
    for req in ("tensions", "pressure", "tip_position"):
        if req not in kw:
            raise ConfigError(f"{path}: static states need a '{req}' dataset")
    if "label" in g:
        kw["label"] = [x.decode() if isinstance(x, bytes) else str(x) for x in g["label"][()]]
    kw["description"] = str(g.attrs.get("description", ""))
    kw["actuator_toml"] = str(g.attrs.get("actuator_toml", ""))
    # appended (resizable) datasets, as a run log writes them: a writer killed within a state leaves a
    # torn last row — datasets one row longer than others, or a resized row never written (NaN).  The
    # complete rows are read; the torn one is reported in ``meta["torn_rows"]``.
    per_state = [n for n in (*_DATASETS, "label") if n in g and n != "marker_arclength"]
    if per_state and all(g[n].maxshape[0] is None for n in per_state):
        total = max(len(kw[n]) for n in per_state)
        n_ok = min(len(kw[n]) for n in per_state)
        if n_ok == total and n_ok > 0 and any(
                n in kw and not np.all(np.isfinite(np.asarray(kw[n][n_ok - 1], float))) for n in _FINITE):
            n_ok -= 1                         # the last row resized but not written (only it can be torn)
        if n_ok < total:
            for n in per_state:
                kw[n] = kw[n][:n_ok]
            kw["meta"] = {"torn_rows": list(range(n_ok, total))}
            if n_ok == 0:
                raise ConfigError(f"{path}: the only static state is torn (the writer stopped while "
                                  f"recording it)")
    try:
        return StaticStates(**kw)
    except InputError as exc:
        raise ConfigError(f"{path}: {exc}") from None


# ------------------------------------------------------------------------------------------------ CSV
#: Units accepted in a CSV column suffix, per dimension (factor to SI).
CSV_UNITS = {
    "force": {"N": 1.0},
    "pressure": {"Pa": 1.0, "kPa": 1e3, "MPa": 1e6, "bar": 1e5},
    "length": {"m": 1.0, "mm": 1e-3},
    "time": {"s": 1.0},
}
#: The CSV columns (without the unit suffix) and the dimension of each; ``tension<i>`` for i = 1 … m.
CSV_COLUMNS = {"pressure": "pressure", "tip_x": "length", "tip_y": "length", "tip_z": "length",
               "force_x": "force", "force_y": "force", "force_z": "force", "tip_std": "length",
               "tension_std": "force", "pressure_std": "pressure", "time": "time"}
_TENSION = re.compile(r"^tension([1-9][0-9]*)$")


def _accepted(dim: str) -> str:
    return ", ".join(CSV_UNITS[dim])


def _parse_header(header: list[str]) -> dict:
    """{stem: (column index, factor to SI)} for every column of ``header`` except ``label``; a column that is
    unknown, lacks a unit, or names a unit not of its quantity's dimension is a :class:`ConfigError`."""
    out = {}
    for i, h in enumerate(header):
        if h == "label":
            continue
        if not h:
            raise ConfigError(f"column {i + 1} has an empty header")
        stem = unit = None
        for j in range(len(h)):           # the longest known stem that the header starts with, then "_<unit>"
            cand = h[:len(h) - j]
            if (cand in CSV_COLUMNS or _TENSION.match(cand)) and (j == 0 or h[len(cand)] == "_"):
                stem, unit = cand, (h[len(cand) + 1:] if j else "")
                break
        if stem is None:
            raise ConfigError(f"unknown column '{h}'; the columns are tension1_<unit> … tension<m>_<unit>, "
                              f"{', '.join(k + '_<unit>' for k in CSV_COLUMNS)} and label "
                              "(docs/data-formats.md)")
        dim = "force" if _TENSION.match(stem) else CSV_COLUMNS[stem]
        if not unit:
            raise ConfigError(f"column '{h}' needs a unit suffix (accepted units for a {dim}: {_accepted(dim)})")
        if unit not in CSV_UNITS[dim]:
            raise ConfigError(f"column '{h}': unit '{unit}' is not a unit of {dim}; accepted units: "
                              f"{_accepted(dim)}")
        if stem in out:
            raise ConfigError(f"column '{stem}' given twice ('{header[out[stem][0]]}' and '{h}')")
        out[stem] = (i, CSV_UNITS[dim][unit])
    return out


def _read_csv(path: pathlib.Path) -> StaticStates:
    numbered = read_csv_rows(path, "static-states CSV file")
    if len(numbered) < 2:
        raise ConfigError(f"{path}: needs a header row and at least one state")
    header = [h.strip() for h in numbered[0][1]]
    lines = [n for n, _ in numbered[1:]]
    body = [r for _, r in numbered[1:]]
    try:
        cols = _parse_header(header)
    except ConfigError as exc:
        raise ConfigError(f"{path}: {exc}") from None

    def col(stem, required=False, empty_ok=False):
        """The column's values in SI (NaN for an empty or ``nan`` cell where ``empty_ok``: an unknown load)."""
        if stem not in cols:
            if required:
                raise ConfigError(f"{path}: missing column '{stem}_<unit>'")
            return None
        i, fac = cols[stem]
        out = []
        for line, row in zip(lines, body):
            txt = row[i].strip() if i < len(row) else ""
            if not txt and not empty_ok:
                raise ConfigError(f"{path}: row {line}, column {header[i]}: empty cell (give every state a value"
                                  + (")" if required else " or drop the column)"))
            out.append(csv_number(path, txt, line, header[i], fac, nan_ok=empty_ok) if txt else math.nan)
        return np.array(out)

    idx = sorted(int(_TENSION.match(k).group(1)) for k in cols if _TENSION.match(k))
    if not idx:
        raise ConfigError(f"{path}: no tension columns (tension1_N, tension2_N, ...)")
    m = len(idx)
    if idx != list(range(1, m + 1)):
        extra = [header[cols[f"tension{k}"][0]] for k in idx if k > m]
        raise ConfigError(f"{path}: tension columns must be numbered 1 … {m} without gaps; got "
                          f"{', '.join(header[cols[f'tension{k}'][0]] for k in idx)} "
                          f"(out of sequence: {', '.join(extra)})")
    T = np.column_stack([col(f"tension{i + 1}", True) for i in range(m)])
    neg = np.argwhere(T < 0)
    if len(neg):
        r, c = neg[0]
        raise ConfigError(f"{path}: row {lines[r]}, column {header[cols[f'tension{c + 1}'][0]]}: a tension must "
                          "be >= 0 (a tendon cannot push)")
    p = col("pressure", True)
    tip = np.column_stack([col(f"tip_{c}", True) for c in "xyz"])
    fcols = [col(f"force_{c}", empty_ok=True) for c in "xyz"]
    F = None if all(c is None for c in fcols) else np.column_stack(
        [c if c is not None else np.zeros(len(body)) for c in fcols])
    tip_std, t_std, p_std, time = (col(k) for k in ("tip_std", "tension_std", "pressure_std", "time"))
    labels = None
    if "label" in header:
        i = header.index("label")
        labels = [row[i] if i < len(row) else "" for row in body]
    try:
        return StaticStates(tensions=T, pressure=p, tip_position=tip, tip_force=F,
                            tip_position_std=None if tip_std is None else np.repeat(tip_std[:, None], 3, 1),
                            tensions_std=None if t_std is None else np.repeat(t_std[:, None], m, 1),
                            pressure_std=p_std, time=time, label=labels)
    except InputError as exc:
        raise ConfigError(f"{path}: {exc}") from None


def write_static_states_csv(path, states: StaticStates, *, overwrite: bool = False) -> pathlib.Path:
    """Write ``states`` as CSV in SI units (markers are not written: HDF5 only)."""
    path = pathlib.Path(path)
    if path.exists() and not overwrite:
        raise InputError(f"{path} exists; pass overwrite=True (CLI: --force) to replace it")
    m = states.n_tendons
    header = [f"tension{i + 1}_N" for i in range(m)] + ["pressure_Pa", "tip_x_m", "tip_y_m", "tip_z_m"]
    cols = [states.tensions[:, i] for i in range(m)] + [states.pressure] + [states.tip_position[:, c]
                                                                             for c in range(3)]
    if states.tip_force is not None:
        header += ["force_x_N", "force_y_N", "force_z_N"]
        cols += [states.tip_force[:, c] for c in range(3)]
    if states.tip_position_std is not None:
        header.append("tip_std_m")
        cols.append(states.tip_position_std.max(axis=1))
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(header + (["label"] if states.label is not None else []))
        for k in range(states.n_states):
            row = [repr(float(c[k])) for c in cols]
            if states.label is not None:
                row.append(states.label[k])
            w.writerow(row)
    return path
