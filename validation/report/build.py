"""One self-contained HTML report of an identification and its validation against the FEM.

:func:`build_report` turns an :class:`~validation.identification.identify.IdentificationResult` (from the FEM or from rig
data), optionally a :class:`~validation.checks.compare.ValidationResult` (held-out states, shapes and compliance
matrices vs the FEM) and the stiffness-vs-tension study (:func:`validation.checks.compare.stiffness_vs_tension`),
into one HTML page that a colleague can open anywhere: figures are embedded as base64 PNG, styles inline,
no script and no network access.  The template is ``validation/report/templates/report.html.j2`` (jinja2).

The page opens with :func:`headline`: what fails, worst first (the quantity — locked or tensions-held
compliance, shape —, its worst held-out state, its value against the target, what it means for LACC), then
what is not checked and what passes, each linked to its section; then a table of contents (:func:`sections`).
Every sentence that states physics or a verdict is made from the numbers it describes (the fitted law's own
pressure factors, the measured errors and their verdicts); none is fixed text.

Sections: identified parameters with 95 % CIs (non-identifiable ones shown as such, never as a number)
and the closed-form first estimate; the model forms compared on held-out error; parameter correlations;
error per state; the reduced model vs the FEM on held-out states (tip, shape, compliance, stiffness
per axis, locked/constant stiffness ratio) beside the FEM's own discretisation error
(:mod:`validation.checks.fem_error`), shape overlays and compliance ellipses; the Fig. 9 analogue;
dynamics (the rod's first bending and axial frequencies beside the FEM's, per pressure:
:mod:`validation.checks.modes_compare`); diagnostics (what the numbers imply, the paper's values beside ours);
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
from validation.checks.compare import N_SHAPE_POINTS, ValidationResult
from validation.identification.forms import MEANINGS, REPORTED, display_unit
from validation.identification.identify import PARSIMONY, IdentificationResult
from validation.checks.modes_compare import modes_sentences, pressure_factor_text
from validation.reference.experiments import EXTRAPOLATION

__all__ = ["build_report", "write_report", "report_figures", "headline", "sections"]

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
                   stiffness: Optional[dict] = None) -> dict:
    """{name: PNG bytes} of every figure the report shows."""
    out = {"forms": figs.forms_figure(ident.comparison)}
    f = ident.fit
    out["correlation"] = figs.correlation_figure(list(f.names), f.correlation)
    ho = ident.heldout_errors
    out["residuals"] = figs.residuals_figure(ident.train.labels, f.tip_errors(),
                                             None if ident.heldout is None else ident.heldout.labels, ho)
    if validation is not None and validation.rows:
        out["shapes"] = figs.shapes_figure(validation.rows)
        ell = figs.ellipses_figure(validation.rows)
        if ell:
            out["ellipses"] = ell
    if stiffness is not None:
        out["stiffness"] = figs.stiffness_figure(stiffness)
    return out


def param_rows(ident: IdentificationResult) -> list[dict]:
    """The chosen form's own parameters (the names of its fit and correlation matrix) with their units."""
    f = ident.fit
    rod = ident.rod or {}
    rows = []
    for k, unit, v in zip(f.form.names, f.form.units, f.theta):
        scale, shown = display_unit(unit)
        lo, hi = f.ci95.get(k, (None, None))
        est = rod.get(ROD_ESTIMATE.get(k, ""))
        rows.append({"name": k, "meaning": MEANINGS.get(k, ""), "value": _fmt(v, scale),
                     "ci": f"{_fmt(lo, scale)} … {_fmt(hi, scale)}", "unit": shown,
                     "identifiable": bool(f.identifiable.get(k, False)),
                     "estimate": "" if est is None else _fmt(est, scale)})
    return rows


def derived_rows(ident: IdentificationResult) -> list[dict]:
    """The values every form reports (:data:`validation.identification.forms.REPORTED`), derived from the chosen form at λ = 1."""
    rows = []
    for k, v in ident.values.items():
        scale, unit = DISPLAY.get(k, (1.0, ""))
        lo, hi = ident.ci95.get(k, (None, None))
        rows.append({"name": k, "meaning": MEANINGS.get(k, ""), "value": _fmt(v, scale),
                     "ci": f"{_fmt(lo, scale)} … {_fmt(hi, scale)}", "unit": unit,
                     "identifiable": bool(ident.identifiable.get(k, False)) and v is not None})
    return rows


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
    """(text, css class) of a held-out state's FEM discretisation error (:func:`validation.checks.fem_error.assess`)."""
    if fe is None:
        return "not estimated", "na"
    if fe.get("measured"):
        return f"{fe['fem_tip_error_pct']:.3f}" + (" — too large" if fe.get("too_large") else ""), \
            ("bad" if fe.get("too_large") else "")
    if fe.get("bound_tip_error_pct") is not None:
        return (f"not measured; bound ≤ {fe['bound_tip_error_pct']:.3f} as measured on {fe['bound_label']} (deformed "
                "more)" + (" — does not rule out too large" if fe.get("bound_too_large") else "")), "na"
    return "not measured (no measured bound)", "na"


def _fem_error_rows(val: ValidationResult) -> list[dict]:
    """The measured FEM error rows of the report's discretisation-error table."""
    fe = val.fem_error or {}
    est = {r["label"]: r for r in (fe.get("estimate") or {}).get("rows", [])}
    out = []
    for r in fe.get("rows", []):
        if not r.get("measured"):
            continue
        e = est.get(r["label"], {})
        out.append({"label": r["label"], "deformation_mm": _mm(r.get("deformation_m")),
                    "model_tip_pct": f"{r['model_tip_error_pct']:.2f}", "fem_tip_pct": f"{r['fem_tip_error_pct']:.3f}",
                    "fem_tip_mm": _mm(r.get("fem_tip_error_m")), "fem_shape_pct": _fmt(r.get("fem_shape_error_pct"), digits=3),
                    "fem_ct": _fmt(r.get("fem_C_tension_error_pct"), digits=3),
                    "fem_cl": _fmt(r.get("fem_C_locked_error_pct"), digits=3),
                    "rate": _fmt(e.get("rate"), digits=3) + (" (observed)" if e.get("rate_observed") else " (assumed)"),
                    "too_large": bool(r.get("too_large")), "why": "; ".join(r.get("why", [])) or "–"})
    return out


def _validation_rows(val: ValidationResult) -> list[dict]:
    out = []
    fem = {r["label"]: r for r in (val.fem_error or {}).get("rows", [])}
    estimated = bool((val.fem_error or {}).get("estimated"))
    for r in val.rows:
        cell, css = _fem_error_cell(fem.get(r["label"]) if estimated else None)
        out.append({"label": r["label"], "loads": _loads(r), "tip_mm": _mm(r["tip_error_m"]),
                    "fem_error": cell, "fem_error_class": css,
                    "tip_pct": f"{r['tip_error_pct']:.2f}", "shape_pct": f"{r['shape_error_pct']:.2f}",
                    "ct": _fmt(r.get("C_tension_error_pct"), digits=3), "cl": _fmt(r.get("C_locked_error_pct"), digits=3),
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


#: the validated compliances, as the headline names them
COMPLIANCE_NAMES = {"locked": "locked compliance", "tension": "tensions-held compliance"}


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


def _compliance_items(val: ValidationResult, t: dict) -> list[dict]:
    """One headline item per compliance (locked, tensions held) with its worst state, against the target."""
    out = []
    for mode in ("locked", "tension"):
        worst = (val.compliance_error_pct.get(mode) or {}).get("max")
        if worst is None or not np.isfinite(worst):
            continue
        row = _row_at(val.rows, f"C_{mode}_error_pct", worst)
        name = COMPLIANCE_NAMES[mode]
        if worst < t["target"]:
            out.append({"status": "passes", "anchor": "sec-validation", "severity": worst / t["target"],
                        "text": f"{name.capitalize()}: worst error {worst:.1f} %{_where(row)}, below the "
                                f"{t['target']:g} % target."})
            continue
        k = None if row is None else row.get(f"k_{mode}_z_error_pct")
        stiff = ("" if k is None or not np.isfinite(k) else
                 f"; there the reduced model's vertical stiffness k_z is {k:+.0f} % against the FEM's "
                 f"({'stiffer' if k > 0 else 'softer'})")
        out.append({"status": "fails", "anchor": "sec-validation", "severity": worst / t["target"],
                    "label": None if row is None else row["label"],
                    "text": f"{name.capitalize()}: error {worst:.1f} %{_where(row)} against the {t['target']:g} % "
                            f"target ({worst / t['target']:.1f} × the target){stiff}. " + _lacc_meaning(mode, row)})
    return out


def _shape_item(val: ValidationResult, t: dict) -> dict:
    v = t["value"]
    row = _row_at([r for r in val.rows if r.get("experiment") != EXTRAPOLATION], "shape_error_pct", v)
    mm = "" if row is None else f" ({1e3 * row['shape_error_m']:.2f} mm)"
    if t["met"]:
        return {"status": "passes", "anchor": "sec-validation", "severity": v / t["target"],
                "text": f"Shape: worst error {v:.2f} % of L{mm}{_where(row)}, below the {t['target']:g} % target."}
    return {"status": "fails", "anchor": "sec-validation", "severity": v / t["target"],
            "label": None if row is None else row["label"],
            "text": f"Shape: error {v:.2f} % of L{mm}{_where(row)} against the {t['target']:g} % target "
                    f"({v / t['target']:.1f} × the target). For the controller: the reduced model's IK commands a "
                    "centreline off by up to that much, and LACC, which sees only the tip, reads the tip part of "
                    "such a model error as a load."}


def _target_items(val: ValidationResult) -> list[dict]:
    """The headline items of the validation targets (their verdicts as :func:`validation.checks.compare`
    made them; a target split into its quantities, each with its worst state)."""
    out = []
    names = {"shape_pct": "shape error", "compliance_pct": "compliance error"}
    for key, t in val.targets.items():
        if t.get("status") == "incomplete":
            missing = ", ".join(t.get("incomplete") or []) or "every state"
            out.append({"status": "incomplete", "anchor": "sec-validation", "severity": 0.0,
                        "text": f"{names.get(key, key).capitalize()} (target {t['target']:g} %): not checked on "
                                f"{missing}; the verdict is incomplete."})
        elif key == "compliance_pct":
            out += _compliance_items(val, t)
        elif key == "shape_pct":
            out.append(_shape_item(val, t))
    return out


def _fem_error_item(fe: Optional[dict]) -> Optional[dict]:
    """The headline item of the FEM's own discretisation error (:func:`validation.checks.fem_error.assess`)."""
    if not fe:
        return None
    if not fe.get("estimated"):
        return {"status": "incomplete", "anchor": "sec-fem-error", "severity": 0.0,
                "text": "The FEM's discretisation error was not estimated: the verdicts assume the FEM is exact."}
    if fe.get("too_large"):
        return {"status": "fails", "anchor": "sec-fem-error", "severity": 0.0,
                "text": "The FEM's discretisation error is too large for the verdict to mean anything on "
                        f"{', '.join(fe.get('too_large_states') or [])} (too large: {fe.get('criterion', '')})."}
    if not fe.get("n_measured"):
        return {"status": "incomplete", "anchor": "sec-fem-error", "severity": 0.0,
                "text": "The FEM's discretisation error was not measured on any held-out state."}
    unsure = fe.get("not_ruled_out_states") or []
    return {"status": "passes", "anchor": "sec-fem-error", "severity": 0.0,
            "text": f"FEM discretisation error, measured on the {fe['n_measured']} most deformed held-out states: tip "
                    f"up to {fe['max_fem_tip_error_pct']:.2f} % of L, not too large for the verdict on any of them "
                    f"(too large: {fe.get('criterion', '')})"
                    + (f"; not ruled out on the unmeasured {', '.join(unsure)}" if unsure else "") + "."}


def headline(val: Optional[ValidationResult]) -> dict:
    """The report's headline, failures first: {"fails": [item, …] (worst first: value / target), "incomplete":
    […], "passes": […], "notes": [str]}; an item is {"status", "text", "anchor" (the section's id), "severity"}.
    Only presents the verdicts of :class:`~validation.checks.compare.ValidationResult` and
    :func:`validation.checks.fem_error.assess`; computes none."""
    items = [] if val is None else _target_items(val)
    fe = None if val is None else _fem_error_item(val.fem_error)
    if fe is not None:
        items.append(fe)
    out = {k: [i for i in items if i["status"] == k] for k in ("fails", "incomplete", "passes")}
    out["fails"].sort(key=lambda i: -i["severity"])
    doubtful = set(((val.fem_error or {}).get("too_large_states") or []) if val is not None else [])
    for i in out["fails"]:
        if i.get("label") in doubtful:
            i["text"] += " The FEM's own discretisation error is too large for a verdict on this state."
    notes = []
    if val is None:
        notes.append("No validation against the FEM: the model was identified from measured states; its held-out "
                     "tip errors are in section 2.")
    elif val.tip_error_pct:
        notes.append(f"Tip error (no target): mean {val.tip_error_pct['mean']:.2f} %, max "
                     f"{val.tip_error_pct['max']:.2f} % of L.")
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
    d.append(f"Model selection: the simplest form within {round(100 * (PARSIMONY - 1))} % of the best held-out "
             f"RMS tip error wins (chosen: '{ident.form}').")
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
             has_ratio: bool) -> list[dict]:
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
                 modes: Optional[dict] = None) -> str:
    """The report as one HTML string (see the module docstring).  ``figures``: PNG bytes from
    :func:`report_figures` (computed if not given); ``modes``: the Dynamics section's data
    (:func:`validation.checks.modes_compare.compare_modes`; no section without it)."""
    if not isinstance(ident, IdentificationResult):
        raise InputError(f"build_report needs an IdentificationResult, got {type(ident).__name__}")
    import jinja2
    env = jinja2.Environment(loader=jinja2.PackageLoader("validation.report", "templates"),
                             autoescape=jinja2.select_autoescape(["html", "j2"]), undefined=jinja2.StrictUndefined)
    figures = report_figures(ident, validation, stiffness) if figures is None else figures
    b64 = {k: base64.b64encode(v).decode("ascii") for k, v in figures.items() if v}
    for k in ("forms", "correlation", "residuals", "shapes", "ellipses", "stiffness"):
        b64.setdefault(k, "")
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
        "parsimony_pct": round(100 * (PARSIMONY - 1)), "form_rows": _form_rows(ident), "figures": b64,
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
        "headline": headline(validation),
        "ratio_note": "" if validation is None else (
            "On a straight tube the difference is the FEM's lateral tip motion without cap rotation, which locked "
            "tendons cannot hold (docs/identification.md §4b); " + _shear_note(validation.params) + "."),
    }
    toc = sections(validation, stiffness, modes, bool(ctx["ratio_rows"]))
    ctx.update(toc=toc, sec={t["id"]: t["title"] for t in toc})
    return env.get_template("report.html.j2").render(**ctx)


def write_report(path, ident: IdentificationResult, validation: Optional[ValidationResult] = None,
                 stiffness: Optional[dict] = None, *, force: bool = False, figures_dir=None, **kw) -> pathlib.Path:
    """Write :func:`build_report` to ``path`` (.html; not overwritten without ``force``); the figures also go
    to ``figures_dir`` as PNG files if given.  Returns the path."""
    p = prepare_output_file(path, force=force, suffixes=(".html",))
    figures = report_figures(ident, validation, stiffness)
    if figures_dir is not None:
        d = pathlib.Path(figures_dir)
        d.mkdir(parents=True, exist_ok=True)
        for k, v in figures.items():
            if v:
                (d / f"{k}.png").write_bytes(v)
    return atomic_write_text(p, build_report(ident, validation, stiffness, figures=figures, **kw))
