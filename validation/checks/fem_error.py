"""The FEM reference's own discretisation error, measured by solving selected load cases on refined meshes,
and the verdict rule that reads the model-vs-FEM errors beside it.

A comparison of the reduced model with the FEM can only resolve model errors larger than the FEM's own
error.  :func:`estimate_fem_error` solves the chosen load cases on the spec's mesh (h) and, for each refinement
direction that matters — ``"along"`` the profile (elements per convolution and per end collar) and
``"through"`` the wall (layers) by default —, on its own mesh refined ``factor``× in that direction only, from
the same base (optionally on a third mesh refined twice, h/4, per direction).  With f a result (the tip
position, the centreline, a tip compliance), Richardson's model f_h = f + C_d h_dᵖ per direction d gives the
error of the default-mesh result due to d

    e_d = (f_h − f_h/2,d) · rᵖ / (rᵖ − 1),        r = factor,

* two meshes: p is *assumed* (:data:`ASSUMED_RATE` = 2 unless given; a lower p gives a larger estimate);
* three meshes: p is *observed*, p = log(‖f_h − f_h/2‖ / ‖f_h/2 − f_h/4‖) / log r from the tip positions.
  When the differences do not fall (p ≤ 0) the results are not converging and no estimate is given.

The directions' leading error terms add, f_h = f + Σ_d C_d h_dᵖ (:func:`combine_directions`), so the error of
the default-mesh result is the vector sum e = Σ_d e_d (tip: a 3-vector; centreline: one per point; compliance:
a 3×3 matrix) and its norm is the estimate; each direction's own number is kept in the rows.  (Measured on the
default bellows at T = (2, 0, 0) N, 30 kPa, coarse mesh: along 4 → 8 moves the tip 0.64 mm, through 2 → 4
layers 0.40 mm in the same direction; around 12 → 24 moves EA and EI by < 0.1 %.)  "Around" is checked once
per call (``check_around``) on the most deformed case: its error is recorded with its number and added — then
measured on every case — only when its tip error exceeds :data:`AROUND_SHARE` of the combined one there.

Per case: the tip error estimate ‖e‖ [m] and in % of the length L, the largest centreline error at
:data:`N_POINTS` points [% of L], and — when the records carry tip compliances — the relative Frobenius error
of each compliance matrix, ‖e_C‖ / ‖C_h‖ [%] (relative to the default-mesh compliance the model is compared
with).  The solves run through :func:`validation.reference.fem_sweep.run_cases` (cached on disk under the
refined mesh level, in parallel, with progress; Ctrl-C keeps the finished cases), one case per task so that
every case is cached on its own.  Each refined solve starts from the same case's equilibrium on the level
below (the records' ``state``, interpolated and its added nodes relaxed: :mod:`fem_reference.transfer`) in
one Newton solve at full load instead of climbing the load path again (measured on the quick report's two
cases: 21 s against 69 s); when that fails it climbs the path from rest as before.  The equilibrium, hence
the estimate, is the same.

:func:`select_cases` chooses the cases with the largest deformation (largest centreline distance from the
straight, unloaded axis).  :func:`assess` gives every held-out state of a validation a FEM error — measured, or
an *estimate* with its basis (tip and shape: the largest FEM error per unit deformation measured, times the
state's own deformation; compliance: the largest measured) — and applies :func:`verdict`: with model error m,
FEM error f and target t a state

    passes      when m + f ≤ t   (within the target whatever the FEM's error),
    fails       when m − f > t   (beyond the target whatever the FEM's error),
    undecided   otherwise        (the FEM's own error straddles the target: a finer FEM mesh decides),

per quantity: tip position and shape (% of L, :data:`validation.checks.compare.SHAPE_TARGET_PCT`), the
tension-held and the locked compliance (%, :data:`validation.checks.compare.COMPLIANCE_TARGET_PCT`).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, replace
from typing import Optional, Sequence

import numpy as np

from ancf.errors import InputError
from ancf.export import to_jsonable

from validation.reference.experiments import LoadCase
from validation.reference.fem_sweep import FemRecord, FemSpec, describe_level, mesh_level, run_cases

__all__ = ["for_validation", "estimate_for_heldout", "QUICK_CASES", "FULL_CASES", "ASSUMED_RATE", "AROUND_SHARE",
           "DEFAULT_DIRECTIONS", "QUANTITIES", "VERDICTS", "FemErrorEstimate", "mesh_level", "refined_level",
           "richardson", "combine_directions", "verdict", "deformation_m", "select_cases", "estimate_fem_error",
           "assess"]

#: convergence rate assumed with two meshes (quadratic elements; the mixed element's displacements converge
#: at a log-log rate above 2 along a curved wall, docs/fem.md §3a)
ASSUMED_RATE = 2.0
#: refinement directions: MeshLevel fields each one multiplies
DIRECTIONS = {"along": ("n_per_conv", "n_collar"), "through": ("n_thick",), "around": ("n_theta",)}
DIRECTION_WORDS = {"along": "along the profile", "through": "through the wall", "around": "around"}
#: the directions refined by default, each on its own mesh from the same base
DEFAULT_DIRECTIONS = ("along", "through")
#: "around" is added to the estimate only when its tip error on the most deformed case exceeds this share of
#: the combined (along + through) tip error there
AROUND_SHARE = 0.25
#: the quantities the verdict rule reads: key → (name, the validation row's / estimate row's key, unit, target)
QUANTITIES = {"tip": ("tip position", "tip_error_pct", "% of L", "shape"),
              "shape": ("shape", "shape_error_pct", "% of L", "shape"),
              "C_tension": ("tension-held compliance", "C_tension_error_pct", "%", "compliance"),
              "C_locked": ("locked compliance", "C_locked_error_pct", "%", "compliance")}
#: the verdicts of :func:`verdict`, best first
VERDICTS = ("passes", "undecided", "fails")
N_POINTS = 17
#: held-out cases measured by the quick and the full report (those with the largest deformation)
QUICK_CASES, FULL_CASES = 1, 4


def refined_level(mesh, factor: int = 2, directions: Sequence[str] = ("along",)):
    """``mesh`` with its element counts in ``directions`` (``"along"`` the profile, ``"through"`` the wall,
    ``"around"``) multiplied by ``factor``."""
    lvl = mesh_level(mesh)
    if not isinstance(factor, (int, np.integer)) or factor < 2:
        raise InputError(f"refinement factor must be an integer >= 2, got {factor!r}")
    bad = [d for d in directions if d not in DIRECTIONS]
    if bad or not directions:
        raise InputError(f"refinement directions {list(directions)}: choose from {sorted(DIRECTIONS)}")
    changes = {f: int(factor) * getattr(lvl, f) for d in directions for f in DIRECTIONS[d]}
    return replace(lvl, **changes)


def richardson(values: Sequence, *, ratio: float = 2.0, rate: Optional[float] = None) -> dict:
    """Richardson estimate of the error of ``values[0]`` (the coarsest) from results on meshes refined by
    ``ratio`` each: 2 values need an assumed ``rate`` (default :data:`ASSUMED_RATE`); with 3 values and
    ``rate=None`` the rate is observed from the norms of the successive differences.

    Returns {"error": e_h (same shape as a value), "norm": ‖e_h‖, "rate": p, "rate_observed": bool,
    "factor": rᵖ/(rᵖ − 1), "differences": [‖f_h − f_h/2‖, …], "converging": bool}; with an observed rate
    p ≤ 0 (differences not falling) "error" and "norm" are None and "converging" is False."""
    vals = [np.asarray(v, float) for v in values]
    if len(vals) not in (2, 3):
        raise InputError(f"richardson needs 2 or 3 values (coarse to fine), got {len(vals)}")
    if any(v.shape != vals[0].shape for v in vals):
        raise InputError("richardson: the values must have one shape")
    if not ratio > 1:
        raise InputError(f"richardson: ratio must be > 1, got {ratio}")
    diffs = [vals[k] - vals[k + 1] for k in range(len(vals) - 1)]
    norms = [float(np.linalg.norm(d)) for d in diffs]
    observed = rate is None and len(vals) == 3
    if observed:
        if norms[1] == 0.0:
            p = math.inf                      # the two finest meshes agree exactly
        elif norms[0] == 0.0:
            p = -math.inf                     # agree on the coarse pair, differ on the fine one
        else:
            p = math.log(norms[0] / norms[1]) / math.log(ratio)
    else:
        p = ASSUMED_RATE if rate is None else float(rate)
        if not p > 0:
            raise InputError(f"richardson: the rate must be > 0, got {rate}")
    out = {"rate": p, "rate_observed": observed, "differences": norms, "converging": bool(p > 0)}
    if not p > 0:
        return {**out, "error": None, "norm": None, "factor": None}
    factor = 1.0 if math.isinf(p) else ratio ** p / (ratio ** p - 1.0)
    err = diffs[0] * factor
    return {**out, "error": err, "norm": float(np.linalg.norm(err)), "factor": factor}


def deformation_m(record: FemRecord) -> float:
    """Largest distance of the FEM centreline from the straight unloaded axis (the x axis of the FEM frame,
    base at the origin) [m]; NaN for a failed record."""
    if not record.ok:
        return float("nan")
    s = np.asarray(record.centreline_s, float)
    straight = np.column_stack([s, np.zeros_like(s), np.zeros_like(s)])
    return float(np.linalg.norm(np.asarray(record.centreline) - straight, axis=1).max())


def select_cases(records: Sequence[FemRecord], n: int) -> list[FemRecord]:
    """The ``n`` solved records with the largest deformation (:func:`deformation_m`), largest first."""
    if n < 1:
        raise InputError(f"select_cases: n must be >= 1, got {n}")
    ok = [r for r in records if r.ok]
    return sorted(ok, key=lambda r: -deformation_m(r))[:n]


@dataclass
class FemErrorEstimate:
    """The measured discretisation error of the FEM results on ``levels[0]`` (SI; see the module docstring).

    rows : one dict per case (label, deformation_m, tip_m per level of the first direction, started_from_coarser
        — per refined mesh, whether its solve started from the level below (:mod:`fem_reference.transfer`) —,
        tip_error_m, tip_error_pct, shape_error_pct, C_tension_error_pct / C_locked_error_pct when compliances were
        solved: the combined estimate; by_direction: {direction: the same numbers of that direction alone, with
        its rate}; rate, rate_observed, error — the failure, if a mesh failed);
    levels : the base mesh, then each direction's refined meshes (a name or element counts); directions :
        {direction: its refined meshes}; method : how the estimate was made, in words; extra["around"] : the
        check around (:func:`estimate_fem_error`'s ``check_around``), extra["seconds_by_direction"].
    """
    rows: list
    length: float
    levels: list
    method: str
    ratio: int = 2
    rate: Optional[float] = None
    seconds: float = 0.0
    extra: dict = field(default_factory=dict)
    directions: dict = field(default_factory=dict)

    def row(self, label: str) -> Optional[dict]:
        return next((r for r in self.rows if r["label"] == label), None)

    def to_dict(self) -> dict:
        tagged = [(lv, None) for lv in self.levels[:1]] + [(lv, d) for d, lvs in self.directions.items() for lv in lvs]
        if not self.directions:
            tagged = [(lv, None) for lv in self.levels]
        return to_jsonable({"rows": self.rows, "length_m": self.length, "levels": [
            {"mesh": lv if isinstance(lv, str) else asdict(mesh_level(lv)), "description": describe_level(lv),
             "direction": d} for lv, d in tagged],
            "method": self.method, "ratio": self.ratio, "rate": self.rate, "seconds": self.seconds,
            "around": self.extra.get("around"), "seconds_by_direction": self.extra.get("seconds_by_direction", {})})


def _direction_error(chain: Sequence[FemRecord], s: np.ndarray, ratio: int, rate, compliance: bool) -> dict:
    """The Richardson error vectors of one direction's chain (base first): tip (3,), centreline (k, 3) and, with
    ``compliance``, each compliance (3, 3) or None — or no "tip" when the chain does not converge."""
    tip = richardson([r.tip_position for r in chain], ratio=ratio, rate=rate)
    out = {"rate": tip["rate"], "rate_observed": tip["rate_observed"], "differences_m": tip["differences"],
           "converging": tip["converging"]}
    if tip["error"] is None:
        return out
    p = tip["rate"]
    out["tip"] = tip["error"]
    out["shape"] = richardson([r.centreline_at(s) for r in chain], ratio=ratio, rate=p)["error"]
    for mode in ("tension", "locked") if compliance else ():
        mats = [getattr(r, f"compliance_{mode}") for r in chain]
        out[f"C_{mode}"] = None if any(m is None for m in mats) else richardson(mats, ratio=ratio, rate=p)["error"]
    return out


def _error_numbers(e: dict, base: FemRecord, L: float) -> dict:
    """Norms of error vectors ``e`` ("tip", "shape", "C_tension", "C_locked") in the rows' units."""
    out = {"tip_error_m": float(np.linalg.norm(e["tip"])), "tip_error_pct": 100.0 * float(np.linalg.norm(e["tip"])) / L,
           "shape_error_pct": 100.0 * float(np.linalg.norm(e["shape"], axis=1).max()) / L}
    for mode in ("tension", "locked"):
        if f"C_{mode}" not in e:
            continue
        C, eC = getattr(base, f"compliance_{mode}"), e[f"C_{mode}"]
        ref = None if C is None else float(np.linalg.norm(C))
        out[f"C_{mode}_error_pct"] = (100.0 * float(np.linalg.norm(eC)) / ref) if eC is not None and ref else None
    return out


def combine_directions(base: FemRecord, refined: dict, *, length: float, ratio: int = 2,
                       rate: Optional[float] = None, compliance: bool = False) -> dict:
    """The FEM error of ``base`` (one case on the base mesh) from its solves on meshes refined in each direction
    on its own: ``refined`` = {direction: [record on h/r, (record on h/r²)]}, all from the same base.

    Per direction d, Richardson (:func:`richardson`, ``rate`` or assumed / observed) gives the error vector e_d
    of the tip (3,), of the centreline at :data:`N_POINTS` points (k, 3) and of each compliance (3, 3); with
    f_h = f + Σ_d C_d h_dᵖ the directions' errors add, e = Σ_d e_d.  Returns {"deformation_m", "tip_error_m",
    "tip_error_pct" (‖e_tip‖, [m] and % of ``length`` L [m]), "shape_error_pct" (max over the points of ‖e‖,
    % of L), "C_<mode>_error_pct" (‖e_C‖/‖C_h‖, %, with ``compliance``), "by_direction": {d: the same numbers of
    e_d alone, with "rate", "rate_observed", "differences_m", "tip_error_vector_m"}, "rate" (the smallest),
    "rate_observed", "error": ""} — or, when a record failed or a direction does not converge, the numbers
    None and "error" saying why."""
    if not refined:
        raise InputError("combine_directions needs at least one refined direction")
    L = float(length)
    s = np.linspace(0.0, L, N_POINTS)
    row = {"deformation_m": deformation_m(base), "by_direction": {}}
    none = {"tip_error_m": None, "tip_error_pct": None, "shape_error_pct": None, "rate": None, "rate_observed": False}
    bad = [f"{d}: {r.error}" for d, recs in refined.items() for r in recs if not r.ok]
    if not base.ok or bad:
        return {**row, **none, "error": "; ".join(([f"base mesh: {base.error}"] if not base.ok else []) + bad)}
    per = {d: _direction_error([base, *recs], s, ratio, rate, compliance) for d, recs in refined.items()}
    stuck = [d for d, e in per.items() if "tip" not in e]
    if stuck:
        return {**row, **none, "error": f"the tip differences do not fall with refinement {', '.join(stuck)} "
                                        "(not converging): no estimate"}
    for d, e in per.items():
        row["by_direction"][d] = {**_error_numbers(e, base, L), "rate": e["rate"], "rate_observed": e["rate_observed"],
                                  "differences_m": e["differences_m"], "tip_error_vector_m": e["tip"]}
    total = {"tip": sum(e["tip"] for e in per.values()), "shape": sum(e["shape"] for e in per.values())}
    for mode in ("tension", "locked") if compliance else ():
        parts = [e.get(f"C_{mode}") for e in per.values()]
        total[f"C_{mode}"] = None if any(p is None for p in parts) else sum(parts)
    row.update(_error_numbers(total, base, L), rate=min(e["rate"] for e in per.values()),
               rate_observed=all(e["rate_observed"] for e in per.values()), converging=True, error="")
    return row


def _solve_directions(spec: FemSpec, cases: list, records: list, directions: Sequence[str], levels: int,
                      factor: int, compliance: bool, kw: dict) -> dict:
    """{direction: (refined meshes, their records per level)} of ``cases`` refined ``factor``× in each of
    ``directions``, each level solved from the level below; the solves of every direction at one level share one
    pool of workers (:func:`run_cases` with one spec per case), so that two directions of one case run side by side."""
    meshes = {d: [] for d in directions}
    per_level = {d: [records] for d in directions}
    for _ in range(levels - 1):
        specs, todo, starts = [], [], []
        for d in directions:
            meshes[d].append(refined_level(meshes[d][-1] if meshes[d] else spec.mesh, factor, (d,)))
            fine = replace(spec, mesh=meshes[d][-1])      # the same design, element and gravity on the finer mesh
            specs += [fine] * len(cases)
            todo += list(cases)
            starts += [r.state if r.ok else None for r in per_level[d][-1]]
        out = run_cases(spec, todo, compliance=bool(compliance), starts=starts, specs=specs, **kw)
        for j, d in enumerate(directions):
            per_level[d].append(out[j * len(cases):(j + 1) * len(cases)])
    return {d: (meshes[d], per_level[d][1:]) for d in directions}


def _solve_direction(spec: FemSpec, cases: list, records: list, direction: str, levels: int, factor: int,
                     compliance: bool, kw: dict) -> tuple[list, list]:
    """(refined meshes, their records per level) of ``cases`` refined ``factor``× in ``direction``."""
    return _solve_directions(spec, cases, records, (direction,), levels, factor, compliance, kw)[direction]


def _rows(cases: list, records: list, chains: dict, L: float, factor: int, rate, compliance: bool) -> list:
    rows = []
    for k, case in enumerate(cases):
        refined = {d: [lvl[k] for lvl in per_level] for d, (_, per_level) in chains.items()}
        first = next(iter(refined.values()))
        row = {"label": case.label, "experiment": case.experiment, "tip_m": [records[k].tip_position]
               + [r.tip_position for r in first],
               "started_from_coarser": [bool(r.extra.get("started_from_other_mesh")) for recs in refined.values()
                                        for r in recs]}
        row.update(combine_directions(records[k], refined, length=L, ratio=factor, rate=rate, compliance=compliance))
        rows.append(row)
    return rows


def _method(base, chains: dict, levels: int, factor: int, rate) -> str:
    per = "; ".join(f"{DIRECTION_WORDS[d]} → {' → '.join(describe_level(m) for m in meshes)}"
                    for d, (meshes, _) in chains.items())
    if levels == 2:
        how = (f"Richardson with an assumed rate p = {ASSUMED_RATE if rate is None else rate:g} per direction: "
               f"e_d = (f_h − f_h/{factor},d) · {factor}ᵖ/({factor}ᵖ − 1)")
    else:
        how = ("Richardson per direction with the " + (
            "observed rate p = log(‖f_h − f_h/2‖/‖f_h/2 − f_h/4‖)/log r of each case's tip" if rate is None
            else f"given rate p = {rate:g}") + ": e_d = (f_h − f_h/r,d) · rᵖ/(rᵖ − 1)")
    return (f"{levels - 1} refined mesh(es) per direction, each {factor}× refined in that direction alone from "
            f"{describe_level(base)}: {per}; {how}; the directions' errors added as vectors, e = Σ_d e_d")


def _check_around(spec, cases, records, rows, factor, rate, compliance, kw) -> tuple[dict, Optional[tuple]]:
    """Solve the most deformed case refined around; returns (the check's record, the chain of every case when
    its error exceeds :data:`AROUND_SHARE` of the combined one, else None)."""
    ok = [k for k, r in enumerate(rows) if r.get("tip_error_m") is not None]
    if not ok:
        return {"checked": False, "why": "no case has an estimate to compare with"}, None
    k = max(ok, key=lambda i: rows[i]["deformation_m"])
    meshes, per_level = _solve_direction(spec, [cases[k]], [records[k]], "around", 2, factor, compliance, kw)
    one = combine_directions(records[k], {"around": [per_level[0][0]]}, length=float(spec.geometry.length),
                             ratio=factor, rate=rate, compliance=compliance)
    check = {"checked": True, "label": cases[k].label, "mesh": describe_level(meshes[0]),
             "share_threshold": AROUND_SHARE, "combined_tip_error_pct": rows[k]["tip_error_pct"]}
    if one.get("tip_error_m") is None:
        return {**check, "tip_error_pct": None, "added": False, "why": one.get("error", "")}, None
    share = one["tip_error_m"] / rows[k]["tip_error_m"] if rows[k]["tip_error_m"] > 0 else math.inf
    check.update(tip_error_pct=one["tip_error_pct"], tip_error_m=one["tip_error_m"], share=share,
                 C_tension_error_pct=one.get("C_tension_error_pct"), C_locked_error_pct=one.get("C_locked_error_pct"),
                 added=bool(share > AROUND_SHARE))
    if not check["added"]:
        return check, None
    return check, _solve_direction(spec, cases, records, "around", 2, factor, compliance, kw)


def estimate_fem_error(spec: FemSpec, cases: Sequence[LoadCase], *, records: Optional[Sequence[FemRecord]] = None,
                       levels: int = 2, factor: int = 2, directions: Sequence[str] = DEFAULT_DIRECTIONS,
                       rate: Optional[float] = None, compliance: Optional[bool] = None, check_around: bool = False,
                       workers: Optional[int] = None, scheduler=None, cache_dir=None,
                       progress: bool = True) -> FemErrorEstimate:
    """Estimate the discretisation error of the FEM results of ``cases`` on ``spec.mesh`` (module docstring).

    records : the results of ``cases`` on ``spec`` if already computed (else solved here, cached);
    levels : 2 (assumed ``rate``, default :data:`ASSUMED_RATE`) or 3 (observed rate unless ``rate`` given) meshes
        per direction; factor : the refinement from one level to the next;
    directions : each refined on its own mesh from the base (:func:`refined_level`), errors combined
        (:func:`combine_directions`);  check_around : solve the most deformed case refined around as well
        (2 meshes) and add "around" to every case when it exceeds :data:`AROUND_SHARE` of the combined error;
    compliance : also solve the tip compliances on the refined meshes (default: when the records have them).
    """
    if levels not in (2, 3):
        raise InputError(f"levels must be 2 or 3, got {levels}")
    if rate is not None and not rate > 0:
        raise InputError(f"rate must be > 0, got {rate}")
    directions = tuple(directions)
    if not directions or len(set(directions)) != len(directions):
        raise InputError(f"refinement directions {list(directions)}: give each of {sorted(DIRECTIONS)} at most once")
    refined_level(spec.mesh, factor, directions)            # checks the factor and the directions' names
    cases = list(cases)
    if not cases or not all(isinstance(c, LoadCase) for c in cases):
        raise InputError("estimate_fem_error needs a non-empty list of validation.reference.experiments.LoadCase")
    import time
    t0 = time.perf_counter()
    kw = dict(workers=workers, scheduler=scheduler, cache_dir=cache_dir, progress=progress, chain_length=1)
    records = list(run_cases(spec, cases, compliance=bool(compliance), **kw) if records is None else records)
    if len(records) != len(cases):
        raise InputError(f"estimate_fem_error: {len(records)} records for {len(cases)} cases")
    if compliance is None:
        compliance = any(r.compliance_tension is not None for r in records)
    t1 = time.perf_counter()
    chains = _solve_directions(spec, cases, records, directions, levels, factor, compliance, kw)
    seconds = {"refined": time.perf_counter() - t1}     # every direction's solves share one pool of workers
    L = float(spec.geometry.length)
    rows = _rows(cases, records, chains, L, factor, rate, compliance)
    extra = {"seconds_by_direction": seconds}
    if check_around and "around" not in directions:
        t1 = time.perf_counter()
        extra["around"], chain = _check_around(spec, cases, records, rows, factor, rate, compliance, kw)
        if chain is not None:
            chains["around"] = chain
            rows = _rows(cases, records, chains, L, factor, rate, compliance)
        seconds["around"] = time.perf_counter() - t1
    meshes = [spec.mesh] + [m for ms, _ in chains.values() for m in ms]
    return FemErrorEstimate(rows, L, meshes, _method(spec.mesh, chains, levels, factor, rate), ratio=factor,
                            rate=(ASSUMED_RATE if rate is None else rate) if levels == 2 or rate is not None else None,
                            seconds=time.perf_counter() - t0, extra=extra,
                            directions={d: ms for d, (ms, _) in chains.items()})


def verdict(model_error: Optional[float], fem_error: float, target: float) -> Optional[str]:
    """The verdict on one state and quantity (module docstring): ``"passes"`` when model error + FEM error ≤
    target, ``"fails"`` when model error − FEM error > target, ``"undecided"`` in between; None when the model
    error is missing or not finite (not checked).  All three in one unit (% of L or %); the FEM error ≥ 0
    (0: the FEM taken as exact, never undecided), the target > 0."""
    if not (isinstance(target, (int, float, np.floating)) and math.isfinite(target) and target > 0):
        raise InputError(f"verdict: the target must be a finite number > 0, got {target!r}")
    if fem_error is None or not (math.isfinite(fem_error) and fem_error >= 0):
        raise InputError(f"verdict: the FEM error must be a finite number >= 0, got {fem_error!r}")
    if model_error is None or not math.isfinite(model_error):
        return None
    if model_error < 0:
        raise InputError(f"verdict: an error is >= 0, got {model_error!r}")
    if model_error + fem_error <= target:
        return "passes"
    if model_error - fem_error > target:
        return "fails"
    return "undecided"


def _ratios(measured: dict, deform: dict) -> dict:
    """The estimate bases from the measured rows: the largest FEM tip / shape error per unit deformation and
    the largest compliance errors, each with the state it was measured on."""
    out = {}
    for q in ("tip", "shape"):
        key = QUANTITIES[q][1]
        per = [(r[key] / deform[lb], lb) for lb, r in measured.items() if r.get(key) is not None
               and deform.get(lb) is not None and np.isfinite(deform[lb]) and deform[lb] > 0]
        out[q] = max(per, default=None)
        out[q + "_max"] = max(((r[key], lb) for lb, r in measured.items() if r.get(key) is not None), default=None)
    for q in ("C_tension", "C_locked"):
        key = QUANTITIES[q][1]
        out[q] = max(((r[key], lb) for lb, r in measured.items() if r.get(key) is not None), default=None)
    return out


def _estimated_fem(d: Optional[float], ratios: dict, L: float) -> tuple[dict, str]:
    """({quantity: FEM error estimate}, basis in words) of a state not measured, deformation ``d`` [m]."""
    fem, words = {}, []
    for q in ("tip", "shape"):
        if ratios[q] is not None and d is not None and np.isfinite(d):
            fem[q] = ratios[q][0] * d
            words.append(f"{QUANTITIES[q][0]}: {ratios[q][0] * L / 100:.3g} (the largest FEM error per unit "
                         f"deformation measured, on {ratios[q][1]}) × this state's deformation {1e3 * d:.1f} mm")
        elif ratios[q + "_max"] is not None:
            fem[q] = ratios[q + "_max"][0]
            words.append(f"{QUANTITIES[q][0]}: the largest measured, on {ratios[q + '_max'][1]}")
    for q in ("C_tension", "C_locked"):
        if ratios[q] is not None:
            fem[q] = ratios[q][0]
            words.append(f"{QUANTITIES[q][0]}: the largest measured, on {ratios[q][1]}")
    return fem, ("estimate — " + "; ".join(words)) if words else "no measured state to estimate from"


def estimate_rule(ratios: dict, L: float) -> str:
    """How every state not measured gets its FEM error (:func:`_estimated_fem`), in words, once for all states."""
    words = []
    for q in ("tip", "shape"):
        if ratios[q] is not None:
            words.append(f"{QUANTITIES[q][0]}: {ratios[q][0] * L / 100:.3g} × the state's deformation (the largest FEM "
                         f"error per unit deformation measured, on {ratios[q][1]})")
        elif ratios[q + "_max"] is not None:
            words.append(f"{QUANTITIES[q][0]}: the largest measured, on {ratios[q + '_max'][1]}")
    for q in ("C_tension", "C_locked"):
        if ratios[q] is not None:
            words.append(f"{QUANTITIES[q][0]}: the largest measured, on {ratios[q][1]}")
    return "; ".join(words) if words else "no measured state to estimate from"


def _state_row(v: dict, fem: dict, measured: bool, basis: str, deform, targets: dict) -> dict:
    """One held-out state: model and FEM errors per quantity and their verdicts (FEM error missing: taken as 0,
    said so in ``basis``)."""
    out = {"label": v["label"], "experiment": v.get("experiment"), "deformation_m": deform, "measured": measured,
           "basis": basis, "verdicts": {}}
    for q, (_, key, _, tk) in QUANTITIES.items():
        m = v.get(key)
        f = fem.get(q)
        out[f"model_{key}"], out[f"fem_{key}"] = m, f
        out["verdicts"][q] = verdict(m, 0.0 if f is None else f, targets[tk])
    return out


def _tally(rows: list, targets: dict) -> dict:
    """Per quantity: the states that pass / fail / are undecided / were not checked (extrapolation states,
    reported apart, left out)."""
    from validation.reference.experiments import EXTRAPOLATION
    out = {}
    for q, (name, key, unit, tk) in QUANTITIES.items():
        t = {"name": name, "key": key, "unit": unit, "target": targets[tk], "not_checked": []}
        t.update({k: [] for k in VERDICTS})
        for r in rows:
            if r.get("experiment") == EXTRAPOLATION:
                continue
            vd = r["verdicts"][q]
            (t[vd] if vd else t["not_checked"]).append(r["label"])
        out[q] = t
    return out


def _tally_statements(quantities: dict, rows: list) -> list[str]:
    by = {r["label"]: r for r in rows}
    out = []
    for q, t in quantities.items():
        if not any(t[k] for k in VERDICTS):
            continue
        s = (f"{t['name'].capitalize()} (target {t['target']:g} {t['unit']}): {len(t['passes'])} state(s) pass, "
             f"{len(t['fails'])} fail, {len(t['undecided'])} undecided")
        for k in ("fails", "undecided"):
            if t[k]:
                mk, fk = f"model_{t['key']}", f"fem_{t['key']}"
                s += f"; {k}: " + ", ".join(f"{lb} (model {by[lb][mk]:.2f} ± FEM {by[lb][fk] or 0:.2f})" for lb in t[k])
        out.append(s + ".")
    return out


RULE = ("a state passes when model error + FEM error ≤ target, fails when model error − FEM error > target, and "
        "is undecided in between (the FEM's own error straddles the target: a finer FEM mesh decides)")


def _measured_statements(estimate: FemErrorEstimate, measured: dict) -> list[str]:
    worst = max((r["tip_error_pct"] for r in measured.values()), default=None)
    dirs = {d: max(r["by_direction"][d]["tip_error_pct"] for r in measured.values() if d in r.get("by_direction", {}))
            for d in estimate.directions if any(d in r.get("by_direction", {}) for r in measured.values())}
    s = [f"FEM discretisation error measured on {len(measured)} held-out state(s) with the largest deformation "
         f"({estimate.method})" + (f": tip up to {worst:.2f} % of L (" + ", ".join(
             f"{DIRECTION_WORDS[d]} up to {v:.2f} %" for d, v in dirs.items()) + ")." if measured else ".")]
    a = estimate.extra.get("around")
    if a and a.get("checked") and a.get("tip_error_pct") is not None:
        s.append(f"Refined around ({a['mesh']}) on {a['label']}: the tip moves by an estimated {a['tip_error_pct']:.3f} "
                 f"% of L, {100 * a['share']:.0f} % of the combined error there — "
                 + (f"above {100 * AROUND_SHARE:.0f} %: measured on every state and added."
                    if a["added"] else f"not above {100 * AROUND_SHARE:.0f} %: recorded, not added."))
    elif a:
        s.append(f"The check around gave no estimate: {a.get('why') or 'failed'}.")
    for r in estimate.rows:
        if r.get("tip_error_pct") is None:
            s.append(f"No estimate for {r['label']}: {r.get('error') or 'failed'}.")
    return s


def assess(validation, estimate: Optional[FemErrorEstimate], records: Sequence[FemRecord] = (), *,
           tip_target_pct: Optional[float] = None, compliance_target_pct: Optional[float] = None,
           reason: str = "") -> dict:
    """The FEM error beside the model-vs-FEM error of every held-out state of ``validation``
    (:class:`validation.checks.compare.ValidationResult`), and the verdict of each (:func:`verdict`).

    A state whose FEM error was measured gets that number; every other state an *estimate* with its basis
    (module docstring; ``records``: the default-mesh records of the held-out states, for their deformation).
    Targets: tip position and shape ``tip_target_pct`` (% of L, default the shape target), both compliances
    ``compliance_target_pct`` (%).  Without an estimate (``estimate`` None, ``reason`` why) the FEM is taken as
    exact, said so.

    Returns {"estimated", "method", "rule", "targets", "rows": per held-out state {label, measured, basis,
    model_<key> / fem_<key> per quantity (:data:`QUANTITIES`), verdicts: {quantity: "passes" / "fails" /
    "undecided" / None}}, "quantities": {quantity: {name, target, unit, passes, fails, undecided, not_checked}},
    "failing_states", "undecided_states", "n_measured", "max_fem_tip_error_pct", "around", "statements",
    "estimate": :meth:`FemErrorEstimate.to_dict`} (JSON-ready)."""
    from validation.checks.compare import COMPLIANCE_TARGET_PCT, SHAPE_TARGET_PCT
    targets = {"shape": SHAPE_TARGET_PCT if tip_target_pct is None else tip_target_pct,
               "compliance": COMPLIANCE_TARGET_PCT if compliance_target_pct is None else compliance_target_pct}
    L = float(getattr(validation, "length", 0.0) or (estimate.length if estimate is not None else 0.0))
    deform = {r.case.label: deformation_m(r) for r in records}
    measured = {}
    if estimate is not None:
        for r in estimate.rows:
            deform.setdefault(r["label"], r["deformation_m"])
        measured = {r["label"]: r for r in estimate.rows if r.get("tip_error_pct") is not None}
    ratios = _ratios(measured, deform)
    rows = []
    for v in validation.rows:
        lab, d = v["label"], deform.get(v["label"])
        m = measured.get(lab)
        if estimate is None:
            fem, basis, was = {}, "not estimated: the FEM taken as exact", False
        elif m is not None:
            fem = {q: m.get(QUANTITIES[q][1]) for q in QUANTITIES}
            basis, was = "measured (" + ", ".join(f"{DIRECTION_WORDS[dd]} {x['tip_error_pct']:.3f} % of L" for dd, x
                                                  in m.get("by_direction", {}).items()) + ")", True
        else:
            (fem, basis), was = _estimated_fem(d, ratios, L), False
        row = _state_row(v, fem, was, basis, d, targets)
        if m is not None:
            row["fem_tip_error_m"] = m["tip_error_m"]
            row["fem_by_direction"] = {dd: {k: x.get(k) for k in ("tip_error_pct", "tip_error_m", "shape_error_pct",
                                                                    "C_tension_error_pct", "C_locked_error_pct", "rate")}
                                       for dd, x in m.get("by_direction", {}).items()}
        rows.append(row)
    quantities = _tally(rows, targets)
    out = {"estimated": estimate is not None, "rule": RULE, "targets": {
        "tip_pct": targets["shape"], "shape_pct": targets["shape"], "compliance_pct": targets["compliance"]},
        "rows": to_jsonable(rows), "quantities": quantities,
        "failing_states": sorted({lb for t in quantities.values() for lb in t["fails"]}),
        "undecided_states": sorted({lb for t in quantities.values() for lb in t["undecided"]})}
    if estimate is None:
        out["statements"] = (["The FEM's discretisation error was not estimated" + (f" ({reason})" if reason else "")
                              + ": the verdicts assume the FEM is exact."] + _tally_statements(quantities, rows))
        return out
    out["estimate_basis"] = estimate_rule(ratios, L)
    statements = _measured_statements(estimate, measured)
    unmeasured = [r["label"] for r in rows if not r["measured"]]
    if unmeasured:
        statements.append(f"Not measured: {', '.join(unmeasured)} — each carries an estimate ({out['estimate_basis']}).")
    statements.append(f"The rule: {RULE}.")
    out.update(method=estimate.method, n_measured=len(measured), around=estimate.extra.get("around"),
               max_fem_tip_error_pct=max((r["tip_error_pct"] for r in measured.values()), default=None),
               statements=statements + _tally_statements(quantities, rows), estimate=estimate.to_dict())
    return to_jsonable(out)


def estimate_for_heldout(spec: FemSpec, records: Sequence[FemRecord], n_cases: int, **kw) -> Optional[FemErrorEstimate]:
    """:func:`estimate_fem_error` of the ``n_cases`` solved held-out records (role ``"heldout"``) with the largest
    deformation, None when there is none — what :func:`for_validation` measures, computable before the model
    is fitted (``validation.identification.identify.from_fem(after_sweep=...)`` runs it beside the fits)."""
    ho = [r for r in records if r.ok and r.case.role == "heldout"]
    if not ho:
        return None
    chosen = select_cases(ho, n_cases)
    return estimate_fem_error(spec, [r.case for r in chosen], records=chosen, **kw)


def for_validation(validation, spec: FemSpec, records: Sequence[FemRecord], n_cases: int, *,
                   estimate: Optional[FemErrorEstimate] = None, **kw) -> dict:
    """Measure the FEM error of the ``n_cases`` held-out states of ``validation`` with the largest deformation
    (``records``: their default-mesh results, e.g. ``IdentificationResult.records``) and set
    ``validation.fem_error`` to :func:`assess` of it; ``kw`` go to :func:`estimate_fem_error`.  ``estimate``: one
    already made by :func:`estimate_for_heldout`, used when its states are among those compared (else measured
    again here).  Returns it."""
    labels = {r["label"] for r in validation.rows}
    ho = [r for r in records if r.ok and r.case.label in labels]
    if not ho:
        validation.fem_error = assess(validation, None, reason="no held-out state was compared")
        return validation.fem_error
    chosen = select_cases(ho, n_cases)
    if estimate is None or [r["label"] for r in estimate.rows] != [r.case.label for r in chosen]:
        estimate = estimate_fem_error(spec, [r.case for r in chosen], records=chosen, **kw)
    validation.fem_error = assess(validation, estimate, ho)
    return validation.fem_error
