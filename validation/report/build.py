"""One self-contained HTML report of an identification and its validation against the FEM.

:func:`build_report` turns an :class:`~validation.identification.identify.IdentificationResult` (from the FEM or from rig
data), optionally a :class:`~validation.checks.compare.ValidationResult` (held-out states, shapes and compliance
matrices vs the FEM) and the stiffness-vs-tension study (:func:`validation.checks.compare.stiffness_vs_tension`),
into one HTML page that a colleague can open anywhere: figures are embedded as base64 PNG, styles inline,
no script and no network access.  The template is ``validation/report/templates/report.html.j2`` (jinja2).

The page opens with :func:`headline`: what fails, worst first (the quantity — locked or tension-held
compliance, tip position, shape —, its worst held-out state, its value against the target with the FEM's own
error beside it, what it means for LACC), then what is undecided (the FEM's error straddles the target), what
is not checked and what passes, each linked to its section; then a table of contents (:func:`sections`).  The
verdicts are :func:`validation.checks.fem_error.assess`'s: pass when model error + FEM error ≤ target, fail
when model error − FEM error > target, undecided in between.
Every sentence that states physics or a verdict is made from the numbers it describes (the fitted law's own
pressure factors, the measured errors and their verdicts); none is fixed text.

Sections: identified parameters with 95 % CIs (non-identifiable ones shown as such, never as a number)
and the closed-form first estimate; the model forms compared on held-out error; parameter correlations;
error per state; the reduced model vs the FEM on held-out states (tip, shape, compliance, stiffness
per axis, locked/constant stiffness ratio) beside the FEM's own discretisation error
(:mod:`validation.checks.fem_error`), shape overlays and compliance ellipses; the Fig. 9 analogue;
dynamics (the rod's first bending and axial frequencies beside the FEM's, per pressure:
:mod:`validation.checks.modes_compare`); for a design with tendon friction, the hysteresis of tension cycles, rod vs
FEM (both branches, loop areas: :mod:`validation.checks.hysteresis`); diagnostics (what the numbers imply, the paper's values beside ours);
provenance (versions, git revision).
"""

from __future__ import annotations

import base64
import pathlib
from typing import Optional

import numpy as np

from ancf.errors import InputError
from ancf.outputs import atomic_write_text, prepare_output_file

from validation.report import figures as figs
from validation.checks.compare import N_SHAPE_POINTS, SHAPE_TARGET_PCT, ValidationResult
from validation.identification.forms import MEANINGS, REPORTED, display_unit
from validation.identification.identify import MEASURED_SHEAR, PARSIMONY, IdentificationResult
from validation.checks.modes_compare import modes_sentences, pressure_factor_text
from validation.checks.hysteresis import LOOP_TARGET_PCT, TIP_TARGET_PCT

__all__ = ["build_report", "write_report", "report_figures", "headline", "sections", "friction_item", "friction_rows"]

#: The paper's identified values (Sec. II-B), shown beside ours.
PAPER_DIAMETERS_MM = {"D_a": 29.59, "D_eff": 26.05}
#: reported value → (scale, unit) as shown (SI units from :data:`validation.identification.forms.REPORTED`)
DISPLAY = {k: display_unit(u) for k, u in REPORTED.items()}
#: a form parameter → the closed-form rod estimate (``IdentificationResult.rod``) of the same quantity
ROD_ESTIMATE = {"k1": "EA", "EA1": "EA", "EA": "EA", "EI1": "EI", "EI": "EI", "D_a": "D_a", "D_eff": "D_eff"}
#: the two models of the validation, as the tables and figures name them
FEM_NAME, REDUCED_NAME = "FEM", "reduced model"


def _fmt(v, scale=1.0, digits=4) -> str:
    if v is None or not np.isfinite(v):
        return "–"
    return f"{v * scale:.{digits}g}"


def _mm(v) -> str:
    return "–" if v is None else f"{1e3 * v:.2f}"


def report_figures(ident: IdentificationResult, validation: Optional[ValidationResult] = None,
                   stiffness: Optional[dict] = None, friction: Optional[dict] = None) -> dict:
    """{name: PNG bytes} of every figure the report shows (a figure with nothing to show is left out)."""
    out = {"forms": figs.forms_figure(ident.comparison)}
    f = ident.fit
    out["correlation"] = figs.correlation_figure(list(f.names), f.correlation)
    ho = ident.heldout_errors
    targets = {} if validation is None else {
        k: t["target"] for k, t in (("tip", validation.targets.get("shape_pct")),
                                    ("compliance", validation.targets.get("compliance_pct"))) if t}
    L = ident.params.length
    out["residuals"] = figs.residuals_figure(ident.train.labels, f.tip_errors(),
                                             None if ident.heldout is None else ident.heldout.labels, ho,
                                             target_m=targets.get("tip", SHAPE_TARGET_PCT) / 100 * L,
                                             target_note=f" ({targets.get('tip', SHAPE_TARGET_PCT):g} % L)")
    if validation is not None and validation.rows:
        train = {a: figs.training_points(ident.train, f.tip_errors(), L, against=a) for a in figs.AGAINST}
        out["error_map"] = figs.error_map_figure(validation.rows, validation.fem_error, targets=targets, train=train)
        out["shapes"] = figs.shapes_figure(validation.rows)
        out["ellipses"] = figs.ellipses_figure(validation.rows)
        out["shapes_3d"] = figs.view3d_figure(validation.rows)
    if stiffness is not None:
        out["stiffness"] = figs.stiffness_figure(stiffness)
    if friction:
        out["friction"] = figs.friction_figure(friction)
    return {k: v for k, v in out.items() if v}


def param_rows(ident: IdentificationResult) -> list[dict]:
    """The chosen form's own parameters (the names of its fit and correlation matrix) with their units."""
    f = ident.fit
    rod = ident.rod or {}
    rows = []
    for k, unit, v in zip(f.form.names, f.form.units, f.theta):
        scale, shown = display_unit(unit)
        lo, hi = f.ci95.get(k, (None, None))
        est = rod.get(ROD_ESTIMATE.get(k, ""))
        given = f.held_at.get(k) == MEASURED_SHEAR          # held at a measured value: shown with it
        rows.append({"name": k, "meaning": MEANINGS.get(k, ""), "value": _fmt(v, scale),
                     "ci": MEASURED_SHEAR if given else f"{_fmt(lo, scale)} … {_fmt(hi, scale)}", "unit": shown,
                     "identifiable": bool(f.identifiable.get(k, False)) or given,
                     "estimate": "" if est is None else _fmt(est, scale)})
    return rows


def derived_rows(ident: IdentificationResult) -> list[dict]:
    """The values every form reports (:data:`validation.identification.forms.REPORTED`), derived from the chosen form at λ = 1."""
    rows = []
    for k, v in ident.values.items():
        scale, unit = DISPLAY.get(k, (1.0, ""))
        lo, hi = ident.ci95.get(k, (None, None))
        given = MEASURED_SHEAR in ident.fit.reasons.get(k, "") and v is not None
        rows.append({"name": k, "meaning": MEANINGS.get(k, ""), "value": _fmt(v, scale),
                     "ci": ident.fit.reasons[k] if given else f"{_fmt(lo, scale)} … {_fmt(hi, scale)}", "unit": unit,
                     "identifiable": bool(ident.identifiable.get(k, False)) and v is not None})
    return rows


def choice_rule(ident: IdentificationResult) -> str:
    """How the form was chosen, from what the comparison rows hold: on the held-out tip error alone, or on the tip
    error and the mean held-out compliance error when every fitted form has the latter
    (:func:`validation.identification.identify._choose`)."""
    pct = round(100 * (PARSIMONY - 1))
    fitted = [r for r in ident.comparison if "heldout_rms_tip_m" in r]
    if fitted and all("heldout_compliance_error_pct" in r for r in fitted):
        return (f"the simplest form within {pct} % of the best on both the held-out RMS tip error and the mean "
                f"held-out compliance error (tensions held and tendons locked) is chosen")
    if fitted:
        return f"the simplest form within {pct} % of the best held-out RMS tip error is chosen"
    return f"the simplest form within {pct} % of the best training RMS tip error is chosen (no held-out states)"


def _form_rows(ident: IdentificationResult) -> list[dict]:
    rows = []
    for r in ident.comparison:
        rows.append({"form": r["form"], "n_params": r["n_params"], "chosen": r.get("chosen", False),
                     "failed": r.get("failed") or r.get("heldout_failed"),
                     "train_rms": _mm(r.get("train_rms_tip_m")), "train_max": _mm(r.get("train_max_tip_m")),
                     "heldout_rms": _mm(r.get("heldout_rms_tip_m")), "heldout_max": _mm(r.get("heldout_max_tip_m")),
                     "not_identifiable": ", ".join(r.get("not_identifiable", [])) or "–"})
    return rows


def _loads(r: dict) -> str:
    T = ", ".join(f"{t:g}" for t in r["tensions_N"])
    s = f"T = ({T}) N, p = {r['pressure_Pa'] / 1e3:g} kPa"
    F = np.asarray(r["tip_force_N"], float)
    if np.any(F):
        s += ", F = (" + ", ".join(f"{x:g}" for x in F) + ") N"
    return s + (", gravity" if r.get("gravity") else "")


def _fem_error_cell(fe: Optional[dict]) -> tuple[str, str]:
    """(text, css class) of a held-out state's FEM discretisation error (:func:`validation.checks.fem_error.assess`):
    measured (its directions), or an estimate (named as such; its basis in section 3a)."""
    if fe is None or fe.get("fem_tip_error_pct") is None:
        return "not estimated", "na"
    if fe.get("measured"):
        parts = ", ".join(f"{d} {x['tip_error_pct']:.3f}" for d, x in (fe.get("fem_by_direction") or {}).items())
        return f"{fe['fem_tip_error_pct']:.3f} (measured{': ' + parts if parts else ''})", ""
    return f"{fe['fem_tip_error_pct']:.3f} (estimate)", "muted"


#: a state's verdicts as the validation table shows them
VERDICT_WORDS = {"fails": "fails", "undecided": "undecided", "passes": "passes"}


def _verdict_cell(fe: Optional[dict]) -> tuple[str, str]:
    """(text, css class) of a state's verdicts per quantity (:func:`validation.checks.fem_error.verdict`)."""
    if fe is None:
        return "–", "na"
    by = {}
    for q, v in (fe.get("verdicts") or {}).items():
        if v:
            by.setdefault(v, []).append(QUANTITY_NAMES[q])
    text = "; ".join(f"{VERDICT_WORDS[v]}: {', '.join(by[v])}" for v in ("fails", "undecided") if v in by)
    css = "bad" if "fails" in by else ("na" if "undecided" in by else "")
    return text or "all pass", css


def _fem_error_rows(val: ValidationResult) -> list[dict]:
    """The rows of the report's discretisation-error table: every held-out state, measured or estimated."""
    fe = val.fem_error or {}
    est = {r["label"]: r for r in (fe.get("estimate") or {}).get("rows", [])}
    out = []
    for r in fe.get("rows", []):
        e = est.get(r["label"], {})
        by = r.get("fem_by_direction") or {}
        out.append({"label": r["label"], "deformation_mm": _mm(r.get("deformation_m")),
                    # the estimate's rule is stated once above the table (fem_error["estimate_basis"])
                    "basis": "measured" if r.get("measured") else ("estimate" if fe.get("estimate_basis")
                                                                    else r.get("basis", "")),
                    "measured": bool(r.get("measured")),
                    "model_tip_pct": _fmt(r.get("model_tip_error_pct"), digits=3),
                    "along_pct": _fmt((by.get("along") or {}).get("tip_error_pct"), digits=3),
                    "through_pct": _fmt((by.get("through") or {}).get("tip_error_pct"), digits=3),
                    "fem_tip_pct": _fmt(r.get("fem_tip_error_pct"), digits=3),
                    "fem_tip_mm": _mm(r.get("fem_tip_error_m")), "fem_shape_pct": _fmt(r.get("fem_shape_error_pct"), digits=3),
                    "fem_ct": _fmt(r.get("fem_C_tension_error_pct"), digits=3),
                    "fem_cl": _fmt(r.get("fem_C_locked_error_pct"), digits=3),
                    "rate": "–" if not e.get("rate") else
                    _fmt(e.get("rate"), digits=3) + (" (observed)" if e.get("rate_observed") else " (assumed)")})
    return out


def _locked_by_sign_cell(r: dict) -> str:
    """A state with a slack tendon: the locked-compliance error for each sign of the load direction, with the tendons
    that sign makes taut (numbered from 1; the same set in both models, else both are shown) — '' otherwise."""
    parts = []
    for s in r.get("locked_by_sign") or []:
        d = np.asarray(s["direction"], float)
        axis = "xyz"[int(np.argmax(np.abs(d)))]
        sign = "+" if d[int(np.argmax(np.abs(d)))] > 0 else "−"
        tf = ",".join(str(i + 1) for i in s["taut_fem"]) or "none"
        ta = ",".join(str(i + 1) for i in s["taut_ancf"]) or "none"
        taut = tf if tf == ta else f"FEM {tf}, model {ta}"
        parts.append(f"{sign}{axis}: {s['error_pct']:.1f} (taut {taut})")
    return " · ".join(parts)


def _validation_rows(val: ValidationResult) -> list[dict]:
    out = []
    fem = {r["label"]: r for r in (val.fem_error or {}).get("rows", [])}
    estimated = bool((val.fem_error or {}).get("estimated"))
    for r in val.rows:
        cell, css = _fem_error_cell(fem.get(r["label"]) if estimated else None)
        vtext, vcss = _verdict_cell(fem.get(r["label"]))
        out.append({"label": r["label"], "loads": _loads(r), "tip_mm": _mm(r["tip_error_m"]),
                    "gravity": "on" if r.get("gravity") else "off", "fem_error": cell, "fem_error_class": css, "verdict": vtext, "verdict_class": vcss,
                    "tip_pct": f"{r['tip_error_pct']:.2f}", "shape_pct": f"{r['shape_error_pct']:.2f}",
                    "ct": _fmt(r.get("C_tension_error_pct"), digits=3), "cl": _fmt(r.get("C_locked_error_pct"), digits=3),
                    "cl_signs": _locked_by_sign_cell(r),
                    "ratio_fem": _fmt(r.get("ratio_z_fem"), digits=3), "ratio_ancf": _fmt(r.get("ratio_z_ancf"), digits=3)})
    return out


def _ratio_rows(val: ValidationResult) -> list[dict]:
    """Section 3b: the locked/held vertical stiffness ratio per state, FEM and reduced model side by side."""
    rows = {r["label"]: r for r in val.rows}
    out = []
    for q in val.ratio_per_state:
        d = q["difference_pct"]
        out.append({"label": q["label"], "loads": _loads(rows[q["label"]]) if q["label"] in rows else "",
                    "fem": _fmt(q["fem"], digits=3), "ancf": _fmt(q["ancf"], digits=3),
                    "difference": f"{d:+.1f}" if np.isfinite(d) else "–",
                    "taut_fem": ", ".join(str(i + 1) for i in q["taut_fem"]) or "none",
                    "taut_ancf": ", ".join(str(i + 1) for i in q["taut_ancf"]) or "none"})
    return out


#: the quantities of the verdict rule (validation.checks.fem_error.QUANTITIES), as the headline names them
QUANTITY_NAMES = {"tip": "tip position", "shape": "shape", "C_locked": "locked compliance",
                  "C_tension": "tension-held compliance"}
#: the headline's order within one status (the locked compliance is LACC's)
HEADLINE_ORDER = ("C_locked", "C_tension", "tip", "shape")
#: the validation target (validation.checks.compare) each quantity falls under
TARGET_OF = {"tip": "shape_pct", "shape": "shape_pct", "C_locked": "compliance_pct", "C_tension": "compliance_pct"}


def _row_at(rows: list, key: str, value: float) -> Optional[dict]:
    """The row whose ``key`` is the stated worst ``value`` (nearest finite one), None without one."""
    cand = [r for r in rows if r.get(key) is not None and np.isfinite(r[key])]
    return min(cand, key=lambda r: abs(r[key] - value)) if cand and np.isfinite(value) else None


def _where(row: Optional[dict]) -> str:
    """" at state <label> (<its loads>)", the loads left out when the label already states the pressure."""
    if row is None:
        return ""
    return f" at state {row['label']}" + ("" if "kPa" in row["label"] else f" ({_loads(row)})")


def _lacc_meaning(mode: str, row: Optional[dict]) -> str:
    """What a failing compliance means for LACC (controller/lacc.py).  Along z, with the FEM as the plant, one
    step ΔF̂ = C'_p⁻¹ e leaves e' = (1 − C_plant/C_model) e = −ε e, ε = k_model/k_plant − 1 (the row's signed
    locked k_z error): a Newton step with a wrong slope."""
    if mode == "tension":
        return ("For the controller: LACC uses the tensions-held compliance to choose which tendons go taut "
                "(δl = J_l C_q δF̂, Sec. III-D); its error matters where it changes that choice.")
    text = ("For the controller: LACC turns each measured tip error e into its load-estimate step through the "
            "locked compliance (ΔF̂ = C'_p⁻¹ e, Algorithm 1 line 10)")
    k = None if row is None else row.get("k_locked_z_error_pct")
    if k is None or not np.isfinite(k):
        return text + "; its error makes that step too large or too small, so the loop needs more iterations."
    if abs(k) >= 100:
        return (text + f"; with the model's vertical stiffness {k:+.0f} % off, one step would not shrink a vertical "
                "error (a stiffness error of 100 % or more): the loop relies on its trust region and fallback.")
    how = "overshooting: the model is stiffer" if k > 0 else "falling short: the model is softer"
    return (text + f"; with a plant like the FEM one step leaves about {-k:+.0f} % of a vertical error ({how}; "
            "0 % for an exact compliance): more iterations to the tolerance, not a worse end position, since the "
            "loop closes on the measured tip.")


def _verdicts(val: ValidationResult) -> dict:
    """The verdicts the headline presents: the validation's own (:func:`validation.checks.fem_error.assess`) or,
    when it carries none, the same rule with the FEM taken as exact."""
    fe = val.fem_error or {}
    if fe.get("quantities"):
        return fe
    from validation.checks.fem_error import assess
    return assess(val, None)


def _num(q: str, x: float) -> str:
    """A value of quantity ``q`` with its unit: % of L (2 decimals) or % (1 decimal)."""
    return f"{x:.2f} % of L" if q in ("tip", "shape") else f"{x:.1f} %"


def _fem_beside(q: str, row: dict, key: str) -> str:
    """"; the FEM's own error there ±x (measured / estimate)", or "" when the FEM is taken as exact."""
    f = row.get(f"fem_{key}")
    if f is None:
        return ""
    return f"; the FEM's own error there ±{_num(q, f)}, {'measured' if row.get('measured') else 'an estimate'}"


def _controller_meaning(q: str, vrow: Optional[dict]) -> str:
    if q == "C_locked":
        return _lacc_meaning("locked", vrow)
    if q == "C_tension":
        return _lacc_meaning("tension", vrow)
    what = "centreline" if q == "shape" else "tip"
    return (f"For the controller: the reduced model's IK commands a {what} off by up to that much, and LACC, which "
            "sees only the tip, reads the tip part of such a model error as a load.")


def _stiffness_note(q: str, vrow: Optional[dict]) -> str:
    mode = {"C_locked": "locked", "C_tension": "tension"}.get(q)
    k = None if mode is None or vrow is None else vrow.get(f"k_{mode}_z_error_pct")
    if k is None or not np.isfinite(k):
        return ""
    return (f"; there the reduced model's vertical stiffness k_z is {k:+.0f} % against the FEM's "
            f"({'stiffer' if k > 0 else 'softer'})")


def _quantity_item(q: str, t: dict, by: dict, vrows: dict) -> Optional[dict]:
    """The headline item of one quantity from its per-state verdicts ``t`` (fails, undecided, passes)."""
    key, target = t["key"], t["target"]
    n = sum(len(t[k]) for k in ("fails", "undecided", "passes"))
    if not n:
        return None
    name = QUANTITY_NAMES[q].capitalize()
    tgt = f"the {target:g} {'% of L' if q in ('tip', 'shape') else '%'} target"
    m = lambda lb: by[lb][f"model_{key}"]                           # noqa: E731
    f = lambda lb: by[lb].get(f"fem_{key}") or 0.0                  # noqa: E731
    if t["fails"]:
        lb = max(t["fails"], key=lambda x: m(x) - f(x))
        others = (f" It fails on {len(t['fails'])} of {n} states" + (f", is undecided on {len(t['undecided'])}"
                  if t["undecided"] else "") + ".") if n > 1 else ""
        return {"status": "fails", "anchor": "sec-validation", "severity": (m(lb) - f(lb)) / target, "label": lb,
                "text": f"{name}: error {_num(q, m(lb))}{_where(vrows.get(lb))} against {tgt} "
                        f"({m(lb) / target:.1f} × the target{_fem_beside(q, by[lb], key)}){_stiffness_note(q, vrows.get(lb))}."
                        f"{others} " + _controller_meaning(q, vrows.get(lb))}
    if t["undecided"]:
        lb = max(t["undecided"], key=m)
        return {"status": "undecided", "anchor": "sec-fem-error", "severity": m(lb) / target, "label": lb,
                "text": f"{name}: undecided on {len(t['undecided'])} of {n} states — error {_num(q, m(lb))}"
                        f"{_where(vrows.get(lb))} with the FEM's own error ±{_num(q, f(lb))} straddles {tgt} "
                        f"({_num(q, max(m(lb) - f(lb), 0.0))} … {_num(q, m(lb) + f(lb))}); a finer FEM mesh decides"
                        + (f"; passes on the other {len(t['passes'])}." if t["passes"] else ".")}
    lb = max(t["passes"], key=lambda x: m(x) + f(x))
    fem = f" (with the FEM's own error ±{_num(q, f(lb))}: ≤ {_num(q, m(lb) + f(lb))})" if by[lb].get(f"fem_{key}") else ""
    return {"status": "passes", "anchor": "sec-validation", "severity": (m(lb) + f(lb)) / target,
            "text": f"{name}: worst error {_num(q, m(lb))}{_where(vrows.get(lb))}{fem}, within {tgt} on all {n} states."}


def _target_items(val: ValidationResult) -> list[dict]:
    """The headline items: per quantity (locked and tension-held compliance, tip position, shape) the verdict of
    :func:`validation.checks.fem_error.verdict` over the held-out states; a validation target that was not
    checked on every state (:func:`validation.checks.compare`) stays one "incomplete" item instead."""
    out, skip = [], set()
    names = {"shape_pct": "shape error", "compliance_pct": "compliance error"}
    for key, t in val.targets.items():
        if t.get("status") == "incomplete":
            missing = ", ".join(t.get("incomplete") or []) or "every state"
            out.append({"status": "incomplete", "anchor": "sec-validation", "severity": 0.0,
                        "text": f"{names.get(key, key).capitalize()} (target {t['target']:g} %): not checked on "
                                f"{missing}; the verdict is incomplete."})
            skip.add(key)
    fe = _verdicts(val)
    by = {r["label"]: r for r in fe.get("rows", [])}
    vrows = {r["label"]: r for r in val.rows}
    for q in HEADLINE_ORDER:
        t = (fe.get("quantities") or {}).get(q)
        if t is None or TARGET_OF[q] in skip:
            continue
        item = _quantity_item(q, t, by, vrows)
        if item is not None:
            out.append(item)
    return out


def _fem_error_note(fe: Optional[dict]) -> tuple[Optional[dict], Optional[str]]:
    """(headline item or None, note or None) of the FEM's own discretisation error
    (:func:`validation.checks.fem_error.assess`)."""
    if not fe:
        return None, None
    if not fe.get("estimated"):
        return {"status": "incomplete", "anchor": "sec-fem-error", "severity": 0.0,
                "text": "The FEM's discretisation error was not estimated: the verdicts assume the FEM is exact."}, None
    if not fe.get("n_measured"):
        return {"status": "incomplete", "anchor": "sec-fem-error", "severity": 0.0,
                "text": "The FEM's discretisation error was not measured on any held-out state: the verdicts "
                        "assume the FEM is exact."}, None
    by_dir = {}
    for r in fe.get("rows", []):
        for d, x in (r.get("fem_by_direction") or {}).items():
            by_dir[d] = max(by_dir.get(d, 0.0), x.get("tip_error_pct") or 0.0)
    dirs = ", ".join(f"{d} up to {v:.2f} %" for d, v in by_dir.items())
    return None, (f"FEM discretisation error measured on the {fe['n_measured']} most deformed held-out states: tip up "
                  f"to {fe['max_fem_tip_error_pct']:.2f} % of L ({dirs}); the other states carry estimates "
                  f"(section 3a). Each verdict reads the FEM's error beside the model's: {fe.get('rule', '')}.")


def _cycle_misses(r: dict) -> tuple[float, str]:
    """(the worst ratio error / target of one compared cycle, what it is in words)."""
    parts = [(r["loop_error_pct"] / LOOP_TARGET_PCT, f"loop area rod / {FEM_NAME} {r['loop_ratio']:.2f} "
                                                     f"({r['loop_error_pct']:.1f} % off, target {LOOP_TARGET_PCT:g} %)")]
    for b in ("loading", "unloading"):
        x = r[f"tip_{b}_mean_pct"]
        parts.append((x / TIP_TARGET_PCT, f"mean tip error on the {b} branch {x:.2f} % of L (target {TIP_TARGET_PCT:g} %)"))
    worst = max(p[0] for p in parts)
    return worst, "; ".join(t for v, t in parts if v > 1.0) or "; ".join(t for _, t in parts)


def friction_item(friction: Optional[dict]) -> Optional[dict]:
    """The headline item of the tendon friction check (:func:`validation.checks.hysteresis.verdict`), or None
    without one.  The FEM is taken as exact (its error is not estimated for the cycles)."""
    if not friction:
        return None
    judged = [r for r in friction["rows"] if r.get("role") != "fit"]
    mu = f"μ = {friction['mu_used']:.3g}, {_mu_source_text(friction)}"
    status = friction["status"]
    if status == "incomplete":
        bad = [f"{r['pressure_kPa']:g} kPa ({r['error']})" for r in judged if r.get("error")]
        return {"status": "incomplete", "anchor": "sec-friction", "severity": 0.0,
                "text": f"Tendon friction ({mu}): not every cycle could be compared: {', '.join(bad) or 'none judged'}."}
    compared = [(r, *_cycle_misses(r)) for r in judged if not r.get("error")]
    r, worst, what = max(compared, key=lambda x: x[1])
    which = "in-sample: the cycle μ was fitted to" if r["role"] == "in-sample" else "a cycle not used for μ"
    if status == "fails":
        n_bad = sum(1 for x in compared if x[0]["passes"] is False)
        return {"status": "fails", "anchor": "sec-friction", "severity": worst,
                "text": f"Tendon friction hysteresis ({mu}): at {r['pressure_kPa']:g} kPa ({which}) {what} — "
                        f"{worst:.1f} × the target, the {FEM_NAME} taken as exact; fails on {n_bad} of "
                        f"{len(compared)} judged cycle(s)."}
    return {"status": "passes", "anchor": "sec-friction", "severity": worst,
            "text": f"Tendon friction hysteresis ({mu}): within the loop-area ({LOOP_TARGET_PCT:g} %) and tip "
                    f"({TIP_TARGET_PCT:g} % of L) targets on all {len(compared)} judged cycle(s); worst at "
                    f"{r['pressure_kPa']:g} kPa ({which}): {worst:.2f} × the target."}


def _mu_source_text(friction: dict) -> str:
    """How the rod's μ was found, in words."""
    fit = friction.get("fit")
    if friction["mu_source"] == "identified" and fit:
        return (f"identified from the {FEM_NAME}'s cycle at {fit['pressure_kPa']:g} kPa, 95 % interval "
                f"{fit['interval'][0]:.3g} … {fit['interval'][1]:.3g}; the design states {friction['mu_design']:g}")
    return f"the design's μ (no fit: the {FEM_NAME}'s cycle for it failed)"


def headline(val: Optional[ValidationResult], friction: Optional[dict] = None) -> dict:
    """The report's headline, failures first: {"fails": [item, …] (worst first: (model − FEM error) / target),
    "undecided": […], "incomplete": […], "passes": […], "notes": [str]}; an item is {"status", "text", "anchor"
    (the section's id), "severity"}.  Only presents the verdicts of
    :func:`validation.checks.fem_error.assess` (or, for a validation without them, the same rule with the FEM
    taken as exact); decides none.  ``friction``: the tendon friction check, one more item
    (:func:`friction_item`)."""
    items = [] if val is None else _target_items(val)
    if friction_item(friction) is not None:
        items.append(friction_item(friction))
    fe_item, fe_note = _fem_error_note(None if val is None else val.fem_error)
    if fe_item is not None:
        items.append(fe_item)
    out = {k: [i for i in items if i["status"] == k] for k in ("fails", "undecided", "incomplete", "passes")}
    out["fails"].sort(key=lambda i: -i["severity"])
    out["undecided"].sort(key=lambda i: -i["severity"])
    notes = [] if fe_note is None else [fe_note]
    if val is None:
        notes.append("No validation against the FEM: the model was identified from measured states; its held-out "
                     "tip errors are in section 2.")
    if val is not None and val.failures:
        out["incomplete"].append({"status": "incomplete", "anchor": "sec-validation", "severity": 0.0,
                                  "text": f"{len(val.failures)} held-out state(s) could not be compared: "
                                          + ", ".join(f"{f['label']} ({f['model']})" for f in val.failures) + "."})
    out["notes"] = notes
    return out


def _matrix(C) -> str:
    return "\n".join(" ".join(f"{1e3 * x:9.3f}" for x in row) for row in np.asarray(C, float))


def _compliance_example(val: ValidationResult) -> Optional[dict]:
    rows = [r for r in val.rows if "C_tension_fem" in r]
    if not rows:
        return None
    r = rows[0]
    return {"label": r["label"], "mats": [{"name": f"C ({m})", "fem": _matrix(r[f"C_{m}_fem"]),
                                           "ancf": _matrix(r[f"C_{m}_ancf"])} for m in ("tension", "locked")]}


def _shear_note(params) -> str:
    """What the chosen reduced model does with the FEM's rotation-free lateral compliance (ancf.shear)."""
    sc = tuple(getattr(params, "shear_compliance", ()) or ())
    if any(sc):
        from ancf.shear import compliance
        return (f"the chosen form carries it as a series shear compliance, s = {1e3 * compliance(sc, 0.0):.2f} / "
                f"{1e3 * compliance(sc, 100e3):.2f} mm/N at 0 / 100 kPa")
    return ("the chosen reduced model has no shear compliance and misses that share (the form "
            "'pressure_ei_shear' adds one)")


def _law_dependence(params, key: str) -> str:
    """What the chosen law's ``key`` ("EA" or "EI") depends on, in words, from its pressure factor."""
    coeffs = getattr(params.stiffness, f"{key}_pressure", ()) if params is not None else ()
    if coeffs:
        return (f"the law's dependence on stretch and pressure ({key}(λ) · ({pressure_factor_text(coeffs)}), "
                "p̂ = p / 100 kPa)")
    return "the law's dependence on stretch alone"


def _ratio_note(val: ValidationResult) -> str:
    """The locked/held ratio, FEM against reduced model, in words (which is lower, from the means)."""
    f, a = val.ratio["fem"]["mean"], val.ratio["ancf"]["mean"]
    if not (np.isfinite(f) and np.isfinite(a)):
        return ""
    if f < a:
        return ("The FEM's ratio is the lower one on average, as where its tip moves sideways without turning "
                "(shear-like, growing with pressure), which locked tendons cannot hold; ")
    return "The reduced model's ratio is not above the FEM's on average; "


def _diagnostics(ident: IdentificationResult, val: Optional[ValidationResult], stiffness: Optional[dict]) -> list[str]:
    d = []
    v = ident.values
    for k, paper in PAPER_DIAMETERS_MM.items():
        if v.get(k) is not None:
            d.append(f"{k} = {1e3 * v[k]:.2f} mm (the paper identifies {paper} mm for its bellows).")
        elif k in v:
            d.append(f"{k} is not identifiable from these data (the paper identifies {paper} mm for its bellows); "
                     "add states that excite it (pressure steps for D_eff, bending for D_a).")
    if v.get("a") is not None and v.get("EA") is not None:
        a = v["a"]
        trend = "softens" if a < 0 else "stiffens"
        d.append(f"Axial law EA(λ) = a λ + b with a = {a:.4g} N: the axial stiffness {trend} with stretch "
                 f"(EA(1) = {v['EA']:.4g} N). The product's axial energy uses the Green strain, which stiffens by "
                 "itself" + ("; this negative slope compensates part of that (docs/identification.md)." if a < 0
                             else " (docs/identification.md)."))
        if a > 0 and v.get("b") is not None and v["b"] < 0:
            d.append(f"The linear law reaches zero stiffness at λ = {-v['b'] / a:.3f}: states compressed further are "
                     "outside the law's validity.")
        elif a < 0:
            d.append(f"The linear law reaches zero stiffness at λ = {-v['b'] / a:.3f} in extension: states stretched "
                     "further are outside the law's validity.")
    if ident.rod:
        r = ident.rod
        d.append("Closed-form first estimate from the unloaded FEM's condensed cap tangent: "
                 f"EA = {r.get('EA', float('nan')):.4g} N, EI = {r.get('EI', float('nan')):.4g} N m², "
                 f"D_a = {1e3 * r.get('D_a', float('nan')):.2f} mm, blocked-force D_eff = "
                 f"{1e3 * r.get('D_eff', float('nan')):.2f} mm.")
    failed = (ident.meta or {}).get("failed_cases") or []
    if failed:
        d.append(f"The FEM did not converge on {len(failed)} load case(s), left out of the fit and the validation: "
                 + "; ".join(f"{f['label']} ({f['role']})" for f in failed) + ".")
    if ident.rod:
        for key, what in (("EA", "axial"), ("EI", "bending")):
            fitted, lin = v.get(key), ident.rod.get(key)
            if fitted is not None and lin and abs(fitted / lin - 1) > 0.10:
                d.append(f"The fitted {what} stiffness at rest ({key} = {fitted:.4g}) differs by "
                         f"{100 * (fitted / lin - 1):+.0f} % "
                         f"from the FEM's small-load tangent ({lin:.4g}): over the training loads the FEM is "
                         f"{'stiffer' if fitted > lin else 'softer'} than at rest in a way "
                         f"{_law_dependence(ident.params, key)} does not follow.")
        if ident.rod.get("EI_tip_force") and ident.rod.get("EI"):
            sh = ident.rod["EI"] / ident.rod["EI_tip_force"] - 1
            d.append(f"Shear: a tip force bends the unloaded FEM {100 * abs(sh):.1f} % {'more' if sh >= 0 else 'less'} "
                     "than its pure-moment EI predicts; " + _shear_note(ident.params) + ".")
    if ident.not_identifiable:
        d.append("Not identifiable: " + ", ".join(ident.not_identifiable) + ". The fit held these at its first-pass "
                 "optimum and refitted the rest (fit.json: 'held'); the actuator file marks them.")
    if val is not None and val.ratio:
        d.append(f"Locked/constant-tension vertical stiffness ratio on the held-out states: FEM "
                 f"{val.ratio['fem']['mean']:.2f} (max {val.ratio['fem']['max']:.2f}), reduced model "
                 f"{val.ratio['ancf']['mean']:.2f} "
                 f"(max {val.ratio['ancf']['max']:.2f}); the paper reports \"about twice\". " + _ratio_note(val)
                 + _shear_note(ident.params) + " (section 3b; docs/identification.md §4b).")
    if val is not None and val.failures:
        d.append(f"{len(val.failures)} held-out state(s) could not be compared: "
                 + "; ".join(f"{f['label']} ({f['model']}: {f['error']})" for f in val.failures))
    if stiffness is not None and stiffness.get("failures"):
        d.append(f"{len(stiffness['failures'])} state(s) of the stiffness study failed.")
    d.append(f"Model selection: {choice_rule(ident)} (chosen: '{ident.form}').")
    return d


def _f(v, fmt) -> str:
    return "–" if v is None else format(v, fmt)


def _modes_rows(modes: Optional[dict]) -> list[dict]:
    """The Dynamics table's rows (text) from :func:`validation.checks.modes_compare.compare_modes`."""
    if not modes:
        return []
    computed = modes.get("fem") == "computed"
    out = []
    for r in modes["rows"]:
        fem_err = r.get("fem_error") or ""
        note = "" if computed and not fem_err else (fem_err or modes.get("fem", ""))
        out.append({"p": f"{r['pressure_kPa']:g}", "fem_b": _f(r["fem_bending_frequency_hz"], ".3f"),
                    "rod_b": _f(r["rod_bending_frequency_hz"], ".3f"), "d_b": _f(r["bending_difference_pct"], "+.1f"),
                    "fem_a": _f(r["fem_axial_frequency_hz"], ".2f"), "rod_a": _f(r["rod_axial_frequency_hz"], ".2f"),
                    "d_a": _f(r["axial_difference_pct"], "+.1f"),
                    "zeta": _f(r.get("rod_first_mode_damping_ratio"), ".4f"),
                    "fem_note": note, "rod_error": r.get("rod_error") or ""})
    return out


def friction_rows(friction: Optional[dict]) -> list[dict]:
    """The friction section's table rows (text cells; verdict "pass"/"fail"/"" for the cycle μ was fitted to)."""
    out = []
    for r in (friction or {}).get("rows", []):
        row = {"p": f"{r['pressure_kPa']:g}", "role": {"fit": "used for μ", "validation": "validation",
                                                        "in-sample": "used for μ (in-sample)"}[r["role"]],
               "error": r.get("error", "")}
        if not row["error"]:
            row.update({k: f"{r[k]:.2f}" for k in ("loop_rod_Nmm", "loop_fem_Nmm", "loop_ratio", "tip_loading_mean_pct",
                                                    "tip_loading_max_pct", "tip_unloading_mean_pct",
                                                    "tip_unloading_max_pct")})
            row["verdict"] = "" if r["role"] == "fit" else ("pass" if r["passes"] else "fail")
        out.append(row)
    return out


def _friction_text(friction: dict) -> str:
    """The section's sentence on μ: stated by the design, identified (with its interval), which cycles judge it."""
    fit = friction.get("fit")
    text = (f"The design states μ = {friction['mu_design']:g}; the {FEM_NAME} solves every cycle with it. ")
    if friction["mu_source"] == "identified" and fit:
        text += (f"The reduced model's μ = {fit['mu']:.4g} (95 % interval {fit['interval'][0]:.4g} … "
                 f"{fit['interval'][1]:.4g}, from the {fit['basis']}; RMS residual {fit['residual_rms_mm']:.3f} mm) "
                 f"is identified from the {FEM_NAME}'s tip data of the cycle at {fit['pressure_kPa']:g} kPa — the gap "
                 "between its branches, unloading − loading tip at each tension, which a static or stiffness "
                 "difference of the models leaves out (every other parameter held) — and written to the actuator "
                 "file. ")
        text += ("This quick report has that one cycle only: its numbers are in-sample (the full report validates "
                 "μ on the cycles at 0 and the largest pressure)." if friction["in_sample"] else
                 "The other cycles are not used for it and validate it.")
    else:
        text += (f"The {FEM_NAME}'s cycle to identify μ from failed: the reduced model takes the design's μ, "
                 "written to the actuator file; every compared cycle validates it.")
    return text


def _provenance_rows(ident: IdentificationResult, command: Optional[str]) -> list:
    p = ident.provenance
    rows = [("created", p.get("created", "")), ("git revision", p.get("git_revision", "")),
            ("platform", p.get("platform", ""))]
    rows += [(f"version of {k}", v) for k, v in sorted(p.get("versions", {}).items())]
    for k, v in (ident.meta or {}).items():
        if k == "failed_cases":
            continue
        if k in ("geometry", "material"):
            v = ", ".join(f"{kk}={vv}" for kk, vv in v.items())
        rows.append((k, v))
    if command:
        rows = [r for r in rows if r[0] != "command"] + [("command", command)]
    return rows


def sections(validation: Optional[ValidationResult], stiffness: Optional[dict], modes: Optional[dict],
             has_ratio: bool, friction: Optional[dict] = None) -> list[dict]:
    """The report's sections in order, numbered as shown, each {"id" (its anchor), "title", "level" (2 or 3)}:
    the table of contents and every heading come from this one list."""
    out = [("sec-params", "Identified parameters", 2), ("sec-forms", "Model forms compared", 2)]
    if validation is not None:
        out += [("sec-validation", "Reduced model vs FEM on held-out states", 2),
                ("sec-fem-error", "The FEM's own discretisation error", 3)]
        if has_ratio:
            out.append(("sec-ratio", "Locked / tension-held vertical stiffness ratio per state", 3))
    if stiffness:
        out.append(("sec-stiffness", "Stiffness vs tendon tension (the Fig. 9 protocol)", 2))
    if friction:
        out.append(("sec-friction", "Tendon friction: hysteresis of tension cycles", 2))
    if modes:
        out.append(("sec-dynamics", "Dynamics: first modes per pressure", 2))
    out.append(("sec-diagnostics", "Diagnostics", 2))
    res, n, sub = [], 0, 0
    for sid, title, level in out:
        n, sub = (n + 1, 0) if level == 2 else (n, sub + 1)
        number = f"{n}." if level == 2 else f"{n}{'abcdefgh'[sub - 1]}."
        res.append({"id": sid, "title": f"{number} {title}", "level": level})
    res.append({"id": "sec-provenance", "title": "Provenance", "level": 2})
    return res


def build_report(ident: IdentificationResult, validation: Optional[ValidationResult] = None,
                 stiffness: Optional[dict] = None, *, title: Optional[str] = None, command: Optional[str] = None,
                 toml_name: str = "actuator.toml", figures: Optional[dict] = None,
                 modes: Optional[dict] = None, friction: Optional[dict] = None) -> str:
    """The report as one HTML string (see the module docstring).  ``figures``: PNG bytes from
    :func:`report_figures` (computed if not given); ``modes``: the Dynamics section's data
    (:func:`validation.checks.modes_compare.compare_modes`; no section without it); ``friction``: the tendon
    friction check (:func:`validation.checks.hysteresis.friction_check`; no section without it)."""
    if not isinstance(ident, IdentificationResult):
        raise InputError(f"build_report needs an IdentificationResult, got {type(ident).__name__}")
    import jinja2
    env = jinja2.Environment(loader=jinja2.PackageLoader("validation.report", "templates"),
                             autoescape=jinja2.select_autoescape(["html", "j2"]), undefined=jinja2.StrictUndefined)
    figures = report_figures(ident, validation, stiffness, friction) if figures is None else figures
    import collections
    # a figure not made (or not given) is an empty string, whichever figures the template shows
    b64 = collections.defaultdict(str, {k: base64.b64encode(v).decode("ascii") for k, v in figures.items() if v})
    if ident.source == "fem":
        mesh = (ident.meta or {}).get("mesh", "")
        name = ((ident.meta or {}).get("geometry") or {}).get("name", "")
        what = (ident.meta or {}).get("design") or "bellows"
        source_text = (f"virtual experiments on the 3-D FEM of the {what}{(' ' + repr(name)) if name else ''} "
                       f"({mesh} mesh; {ident.train.n} training and {0 if ident.heldout is None else ident.heldout.n} "
                       "held-out load cases)")
    else:
        source_text = (f"measured static states ({ident.train.n} training, "
                       f"{0 if ident.heldout is None else ident.heldout.n} held out)")
    ctx = {
        "title": title or "Bellows actuator: identification and validation",
        "prov": {k: ident.provenance.get(k, "") for k in ("created", "git_revision", "platform")},
        "source_text": source_text, "form": ident.form, "form_description": ident.fit.form.description,
        "targets": {} if validation is None else {
            {"shape_pct": "shape error", "compliance_pct": "compliance error"}.get(k, k): t
            for k, t in validation.targets.items()},
        "not_identifiable": ident.not_identifiable, "data_warnings": ident.warnings, "params_rows": param_rows(ident),
        "derived_rows": derived_rows(ident), "fem_name": FEM_NAME, "reduced_name": REDUCED_NAME,
        "absolute_sigma": bool(ident.train.has_sigma), "toml_name": toml_name, "toml_text": ident.to_toml(),
        "n_train": ident.train.n, "n_heldout": 0 if ident.heldout is None else ident.heldout.n,
        "choice_rule": choice_rule(ident), "form_rows": _form_rows(ident), "figures": b64,
        "validation": validation, "validation_rows": [] if validation is None else _validation_rows(validation),
        "ratio_rows": [] if validation is None else _ratio_rows(validation),
        "fem_error": None if validation is None else (validation.fem_error or None),
        "fem_error_rows": [] if validation is None else _fem_error_rows(validation),
        "validation_failures": "" if validation is None else "; ".join(
            f"{f['label']} ({f['model']}): {f['error']}" for f in validation.failures),
        "stiffness_axes": None if validation is None else validation.stiffness_error_pct or None,
        "compliance_example": None if validation is None else _compliance_example(validation),
        "n_shape_points": N_SHAPE_POINTS, "stiffness": stiffness,
        "diagnostics": _diagnostics(ident, validation, stiffness),
        "provenance_rows": _provenance_rows(ident, command),
        "modes": modes, "modes_rows": _modes_rows(modes),
        "modes_sentences": [] if not modes else modes_sentences(modes),
        "headline": headline(validation, friction),
        "friction": friction or None, "friction_rows": friction_rows(friction),
        "friction_text": "" if not friction else _friction_text(friction),
        "ratio_note": "" if validation is None else (
            "On a straight tube the difference is the FEM's lateral tip motion without cap rotation, which locked "
            "tendons cannot hold (docs/identification.md §4b); " + _shear_note(validation.params) + "."),
    }
    toc = sections(validation, stiffness, modes, bool(ctx["ratio_rows"]), friction)
    ctx.update(toc=toc, sec={t["id"]: t["title"] for t in toc})
    return env.get_template("report.html.j2").render(**ctx)


def write_report(path, ident: IdentificationResult, validation: Optional[ValidationResult] = None,
                 stiffness: Optional[dict] = None, *, force: bool = False, figures_dir=None,
                 friction: Optional[dict] = None, **kw) -> pathlib.Path:
    """Write :func:`build_report` to ``path`` (.html; not overwritten without ``force``); the figures also go
    to ``figures_dir`` as PNG files if given.  Returns the path."""
    p = prepare_output_file(path, force=force, suffixes=(".html",))
    figures = report_figures(ident, validation, stiffness, friction)
    if figures_dir is not None:
        d = pathlib.Path(figures_dir)
        d.mkdir(parents=True, exist_ok=True)
        for k, v in figures.items():
            if v:
                (d / f"{k}.png").write_bytes(v)
    return atomic_write_text(p, build_report(ident, validation, stiffness, figures=figures, friction=friction, **kw))
