r"""Tendon friction in the validation: tension cycles of the FEM and of the identified rod, both branches.

A design with tendon friction μ > 0 (:func:`validation.reference.designs.design_friction`, or ``bellows report
--tendon-friction μ``) is checked on quasi-static *tension cycles*: tendon 1 pulled 0 → T → 0 in ``s`` equal steps
per branch, every other tendon slack, at a few pressures (:func:`cycle_plan`):

* T = :data:`PEAK_FRACTION` × the design's ``tension_max`` (3 N of the ``paper`` design's 5 N);
* the full report: p = 0, ½ and 1 × ``pressure_max``, :data:`STEPS_FULL` steps per branch; ``quick``: ½ ×
  ``pressure_max`` only, :data:`STEPS_QUICK` steps.

**The FEM** solves each cycle with the capstan law at its guides and the design's μ
(:meth:`fem_reference.BellowsModel.tension_cycle`, gravity as the design is mounted), one cycle per task through
:func:`validation.infra.runner.run_tasks` and its on-disk cache (keyed like the load cases: the design, the mesh,
:func:`validation.reference.fem_sweep.fem_fingerprint`, and the cycle's loads and μ).

**μ of the rod** (:func:`fit_mu`).  The identified actuator gets the μ that makes its own cycle reproduce the
*hysteresis* of the FEM's tool points on the ½ p_max cycle: the gap between the branches at each tension,

    g_k = x_unloading(T_k) − x_loading(T_k)      (k = 0 … s − 1, the tensions below the peak, where g_s ≡ 0),

by Gauss–Newton on μ, every other parameter held (∂g/∂μ by central differences, as
:func:`validation.identification.friction.fit_tension_cycle` does with the tool points themselves), the 95 %
interval from the curvature JᵀJ and the residual scale (Student's t, 3 s − 1 degrees of freedom).  The gap, not the
points: the frictionless part of the response (a static offset, a stiffness a few % off) is the same on both
branches and drops out of g, while a fit to the points lets μ take it up — on the ``paper`` design's quick report
the rod is 1.7 % softer than the FEM under tendon 1, and the points gave μ = 0.31 for the FEM's 0.2 and a loop 1.4 ×
the FEM's.  The 0 and p_max cycles are not used for μ and *validate* it.  The quick report has one cycle only: its μ is fitted to that cycle and its numbers are in-sample (the section
says so).  Where the FEM's fit cycle failed, the rod takes the design's μ.

**The comparison** per cycle (:func:`compare_cycle`), both models over the same 2 s + 1 states:

* tip error per branch: |x_rod − x_FEM| / L [% of L], mean and max over the loading branch (0 … T) and over the
  unloading branch (T … 0), against :data:`TIP_TARGET_PCT` on the mean;
* loop area A: each model's own ``loop_area`` — the shoelace area of the closed polygon (T_j, u_j), T_j the tendon
  tension and u_j the tip displacement from the start along the loading direction (start → peak) of *that* model
  (as :meth:`ancf.Model.tension_cycle` and the FEM's ``tension_cycle`` define it); the ratio A_rod / A_FEM against
  1 ± :data:`LOOP_TARGET_PCT` %.

A cycle passes when both branches' mean tip errors and the loop ratio are within their targets; the check fails
when a cycle not used for μ fails (the FEM is taken as exact here: its discretisation error is not estimated for
the cycles).  SI inside; the dicts state their units in their keys (``_N``, ``_kPa``, ``_mm``, ``_Nmm``, ``_pct``).
"""

from __future__ import annotations

import math
import time
from typing import Any, Callable, Optional

import numpy as np

from ancf.errors import BellowsError, InputError
from ancf.params import TENDON_FRICTION_MAX

__all__ = ["check_friction", "friction_check", "cycle_plan", "fem_cycle_task", "run_fem_cycles", "rod_cycle",
           "compare_cycle", "verdict", "fit_mu", "branch_gap", "LOOP_TARGET_PCT", "TIP_TARGET_PCT", "PEAK_FRACTION", "STEPS_FULL",
           "STEPS_QUICK"]

#: loop area: |A_rod / A_FEM − 1| ≤ this [%]
LOOP_TARGET_PCT = 15.0
#: tip error, mean over a branch, ≤ this [% of L]
TIP_TARGET_PCT = 2.5
#: the cycle's peak tension on tendon 1 as a share of the design's tension_max
PEAK_FRACTION = 0.6
#: steps per branch of a cycle: the full report, the quick one
STEPS_FULL, STEPS_QUICK = 6, 4
#: pressures of the cycles as shares of pressure_max: the full report, the quick one; the one μ is fitted to
FULL_PRESSURES, QUICK_PRESSURES, FIT_PRESSURE = (0.0, 0.5, 1.0), (0.5,), 0.5
#: the cache entry's format (raise when fem_cycle_task's result changes)
CYCLE_FORMAT = 1


def check_friction(mu, name: str = "tendon_friction") -> float:
    """``mu`` as a float when it is a finite number in 0 … 1 (as ``ActuatorParams.tendon_friction``); InputError
    naming ``name`` otherwise."""
    if isinstance(mu, bool) or not isinstance(mu, (int, float, np.floating, np.integer)) \
            or not (math.isfinite(mu) and 0.0 <= mu <= TENDON_FRICTION_MAX):
        raise InputError(f"{name} must be a friction coefficient μ in 0 … {TENDON_FRICTION_MAX:g}, got {mu!r}")
    return float(mu)


def cycle_plan(limits: dict, n_tendons: int, quick: bool) -> dict:
    """The cycles of the check (module docstring): {"peak_N" (m,) [N], "pressures_Pa" [Pa], "steps", "fit_index"
    (the cycle μ is fitted to), "in_sample" (True: only one cycle, μ fitted to it)}; ``limits`` the design's
    {"tension_max": N, "pressure_max": Pa}."""
    peak = [0.0] * int(n_tendons)
    peak[0] = PEAK_FRACTION * float(limits["tension_max"])
    shares = QUICK_PRESSURES if quick else FULL_PRESSURES
    return {"peak_N": peak, "pressures_Pa": [f * float(limits["pressure_max"]) for f in shares],
            "steps": STEPS_QUICK if quick else STEPS_FULL, "fit_index": shares.index(FIT_PRESSURE),
            "in_sample": len(shares) == 1}


# ------------------------------------------------------------------------------------------------ the FEM
def fem_cycle_task(task: dict) -> dict:
    """Worker: the FEM's tension cycle of ``task`` (spec, peak_N, pressure_Pa, steps, mu) → {"pressure_Pa",
    "scale" (2 s + 1,), "tip" (2 s + 1, 3) [m], "loop_area" [N m], "seconds", "error" ('' or the failure)}."""
    from validation.reference.fem_sweep import fem_model
    return _cycle_record(task["pressure_Pa"], lambda: fem_model(task["spec"]).tension_cycle(
        task["peak_N"], task["pressure_Pa"], steps=task["steps"], friction=task["mu"], gravity=True))


def _cycle_record(pressure: float, run) -> dict:
    """The result dict of :func:`fem_cycle_task` from ``run()`` (a tension cycle of the FEM or the rod), timed; a
    :class:`~ancf.errors.BellowsError` it raises becomes the record's ``error``."""
    t0 = time.perf_counter()
    out = {"pressure_Pa": float(pressure), "scale": None, "tip": None, "loop_area": None, "error": ""}
    try:
        cyc = run()
    except BellowsError as exc:
        out["error"] = f"{type(exc).__name__}: {exc}"
    else:
        out.update(scale=np.asarray(cyc.scale, float), tip=np.asarray(cyc.tip, float), loop_area=float(cyc.loop_area))
    out["seconds"] = time.perf_counter() - t0
    return out


def run_fem_cycles(spec, plan: dict, mu: float, *, workers=None, scheduler=None, cache_dir=None,
                   progress: bool = True) -> list:
    """:func:`fem_cycle_task` for every pressure of ``plan`` (:func:`cycle_plan`) with friction ``mu``, in
    parallel, each cached in ``cache_dir`` (None: no cache); one result dict per pressure, in plan order."""
    from validation.infra.runner import ResultCache, run_tasks
    from validation.reference.fem_sweep import fem_fingerprint
    tasks = [{"spec": spec, "peak_N": list(plan["peak_N"]), "pressure_Pa": float(p), "steps": int(plan["steps"]),
              "mu": float(mu)} for p in plan["pressures_Pa"]]
    cache = None if cache_dir is None else ResultCache(cache_dir, version=fem_fingerprint())

    def key(t):
        return {**t["spec"].key(), "kind": "tension_cycle", "format": CYCLE_FORMAT,
                **{k: t[k] for k in ("peak_N", "pressure_Pa", "steps", "mu")}}
    return list(run_tasks(fem_cycle_task, tasks, workers=workers, scheduler=scheduler, progress=progress,
                          description=f"FEM tension cycles ({spec.mesh} mesh, μ = {mu:g})", cache=cache,
                          key_inputs=key).results)


# ------------------------------------------------------------------------------------------------ the rod
def rod_model(params, gravity):
    """The rod of ``params`` under the design's ``gravity`` (3,) [m/s²]."""
    from ancf import Model
    return Model(params.replace(gravity=tuple(float(g) for g in gravity)))


def rod_cycle(model, plan: dict, pressure: float, mu: float) -> dict:
    """The rod's cycle of ``plan`` at ``pressure`` [Pa] with friction ``mu`` (:meth:`ancf.Model.tension_cycle`),
    in the form of :func:`fem_cycle_task`'s result."""
    from ancf import Model
    return _cycle_record(pressure, lambda: Model(model.params.replace(tendon_friction=float(mu))).tension_cycle(
        plan["peak_N"], pressure, steps=plan["steps"]))


def branch_gap(tip) -> np.ndarray:
    """g (s, 3) [m]: unloading − loading tool point at each tension below the peak of a cycle's ``tip``
    (2 s + 1, 3) (module docstring)."""
    tip = np.asarray(tip, float)
    s = (len(tip) - 1) // 2
    return (tip[s:][::-1] - tip[:s + 1])[:s]


def _rod_gap(model, plan: dict, pressure: float, mu: float) -> np.ndarray:
    from ancf import Model
    m = Model(model.params.replace(tendon_friction=float(mu)))
    return branch_gap(m.tension_cycle(plan["peak_N"], pressure, steps=plan["steps"]).tip).ravel()


def fit_mu(model, plan: dict, fem: dict, mu0: float, max_iter: int = 12) -> dict:
    """μ of the rod ``model`` (gravity set) fitted to the branch gap of the FEM cycle ``fem`` (module docstring):
    {"mu", "interval" [low, high], "std", "basis", "residual_rms_mm" (of the gap), "pressure_kPa", "states" (the
    gaps used)}.  ConvergenceError when Gauss–Newton does not settle; InputError when the gap does not depend on μ."""
    from scipy import stats
    from ancf.errors import ConvergenceError
    g = branch_gap(fem["tip"]).ravel()
    p = fem["pressure_Pa"]
    mu = min(max(float(mu0), 1e-3), TENDON_FRICTION_MAX)
    for _ in range(max_iter):
        h = 1e-3 * max(mu, 0.01)
        J = (_rod_gap(model, plan, p, mu + h) - _rod_gap(model, plan, p, mu - h)) / (2 * h)
        jj = float(J @ J)
        if jj == 0:
            raise InputError("the rod's branch gap does not depend on μ (no tension cycle?)")
        new = mu + float(J @ (g - _rod_gap(model, plan, p, mu))) / jj
        new = min(max(new, 0.5 * mu), min(2 * mu, TENDON_FRICTION_MAX))
        done, mu = abs(new - mu) < 1e-6 * max(mu, 1e-3), new
        if done:
            break
    else:
        raise ConvergenceError("the μ fit to the FEM cycle's branch gap did not converge", solver="fit_mu",
                               iterations=max_iter, residual_norm=float("nan"), tolerance=1e-6)
    r = g - _rod_gap(model, plan, p, mu)
    n = r.size
    sd = math.sqrt(float(r @ r) / (n - 1) / jj)
    q = float(stats.t.ppf(0.975, n - 1))
    return {"mu": mu, "interval": [mu - q * sd, mu + q * sd], "std": sd, "basis": "residuals",
            "residual_rms_mm": 1e3 * float(np.sqrt(np.mean(r ** 2))), "pressure_kPa": p / 1e3, "states": n // 3}


# ------------------------------------------------------------------------------------------------ comparison
def _displacement(tip: np.ndarray, origin: np.ndarray, direction: np.ndarray) -> np.ndarray:
    return (tip - origin) @ direction


def compare_cycle(rod: dict, fem: dict, length: float, peak_N: float) -> dict:
    """One cycle's row (module docstring): pressure_kPa, tension_N (2 s + 1,), the tip displacements u_rod_mm /
    u_fem_mm along the FEM's loading direction from the FEM's start [mm], loop_rod_Nmm, loop_fem_Nmm, loop_ratio,
    loop_error_pct, tip_{loading,unloading}_{mean,max}_pct [% of L], passes, error ('' or why not compared)."""
    row = {"pressure_kPa": fem["pressure_Pa"] / 1e3, "error": ""}
    bad = [f"{who}: {r['error']}" for who, r in (("FEM", fem), ("rod", rod)) if r.get("error")]
    if bad:
        row.update(error="; ".join(bad), passes=None)
        return row
    tr, tf = np.asarray(rod["tip"], float), np.asarray(fem["tip"], float)
    s = (len(tf) - 1) // 2
    d = tf[s] - tf[0]
    e = d / np.linalg.norm(d) if np.linalg.norm(d) > 0 else d
    dist = np.linalg.norm(tr - tf, axis=1) / length * 100.0
    ratio = rod["loop_area"] / fem["loop_area"] if fem["loop_area"] > 0 else float("nan")
    row.update(tension_N=(np.asarray(fem["scale"]) * peak_N).tolist(),
               u_rod_mm=(1e3 * _displacement(tr, tf[0], e)).tolist(), u_fem_mm=(1e3 * _displacement(tf, tf[0], e)).tolist(),
               loop_rod_Nmm=1e3 * rod["loop_area"], loop_fem_Nmm=1e3 * fem["loop_area"], loop_ratio=ratio,
               loop_error_pct=abs(ratio - 1.0) * 100.0,
               tip_loading_mean_pct=float(dist[:s + 1].mean()), tip_loading_max_pct=float(dist[:s + 1].max()),
               tip_unloading_mean_pct=float(dist[s:].mean()), tip_unloading_max_pct=float(dist[s:].max()))
    row["passes"] = bool(row["loop_error_pct"] <= LOOP_TARGET_PCT and row["tip_loading_mean_pct"] <= TIP_TARGET_PCT
                         and row["tip_unloading_mean_pct"] <= TIP_TARGET_PCT)
    return row


def verdict(rows: list) -> str:
    """"fails" when a judged cycle (role "validation" or "in-sample") fails, "incomplete" when one could not be
    compared and none fails, else "passes"."""
    judged = [r for r in rows if r.get("role") != "fit"]
    if any(r.get("passes") is False for r in judged):
        return "fails"
    if any(r.get("passes") is None for r in judged) or not judged:
        return "incomplete"
    return "passes"


def friction_check(params, spec, limits: dict, mu: float, *, quick: bool, workers=None, scheduler=None,
                   cache_dir=None, log: Optional[Callable[[str], Any]] = None, fem_cycles=None) -> dict:
    """The whole check (module docstring) of the identified actuator ``params`` against the FEM ``spec``
    (:class:`~validation.reference.fem_sweep.FemSpec`, gravity as mounted) with the design's friction ``mu`` (> 0)
    and operating range ``limits``.  ``fem_cycles(spec, plan, mu)``: the FEM's cycles (default
    :func:`run_fem_cycles`).  Returns the dict the report, validation.json and actuator.toml use: mu_design,
    mu_used, mu_source ("identified" | "design"), fit (or None), peak_tensions_N, steps, pressures_kPa,
    in_sample, rows (:func:`compare_cycle` + "role": "fit" | "validation" | "in-sample"), targets, status,
    fem_seconds (this run's wall time [s], ≈ 0 when cached), fem_solve_seconds (the cycles' own solves [s])."""
    log = log or (lambda text: None)
    mu = check_friction(mu)
    if mu == 0:
        raise InputError("friction_check needs a design with tendon friction μ > 0")
    plan = cycle_plan(limits, len(params.tendons), quick)
    log(f"tendon friction μ = {mu:g}: FEM tension cycles 0 → {plan['peak_N'][0]:g} N → 0 on tendon 1 in "
        f"{plan['steps']} steps per branch at {', '.join(f'{p / 1e3:g}' for p in plan['pressures_Pa'])} kPa …")
    t0 = time.perf_counter()
    run = fem_cycles or (lambda sp, pl, m: run_fem_cycles(sp, pl, m, workers=workers, scheduler=scheduler,
                                                           cache_dir=cache_dir))
    fems = list(run(spec, plan, mu))
    fem_s = time.perf_counter() - t0
    log(f"FEM tension cycles: {fem_s:.0f} s")
    model = rod_model(params, spec.gravity)
    fit_fem = fems[plan["fit_index"]]
    fit, used, source = None, mu, "design"
    if not fit_fem["error"]:
        try:
            fit = fit_mu(model, plan, fit_fem, mu)
            used, source = float(fit["mu"]), "identified"
        except BellowsError as exc:
            log(f"μ fit to the FEM's cycle failed ({type(exc).__name__}: {exc}): the rod takes the design's μ")
    rows = []
    for i, fem in enumerate(fems):
        row = compare_cycle(rod_cycle(model, plan, fem["pressure_Pa"], used), fem, params.length, plan["peak_N"][0])
        row["role"] = ("in-sample" if plan["in_sample"] else "fit") if (i == plan["fit_index"] and fit) \
            else "validation"
        rows.append(row)
    return {"mu_design": mu, "mu_used": used, "mu_source": source, "fit": fit, "peak_tensions_N": plan["peak_N"],
            "steps": plan["steps"], "pressures_kPa": [p / 1e3 for p in plan["pressures_Pa"]],
            "in_sample": plan["in_sample"], "rows": rows, "fem_seconds": fem_s, "status": verdict(rows),
            "fem_solve_seconds": float(sum(f.get("seconds") or 0.0 for f in fems)),
            "targets": {"loop_ratio_pct": LOOP_TARGET_PCT, "tip_mean_pct": TIP_TARGET_PCT}}
