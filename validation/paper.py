"""Reproductions of the paper's simulation studies (Sec. IV-A workspace, Sec. V-C stiffness, and the
controller studies of Sec. IV-B / V-E through :mod:`validation.control_studies`).

Every study returns a plain ``dict`` (SI units, the unit in each key name), and with ``out=DIR`` writes
``<study>.json`` and ``<study>.png`` / ``<study>.svg`` there.  :func:`print_workspace` and
:func:`print_stiffness` print a rich table that sets our numbers beside the paper's (``PAPER``).

Workspace (Sec. IV-A, Fig. 4)
=============================
Paper: 10 000 Monte Carlo actuation inputs per mode; TD: p = 0, T ∈ [0, 5]³ N; TPHD: the same tension
limits and p ∈ [0, 120] kPa; FK for each; the workspace volume is the convex-hull volume of the tip
cloud; TPHD is +108.6 % over TD.

Choices made here (the paper does not state them):

* Inputs are uniform in the box of each mode.  By default both modes use the *same* tension draws
  (common random numbers; ``common_tensions=True``): the TD cloud is then exactly the p = 0 section of
  the TPHD input set, which removes one source of sampling noise from the ratio.  The TPHD pressures are
  drawn after the tensions from the same seeded generator.
* Volume: ``scipy.spatial.ConvexHull(points).volume`` (Qhull; the hull is closed, and its volume is
  Σ over the facets of the cone volume from an interior point, i.e. the divergence theorem).  A sampled
  hull is inside the true hull of the reachable set, so the Monte Carlo estimate converges *from below*;
  ``convergence`` in the result gives the volume on the first N/4 and N/2 samples as a check.  Fewer than
  4 points or a flat cloud give volume 0 (reported, not raised).
* Failed FK solves are not dropped silently: each mode reports ``failures`` (count), their inputs and
  the first error messages; the hull uses the solved samples only; the top-level ``failures`` is the
  total.  A sample whose warm start fails is retried cold before it counts as failed.
* Parallelism: the samples are cut into chunks of ``chunk_size`` in a fixed layout that does not depend
  on the number of workers; each chunk is solved independently (no state crosses chunks) and its order
  inside the chunk is fixed too, so serial, process-parallel and dask runs give
  bit-identical clouds for the same seed.  Each worker process builds its own :class:`ancf.Model` once
  (cached per process).  Local processes start by ``fork`` where available and safe (no other thread
  in this process), else by ``spawn``.  Warm starts (``warm_start=True``, default): inside a chunk the samples are
  visited along a Morton (Z-order) curve of the inputs and each FK starts from the previous equilibrium;
  measured (``benchmarks/bench_workspace.py``, 2 × 1000 samples, chunks of 100): 5.55 → 4.83 Newton
  iterations and 1.1–1.6× less time per FK than cold starts from the straight reference (several runs on
  a shared, loaded machine); the tips agree with cold starts to < 1e-8 m.  (Much larger chunks help less: consecutive Morton neighbours in 4-D are
  then not always close, and a poor start can fall back to load stepping.)
* ``scheduler``: ``None`` → local processes (``workers``, default all cores; 1 = in this process);
  ``"local"`` → a temporary ``dask.distributed.LocalCluster`` with ``workers`` processes; any other string
  → the address of a running dask scheduler; a ``dask.distributed.Client`` is used as given.
* ``inside_fraction``: the share of the TD tips inside the TPHD hull (a plausibility check: TD inputs are
  a subset of TPHD inputs, so only TD tips near the hull's boundary may fall outside a *sampled* hull).

Stiffness vs T1 (Sec. V-C, Fig. 9)
==================================
Protocol: p ∈ {0, 25, 50} kPa; T1 ∈ {0, …, 5} N on the top tendon (θ1 = 0), T2 = T3 = 0; the motors are
locked; a 50 g payload hangs at the tip; k = m g / (z_unload − z_load).

* Nonlinear ("measured" in simulation): ``eq0 = fk((T1, 0, 0), p)``; constant tension:
  ``fk((T1, 0, 0), p, F)``; locked: ``fk_locked(eq0.tendon_lengths, p, F)`` with F = (0, 0, −m g).
  This is a *secant* stiffness over the payload.
* Linear: k = 1 / (e_zᵀ C_p e_z) = ``directional_stiffness(C_p, e_z)`` at eq0, the *tangent* stiffness,
  for ``cp.tension`` and ``cp.locked`` with methods ``"exact"`` (KKT), ``"paper"`` (eq. 13) and ``"ik"``
  (eqs. 15/16), active set along the payload direction (0, 0, −1).  The secant and tangent values differ
  by O(m g) (tested: the gap halves when the payload halves).
* Closed-form check (uniform straight beam, no gravity, tendon at distance d, one taut tendon):
  constant tension k = 3EI/L³; locked, the tendon's zero stretch d θ(L) − T L/EA = 0 with
  θ(L) = (P L²/2 − T d L)/EI gives T = P L d /(2EI (a + b)) and
  k_locked = k / (1 − ¾ a/(a + b)), a = d²/EI, b = 1/EA — ≈ 2.9× for the paper's d, EI, EA.  So this
  model predicts "about three times", not the paper's "about twice"; the literal (unweighted) ``paper``
  and ``ik`` stacks come out near the constant-tension value (see :func:`ancf.compliance.locked`).

Measured (paper preset, n = 6; ``bellows paper all``)
====================================================
* Workspace, 10 000 samples per mode, seed 0, no failed solve: TD 2.38 cm³, TPHD 14.57 cm³,
  TPHD +512 % vs TD (paper +108.6 %).  The half-sample hulls are 1.7 % (TD) and 3.6 % (TPHD) smaller, so
  the ratio is still creeping up, not down.  Why so far from the paper: with EA = k(λ) ≈ 767 N
  (docs/design.md §3) the tendons (≤ 15 N) shorten the actuator by only ≈ 3 mm, so the TD cloud is a thin
  shell, while 120 kPa (≈ 64 N on A_eff) lengthens it by ≈ 12 mm; pressure hardly changes the lateral
  reach (front view of the figure).  With the alternative reading EA = k(λ)·L (≈ 123 N) the same study
  gives ≈ +77 % (2 000 samples; 183 of 4 000 FK solves fail at the extreme inputs) — the paper's order —
  but then the stiffnesses below drop to ≈ 12–17 N/m (constant) and 32–46 N/m (locked).
* Stiffness, 50 g: constant tension 54–57 N/m, locked 172–176 N/m at every (p, T1), ratio 3.0–3.2
  (paper: "about twice"); the nonlinear (secant) and exact linear (tangent) values agree within 1 %;
  the paper's literal eq. (13) / (15) stacks give 54–58 / 60–63 N/m, i.e. near the constant-tension value.

Controller studies
==================
``table1``, ``compliance_ablation`` and ``loading`` forward to :mod:`validation.control_studies` (written
separately), imported lazily: this module works without it, and the wrappers raise
:class:`StudyUnavailableError` with a clear message when it is missing.
"""

from __future__ import annotations

import inspect
import json
import os
import pathlib
import time
from typing import Any, Callable, Optional, Sequence, Union

import numpy as np

from ancf.export import to_jsonable, write_json
from ancf import ActuatorParams, Model, presets
from ancf import compliance as cp
from ancf.errors import BellowsError

G = 9.81
MODES = ("TD", "TPHD")

from .paper_numbers import PAPER  # noqa: E402  (every paper number lives in validation/paper_numbers.py)


class StudyUnavailableError(BellowsError, ImportError):
    """A study's implementation module is not installed / not written yet."""


# ============================================================================== small helpers
def _params(preset: Union[str, ActuatorParams, None]) -> ActuatorParams:
    if preset is None:
        return presets.paper()
    if isinstance(preset, ActuatorParams):
        return preset
    return presets.get(str(preset))




def _save_figure(fig, out: pathlib.Path, stem: str) -> list[pathlib.Path]:
    import matplotlib.pyplot as plt
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for ext in ("png", "svg"):
        p = out / f"{stem}.{ext}"
        fig.savefig(p, dpi=130)
        paths.append(p)
    plt.close(fig)
    return paths


def _pyplot():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


# ============================================================================== convex hulls
def hull_volume(points) -> float:
    """Volume of the convex hull of ``points`` (k, 3) [m³ for m]; 0.0 for fewer than 4 points or a flat
    (coplanar / collinear) cloud.  NaN rows are ignored."""
    from scipy.spatial import ConvexHull
    from scipy.spatial import QhullError

    P = np.asarray(points, float).reshape(-1, 3)
    P = P[np.all(np.isfinite(P), axis=1)]
    if len(P) < 4:
        return 0.0
    try:
        return float(ConvexHull(P).volume)
    except QhullError:
        return 0.0


def hull_distance(points, hull_points) -> np.ndarray:
    """Signed distance [m] of each of ``points`` (k, 3) to the convex hull of ``hull_points``: the largest
    facet-plane offset, ≤ 0 inside (its magnitude is then the distance to the nearest facet plane), > 0
    outside (a lower bound of the Euclidean distance to the hull, exact where the nearest hull point lies
    on a facet's interior)."""
    from scipy.spatial import ConvexHull

    H = ConvexHull(np.asarray(hull_points, float))
    P = np.asarray(points, float).reshape(-1, 3)
    return np.max(P @ H.equations[:, :3].T + H.equations[:, 3], axis=1)


# ============================================================================== workspace
def workspace_inputs(samples: int, seed: int = 0, params: Union[str, ActuatorParams, None] = None,
                     tension_range: Optional[Sequence[float]] = None,
                     pressure_range: Optional[Sequence[float]] = None,
                     common_tensions: bool = True) -> dict[str, np.ndarray]:
    """The Monte Carlo inputs: ``{"TD": X, "TPHD": X}`` with X (samples, m + 1) = [T_1 … T_m [N], p [Pa]].

    Defaults: the tension and pressure limits of ``params`` (paper: [0, 5] N, [0, 120] kPa)."""
    prm = _params(params)
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
    key = params.model_dump_json() if hasattr(params, "model_dump_json") else repr(params)
    m = _WORKER_MODELS.get(key)
    if m is None:
        m = _WORKER_MODELS[key] = Model(params)
    return m


def _morton_order(X: np.ndarray, bits: int = 8) -> np.ndarray:
    lo, hi = X.min(axis=0), X.max(axis=0)
    span = np.where(hi > lo, hi - lo, 1.0)
    u = np.clip(((X - lo) / span * (2 ** bits - 1)).astype(np.int64), 0, 2 ** bits - 1)
    key = np.zeros(len(X), np.int64)
    for b in range(bits - 1, -1, -1):
        for d in range(X.shape[1]):
            key = (key << 1) | ((u[:, d] >> b) & 1)
    return np.argsort(key, kind="stable")


def _solve_chunk(task: dict) -> dict:
    """Solve FK for one chunk of samples (runs in a worker).  ``task``: params, X (k, m + 1), warm_start,
    fk_kwargs, plus bookkeeping keys that are returned unchanged."""
    t0, c0 = time.perf_counter(), time.process_time()
    model = _worker_model(task["params"])
    X = np.asarray(task["X"], float)
    m = model.m
    k = len(X)
    tips = np.full((k, 3), np.nan)
    iters = np.zeros(k, np.int64)
    errors: list[tuple[int, str]] = []
    order = _morton_order(X) if task.get("warm_start") and k > 1 else np.arange(k)
    fk_kwargs = dict(task.get("fk_kwargs") or {})
    q_prev = None
    for i in order:
        T, p = X[i, :m], X[i, m]
        eq = None
        for q0 in ((q_prev, None) if q_prev is not None else (None,)):
            try:
                eq = model.fk(T, p, (0.0, 0.0, 0.0), q0=q0, **fk_kwargs)
                break
            except (BellowsError, FloatingPointError, np.linalg.LinAlgError) as exc:
                err = f"{type(exc).__name__}: {exc}"
        if eq is None:
            errors.append((int(i), err))
            continue
        tips[i] = eq.tip
        iters[i] = eq.iterations
        if task.get("warm_start"):
            q_prev = eq.q
    out = {key: v for key, v in task.items() if key not in ("params", "X", "fk_kwargs")}
    out.update(tips=tips, iterations=iters, errors=errors, seconds=time.perf_counter() - t0,
               cpu_seconds=time.process_time() - c0, pid=os.getpid())
    return out


def _progress(enabled: bool):
    from rich.progress import (BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn,
                               TimeRemainingColumn)
    return Progress(TextColumn("[bold]{task.description}"), BarColumn(), MofNCompleteColumn(),
                    TextColumn("{task.fields[rate]}"), TimeElapsedColumn(), TimeRemainingColumn(),
                    disable=not enabled, transient=False)


def _start_method() -> str:
    """Process start method for the local pool: ``fork`` where the platform has it and this process runs
    no other thread (fast, and works from scripts without an ``if __name__ == "__main__"`` guard or from
    code piped to ``python -``); else ``spawn`` (clean workers; needs the guard)."""
    import multiprocessing as mp
    import threading
    if "fork" in mp.get_all_start_methods() and threading.active_count() == 1:
        return "fork"
    return "spawn"


def _run_tasks(tasks: list[dict], workers: Optional[int], scheduler, progress: bool,
               totals: dict[str, int], start_method: Optional[str] = None) -> tuple[list[dict], str, int]:
    """Run ``_solve_chunk`` over the tasks serially, on local processes or on dask, with a progress bar
    per mode.  Returns (results in completion order, backend description, number of workers)."""
    import contextlib
    results: list[dict] = []
    done = {mode: 0 for mode in totals}

    def run(stream, backend, nworkers):
        t0 = time.perf_counter()
        with _progress(progress) as bar:
            ids = {mode: bar.add_task(f"FK {mode}", total=n, rate="") for mode, n in totals.items()}
            for res in stream:
                results.append(res)
                done[res["mode"]] += len(res["tips"])
                rate = sum(done.values()) / max(time.perf_counter() - t0, 1e-9)
                bar.update(ids[res["mode"]], advance=len(res["tips"]), rate=f"{rate:,.0f} FK/s")
        return results, backend, nworkers

    if scheduler is not None:
        from dask.distributed import Client, LocalCluster, as_completed
        with contextlib.ExitStack() as stack:
            if isinstance(scheduler, Client):
                client, where = scheduler, str(getattr(scheduler.scheduler, "address", "?"))
            elif scheduler == "local":
                cluster = stack.enter_context(LocalCluster(n_workers=workers or os.cpu_count() or 1,
                                                           threads_per_worker=1, processes=True,
                                                           dashboard_address=None))
                client, where = stack.enter_context(Client(cluster)), "temporary LocalCluster"
            else:
                client = stack.enter_context(Client(str(scheduler)))
                where = str(scheduler)
            nworkers = len(client.scheduler_info().get("workers", {}))
            futures = client.map(_solve_chunk, tasks, pure=False)
            return run((f.result() for f in as_completed(futures)), f"dask ({where})", nworkers)
    nworkers = workers if workers is not None else (os.cpu_count() or 1)
    nworkers = max(1, min(nworkers, len(tasks)))
    if nworkers == 1:
        return run((_solve_chunk(t) for t in tasks), "serial (this process)", 1)
    import concurrent.futures as cf
    import multiprocessing as mp
    method = start_method or _start_method()
    # the pool (and with fork, all its processes) is created before the progress bar starts its thread
    with cf.ProcessPoolExecutor(max_workers=nworkers, mp_context=mp.get_context(method)) as pool:
        futs = [pool.submit(_solve_chunk, t) for t in tasks]
        return run((f.result() for f in cf.as_completed(futs)), f"processes ({method})", nworkers)


def workspace(samples: int = 10_000, seed: int = 0, workers: Optional[int] = None, scheduler=None,
              out: Union[str, pathlib.Path, None] = None, progress: bool = True, *,
              params: Union[str, ActuatorParams, None] = None, chunk_size: int = 100,
              warm_start: bool = True, common_tensions: bool = True,
              tension_range: Optional[Sequence[float]] = None, pressure_range: Optional[Sequence[float]] = None,
              fk_kwargs: Optional[dict] = None, figure: bool = True, start_method: Optional[str] = None) -> dict:
    """Monte Carlo workspace of the TD and TPHD modes and their convex-hull volumes (paper Sec. IV-A).

    Returns a dict (SI units): ``volume_td_m3``, ``volume_tphd_m3``, ``ratio`` (TPHD / TD),
    ``increase_percent`` (paper: 108.6), ``samples`` (per mode), ``failures`` (total), ``modes`` (per mode:
    solved, failures, failed inputs, first errors, volume, hull vertex count, bounding box, convergence),
    ``inside_fraction``, ``timing`` and ``clouds`` (per mode: ``inputs`` (N, m + 1) [N…, Pa], ``tips``
    (N, 3) [m] with NaN rows for failed samples, ``ok`` (N,) bool) — ``clouds`` is not written to the JSON
    but to ``workspace_clouds.npz``.  With ``out``: workspace.json, workspace_clouds.npz, workspace.png/.svg.
    ``tension_range`` / ``pressure_range`` override the sampled box (inputs outside the model's limits are
    rejected by FK and counted as failures); ``fk_kwargs`` go to :meth:`ancf.Model.fk`; ``start_method``
    (``"fork"`` / ``"spawn"`` / ``"forkserver"``) overrides the automatic choice for local processes.
    """
    prm = _params(params)
    if chunk_size < 1:
        raise ValueError("chunk_size must be ≥ 1")
    t_start = time.perf_counter()
    X = workspace_inputs(samples, seed, prm, tension_range, pressure_range, common_tensions)
    tasks = []
    for mode in MODES:
        for s in range(0, samples, chunk_size):
            tasks.append({"mode": mode, "start": s, "X": X[mode][s:s + chunk_size], "params": prm,
                          "warm_start": warm_start, "fk_kwargs": fk_kwargs})
    results, backend, nworkers = _run_tasks(tasks, workers, scheduler, progress, {m: samples for m in MODES},
                                            start_method)
    wall = time.perf_counter() - t_start
    tips = {mode: np.full((samples, 3), np.nan) for mode in MODES}
    iters = {mode: np.zeros(samples, np.int64) for mode in MODES}
    errors: dict[str, list] = {mode: [] for mode in MODES}
    busy = cpu = 0.0
    for r in results:
        s = r["start"]
        tips[r["mode"]][s:s + len(r["tips"])] = r["tips"]
        iters[r["mode"]][s:s + len(r["tips"])] = r["iterations"]
        errors[r["mode"]] += [(s + i, msg) for i, msg in r["errors"]]
        busy += r["seconds"]
        cpu += r["cpu_seconds"]
    res: dict[str, Any] = {"study": "workspace (paper Sec. IV-A, Fig. 4)", "preset": prm.name,
                           "samples": samples, "seed": seed, "common_tensions": common_tensions,
                           "modes": {}, "clouds": {}}
    for mode in MODES:
        ok = np.all(np.isfinite(tips[mode]), axis=1)
        P = tips[mode][ok]
        errs = sorted(errors[mode])
        vol = hull_volume(P)
        conv = {f"volume_first_{n}_m3": hull_volume(tips[mode][:n][ok[:n]])
                for n in sorted({max(4, samples // 4), max(4, samples // 2)}) if n < samples}
        nverts = 0
        if vol > 0:
            from scipy.spatial import ConvexHull
            nverts = len(ConvexHull(P).vertices)
        res["modes"][mode] = {
            "samples": samples, "solved": int(ok.sum()), "failures": int((~ok).sum()),
            "failed_indices": [i for i, _ in errs], "failed_inputs": X[mode][~ok],
            "first_errors": [msg for _, msg in errs[:5]],
            "volume_m3": vol, "volume_cm3": vol * 1e6, "hull_vertices": nverts,
            "bbox_min_m": P.min(axis=0) if len(P) else None, "bbox_max_m": P.max(axis=0) if len(P) else None,
            "mean_fk_iterations": float(iters[mode][ok].mean()) if ok.any() else None,
            "convergence": conv,
        }
        res["clouds"][mode] = {"inputs": X[mode], "tips": tips[mode], "ok": ok}
    v_td, v_tphd = res["modes"]["TD"]["volume_m3"], res["modes"]["TPHD"]["volume_m3"]
    ratio = v_tphd / v_td if v_td > 0 else float("nan")
    P_td = tips["TD"][res["clouds"]["TD"]["ok"]]
    P_tphd = tips["TPHD"][res["clouds"]["TPHD"]["ok"]]
    if v_tphd > 0 and len(P_td):
        dist = hull_distance(P_td, P_tphd)
        inside, max_out = float(np.mean(dist <= 1e-12)), float(max(dist.max(), 0.0))
    else:
        inside, max_out = float("nan"), float("nan")
    res.update(volume_td_m3=v_td, volume_tphd_m3=v_tphd, ratio=ratio, increase_percent=(ratio - 1) * 100,
               paper_increase_percent=PAPER["workspace"]["increase_percent"],
               failures=res["modes"]["TD"]["failures"] + res["modes"]["TPHD"]["failures"],
               inside_fraction=inside, max_td_outside_tphd_hull_m=max_out,
               timing={"wall_s": wall, "worker_busy_s": busy, "worker_cpu_s": cpu,
                       "per_sample_ms": busy / (2 * samples) * 1e3, "per_sample_cpu_ms": cpu / (2 * samples) * 1e3,
                       "backend": backend, "workers": nworkers, "chunk_size": chunk_size,
                       "warm_start": warm_start})
    if out is not None:
        out = pathlib.Path(out)
        out.mkdir(parents=True, exist_ok=True)
        npz = out / "workspace_clouds.npz"
        np.savez_compressed(npz, **{f"{mode.lower()}_{k}": v for mode in MODES
                                    for k, v in res["clouds"][mode].items()},
                            columns=np.array([f"T{i + 1}_N" for i in range(prm.n_tendons)] + ["p_Pa"]))
        files = {"clouds": npz}
        if figure:
            files["figures"] = plot_workspace(res, out)
        files["json"] = out / "workspace.json"
        res["files"] = files
        write_json(files["json"], {k: v for k, v in res.items() if k != "clouds"})
    return res


def plot_workspace(res: dict, out: Union[str, pathlib.Path]) -> list[pathlib.Path]:
    """Fig. 4 look-alike: TD (blue) and TPHD (red) tip clouds in 3-D with their hulls, plus side (x–z)
    and front (y–z) views.  Writes workspace.png and workspace.svg (scatter rasterised)."""
    from scipy.spatial import ConvexHull

    plt = _pyplot()
    fig = plt.figure(figsize=(14, 4.8))
    ax3 = fig.add_subplot(1, 3, 1, projection="3d")
    axs = fig.add_subplot(1, 3, 2)
    axf = fig.add_subplot(1, 3, 3)
    style = {"TPHD": ("tab:red", 0.25), "TD": ("tab:blue", 0.5)}
    for mode in ("TPHD", "TD"):
        c = res["clouds"][mode]
        P = c["tips"][c["ok"]] * 1e3
        col, alpha = style[mode]
        v = res["modes"][mode]["volume_cm3"]
        lab = f"{mode}: {v:.1f} cm³ ({len(P)} tips)"
        ax3.scatter(*P.T, s=1, color=col, alpha=alpha, label=lab, rasterized=True, depthshade=False)
        if len(P) >= 4 and res["modes"][mode]["volume_m3"] > 0:
            H = ConvexHull(P)
            ax3.plot_trisurf(P[:, 0], P[:, 1], P[:, 2], triangles=H.simplices, color=col, alpha=0.08,
                             linewidth=0)
            for ax, (i, j) in ((axs, (0, 2)), (axf, (1, 2))):
                H2 = ConvexHull(P[:, [i, j]])
                loop = np.append(H2.vertices, H2.vertices[0])
                ax.plot(P[loop, i], P[loop, j], color=col, lw=1.2)
        axs.scatter(P[:, 0], P[:, 2], s=1, color=col, alpha=alpha, label=lab, rasterized=True)
        axf.scatter(P[:, 1], P[:, 2], s=1, color=col, alpha=alpha, rasterized=True)
    ax3.set_xlabel("x [mm]"), ax3.set_ylabel("y [mm]"), ax3.set_zlabel("z [mm]")
    axs.set_xlabel("x [mm]"), axs.set_ylabel("z [mm]"), axs.set_title("side view (x–z)")
    axf.set_xlabel("y [mm]"), axf.set_ylabel("z [mm]"), axf.set_title("front view (y–z)")
    for a in (axs, axf):
        a.set_aspect("equal", adjustable="datalim")
        a.grid(alpha=0.3)
    axs.legend(loc="best", fontsize=8, markerscale=6)
    fig.suptitle(f"Workspace, {res['samples']} samples per mode: TPHD {res['increase_percent']:+.1f} % vs TD "
                 f"(paper {PAPER['workspace']['increase_percent']:+.1f} %)")
    fig.tight_layout()
    return _save_figure(fig, pathlib.Path(out), "workspace")


def print_workspace(res: dict, console=None) -> None:
    """Rich table: our workspace numbers beside the paper's."""
    from rich.console import Console
    from rich.table import Table

    console = console or Console(width=130)
    t = Table(title="Workspace (Sec. IV-A, Fig. 4): convex-hull volume of the tip cloud")
    for c in ("quantity", "ours", "paper"):
        t.add_column(c, justify="left" if c == "quantity" else "right")
    md = res["modes"]
    t.add_row("samples per mode", f"{res['samples']:,}", f"{PAPER['workspace']['samples_per_mode']:,}")
    for mode in MODES:
        t.add_row(f"{mode} volume (cm³)", f"{md[mode]['volume_cm3']:.2f}", "–")
        t.add_row(f"{mode} failed FK solves", f"{md[mode]['failures']}", "–")
    t.add_row("TPHD vs TD", f"{res['increase_percent']:+.1f} %", f"{PAPER['workspace']['increase_percent']:+.1f} %")
    t.add_row("TD tips inside TPHD hull", f"{res['inside_fraction'] * 100:.1f} %", "–")
    tm = res["timing"]
    t.add_row("wall time (s)", f"{tm['wall_s']:.1f} ({tm['backend']}, {tm['workers']} workers)", "–")
    t.add_row("time per FK (ms, worker wall / CPU)",
              f"{tm['per_sample_ms']:.2f} / {tm.get('per_sample_cpu_ms', float('nan')):.2f}", "–")
    console.print(t)


# ============================================================================== stiffness vs T1
def stiffness_vs_tension(pressures: Sequence[float] = (0.0, 25e3, 50e3),
                         tensions: Sequence[float] = (0, 1, 2, 3, 4, 5), mass: float = 0.05,
                         out: Union[str, pathlib.Path, None] = None, *,
                         params: Union[str, ActuatorParams, None] = None, tendon: int = 0,
                         methods: Sequence[str] = cp.METHODS, constraint_weight: float = 1.0,
                         figure: bool = True) -> dict:
    """Tip stiffness along z under a payload ``mass`` [kg] vs the tension of ``tendon`` (paper Sec. V-C,
    Fig. 9), at constant tension and with locked tendon lengths, nonlinear (secant) and linear (tangent).

    Returns ``{"rows": [...], "curves": {name: (n_p, n_T) [N/m]}, "ratio": ..., "summary": ...}``;
    curve names: ``constant_nonlinear``, ``locked_nonlinear``, ``constant_linear``,
    ``locked_linear_<method>``.  Failed solves give NaN and are counted in ``failures``.
    """
    prm = _params(params)
    model = Model(prm)
    W = mass * G
    F = np.array([0.0, 0.0, -W])
    ez = np.array([0.0, 0.0, 1.0])
    pressures = [float(p) for p in pressures]
    tensions = [float(t) for t in tensions]
    names = ["constant_nonlinear", "locked_nonlinear", "constant_linear"] + [f"locked_linear_{m}" for m in methods]
    curves = {n: np.full((len(pressures), len(tensions)), np.nan) for n in names}
    rows, failures = [], []
    t0 = time.perf_counter()
    for ip, p in enumerate(pressures):
        q_prev = None
        for it, T1 in enumerate(tensions):
            T = np.zeros(model.m)
            T[tendon] = T1
            row: dict[str, Any] = {"pressure_Pa": p, "tension_N": T1, "tensions_N": T}
            try:
                eq0 = model.fk(T, p, (0, 0, 0), q0=q_prev)
            except BellowsError as exc:
                failures.append({"pressure_Pa": p, "tension_N": T1, "solve": "fk unloaded", "error": str(exc)})
                rows.append(row)
                continue
            q_prev = eq0.q
            row["tip_unloaded_m"] = eq0.tip
            z0 = eq0.tip[2]
            try:
                eqc = model.fk(T, p, F, q0=eq0.q)
                row["tip_loaded_constant_m"] = eqc.tip
                curves["constant_nonlinear"][ip, it] = W / (z0 - eqc.tip[2])
            except BellowsError as exc:
                failures.append({"pressure_Pa": p, "tension_N": T1, "solve": "fk loaded", "error": str(exc)})
            try:
                lk = model.fk_locked(eq0.tendon_lengths, p, F, q0=eq0.q, tensions0=eq0.tensions)
                row["tip_loaded_locked_m"] = lk.tip
                row["locked_tensions_N"] = lk.tensions
                row["locked_active"] = list(lk.active)
                curves["locked_nonlinear"][ip, it] = W / (z0 - lk.tip[2])
            except BellowsError as exc:
                failures.append({"pressure_Pa": p, "tension_N": T1, "solve": "fk_locked", "error": str(exc)})
            curves["constant_linear"][ip, it] = cp.directional_stiffness(cp.tension(model, eq0).C_p, ez)
            for meth in methods:
                try:
                    c = cp.locked(model, eq0, method=meth, load_direction=F, constraint_weight=constraint_weight)
                    curves[f"locked_linear_{meth}"][ip, it] = cp.directional_stiffness(c.C_p, ez)
                    row[f"active_{meth}"] = list(c.active)
                except BellowsError as exc:
                    failures.append({"pressure_Pa": p, "tension_N": T1, "solve": f"locked {meth}",
                                     "error": str(exc)})
            for n in names:
                row[f"k_{n}_N_per_m"] = curves[n][ip, it]
            rows.append(row)
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio_nl = curves["locked_nonlinear"] / curves["constant_nonlinear"]
        ratio_lin = {m: curves[f"locked_linear_{m}"] / curves["constant_linear"] for m in methods}
        secant_vs_tangent = {
            "constant": curves["constant_nonlinear"] / curves["constant_linear"] - 1,
            "locked": (curves["locked_nonlinear"] / curves["locked_linear_exact"] - 1
                       if "exact" in methods else None)}
    res = {
        "study": "stiffness vs T1, constant tension vs locked tendons (paper Sec. V-C, Fig. 9)",
        "preset": prm.name, "pressures_Pa": pressures, "tensions_N": tensions, "tendon": tendon,
        "mass_kg": mass, "payload_N": W, "methods": list(methods), "constraint_weight": constraint_weight,
        "rows": rows, "curves_N_per_m": curves,
        "ratio_locked_over_constant": {"nonlinear": ratio_nl, **{f"linear_{m}": r for m, r in ratio_lin.items()}},
        "secant_over_tangent_minus_1": secant_vs_tangent,
        "summary": {
            "mean_ratio_nonlinear": float(np.nanmean(ratio_nl)),
            "per_pressure_mean_ratio_nonlinear": {f"{p / 1e3:g} kPa": float(np.nanmean(ratio_nl[i]))
                                                  for i, p in enumerate(pressures)},
            **{f"mean_ratio_linear_{m}": float(np.nanmean(r)) for m, r in ratio_lin.items()},
            "paper_ratio": PAPER["stiffness"]["locked_over_constant"],
        },
        "failures": len(failures), "failure_details": failures,
        "timing": {"wall_s": time.perf_counter() - t0},
    }
    if out is not None:
        out = pathlib.Path(out)
        files = {}
        if figure:
            files["figures"] = plot_stiffness(res, out)
        files["json"] = out / "stiffness.json"
        res["files"] = files
        write_json(files["json"], res)
    return res


def plot_stiffness(res: dict, out: Union[str, pathlib.Path]) -> list[pathlib.Path]:
    """Fig. 9 look-alike: one panel per pressure, k vs T1, constant tension vs locked."""
    plt = _pyplot()
    P = res["pressures_Pa"]
    T = np.asarray(res["tensions_N"])
    cv = res["curves_N_per_m"]
    fig, axes = plt.subplots(1, len(P), figsize=(4.6 * len(P), 4.0), sharey=True, squeeze=False)
    style = {"locked_linear_exact": ("tab:red", "-", "locked, linear (exact KKT)"),
             "locked_linear_paper": ("tab:orange", "--", "locked, linear (paper eq. 13)"),
             "locked_linear_ik": ("tab:purple", ":", "locked, linear (IK eq. 15)"),
             "constant_linear": ("tab:blue", "-", "constant tension, linear")}
    for i, p in enumerate(P):
        ax = axes[0, i]
        for name, (col, ls, lab) in style.items():
            if name in cv:
                ax.plot(T, cv[name][i], color=col, ls=ls, lw=1.6, label=lab)
        ax.plot(T, cv["locked_nonlinear"][i], "o", color="tab:red", mfc="none", label="locked, nonlinear FK")
        ax.plot(T, cv["constant_nonlinear"][i], "s", color="tab:blue", mfc="none",
                label="constant tension, nonlinear FK")
        ax.set_title(f"p = {p / 1e3:g} kPa")
        ax.set_xlabel(f"T{res['tendon'] + 1} [N]")
        ax.grid(alpha=0.3)
    axes[0, 0].set_ylabel("k_equivalent = m g / (z_unload − z_load) [N/m]")
    axes[0, 0].set_ylim(bottom=0)
    axes[0, -1].legend(fontsize=7, loc="best")
    fig.suptitle(f"Tip stiffness along z, {res['mass_kg'] * 1e3:g} g payload: locked / constant = "
                 f"{res['summary']['mean_ratio_nonlinear']:.2f} (paper: about 2)")
    fig.tight_layout()
    return _save_figure(fig, pathlib.Path(out), "stiffness")


def print_stiffness(res: dict, console=None) -> None:
    from rich.console import Console
    from rich.table import Table

    console = console or Console(width=130)
    cv = res["curves_N_per_m"]
    t = Table(title=f"Stiffness along z, {res['mass_kg'] * 1e3:g} g payload (Sec. V-C, Fig. 9), k in N/m")
    cols = ["p (kPa)", f"T{res['tendon'] + 1} (N)", "const NL", "const lin", "locked NL", "locked exact"]
    cols += [f"locked {m}" for m in res["methods"] if m != "exact"]
    cols += ["locked/const NL", "paper"]
    for c in cols:
        t.add_column(c, justify="right")
    ratio = res["ratio_locked_over_constant"]["nonlinear"]
    for i, p in enumerate(res["pressures_Pa"]):
        for j, T1 in enumerate(res["tensions_N"]):
            vals = [cv["constant_nonlinear"][i, j], cv["constant_linear"][i, j], cv["locked_nonlinear"][i, j],
                    cv.get("locked_linear_exact", np.full_like(ratio, np.nan))[i, j]]
            vals += [cv[f"locked_linear_{m}"][i, j] for m in res["methods"] if m != "exact"]
            t.add_row(f"{p / 1e3:g}", f"{T1:g}", *[f"{v:.1f}" for v in vals], f"{ratio[i, j]:.2f}", "≈ 2")
    console.print(t)
    s = res["summary"]
    console.print(f"mean locked/constant ratio: nonlinear {s['mean_ratio_nonlinear']:.2f}, "
                  + ", ".join(f"linear {m} {s[f'mean_ratio_linear_{m}']:.2f}" for m in res["methods"])
                  + f"; paper: about {s['paper_ratio']:g}.  Failed solves: {res['failures']}.")


# ============================================================================== controller studies
def _control_studies():
    import importlib
    import importlib.util

    name = f"{__package__ or 'validation'}.control_studies"
    if importlib.util.find_spec(name) is None:
        raise StudyUnavailableError(
            "the controller studies (Table I, compliance ablation, continuous/cyclic loading) live in "
            "validation/control_studies.py, which is not available in this installation yet")
    return importlib.import_module(name)  # errors inside that module propagate unchanged


def _call_study(name: str, kw: dict) -> dict:
    """Call ``control_studies.<name>(**kw)``; ``out`` is passed only if that function takes it (the
    wrappers here always offer it), every other keyword unchanged (a typo fails loudly there)."""
    fn: Callable = getattr(_control_studies(), name, None)
    if fn is None:
        raise StudyUnavailableError(f"validation.control_studies has no function {name}()")
    if "out" in kw:
        try:
            params = inspect.signature(fn).parameters
            if "out" not in params and not any(p.kind is p.VAR_KEYWORD for p in params.values()):
                kw = {k: v for k, v in kw.items() if k != "out"}
        except (TypeError, ValueError):
            pass
    return fn(**kw)


def table1(**kw) -> dict:
    """Table I (Sec. IV-B): VF-CC vs LACC residual errors after five iterations, keyed by configuration
    (forwards to :func:`validation.control_studies.table1`)."""
    return _call_study("table1", kw)


def compliance_ablation(**kw) -> dict:
    """FK- vs IK-derived compliance in the LACC loop (paper: IK-derived converges ≈ 50 % faster)."""
    return _call_study("compliance_ablation", kw)


def loading(**kw) -> dict:
    """Continuous (0 → 110 g → 0 over 50 s) and cyclic (0.125 Hz) loading (Sec. V-E)."""
    return _call_study("loading", kw)


CONTROL_STUDIES = {"table1": table1, "ablation": compliance_ablation, "loading": loading}
#: JSON file of each controller study in the output folder (the names control_studies itself writes).
CONTROL_FILES = {"table1": "table1.json", "ablation": "compliance_ablation.json", "loading": "loading.json"}


def print_control_study(name: str, res: dict, console=None) -> None:
    """Best-effort table of a controller study's scalar results beside the paper's (the result layout
    belongs to :mod:`validation.control_studies`)."""
    from rich.console import Console
    from rich.markup import escape
    from rich.table import Table

    console = console or Console(width=130)
    paper = PAPER.get(name, {})
    if isinstance(res.get("table"), str):     # the study's own comparison table (ours beside the paper's)
        console.print(f"[bold]{escape(name)}[/bold] (controller study)")
        console.print(escape(res["table"]), highlight=False)
        return
    t = Table(title=f"{name} (controller study)")
    t.add_column("result", justify="left")
    t.add_column("ours", justify="right")
    t.add_column("paper", justify="right")

    def walk(prefix, d, pp):
        for k, v in d.items():
            key = f"{prefix}{k}"
            pv = pp.get(k) if isinstance(pp, dict) else None
            if isinstance(v, dict):
                walk(key + ".", v, pv if isinstance(pv, dict) else {})
            elif isinstance(v, (int, float, np.floating, np.integer)) and not isinstance(v, bool):
                t.add_row(escape(key), f"{float(v):.6g}", "" if pv is None or isinstance(pv, dict) else f"{pv:g}")
    walk("", res, paper)
    console.print(t)
    if paper:
        console.print(escape(f"paper: {json.dumps(to_jsonable(paper))}"))


# ============================================================================== everything
def run_all(out: Union[str, pathlib.Path] = "bellows_out/paper", *, samples: int = 10_000, seed: int = 0,
            workers: Optional[int] = None, scheduler=None, progress: bool = True,
            console=None) -> dict:
    """Run every study into ``out``; controller studies that are unavailable are reported as skipped.
    Returns ``{study: result or {"skipped": reason}}`` and writes ``summary.json``."""
    from rich.markup import escape

    out = pathlib.Path(out)
    results: dict[str, Any] = {}
    ws = workspace(samples=samples, seed=seed, workers=workers, scheduler=scheduler, out=out, progress=progress)
    results["workspace"] = {k: v for k, v in ws.items() if k != "clouds"}
    if console is not None:
        print_workspace(ws, console)
    st = stiffness_vs_tension(out=out)
    results["stiffness"] = st
    if console is not None:
        print_stiffness(st, console)
    for name, fn in CONTROL_STUDIES.items():
        try:
            r = fn(out=out)
            results[name] = r
            write_json(out / CONTROL_FILES[name], r)
            if console is not None:
                print_control_study(name, r, console)
        except StudyUnavailableError as exc:
            results[name] = {"skipped": str(exc)}
            if console is not None:
                console.print(f"[yellow]{name}: skipped — {escape(str(exc))}[/yellow]")
    summary = {
        "workspace": {k: results["workspace"][k] for k in ("volume_td_m3", "volume_tphd_m3", "ratio",
                                                            "increase_percent", "failures", "samples")},
        "stiffness": st["summary"],
        **{n: ("skipped" if isinstance(results[n], dict) and "skipped" in results[n] else "done")
           for n in CONTROL_STUDIES},
    }
    write_json(out / "summary.json", summary)
    results["summary"] = summary
    return results
