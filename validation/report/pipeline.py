"""``bellows report`` as one Python call: identify, validate, the stiffness study, the modes, the files.

:func:`run_report` runs the same sequence as the command (the command calls it):

1. identify the reduced model — from the FEM of a design (:func:`validation.identification.identify.from_fem`,
   with the FEM's own discretisation error measured beside the fits, :mod:`validation.checks.fem_error`) or
   from measured static states (:func:`~validation.identification.identify.from_measurements`);
2. from the FEM only: validate it on the held-out states (:func:`validation.checks.compare.compare_records`)
   and, unless ``quick``, the vertical stiffness vs tension study (:func:`~validation.checks.compare.stiffness_vs_tension`);
3. the first vibration modes per pressure beside the FEM's (:func:`report_modes`);
4. from the FEM of a design with tendon friction μ > 0 only (the design's ``tendon_friction`` key,
   :func:`validation.reference.designs.design_friction`, or ``tendon_friction=`` — which wins when given): tension
   cycles of the FEM and of the rod, μ of the rod identified from the FEM's cycle at ½ p_max and validated on the
   others (:func:`validation.checks.hysteresis.friction_check`); the identified actuator carries that μ;
5. write ``actuator.toml``, ``fit.json``, ``validation.json``, ``stiffness.json``, ``report.html`` and
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

__all__ = ["run_report", "ReportRun", "FemDesign", "fem_design", "report_modes", "report_friction",
           "design_friction_of", "QUICK_FORMS", "REPORT_FILES"]

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
    files : the files written (paths); seconds : wall time [s]; friction : the tendon friction check
    (:func:`validation.checks.hysteresis.friction_check`; None for a frictionless design or measured data)."""
    identification: Any
    validation: Any = None
    stiffness: Optional[dict] = None
    modes: Optional[dict] = None
    out: Optional[pathlib.Path] = None
    files: tuple = ()
    seconds: float = 0.0
    friction: Optional[dict] = None

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


def _check_inputs(design, measurements, base, forms: Optional[Sequence[str]], quick: bool, cases: str,
                  tendon_friction=None):
    """(form names, the base actuator or None) after checking the combination of inputs, before any work."""
    from ancf import ActuatorParams, presets
    from validation.checks.hysteresis import check_friction
    if tendon_friction is not None:
        if measurements is not None:
            raise InputError("tendon_friction applies to the FEM of a design (its tension cycles), not to measurements")
        check_friction(tendon_friction)
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
               command: Optional[str] = None, log: Optional[Callable[[str], Any]] = None,
               tendon_friction: Optional[float] = None) -> ReportRun:
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
    ``log(text)`` for progress lines (default: silent); tendon_friction : μ in 0 … 1 of the FEM's tendons,
    overriding the design's ``tendon_friction`` (None: the design's; > 0 adds the tension cycles, step 4).

    Raises :class:`~ancf.errors.InputError` / :class:`~ancf.errors.ConfigError` on bad inputs and
    :class:`~ancf.errors.OutputExistsError` when ``out`` holds results, before any work."""
    log = log or (lambda text: None)
    names, base = _check_inputs(design, measurements, base, forms, quick, cases, tendon_friction)
    fem = None if measurements is not None else fem_design(design, tension_max, pressure_max)
    mu = 0.0 if fem is None else design_friction_of(fem.name, tendon_friction)
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
    fric = None
    if mu > 0:              # after the modes: the rod's modes are those of the frictionless actuator
        fric = report_friction(res, fem, mu, mesh=mesh, quick=quick, workers=workers, scheduler=scheduler,
                               cache_dir=cache_dir, log=log)
    if command:
        res.meta["command"] = command
    files = _write(d, res, val, stiff, force=force, command=command, friction=fric)
    return ReportRun(res, val, stiff, res.modes, d, files, time.perf_counter() - t0, fric)


def design_friction_of(design: str, override: Optional[float] = None) -> float:
    """The tendon friction μ of the report of ``design``: ``override`` when given (checked, 0 … 1), else the
    design's ``tendon_friction`` (:func:`validation.reference.designs.design_friction`)."""
    from validation.checks.hysteresis import check_friction
    from validation.reference.designs import design_friction
    return design_friction(design) if override is None else check_friction(override)


def report_friction(res, fem: FemDesign, mu: float, *, mesh: str, quick: bool, workers=None, scheduler=None,
                    cache_dir=None, log=None, fem_cycles=None) -> dict:
    """The tendon friction check of the identified ``res`` against the FEM design ``fem`` with friction ``mu``
    (:func:`validation.checks.hysteresis.friction_check`, gravity as the design is mounted); ``res.params`` then
    carries the μ the check used (identified, or the design's where the fit was not possible)."""
    from validation.checks.hysteresis import friction_check
    from validation.reference.designs import design_mounting, mounting_gravity
    from validation.reference.fem_sweep import FemSpec
    spec = FemSpec(fem.geometry, fem.material, mesh, gravity=mounting_gravity(design_mounting(fem.name)))
    fric = friction_check(res.params, spec, fem.limits, mu, quick=quick, workers=workers, scheduler=scheduler,
                          cache_dir=cache_dir, log=log, fem_cycles=fem_cycles)
    res.params = res.params.replace(tendon_friction=fric["mu_used"])
    res.meta["tendon_friction"] = {k: fric[k] for k in ("mu_design", "mu_used", "mu_source")}
    return fric


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


def _write(d: pathlib.Path, res, val, stiff, *, force: bool, command: Optional[str], friction=None) -> tuple:
    """Write the report folder's files; returns their paths (validation.json holds the friction check, if any,
    under "tendon_friction")."""
    from validation.report.build import write_report
    files = [d / "actuator.toml", d / "fit.json"]
    res.to_toml(files[0], force=force)
    res.save(files[1], force=force)
    if val is not None:
        data = val.to_dict() if friction is None else {**val.to_dict(), "tendon_friction": to_jsonable(friction)}
        files.append(atomic_write_text(d / "validation.json", json.dumps(data, indent=1)))
    if stiff is not None:
        files.append(atomic_write_text(d / "stiffness.json", json.dumps(to_jsonable(stiff), indent=1)))
    files.append(write_report(d / "report.html", res, val, stiff, force=force, figures_dir=d / "figures",
                              command=command, modes=res.modes, friction=friction))
    files.append(d / "figures")
    return tuple(pathlib.Path(f) for f in files)
