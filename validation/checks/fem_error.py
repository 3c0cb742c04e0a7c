"""The FEM reference's own discretisation error, measured by solving selected load cases on refined meshes.

A comparison of the reduced model with the FEM can only resolve model errors larger than the FEM's own
error.  :func:`estimate_fem_error` solves the chosen load cases on the spec's mesh (h) and on a mesh refined
``factor``× (h/2; by default along the profile: elements per convolution and per end collar; the counts
through the wall and around are kept) and, optionally, on a third mesh refined twice (h/4).  With f a
result (the tip position, the centreline, a tip compliance), Richardson's model f_h = f + C hᵖ gives the
error of the default-mesh result

    e_h = (f_h − f_h/2) · rᵖ / (rᵖ − 1),        r = factor,

* two meshes: p is *assumed* (:data:`ASSUMED_RATE` = 2 unless given; a lower p gives a larger estimate);
* three meshes: p is *observed*, p = log(‖f_h − f_h/2‖ / ‖f_h/2 − f_h/4‖) / log r from the tip positions.
  When the differences do not fall (p ≤ 0) the results are not converging and no estimate is given.

Per case: the tip error estimate ‖e_h‖ [m] and in % of the length L, the largest centreline error at
:data:`validation.checks.compare.N_SHAPE_POINTS` points [% of L], and — when the records carry tip compliances —
the relative Frobenius error of each compliance matrix [%].  The solves run through
:func:`validation.reference.fem_sweep.run_cases` (cached on disk under the refined mesh level, in parallel, with
progress; Ctrl-C keeps the finished cases), one case per task so that every case is cached on its own.
Each refined solve starts from the same case's equilibrium on the level below (the records' ``state``,
interpolated and its added nodes relaxed: :mod:`fem_reference.transfer`) in one Newton solve at full load
instead of climbing the load path again (measured on the quick report's two cases: 21 s against 69 s);
when that fails it climbs the path from rest as before.  The equilibrium, hence the estimate, is the same.

:func:`select_cases` chooses the cases with the largest deformation (largest centreline distance from the
straight, unloaded axis); :func:`assess` sets the measured errors beside the model-vs-FEM errors of a
validation and states where the FEM error is too large for the verdict to mean anything.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Optional, Sequence

import numpy as np

from ancf.errors import InputError
from ancf.export import to_jsonable

from validation.reference.experiments import LoadCase
from validation.reference.fem_sweep import FemRecord, FemSpec, run_cases

__all__ = ["for_validation", "estimate_for_heldout", "QUICK_CASES", "FULL_CASES", "ASSUMED_RATE", "TOO_LARGE_SHARE", "FemErrorEstimate",
           "mesh_level", "refined_level", "richardson",
           "deformation_m", "select_cases", "estimate_fem_error", "assess"]

#: convergence rate assumed with two meshes (quadratic elements; the mixed element's displacements converge
#: at a log-log rate above 2 along a curved wall, docs/fem.md §3a)
ASSUMED_RATE = 2.0
#: the FEM error is "too large" when it exceeds this share of the model-vs-FEM error (or the target itself)
TOO_LARGE_SHARE = 1.0 / 3.0
#: refinement directions: MeshLevel fields each one multiplies
DIRECTIONS = {"along": ("n_per_conv", "n_collar"), "through": ("n_thick",), "around": ("n_theta",)}
DIRECTION_WORDS = {"along": "along the profile", "through": "through the wall", "around": "around"}
N_POINTS = 17
#: held-out cases measured by the quick and the full report (those with the largest deformation)
QUICK_CASES, FULL_CASES = 2, 4


def mesh_level(mesh):
    """A mesh level name or :class:`fem_reference.MeshLevel` → the MeshLevel."""
    from fem_reference.mesh import MESH_LEVELS, MeshLevel
    if isinstance(mesh, MeshLevel):
        return mesh
    if isinstance(mesh, str) and mesh in MESH_LEVELS:
        return MESH_LEVELS[mesh]
    raise InputError(f"unknown mesh level {mesh!r}; choose from {sorted(MESH_LEVELS)} or give a MeshLevel")


def refined_level(mesh, factor: int = 2, directions: Sequence[str] = ("along",)):
    """``mesh`` with its element counts in ``directions`` (``"along"`` the profile, ``"through"`` the wall,
    ``"around"``) multiplied by ``factor``."""
    from dataclasses import replace
    lvl = mesh_level(mesh)
    if not isinstance(factor, (int, np.integer)) or factor < 2:
        raise InputError(f"refinement factor must be an integer >= 2, got {factor!r}")
    bad = [d for d in directions if d not in DIRECTIONS]
    if bad or not directions:
        raise InputError(f"refinement directions {list(directions)}: choose from {sorted(DIRECTIONS)}")
    changes = {f: int(factor) * getattr(lvl, f) for d in directions for f in DIRECTIONS[d]}
    return replace(lvl, **changes)


def describe_level(mesh) -> str:
    lvl = mesh_level(mesh)
    name = f"'{mesh}' " if isinstance(mesh, str) else ""
    return (f"{name}({lvl.n_per_conv} per convolution × {lvl.n_thick} through the wall × {lvl.n_theta} around, "
            f"{lvl.n_collar} per collar)")


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

    rows : one dict per case (label, deformation_m, tip_m per level, started_from_coarser — per refined level,
        whether its solve started from the level below (:mod:`fem_reference.transfer`) —, tip_error_m, tip_error_pct,
        shape_error_pct, C_tension_error_pct / C_locked_error_pct when compliances were solved, rate,
        rate_observed, error — the failure, if a level failed);
    levels : the mesh of each level (a name or element counts); method : how the estimate was made, in words.
    """
    rows: list
    length: float
    levels: list
    method: str
    ratio: int = 2
    rate: Optional[float] = None
    seconds: float = 0.0
    extra: dict = field(default_factory=dict)

    def row(self, label: str) -> Optional[dict]:
        return next((r for r in self.rows if r["label"] == label), None)

    def to_dict(self) -> dict:
        return to_jsonable({"rows": self.rows, "length_m": self.length, "levels": [
            {"mesh": lv if isinstance(lv, str) else asdict(lv),
             "description": describe_level(lv)} for lv in self.levels],
            "method": self.method, "ratio": self.ratio, "rate": self.rate, "seconds": self.seconds})


def _compliance_error_pct(mats: list, rate) -> Optional[float]:
    if any(m is None for m in mats):
        return None
    est = richardson(mats, rate=rate)
    if est["norm"] is None:
        return None
    ref = float(np.linalg.norm(mats[-1]))
    return 100.0 * est["norm"] / ref if ref > 0 else None


def estimate_fem_error(spec: FemSpec, cases: Sequence[LoadCase], *, records: Optional[Sequence[FemRecord]] = None,
                       levels: int = 2, factor: int = 2, directions: Sequence[str] = ("along",),
                       rate: Optional[float] = None, compliance: Optional[bool] = None, workers: Optional[int] = None,
                       scheduler=None, cache_dir=None, progress: bool = True) -> FemErrorEstimate:
    """Estimate the discretisation error of the FEM results of ``cases`` on ``spec.mesh`` (module docstring).

    records : the results of ``cases`` on ``spec`` if already computed (else solved here, cached);
    levels : 2 (assumed ``rate``, default :data:`ASSUMED_RATE`) or 3 (observed rate unless ``rate`` given);
    factor, directions : the refinement (:func:`refined_level`) from one level to the next;
    compliance : also solve the tip compliances on the refined meshes (default: when the records have them).
    """
    if levels not in (2, 3):
        raise InputError(f"levels must be 2 or 3, got {levels}")
    if rate is not None and not rate > 0:
        raise InputError(f"rate must be > 0, got {rate}")
    cases = list(cases)
    if not cases or not all(isinstance(c, LoadCase) for c in cases):
        raise InputError("estimate_fem_error needs a non-empty list of validation.reference.experiments.LoadCase")
    import time
    t0 = time.perf_counter()
    kw = dict(workers=workers, scheduler=scheduler, cache_dir=cache_dir, progress=progress, chain_length=1)
    if records is None:
        records = run_cases(spec, cases, compliance=bool(compliance), **kw)
    records = list(records)
    if len(records) != len(cases):
        raise InputError(f"estimate_fem_error: {len(records)} records for {len(cases)} cases")
    if compliance is None:
        compliance = any(r.compliance_tension is not None for r in records)
    meshes = [spec.mesh]
    for _ in range(levels - 1):
        meshes.append(refined_level(meshes[-1], factor, directions))
    per_level = [records]
    for lv in meshes[1:]:
        fine = FemSpec(spec.geometry, spec.material, lv, spec.element)
        per_level.append(run_cases(fine, cases, compliance=bool(compliance),
                                   starts=[r.state if r.ok else None for r in per_level[-1]], **kw))
    L = float(spec.geometry.length)
    s = np.linspace(0.0, L, N_POINTS)
    rows = []
    for k, case in enumerate(cases):
        recs = [lvl[k] for lvl in per_level]
        row = {"label": case.label, "experiment": case.experiment, "deformation_m": deformation_m(recs[0]),
               "tip_m": [r.tip_position for r in recs],
               "started_from_coarser": [bool(r.extra.get("started_from_other_mesh")) for r in recs[1:]]}
        bad = [f"{describe_level(m)}: {r.error}" for m, r in zip(meshes, recs) if not r.ok]
        if bad:
            rows.append({**row, "error": "; ".join(bad), "tip_error_m": None, "tip_error_pct": None,
                         "shape_error_pct": None, "rate": None, "rate_observed": False})
            continue
        tip = richardson([r.tip_position for r in recs], ratio=factor, rate=rate)
        p = tip["rate"]
        row.update(rate=p, rate_observed=tip["rate_observed"], differences_m=tip["differences"],
                   converging=tip["converging"], error="")
        if tip["norm"] is None:
            row.update(tip_error_m=None, tip_error_pct=None, shape_error_pct=None,
                       error="the tip differences do not fall with refinement (not converging): no estimate")
            rows.append(row)
            continue
        shape = richardson([r.centreline_at(s) for r in recs], ratio=factor, rate=p)
        row.update(tip_error_m=tip["norm"], tip_error_pct=100.0 * tip["norm"] / L,
                   shape_error_pct=100.0 * float(np.linalg.norm(shape["error"], axis=1).max()) / L)
        if compliance:
            for mode in ("tension", "locked"):
                mats = [getattr(r, f"compliance_{mode}") for r in recs]
                row[f"C_{mode}_error_pct"] = _compliance_error_pct(mats, p)
        rows.append(row)
    if levels == 2:
        method = (f"two meshes, {describe_level(meshes[0])} and {factor}× refined "
                  f"{', '.join(DIRECTION_WORDS[d] for d in directions)} {describe_level(meshes[1])}; Richardson with an assumed rate "
                  f"p = {ASSUMED_RATE if rate is None else rate:g}: e = |f_h − f_h/{factor}| · {factor}ᵖ/({factor}ᵖ − 1)")
    else:
        method = (f"three meshes, {' → '.join(describe_level(m) for m in meshes)} ({factor}× refined "
                  f"{', '.join(DIRECTION_WORDS[d] for d in directions)} each); Richardson with the "
                  + ("observed rate p = log(‖f_h − f_h/2‖/‖f_h/2 − f_h/4‖)/log r of each case's tip" if rate is None
                     else f"given rate p = {rate:g}") + ": e = |f_h − f_h/r| · rᵖ/(rᵖ − 1)")
    return FemErrorEstimate(rows, L, meshes, method, ratio=factor,
                            rate=(ASSUMED_RATE if rate is None else rate) if levels == 2 or rate is not None else None,
                            seconds=time.perf_counter() - t0)



def assess(validation, estimate: Optional[FemErrorEstimate], records: Sequence[FemRecord] = (), *,
           tip_target_pct: Optional[float] = None, compliance_target_pct: Optional[float] = None,
           reason: str = "") -> dict:
    """The FEM error beside the model-vs-FEM error of every held-out state of ``validation``
    (:class:`validation.checks.compare.ValidationResult`), with a verdict.

    A state whose FEM error was measured gets that number; a state that was not measured gets the largest
    estimate measured on a state with at least its deformation (``records``: the default-mesh records of the
    held-out states, for their deformation), named as such — or "no measured bound".  The FEM error is
    *too large* for a verdict when it exceeds :data:`TOO_LARGE_SHARE` of the model-vs-FEM error or the target
    itself (tip: the shape target, % of L; compliance: the compliance target).

    Returns {"method", "levels", "rows": per held-out state, "too_large": bool, "statements": [str, …],
    "estimate": :meth:`FemErrorEstimate.to_dict`} (JSON-ready)."""
    from validation.checks.compare import COMPLIANCE_TARGET_PCT, SHAPE_TARGET_PCT
    tip_target = SHAPE_TARGET_PCT if tip_target_pct is None else tip_target_pct
    c_target = COMPLIANCE_TARGET_PCT if compliance_target_pct is None else compliance_target_pct
    if estimate is None:
        return {"estimated": False, "rows": [], "too_large": None,
                "statements": ["The FEM's discretisation error was not estimated" + (f" ({reason})" if reason else "")
                               + ": the verdicts assume the FEM is exact."]}
    deform = {r.case.label: deformation_m(r) for r in records}
    for r in estimate.rows:
        deform.setdefault(r["label"], r["deformation_m"])
    measured = {r["label"]: r for r in estimate.rows if r.get("tip_error_pct") is not None}
    rows, too_large, notes, unsure = [], [], [], []
    share = TOO_LARGE_SHARE
    for v in validation.rows:
        lab = v["label"]
        out = {"label": lab, "model_tip_error_pct": v["tip_error_pct"], "deformation_m": deform.get(lab)}
        m = measured.get(lab)
        if m is not None:
            out.update(measured=True, fem_tip_error_pct=m["tip_error_pct"], fem_tip_error_m=m["tip_error_m"],
                       fem_shape_error_pct=m["shape_error_pct"], basis="measured")
            why = []
            if m["tip_error_pct"] > tip_target:
                why.append(f"the FEM's tip error {m['tip_error_pct']:.2f} % of L exceeds the {tip_target:g} % target")
            if m["tip_error_pct"] > share * v["tip_error_pct"]:
                why.append(f"the FEM's tip error {m['tip_error_pct']:.2f} % of L is more than a third of the "
                           f"model-vs-FEM tip error {v['tip_error_pct']:.2f} %")
            for mode in ("tension", "locked"):
                fe, me = m.get(f"C_{mode}_error_pct"), v.get(f"C_{mode}_error_pct")
                out[f"fem_C_{mode}_error_pct"] = fe
                out[f"model_C_{mode}_error_pct"] = me
                if fe is None or me is None:
                    continue
                if fe > c_target:
                    why.append(f"the FEM's compliance error ({mode}) {fe:.1f} % exceeds the {c_target:g} % target")
                if fe > share * me:
                    why.append(f"the FEM's compliance error ({mode}) {fe:.1f} % is more than a third of the "
                               f"model-vs-FEM compliance error {me:.1f} %")
            out["too_large"] = bool(why)
            out["why"] = why
            if why:
                too_large.append(lab)
                notes.append(f"{lab}: " + "; ".join(why))
        else:
            d = deform.get(lab)
            cover = [r for lb, r in measured.items() if d is not None and np.isfinite(d)
                     and deform.get(lb) is not None and deform[lb] >= d]
            out.update(measured=False, fem_tip_error_pct=None, too_large=None)
            if cover:
                worst = max(cover, key=lambda r: r["tip_error_pct"])
                b = worst["tip_error_pct"]
                out.update(bound_label=worst["label"], bound_tip_error_pct=b,
                           bound_too_large=bool(b > tip_target or b > share * v["tip_error_pct"]),
                           basis=f"not measured; bound: {b:.2f} % of L measured on {worst['label']} (deformed more)")
                if out["bound_too_large"]:
                    unsure.append(lab)
            else:
                out.update(bound_label=None, bound_tip_error_pct=None, bound_too_large=None,
                           basis="not measured; no measured state is deformed more: no measured bound")
                unsure.append(lab)
        rows.append(out)
    failed = [r for r in estimate.rows if r.get("tip_error_pct") is None]
    worst_tip = max((r["tip_error_pct"] for r in measured.values()), default=None)
    statements = [f"FEM discretisation error measured on {len(measured)} held-out state(s) with the largest "
                  f"deformation ({estimate.method})" + (f": tip up to {worst_tip:.2f} % of L." if measured else ".")]
    for r in failed:
        statements.append(f"No estimate for {r['label']}: {r.get('error') or 'failed'}.")
    if too_large:
        statements.append("The FEM's discretisation error is too large for the verdict to mean anything on "
                          f"{len(too_large)} state(s) — " + " · ".join(notes)
                          + ". Refine the FEM mesh before reading these errors as the reduced model's.")
    elif measured:
        statements.append("On every measured state the FEM's error is below a third of the model-vs-FEM error and "
                          "below the targets: the differences are the reduced model's.")
    unmeasured = [r["label"] for r in rows if not r["measured"]]
    if unmeasured:
        statements.append(f"Not measured: {', '.join(unmeasured)} (each shows, as its bound, the largest error "
                          "measured on a state deformed more, where there is one).")
    if unsure:
        statements.append(f"On {len(unsure)} state(s) not measured the measured bound does not rule out a FEM error "
                          f"too large for the verdict (or there is no bound): {', '.join(unsure)}.")
    return {"estimated": True, "method": estimate.method, "too_large": bool(too_large), "too_large_states": too_large,
            "not_ruled_out_states": unsure, "n_measured": len(measured), "max_fem_tip_error_pct": worst_tip,
            "criterion": f"FEM error > {share:.2g} × the model-vs-FEM error, or > the target ({tip_target:g} % of L tip, "
                         f"{c_target:g} % compliance)",
            "rows": to_jsonable(rows), "statements": statements, "estimate": estimate.to_dict()}


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
