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
writes into ``fit.json`` under ``modes``.
"""

from __future__ import annotations

from typing import Optional, Sequence

import numpy as np

from ancf.errors import BellowsError, InputError

__all__ = ["PRESSURE_SHARES", "QUICK_NOTE", "MEASURED_NOTE", "report_pressures", "classify_rod_modes",
           "rod_modes", "compare_modes", "modes_sentences"]

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
            "rod": NO_MASS_NOTE if massless else "computed", "rows": rows}


def modes_sentences(modes: dict) -> list:
    """What the comparison means, in words, from its numbers (the report prints these under the table)."""
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
    if fem and fem[0]["bending_difference_pct"] is not None and abs(fem[0]["bending_difference_pct"]) > 5:
        out.append(f"At {fem[0]['pressure_kPa']:g} kPa the rod's bending frequency is already "
                   f"{fem[0]['bending_difference_pct']:+.0f} % off: the law is fitted over the whole load range, "
                   "a mode is a small vibration about one state (compare the fitted EI with the FEM's small-load "
                   "tangent in the diagnostics).")
    if modes["fem"] == "computed":
        out.append("The rod's masses are the FEM's, so a frequency difference is a stiffness difference. The "
                   "rod's bending stiffness EI(λ) depends on its stretch only, not on the pressure: where "
                   "pressure stiffens the bellows in bending, the FEM's bending frequency rises with pressure "
                   "and the rod's does not (it follows only its lengthening). A bending difference that grows "
                   "with pressure is that missing pressure dependence of EI — the dynamic face of the bending "
                   "errors of the static validation; the axial difference reflects the fitted axial law k(λ) "
                   "over the pressure range.")
    else:
        out.append(f"FEM modes: {modes['fem']}. The rod's bending stiffness EI(λ) depends on its stretch only, "
                   "not on the pressure: its bending frequency follows only its lengthening.")
    if modes.get("damping"):
        out.append("Damping ratio of the rod's first mode from the actuator's damping coefficients (exact for "
                   "Rayleigh damping about each state).")
    return out
