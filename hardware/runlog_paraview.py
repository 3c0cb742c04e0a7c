"""A run log as a ParaView time series (``bellows log export RUN.h5 --pvd RUN.pvd``).

A run log records the *measured tip* at each sample, not the rod's shape (no model coordinates: the rig
measures the tool point; docs/data-formats.md, Run logs), so the export is the tip trajectory: frame k of
the ``.pvd`` (time = the sample's rig clock ``t`` [s]) holds the path of the tip from the first sample up
to sample k as a polyline, cell data ``curve`` 0 — and, on a simulated rig, the true tip's path as
``curve`` 1 — with point data per sample

    ``t_s``, ``error_norm_m``, ``pressure_Pa``, ``tension1_N`` … ``tensionm_N`` (measured),
    ``saturated`` (1/0) and ``iteration``.

Samples whose tip is not finite are left out of the path.  At most ``max_frames`` frames, spread evenly
over the samples (the first and the last included): ParaView animates them at their logged times.
"""

from __future__ import annotations

import pathlib

import numpy as np

from ancf.errors import InputError
from ancf.paraview import frame_indices, prepare_pvd, write_pvd

from .runlog import read_run_log

#: Default most frames of a run-log export.
MAX_FRAMES = 200


def _sample_point_data(samples: dict, rows: np.ndarray) -> dict:
    """Point data of the samples ``rows`` (indices): time, error, pressure, tensions, flags."""
    n = len(rows)
    get = lambda name: np.asarray(samples[name], float)[rows] if name in samples else np.full(n, np.nan)  # noqa: E731
    out = {"t_s": get("t"), "error_norm_m": get("error_norm"), "pressure_Pa": get("pressure"),
           "saturated": get("saturated"), "iteration": get("iteration")}
    tension = np.asarray(samples.get("tension", np.full((len(samples["t"]), 0), np.nan)), float)
    for i in range(tension.shape[1] if tension.ndim == 2 else 0):
        out[f"tension{i + 1}_N"] = tension[rows, i]
    return out


def _trail_mesh(samples: dict, upto: int):
    """The mesh of frame ``upto``: measured (and true) tip paths over samples 0 … ``upto``."""
    import meshio

    pts, lines, curves, data = [], [], [], []
    for c, name in enumerate(("tip", "true_tip")):
        tip = np.asarray(samples.get(name, np.empty((0, 3))), float)[: upto + 1]
        rows = np.flatnonzero(np.all(np.isfinite(tip), axis=1)) if tip.size else np.empty(0, int)
        if not len(rows):
            continue
        off = sum(len(p) for p in pts)
        pts.append(tip[rows])
        k = len(rows)
        if k > 1:
            lines.append(("line", np.column_stack([np.arange(off, off + k - 1), np.arange(off + 1, off + k)])))
        else:
            lines.append(("vertex", np.array([[off]])))        # one sample so far: a point
        curves.append(np.full(len(lines[-1][1]), c))
        data.append(_sample_point_data(samples, rows))
    point_data = {k: np.concatenate([d[k] for d in data]) for k in data[0]}
    return meshio.Mesh(np.vstack(pts), lines, point_data=point_data,
                       cell_data={"curve": curves})


def export_pvd(path, out, *, force: bool = False, max_frames: int = MAX_FRAMES) -> pathlib.Path:
    """Write the tip trajectory of the run log ``path`` as the ParaView collection ``out`` (.pvd) with its
    frames in the folder beside it (module docstring).  InputError for a log without a finite measured
    tip; OutputExistsError for an existing output without ``force``.  Returns the .pvd path."""
    out = prepare_pvd(out, force=force)
    frame_indices(1, max_frames)                           # the number of frames checked before reading
    d = read_run_log(path)
    tip = np.asarray(d.samples.get("tip", np.empty((0, 3))), float)
    finite = np.flatnonzero(np.all(np.isfinite(tip), axis=1)) if tip.size else np.empty(0, int)
    if not len(finite):
        raise InputError(f"{d.path}: no sample with a measured tip position: nothing to write as a trajectory")
    t = np.asarray(d.samples["t"], float)
    rows = finite[frame_indices(len(finite), max_frames)]
    rows = rows[np.isfinite(t[rows])]
    keep = np.concatenate([[True], np.diff(np.maximum.accumulate(t[rows])) > 0]) if len(rows) else rows
    rows = rows[keep]                                       # a frame per distinct, increasing time
    return write_pvd(out, ((t[k], _trail_mesh(d.samples, k)) for k in rows))
