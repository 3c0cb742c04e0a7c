"""The identified rod's vibration modes beside the FEM's, per pressure: the report's Dynamics section.

At each pressure of :data:`PRESSURE_SHARES` × the operating range's largest pressure, tendons slack (tensions
held at 0 N), the first bending and the first axial frequency [Hz] of the reduced model
(:meth:`ancf.Model.modes` of the identified parameters) and of the FEM
(:meth:`fem_reference.BellowsModel.modes` through :func:`validation.reference.fem_sweep.run_modes`, cached like the
load cases) and their relative difference.  The rod's masses are the FEM's (the wall's line mass, the cap
as tip mass at the tool point: ``fem_base_params``), so a difference in frequency is a stiffness difference.  Without gravity
when compared with the FEM (its load cases have none), with the actuator's own gravity otherwise.  When
the parameters carry damping coefficients (``rayleigh_alpha_per_s``, ``rayleigh_beta_s``,
``axial_damping_N_s``) the rod's first-mode damping ratio is given too.

:func:`compare_modes` returns a JSON-ready dict (units in the key names), which the report shows and
writes into ``fit.json`` under ``modes``; it carries the rod's pressure factors
(``rod_EI_pressure_coeffs_per_100kPa``, ``rod_EA_pressure_coeffs_per_100kPa``: EI(λ, p) = EI(λ) f_I(p̂),
f_I = 1 + Σ_j c_j p̂^j, p̂ = p / 100 kPa, :mod:`ancf.stiffness`) so that :func:`modes_sentences` states what the
rod's stiffness does with pressure from the fitted law itself, never from an assumption.  At equal length
and mass a cantilever's bending frequency goes as √EI, so the factor alone changes the rod's bending frequency
by √f_I(p̂) between 0 and p.
"""

from __future__ import annotations

from typing import Optional, Sequence

import numpy as np

from ancf.errors import BellowsError, InputError

__all__ = ["PRESSURE_SHARES", "QUICK_NOTE", "MEASURED_NOTE", "report_pressures", "classify_rod_modes",
           "rod_modes", "compare_modes", "modes_sentences", "pressure_factor_text"]

#: the pressures of the comparison, as shares of the operating range's largest pressure
PRESSURE_SHARES = (0.0, 0.5, 1.0)
#: modes asked of the reduced model per state (the first bending pair, the second, the first axial)
ROD_MODE_COUNT = 8
#: what the FEM columns say when the FEM modes were not computed
QUICK_NOTE = "not computed in --quick (run the full report)"
MEASURED_NOTE = "no FEM: the parameters were identified from measured states"
NO_MASS_NOTE = ("not computed: the actuator has no line mass (line_mass = 0 kg/m); give the base actuator's "
                "line_mass_kg_per_m and tip_mass_kg")


class _NoMass(Exception):
    pass


def report_pressures(pressure_max: float) -> list:
    """The comparison's pressures [Pa]: :data:`PRESSURE_SHARES` of ``pressure_max`` [Pa] (> 0)."""
    if not (np.isfinite(pressure_max) and pressure_max > 0):
        raise InputError(f"the largest pressure of the modes comparison must be > 0 Pa, got {pressure_max!r}")
    return [float(s * pressure_max) for s in PRESSURE_SHARES]


def classify_rod_modes(frequencies_hz, tip_shapes, axis) -> dict:
    """The first bending and first axial frequency [Hz] of the reduced model: a shape whose tool-point motion
    (``tip_shapes`` (k, 3)) lies ≥ 90 % along the actuator's ``axis`` is axial, ≥ 90 % across it bending (the
    cable has no torsion).  None where no mode of the kind is among those computed."""
    from validation.reference.fem_sweep import first_bending_and_axial
    return first_bending_and_axial(frequencies_hz, tip_shapes, axis)


def has_damping(params) -> bool:
    return bool(params.rayleigh_alpha or params.rayleigh_beta or params.axial_damping)


def rod_modes(params, pressure: float, tensions: Sequence[float], *, gravity: bool = False) -> dict:
    """The reduced model's first bending and axial frequency [Hz] about its equilibrium at ``pressure`` [Pa]
    with ``tensions`` [N] held (``gravity``: keep the actuator's gravity, else none), every frequency
    computed, and the first mode's damping ratio from the parameters' damping (None without damping)."""
    from ancf import Model
    p = params if gravity else params.replace(gravity=(0.0, 0.0, 0.0))
    model = Model(p)
    eq = model.fk(np.asarray(tensions, float), float(pressure))
    md = model.modes(eq, min(ROD_MODE_COUNT, model.nz))
    out = classify_rod_modes(md.frequencies_hz, md.tip_shapes, eq.tip)
    out["frequencies_hz"] = [float(f) for f in md.frequencies_hz]
    out["damping_ratio"] = float(md.damping_ratios[0]) if has_damping(p) else None
    return out


def _pct(rod, fem):
    return None if rod is None or fem is None or not fem > 0 else 100.0 * (rod / fem - 1.0)


def compare_modes(params, pressures: Sequence[float], tensions: Sequence[float], *, fem: Optional[list] = None,
                  fem_note: Optional[str] = None, gravity: bool = False) -> dict:
    """The Dynamics section's data (module docstring): one row per pressure [Pa] with the rod's frequencies
    (:func:`rod_modes`) beside the FEM's rows ``fem`` (from :func:`validation.reference.fem_sweep.run_modes`, same
    pressures), or with ``fem_note`` saying why there are none.  A state a model cannot analyse keeps its
    row, with the error text (``rod_error`` / ``fem_error``)."""
    pressures = [float(p) for p in pressures]
    if fem is not None and len(fem) != len(pressures):
        raise InputError(f"compare_modes: {len(fem)} FEM rows for {len(pressures)} pressures")
    damped = has_damping(params)
    massless = not params.line_mass > 0
    rows = []
    for k, p in enumerate(pressures):
        row = {"pressure_kPa": p / 1e3}
        try:
            if massless:
                raise _NoMass
            r = rod_modes(params, p, tensions, gravity=gravity)
            rerr = ""
        except _NoMass:
            r, rerr = {"bending_hz": None, "axial_hz": None, "frequencies_hz": None, "damping_ratio": None}, ""
        except BellowsError as exc:
            r, rerr = {"bending_hz": None, "axial_hz": None, "frequencies_hz": None, "damping_ratio": None}, \
                f"{type(exc).__name__}: {exc}"
        f = fem[k] if fem is not None else {"bending_hz": None, "axial_hz": None, "frequencies_hz": None,
                                             "error": ""}
        row.update({
            "fem_bending_frequency_hz": f.get("bending_hz"), "rod_bending_frequency_hz": r["bending_hz"],
            "bending_difference_pct": _pct(r["bending_hz"], f.get("bending_hz")),
            "fem_axial_frequency_hz": f.get("axial_hz"), "rod_axial_frequency_hz": r["axial_hz"],
            "axial_difference_pct": _pct(r["axial_hz"], f.get("axial_hz")),
            "fem_frequencies_hz": f.get("frequencies_hz"), "rod_frequencies_hz": r["frequencies_hz"],
            "fem_error": f.get("error", ""), "rod_error": rerr})
        if damped:
            row["rod_first_mode_damping_ratio"] = r["damping_ratio"]
        rows.append(row)
    return {"tensions_N": [float(t) for t in tensions], "tendons": "held (constant tension)",
            "gravity": bool(gravity), "fem": "computed" if fem is not None else (fem_note or "not computed"),
            "damping": ({"rayleigh_alpha_per_s": params.rayleigh_alpha, "rayleigh_beta_s": params.rayleigh_beta,
                         "axial_damping_N_s": params.axial_damping} if damped else None),
            "difference": "rod / FEM − 1 [%]",
            "rod_EI_pressure_coeffs_per_100kPa": [float(c) for c in params.stiffness.EI_pressure],
            "rod_EA_pressure_coeffs_per_100kPa": [float(c) for c in params.stiffness.EA_pressure],
            "rod": NO_MASS_NOTE if massless else "computed", "rows": rows}


SUPERSCRIPTS = str.maketrans("0123456789", "⁰¹²³⁴⁵⁶⁷⁸⁹")


def pressure_factor_text(coeffs: Sequence[float]) -> str:
    """The pressure factor 1 + c₁ p̂ + c₂ p̂² + … as text (coefficients to 2 significant digits,
    e.g. ``"1 + 0.71 p̂ + 0.50 p̂²"``); ``"1"`` without coefficients."""
    out = "1"
    for j, c in enumerate(coeffs, start=1):
        if c == 0:
            continue
        power = "" if j == 1 else str(j).translate(SUPERSCRIPTS)
        out += f" {'−' if c < 0 else '+'} {abs(c):.2f} p̂{power}"
    return out


def _factor(coeffs: Sequence[float], pressure_kpa: float) -> float:
    """1 + Σ_j c_j p̂^j at p̂ = pressure_kpa / 100 [−]."""
    return 1.0 + sum(c * (pressure_kpa / 100.0) ** j for j, c in enumerate(coeffs, start=1))


def _law_sentences(modes: dict) -> list:
    """What the rod's fitted law does with pressure (bending, then axial), from the pressure factors
    :func:`compare_modes` recorded; nothing when the dict does not carry them."""
    key = "rod_EI_pressure_coeffs_per_100kPa"
    if key not in modes:
        return []
    ei = list(modes[key])
    ps = [r["pressure_kPa"] for r in modes["rows"]]
    if not any(ei):
        return [("The rod's bending stiffness EI(λ) has no pressure factor in the chosen form: pressure changes "
                 "the rod's bending frequency only through the equilibrium it sets (the stretch and the load on "
                 "the rod), not through EI.")]
    p = max(ps, key=lambda x: abs(_factor(ei, x) - 1.0))
    f = _factor(ei, p)
    if abs(f - 1.0) < 5e-3:
        return [(f"The rod's bending stiffness carries the fitted pressure factor EI(λ, p) = EI(λ) · "
                 f"({pressure_factor_text(ei)}), p̂ = p / 100 kPa, which is 1 at every pressure compared.")]
    return [(f"The rod's bending stiffness carries the fitted pressure factor EI(λ, p) = EI(λ) · "
             f"({pressure_factor_text(ei)}), p̂ = p / 100 kPa: at {p:g} kPa it is {f:.2f} × EI(λ), "
             f"{'stiffer' if f > 1 else 'softer'} than at 0 kPa, which alone changes the rod's bending frequency by "
             f"{100 * (np.sqrt(f) - 1):+.0f} % at equal length (f ∝ √EI).")]


def _trend_reason(modes: dict, fem_stiffens_more: bool) -> str:
    """Why the bending difference (rod / FEM − 1) changes with pressure, from its direction (falling: the FEM
    stiffens more) and the rod's EI pressure factor (if recorded)."""
    if "rod_EI_pressure_coeffs_per_100kPa" not in modes:
        return "the FEM's and the rod's bending stiffness change differently with pressure"
    has_ei = any(modes["rod_EI_pressure_coeffs_per_100kPa"])
    if fem_stiffens_more:
        return ("the FEM stiffens in bending with pressure more than the rod's fitted pressure factor gives (the "
                "factor is fitted to static states over the whole load range, a mode is a small vibration about one "
                "state)" if has_ei else
                "the FEM stiffens in bending with pressure and the rod's EI has no pressure factor (no pressure "
                "dependence of EI); compare the bending errors of the static validation")
    return ("the rod stiffens in bending with pressure more than the FEM: its fitted pressure factor goes beyond the "
            "FEM's small-vibration stiffening" if has_ei else
            "the rod stiffens in bending with pressure more than the FEM, through the equilibrium the pressure sets "
            "(its EI has no pressure factor)")


def _difference_sentences(modes: dict) -> list:
    """The FEM comparison's trend over pressure, bending then axial, read from the differences."""
    rows = [r for r in modes["rows"] if r["bending_difference_pct"] is not None]
    out = []
    if len(rows) >= 2:
        a, b = rows[0], rows[-1]
        da, db = a["bending_difference_pct"], b["bending_difference_pct"]
        span = f"from {da:+.0f} % at {a['pressure_kPa']:g} kPa to {db:+.0f} % at {b['pressure_kPa']:g} kPa"
        if abs(db - da) > 1.0:
            out.append(f"The bending difference goes {span}: {_trend_reason(modes, db < da)}.")
        else:
            out.append(f"The bending difference hardly changes with pressure ({span}).")
    ax = [r for r in modes["rows"] if r["axial_difference_pct"] is not None]
    if len(ax) >= 2:
        ea = modes.get("rod_EA_pressure_coeffs_per_100kPa")
        law = ("" if ea is None else " (no pressure factor on EA)" if not any(ea) else
               f" (EA carries the fitted pressure factor {pressure_factor_text(ea)})")
        out.append(f"The axial difference goes from {ax[0]['axial_difference_pct']:+.0f} % to "
                   f"{ax[-1]['axial_difference_pct']:+.0f} % over the same pressures: the fitted axial law{law} "
                   "against the FEM's small-vibration axial stiffness.")
    return out


def modes_sentences(modes: dict) -> list:
    """What the comparison means, in words, from its numbers and the rod's fitted pressure factors (the
    report prints these under the table).  Every claim is read from ``modes``
    (:func:`compare_modes`); a dict without the pressure factors (an older ``fit.json``) gets no sentence
    about them."""
    rows = modes["rows"]
    out = []
    rod = [r for r in rows if r["rod_bending_frequency_hz"]]
    fem = [r for r in rows if r["fem_bending_frequency_hz"] and r["rod_bending_frequency_hz"]]
    change = lambda a, b, k: 100 * (b[k] / a[k] - 1)  # noqa: E731
    if len(fem) >= 2:
        a, b = fem[0], fem[-1]
        out.append(f"From {a['pressure_kPa']:g} to {b['pressure_kPa']:g} kPa the FEM's first bending frequency "
                   f"changes by {change(a, b, 'fem_bending_frequency_hz'):+.0f} %, the rod's by "
                   f"{change(a, b, 'rod_bending_frequency_hz'):+.0f} %.")
    elif len(rod) >= 2:
        a, b = rod[0], rod[-1]
        out.append(f"From {a['pressure_kPa']:g} to {b['pressure_kPa']:g} kPa the rod's first bending frequency "
                   f"changes by {change(a, b, 'rod_bending_frequency_hz'):+.0f} %.")
    out += _law_sentences(modes)
    if fem and fem[0]["bending_difference_pct"] is not None and abs(fem[0]["bending_difference_pct"]) > 5:
        out.append(f"At {fem[0]['pressure_kPa']:g} kPa the rod's bending frequency is "
                   f"{fem[0]['bending_difference_pct']:+.0f} % off the FEM's: the law is fitted over the whole load "
                   "range, a mode is a small vibration about one state (compare the fitted EI with the FEM's "
                   "small-load tangent in the diagnostics).")
    if modes["fem"] == "computed":
        out.append("The rod's masses are the FEM's, so a frequency difference is a stiffness difference.")
        out += _difference_sentences(modes)
    else:
        out.append(f"FEM modes: {modes['fem']}.")
    if modes.get("damping"):
        out.append("Damping ratio of the rod's first mode from the actuator's damping coefficients (exact for "
                   "Rayleigh damping about each state).")
    return out
