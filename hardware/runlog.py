r"""Crash-safe run logs: one HDF5 file per run, written incrementally in SWMR mode.

Layout (format ``bellows-run-log``, version 1; documented in docs/data-formats.md):

* root attributes — ``format``, ``format_version``, ``created`` (ISO 8601), ``versions`` (JSON: package
  versions), ``rig`` (JSON: the resolved rig description and limits), ``controller`` (JSON),
  ``actuator_toml`` (the controller model's parameters as an actuator file), ``run`` (JSON: target,
  pressure, options), ``n_tendons``.
* ``/samples`` — one row per control cycle, every dataset with a ``units`` attribute:
  ``t`` [s] (rig clock), ``iteration``, ``tip`` (N, 3) [m] measured, ``error`` (N, 3) [m] measured
  p_m − p_d, ``error_norm`` [m], ``command`` (N, m) [m] tendon lengths commanded after the sample (NaN
  when none), ``position`` (N, m) [m] drive positions, ``tension`` (N, m) [N] measured, ``pressure`` [Pa]
  measured, ``estimate`` (N, 3) [N] the controller's load estimate, ``compute_time`` [s], and — on a
  simulated rig only, NaN otherwise — ``true_tip`` (N, 3) [m] and ``true_load`` (N, 3) [N].
* ``/events`` — ``t`` [s], ``kind`` (open, pressure, limit, fault, stop, converged, end, ...), ``message``.
* ``/static_states`` — converged equilibria in the :mod:`hardware.static_states` format, readable by
  :func:`hardware.static_states.read_static_states` (tip force NaN = unknown to the rig).
* ``/summary`` — the whole-run summary, written when the run ends (empty if the writer was killed):
  ``result`` (one JSON string: settled tip error per load period with median and max over the periods,
  saturation time, faults, corrections, whether the tolerance was met — :mod:`controller.summary`) and
  ``periods/`` (one row per load period: ``start``, ``end`` [s], ``settled_samples``, ``settled_error``,
  ``settled_max_error``, ``true_settled_error``, ``true_settled_max_error`` [m], ``judged``,
  ``within_tolerance`` (1/0, NaN = not judged)).  The group's ``definition`` attribute says what
  "settled" means.  Logs written before the summary existed have no ``/summary``.

Why it survives a crash: every dataset is chunked and resizable and *created when the log is opened*;
then ``swmr_mode`` is switched on (no group or attribute can be created after that) and each append is
resize + write + ``flush``.  HDF5 guarantees that a file written in SWMR mode stays valid if the writer
dies (even by SIGKILL).  Numeric datasets are filled with NaN, so a row resized but never written reads
NaN.  The end of a run is an ``end`` event (attributes cannot change any more).

Reading: a finished log is opened without SWMR (HDF5 then refuses a truncated file at once); only a file a
writer holds — a run going on, or a writer that was killed — is opened with ``swmr=True``, after its
recorded end of file was checked against its size and with a bounded number of metadata read attempts
(:func:`hardware.static_states.open_hdf5`), so a damaged log is a ConfigError, never a hang.
"""

from __future__ import annotations

import datetime as _dt
import json
import math
import os
import pathlib
import socket
import time
from typing import Optional

import numpy as np

from ancf.errors import ConfigError, InputError
from ancf.export import to_jsonable
from ancf.outputs import prepare_output_file

from . import static_states as ss

FORMAT = "bellows-run-log"
FORMAT_VERSION = 1
SUFFIXES = (".h5", ".hdf5")
SUMMARY_DEFINITION = (
    "load period = time between two load changes (simulated load profile), or the whole run when the load is "
    "constant, continuous or unknown (hardware); settled part = its second half; settled tip error = median of "
    "the measured tip error over the settled part; the last period, cut short by the end of the run, is judged "
    "only if it is the only one or lasted at least half as long as the longest earlier period; a period whose "
    "every settled sample was reach-saturated (target out of reach under the load) is out of reach, not judged; "
    "met = every judged period below the tolerance (and at least one judged or out of reach)")
PERIOD_FIELDS = {"start": "s", "end": "s", "settled_samples": "1", "settled_error": "m", "settled_max_error": "m",
                 "true_settled_error": "m", "true_settled_max_error": "m", "judged": "1", "within_tolerance": "1",
                 "out_of_reach": "1", "reach_gap": "m"}
_PERIOD_KEYS = {"start": "start_s", "end": "end_s", "settled_samples": "settled_samples",
                "settled_error": "settled_error_m", "settled_max_error": "settled_max_error_m",
                "true_settled_error": "true_settled_error_m", "true_settled_max_error": "true_settled_max_error_m",
                "judged": "judged", "within_tolerance": "within_tolerance",
                "out_of_reach": "out_of_reach", "reach_gap": "reach_gap_m"}


def _sample_fields(m: int) -> dict:
    return {"t": ((), "s"), "iteration": ((), "1"), "tip": ((3,), "m"), "error": ((3,), "m"),
            "error_norm": ((), "m"), "command": ((m,), "m"), "position": ((m,), "m"), "tension": ((m,), "N"),
            "pressure": ((), "Pa"), "estimate": ((3,), "N"), "compute_time": ((), "s"), "true_tip": ((3,), "m"),
            "true_load": ((3,), "N"), "saturated": ((), "1"), "io_time": ((), "s"), "cycle_time": ((), "s"),
            "reach_gap": ((), "m")}


def versions() -> dict:
    """Versions of the product and the libraries a run depends on."""
    from importlib import metadata
    out = {}
    for pkg in ("bellows", "numpy", "scipy", "numba", "h5py", "canopen", "python-can", "pyserial"):
        try:
            out[pkg] = metadata.version(pkg)
        except metadata.PackageNotFoundError:
            pass
    import platform
    out["python"] = platform.python_version()
    return out


#: Event kinds written to disk at once (the others go out with the next block of samples).
URGENT_EVENTS = frozenset({"fault", "limit", "error", "warning", "end"})


class RunLog:
    """Writer of one run log.  Use as a context manager; :meth:`close` writes the ``end`` event.

    Parameters
    ----------
    path : output file (``.h5``/``.hdf5``), checked with :func:`ancf.outputs.prepare_output_file`
    n_tendons : m
    force : overwrite an existing file
    rig, controller, run : JSON-friendly descriptions stored as root attributes
    actuator_toml : the actuator parameters as TOML text
    chunk : rows per chunk
    flush_rows, flush_period : samples are buffered and written in blocks, at the latest every ``flush_rows``
        rows or ``flush_period`` seconds (wall clock); events and static states go out with them (faults,
        limits, errors, warnings and the end at once, :data:`URGENT_EVENTS`).  A crash (SIGKILL, power loss)
        loses at most what was written since the last flush: fewer than ``flush_rows`` sample rows and at most
        ``flush_period`` of wall-clock time (defaults 50 rows, 0.1 s).  ``flush_rows=1`` flushes every row (the
        slowest and safest).
    static_std : ``/static_states`` also holds the standard errors ``tensions_std``, ``pressure_std``,
        ``tip_position_std`` of each state (an identification experiment's means of several samples)
    """

    def __init__(self, path, *, n_tendons: int, force: bool = False, rig: Optional[dict] = None,
                 controller: Optional[dict] = None, run: Optional[dict] = None, actuator_toml: str = "",
                 chunk: int = 256, flush_rows: int = 50, flush_period: float = 0.1, static_std: bool = False):
        import h5py
        if isinstance(n_tendons, bool) or not isinstance(n_tendons, (int, np.integer)) or n_tendons < 1:
            raise InputError(f"n_tendons must be a positive integer, got {n_tendons!r}")
        if isinstance(flush_rows, bool) or not isinstance(flush_rows, (int, np.integer)) or flush_rows < 1:
            raise InputError(f"flush_rows must be a positive integer, got {flush_rows!r}")
        if not (isinstance(flush_period, (int, float)) and 0 <= flush_period < math.inf):
            raise InputError(f"flush_period must be a number of seconds >= 0, got {flush_period!r}")
        self.flush_rows, self.flush_period = int(flush_rows), float(flush_period)
        self.path = prepare_output_file(path, force=force, suffixes=SUFFIXES)
        self.m = int(n_tendons)
        self.fields = _sample_fields(self.m)
        f = h5py.File(self.path, "w", libver="latest")
        self.f = f
        f.attrs["format"] = FORMAT
        f.attrs["format_version"] = FORMAT_VERSION
        f.attrs["created"] = _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")
        f.attrs["versions"] = json.dumps(versions())
        f.attrs["rig"] = json.dumps(to_jsonable(rig or {}))
        f.attrs["controller"] = json.dumps(to_jsonable(controller or {}))
        f.attrs["run"] = json.dumps(to_jsonable(run or {}))
        f.attrs["actuator_toml"] = actuator_toml
        f.attrs["n_tendons"] = self.m
        # who writes it: a log whose writer is gone can have its open-for-write flags cleared (recover_crashed_log)
        f.attrs["writer"] = json.dumps({"host": socket.gethostname(), "pid": os.getpid()})
        g = f.create_group("samples")
        self.samples = {}
        for name, (shape, units) in self.fields.items():
            ds = g.create_dataset(name, shape=(0, *shape), maxshape=(None, *shape), chunks=(chunk, *shape),
                                  dtype="f8", fillvalue=np.nan)
            ds.attrs["units"] = units
            self.samples[name] = ds
        e = f.create_group("events")
        sdt = h5py.string_dtype()
        self.ev_t = e.create_dataset("t", shape=(0,), maxshape=(None,), chunks=(64,), dtype="f8", fillvalue=np.nan)
        self.ev_t.attrs["units"] = "s"
        self.ev_kind = e.create_dataset("kind", shape=(0,), maxshape=(None,), chunks=(64,), dtype=sdt)
        self.ev_msg = e.create_dataset("message", shape=(0,), maxshape=(None,), chunks=(64,), dtype=sdt)
        s = f.create_group("static_states")
        s.attrs["format"] = ss.FORMAT
        s.attrs["format_version"] = ss.FORMAT_VERSION
        s.attrs["description"] = "static states recorded by a control run (converged equilibria)"
        s.attrs["actuator_toml"] = actuator_toml
        st_shapes = {"tensions": (self.m,), "pressure": (), "tip_position": (3,), "tip_force": (3,), "time": ()}
        if static_std:                                # standard errors of the static states' means
            st_shapes.update({"tensions_std": (self.m,), "pressure_std": (), "tip_position_std": (3,)})
        self.static = {}
        for name, shape in st_shapes.items():
            ds = s.create_dataset(name, shape=(0, *shape), maxshape=(None, *shape), chunks=(64, *shape), dtype="f8",
                                  fillvalue=np.nan)
            ds.attrs["units"] = ss._DATASETS[name]
            self.static[name] = ds
        self.static_label = s.create_dataset("label", shape=(0,), maxshape=(None,), chunks=(64,), dtype=sdt)
        g = f.create_group("summary")                 # filled when the run ends (SWMR: created now)
        g.attrs["description"] = "whole-run summary written when the run ended (empty: the writer did not finish)"
        g.attrs["definition"] = SUMMARY_DEFINITION
        self.summary_result = g.create_dataset("result", shape=(0,), maxshape=(1,), chunks=(1,), dtype=sdt)
        pg = g.create_group("periods")
        self.summary_periods = {}
        for name, unit in PERIOD_FIELDS.items():
            ds = pg.create_dataset(name, shape=(0,), maxshape=(None,), chunks=(64,), dtype="f8", fillvalue=np.nan)
            ds.attrs["units"] = unit
            self.summary_periods[name] = ds
        f.swmr_mode = True
        f.flush()
        self.rows = 0
        self.closed = False
        self._buffer: dict = {name: [] for name in self.fields}
        self._events: list = []
        self._statics: list = []
        self._flushed_at = time.monotonic()

    # ------------------------------------------------------------------------------------------ writing
    @staticmethod
    def _extend(ds, rows) -> None:
        n = ds.shape[0]
        ds.resize(n + len(rows), axis=0)
        ds[n:] = np.asarray(rows, dtype=object if ds.dtype.kind == "O" else None)

    def _write_buffered(self) -> None:
        """Write the buffered sample rows, events and static states, one block per dataset (the caller
        flushes).  A dataset is resized and written in one go, so a crash leaves either the block or not."""
        if self._buffer["t"]:
            for name, rows in self._buffer.items():
                self._extend(self.samples[name], rows)
                rows.clear()
        if self._events:
            t, kind, msg = zip(*self._events)
            self._extend(self.ev_t, t)
            self._extend(self.ev_kind, kind)
            self._extend(self.ev_msg, msg)
            self._events.clear()
        if self._statics:
            for name in self.static:
                self._extend(self.static[name], [v[name] for v, _ in self._statics])
            self._extend(self.static_label, [label for _, label in self._statics])
            self._statics.clear()

    @staticmethod
    def _append(ds, value) -> None:
        n = ds.shape[0]
        ds.resize(n + 1, axis=0)
        ds[n] = value

    def sample(self, **values) -> None:
        """Append one row; fields not given are NaN.  Unknown fields are an InputError."""
        unknown = set(values) - set(self.fields)
        if unknown:
            raise InputError(f"run log: unknown sample fields {sorted(unknown)}")
        rows = {}
        for name, (shape, _) in self.fields.items():
            v = values.get(name)
            try:
                rows[name] = np.full(shape, np.nan) if v is None else np.asarray(v, float).reshape(shape)
            except (TypeError, ValueError):
                raise InputError(f"run log: sample field {name} must be numeric with shape {shape}, got {v!r}") from None
        for name, a in rows.items():
            self._buffer[name].append(a)
        self.rows += 1
        if (len(self._buffer["t"]) >= self.flush_rows
                or time.monotonic() - self._flushed_at >= self.flush_period):
            self.flush()

    def flush(self) -> None:
        """Write the buffered samples as one block and flush the file (readers in SWMR mode see them)."""
        self._write_buffered()
        self.f.flush()
        self._flushed_at = time.monotonic()

    def _flush_due(self) -> None:
        if time.monotonic() - self._flushed_at >= self.flush_period:
            self.flush()

    def event(self, t: float, kind: str, message: str) -> None:
        """Append an event.  Faults, limits, errors, warnings and the end are flushed at once; other events
        (``converged``, notes) go out with the next block, like the samples."""
        self._events.append((float(t), str(kind), str(message)))
        if kind in URGENT_EVENTS:
            self.flush()
        else:
            self._flush_due()

    def static_state(self, *, time: float, tensions, pressure: float, tip, tip_force=None, label: str = "",
                     std: Optional[dict] = None) -> None:
        """Append one measured equilibrium to ``/static_states`` (tip force NaN = unknown).  ``std``: the
        standard errors {"tensions_std": (m,) [N], "pressure_std": [Pa], "tip_position_std": (3,) [m]}, required
        by (and only by) a log opened with ``static_std=True``."""
        std_names = [n for n in self.static if n.endswith("_std")]
        if set(std or {}) != set(std_names):
            raise InputError(f"static state: this log records the standard errors {std_names or 'none'}; "
                             f"got {sorted(std or {}) or 'none'}")
        try:
            T = np.asarray(tensions, float).reshape(self.m)
            vals = {"tensions": T, "pressure": float(pressure), "tip_position": np.asarray(tip, float).reshape(3),
                    "tip_force": np.full(3, np.nan) if tip_force is None else np.asarray(tip_force, float).reshape(3),
                    "time": float(time)}
            vals.update({n: np.asarray(std[n], float).reshape(self.static[n].shape[1:]) for n in std_names})
        except (TypeError, ValueError):
            raise InputError("static state: tensions (m,), pressure, tip (3,), tip_force (3,), time and the standard "
                             "errors must be numeric with those shapes") from None
        if np.any(~np.isfinite(T)) or np.any(T < 0):
            raise InputError(f"static state: tensions must be finite and >= 0 N, got {T.tolist()}")
        if any(not np.all(np.isfinite(vals[n]) & (vals[n] >= 0)) for n in std_names):
            raise InputError("static state: standard errors must be finite and >= 0")
        self._statics.append((vals, str(label)))
        self._flush_due()

    def summary(self, summary: dict) -> None:
        """Write the whole-run summary (a :meth:`controller.summary.RunSummary.to_dict`) to ``/summary``:
        the JSON in ``result`` and one row per load period in ``periods/``.  Written once."""
        if self.summary_result.shape[0]:
            raise InputError("run log: the run summary is already written")
        try:
            text = json.dumps(to_jsonable(summary))
            rows = [[float("nan") if p.get(_PERIOD_KEYS[k]) is None else float(p[_PERIOD_KEYS[k]])
                     for k in PERIOD_FIELDS] for p in summary.get("periods", [])]
        except (TypeError, ValueError, AttributeError) as exc:
            raise InputError(f"run log: the run summary must be a JSON-friendly dict with periods ({exc})") from None
        self.flush()
        for row in rows:
            for name, v in zip(PERIOD_FIELDS, row):
                self._append(self.summary_periods[name], v)
        self._append(self.summary_result, text)
        self.flush()

    def close(self, status: str = "completed", reason: str = "", t: float = float("nan")) -> None:
        if self.closed:
            return
        try:
            self.event(t, "end", f"{status}" + (f": {reason}" if reason else ""))
        finally:
            self.f.close()
            self.closed = True

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb):
        if exc_type is None:
            self.close()
        else:
            self.close("aborted", f"{exc_type.__name__}: {exc}")
        return False


def recover_crashed_log(path) -> Optional[str]:
    """Clear the HDF5 "open for write" flags of a log whose writer is gone (killed, crashed), like
    ``h5clear -s``, so that every HDF5 reader opens it, not only SWMR-aware ones (:mod:`hardware.h5status`).
    The writer is gone when the log names this host and a process id that no longer runs; a log written on
    another host, or by an older version without the ``writer`` attribute, is left alone.  Returns a note for
    the user, or None when there was nothing to do (a cleanly closed log, or a live writer)."""
    import h5py
    from .h5status import clear_status_flags, status_flags
    try:
        if not status_flags(path):
            return None
        with h5py.File(path, "r", swmr=True) as f:
            writer = json.loads(f.attrs.get("writer", "{}"))
    except (OSError, ValueError, TypeError):
        return None                                  # unreadable: the reader says why
    host, pid = writer.get("host"), writer.get("pid")
    if host is None or pid is None:
        return (f"{path} is marked open for write and names no writer (an older log): if no run is writing it, "
                "'h5clear -s' lets non-SWMR readers open it")
    if host != socket.gethostname():
        return f"{path} is marked open for write by {host}, another host: not cleared (is that run still going?)"
    try:
        os.kill(int(pid), 0)
        return None                                  # the writer runs: readers use SWMR
    except ProcessLookupError:
        pass
    except PermissionError:
        return None                                  # a process with that id runs (another user's)
    try:
        clear_status_flags(path)
    except ValueError:
        return None                                  # truncated or unknown: the reader says why
    return (f"{path}: its writer (process {pid}) is gone; cleared the file's open-for-write flags (like "
            "'h5clear -s'), so any HDF5 reader opens it now")


def loop_timing(samples: dict) -> dict:
    """Per-cycle timing of a run log's samples [s]: for ``compute_time`` (controller), ``io_time`` (rig calls)
    and ``cycle_time`` (loop period as run), the median and 99th percentile over the cycles that have them,
    the jitter of the period (99th percentile − median) and the overruns: cycles longer than twice the
    median period.  Empty for a log without timing (older logs)."""
    out = {}
    for name in ("compute_time", "io_time", "cycle_time"):
        a = np.asarray(samples.get(name, ()), float)
        a = a[np.isfinite(a)]
        if a.size:
            out[name] = {"median": float(np.median(a)), "p99": float(np.percentile(a, 99)), "n": int(a.size)}
    if "cycle_time" in out:
        c = np.asarray(samples["cycle_time"], float)
        c = c[np.isfinite(c)]
        med = out["cycle_time"]["median"]
        out["jitter"] = out["cycle_time"]["p99"] - med
        out["overruns"] = int(np.sum(c > 2 * med))
    return out


def loop_timing_lines(samples: dict) -> list:
    lt = loop_timing(samples)
    if not lt:
        return []
    ms = lambda k: (f"median {lt[k]['median'] * 1e3:.3f}, p99 {lt[k]['p99'] * 1e3:.3f}" if k in lt else "—")
    out = [f"  loop timing [ms]: controller {ms('compute_time')}; rig I/O {ms('io_time')}; cycle {ms('cycle_time')}"]
    if "cycle_time" in lt:
        out.append(f"  loop jitter {lt['jitter'] * 1e3:.3f} ms (p99 − median); overruns {lt['overruns']} of "
                   f"{lt['cycle_time']['n']} cycles (longer than twice the median)")
    return out


# ============================================================================================ reading
class RunData:
    """A run log read back: ``attrs`` (dict, JSON attributes decoded), ``samples`` {name: array},
    ``units`` {name: unit}, ``events`` [(t, kind, message)], ``summary`` (dict or None), ``path``."""

    def __init__(self, path, attrs, samples, units, events, summary=None):
        self.path, self.attrs, self.samples, self.units, self.events = path, attrs, samples, units, events
        self.summary = summary        # the whole-run summary (dict) or None (killed writer, older log)

    @property
    def rows(self) -> int:
        return len(self.samples.get("t", ()))

    @property
    def ended(self) -> Optional[str]:
        """The ``end`` event's message, or None if the writer never closed the log (killed mid-run)."""
        ends = [m for _, k, m in self.events if k == "end"]
        return ends[-1] if ends else None

    def static_states(self):
        return ss.read_static_states(self.path)


JSON_ATTRS = ("versions", "rig", "controller", "run")


def read_run_log(path) -> RunData:
    """Read a run log (also while it is being written, and after the writer was killed).

    A finished log is opened without SWMR; SWMR only while a writer holds the file (or held it and was
    killed) — see :func:`hardware.static_states.open_hdf5`.  A truncated or damaged file, a missing
    ``/samples`` or ``/events`` group and a malformed JSON attribute are :class:`ConfigError` naming what
    is wrong; an empty ``/samples`` group is a log of 0 rows."""
    p = pathlib.Path(path)
    if not p.exists():
        raise InputError(f"run log {p} does not exist")
    f = ss.open_hdf5(p)
    with f:
        try:
            return _read(f, p)
        except (ConfigError, InputError):
            raise
        except (OSError, KeyError, ValueError, TypeError, RuntimeError, AttributeError, IndexError) as exc:
            raise ConfigError(f"{p}: damaged run log ({type(exc).__name__}: {exc})") from None


def _read(f, p: pathlib.Path) -> RunData:
    import h5py
    dec = lambda x: x.decode() if isinstance(x, bytes) else str(x)          # noqa: E731

    def group(name: str):
        if name not in f or not isinstance(f[name], h5py.Group):
            raise ConfigError(f"{p}: no /{name} group: not a complete bellows run log")
        g = f[name]
        if f.swmr_mode:
            for ds in g.values():
                if isinstance(ds, h5py.Dataset):
                    ds.refresh()
        return g

    if f.attrs.get("format") != FORMAT:
        raise ConfigError(f"{p}: not a bellows run log (format attribute {f.attrs.get('format')!r})")
    if int(f.attrs.get("format_version", 0)) > FORMAT_VERSION:
        raise ConfigError(f"{p}: run-log format version {f.attrs['format_version']} is newer than this reader")
    attrs = {}
    for k, v in f.attrs.items():
        if k in JSON_ATTRS:
            try:
                attrs[k] = json.loads(dec(v))
            except ValueError:
                raise ConfigError(f"{p}: root attribute '{k}' is not valid JSON ({dec(v)[:40]!r})") from None
            if not isinstance(attrs[k], dict):
                raise ConfigError(f"{p}: root attribute '{k}' must be a JSON object, got "
                                  f"{type(attrs[k]).__name__} {dec(v)[:40]!r}")
        else:
            attrs[k] = v.item() if hasattr(v, "item") else v
    g = group("samples")
    bad = [k for k, ds in g.items() if not isinstance(ds, h5py.Dataset) or ds.ndim < 1]
    if bad:
        raise ConfigError(f"{p}: /samples/{bad[0]} is not a dataset of rows")
    n = min((ds.shape[0] for ds in g.values()), default=0)   # a row is complete when every field has it
    samples = {k: ds[:n] for k, ds in g.items()}
    units = {k: dec(ds.attrs.get("units", "")) for k, ds in g.items()}
    e = group("events")
    missing = [k for k in ("t", "kind", "message") if k not in e]
    if missing:
        raise ConfigError(f"{p}: /events has no '{missing[0]}' dataset")
    ne = min(e[k].shape[0] for k in ("t", "kind", "message"))
    events = [(float(t), dec(k), dec(m)) for t, k, m in zip(e["t"][:ne], e["kind"][:ne], e["message"][:ne])]
    summ = None
    if "summary" in f and "result" in f["summary"]:
        r = f["summary"]["result"]
        if f.swmr_mode:
            r.refresh()
        if r.shape[0]:
            try:
                summ = json.loads(dec(r[0]))
            except ValueError:
                raise ConfigError(f"{p}: /summary/result is not valid JSON") from None
    return RunData(p, attrs, samples, units, events, summ)


def _describe_actuator(rec: dict) -> str:
    """One actuator record of a run (``bellows control`` writes ``run["actuator"]`` and ``run["plant"]``):
    its name, where it came from (a preset, or a file with the start of its SHA-256)."""
    where = rec.get("source", "?")
    if rec.get("path"):
        sha = str(rec.get("file_sha256") or "")[:12]
        where = f"file {rec['path']}" + (f", sha256 {sha}…" if sha else "")
    return f"'{rec.get('name', '?')}' ({where})"


def _actuator_lines(run: dict) -> list[str]:
    """Which actuator the controller's model was and which the simulated plant was (none for older logs)."""
    out = []
    if isinstance(run.get("actuator"), dict):
        out.append(f"  controller's model: actuator {_describe_actuator(run['actuator'])}")
    if isinstance(run.get("plant"), dict):
        pl = run["plant"]
        out.append(f"  simulated plant: actuator {_describe_actuator(pl)}"
                   + (", perturbed by --mismatch" if pl.get("mismatch") else ""))
    return out


def summary(path) -> str:
    """A short human-readable summary of a run log."""
    d = read_run_log(path)
    run, rig = d.attrs.get("run", {}), d.attrs.get("rig", {})
    lines = [f"run log {d.path}", f"  created {d.attrs.get('created')}, bellows {d.attrs.get('versions', {}).get('bellows', '?')}",
             f"  rig: {rig.get('name', '?')} ({'simulated' if rig.get('simulated') else 'hardware'}, "
             f"{d.attrs.get('n_tendons')} tendons); controller: {d.attrs.get('controller', {}).get('name', '?')}"]
    lines += _actuator_lines(run)
    if "target_m" in run:
        try:
            lines.append(f"  target [mm]: {np.round(np.asarray(run['target_m'], float) * 1e3, 3).tolist()}, "
                         f"pressure {float(run.get('pressure_Pa', float('nan'))) / 1e3:.1f} kPa")
        except (TypeError, ValueError):
            lines.append(f"  target: malformed in the 'run' attribute ({str(run['target_m'])[:40]})")
    n = d.rows
    lines.append(f"  samples: {n}")
    if n and "t" in d.samples and "error_norm" in d.samples:
        t, en = d.samples["t"], d.samples["error_norm"]
        lines.append(f"  time {t[0]:.3f} … {t[-1]:.3f} s; tip error [mm]: first {en[0] * 1e3:.4f}, last "
                     f"{en[-1] * 1e3:.4f}, max {np.nanmax(en) * 1e3:.4f}")
        tt = d.samples.get("true_tip", np.full((n, 3), np.nan))
        if np.any(np.isfinite(tt)):
            target = np.asarray(run.get("target_m", [np.nan] * 3))
            te = np.linalg.norm(tt - target, axis=1)
            lines.append(f"  true tip error (simulated rig) [mm]: last {te[-1] * 1e3:.4f}, max {np.nanmax(te) * 1e3:.4f}")
        lines += loop_timing_lines(d.samples)
    try:
        st = d.static_states()
        torn = st.meta.get("torn_rows", [])
        lines.append(f"  static states: {st.n_states}" + (f" (and {len(torn)} torn row not read: the writer "
                                                           f"stopped while recording it)" if torn else ""))
    except (ConfigError, InputError):
        lines.append("  static states: 0")
    sm = d.summary
    if sm:
        f = lambda x: "—" if x is None else f"{x * 1e3:.4f}"          # noqa: E731
        lines.append(f"  load periods: {len(sm['periods'])}, {sm['periods_judged']} judged, "
                     + (f"{sm['periods_out_of_reach']} out of reach, " if sm.get('periods_out_of_reach') else "")
                     + f"{sm['periods_within_tolerance']} within the tolerance {sm['tolerance_m'] * 1e3:.4f} mm "
                     f"(settled = second half of each period)")
        lines.append(f"  settled tip error [mm]: median {f(sm['settled_error_median_m'])}, max "
                     f"{f(sm['settled_error_max_m'])} over the judged periods")
        lines.append(f"  saturation time {sm['saturation_time_s']:.2f} s; faults {len(sm['faults'])}; "
                     f"corrections {sm['corrections']}")
    else:
        lines.append("  summary: none (the writer did not finish, or an older log)")
    lines.append(f"  events: {len(d.events)}")
    for t, k, m in d.events[-8:]:
        lines.append(f"    {t:9.3f} s  {k:9s} {m}")
    lines.append(f"  end: {d.ended or 'none recorded — the writer did not close the log (killed or still running)'}")
    return "\n".join(lines)


def export_csv(path, out, *, force: bool = False) -> pathlib.Path:
    """Write the samples as CSV, one column per component with its unit in the header (``tip_x_m``,
    ``tension1_N``, ...).  Returns the CSV path."""
    import csv
    out = prepare_output_file(out, force=force, suffixes=(".csv",))
    d = read_run_log(path)
    cols, header = [], []
    for name, a in d.samples.items():
        u = d.units.get(name, "")
        suf = f"_{u}" if u and u != "1" else ""
        if a.ndim == 1:
            header.append(f"{name}{suf}")
            cols.append(a)
        else:
            labels = "xyz" if a.shape[1] == 3 and name in ("tip", "error", "estimate", "true_tip", "true_load") \
                else [str(i + 1) for i in range(a.shape[1])]
            for i, lab in enumerate(labels):
                header.append(f"{name}_{lab}{suf}" if lab in "xyz" else f"{name}{lab}{suf}")
                cols.append(a[:, i])
    order = [h for h in header if h == "t_s"] + [h for h in header if h != "t_s"]
    idx = [header.index(h) for h in order]
    with open(out, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(order)
        for r in range(d.rows):
            w.writerow(["" if np.isnan(cols[i][r]) else repr(float(cols[i][r])) for i in idx])
    return out
