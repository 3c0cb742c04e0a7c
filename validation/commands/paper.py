"""``bellows paper workspace | segments | stiffness | convergence | loads | table1 | ablation | loading | dynamic | all | compare``.

Each subcommand runs on ``--preset`` (default ``paper``), writes ``<study>.json`` and figures (PNG, SVG)
to ``--out`` (default ``bellows_out/paper``; existing results are kept unless ``--force``) and prints a
table that sets our numbers beside the paper's; ``--json`` prints the result as JSON (SI units, unit in
each key) instead.  ``compare`` prints every headline number for several presets side by side.  Product
errors give one ``error:`` line and exit status 2; Ctrl-C exits 130 and says where the finished work is.
The controller studies (``table1``, ``ablation``, ``loading``) come from
:mod:`validation.paper.control`; when it is missing they say so and exit with status 2 (``all`` skips
them with a note).  ``convergence`` (convergence.json and a log-log figure with the fitted slope) and ``loads``
(loads.json) write and print the element convergence and the loading checks, and say which solves failed,
why, and what that does to the numbers.  ``table1 --mismatch`` runs Table I on the imperfect simulated rig.
"""

from __future__ import annotations

import contextlib

import json
import pathlib
import sys
from typing import Optional

import typer
from rich.console import Console

from ancf import clitools
from ancf.errors import BellowsError
from ancf.export import to_jsonable
from ancf import presets as ancf_presets
from ancf.outputs import prepare_output_dir
from ancf.params import N_ELEMENTS_MAX, N_ELEMENTS_MIN
from ancf.textfmt import one_of

from validation import paper
from validation.infra.runner import RunInterrupted

app = typer.Typer(help="Reproductions of the paper's studies (workspace, stiffness, Table I, ...).",
                  no_args_is_help=True, add_completion=False, pretty_exceptions_enable=False)

OUT_HELP = "Output folder for the JSON, figures (PNG, SVG) and data files."
DEFAULT_OUT = pathlib.Path("bellows_out/paper")
_DEFAULT_COMPARE = ("paper_unscaled", "paper_scaled", "paper_scaled_020", "paper_diameter")
PRESET_HELP = f"Actuator preset name {one_of(ancf_presets.NAMES)} or a path to an actuator .toml file."

# option ranges, checked while the command line is parsed (ancf.clitools): integers by typer's min=/max=, floats by
# clitools.number_range, comma lists by clitools.parse_numbers; a value outside is a usage error (exit status 2)
SAMPLES = {"min": 1, "max": clitools.SAMPLES_MAX}
SEED = {"min": 0, "max": clitools.SEED_MAX}
WORKERS = {"min": 1, "max": clitools.WORKERS_MAX}
N_ELEMENTS = {"min": N_ELEMENTS_MIN, "max": N_ELEMENTS_MAX}
#: payloads of the studies [kg] (the same (0, 1] kg as the cyclic mass of validation.paper.dynamic)
MASS_KG = clitools.number_range(0.0, 1.0, low_open=True, unit="kg")
MASS_G = clitools.number_range(0.0, 1000.0, low_open=True, unit="g")
#: the cyclic loads' frequencies [Hz]: at most validation.paper.dynamic' 20 Hz, at least 0.01 Hz (a 100 s period;
#: lower ones would simulate for days)
FREQ_HZ = {"low": 0.01, "high": 20.0}
#: the loop's times [ms] (the paper's rig: 100, 10, 20 ms): at most 10 s each
LOOP_MS = clitools.number_range(0.0, 10_000.0, unit="ms")
MOTOR_RATE = clitools.number_range(0.0, low_open=True, unit="mm/s")
RATIO = clitools.number_range(0.0, 1.0)
#: the dynamic LACC's observer bandwidth [Hz]: below a quarter of the 1 kHz loop's Nyquist frequency
OBSERVER_HZ = clitools.number_range(0.0, 125.0, low_open=True, high_open=True, unit="Hz")
#: time from a measurement to the motors acting on its command [ms]: at most 30 periods of the 1 kHz loop
LOOP_LATENCY_MS = clitools.number_range(0.0, 30.0, unit="ms")
#: the bound of the modes' frequency error the dynamic LACC stays stable for [%] (0: the model as exact)
MODEL_ERROR_PCT = clitools.number_range(0.0, 50.0, high_open=True, unit="%")


def _console(as_json: bool) -> Console:
    # with --json the table and notes go to stderr so that stdout stays valid JSON
    return Console(width=130, stderr=as_json)


def _echo_json(data) -> None:
    typer.echo(json.dumps(to_jsonable(data), indent=2))


def _fail(msg: str) -> None:
    typer.secho(f"error: {msg}", fg=typer.colors.RED, err=True)
    raise typer.Exit(2)



@contextlib.contextmanager
def _scheduler_errors(scheduler, always_on_import: bool = False):
    """Turn a missing dask or an unreachable scheduler into one clear error line (exit 2), Ctrl-C into a
    note saying where the finished work is (exit 130), and any other error of the product into one
    ``error:`` line (exit 2)."""
    try:
        yield
    except RunInterrupted as exc:
        _interrupted(exc)
    except BellowsError as exc:
        _fail(str(exc))
    except ImportError as exc:
        if scheduler is None and not always_on_import:
            raise
        _fail(f"{exc} (the --scheduler option needs dask[distributed])")
    except OSError as exc:
        if scheduler is None:
            raise
        _fail(f"cannot use the dask scheduler {scheduler!r}: {exc}")

FORCE_HELP = "Overwrite existing result files in --out."


def _interrupted(exc: RunInterrupted) -> None:
    where = f"; the finished samples are in {exc.saved_to}" if exc.saved_to else ""
    typer.secho(f"interrupted: {len(exc.completed)} of {exc.total} tasks finished{where}", fg=typer.colors.YELLOW,
                err=True)
    raise typer.Exit(130)


@app.command()
def workspace(samples: int = typer.Option(10_000, **SAMPLES, help="Monte Carlo samples per mode (paper: 10 000)."),
              seed: int = typer.Option(0, **SEED, help="Random seed (same seed → identical clouds)."),
              workers: Optional[int] = typer.Option(None, **WORKERS,
                                                    help="Worker processes (default: all cores; 1 = serial)."),
              scheduler: Optional[str] = typer.Option(
                  None, help="dask scheduler address (tcp://host:8786), or 'local' for a temporary "
                             "LocalCluster with --workers processes."),
              chunk_size: int = typer.Option(100, **SAMPLES, help="Samples per task."),
              warm_start: bool = typer.Option(True, help="Warm-start FK within a chunk (Morton order)."),
              preset: str = typer.Option("paper", help=PRESET_HELP),
              out: pathlib.Path = typer.Option(DEFAULT_OUT, help=OUT_HELP),
              progress: bool = typer.Option(True, help="Show a progress bar."),
              force: bool = typer.Option(False, "--force", help=FORCE_HELP),
              as_json: bool = typer.Option(False, "--json", help="Print JSON instead of a table.")):
    """Workspace of the TD and TPHD modes (paper Sec IV-A, Fig 4): convex-hull volumes and their ratio.

    Finished samples are appended to workspace_samples.csv as the run goes; Ctrl-C keeps them."""
    con = _console(as_json)
    with _scheduler_errors(scheduler, always_on_import=True):
        res = paper.workspace(samples=samples, seed=seed, workers=workers, scheduler=scheduler, out=out,
                              progress=progress and not as_json, chunk_size=chunk_size,
                              warm_start=warm_start, params=preset, force=force)
    if as_json:
        _echo_json({k: v for k, v in res.items() if k != "clouds"})
    else:
        paper.print_workspace(res, con)
    if res["failures"] or res["collapsed"]:
        con.print(f"[yellow]{res['collapsed']} samples collapsed and {res['failures']} FK solves failed; "
                  "their inputs are in workspace.json[/yellow]")
    con.print(f"wrote {out}/workspace.json, workspace_samples.csv, workspace_clouds.npz, workspace.png, "
              "workspace.svg")


#: the single segment's length of ``paper segments`` [mm] (validation.paper.segments.single_params' range)
SINGLE_LENGTH_MM = clitools.number_range(50.0, 500.0, unit="mm")


@app.command()
def segments(samples: Optional[int] = typer.Option(None, **SAMPLES, help="Workspace Monte Carlo samples of each "
                                                   "actuator (default 1000; --quick: 40)."),
             seed: int = typer.Option(0, **SEED, help="Random seed (same seed → identical clouds)."),
             rays: Optional[int] = typer.Option(None, min=2, max=64, help="Azimuths along which the chain's "
                                                "reachable tip tilt is bracketed at each point (default 8; "
                                                "--quick: 4)."),
             bisections: Optional[int] = typer.Option(None, min=0, max=10, help="Halvings of each tilt bracket "
                                                      "(default 3; --quick: 1)."),
             points: Optional[int] = typer.Option(None, min=1, max=3, help="Target points (default 3; --quick: 1)."),
             single_length_mm: float = typer.Option(170.0, callback=SINGLE_LENGTH_MM, help="Length of the single "
                                                    f"segment, {SINGLE_LENGTH_MM.text} (170: the chain's length "
                                                    "to its last cap; 160: the paper preset)."),
             quick: bool = typer.Option(False, "--quick", help="Small sample counts: seconds, for a check."),
             workers: Optional[int] = typer.Option(1, **WORKERS, help="Worker processes for the workspace FK."),
             out: pathlib.Path = typer.Option(DEFAULT_OUT, help=OUT_HELP),
             progress: bool = typer.Option(True, help="Show progress."),
             force: bool = typer.Option(False, "--force", help=FORCE_HELP),
             as_json: bool = typer.Option(False, "--json", help="Print JSON instead of a table.")):
    """What a second segment buys: one segment against two_segment (workspace, tip directions and stiffness
    at a point, an obstacle); docs/multisegment.md.  Writes segments.json, segments_clouds.npz and 3 PNGs."""
    from validation.paper import segments as sg
    con = _console(as_json)
    log = (lambda s: con.print(f"[dim]{s}[/dim]")) if progress else (lambda s: None)
    with _scheduler_errors(None):
        res = sg.segments_study(samples, seed, rays=rays, bisections=bisections, n_points=points, quick=quick,
                                single_length=single_length_mm * 1e-3, workers=workers,
                                progress=progress and not as_json, out=out, force=force, log=log)
    if as_json:
        _echo_json(sg.public_result(res))
    else:
        from rich.markup import escape
        from rich.table import Table
        tab = Table(title=f"{res['single']} vs {res['chain']} (seed {seed})")
        for col in ("quantity", "one segment", "two segments"):
            tab.add_column(col)
        for row in sg.table_rows(res):
            tab.add_row(*map(escape, row))
        con.print(tab)
    con.print(f"wrote {out}/{', '.join(sg.FILES)}")


@app.command()
def stiffness(pressures_kpa: str = typer.Option("0,25,50",
                                                help="Chamber pressures in kPa, comma separated, each >= 0."),
              tensions_n: str = typer.Option("0,1,2,3,4,5",
                                             help="Tensions of the top tendon T1 in N, comma separated, each >= 0."),
              mass_kg: float = typer.Option(0.05, callback=MASS_KG,
                                            help=f"Tip payload, {MASS_KG.text} (paper: 0.05)."),
              preset: str = typer.Option("paper", help=PRESET_HELP),
              out: pathlib.Path = typer.Option(DEFAULT_OUT, help=OUT_HELP),
              force: bool = typer.Option(False, "--force", help=FORCE_HELP),
              as_json: bool = typer.Option(False, "--json", help="Print JSON instead of a table.")):
    """Stiffness vs T1, constant tension vs locked tendons (paper Sec V-C, Fig 9)."""
    pressures = clitools.parse_numbers(pressures_kpa, "--pressures-kpa", low=0.0, scale=1e3)
    tensions = clitools.parse_numbers(tensions_n, "--tensions-n", low=0.0)
    con = _console(as_json)
    with _scheduler_errors(None):
        res = paper.stiffness_vs_tension(pressures=pressures, tensions=tensions, mass=mass_kg, out=out,
                                         params=preset, force=force)
    if as_json:
        _echo_json(res)
    else:
        paper.print_stiffness(res, con)
    con.print(f"wrote {out}/stiffness.json, stiffness.png, stiffness.svg")


def _control(name: str, out: pathlib.Path, as_json: bool, preset: str = "paper", force: bool = False,
             mismatch: bool = False, study_kw: Optional[dict] = None) -> None:
    con = _console(as_json)
    with _scheduler_errors(None):
        params = paper.resolve_params(preset)
        out = prepare_output_dir(out, paper.study_files(name), force=force)     # before the study runs
        extra = dict(study_kw or {})
        if mismatch:      # the simulated rig of ``bellows control --rig sim --mismatch`` around this preset
            from controller import PlantOptions
            extra["plant_options"] = PlantOptions.mismatched(base=params)
        res = {**paper.CONTROL_STUDIES, **paper.RIG_STUDIES}[name](out=out, params=params, **extra)
    path = paper.write_json(out / paper.study_files(name)[0], res)
    if as_json:
        _echo_json(res)
    else:
        paper.print_control_study(name, res, con)
    con.print(f"wrote {path}")


#: Controller and rig-protocol studies: one command each, same options (name → summary for --help).
CONTROL_COMMANDS = {
    "table1": "Table I: VF-CC vs LACC residual error after five iterations (up / horizontal / down).",
    "ablation": "FK- vs IK-derived compliance in the LACC loop (paper: IK-derived ≈ 50 % faster).",
    "loading": "Continuous (0 → 110 g → 0 over 50 s) and cyclic (0.125 Hz) loading (paper Sec V-E).",
    "tracking": "Open-loop IK tracking of a 30 mm circle, a 50 mm rose curve and \"SJTU\" (Sec V-B): RMSE",
    "feedforward": "Open-loop tracking under tip loads, Fig 8 protocol (15 g + 25 + 25 + 50 g)",
}


def _control_command(name: str, summary: str):
    def command(out: pathlib.Path = typer.Option(DEFAULT_OUT, help=OUT_HELP),
                preset: str = typer.Option("paper", help=PRESET_HELP),
                force: bool = typer.Option(False, "--force", help=FORCE_HELP),
                as_json: bool = typer.Option(False, "--json", help="Print JSON instead of a table.")):
        _control(name, out, as_json, preset, force)
    command.__doc__ = summary
    command.__name__ = name
    return command


for _name, _summary in CONTROL_COMMANDS.items():
    if _name not in ("table1", "loading"):
        app.command(_name)(_control_command(_name, _summary))


def _friction_study(plant_friction: Optional[str], friction_aware: bool) -> dict:
    """The study's keyword arguments of ``--plant-friction`` (μ values in [0, 1]) and ``--friction-aware`` (which
    needs it): {} without friction."""
    if friction_aware and plant_friction is None:
        raise typer.BadParameter("needs --plant-friction (the plant's μ values)", param_hint="'--friction-aware'")
    return {} if plant_friction is None else {
        "friction": clitools.parse_numbers(plant_friction, "--plant-friction", low=0.0, high=1.0),
        "friction_aware": friction_aware}


#: ``--friction-aware`` of ``paper loading`` and ``paper table1``
FRICTION_AWARE_HELP = "With --plant-friction: also the LACC whose model has the plant's μ (controller.friction_aware)."


@app.command("loading")
def loading(out: pathlib.Path = typer.Option(DEFAULT_OUT, help=OUT_HELP),
            preset: str = typer.Option("paper", help=PRESET_HELP),
            plant_friction: Optional[str] = typer.Option(
                None, help="Tendon friction coefficients μ of the plant's actuator, comma separated, each in "
                           "[0, 1] (e.g. 0,0.1,0.3): both load cases once per μ, LACC's model frictionless, "
                           "each correction a fixed time on the loop's clock; docs/friction.md."),
            friction_aware: bool = typer.Option(False, "--friction-aware", help=FRICTION_AWARE_HELP),
            aware_compute_ms: Optional[float] = typer.Option(
                None, callback=LOOP_MS, help=f"With --friction-aware: its compute time per correction on the loop's "
                                             f"clock, {LOOP_MS.text} (default 500, its measured median)."),
            force: bool = typer.Option(False, "--force", help=FORCE_HELP),
            as_json: bool = typer.Option(False, "--json", help="Print JSON instead of a table.")):
    """Continuous (0 → 110 g → 0 over 50 s) and cyclic (0.125 Hz) loading (paper Sec V-E).

    With --plant-friction the plant's tendons have friction (one run per μ; the frictionless study's IK-compliance
    comparison and bandwidth rows are not run)."""
    kw = _friction_study(plant_friction, friction_aware)
    if aware_compute_ms is not None and not friction_aware:
        raise typer.BadParameter("needs --friction-aware", param_hint="'--aware-compute-ms'")
    if aware_compute_ms is not None:
        kw["friction_compute"] = (None, aware_compute_ms * 1e-3)
    _control("loading", out, as_json, preset, force, study_kw=kw)


@app.command("table1")
def table1(out: pathlib.Path = typer.Option(DEFAULT_OUT, help=OUT_HELP),
           preset: str = typer.Option("paper", help=PRESET_HELP),
           mismatch: bool = typer.Option(False, "--mismatch", help="Run on an imperfect simulated rig instead of the "
                                         "controllers' own noise-free model: +15 % line mass, stiffness × 0.95, +5 g "
                                         "tip, 0.05 mm tracker noise, 1 µm motor steps, 0.1 N tendon friction "
                                         "(PlantOptions.mismatched, as bellows control --rig sim --mismatch)."),
           plant_friction: Optional[str] = typer.Option(
               None, help="Tendon friction coefficients μ of the plant's actuator, comma separated, each in "
                          "[0, 1] (e.g. 0,0.1,0.3): Table I once per μ, the controllers' model frictionless, "
                          "LACC run on to 20 iterations (iterations to 0.1 mm); docs/friction.md."),
           friction_aware: bool = typer.Option(False, "--friction-aware", help=FRICTION_AWARE_HELP),
           force: bool = typer.Option(False, "--force", help=FORCE_HELP),
           as_json: bool = typer.Option(False, "--json", help="Print JSON instead of a table.")):
    """Table I: VF-CC vs LACC residual error after five iterations (up / horizontal / down).

    The plant is simulated (locked-length FK with the load hidden); by default it is the controllers' own model
    without noise, with --mismatch an imperfect rig, with --plant-friction a rig whose tendons have friction.
    The paper's numbers are measurements on its physical rig."""
    kw = _friction_study(plant_friction, friction_aware)
    _control("table1", out, as_json, preset, force, mismatch=mismatch, study_kw=kw)


@app.command("dynamic", short_help="Cyclic loads 0.125–2 Hz: quasi-static LACC on a static vs a dynamic plant.")
def dynamic(frequencies_hz: str = typer.Option("0.125,0.25,0.5,1,2",
                                               help="Cyclic load frequencies [Hz], comma separated, each in "
                                                    f"[{FREQ_HZ['low']:g}, {FREQ_HZ['high']:g}]."),
            cycles: int = typer.Option(3, min=2, max=50,              # validation.paper.dynamic' range
                                       help="Load cycles per frequency (the first is not judged)."),
            mass_g: float = typer.Option(80.0, callback=MASS_G, help=f"Cyclic tip mass, {MASS_G.text} (paper: 80)."),
            motor_rate_mm_s: float = typer.Option(5.0, callback=MOTOR_RATE,
                                                  help=f"Motor speed, {MOTOR_RATE.text} (the loop's travel time)."),
            settle_ms: float = typer.Option(100.0, callback=LOOP_MS,
                                            help=f"Wait after each move before measuring, {LOOP_MS.text}."),
            compute_ms: float = typer.Option(10.0, callback=LOOP_MS,
                                             help=f"Controller step time on the rig clock, {LOOP_MS.text}."),
            latency_ms: float = typer.Option(20.0, callback=LOOP_MS,
                                             help=f"Actuation latency per move, {LOOP_MS.text}."),
            damping_ratio: float = typer.Option(0.1, callback=RATIO, help="Damping ratio of the dynamic plant's "
                                                f"first mode, {RATIO.text}."),
            shaping: bool = typer.Option(False, "--shaping", help="Also run the dynamic plant with ZV-shaped "
                                         "moves (input shaping at the model's first locked mode)."),
            dynamic_lacc: bool = typer.Option(False, "--dynamic-lacc", help="Also run the dynamic LACC (load "
                                              "observer at 1 kHz) on the dynamic plant."),
            mismatch: bool = typer.Option(False, "--mismatch", help="Every plant differs from the controllers' "
                                          "model: EI -20 %, D_eff +2.5 %, the model's damping ratio half the "
                                          "plant's, 0.05 mm tracker noise."),
            observer_bandwidth_hz: float = typer.Option(12.0, callback=OBSERVER_HZ, help="Dynamic LACC: the "
                                                        f"observer's bandwidth asked, {OBSERVER_HZ.text} (lowered "
                                                        "where --model-error-pct needs it)."),
            loop_latency_ms: float = typer.Option(2.0, callback=LOOP_LATENCY_MS, help="Dynamic LACC: time from a "
                                                  f"measurement to its command acting, {LOOP_LATENCY_MS.text}."),
            model_error_pct: float = typer.Option(12.0, callback=MODEL_ERROR_PCT, help="Dynamic LACC: the plant's "
                                                  "modal frequency error the loop stays stable for, "
                                                  f"{MODEL_ERROR_PCT.text} (0: the model taken as exact)."),
            internal_model: bool = typer.Option(True, "--internal-model/--no-internal-model", help="Dynamic "
                                                "LACC: learn a periodic load's frequency online and add its "
                                                "oscillator to the observer (docs/dynamics.md)."),
            preset: str = typer.Option("paper", help=PRESET_HELP),
            out: pathlib.Path = typer.Option(DEFAULT_OUT, help=OUT_HELP),
            force: bool = typer.Option(False, "--force", help=FORCE_HELP),
            as_json: bool = typer.Option(False, "--json", help="Print JSON instead of a table.")):
    """Cyclic loading at rising frequency: quasi-static LACC on the static vs the dynamic plant
    (docs/dynamics.md).  Writes dynamic_loading.json and dynamic_loading.png."""
    from validation.paper.dynamic import dynamic_loading
    freqs = clitools.parse_numbers(frequencies_hz, "--frequencies-hz", **FREQ_HZ)
    con = _console(as_json)
    with _scheduler_errors(None):
        params = paper.resolve_params(preset)
        out = prepare_output_dir(out, ("dynamic_loading.json", "dynamic_loading.png"), force=force)
        with con.status("running the cyclic loads on both plants") as st:
            res = dynamic_loading(frequencies=freqs, cycles=cycles, cyclic_mass=mass_g * 1e-3,
                                  motor_rate=motor_rate_mm_s * 1e-3, settle_time=settle_ms * 1e-3,
                                  compute_time=compute_ms * 1e-3, actuation_latency=latency_ms * 1e-3,
                                  damping=damping_ratio, shaping=shaping, dynamic_lacc=dynamic_lacc,
                                  mismatch=mismatch, observer_bandwidth_hz=observer_bandwidth_hz,
                                  loop_latency=loop_latency_ms * 1e-3,
                                  model_error=model_error_pct * 1e-2 if model_error_pct > 0 else None,
                                  internal_model=internal_model, params=params, out=out,
                                  progress=lambda f, n: st.update(f"{f:g} Hz, {n} plant done"))
    if as_json:
        _echo_json(res)
    else:
        paper.print_control_study("dynamic", res, con)
    con.print(f"wrote {out}/dynamic_loading.json and dynamic_loading.png")


@app.command("all")
def all_(samples: int = typer.Option(10_000, **SAMPLES, help="Workspace Monte Carlo samples per mode."),
         seed: int = typer.Option(0, **SEED, help="Random seed."),
         workers: Optional[int] = typer.Option(None, **WORKERS, help="Worker processes for the workspace."),
         scheduler: Optional[str] = typer.Option(None, help="dask scheduler address, or 'local'."),
         out: pathlib.Path = typer.Option(DEFAULT_OUT, help=OUT_HELP),
         progress: bool = typer.Option(True, help="Show a progress bar."),
         preset: str = typer.Option("paper", help=PRESET_HELP),
         force: bool = typer.Option(False, "--force", help=FORCE_HELP),
         as_json: bool = typer.Option(False, "--json", help="Print the summary as JSON.")):
    """Every study into one folder (controller studies are skipped with a note if unavailable)."""
    con = _console(as_json)
    with _scheduler_errors(scheduler):
        res = paper.run_all(out, samples=samples, seed=seed, workers=workers, scheduler=scheduler,
                            progress=progress and not as_json, console=con, params=preset, force=force)
    if as_json:
        _echo_json(res["summary"])
    con.print(f"wrote {out}/summary.json and the studies' files")


@app.command()
def convergence(n_values: str = typer.Option("1,2,3,4,5,6,8", help="Numbers of elements, comma separated, each "
                                             f"{N_ELEMENTS_MIN} to {N_ELEMENTS_MAX}."),
                n_ref: int = typer.Option(16, **N_ELEMENTS, help="Elements of the reference solution."),
                preset: str = typer.Option("paper", help=PRESET_HELP),
                out: pathlib.Path = typer.Option(DEFAULT_OUT, help=OUT_HELP),
                force: bool = typer.Option(False, "--force", help=FORCE_HELP),
                as_json: bool = typer.Option(False, "--json", help="Print JSON instead of a table.")):
    """Tip error vs the number of elements n (paper: 6.1 -> 0.3 mm from n = 1 to 6).

    Writes convergence.json and a log-log figure of the error vs n with the fitted slope (convergence.png, .svg)."""
    from validation.paper import convergence as cv
    from validation.paper.plots import plot_convergence
    ns = clitools.parse_numbers(n_values, "--n-values", low=N_ELEMENTS_MIN, high=N_ELEMENTS_MAX, integer=True)
    con = _console(as_json)
    with _scheduler_errors(None):
        out = prepare_output_dir(out, cv.FILES, force=force)        # before the study runs
        res = cv.element_convergence(preset, n_values=ns, n_ref=n_ref)
        paper.write_json(out / cv.FILES[0], res)
        plot_convergence(res, out)
    if as_json:
        _echo_json(res)
    else:
        for n, e, ok in zip(res["n"], res["tip_error_m"], res["complete"]):
            con.print(f"n = {n:2d}: tip error {e * 1e3:8.3f} mm" + ("" if ok else "  (some state failed: lower bound)"))
        fit = ", ".join(map(str, res["rate_n"])) or "none"
        con.print(f"rate {res['rate']:.2f} (log-log slope over n = {fit}); paper: 6.1 mm at n = 1, 0.3 mm at n = 6")
        _print_notes(con, res["notes"], f"{len(res['failures'])} failed solves")
    con.print(f"wrote {out}/{', '.join(cv.FILES)}")


def _print_notes(con: Console, notes, title: str) -> None:
    """``title:`` and one bullet per note (yellow; the text escaped from rich markup)."""
    from rich.markup import escape
    if notes:
        con.print(f"[yellow]{escape(title)}:[/yellow]")
        for note in notes:
            con.print(f"[yellow]  - {escape(note)}[/yellow]")


@app.command()
def loads(mass_kg: float = typer.Option(0.110, callback=MASS_KG,
                                       help=f"Payload of the locked drift, {MASS_KG.text} (paper: 0.110)."),
          hold_mass_kg: float = typer.Option(0.100, callback=MASS_KG,
                                             help=f"Payload to hold in each configuration, {MASS_KG.text}."),
          preset: str = typer.Option("paper", help=PRESET_HELP),
          out: pathlib.Path = typer.Option(DEFAULT_OUT, help=OUT_HELP),
          force: bool = typer.Option(False, "--force", help=FORCE_HELP),
          as_json: bool = typer.Option(False, "--json", help="Print JSON instead of a table.")):
    """Locked drift under a payload, holding a payload in the Table I configurations, and the IK time.

    Writes loads.json ({"drift", "hold", "ik_time"}, SI units, the unit in each key)."""
    from validation.paper.loads import FILES, hold_notes, hold_payload, ik_time, locked_drift
    con = _console(as_json)
    with _scheduler_errors(None):
        out = prepare_output_dir(out, FILES, force=force)           # before the study runs
        res = {"drift": locked_drift(preset, mass=mass_kg), "hold": hold_payload(preset, mass=hold_mass_kg),
               "ik_time": ik_time(preset)}
        res["notes"] = hold_notes(res["hold"])
        paper.write_json(out / FILES[0], res)
    if as_json:
        _echo_json(res)
    else:
        d = res["drift"]
        con.print(f"locked drift under {mass_kg * 1e3:g} g: {d['drift_m'] * 1e3:.2f} mm (tip {d['tip_angle_deg']:.1f}°; "
                  "paper: over 10 mm at 110 g)")
        for name, row in res["hold"]["configurations"].items():
            need = row["max_tension_needed_N"]
            need_text = (f"{need:.2f} N" if row["tensions_needed_N"] is not None
                         else f"none ≤ {res['hold']['relaxed_tension_max_N']:g} N (see below)")
            con.print(f"holds {hold_mass_kg * 1e3:g} g {name} (tip {row['tip_angle_deg']:.1f}°): "
                      f"{'yes' if row['held'] else 'no'}, max tension needed {need_text}")
        t = res["ik_time"]
        con.print(f"IK time: cold {t['cold_s'] * 1e3:.2f} ms, warm {t['warm_s'] * 1e3:.2f} ms (paper: 2.95 s)")
        _print_notes(con, res["notes"], "why")
    con.print(f"wrote {out}/{FILES[0]}")


@app.command()
def compare(presets: str = typer.Option(",".join(_DEFAULT_COMPARE),
                                        help="Presets to compare, comma separated (names or .toml paths)."),
            samples: int = typer.Option(5000, **SAMPLES, help="Workspace samples per mode and seed."),
            seeds: str = typer.Option("0,1", help=f"Workspace seeds, comma separated, each 0 to {clitools.SEED_MAX} "
                                                  "(two give the spread)."),
            workers: Optional[int] = typer.Option(None, **WORKERS, help="Worker processes for the workspace."),
            control: bool = typer.Option(True, help="Run the controller studies (Table I, ablation, loading)."),
            out: pathlib.Path = typer.Option(pathlib.Path("bellows_out/paper_compare"), help=OUT_HELP),
            progress: bool = typer.Option(True, help="Show progress."),
            force: bool = typer.Option(False, "--force", help=FORCE_HELP),
            as_json: bool = typer.Option(False, "--json", help="Print the result as JSON.")):
    """Every headline number of the paper for several presets side by side with the paper's values.

    Default: 4 presets x 2 seeds x 5000 samples per mode (workspace), stiffness at 0/25/50 kPa x 6
    tensions, convergence n = 1, 6 vs 16, drift, holding, IK time and the controller studies: a few
    minutes on 2 cores.  Writes compare.json (after every preset) and compare.png/.svg."""
    from validation.paper import comparison, tables
    names = [x for x in presets.replace(" ", "").split(",") if x]
    if not names:
        raise typer.BadParameter(f"expected at least one preset, got {presets!r}", param_hint="'--presets'")
    seed_list = clitools.parse_numbers(seeds, "--seeds", low=0, high=clitools.SEED_MAX, integer=True)
    con = _console(as_json)
    with _scheduler_errors(None):
        res = comparison.compare(names, samples=samples, seeds=seed_list, workers=workers,
                                 control=comparison.CONTROL if control else (), out=out, force=force,
                                 progress=progress and not as_json,
                                 log=(lambda s: con.print(f"[dim]{s}[/dim]")) if progress else (lambda s: None))
    if as_json:
        _echo_json(res)
    else:
        tables.print_comparison(res, con)
    con.print(f"wrote {out}/compare.json, compare.png, compare.svg")


def main() -> None:  # pragma: no cover - standalone entry (the product mounts ``app`` as ``bellows paper``)
    try:
        app()
    except BellowsError as exc:
        typer.secho(f"error: {exc}", fg=typer.colors.RED, err=True)
        sys.exit(2)


if __name__ == "__main__":  # pragma: no cover
    main()
