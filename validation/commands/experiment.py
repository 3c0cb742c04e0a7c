"""``bellows experiment``: drive a rig (simulated or real) through a D-optimal identification experiment and
record its static states in a run log, for ``bellows identify --measurements LOG --base ACTUATOR``.

The design is :mod:`validation.identification.experiment`, the run :mod:`validation.identification.experiment_run`.
The rig is built as ``bellows control`` builds it (``--rig sim|FILE``, ``--actuator``, ``--plant``, ``--mismatch``,
``--seed``).  Every option is checked, and the log too (not overwritten without ``--force``; ``--resume`` continues
it with the same options), before the rig moves; errors are one ``error:`` line with exit status 2.
"""

from __future__ import annotations

import pathlib
import sys
import time
from types import SimpleNamespace
from typing import Optional

import typer

from ancf.clitools import SEED_MAX, number_range, parse_numbers
from ancf.errors import InputError
from ancf.textfmt import one_of
from validation.identification.forms import FORMS

_SETTLE = number_range(0, 600, unit="s")
_TOL = number_range(0, 10, low_open=True, unit="N")


def _hang_prompt(mass: float, force) -> None:
    """A person hangs ``mass`` [kg] at the tip (or removes every mass) and presses Enter (end of input: abort)."""
    what = f"hang {mass * 1e3:g} g at the tip" if mass > 0 else "remove every mass from the tip"
    try:
        input(f"{what}, then press Enter: ")
    except EOFError:
        raise KeyboardInterrupt from None


def _progress(rec: dict) -> None:
    T = ", ".join(f"{t:.3f}" for t in rec["measured_N"])
    typer.echo(f"state {rec['done']}/{rec['total']} {rec['label']}: measured T ({T}) N, "
               f"p {rec['pressure_Pa'] / 1e3:.2f} kPa after {rec['corrections']} correction(s)"
               + ("" if rec["reached"] else " — NOT within the tolerance (recorded as measured)"), err=True)
    sys.stderr.flush()


def experiment(
    log: pathlib.Path = typer.Option(..., "--log", help="run log to write (.h5): the states for `bellows identify "
                                     "--measurements`"),
    rig: str = typer.Option("sim", "--rig", help="'sim' (simulated rig) or a rig TOML file"),
    actuator: Optional[str] = typer.Option(None, "--actuator", help="the model that designs the states and sends the rig to them: "
                                           "a preset name or an actuator .toml (default: the rig file's; sim: paper)"),
    plant: Optional[str] = typer.Option(None, "--plant", help="simulated rig: the plant's actuator (its truth)"),
    mismatch: bool = typer.Option(False, "--mismatch", help="simulated rig: imperfect plant (other parameters, "
                                                           "friction, tracker noise, motor limits)"),
    seed: Optional[int] = typer.Option(None, "--seed", min=0, max=SEED_MAX, help="simulated rig: random seed"),
    states: int = typer.Option(40, "--states", min=3, max=1000, help="states to measure (at least the form's "
                                                                     "parameters)"),
    form: Optional[str] = typer.Option(None, "--form", help=f"design for this model form {one_of(FORMS)} "
                                       "(default: pressure_ei_shear with masses, else pressure_ei_ea)"),
    loads_g: Optional[str] = typer.Option(None, "--loads-g", help="masses hung at the tip [g], comma separated, "
                                          "each in [0, 1000] (default: none on hardware; 0,20,50 on --rig sim)"),
    samples: int = typer.Option(5, "--samples", min=2, max=10000, help="readings averaged per state"),
    settle_s: float = typer.Option(0.5, "--settle-s", callback=_SETTLE, help=f"wait before the readings, "
                                   f"{_SETTLE.text}"),
    tension_tolerance_n: float = typer.Option(0.02, "--tension-tolerance-n", callback=_TOL,
                                              help=f"a state is reached within this of its tensions, {_TOL.text}"),
    corrections: int = typer.Option(5, "--corrections", min=0, max=50, help="tension corrections per state at most"),
    resume: bool = typer.Option(False, "--resume", help="continue the log with the states not yet done (same "
                                                        "options)"),
    force: bool = typer.Option(False, "--force", help="overwrite an existing log (start again)"),
):
    """Measure the static states that identify the actuator: a D-optimal choice over its operating range
    (tensions up to its limit, pressures 0 … p_max, known tip masses), each reached on the measured tensions and
    averaged over --samples readings, recorded with their standard errors in the log's /static_states.  On
    hardware a change of mass waits for the operator (Enter).  Ctrl-C stops with the rig safe and the states done
    kept (--resume continues); then `bellows identify --measurements LOG --base ACTUATOR`."""
    a = SimpleNamespace(**locals())
    cfg, models, masses, options = _checked(a)
    from validation.identification.experiment import design_experiment
    params = cfg.actuator_params()
    info = _run_info(a, models, params, masses)
    if a.resume:                    # before the design (10–40 s) and before the rig: the options must match the log's
        from dataclasses import asdict
        from validation.identification.experiment_run import check_resume
        check_resume(a.log, {**asdict(options), **info}, OPTION_NAMES)
    t0 = time.monotonic()
    lim = cfg.safety_limits()
    plan = design_experiment(params, states, form=form, masses_kg=masses, travel=(lim.length_min, lim.length_max))
    typer.echo(f"design: {len(plan.states)} states for form {plan.form} from {plan.n_candidates} candidates "
               f"(log det information {plan.logdet:.2f}), {time.monotonic() - t0:.1f} s", err=True)
    _run(a, cfg, plan, options, info)


#: the command-line option of each entry of the options stored in an experiment log (``--resume`` names them)
OPTION_NAMES = {"samples": "--samples", "settle_s": "--settle-s", "tension_tolerance": "--tension-tolerance-n",
                "max_corrections": "--corrections", "rig": "--rig", "form": "--form", "states": "--states",
                "loads_g": "--loads-g", "seed": "--seed", "mismatch": "--mismatch", "actuator": "--actuator",
                "plant": "--plant"}


def _run_info(a: SimpleNamespace, models: dict, params, masses: list) -> dict:
    """What the log stores of the command's options and must match on ``--resume`` (the form and the masses as the
    design resolves them: :func:`validation.identification.experiment.default_form`, sorted masses [g])."""
    from validation.identification.experiment import _check_masses, default_form
    resolved = _check_masses(masses, params)
    return {"rig": a.rig, "form": a.form or default_form(resolved), "states": a.states,
            "loads_g": [m * 1e3 for m in resolved], "seed": a.seed, "mismatch": a.mismatch,
            **{k: models[k] for k in ("actuator", "plant")}}


def _checked(a: SimpleNamespace):
    """Every option and the log checked before any work: (rig config with the models, model records, masses [kg],
    ExperimentOptions)."""
    from ancf.outputs import prepare_output_file
    from hardware.config import RigConfig
    from hardware.runlog import SUFFIXES
    from validation.commands.control import _model_records, _with_models
    from validation.identification.experiment_run import ExperimentOptions
    if a.form is not None and a.form not in FORMS:
        raise InputError(f"--form must be one of {', '.join(FORMS)}, got {a.form!r}")
    if a.resume and a.force:
        raise InputError("give --resume (continue the log) or --force (start it again), not both")
    if a.resume:
        if not a.log.is_file():
            raise InputError(f"--resume: no experiment log {a.log}")
    else:
        prepare_output_file(a.log, force=a.force, suffixes=SUFFIXES)
    cfg = RigConfig(name="simulated rig") if a.rig == "sim" else RigConfig.from_toml(a.rig)
    sim = cfg.backend == "sim"
    if not sim and (a.mismatch or a.seed is not None):
        raise InputError("--mismatch, --seed: only for a simulated rig (the rig file says backend = 'hardware')")
    text = a.loads_g if a.loads_g is not None else ("0,20,50" if sim else "0")
    masses = [g * 1e-3 for g in parse_numbers(text, "--loads-g", low=0, high=1000)]
    ns = SimpleNamespace(actuator=a.actuator, plant=a.plant, mismatch=a.mismatch)
    cfg = _with_models(ns, cfg)
    options = ExperimentOptions(samples=a.samples, settle_s=a.settle_s,
                                tension_tolerance=a.tension_tolerance_n, max_corrections=a.corrections)
    return cfg, _model_records(ns, cfg), masses, options


def _run(a: SimpleNamespace, cfg, plan, options, info: dict) -> None:
    from hardware.build import build_rig
    from hardware.errors import RunAborted
    from validation.commands.control import _sim_overrides
    from validation.identification.experiment_run import run_experiment
    sim = cfg.backend == "sim"
    ns = SimpleNamespace(load_mass_g=None, load_profile="none", seed=a.seed, mismatch=a.mismatch, dynamics=False,
                         plant_damping_ratio=None)
    the_rig = build_rig(cfg, **(_sim_overrides(ns, cfg) if sim else {}))
    try:
        with the_rig:
            res = run_experiment(plan, the_rig, cfg.actuator_params(), a.log, options=options, force=a.force,
                                 resume=a.resume, change_load=None if sim else _hang_prompt, progress=_progress,
                                 run_info=info)
    except RunAborted as exc:
        raise RunAborted(str(exc)) from None
    typer.echo(f"{res.status}: {res.done} of {res.total} states in {res.log_path} ({res.recorded} recorded now, "
               f"{res.wall_s:.1f} s); next: bellows identify --measurements {res.log_path} --base "
               f"{a.actuator or ('paper' if sim else '<the rig file actuator>')}")


def register(app: typer.Typer) -> None:
    app.command("experiment", short_help="Measure the static states that identify the actuator, on a rig.")(experiment)
