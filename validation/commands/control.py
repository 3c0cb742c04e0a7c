"""``bellows control``: run LACC / VF-CC on a rig (simulated or real), live, with a run log.

It runs a :mod:`controller` on a :mod:`hardware` rig, so it lives here, above both (``hardware`` never
imports ``controller``).  Units are in the option names; an option that is given is used or rejected, never
replaced; the run log is checked before any motion and never overwritten without ``--force``; handled
errors are one ``error:`` line with exit status 2 (:func:`validation.commands.main.main`); Ctrl-C stops the run,
leaves the rig safe (drives holding, pressure held or vented as configured), closes the log and says where
it is.
"""

from __future__ import annotations

import math
import pathlib
import sys
import time
from typing import Optional

import typer

from ancf.clitools import SEED_MAX
from ancf.compliance import METHODS as COMPLIANCE_METHODS
from ancf.errors import InputError
from ancf.textfmt import one_of, vector
from hardware.loads import PROFILES as LOAD_PROFILES

#: ``--controller`` choices (the classes live in :mod:`controller`, imported when the command runs)
CONTROLLERS = ("lacc", "vfcc")
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
    it did not reach compiles when first used), True otherwise."""
    import numpy as np

    from ancf import Model, presets
    from ancf.errors import BellowsError, InfeasibleTargetError
    from controller import LACC, VFCC, run_on_rig
    from hardware import SimulatedRig

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
    ctrl = (LACC(model, p, compliance=compliance or "exact") if controller == "lacc" else VFCC(model, p))
    try:
        target = model.fk(T, p, load).tip
        run_on_rig(ctrl, SimulatedRig(params, load=load, seed=0, dynamics=dynamics), target, max_iterations=2)
        try:                                               # the bounded IK: a tip 10 cm off to the side
            model.ik(target + (0.0, 0.1, 0.0), p, load)
        except InfeasibleTargetError:
            pass
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
    rig: str = typer.Option("sim", "--rig", help="'sim' (simulated rig, paper preset) or a rig TOML file"),
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

    A status line while it runs, a run log, and at the end a summary of the whole run: the settled tip error per load period (a load period is the
    time between two load changes of the simulated rig's load profile, or the whole run when the load is
    constant or unknown, as on hardware; settled = its second half; a period's settled error is the median
    tip error there) with median and max over the periods, the saturation time, faults and corrections
    (also in --json and in the run log's /summary).  The target, pressure and limits are checked before
    the run log is created.

    Exit status: a --duration-s (hold) run exits 0 when every judged load period settled below the
    tolerance and 1 when one did not (a last period cut short by the end of the run is not judged, nor
    one whose load kept the target out of reach — saturated throughout its settled half); a
    --max-iterations run exits 0 at convergence and 1 without; 2 on an error (a fault, a limit, Ctrl-C:
    the rig is made safe first)."""
    import json

    from ancf import Model
    from ancf.cli import parse_vector
    from ancf.outputs import prepare_output_file
    from controller import LACC, VFCC, run_on_rig
    from hardware.build import build_rig
    from hardware.config import RigConfig
    from hardware.errors import RunAborted
    from hardware.loads import load_profile as make_profile
    from hardware.runlog import SUFFIXES

    target = parse_vector(target_mm, 3, "--target-mm") * 1e-3
    if not (math.isfinite(pressure_kpa) and pressure_kpa >= 0):
        raise InputError(f"--pressure-kpa must be a finite pressure >= 0 kPa, got {pressure_kpa}")
    if not (math.isfinite(tolerance_mm) and tolerance_mm >= 0):
        raise InputError(f"--tolerance-mm must be >= 0 mm, got {tolerance_mm}")
    if controller not in CONTROLLERS:
        raise InputError(f"--controller must be one of {', '.join(CONTROLLERS)}, got {controller!r}")
    if compliance is not None and compliance not in COMPLIANCE_METHODS:
        raise InputError(f"--compliance must be one of {', '.join(COMPLIANCE_METHODS)}, got {compliance!r}")
    if on_drive_fault not in ("ask", "stop"):
        raise InputError(f"--on-drive-fault must be 'ask' or 'stop', got {on_drive_fault!r}")
    if controller == "vfcc" and compliance is not None:
        raise InputError("--compliance applies to LACC only; VF-CC has no compliance option")
    if duration_s is not None and not (math.isfinite(duration_s) and duration_s > 0):
        raise InputError(f"--duration-s must be a finite time > 0 s, got {duration_s}")
    if load_mass_g is not None and not (0 <= load_mass_g <= 1000):
        raise InputError(f"--load-mass-g must be in [0, 1000] g, got {load_mass_g}")
    if seed is not None and not (0 <= seed <= SEED_MAX):
        raise InputError(f"--seed must be in [0, {SEED_MAX}], got {seed}")
    if plant_damping_ratio is not None and not (0 <= plant_damping_ratio <= 1):
        raise InputError(f"--plant-damping-ratio must be in [0, 1], got {plant_damping_ratio}")
    if shaping_damping_ratio is not None and not (0 <= shaping_damping_ratio < 1):
        raise InputError(f"--shaping-damping-ratio must be in [0, 1), got {shaping_damping_ratio:g}")
    if max_iterations is not None and max_iterations < 0:
        raise InputError(f"--max-iterations must be >= 0, got {max_iterations}")
    if duration_s is not None and max_iterations is not None:
        raise InputError("give --duration-s (hold the target) or --max-iterations (stop at convergence), not both")
    if log is not None:
        prepare_output_file(log, force=force, suffixes=SUFFIXES)        # before any work or motion
    cfg = RigConfig(name="simulated rig") if rig == "sim" else RigConfig.from_toml(rig)
    simulated = cfg.backend == "sim"
    sim_only = {"--load-profile": load_profile != "none", "--load-mass-g": load_mass_g is not None,
                "--seed": seed is not None, "--mismatch": mismatch, "--fast": not realtime, "--dynamics": dynamics,
                "--plant-damping-ratio": plant_damping_ratio is not None}
    if plant_damping_ratio is not None and not dynamics:
        raise InputError("--plant-damping-ratio is the dynamic plant's: it needs --dynamics")
    if mismatch and dynamics:
        raise InputError("--mismatch includes tendon friction, which the dynamic plant does not model: use one "
                         "of --mismatch, --dynamics")
    if not simulated and any(sim_only.values()):
        raise InputError(f"{', '.join(k for k, v in sim_only.items() if v)}: only for a simulated rig "
                         f"(the rig file says backend = 'hardware')")
    overrides = {}
    if simulated:
        kw = {} if load_mass_g is None else {"mass": load_mass_g * 1e-3}
        if load_mass_g is not None and load_profile in ("none", "stochastic"):
            raise InputError(f"--load-mass-g does not apply to --load-profile {load_profile} "
                             f"(stochastic draws 20–60 g)")
        overrides["load"] = make_profile(load_profile, seed=cfg.simulation.get("seed", 0) if seed is None else seed,
                                         **kw)
        if seed is not None:
            overrides["seed"] = seed
        if mismatch:
            from hardware.simulated import PlantOptions
            mm = PlantOptions.mismatched(base=cfg.actuator_params())
            overrides.update({k: getattr(mm, k) for k in ("params", "noise_std", "length_resolution", "length_rate",
                                                          "tendon_friction", "tendon_stiffness")})
    if simulated and dynamics:
        overrides["dynamics"] = True
        if plant_damping_ratio is not None:
            overrides["damping"] = plant_damping_ratio
    # the loop's kernels, before the rig is built (and a real one powered) and before the run log exists
    typer.echo("loading the model's compiled kernels (compiling them on the first run of an install) …", err=True)
    compile_loop_kernels(cfg.actuator_params(), controller, compliance, dynamics=simulated and dynamics)
    the_rig = build_rig(cfg, **overrides)
    if simulated and realtime:
        the_rig.pace = 1.0
    model = Model(cfg.actuator_params())
    p = pressure_kpa * 1e3
    ctrl = (LACC(model, p, compliance=compliance or "exact", tolerance=tolerance_mm * 1e-3) if controller == "lacc"
            else VFCC(model, p, tolerance=tolerance_mm * 1e-3))
    shaper = None
    if shaping_damping_ratio is not None:
        from controller import zv_shaper
        start = model.ik(target, p)                          # the mode of the start state, tendons locked
        locked = model.fk_locked(start.tendon_lengths, p, q0=start.q, tensions0=start.tensions)
        f1 = float(model.modes(locked, 1).frequencies_hz[0])
        shaper = zv_shaper(f1, shaping_damping_ratio)
    duration = duration_s if duration_s is not None else (None if max_iterations is not None else math.inf)
    where = f"; run log: {log}" if log else ""
    typer.echo(f"{ctrl.name} on {the_rig.name} ({'simulated' if simulated else 'hardware'}): target "
               f"{vector(target, 'mm', 1e3, 3)} at {pressure_kpa:g} kPa"
               + (f", load profile {load_profile}" if simulated else "")
               + ("; Ctrl-C stops" if duration == math.inf else "") + where, err=True)
    t0 = time.monotonic()
    try:
        res = run_on_rig(ctrl, the_rig, target, log=log, force=force, duration=duration,
                         max_iterations=max_iterations, status=_status_printer(),
                         # the simulated experiment knows the load it applies: its static states record it
                         applied_load=the_rig.load if simulated else None,
                         run_info={"command": "bellows " + " ".join(sys.argv[1:]), "load_profile": load_profile},
                         shaper=shaper, recover=_ask_recovery if on_drive_fault == "ask" else None)
    except RunAborted as exc:
        _end_status_line()
        raise RunAborted(f"{exc}") from None
    _end_status_line()
    out = res.to_dict()
    out["wall_s"] = time.monotonic() - t0
    sm = res.summary
    missed = res.status == "held" and sm is not None and not sm.met
    out["exit_status"] = 1 if (res.status == "not converged" or missed) else 0
    if json_out:
        typer.echo(json.dumps(out))
    else:
        for line in (sm.lines() if sm is not None else []):
            typer.echo(line)
        tol = f"{ctrl.tolerance * 1e3:.3f} mm"
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
        typer.echo(head + f", {res.iterations} corrections, {res.duration:.2f} s rig time"
                   + (f"; {res.reason}" if res.reason else "")
                   + (f"; run log {res.log_path}" if res.log_path else ""))
    if out["exit_status"]:
        raise typer.Exit(1)
