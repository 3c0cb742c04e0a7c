"""``bellows identify | validate | report | calibrate``: identification of the reduced model, its validation
against the FEM, the HTML report and the calibration of an FEM design (docs/identification.md).

Every command checks its outputs before any work (an existing result is not overwritten without
``--force``), caches each FEM solve under ``--cache`` (a re-run or an interrupted run computes only what is
missing) and prints where it wrote what.  Units are in the option names.
"""

from __future__ import annotations

import json
import pathlib
import shlex
import sys
import time
from typing import Optional

import numpy as np
import typer
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from ancf import clitools
from ancf.errors import InputError
from ancf.export import to_jsonable
from ancf.outputs import atomic_write_text, prepare_output_dir, prepare_output_file
from ancf.textfmt import one_of
from fem_reference.mesh import MESH_LEVELS
from fem_reference.model import OperatingLimits

from validation.identification.calibrate import GEOMETRY_PARAMETERS, MATERIAL_PARAMETERS
from validation.reference.designs import PRESETS as DESIGN_PRESETS
from validation.reference.experiments import default_design
from validation.identification.forms import FORMS
from validation.report.pipeline import QUICK_FORMS

# every list of choices below is built from the code's own registry, so that --help cannot drift from it
DESIGN_HELP = f"FEM design: a preset {one_of(DESIGN_PRESETS)} or a design .toml file."
CACHE_HELP = "Folder of the on-disk FEM cache (re-runs and interrupted runs compute only what is missing)."
WORKERS_HELP = "Parallel FEM processes (default: all cores)."
SCHEDULER_HELP = "dask scheduler address (tcp://host:8786) to run the FEM cases on a cluster."
FORMS_HELP = f"Model forms to compare, comma separated, from {one_of(FORMS)} (default: all)."
DEFAULT_CACHE = pathlib.Path("bellows_out/fem_cache")
N_FEM_CASES = len(default_design().cases)
QUICK_HELP = (f"Only the model forms {one_of(QUICK_FORMS)}, no stiffness-vs-tension study and no FEM modes (the "
              f"Dynamics section shows the rod's). The FEM solves still dominate a run with an empty --cache: the "
              f"design's {N_FEM_CASES} load cases, then the FEM-error solves beside the fits (--no-fem-error skips "
              "them): 4.1 min measured on 2 idle cores with pypardiso (the [pardiso] extra) and the model's kernels "
              "compiled (the first run of a fresh install compiles them too), slower with SciPy's SuperLU "
              "(docs/identification.md §Measured); a re-run whose solves are cached takes seconds.")
FREE_PARAMETERS = GEOMETRY_PARAMETERS + MATERIAL_PARAMETERS
FEM_ERROR_HELP = ("Measure the FEM's own discretisation error: the held-out states with the largest deformation "
                  "(1 with --quick, 4 otherwise) solved again with 2× the elements along the profile and, apart, "
                  "through the wall (without --quick the most deformed also around); the combined Richardson estimate shown beside "
                  "the model-vs-FEM error, each state passing, failing or undecided (docs/identification.md §4a). "
                  "--no-fem-error skips those solves.")

# options shared by several commands (typer reads these as defaults)
MESH_OPT = typer.Option("coarse", help=f"FEM mesh level {one_of(MESH_LEVELS)}.")
FORMS_OPT = typer.Option(None, help=FORMS_HELP)
CASES_HELP = ("Load cases of the FEM experiments: 'default' (the fixed design, docs/identification.md §2) or "
              "'informative' (training cases chosen D-optimally for the richest form from a grid over the whole "
              "range, held-out states inside the training hull and an extrapolation set reported apart; "
              "validation.identification.design_select).")
CASES_OPT = typer.Option("default", help=CASES_HELP)


def _cases_check(cases: str) -> str:
    if cases not in ("default", "informative"):
        raise InputError(f"--cases must be 'default' or 'informative', got {cases!r}")
    return cases
FIT_D_OPT = typer.Option(False, help="Also fit the tendon routing distance d.")
WORKERS_OPT = typer.Option(None, min=1, max=clitools.WORKERS_MAX, help=WORKERS_HELP)
SCHEDULER_OPT = typer.Option(None, help=SCHEDULER_HELP)
CACHE_OPT = typer.Option(DEFAULT_CACHE, help=CACHE_HELP)
FORCE_OPT = typer.Option(False, help="Overwrite results already in --out.")
# option ranges (clitools.number_range: a given value outside is a usage error, exit status 2)
POSITIVE = clitools.number_range(0.0, low_open=True)
# a pressure of the FEM model within its operating limits (fem_reference.model.OperatingLimits: calibrate's solves
# check them); the virtual experiments' largest tension and pressure are only > 0 here: whether their load cases
# stay within those limits depends on --cases and is checked with the cases, before any solve (fem_sweep.check_cases)
FEM_PRESSURE_KPA = clitools.number_range(0.0, OperatingLimits.pressure_max / 1e3, low_open=True, unit="kPa")
TENSION_N = clitools.number_range(0.0, low_open=True, unit="N")
PRESSURE_KPA = clitools.number_range(0.0, low_open=True, unit="kPa")
HELDOUT = clitools.number_range(0.0, 1.0, high_open=True)                # validation.identification.identify's range
RANGE_FACTOR = clitools.number_range(1.0, 10.0, low_open=True)         # beyond 10× it is another design
START_S = clitools.number_range(0.0, unit="s")
END_S = clitools.number_range(0.0, low_open=True, unit="s")
FRICTION = clitools.number_range(0.0, 1.0)                 # ActuatorParams.tendon_friction's range
TMAX_OPT = typer.Option(None, callback=TENSION_N, help="Largest tendon tension of the virtual experiments, "
                                                       f"{TENSION_N.text} (default: the design's).")
PMAX_OPT = typer.Option(None, callback=PRESSURE_KPA, help="Largest pressure of the virtual experiments, "
                                                          f"{PRESSURE_KPA.text} (default: the design's).")

console = Console(width=120)


def _forms(text: Optional[str], quick: bool = False) -> tuple:
    if text is None:                   # not given (a given empty list is an error below, not the default)
        return QUICK_FORMS if quick else FORMS
    names = tuple(x.strip() for x in text.split(",") if x.strip())
    bad = [n for n in names if n not in FORMS]
    if bad or not names:
        raise InputError(f"--forms: unknown form(s) {', '.join(bad) or '(none given)'}; choose from {', '.join(FORMS)}")
    return names


def _command_line() -> str:
    return "bellows " + " ".join(shlex.quote(a) for a in sys.argv[1:])


def _print_identification(res) -> None:
    from validation.report.build import derived_rows, param_rows
    for line in res.warnings:           # what the data do not determine, before any number
        console.print("[bold yellow]warning:[/bold yellow] " + escape(line))
    for title, rows in ((f"Identified parameters of the form '{res.form}'", param_rows(res)),
                        ("Derived values at rest (λ = 1)", derived_rows(res))):
        t = Table(title=title)
        for c in ("parameter", "value", "95 % CI", "unit"):
            t.add_column(escape(c), justify="left" if c in ("parameter", "unit") else "right")
        for r in rows:
            t.add_row(r["name"], *((r["value"], r["ci"]) if r["identifiable"] else ("not identifiable", "")), r["unit"])
        console.print(t)
    f = Table(title="Model forms (tip error)")
    for c in ("form", "params", "train RMS [mm]", "held-out RMS [mm]", "held-out max [mm]", "not identifiable"):
        f.add_column(escape(c), justify="left" if c in ("form", "not identifiable") else "right")   # "[mm]" is no markup
    for r in res.comparison:
        if "failed" in r:
            f.add_row(r["form"], str(r["n_params"]), "failed", r["failed"], "", "")
            continue
        mm = lambda key: "–" if r.get(key) is None else f"{1e3 * r[key]:.2f}"  # noqa: E731
        f.add_row(r["form"] + (" (chosen)" if r.get("chosen") else ""), str(r["n_params"]), mm("train_rms_tip_m"),
                  mm("heldout_rms_tip_m"), mm("heldout_max_tip_m"), ", ".join(r.get("not_identifiable", [])) or "–")
    console.print(f)


def _print_validation(val) -> None:
    if not val.rows:
        console.print("[red]no held-out state could be compared[/red]")
        return
    console.print(f"held-out tip error: mean {val.tip_error_pct['mean']:.2f} %, max {val.tip_error_pct['max']:.2f} % of L; "
                  f"shape error: mean {val.shape_error_pct['mean']:.2f} %, max {val.shape_error_pct['max']:.2f} % of L")
    if val.compliance_error_pct:
        c = val.compliance_error_pct
        console.print(f"compliance error (Frobenius): tension held mean {c['tension']['mean']:.1f} % (max "
                      f"{c['tension']['max']:.1f} %), tendons locked mean {c['locked']['mean']:.1f} % "
                      f"(max {c['locked']['max']:.1f} %)")
    if val.extrapolation:
        e = val.extrapolation["tip_error_pct"]
        console.print(f"extrapolation (outside the training hull, reported apart; {len(val.extrapolation['states'])} "
                      f"states): tip error mean {e['mean']:.2f} %, max {e['max']:.2f} % of L")
    _print_verdicts(val)


def _print_verdicts(val) -> None:
    """Per quantity (locked and tension-held compliance, tip position, shape) how many held-out states pass,
    fail or are undecided beside the FEM's own error, the per-state table and the statements
    (:func:`validation.checks.fem_error.assess`; without it, the same rule with the FEM taken as exact)."""
    from validation.checks.fem_error import QUANTITIES, assess
    for f in val.failures:
        console.print(f"[yellow]not compared: {f['label']} ({f['model']}): {f['error']}[/yellow]")
    fe = val.fem_error if (val.fem_error or {}).get("quantities") else assess(val, None)
    incomplete = {k: t for k, t in val.targets.items() if t.get("status") == "incomplete"}
    for q in ("C_locked", "C_tension", "tip", "shape"):
        t, target_key = fe["quantities"][q], f"{QUANTITIES[q][3]}_pct"       # the validation target it falls under
        if target_key in incomplete:
            console.print(f"{t['name']} < {t['target']:g} {t['unit']}: INCOMPLETE (not checked on "
                          f"{', '.join(incomplete[target_key].get('incomplete') or []) or 'every state'})")
            continue
        n = {k: len(t[k]) for k in ("passes", "fails", "undecided")}
        if not sum(n.values()):
            continue
        word = "FAILS" if n["fails"] else ("UNDECIDED" if n["undecided"] else "passes")
        colour = {"FAILS": "red", "UNDECIDED": "yellow"}.get(word)
        line = (f"{t['name']} < {t['target']:g} {t['unit']}: {word} — {n['passes']} pass, {n['fails']} fail, "
                f"{n['undecided']} undecided" + "".join(f"; {k}: {', '.join(t[k])}" for k in ("fails", "undecided")
                                                         if t[k]))
        console.print(f"[{colour}]{escape(line)}[/{colour}]" if colour else escape(line))
    if fe.get("estimated"):
        tab = Table(title="FEM discretisation error beside the model-vs-FEM error (held-out states)")
        for c in ("state", "model vs FEM, tip [% L]", "FEM error, tip [% L]", "along", "through", "basis",
                  "verdicts"):
            tab.add_column(escape(c), justify="left" if c in ("state", "basis", "verdicts") else "right")
        for r in fe["rows"]:
            by = r.get("fem_by_direction") or {}
            cells = [f"{x:.3f}" if x is not None else "–" for x in (
                r.get("fem_tip_error_pct"), (by.get("along") or {}).get("tip_error_pct"),
                (by.get("through") or {}).get("tip_error_pct"))]
            bad = ", ".join(f"{q}: {v}" for q, v in r["verdicts"].items() if v in ("fails", "undecided")) or "all pass"
            tab.add_row(escape(r["label"]), f"{r['model_tip_error_pct']:.2f}", *cells,
                        escape("measured" if r["measured"] else "estimate"), escape(bad))
        console.print(tab)
    for s in fe.get("statements", []):
        console.print(escape(s))


def _limits(design: str, tension_max_n: Optional[float], pressure_max_kpa: Optional[float]) -> dict:
    """The design's operating range, overridden by the options that were given (a given 0 is rejected)."""
    from validation.reference.designs import design_limits
    lim = design_limits(design)
    for key, val, scale, opt in (("tension_max", tension_max_n, 1.0, "--tension-max-n"),
                                 ("pressure_max", pressure_max_kpa, 1e3, "--pressure-max-kpa")):
        if val is not None:
            if not (val > 0):
                raise InputError(f"{opt} must be > 0, got {val}")
            lim[key] = val * scale
    return lim


def _fem_design(design: Optional[str], tension_max_n, pressure_max_kpa) -> tuple:
    """(name, geometry, material, limits) of the FEM design, read and checked before any work."""
    from validation.reference.designs import load_design
    name = design or "paper"
    geo, mat = load_design(name)
    return name, geo, mat, _limits(name, tension_max_n, pressure_max_kpa)


def _identify_fem(fem: tuple, mesh: str, workers, scheduler, cache: Optional[pathlib.Path], forms, fit_distance: bool,
                  cases: str = "default", after_sweep=None):
    from validation.identification.identify import from_fem
    from validation.reference.designs import design_mounting
    name, geo, mat, limits = fem
    console.print(f"design {name}: operating range {limits['tension_max']:g} N, {limits['pressure_max'] / 1e3:g} kPa")
    res = from_fem(geo, mat, mesh, workers=workers, scheduler=scheduler, cache_dir=cache, forms=forms,
                   fit_distance=fit_distance, progress=True, tension_max=limits["tension_max"],
                   pressure_max=limits["pressure_max"], cases=cases, after_sweep=after_sweep,
                   mounting=design_mounting(name))
    res.meta["design_name"] = name                  # the identified actuator's name and provenance (to_toml)
    return res


def _identify_measured(measurements: pathlib.Path, base: str, forms, fit_distance: bool, heldout_fraction: float,
                       gravity: bool, masses: str = "free"):
    from ancf import presets
    from validation.identification.identify import from_measurements
    return from_measurements(measurements, presets.get(base), forms=forms, heldout_fraction=heldout_fraction,
                             fit_distance=fit_distance, gravity=gravity, progress=_progress_printer(), masses=masses)


MASSES_HELP = ("With --measurements: the line mass [kg/m] and tip mass [kg] 'free' (fitted, starting at --base's; "
               "held there, and said so, when the states do not determine them — known tip loads at several pressures "
               "do) or 'base' (held at --base's values).")


def _masses_check(masses: str, measurements: Optional[pathlib.Path]) -> str:
    from validation.identification.identify import MASS_CHOICES
    if masses not in MASS_CHOICES:
        raise InputError(f"--masses must be one of {', '.join(MASS_CHOICES)}, got {masses!r}")
    if measurements is None and masses != "free":
        raise InputError("--masses applies only with --measurements (the FEM's states carry no gravity)")
    return masses


#: Progress lines (per form: which, how long, the result) are printed once a run has taken this long [s].
PROGRESS_AFTER_S = 3.0


def _progress_printer(after_s: float = PROGRESS_AFTER_S):
    """``progress(line)`` for :func:`validation.identification.identify.identify`: silent for a run that ends
    within ``after_s`` seconds; after that, the lines held back so far and each new one as it comes."""
    t0, held = time.perf_counter(), []

    def progress(line: str) -> None:
        held.append(line)
        if time.perf_counter() - t0 >= after_s:
            for h in held:
                console.print(escape(h))
            held.clear()
    return progress


def _source_check(design: Optional[str], measurements: Optional[pathlib.Path]) -> None:
    if design is not None and measurements is not None:
        raise InputError("give either --design (virtual experiments on the FEM) or --measurements (rig data), not both")
    if measurements is not None and not measurements.is_file():
        raise InputError(f"--measurements: {measurements} is a folder, not a file" if measurements.is_dir() else
                         f"--measurements: no such file {measurements}")


def _base_check(measurements: Optional[pathlib.Path], base: Optional[str]) -> None:
    """Measured data need the actuator they were measured on: no default (a wrong base gives wrong numbers)."""
    if measurements is not None and base is None:
        raise InputError("--measurements needs --base: the actuator the states were measured on (a preset name or "
                         "an actuator .toml: length, tendon routing, masses, limits, starting stiffness)")
    if measurements is None and base is not None:
        raise InputError("--base applies only with --measurements (the FEM design sets the actuator)")


def identify_cmd(
        design: Optional[str] = typer.Option(None, help=DESIGN_HELP + " Default: paper (unless --measurements)."),
        measurements: Optional[pathlib.Path] = typer.Option(
            None, help="Measured static states (.h5 run log or static-states file, or .csv; docs/data-formats.md)."),
        base: Optional[str] = typer.Option(None, help="Required with --measurements: the actuator as built (preset "
                                                      "or .toml) — length, tendon routing, masses, limits, starting "
                                                      "stiffness."),
        heldout_fraction: float = typer.Option(0.25, callback=HELDOUT,
                                               help=f"With --measurements: share of states held out to choose "
                                                    f"the model form, {HELDOUT.text} (states labelled 'heldout…' are "
                                                    "held out instead)."),
        gravity: bool = typer.Option(True, help="With --measurements: the states were measured under gravity."),
        masses: str = typer.Option("free", help=MASSES_HELP),
        tension_max_n: Optional[float] = TMAX_OPT,
        pressure_max_kpa: Optional[float] = PMAX_OPT,
        mesh: str = MESH_OPT,
        forms: Optional[str] = FORMS_OPT,
        fit_distance: bool = FIT_D_OPT,
        cases: str = CASES_OPT,
        workers: Optional[int] = WORKERS_OPT,
        scheduler: Optional[str] = SCHEDULER_OPT,
        cache: pathlib.Path = CACHE_OPT,
        out: pathlib.Path = typer.Option(pathlib.Path("bellows_out/identify"), help="Output folder."),
        name: Optional[str] = typer.Option(None, "--name", help="The identified actuator's name in actuator.toml "
                                           "(default: '<design or base actuator>-identified')."),
        force: bool = FORCE_OPT):
    """Identify k(λ), D_a, D_eff from the FEM or rig data.

    Writes actuator.toml (with 95 % intervals) and fit.json into --out."""
    _source_check(design, measurements)
    names = _forms(forms)
    _cases_check(cases)
    _base_check(measurements, base)
    _masses_check(masses, measurements)
    if name is not None and not name.strip():
        raise InputError("--name must not be empty")
    fem = None if measurements is not None else _fem_design(design, tension_max_n, pressure_max_kpa)
    d = prepare_output_dir(out, ("actuator.toml", "fit.json"), force=force)
    t0 = time.perf_counter()
    if measurements is not None:
        res = _identify_measured(measurements, base, names, fit_distance, heldout_fraction, gravity, masses)
    else:
        res = _identify_fem(fem, mesh, workers, scheduler, cache, names, fit_distance, cases)
    res.meta["command"] = _command_line()
    if res.meta.get("torn_rows"):
        console.print(f"note: {measurements}: static-state row(s) {res.meta['torn_rows']} torn (the writer stopped "
                      f"while recording them) and not used; {res.meta['n_states']} complete states used")
    res.to_toml(d / "actuator.toml", force=force, name=name)
    res.save(d / "fit.json", force=force)
    _print_identification(res)
    console.print(f"{time.perf_counter() - t0:.0f} s; wrote {d / 'actuator.toml'} and {d / 'fit.json'}")


def validate_cmd(
        params: str = typer.Option(..., help="Reduced model to validate: an actuator .toml file (e.g. from "
                                             "'bellows identify') or a preset name."),
        design: str = typer.Option("paper", help=DESIGN_HELP),
        mesh: str = MESH_OPT,
        fem_error: bool = typer.Option(True, help=FEM_ERROR_HELP.replace("(1 with --quick, 4 otherwise)", "(4)").replace("without --quick ", "")),
        workers: Optional[int] = WORKERS_OPT,
        scheduler: Optional[str] = SCHEDULER_OPT,
        cache: pathlib.Path = CACHE_OPT,
        out: pathlib.Path = typer.Option(pathlib.Path("bellows_out/validate"), help="Output folder."),
        force: bool = FORCE_OPT):
    """Validate a reduced model against the FEM.

    Tip, shape and compliance errors on the held-out states, written to validation.json."""
    from ancf import presets
    from validation.checks.compare import check_actuator_matches, default_heldout, validate
    from validation.reference.designs import load_design
    from validation.checks.fem_error import FULL_CASES, assess, for_validation
    from validation.reference.fem_sweep import FemSpec, check_cases, run_cases
    p = presets.get(params)
    geo, mat = load_design(design)
    check_actuator_matches(p, geo)
    spec = FemSpec(geo, mat, mesh)
    states = default_heldout(p, geo)
    check_cases(spec, states)
    d = prepare_output_dir(out, ("validation.json",), force=force)
    records = run_cases(spec, states, compliance=True, workers=workers, scheduler=scheduler, cache_dir=cache)
    val = validate(p, spec, records=records)
    if fem_error:
        console.print(f"FEM discretisation error: {FULL_CASES} held-out states on meshes refined 2× along the profile "
                      "and through the wall (the most deformed also around) …")
        for_validation(val, spec, records, FULL_CASES, workers=workers, scheduler=scheduler, cache_dir=cache,
                       check_around=True)
    else:
        val.fem_error = assess(val, None, reason="--no-fem-error")
    atomic_write_text(d / "validation.json", json.dumps(val.to_dict(), indent=1))
    _print_validation(val)
    console.print(f"wrote {d / 'validation.json'}")


def _report_modes(res, fem, mesh, cache, quick: bool) -> dict:
    """The report's Dynamics data (:func:`validation.report.pipeline.report_modes`), progress on the console."""
    from validation.report.pipeline import report_modes
    return report_modes(res.params, fem, mesh, cache, quick, log=console.print)


def _print_modes(modes: Optional[dict]) -> None:
    if not modes:
        return
    t = Table(title=escape(f"First modes, tendons slack (FEM: {modes['fem']})"))
    for c in ("pressure [kPa]", "FEM bending [Hz]", "rod bending [Hz]", "difference [%]", "FEM axial [Hz]",
              "rod axial [Hz]", "difference [%]"):
        t.add_column(escape(c), justify="right")
    f = lambda v, fmt: "–" if v is None else format(v, fmt)  # noqa: E731
    for r in modes["rows"]:
        t.add_row(f"{r['pressure_kPa']:g}", f(r["fem_bending_frequency_hz"], ".3f"),
                  f(r["rod_bending_frequency_hz"], ".3f"), f(r["bending_difference_pct"], "+.1f"),
                  f(r["fem_axial_frequency_hz"], ".2f"), f(r["rod_axial_frequency_hz"], ".2f"),
                  f(r["axial_difference_pct"], "+.1f"))
    console.print(t)


def report_cmd(
        design: Optional[str] = typer.Option(None, help=DESIGN_HELP + " Default: paper (unless --measurements)."),
        measurements: Optional[pathlib.Path] = typer.Option(None, help="Measured static states instead of the FEM."),
        base: Optional[str] = typer.Option(None, help="Required with --measurements: the actuator as built (preset "
                                                      "or .toml)."),
        quick: bool = typer.Option(False, help=QUICK_HELP),
        fem_error: bool = typer.Option(True, help=FEM_ERROR_HELP),
        tension_max_n: Optional[float] = TMAX_OPT,
        pressure_max_kpa: Optional[float] = PMAX_OPT,
        tendon_friction: Optional[float] = typer.Option(
            None, callback=FRICTION, help=f"Tendon friction coefficient μ [-], {FRICTION.text}, of the FEM's tendons; "
                                          "overrides the design's tendon_friction (default: the design's, 0 = "
                                          "frictionless). μ > 0 adds tension cycles rod vs FEM (hysteresis)."),
        mesh: str = MESH_OPT,
        forms: Optional[str] = FORMS_OPT,
        fit_distance: bool = FIT_D_OPT,
        cases: str = CASES_OPT,
        workers: Optional[int] = WORKERS_OPT,
        scheduler: Optional[str] = SCHEDULER_OPT,
        cache: pathlib.Path = CACHE_OPT,
        out: pathlib.Path = typer.Option(pathlib.Path("bellows_out/report"), help="Output folder."),
        force: bool = FORCE_OPT):
    """Identify, validate and write one HTML report.

    report.html is self-contained; beside it: the actuator file, the fit data and the figures."""
    from validation.report.pipeline import run_report
    _source_check(design, measurements)
    names = _forms(forms, quick)
    _cases_check(cases)
    _base_check(measurements, base)
    if tendon_friction is not None and measurements is not None:
        raise typer.BadParameter("applies to the FEM of a design, not to --measurements", param_hint="'--tendon-friction'")
    fem = None if measurements is not None else _fem_design(design, tension_max_n, pressure_max_kpa)
    limits = {} if fem is None else fem[3]         # checked with the CLI's option names (--tension-max-n, …)
    run = run_report(out, design=None if fem is None else fem[0], measurements=measurements, base=base, quick=quick,
                     fem_error=fem_error, tension_max=limits.get("tension_max"),
                     pressure_max=limits.get("pressure_max"), mesh=mesh, forms=names,
                     fit_distance=fit_distance, cases=cases, workers=workers, scheduler=scheduler, cache_dir=cache,
                     force=force, command=_command_line(), log=console.print, tendon_friction=tendon_friction)
    res, val, stiff = run.identification, run.validation, run.stiffness
    _print_identification(res)
    if val is not None:
        _print_validation(val)
    _print_modes(res.modes)
    if run.friction:
        f = run.friction
        console.print(f"tendon friction: μ = {f['mu_used']:.4g} ({f['mu_source']}; the design's {f['mu_design']:g}), "
                      f"hysteresis {f['status']}: " + ", ".join(
                          f"{r['pressure_kPa']:g} kPa loop ratio {r['loop_ratio']:.2f}" for r in f["rows"]
                          if not r.get("error")))
    console.print(f"{run.seconds:.0f} s; wrote {run.report} (open it in a browser), actuator.toml, "
                  f"fit.json{', validation.json' if val else ''}{', stiffness.json' if stiff else ''} and figures/ in "
                  f"{run.out}")


def calibrate_cmd(
        design: str = typer.Option("paper", help=DESIGN_HELP + " The starting design."),
        target_ea_n: Optional[float] = typer.Option(None, callback=POSITIVE,
                                                    help="Target axial stiffness EA at rest [N], > 0."),
        target_ei_n_m2: Optional[float] = typer.Option(None, callback=POSITIVE,
                                                       help="Target bending stiffness EI at rest [N m²], > 0."),
        target_d_eff_mm: Optional[float] = typer.Option(None, callback=POSITIVE,
                                                        help="Target pressure diameter D_eff [mm], > 0 (secant at "
                                                             "--pressure-kpa)."),
        free: str = typer.Option("wall_thickness,root_radius,crest_radius",
                                 help=f"Parameters to adjust, comma separated, from {one_of(FREE_PARAMETERS)}."),
        range_factor: float = typer.Option(1.6, callback=RANGE_FACTOR, help="Each free parameter stays within "
                                           f"[start/f, start·f]; f is {RANGE_FACTOR.text}."),
        pressure_kpa: float = typer.Option(60.0, callback=FEM_PRESSURE_KPA,
                                           help=f"Pressure of the secant D_eff measure, {FEM_PRESSURE_KPA.text}."),
        mesh: str = MESH_OPT,
        workers: Optional[int] = WORKERS_OPT,
        cache: pathlib.Path = CACHE_OPT,
        out: pathlib.Path = typer.Option(pathlib.Path("bellows_out/calibrated_design.toml"),
                                         help="Design .toml to write."),
        force: bool = typer.Option(False, help="Overwrite --out if it exists.")):
    """Fit an FEM design to target EA, EI, D_eff.

    Adjusts the chosen dimensions and writes a design .toml."""
    from validation.identification.calibrate import calibrate
    from validation.reference.designs import design_to_toml, load_design
    target = {k: v for k, v in (("EA", target_ea_n), ("EI", target_ei_n_m2),
                                ("D_eff", None if target_d_eff_mm is None else target_d_eff_mm * 1e-3)) if v is not None}
    if not target:
        raise InputError("give at least one of --target-ea-n, --target-ei-n-m2, --target-d-eff-mm")
    names = [n.strip() for n in free.split(",") if n.strip()]
    bad = [n for n in names if n not in FREE_PARAMETERS]
    if bad or not names:
        raise InputError(f"--free: cannot adjust {', '.join(bad) or '(none given)'}; choose from "
                         f"{', '.join(FREE_PARAMETERS)}")
    path = prepare_output_file(out, force=force, suffixes=(".toml",))
    geo, mat = load_design(design)
    start = {n: getattr(geo, n) if n in GEOMETRY_PARAMETERS else getattr(mat, n) for n in names}
    bounds = {n: (v / range_factor, v * range_factor) for n, v in start.items()}
    res = calibrate(target, geo, mat, bounds, mesh=mesh, p_mid=pressure_kpa * 1e3, workers=workers, cache_dir=cache)
    atomic_write_text(path, f"# calibrated by {_command_line()}\n# measures: "
                      + ", ".join(f"{k} = {v:.5g}" for k, v in res.measures.items())
                      + "\n" + design_to_toml(res.geometry, res.material, name=f"{design} (calibrated)"))
    for k, m in res.mismatch_pct.items():
        console.print(f"{k}: {res.measures[k]:.5g} (target {target[k]:.5g}, {m:+.1f} %)")
    console.print(("converged" if res.converged else "[yellow]not converged: best design written[/yellow]")
                  + f"; wrote {path}")


def damping_cmd(record: pathlib.Path = typer.Argument(..., help="A free decay: simulation.csv of `bellows "
                                                     "simulate`, or a run log (.h5)."),
                start_s: Optional[float] = typer.Option(None, callback=START_S, help="Fit from this time, "
                                                        f"{START_S.text} (skip the release)."),
                end_s: Optional[float] = typer.Option(None, callback=END_S, help=f"Fit up to this time, {END_S.text} "
                                                      "(after --start-s)."),
                true_tip: bool = typer.Option(False, "--true-tip", help="Run log of a simulated rig: fit its "
                                              "noise-free tip instead of the tracker's."),
                tendons: Optional[str] = typer.Option(None, help="How the tendons were held, for the model's "
                                                      "frequency beside the measured one: 'held' (constant "
                                                      "tension) or 'locked' (motors); default: held for a "
                                                      "CSV, locked for a run log."),
                preset: str = typer.Option("paper", help="The actuator (preset or .toml) whose first mode is "
                                           "compared."),
                as_json: bool = typer.Option(False, "--json", help="Print JSON instead of a table.")):
    """Damping from a free decay: natural frequency and damping ratio with 95 % intervals, as Rayleigh
    coefficients for the actuator file, beside the model's first mode (docs/dynamics.md).  A record that holds
    no decay (no oscillation above the noise, a growing oscillation, a ζ interval containing 0) is an error."""
    from ancf import Model, presets
    from validation.identification.damping import MIN_AMPLITUDE_TO_NOISE, fit_free_decay, read_decay

    if tendons not in (None, "held", "locked"):
        raise InputError(f"--tendons must be 'held' or 'locked', got {tendons!r}")
    if start_s is not None and end_s is not None and not end_s > start_s:
        raise InputError(f"--end-s must be after --start-s, got {start_s:g} s and {end_s:g} s")
    t, tip, info = read_decay(record, true_tip=true_tip)
    fit = fit_free_decay(t, tip, t_start=start_s, t_end=end_s)
    out = {"record": str(record), **fit.to_dict()}
    model = Model(presets.get(preset))
    tendons = tendons or ("held" if record.suffix.lower() == ".csv" else "locked")
    if info.get("tensions") is not None and info.get("pressure") is not None and len(info["tensions"]) == model.m:
        T = np.maximum(np.asarray(info["tensions"], float), 0.0)
        eq = model.fk(T, info["pressure"], check_limits=False)
        if tendons == "locked":
            eq = model.fk_locked(eq.tendon_lengths, info["pressure"], q0=eq.q, tensions0=eq.tensions,
                                 check_limits=False)
        out["model_frequency_hz"] = float(model.modes(eq, 1).frequencies_hz[0])
        out["model_state"] = {"tensions_N": T.tolist(), "pressure_kPa": info["pressure"] / 1e3, "tendons": tendons}
    if as_json:
        typer.echo(json.dumps(to_jsonable(out), indent=2))
        return
    lo, hi = fit.frequency_ci
    t_ = Table(title=escape(f"free decay of {record} ({fit.samples} samples, {fit.t_start:.3g}–{fit.t_end:.3g} s, "
                            f"residual {fit.residual_rms * 1e3:.3g} mm RMS, amplitude {fit.amplitude_to_noise:.3g}× "
                            f"the residual, {fit.cycles_above_noise:.3g} periods above "
                            f"{MIN_AMPLITUDE_TO_NOISE:g}× it)"))
    for c in ("quantity", "value", f"{fit.confidence:.0%} interval"):
        t_.add_column(escape(c))
    t_.add_row("natural frequency [Hz]", f"{fit.frequency_hz:.4f}", f"{lo:.4f} … {hi:.4f}")
    t_.add_row("damping ratio ζ", f"{fit.damping_ratio:.5f}", f"{fit.damping_ratio_ci[0]:.5f} … {fit.damping_ratio_ci[1]:.5f}")
    t_.add_row("rayleigh_alpha_per_s (α = 2ζω)", f"{fit.alpha_per_s:.5g}", f"{fit.alpha_ci[0]:.5g} … {fit.alpha_ci[1]:.5g}")
    t_.add_row("rayleigh_beta_s (β = 2ζ/ω)", f"{fit.beta_s:.5g}", f"{fit.beta_ci[0]:.5g} … {fit.beta_ci[1]:.5g}")
    if "model_frequency_hz" in out:
        t_.add_row(f"model's first mode [Hz] ({tendons})", f"{out['model_frequency_hz']:.4f}",
                   f"measured/model {fit.frequency_hz / out['model_frequency_hz']:.4f}")
    console.print(t_)
    console.print(escape("  α damps every mode at the rate ζω of this one; β damps higher modes more. A measured "
                         "frequency far from the model's is a mass or stiffness question, not a damping one."))


def register(app: typer.Typer) -> None:
    """Attach ``identify``, ``validate``, ``report``, ``calibrate`` and ``identify-damping`` to the root
    ``bellows`` app."""
    app.command("identify-damping", short_help="Damping ratio and frequency from a free decay, with intervals.")(damping_cmd)
    app.command("identify")(identify_cmd)
    app.command("validate")(validate_cmd)
    app.command("report")(report_cmd)
    app.command("calibrate")(calibrate_cmd)
