"""``bellows report`` as one Python call: identify, validate, the stiffness study, the modes, the files.

:func:`run_report` runs the same sequence as the command (the command calls it):

1. identify the reduced model — from the FEM of a design (:func:`validation.identification.identify.from_fem`,
   with the FEM's own discretisation error measured beside the fits, :mod:`validation.checks.fem_error`) or
   from measured static states (:func:`~validation.identification.identify.from_measurements`);
2. from the FEM only: validate it on the held-out states (:func:`validation.checks.compare.compare_records`)
   and, unless ``quick``, the vertical stiffness vs tension study (:func:`~validation.checks.compare.stiffness_vs_tension`);
3. the first vibration modes per pressure beside the FEM's (:func:`report_modes`);
4. write ``actuator.toml``, ``fit.json``, ``validation.json``, ``stiffness.json``, ``report.html`` and
   ``figures/`` into one folder (every output checked before any work; nothing overwritten without ``force``).

SI units throughout (``tension_max`` [N], ``pressure_max`` [Pa]).
"""

from __future__ import annotations

import json
import pathlib
import time
from dataclasses import dataclass
from typing import Any, Callable, NamedTuple, Optional, Sequence

from ancf.errors import InputError
from ancf.export import to_jsonable
from ancf.outputs import atomic_write_text, prepare_output_dir

from validation.identification.forms import FORMS

__all__ = ["run_report", "ReportRun", "FemDesign", "fem_design", "report_modes", "QUICK_FORMS", "REPORT_FILES"]

#: The model forms of a quick report (no stiffness-vs-tension study, no FEM modes).
QUICK_FORMS = ("paper", "separate", "pressure_ei", "pressure_ei_shear")
#: What a report folder holds (all checked before any work: none is overwritten without ``force``).
REPORT_FILES = ("report.html", "actuator.toml", "fit.json", "validation.json", "stiffness.json", "figures")
#: Share of measured states held out to choose the model form (as ``bellows report --measurements``).
MEASURED_HELDOUT_FRACTION = 0.25


class FemDesign(NamedTuple):
    """An FEM design ready to run: its name, ``fem_reference`` geometry and material, and its operating range
    ``limits`` ({"tension_max": N, "pressure_max": Pa})."""
    name: str
    geometry: Any
    material: Any
    limits: dict


def fem_design(design=None, tension_max: Optional[float] = None, pressure_max: Optional[float] = None) -> FemDesign:
    """The FEM design ``design`` (a preset name or a design .toml; default ``"paper"``) with its operating
    range, ``tension_max`` [N] / ``pressure_max`` [Pa] overriding the design's when given (each > 0)."""
    from validation.reference.designs import design_limits, load_design
    name = "paper" if design is None else str(design)
    geometry, material = load_design(name)
    limits = design_limits(name)
    for key, value in (("tension_max", tension_max), ("pressure_max", pressure_max)):
        if value is not None:
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not (value > 0):
                raise InputError(f"{key} must be a number > 0, got {value!r}")
            limits[key] = float(value)
    return FemDesign(name, geometry, material, limits)


@dataclass
class ReportRun:
    """What :func:`run_report` made: the results and the files.

    identification : :class:`~validation.identification.identify.IdentificationResult`; validation :
    :class:`~validation.checks.compare.ValidationResult` (None from measurements); stiffness : the stiffness
    vs tension study (None from measurements or quick); modes : the Dynamics section's data; out : the folder;
    files : the files written (paths); seconds : wall time [s]."""
    identification: Any
    validation: Any = None
    stiffness: Optional[dict] = None
    modes: Optional[dict] = None
    out: Optional[pathlib.Path] = None
    files: tuple = ()
    seconds: float = 0.0

    @property
    def report(self) -> pathlib.Path:
        """The HTML report's path."""
        return self.out / "report.html"

    def __repr__(self) -> str:
        return (f"ReportRun({self.report}, form={self.identification.form!r}, source={self.identification.source!r}, "
                f"validation={'yes' if self.validation is not None else 'no'}, "
                f"{len(self.files)} files, {self.seconds:.0f} s)")

    def _repr_html_(self) -> str:
        from ancf.htmlrepr import table
        parts = [table("Report", [("report", str(self.report)), ("files", ", ".join(p.name for p in self.files)),
                                  ("wall time", f"{self.seconds:.1f} s")], header=("item", "value")),
                 self.identification._repr_html_()]
        if self.validation is not None:
            parts.append(self.validation._repr_html_())
        return "".join(parts)


def _check_inputs(design, measurements, base, forms: Optional[Sequence[str]], quick: bool, cases: str):
    """(form names, the base actuator or None) after checking the combination of inputs, before any work."""
    from ancf import ActuatorParams, presets
    if design is not None and measurements is not None:
        raise InputError("give either design (virtual experiments on the FEM) or measurements (rig data), not both")
    if measurements is not None and base is None:
        raise InputError("measurements need base=: the actuator the states were measured on (ActuatorParams, a preset "
                         "name or an actuator .toml); there is no default")
    if measurements is None and base is not None:
        raise InputError("base applies only with measurements (the FEM design sets the actuator)")
    if isinstance(measurements, (str, pathlib.Path)) and not pathlib.Path(measurements).is_file():
        raise InputError(f"measurements: no such file {measurements}")
    if cases not in ("default", "informative"):
        raise InputError(f"cases must be 'default' or 'informative', got {cases!r}")
    names = (QUICK_FORMS if quick else FORMS) if forms is None else tuple(forms)
    bad = [n for n in names if n not in FORMS]
    if bad or not names:
        raise InputError(f"forms: unknown form(s) {', '.join(map(str, bad)) or '(none given)'}; choose from "
                         f"{', '.join(FORMS)}")
    if base is not None and not isinstance(base, ActuatorParams):
        base = presets.get(str(base))
    return names, base


def run_report(out, *, design=None, measurements=None, base=None, quick: bool = False, fem_error: bool = True,
               tension_max: Optional[float] = None, pressure_max: Optional[float] = None, mesh: str = "coarse",
               forms: Optional[Sequence[str]] = None, fit_distance: bool = False, cases: str = "default",
               workers: Optional[int] = None, scheduler: Optional[str] = None, cache_dir=None, force: bool = False,
               command: Optional[str] = None, log: Optional[Callable[[str], Any]] = None) -> ReportRun:
    """Identify, validate and write one report into the folder ``out`` (module docstring); returns a
    :class:`ReportRun`.

    design : an FEM design (preset name or .toml; default ``"paper"`` unless ``measurements``); measurements :
    measured static states (a file or :class:`hardware.static_states.StaticStates`) instead, with ``base`` the
    actuator they were measured on (ActuatorParams, preset or .toml); quick : only :data:`QUICK_FORMS`, no
    stiffness study, no FEM modes; fem_error : measure the FEM's discretisation error (2 held-out states with
    ``quick``, else 4); tension_max [N], pressure_max [Pa] : the virtual experiments' range (default: the
    design's); mesh, forms, fit_distance, cases : as :func:`~validation.identification.identify.from_fem`;
    workers / scheduler / cache_dir : the FEM solves' processes, dask scheduler and on-disk cache (None: no
    cache); force : overwrite what ``out`` holds; command : recorded in the files and the report; log :
    ``log(text)`` for progress lines (default: silent).

    Raises :class:`~ancf.errors.InputError` / :class:`~ancf.errors.ConfigError` on bad inputs and
    :class:`~ancf.errors.OutputExistsError` when ``out`` holds results, before any work."""
    log = log or (lambda text: None)
    names, base = _check_inputs(design, measurements, base, forms, quick, cases)
    fem = None if measurements is not None else fem_design(design, tension_max, pressure_max)
    d = prepare_output_dir(out, REPORT_FILES, force=force)
    t0 = time.perf_counter()
    val = stiff = None
    if measurements is not None:
        from validation.identification.identify import from_measurements
        res = from_measurements(measurements, base, forms=names, heldout_fraction=MEASURED_HELDOUT_FRACTION,
                                fit_distance=fit_distance, gravity=True)
    else:
        res, val, stiff = _from_fem(fem, names, quick=quick, fem_error=fem_error, mesh=mesh, fit_distance=fit_distance,
                                    cases=cases, workers=workers, scheduler=scheduler, cache_dir=cache_dir, log=log)
    res.modes = report_modes(res.params, fem, mesh, cache_dir, quick, log)
    if command:
        res.meta["command"] = command
    files = _write(d, res, val, stiff, force=force, command=command)
    return ReportRun(res, val, stiff, res.modes, d, files, time.perf_counter() - t0)


def _from_fem(fem: FemDesign, names, *, quick: bool, fem_error: bool, mesh: str, fit_distance: bool, cases: str,
              workers, scheduler, cache_dir, log):
    """(identification, validation, stiffness study or None) from the FEM design ``fem``."""
    from validation.checks.compare import compare_records, stiffness_vs_tension
    from validation.checks.fem_error import FULL_CASES, QUICK_CASES, assess, estimate_for_heldout, for_validation
    from validation.identification.identify import from_fem
    from validation.reference.fem_sweep import FemSpec
    from validation.reference.designs import design_mounting, mounting_gravity
    name, geo, mat, limits = fem
    mounting = design_mounting(name)                 # the gravity of the states with gravity, both models alike
    spec = FemSpec(geo, mat, mesh, gravity=mounting_gravity(mounting))
    n_fe = QUICK_CASES if quick else FULL_CASES
    # --quick: one state, its two refined solves side by side on the two cores, "around" left to the full report
    fe_kw = dict(workers=workers, scheduler=scheduler, cache_dir=cache_dir, check_around=not quick)

    def fem_error_beside(records):     # the refined solves run while the forms are fitted (identify.from_fem)
        log(f"FEM discretisation error: {n_fe} held-out state(s) on meshes refined 2× along the profile and through "
            "the wall" + (" (around: checked by the full report)" if quick else " (the most deformed also around)")
            + ", beside the fits …")
        return estimate_for_heldout(spec, records, n_fe, **fe_kw)

    log(f"design {name}: operating range {limits['tension_max']:g} N, {limits['pressure_max'] / 1e3:g} kPa")
    res = from_fem(geo, mat, mesh, workers=workers, scheduler=scheduler, cache_dir=cache_dir, forms=names,
                   fit_distance=fit_distance, progress=True, tension_max=limits["tension_max"],
                   pressure_max=limits["pressure_max"], cases=cases,
                   after_sweep=fem_error_beside if fem_error else None, mounting=mounting)
    res.meta["design_name"] = name                  # the identified actuator's name and provenance (to_toml)
    val = compare_records(res.params, [r for r in res.records if r.case.role == "heldout"])
    if fem_error:
        for_validation(val, spec, res.records, n_fe, estimate=res.after_sweep, **fe_kw)
        val.fem_error["seconds"] = float(val.fem_error.get("estimate", {}).get("seconds") or 0.0)
    else:
        val.fem_error = assess(val, None, reason="--no-fem-error")      # the command's option: fem_error=False
    stiff = None
    if not quick:
        log("stiffness vs tension (Fig. 9 protocol) on the FEM …")
        stiff = stiffness_vs_tension(res.params, spec, workers=workers, scheduler=scheduler, cache_dir=cache_dir)
    return res, val, stiff


def report_modes(params, fem: Optional[tuple], mesh: str, cache_dir, quick: bool,
                 log: Optional[Callable[[str], Any]] = None) -> dict:
    """The report's Dynamics data (:mod:`validation.checks.modes_compare`): the rod ``params``' first bending and
    axial modes per pressure, tendons slack, beside the FEM's of the design ``fem`` (a :class:`FemDesign`; None:
    measured data, no FEM) — computed and cached in ``cache_dir`` here, not with ``quick``."""
    from validation.checks.modes_compare import MEASURED_NOTE, QUICK_NOTE, compare_modes, report_pressures
    from validation.reference.fem_sweep import FemSpec, run_modes
    log = log or (lambda text: None)
    slack = [0.0] * len(params.tendons)
    if fem is None:
        return compare_modes(params, report_pressures(params.pressure_max), slack, fem_note=MEASURED_NOTE,
                             gravity=True)
    _, geo, mat, limits = fem
    pressures = report_pressures(limits["pressure_max"])
    if quick:
        return compare_modes(params, pressures, slack, fem_note=QUICK_NOTE)
    log(f"FEM modes at {', '.join(f'{x / 1e3:g}' for x in pressures)} kPa …")
    t0 = time.perf_counter()
    fem_rows = run_modes(FemSpec(geo, mat, mesh), pressures, slack, cache_dir=cache_dir)
    log(f"FEM modes: {time.perf_counter() - t0:.1f} s")
    return compare_modes(params, pressures, slack, fem=fem_rows)


def _write(d: pathlib.Path, res, val, stiff, *, force: bool, command: Optional[str]) -> tuple:
    """Write the report folder's files; returns their paths."""
    from validation.report.build import write_report
    files = [d / "actuator.toml", d / "fit.json"]
    res.to_toml(files[0], force=force)
    res.save(files[1], force=force)
    if val is not None:
        files.append(atomic_write_text(d / "validation.json", json.dumps(val.to_dict(), indent=1)))
    if stiff is not None:
        files.append(atomic_write_text(d / "stiffness.json", json.dumps(to_jsonable(stiff), indent=1)))
    files.append(write_report(d / "report.html", res, val, stiff, force=force, figures_dir=d / "figures",
                              command=command, modes=res.modes))
    files.append(d / "figures")
    return tuple(pathlib.Path(f) for f in files)
