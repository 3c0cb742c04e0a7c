"""Workspace of the TD and TPHD modes (paper Sec. IV-A, Fig. 4).

Paper: 10 000 Monte Carlo actuation inputs per mode; TD: p = 0, T ∈ [0, 5]³ N; TPHD: the same tension
limits and p ∈ [0, 120] kPa; FK for each; the workspace volume is the convex-hull volume of the tip
cloud; TPHD is +108.6 % over TD.

Choices made here (the paper does not state them):

* Inputs are uniform in the box of each mode.  By default both modes use the *same* tension draws
  (common random numbers, ``common_tensions=True``): the TD cloud is then the p = 0 section of the TPHD
  input set, which removes one source of noise from the ratio.  The pressures are drawn after the tensions
  from the same seeded generator.
* Volume: ``scipy.spatial.ConvexHull(points).volume``.  A sampled hull lies inside the hull of the
  reachable set, so the estimate converges *from below*; ``convergence`` gives the volumes on the first
  N/4 and N/2 samples.
* Sampling error: the N samples are two independent halves (even and odd indices); each half gives its
  own TPHD/TD ratio, and ``sampling_error`` reports both and half their difference — the Monte Carlo
  error of a run with N/2 samples, an upper bound for the full run's.  A second seed
  (``bellows paper compare`` runs two) gives the full-size spread directly.
* Every sample is one of ``ok``, ``collapsed`` (the stiffness law is past its limit point, or the
  tendons' compression exceeds the largest the law can carry: :mod:`validation.paper.states`; when it
  does so by more than the weight, the sample is not even solved) or ``failed`` (any other failed solve;
  ``failures_near_limit`` counts those whose compression is above 85 % of that largest value — bent
  sections reach the limit point earlier than the straight-rod bound can certify).  Collapsed and
  failed samples are counted, their inputs reported, and they are left out of the hull — never dropped
  silently.  A sample whose warm start fails is retried cold before it counts (not near the law's limit,
  where a failure is almost always a collapse).
* Parallelism: :func:`validation.infra.runner.run_tasks` over chunks of ``chunk_size`` samples in a fixed
  layout; each chunk is solved independently along a Morton (Z-order) curve of its inputs with warm
  starts, so serial, process-parallel and dask runs give the same clouds (to round-off).
* Nothing finished is lost: with ``out``, every finished chunk is appended at once to
  ``workspace_samples.csv`` (mode, index, inputs, tip, status, iterations); on Ctrl-C the study raises
  :class:`~validation.infra.runner.RunInterrupted` with ``saved_to`` naming that file.  The result files are
  checked before any work and not overwritten without ``force``.
"""

from __future__ import annotations

import csv
import os
import pathlib
import time
from typing import Any, Optional, Sequence, Union

import numpy as np

from ancf import ActuatorParams, Model
from ancf.errors import BellowsError
from ancf.export import write_json
from ancf.outputs import prepare_output_dir

from validation.paper.numbers import WORKSPACE as PAPER_WORKSPACE
from validation.infra.runner import RunInterrupted, run_tasks
from validation.paper import states
from validation.paper.common import ParamsLike, resolve_params
from validation.paper.hulls import hull_distance, hull_volume

MODES = ("TD", "TPHD")
STATUS = ("ok", "collapsed", "failed")
FILES = ("workspace.json", "workspace_clouds.npz", "workspace_samples.csv", "workspace.png", "workspace.svg")


def workspace_inputs(samples: int, seed: int = 0, params: ParamsLike = None,
                     tension_range: Optional[Sequence[float]] = None,
                     pressure_range: Optional[Sequence[float]] = None,
                     common_tensions: bool = True) -> dict[str, np.ndarray]:
    """The Monte Carlo inputs: ``{"TD": X, "TPHD": X}`` with X (samples, m + 1) = [T_1 … T_m [N], p [Pa]].

    Defaults: the tension and pressure limits of ``params`` (paper: [0, 5] N, [0, 120] kPa)."""
    prm = resolve_params(params)
    if samples < 1:
        raise ValueError(f"samples must be ≥ 1, got {samples}")
    tlo, thi = tension_range if tension_range is not None else (prm.tension_min, prm.tension_max)
    plo, phi = pressure_range if pressure_range is not None else (prm.pressure_min, prm.pressure_max)
    m = prm.n_tendons
    rng = np.random.default_rng(seed)
    T_td = rng.uniform(tlo, thi, (samples, m))
    T_tphd = T_td.copy() if common_tensions else rng.uniform(tlo, thi, (samples, m))
    p = rng.uniform(plo, phi, samples)
    return {"TD": np.column_stack([T_td, np.zeros(samples)]), "TPHD": np.column_stack([T_tphd, p])}


_WORKER_MODELS: dict[str, Model] = {}


def _worker_model(params: ActuatorParams) -> Model:
    key = params.model_dump_json()
    m = _WORKER_MODELS.get(key)
    if m is None:
        m = _WORKER_MODELS[key] = Model(params)
    return m


def morton_order(X: np.ndarray, bits: int = 8) -> np.ndarray:
    """Indices that visit the rows of ``X`` along a Morton (Z-order) curve of the unit box."""
    lo, hi = X.min(axis=0), X.max(axis=0)
    span = np.where(hi > lo, hi - lo, 1.0)
    u = np.clip(((X - lo) / span * (2 ** bits - 1)).astype(np.int64), 0, 2 ** bits - 1)
    key = np.zeros(len(X), np.int64)
    for b in range(bits - 1, -1, -1):
        for d in range(X.shape[1]):
            key = (key << 1) | ((u[:, d] >> b) & 1)
    return np.argsort(key, kind="stable")


def solve_chunk(task: dict) -> dict:
    """FK for one chunk of samples (runs in a worker).  ``task``: params, X (k, m + 1), warm_start,
    fk_kwargs, plus bookkeeping keys returned unchanged.  Returns tips (k, 3) (NaN unless ok), status
    (k,) index into :data:`STATUS`, iterations, errors [(i, message)], timing."""
    t0, c0 = time.perf_counter(), time.process_time()
    model = _worker_model(task["params"])
    X = np.asarray(task["X"], float)
    m, k = model.m, len(X)
    tips = np.full((k, 3), np.nan)
    status = np.zeros(k, np.int8)
    iters = np.zeros(k, np.int64)
    errors: list[tuple[int, str]] = []
    order = morton_order(X) if task.get("warm_start") and k > 1 else np.arange(k)
    fk_kwargs = dict(task.get("fk_kwargs") or {})
    q_prev = None
    for i in order:
        T, p = X[i, :m], X[i, m]
        if states.certainly_collapsed(model.params, T, p):
            status[i] = 1
            errors.append((int(i), f"collapsed: Σ T − p A_eff = {states.axial_compression(model.params, T, p):.2f} N "
                                   f"> N_c = {states.law_limits(model.params)['max_compression_N']:.2f} N "
                                   "plus the weight: no equilibrium (not solved)"))
            continue
        eq, err, exc_last = None, "", None
        # a cold retry after a failed warm start, except near the law's limit (there a failure is almost
        # always a collapse, and each failed solve costs a full load-stepping run)
        retry = q_prev is not None and not states.near_limit(model.params, T, p)
        for q0 in ((q_prev, None) if retry else (q_prev,)):
            try:
                eq = model.fk(T, p, (0.0, 0.0, 0.0), q0=q0, **fk_kwargs)
                break
            except (BellowsError, FloatingPointError, np.linalg.LinAlgError) as exc:
                err, exc_last = f"{type(exc).__name__}: {exc}", exc
        if eq is None:
            status[i] = 1 if states.failure_is_collapse(model.params, T, p, exc_last) else 2
            errors.append((int(i), err))
            continue
        if states.state_collapsed(model, eq.q):
            status[i] = 1
            errors.append((int(i), f"collapsed: min stretch {states.stretches(model, eq.q).min():.3f} ≤ "
                                   f"{states.law_limits(model.params)['critical_stretch']:.3f}"))
            continue
        tips[i] = eq.tip
        iters[i] = eq.iterations
        if task.get("warm_start"):
            q_prev = eq.q
    out = {key: v for key, v in task.items() if key not in ("params", "X", "fk_kwargs")}
    out.update(tips=tips, status=status, iterations=iters, errors=errors, seconds=time.perf_counter() - t0,
               cpu_seconds=time.process_time() - c0, pid=os.getpid())
    return out


class _SampleLog:
    """Appends every finished chunk to ``workspace_samples.csv`` at once (flushed), so a crash or Ctrl-C
    keeps what was done."""

    def __init__(self, path: Optional[pathlib.Path], X: dict, m: int):
        self.path, self.X, self.m = path, X, m
        self._fh = None
        if path is not None:
            self._fh = open(path, "w", newline="")
            self._w = csv.writer(self._fh)
            self._w.writerow(["mode", "index"] + [f"T{i + 1}_N" for i in range(m)]
                             + ["p_Pa", "x_m", "y_m", "z_m", "status", "iterations"])
            self._fh.flush()

    def add(self, r: dict) -> None:
        if self._fh is None:
            return
        s = r["start"]
        for j in range(len(r["tips"])):
            x = self.X[r["mode"]][s + j]
            self._w.writerow([r["mode"], s + j, *map(repr, map(float, x)), *map(repr, map(float, r["tips"][j])),
                              STATUS[int(r["status"][j])], int(r["iterations"][j])])
        self._fh.flush()
        os.fsync(self._fh.fileno())

    def close(self) -> None:
        if self._fh is not None:
            self._fh.close()


def read_samples(path) -> dict[str, dict[str, np.ndarray]]:
    """Read ``workspace_samples.csv`` back: {mode: {"index", "inputs", "tips", "status"}} (sorted by index)."""
    rows: dict[str, list] = {mode: [] for mode in MODES}
    with open(path, newline="") as fh:
        rd = csv.reader(fh)
        header = next(rd)
        m = sum(h.startswith("T") for h in header)
        for row in rd:
            rows[row[0]].append(row)
    out = {}
    for mode, rr in rows.items():
        rr.sort(key=lambda r: int(r[1]))
        out[mode] = {"index": np.array([int(r[1]) for r in rr], int),
                     "inputs": np.array([[float(v) for v in r[2:3 + m]] for r in rr]).reshape(-1, m + 1),
                     "tips": np.array([[float(v) for v in r[3 + m:6 + m]] for r in rr]).reshape(-1, 3),
                     "status": np.array([r[6 + m] for r in rr], dtype=object)}
    return out


def _ratio(td, tphd) -> float:
    v_td, v_tphd = hull_volume(td), hull_volume(tphd)
    return v_tphd / v_td if v_td > 0 else float("nan")


def sampling_error(tips_td: np.ndarray, tips_tphd: np.ndarray) -> dict:
    """Ratio on two disjoint halves of the samples (even / odd indices) and half their difference [%]."""
    inc = [(_ratio(tips_td[h::2], tips_tphd[h::2]) - 1) * 100 for h in (0, 1)]
    return {"halves_increase_percent": inc, "half_difference_percent": abs(inc[0] - inc[1]) / 2,
            "note": "Monte Carlo error of a run with half the samples (an upper bound for the full run)"}


def workspace(samples: int = 10_000, seed: int = 0, workers: Optional[int] = None, scheduler=None,
              out: Union[str, pathlib.Path, None] = None, progress: bool = True, *,
              params: ParamsLike = None, chunk_size: int = 100, warm_start: bool = True,
              common_tensions: bool = True, tension_range: Optional[Sequence[float]] = None,
              pressure_range: Optional[Sequence[float]] = None, fk_kwargs: Optional[dict] = None,
              figure: bool = True, start_method: Optional[str] = None, force: bool = False) -> dict:
    """Monte Carlo workspace of the TD and TPHD modes and their convex-hull volumes (module docstring).

    Returns a dict (SI units): ``volume_td_m3``, ``volume_tphd_m3``, ``ratio`` (TPHD / TD),
    ``increase_percent`` (paper: 108.6), ``sampling_error``, ``samples`` (per mode), ``failures`` and
    ``collapsed`` (totals), ``modes`` (per mode: solved, collapsed, failures, their indices and inputs,
    first messages, volume, hull vertex count, bounding box, convergence), ``inside_fraction``, ``timing``
    and ``clouds`` (per mode: ``inputs`` (N, m + 1) [N…, Pa], ``tips`` (N, 3) [m] with NaN rows unless ok,
    ``ok`` (N,) bool, ``status`` (N,) str).  With ``out``: workspace.json, workspace_clouds.npz,
    workspace_samples.csv (written as the run goes), workspace.png/.svg.

    Raises :class:`~validation.infra.runner.RunInterrupted` on Ctrl-C (``saved_to``: the samples CSV, if ``out``).
    """
    prm = resolve_params(params)
    if chunk_size < 1:
        raise ValueError("chunk_size must be ≥ 1")
    if out is not None:
        out = prepare_output_dir(out, FILES if figure else FILES[:3], force=force)
    t_start = time.perf_counter()
    X = workspace_inputs(samples, seed, prm, tension_range, pressure_range, common_tensions)
    tasks = [{"mode": mode, "start": s, "X": X[mode][s:s + chunk_size], "params": prm,
              "warm_start": warm_start, "fk_kwargs": fk_kwargs}
             for mode in MODES for s in range(0, samples, chunk_size)]
    log = _SampleLog(None if out is None else out / "workspace_samples.csv", X, prm.n_tendons)
    try:
        run = run_tasks(solve_chunk, tasks, workers=workers, scheduler=scheduler, progress=progress,
                        description=f"workspace FK ({prm.name}, {2 * samples} samples)",
                        on_result=lambda i, r: log.add(r), start_method=start_method,
                        weights=[len(t["X"]) for t in tasks])
    except RunInterrupted as exc:
        exc.saved_to = log.path
        raise
    finally:
        log.close()
    res = assemble(run.results, X, prm, samples, seed, common_tensions)
    busy = sum(r["seconds"] for r in run.results)
    cpu = sum(r["cpu_seconds"] for r in run.results)
    res["timing"] = {"wall_s": time.perf_counter() - t_start, "worker_busy_s": busy, "worker_cpu_s": cpu,
                     "per_sample_ms": busy / (2 * samples) * 1e3, "per_sample_cpu_ms": cpu / (2 * samples) * 1e3,
                     "backend": run.backend, "workers": run.workers, "chunk_size": chunk_size,
                     "warm_start": warm_start}
    if out is not None:
        write_outputs(res, out, figure=figure)
    return res


def assemble(results: list[dict], X: dict, prm: ActuatorParams, samples: int, seed: int,
             common_tensions: bool = True) -> dict:
    """The study's result from the finished chunks (any order)."""
    tips = {mode: np.full((samples, 3), np.nan) for mode in MODES}
    status = {mode: np.full(samples, 2, np.int8) for mode in MODES}
    iters = {mode: np.zeros(samples, np.int64) for mode in MODES}
    errors: dict[str, list] = {mode: [] for mode in MODES}
    for r in results:
        s, k = r["start"], len(r["tips"])
        tips[r["mode"]][s:s + k] = r["tips"]
        status[r["mode"]][s:s + k] = r["status"]
        iters[r["mode"]][s:s + k] = r["iterations"]
        errors[r["mode"]] += [(s + i, msg) for i, msg in r["errors"]]
    res: dict[str, Any] = {"study": "workspace (paper Sec. IV-A, Fig. 4)", "preset": prm.name,
                           "samples": samples, "seed": seed, "common_tensions": common_tensions,
                           "law_limits": states.law_limits(prm), "modes": {}, "clouds": {}}
    for mode in MODES:
        st = status[mode]
        ok = st == 0
        P = tips[mode][ok]
        errs = sorted(errors[mode])
        vol = hull_volume(P)
        conv = {f"volume_first_{n}_m3": hull_volume(tips[mode][:n][ok[:n]])
                for n in sorted({max(4, samples // 4), max(4, samples // 2)}) if n < samples}
        nverts = 0
        if vol > 0:
            from scipy.spatial import ConvexHull
            nverts = len(ConvexHull(P).vertices)
        near = [bool(states.near_limit(prm, x[:-1], x[-1])) for x in X[mode][st == 2]]
        res["modes"][mode] = {
            "samples": samples, "solved": int(ok.sum()), "collapsed": int((st == 1).sum()),
            "failures": int((st == 2).sum()), "failures_near_limit": int(sum(near)),
            "collapsed_indices": np.flatnonzero(st == 1).tolist(), "collapsed_inputs": X[mode][st == 1],
            "failed_indices": np.flatnonzero(st == 2).tolist(), "failed_inputs": X[mode][st == 2],
            "first_errors": [msg for i, msg in errs if st[i] == 2][:5],
            "first_collapses": [msg for i, msg in errs if st[i] == 1][:5],
            "volume_m3": vol, "volume_cm3": vol * 1e6, "hull_vertices": nverts,
            "bbox_min_m": P.min(axis=0) if len(P) else None, "bbox_max_m": P.max(axis=0) if len(P) else None,
            "mean_fk_iterations": float(iters[mode][ok].mean()) if ok.any() else None,
            "convergence": conv,
        }
        res["clouds"][mode] = {"inputs": X[mode], "tips": tips[mode], "ok": ok,
                               "status": np.array([STATUS[i] for i in st])}
    v_td, v_tphd = res["modes"]["TD"]["volume_m3"], res["modes"]["TPHD"]["volume_m3"]
    ratio = v_tphd / v_td if v_td > 0 else float("nan")
    P_td, P_tphd = tips["TD"][status["TD"] == 0], tips["TPHD"][status["TPHD"] == 0]
    if v_tphd > 0 and len(P_td):
        dist = hull_distance(P_td, P_tphd)
        inside, max_out = float(np.mean(dist <= 1e-12)), float(max(dist.max(), 0.0))
    else:
        inside, max_out = float("nan"), float("nan")
    res.update(volume_td_m3=v_td, volume_tphd_m3=v_tphd, ratio=ratio, increase_percent=(ratio - 1) * 100,
               paper_increase_percent=PAPER_WORKSPACE["increase_percent"],
               sampling_error=sampling_error(np.where(status["TD"][:, None] == 0, tips["TD"], np.nan),
                                             np.where(status["TPHD"][:, None] == 0, tips["TPHD"], np.nan)),
               failures=sum(res["modes"][m]["failures"] for m in MODES),
               collapsed=sum(res["modes"][m]["collapsed"] for m in MODES),
               inside_fraction=inside, max_td_outside_tphd_hull_m=max_out)
    return res


def write_outputs(res: dict, out: Union[str, pathlib.Path], *, figure: bool = True) -> dict:
    """workspace_clouds.npz, workspace.png/.svg (with ``figure``) and workspace.json into ``out``."""
    out = pathlib.Path(out)
    m = res["clouds"]["TD"]["inputs"].shape[1] - 1
    npz = out / "workspace_clouds.npz"
    np.savez_compressed(npz, **{f"{mode.lower()}_{k}": v for mode in MODES for k, v in res["clouds"][mode].items()
                                if k != "status"},
                        **{f"{mode.lower()}_status": res["clouds"][mode]["status"].astype(str) for mode in MODES},
                        columns=np.array([f"T{i + 1}_N" for i in range(m)] + ["p_Pa"]))
    files: dict[str, Any] = {"clouds": npz, "samples": out / "workspace_samples.csv"}
    if figure:
        from validation.paper.plots import plot_workspace
        files["figures"] = plot_workspace(res, out)
    files["json"] = out / "workspace.json"
    res["files"] = files
    write_json(files["json"], {k: v for k, v in res.items() if k != "clouds"})
    return files
