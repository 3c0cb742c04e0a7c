"""``bellows control``: run LACC / VF-CC on a rig (simulated or real), live, with a run log.

It runs a :mod:`controller` on a :mod:`hardware` rig, so it lives here, above both (``hardware`` never
imports ``controller``).  Units are in the option names; an option that is given is used or rejected, never
replaced; the run log is checked before any motion and never overwritten without ``--force``; handled
errors are one ``error:`` line with exit status 2 (:func:`validation.commands.main.main`).  Ctrl-C is a run's
normal end (the way to end one without ``--duration-s``): the rig is left safe (drives holding, pressure held
or vented as configured), the summary printed, the log closed complete, and the exit status is the verdict of
the run's load periods; SIGTERM, a fault or a limit also leave the rig safe and close the log, with one
``error:`` line that says where the log is.

:func:`control` is the typer command; its steps: check the request (:func:`_checked_request`), build the rig
(:func:`_built_rig`), build the controller (:func:`_built_controller`), run (:func:`_run`), print the result
(:func:`_print_result`).
"""

from __future__ import annotations

import math
import pathlib
import sys
import time
from types import SimpleNamespace
from typing import Optional

import numpy as np
import typer

from ancf.clitools import SEED_MAX
from ancf.compliance import METHODS as COMPLIANCE_METHODS
from ancf.errors import InputError
from ancf.textfmt import one_of, vector
from hardware.loads import PROFILES as LOAD_PROFILES

#: ``--controller`` choices (the classes live in :mod:`controller`, imported when the command runs)
CONTROLLERS = ("lacc", "vfcc", "dynamic-lacc")
#: what each LACC ``--compliance`` method is (keys: :data:`ancf.compliance.METHODS`)
_COMPLIANCE_NOTES = {"exact": "default", "ik": "eq. 15/16", "paper": "eq. 13"}

def _status_printer(stream=None, every_s: float = 0.5):
    """The live status: on a terminal one line redrawn after every sample; otherwise (a pipe, a file, CI)
    a plain line per ``every_s`` seconds of rig time, flushed at once so that progress shows during the run."""
    stream = stream or sys.stderr
    tty = stream.isatty()
    last = [-math.inf]

    def status(s: dict) -> None:
        if not tty and s["t"] - last[0] < every_s:
            return
        last[0] = s["t"]
        F = s["estimate_N"]
        line = (f"t {s['t']:8.2f} s  iter {s['iteration']:4d}  tip error {s['error_m'] * 1e3:8.4f} mm  "
                f"{s['mode']:8s}  F̂ ({F[0]:+.3f}, {F[1]:+.3f}, {F[2]:+.3f}) N  p {s['pressure_Pa'] / 1e3:6.2f} kPa"
                f"{'  SATURATED' if s.get('saturated') else '           '}")
        stream.write(("\r" + line) if tty else (line + "\n"))
        stream.flush()
    return status


def compile_loop_kernels(params=None, controller: str = "lacc", compliance: Optional[str] = None,
                         dynamics: bool = False) -> bool:
    """Compile (first run of an install) or load (later runs) every numba kernel the control loop calls, before
    the rig moves: the controller's IK, locked FK and compliance, the bounded IK of a saturated step and the
    simulated plant (with ``dynamics``: its time integration) — by a short run of the same controller on a
    simulated rig of the same actuator (``params``, :class:`ancf.ActuatorParams`; default the ``paper`` preset)
    with one element (types, not sizes, make a kernel's signature), and one target out of reach.
    Otherwise the first saturation of a live run would stop the loop for the compiler (tens of seconds on a
    fresh install), and a Ctrl-C could wait for it (tests/test_hardware/test_control_warm_up.py checks that a
    run after it compiles nothing).  Returns False when a solve of the warm-up failed for this actuator (then what
    it did not reach compiles when first used), True otherwise.  A Ctrl-C (or SIGTERM) during the warm-up raises
    KeyboardInterrupt: the command is aborted before its run starts."""
    from ancf import Model, presets
    from ancf.errors import BellowsError, InfeasibleTargetError
    from controller import LACC, VFCC, RunOptions, run_on_rig
    from hardware import SimulatedRig
    from hardware.errors import RunAborted

    from ancf import ActuatorParams
    if controller not in CONTROLLERS:
        raise InputError(f"controller must be one of {', '.join(CONTROLLERS)}, got {controller!r}")
    if compliance is not None and (controller != "lacc" or compliance not in COMPLIANCE_METHODS):
        raise InputError(f"compliance is LACC's, one of {', '.join(COMPLIANCE_METHODS)}; got {compliance!r} for "
                         f"{controller}")
    if params is not None and not isinstance(params, ActuatorParams):
        raise InputError(f"params must be ancf.ActuatorParams or None, got {type(params).__name__}")
    params = (presets.paper() if params is None else params).replace(n_elements=1)
    model = Model(params)
    # loads well inside this actuator's limits: a quarter of its pressure range, a bend by its first tendon
    p, load = 0.25 * params.pressure_max, (0.0, 0.0, -0.05)
    lo, span = params.tension_min, params.tension_max - params.tension_min
    T = np.full(params.n_tendons, lo + 0.1 * span)
    T[0] = lo + 0.3 * span
    # the dynamic LACC solves with the same kernels as LACC (IK, locked FK, compliance) plus the modes
    ctrl = VFCC(model, p) if controller == "vfcc" else LACC(model, p, compliance=compliance or "exact")
    try:
        target = model.fk(T, p, load).tip
        run_on_rig(ctrl, SimulatedRig(params, load=load, seed=0, dynamics=dynamics), target,
                   RunOptions(max_iterations=2))
        try:                                               # the bounded IK: a tip 10 cm off to the side
            model.ik(target + (0.0, 0.1, 0.0), p, load)
        except InfeasibleTargetError:
            pass
    except RunAborted:     # Ctrl-C (or SIGTERM) before the real run: abort the command, do not start the run
        raise KeyboardInterrupt from None
    except BellowsError:   # its only product is the compiled kernels: the run itself says what is wrong
        return False
    return True


def _end_status_line() -> None:
    """End the live status line (a terminal redraws one line with \\r; elsewhere every line is complete)."""
    if sys.stderr.isatty():
        sys.stderr.write("\n")
    sys.stderr.flush()


def _ask_recovery(exc) -> bool:
    """A person decides whether a stopped rig goes on after a drive fault (end of input: no)."""
    _end_status_line()
    typer.echo(f"drive fault: {exc}\nthe drives are stopped (quick stop) and the pressure "
               "held or vented as the rig file says.", err=True)
    try:
        yes = typer.confirm("Reset the faulted drives, enable them where they stand and go on?", default=False,
                            err=True)
    except (typer.Abort, EOFError):
        yes = False
    if not sys.stdin.isatty():            # the answer was not typed (no echoed newline): end the prompt's line
        typer.echo("", err=True)
    return yes


def control(
    rig: str = typer.Option("sim", "--rig", help="'sim' (simulated rig) or a rig TOML file"),
    actuator: Optional[str] = typer.Option(None, "--actuator", help="the controller's model: an actuator preset "
                                           "name or an actuator .toml file (e.g. from `bellows identify`); "
                                           "default: the rig file's actuator (--rig sim: the paper preset)"),
    plant: Optional[str] = typer.Option(None, "--plant", help="simulated rig: the plant's actuator (its truth), "
                                        "a preset name or an actuator .toml file; default: the controller's "
                                        "model (--mismatch perturbs it)"),
    target_mm: str = typer.Option(..., "--target-mm", help="desired tip position X,Y,Z [mm]"),
    pressure_kpa: float = typer.Option(..., "--pressure-kpa", help="chamber pressure [kPa], held constant"),
    controller: str = typer.Option("lacc", "--controller", help=f"controller {one_of(CONTROLLERS)}"),
    compliance: Optional[str] = typer.Option(
        None, "--compliance", help=f"LACC compliance {one_of(COMPLIANCE_METHODS)}: "
        + ", ".join(f"{m} ({_COMPLIANCE_NOTES[m]})" if m in _COMPLIANCE_NOTES else m for m in COMPLIANCE_METHODS)),
    tolerance_mm: float = typer.Option(0.2, "--tolerance-mm", help="stop correcting below this tip error [mm]"),
    load_profile: str = typer.Option("none", "--load-profile",
                                     help=f"simulated rig only: load profile {one_of(LOAD_PROFILES)}"),
    load_mass_g: Optional[float] = typer.Option(None, "--load-mass-g",
                                                help="simulated rig: mass of the step/continuous/cyclic load [g]"),
    seed: Optional[int] = typer.Option(None, "--seed", help="simulated rig: random seed (noise, stochastic load)"),
    mismatch: bool = typer.Option(False, "--mismatch", help="simulated rig: imperfect plant (other parameters, "
                                                           "friction, tracker noise, motor limits)"),
    duration_s: Optional[float] = typer.Option(None, "--duration-s",
                                               help="hold the target this long [s]; default: until Ctrl-C"),
    max_iterations: Optional[int] = typer.Option(None, "--max-iterations",
                                                 help="stop after this many corrections or at convergence "
                                                      "(instead of holding)"),
    dynamics: bool = typer.Option(False, "--dynamics", help="simulated rig: integrate the actuator in time "
                                  "(inertia, ringing) instead of jumping to its equilibrium (docs/dynamics.md)"),
    plant_damping_ratio: Optional[float] = typer.Option(None, "--plant-damping-ratio",
                                                        help="simulated rig with --dynamics: damping ratio of its "
                                                             "first mode (default 0.05)"),
    shaping_damping_ratio: Optional[float] = typer.Option(
        None, "--shaping-damping-ratio", help="shape every move (ZV input shaping) at the model's first locked "
        "mode with this damping ratio (identified with `bellows identify-damping`); default: no shaping"),
    realtime: bool = typer.Option(True, "--realtime/--fast", help="simulated rig: pace the simulation to the "
                                                                  "wall clock (--fast: as fast as it computes)"),
    log: Optional[pathlib.Path] = typer.Option(None, "--log", help="run log to write (.h5)"),
    force: bool = typer.Option(False, "--force", help="overwrite an existing run log"),
    json_out: bool = typer.Option(False, "--json", help="print the result as JSON"),
    on_drive_fault: str = typer.Option("ask", "--on-drive-fault",
                                       help="after a drive fault has stopped the rig: 'ask' (a person decides "
                                            "whether to reset the drives where they stand and go on; no answer "
                                            "= stop) or 'stop'"),
):
    """Run a tip-position controller live on a rig (simulated or real).

    A status line while it runs, a run log, and at the end a summary of the whole run: the settled tip error
    per load period (a load period is the time between two load changes of the simulated rig's load profile,
    or the whole run when the load is constant or unknown, as on hardware; settled = its second half; a
    period's settled error is the median tip error there) with median and max over the periods, the
    saturation time, faults and corrections (also in --json and in the run log's /summary).  The target,
    pressure and limits are checked before the run log is created.

    Ctrl-C ends the run normally (the way to end a run without --duration-s): the rig is made safe (drives
    holding, pressure held or vented as the rig file says), the summary is printed and the log closed as at the
    end of a --duration-s; a second Ctrl-C, or one before the run started, aborts.

    Exit status: a --duration-s (hold) run, or one ended by Ctrl-C, exits 0 when every judged load period
    settled below the tolerance and 1 when one did not (a last period cut short by the end of the run is not
    judged, nor one whose load kept the target out of reach — saturated throughout its settled half); a
    --max-iterations run exits 0 at convergence and 1 without (also when Ctrl-C ended it first); 2 on an error
    (a fault, a limit, SIGTERM: the rig is made safe first)."""
    args = SimpleNamespace(**locals())                    # the options, as given (checked in the steps below)
    target, cfg, models = _checked_request(args)
    the_rig = _built_rig(args, cfg)
    ctrl, shaper = _built_controller(args, cfg, target)
    t0 = time.monotonic()
    res = _run(args, ctrl, the_rig, target, shaper, models)
    exit_status = _print_result(args, ctrl, res, models, wall_s=time.monotonic() - t0)
    if exit_status:
        raise typer.Exit(exit_status)


def _checked_request(a: SimpleNamespace):
    """Parse and check every option before any work or motion (the run log too: refused if it exists unless
    --force).  Returns (target (3,) [m], the rig's :class:`hardware.config.RigConfig` with the --actuator and
    --plant given, the record of the controller's model and the plant (:func:`_model_records`))."""
    from ancf.cli import parse_vector
    from ancf.outputs import prepare_output_file
    from hardware.config import RigConfig
    from hardware.runlog import SUFFIXES

    target = parse_vector(a.target_mm, 3, "--target-mm") * 1e-3
    _check_ranges(a)
    if a.log is not None:
        prepare_output_file(a.log, force=a.force, suffixes=SUFFIXES)        # before any work or motion
    cfg = RigConfig(name="simulated rig") if a.rig == "sim" else RigConfig.from_toml(a.rig)
    _check_sim_only(a, simulated=cfg.backend == "sim")
    cfg = _with_models(a, cfg)
    return target, cfg, _model_records(a, cfg)


def _actuator_spec(text: str, option: str) -> str:
    """An --actuator / --plant value as the rig file's ``actuator`` key takes it: a preset name as given, an
    actuator file as an absolute path (the rig file's keys are relative to the rig file, options to the working
    directory).  The file is read and checked here (ConfigError naming the option)."""
    from ancf import presets
    from ancf.errors import ConfigError
    spec = str(pathlib.Path(text).resolve()) if text.endswith(".toml") else text
    try:
        presets.get(spec)
    except ConfigError as exc:
        raise ConfigError(f"{option}: {exc}") from None
    return spec


def _with_models(a: SimpleNamespace, cfg):
    """The rig config with the controller's model (--actuator) and the simulated plant (--plant) given on the
    command line; contradictions are refused: --plant on a hardware rig (the real actuator is the plant), a
    plant or a rig whose tendon count differs from the model's."""
    import dataclasses
    if a.plant is not None and cfg.backend != "sim":
        raise InputError("--plant: only for a simulated rig (the rig file says backend = 'hardware': the real "
                         "actuator is the plant); give the controller's model with --actuator")
    changes = {}
    if a.actuator is not None:
        changes["actuator"] = _actuator_spec(a.actuator, "--actuator")
    if a.plant is not None:
        changes["simulation"] = {**cfg.simulation, "plant_actuator": _actuator_spec(a.plant, "--plant")}
    cfg = dataclasses.replace(cfg, **changes) if changes else cfg
    model = cfg.actuator_params()
    if cfg.backend == "sim":
        plant = cfg.actuator_params("plant_actuator")
        if plant.n_tendons != model.n_tendons:
            raise InputError(f"the plant {plant.name!r} has {plant.n_tendons} tendons, the controller's model "
                             f"{model.name!r} {model.n_tendons}: a model of another actuator cannot drive it")
    elif len(cfg.drives) != model.n_tendons:
        raise InputError(f"--actuator {a.actuator}: {model.n_tendons} tendons, the rig file has {len(cfg.drives)} "
                         f"[[drives]] (one per tendon)")
    return cfg


def _model_record(spec: str, params, base_dir: str) -> dict:
    """Which actuator: its name, a preset or a file (absolute path, SHA-256 of the file) and the SHA-256 of its
    parameters as TOML (:meth:`ancf.ActuatorParams.to_toml`: equal for equal parameters)."""
    import hashlib
    path = pathlib.Path(base_dir, spec).resolve() if spec.endswith(".toml") else None
    return {"name": params.name, "source": "file" if path else "preset", "path": None if path is None else str(path),
            "file_sha256": None if path is None else hashlib.sha256(path.read_bytes()).hexdigest(),
            "parameters_sha256": hashlib.sha256(params.to_toml().encode()).hexdigest(), "n_tendons": params.n_tendons}


def _model_records(a: SimpleNamespace, cfg) -> dict:
    """{"actuator": the controller's model, "plant": the simulated plant (with ``mismatch``: perturbed by
    --mismatch) or None on a hardware rig} (:func:`_model_record`); in the run log and the result."""
    out = {"actuator": _model_record(cfg.actuator, cfg.actuator_params(), cfg.base_dir), "plant": None}
    if cfg.backend == "sim":
        spec = cfg.simulation.get("plant_actuator", cfg.actuator)
        out["plant"] = {**_model_record(spec, cfg.actuator_params("plant_actuator"), cfg.base_dir),
                        "mismatch": bool(a.mismatch)}
    return out


def _models_line(models: dict) -> str:
    """One line: which model the controller uses and which actuator the plant is."""
    def one(r: dict) -> str:
        return (f"{r['name']!r} from {r['path']} (sha256 {r['file_sha256'][:12]}…)" if r["source"] == "file"
                else f"preset {r['name']!r}")
    pl = models["plant"]
    if pl is None:
        plant = "the real actuator (hardware rig)"
    else:
        same = pl["parameters_sha256"] == models["actuator"]["parameters_sha256"]
        plant = ("the model's own parameters" if same else "ANCF rod, actuator " + one(pl)) \
            + (", perturbed by --mismatch" if pl["mismatch"] else "")
    return f"controller's model: ANCF rod, actuator {one(models['actuator'])}; plant: {plant}"


def _check_ranges(a: SimpleNamespace) -> None:
    """Each option on its own and the pairs that exclude each other (InputError naming the option)."""
    if not (math.isfinite(a.pressure_kpa) and a.pressure_kpa >= 0):
        raise InputError(f"--pressure-kpa must be a finite pressure >= 0 kPa, got {a.pressure_kpa}")
    if not (math.isfinite(a.tolerance_mm) and a.tolerance_mm >= 0):
        raise InputError(f"--tolerance-mm must be >= 0 mm, got {a.tolerance_mm}")
    if a.controller not in CONTROLLERS:
        raise InputError(f"--controller must be one of {', '.join(CONTROLLERS)}, got {a.controller!r}")
    if a.compliance is not None and a.compliance not in COMPLIANCE_METHODS:
        raise InputError(f"--compliance must be one of {', '.join(COMPLIANCE_METHODS)}, got {a.compliance!r}")
    if a.on_drive_fault not in ("ask", "stop"):
        raise InputError(f"--on-drive-fault must be 'ask' or 'stop', got {a.on_drive_fault!r}")
    if a.controller != "lacc" and a.compliance is not None:
        raise InputError("--compliance applies to LACC only; VF-CC has no compliance option")
    if a.duration_s is not None and not (math.isfinite(a.duration_s) and a.duration_s > 0):
        raise InputError(f"--duration-s must be a finite time > 0 s, got {a.duration_s}")
    if a.load_mass_g is not None and not (0 <= a.load_mass_g <= 1000):
        raise InputError(f"--load-mass-g must be in [0, 1000] g, got {a.load_mass_g}")
    if a.seed is not None and not (0 <= a.seed <= SEED_MAX):
        raise InputError(f"--seed must be in [0, {SEED_MAX}], got {a.seed}")
    if a.plant_damping_ratio is not None and not (0 <= a.plant_damping_ratio <= 1):
        raise InputError(f"--plant-damping-ratio must be in [0, 1], got {a.plant_damping_ratio}")
    if a.shaping_damping_ratio is not None and not (0 <= a.shaping_damping_ratio < 1):
        raise InputError(f"--shaping-damping-ratio must be in [0, 1), got {a.shaping_damping_ratio:g}")
    if a.max_iterations is not None and a.max_iterations < 0:
        raise InputError(f"--max-iterations must be >= 0, got {a.max_iterations}")
    if a.duration_s is not None and a.max_iterations is not None:
        raise InputError("give --duration-s (hold the target) or --max-iterations (stop at convergence), not both")


def _check_sim_only(a: SimpleNamespace, simulated: bool) -> None:
    """The simulated rig's options: only for one, and only in combinations the simulated plant models."""
    sim_only = {"--load-profile": a.load_profile != "none", "--load-mass-g": a.load_mass_g is not None,
                "--seed": a.seed is not None, "--mismatch": a.mismatch, "--fast": not a.realtime,
                "--dynamics": a.dynamics, "--plant-damping-ratio": a.plant_damping_ratio is not None}
    if a.plant_damping_ratio is not None and not a.dynamics:
        raise InputError("--plant-damping-ratio is the dynamic plant's: it needs --dynamics")
    if a.mismatch and a.dynamics:
        raise InputError("--mismatch includes tendon friction, which the dynamic plant does not model: use one "
                         "of --mismatch, --dynamics")
    if not simulated and any(sim_only.values()):
        raise InputError(f"{', '.join(k for k, v in sim_only.items() if v)}: only for a simulated rig "
                         f"(the rig file says backend = 'hardware')")
    if simulated and a.load_mass_g is not None and a.load_profile in ("none", "stochastic"):
        raise InputError(f"--load-mass-g does not apply to --load-profile {a.load_profile} "
                         f"(stochastic draws 20–60 g)")


def _sim_overrides(a: SimpleNamespace, cfg) -> dict:
    """What the simulated rig's options change in the rig file's simulation: load profile, seed, mismatched
    plant, dynamics (keyword arguments of :func:`hardware.build.build_rig`)."""
    from hardware.loads import load_profile as make_profile
    kw = {} if a.load_mass_g is None else {"mass": a.load_mass_g * 1e-3}
    seed = cfg.simulation.get("seed", 0) if a.seed is None else a.seed
    overrides = {"load": make_profile(a.load_profile, seed=seed, **kw)}
    if a.seed is not None:
        overrides["seed"] = a.seed
    if a.mismatch:
        from hardware.simulated import PlantOptions
        mm = PlantOptions.mismatched(base=cfg.actuator_params("plant_actuator"))
        overrides.update({k: getattr(mm, k) for k in ("params", "noise_std", "length_resolution", "length_rate",
                                                      "tendon_friction", "tendon_stiffness")})
    if a.dynamics:
        overrides["dynamics"] = True
        if a.plant_damping_ratio is not None:
            overrides["damping"] = a.plant_damping_ratio
    return overrides


def _built_rig(a: SimpleNamespace, cfg):
    """Compile (or load) the loop's kernels, then build the rig — a real one is powered only now, after every
    check and before the run log exists."""
    from hardware.build import build_rig
    simulated = cfg.backend == "sim"
    overrides = _sim_overrides(a, cfg) if simulated else {}
    typer.echo("loading the model's compiled kernels (compiling them on the first run of an install) …", err=True)
    compile_loop_kernels(cfg.actuator_params(), a.controller, a.compliance, dynamics=simulated and a.dynamics)
    the_rig = build_rig(cfg, **overrides)
    if simulated and a.realtime:
        the_rig.pace = 1.0
    return the_rig


def _built_controller(a: SimpleNamespace, cfg, target: np.ndarray):
    """The controller (LACC or VF-CC at the pressure and tolerance asked) and the ZV shaper of every move
    (None without --shaping-damping-ratio).  Returns (controller, shaper)."""
    from ancf import Model
    from controller import LACC, VFCC, DynamicLACC
    model = Model(cfg.actuator_params())
    p, tol = a.pressure_kpa * 1e3, a.tolerance_mm * 1e-3
    if a.controller == "dynamic-lacc":
        # stepped every millisecond (the run waits one period after each command, controller/run.py); the
        # model's damping: the plant's ratio on the simulated rig, else the shaping ratio, else 0.05
        zeta = (a.plant_damping_ratio if getattr(a, "dynamics", False) and a.plant_damping_ratio is not None
                else (a.shaping_damping_ratio or 0.05))
        ctrl = DynamicLACC(model, p, tolerance=tol, latency=0.0, damping_ratio=zeta)
    elif a.controller == "lacc":
        ctrl = LACC(model, p, compliance=a.compliance or "exact", tolerance=tol)
    else:
        ctrl = VFCC(model, p, tolerance=tol)
    shaper = None
    if a.shaping_damping_ratio is not None:
        from controller import zv_shaper
        start = model.ik(target, p)                          # the mode of the start state, tendons locked
        locked = model.fk_locked(start.tendon_lengths, p, q0=start.q, tensions0=start.tensions)
        f1 = float(model.modes(locked, 1).frequencies_hz[0])
        shaper = zv_shaper(f1, a.shaping_damping_ratio)
    return ctrl, shaper


def _run(a: SimpleNamespace, ctrl, the_rig, target: np.ndarray, shaper, models: dict):
    """The run itself (:func:`controller.run_on_rig`): Ctrl-C is its normal end; SIGTERM or a fault aborts it
    (one ``error:`` line, the rig made safe, the log closed; the log's ``run`` attribute records ``models``,
    :func:`_model_records`).  Returns the :class:`controller.RunResult`."""
    from controller import RunOptions, run_on_rig
    from hardware.errors import RunAborted
    simulated = bool(getattr(the_rig, "simulated", False))
    duration = a.duration_s if a.duration_s is not None else (None if a.max_iterations is not None else math.inf)
    where = f"; run log: {a.log}" if a.log else ""
    typer.echo(f"{ctrl.name} on {the_rig.name} ({'simulated' if simulated else 'hardware'}): target "
               f"{vector(target, 'mm', 1e3, 3)} at {a.pressure_kpa:g} kPa"
               + (f", load profile {a.load_profile}" if simulated else "")
               + ("; Ctrl-C ends the run" if duration == math.inf else "") + where, err=True)
    typer.echo(_models_line(models), err=True)
    options = RunOptions(log=a.log, force=a.force, duration=duration, max_iterations=a.max_iterations,
                         status=_status_printer(), on_ctrl_c="end",
                         # the simulated experiment knows the load it applies: its static states record it
                         applied_load=the_rig.load if simulated else None,
                         run_info={"command": "bellows " + " ".join(sys.argv[1:]), "load_profile": a.load_profile,
                                   **models},
                         shaper=shaper, recover=_ask_recovery if a.on_drive_fault == "ask" else None)
    try:
        res = run_on_rig(ctrl, the_rig, target, options)
    except RunAborted as exc:
        _end_status_line()
        raise RunAborted(f"{exc}") from None
    _end_status_line()
    return res


def _exit_status(res) -> int:
    """0 when the run met its goal (converged; held with every judged load period within tolerance), else 1."""
    sm = res.summary
    missed = res.status == "held" and sm is not None and not sm.met
    return 1 if (res.status == "not converged" or missed) else 0


def _headline(res, tolerance: float) -> str:
    """The last line: how the run ended — held (the verdict of its load periods) or converged / not — with the
    corrections, rig time, the reason and where the log is.  ``tolerance`` [m]."""
    sm = res.summary
    tol = f"{tolerance * 1e3:.3f} mm"
    if res.status == "held" and sm is not None:
        n_oor = len(sm.out_of_reach)
        oor = (f"{n_oor} load period(s) out of reach (saturated: the nearest reachable state held)"
               if n_oor else "")
        if sm.met and not sm.judged:
            head = f"held: {oor}; none judged"
        else:
            head = (f"held: all {len(sm.judged)} judged load periods settled below {tol}" if sm.met else
                    f"held, but {len(sm.judged) - sm.periods_within_tolerance} of {len(sm.judged)} judged load "
                    f"periods did not settle below {tol}" if sm.judged else
                    "held, but no load period could be judged (run too short?)")
            head += (f" (settled tip error median {sm.settled_error_median * 1e3:.4f} mm, max "
                     f"{sm.settled_error_max * 1e3:.4f} mm)" if sm.judged else "") + (f"; {oor}" if oor else "")
        head += f"; last sample {res.final_error * 1e3:.4f} mm"
    else:
        head = f"{res.status}: tip error {res.final_error * 1e3:.4f} mm"
    return (head + f", {res.iterations} corrections, {res.duration:.2f} s rig time"
            + (f"; {res.reason}" if res.reason else "")
            + (f"; run log {res.log_path}" if res.log_path else ""))


def _print_result(a: SimpleNamespace, ctrl, res, models: dict, wall_s: float) -> int:
    """The summary (or the JSON of the result with ``wall_s`` [s], ``exit_status`` and the ``actuator`` and
    ``plant`` records of :func:`_model_records`); returns the exit status."""
    import json
    status = _exit_status(res)
    if a.json_out:
        out = res.to_dict()
        out["wall_s"] = wall_s
        out["exit_status"] = status
        out.update(models)
        typer.echo(json.dumps(out))
    else:
        typer.echo(_models_line(models))
        for line in (res.summary.lines() if res.summary is not None else []):
            typer.echo(line)
        typer.echo(_headline(res, ctrl.tolerance))
    return status
