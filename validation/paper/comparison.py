"""Every headline number of the paper for several presets, side by side with the paper's values.

``compare(presets=...)`` runs, on each preset: what the reading implies (EA(1), EI(1), extension at
120 kPa, compression under 15 N, largest compression the law carries), the workspace (two seeds, each
with its own half-sample error), stiffness vs T1 at 0/25/50 kPa, element convergence, the locked drift
under 110 g, holding 100 g, the IK time, and the controller studies (Table I, the compliance ablation,
continuous/cyclic loading) through :mod:`validation.paper`; a study that fails on a preset is reported
as ``"not run: <reason>"``.  The result is written as ``compare.json`` (after every preset, so an
interrupted run keeps the finished presets) and ``compare.png/.svg``.

Verdicts — a number *reproduces* the paper when (criteria chosen here, stated so they can be argued with):

==============================  ===============================================================
headline                        reproduced if
==============================  ===============================================================
workspace gain                  within ±25 % of +108.6 % (81–136 %)
locked / constant stiffness     mean ratio in [1.5, 2.5] ("about twice")
convergence n = 1 / n = 6       within a factor 2 of 6.1 mm / 0.3 mm
110 g locked drift              > 10 mm ("drifts by over 10 mm")
loading uncontrolled drifts     continuous > 10 mm and cyclic > 7 mm
Table I VF-CC                   each configuration within a factor 2 of the paper's
Table I LACC                    each ≤ 0.03 mm after five iterations
ablation                        IK-derived compliance 25–75 % fewer iterations (paper ≈ 50 %)
loading LACC errors             continuous ≤ 0.722 mm and cyclic ≤ 3.573 mm
==============================  ===============================================================
"""

from __future__ import annotations

import pathlib
import time
from typing import Any, Callable, Optional, Sequence, Union

import numpy as np

from ancf.errors import BellowsError
from ancf.export import write_json
from ancf.outputs import prepare_output_dir

from validation.paper import numbers as PN
from validation.paper import states
from validation.paper.common import resolve_params
from validation.paper.convergence import PAPER_CONVERGENCE, element_convergence
from validation.paper.criteria import within
from validation.paper.loads import hold_payload, ik_time, locked_drift
from validation.paper.stiffness import ratio_closed_form, series_stiffness_for_ratio, stiffness_vs_tension
from validation.paper.workspace_volume import workspace

DEFAULT_PRESETS = ("paper_unscaled", "paper_scaled", "paper_scaled_020", "paper_diameter")
FILES = ("compare.json", "compare.png", "compare.svg")
CONTROL = ("table1", "ablation", "loading")

#: headline key → (label, paper value or None, unit, lower bound, upper bound) of a reproduced value
HEADLINES: dict[str, tuple] = {
    "workspace_increase_percent": ("workspace TPHD vs TD [%]", PN.WORKSPACE["increase_percent"], "%", 81.0, 136.0),
    "stiffness_ratio": ("locked / constant stiffness, mean [-]", PN.STIFFNESS["locked_over_constant"], "", 1.5, 2.5),
    "stiffness_ratio_0kPa": ("  at 0 kPa", 2.0, "", None, None),
    "stiffness_ratio_25kPa": ("  at 25 kPa", 2.0, "", None, None),
    "stiffness_ratio_50kPa": ("  at 50 kPa", 2.0, "", None, None),
    "stiffness_ratio_closed_form": ("  straight-beam closed form [-]", 2.0, "", None, None),
    "series_stiffness_for_ratio_2_N_per_m": ("  series tendon stiffness giving 2 [N/m]", None, "N/m", None, None),
    "convergence_n1_mm": ("tip error n = 1 [mm]", PAPER_CONVERGENCE["tip_error_mm"][0], "mm", 3.05, 12.2),
    "convergence_n6_mm": ("tip error n = 6 [mm]", PAPER_CONVERGENCE["tip_error_mm"][1], "mm", 0.15, 0.6),
    "locked_drift_110g_mm": ("110 g locked drift [mm]", 10.0, "mm", 10.0, None),
    "loading_continuous_drift_mm": ("continuous loading, uncontrolled drift [mm]",
                                    PN.LOADING["continuous_uncontrolled_drift_mm"], "mm", 10.0, None),
    "loading_cyclic_drift_mm": ("cyclic loading, uncontrolled drift [mm]", PN.LOADING["cyclic_uncontrolled_drift_mm"],
                                "mm", 7.0, None),
    "loading_continuous_error_mm": ("continuous loading, LACC max error [mm]", PN.LOADING["continuous_max_error_mm"],
                                    "mm", None, PN.LOADING["continuous_max_error_mm"]),
    "loading_cyclic_error_mm": ("cyclic loading, LACC max error [mm]", PN.LOADING["cyclic_max_error_mm"], "mm",
                                None, PN.LOADING["cyclic_max_error_mm"]),
    **{f"table1_{c}_vfcc_mm": (f"Table I {c}, VF-CC [mm]", PN.TABLE1[c]["vfcc_mm"], "mm",
                               PN.TABLE1[c]["vfcc_mm"] / 2, PN.TABLE1[c]["vfcc_mm"] * 2) for c in PN.TABLE1},
    **{f"table1_{c}_lacc_mm": (f"Table I {c}, LACC [mm]", PN.TABLE1[c]["lacc_mm"], "mm", None, 0.03)
       for c in PN.TABLE1},
    "ablation_ik_faster_percent": ("IK- vs FK-derived compliance, fewer iterations [%]",
                                   PN.ABLATION["ik_faster_percent"], "%", 25.0, 75.0),
    "ik_time_cold_ms": ("IK time, cold, n = 6 [ms]", 2950.0, "ms", None, None),
    "hold_100g_upward": ("holds 100 g, upward (max T needed [N])", None, "N", None, None),
    "hold_100g_horizontal": ("holds 100 g, horizontal (max T needed [N])", None, "N", None, None),
    "hold_100g_downward": ("holds 100 g, downward (max T needed [N])", None, "N", None, None),
    "EA1_N": ("EA(1) [N]", None, "N", None, None),
    "EI1_N_m2": ("EI(1) [N m²]", None, "N m²", None, None),
    "stretch_at_max_pressure": ("stretch at 120 kPa (straight rod) [-]", None, "", None, None),
    "stretch_under_compression": ("stretch under 15 N (nan: collapses) [-]", None, "", None, None),
    "max_compression_N": ("largest compression the law carries [N]", None, "N", None, None),
    "workspace_td_collapsed_percent": ("TD samples collapsed [%]", None, "%", None, None),
    "workspace_seed_spread_percent": ("workspace gain, half spread of 2 seeds [%]", None, "%", None, None),
    "workspace_halves_error_percent": ("workspace gain, half-sample error [%]", None, "%", None, None),
}


def verdict(key: str, value) -> Optional[bool]:
    """True/False if ``value`` reproduces / misses the paper's headline ``key``; None if not judged.  The
    criterion is :func:`validation.paper.criteria.within`, the same that draws compare.png's bands."""
    return within(value, HEADLINES[key][3], HEADLINES[key][4])


def _guard(fn: Callable, *a, **kw):
    try:
        return fn(*a, **kw), None
    except BellowsError as exc:         # a typed failure on a preset is reported; a bug propagates
        return None, f"not run: {type(exc).__name__}: {str(exc)[:200]}"


def _control_numbers(name: str, prm, row: dict, notes: dict) -> None:
    from validation import paper as _paper
    fn = _paper.CONTROL_STUDIES[name]
    res, err = _guard(fn, params=prm)
    if err:
        notes[name] = err
        return
    if name == "table1":
        for c in PN.TABLE1:
            if c in res:
                row[f"table1_{c}_vfcc_mm"] = float(res[c]["vfcc_error"]) * 1e3
                row[f"table1_{c}_lacc_mm"] = float(res[c]["lacc_error"]) * 1e3
    elif name == "ablation":
        if "ik_faster_percent" in res:
            row["ablation_ik_faster_percent"] = float(res["ik_faster_percent"])
    elif name == "loading":
        row["loading_continuous_drift_mm"] = float(res["continuous"]["uncontrolled_max_drift"]) * 1e3
        row["loading_cyclic_drift_mm"] = float(res["cyclic"]["uncontrolled_max_drift"]) * 1e3
        row["loading_continuous_error_mm"] = float(res["continuous"]["max_error"]) * 1e3
        row["loading_cyclic_error_mm"] = float(res["cyclic"]["max_error"]) * 1e3


def run_preset(preset, *, samples: int = 5000, seeds: Sequence[int] = (0, 1), workers: Optional[int] = None,
               control: Sequence[str] = CONTROL, out: Optional[pathlib.Path] = None, progress: bool = True,
               log: Callable[[str], None] = lambda s: None) -> dict:
    """Every headline number for one preset: ``{"preset", "numbers": {key: value}, "notes": {study: msg},
    "details": {...}}``."""
    prm = resolve_params(preset)
    row: dict[str, Any] = {}
    notes: dict[str, str] = {}
    details: dict[str, Any] = {}
    t0 = time.perf_counter()
    f = states.reading_facts(prm)
    row.update({k: f[k] for k in ("EA1_N", "EI1_N_m2", "stretch_at_max_pressure", "stretch_under_compression",
                                  "max_compression_N")})
    incs, halves, collapsed = [], [], []
    for seed in seeds:
        log(f"{prm.name}: workspace, seed {seed}, {samples} samples per mode")
        ws_out = None if out is None else out / f"workspace_{prm.name}_seed{seed}"
        ws, err = _guard(workspace, samples=samples, seed=seed, workers=workers, progress=progress, params=prm,
                         out=ws_out, figure=False, force=True)
        if err:
            notes["workspace"] = err
            continue
        incs.append(ws["increase_percent"])
        halves.append(ws["sampling_error"]["half_difference_percent"])
        collapsed.append(ws["modes"]["TD"]["collapsed"] / samples * 100)
        details[f"workspace_seed{seed}"] = {k: ws[k] for k in ("increase_percent", "volume_td_m3", "volume_tphd_m3",
                                                                "failures", "collapsed", "sampling_error")}
    if incs:
        row["workspace_increase_percent"] = float(np.mean(incs))
        row["workspace_seed_spread_percent"] = float(np.ptp(incs) / 2) if len(incs) > 1 else float("nan")
        row["workspace_halves_error_percent"] = float(np.mean(halves))
        row["workspace_td_collapsed_percent"] = float(np.mean(collapsed))
    row["stiffness_ratio_closed_form"] = ratio_closed_form(prm)
    row["series_stiffness_for_ratio_2_N_per_m"] = series_stiffness_for_ratio(prm, 2.0)
    log(f"{prm.name}: stiffness vs T1")
    st, err = _guard(stiffness_vs_tension, params=prm, methods=("exact",))
    if err:
        notes["stiffness"] = err
    else:
        r = np.asarray(st["ratio_locked_over_constant"]["nonlinear"])
        row["stiffness_ratio"] = float(np.nanmean(r))
        for i, p in enumerate(st["pressures_Pa"]):
            row[f"stiffness_ratio_{p / 1e3:g}kPa"] = float(np.nanmean(r[i]))
        cv = st["curves_N_per_m"]
        details["stiffness_N_per_m"] = {k: [float(np.nanmin(cv[k])), float(np.nanmax(cv[k]))]
                                        for k in ("constant_nonlinear", "locked_nonlinear")}
        details["stiffness_failures"] = st["failures"]
    log(f"{prm.name}: convergence, drift, holding, IK time")
    cv, err = _guard(element_convergence, prm, n_values=(1, 6))
    if err:
        notes["convergence"] = err
    else:
        row["convergence_n1_mm"], row["convergence_n6_mm"] = (float(v) * 1e3 for v in cv["tip_error_m"])
    dr, err = _guard(locked_drift, prm)
    if err:
        notes["drift"] = err
    else:
        row["locked_drift_110g_mm"] = dr["drift_m"] * 1e3
        details["loading_tip_angle_deg"] = dr["tip_angle_deg"]
    hp, err = _guard(hold_payload, prm)
    if err:
        notes["hold"] = err
    else:
        for c, v in hp["configurations"].items():
            need = v["max_tension_needed_N"]
            need_s = f"{need:.1f} N" if np.isfinite(need) else "no IK solution ≤ 50 N"
            row[f"hold_100g_{c}"] = f"{'yes' if v['held'] else 'no'} ({need_s})"
        details["hold_100g"] = hp
    ik, err = _guard(ik_time, prm, repeats=3)
    if err:
        notes["ik_time"] = err
    else:
        row["ik_time_cold_ms"] = ik["cold_s"] * 1e3
    for name in control:
        log(f"{prm.name}: controller study {name}")
        _control_numbers(name, prm, row, notes)
    verdicts = {k: verdict(k, v) for k, v in row.items() if k in HEADLINES}
    judged = [v for v in verdicts.values() if v is not None]
    return {"preset": prm.name, "description": prm.description, "numbers": row, "notes": notes,
            "verdicts": verdicts, "reproduced": int(sum(judged)), "judged": len(judged), "details": details,
            "seconds": time.perf_counter() - t0}


def compare(presets: Sequence = DEFAULT_PRESETS, *, samples: int = 5000, seeds: Sequence[int] = (0, 1),
            workers: Optional[int] = None, control: Sequence[str] = CONTROL,
            out: Union[str, pathlib.Path, None] = None, force: bool = False, progress: bool = True,
            figure: bool = True, log: Callable[[str], None] = lambda s: None) -> dict:
    """Run :func:`run_preset` on each preset; ``{"presets": [...], "paper": {key: value}, "labels", ...}``.

    With ``out``: compare.json (rewritten after every preset), compare.png/.svg, and each workspace run's
    samples in ``workspace_<preset>_seed<k>/``."""
    names = [resolve_params(p).name if not isinstance(p, str) else p for p in presets]
    for p in presets:                               # unknown names fail before any work
        resolve_params(p)
    if out is not None:
        out = prepare_output_dir(out, FILES + tuple(f"workspace_{n}_seed{s}" for n in names for s in seeds),
                                 force=force)
    res: dict[str, Any] = {"study": "headline numbers of the paper for several presets",
                           "settings": {"samples_per_mode_per_seed": samples, "seeds": list(seeds),
                                        "control_studies": list(control)},
                           "paper": {k: v[1] for k, v in HEADLINES.items()},
                           "labels": {k: v[0] for k, v in HEADLINES.items()},
                           "criteria": {k: [v[3], v[4]] for k, v in HEADLINES.items() if v[3] is not None
                                        or v[4] is not None},
                           "presets": []}
    for p in presets:
        res["presets"].append(run_preset(p, samples=samples, seeds=seeds, workers=workers, control=control,
                                         out=out, progress=progress, log=log))
        if out is not None:
            write_json(out / "compare.json", res)
    if out is not None and figure:
        from validation.paper.plots import plot_comparison
        res["files"] = {"figures": plot_comparison(res, out), "json": out / "compare.json"}
        write_json(out / "compare.json", res)
    return res
