r"""Run a controller on a rig — simulated or real — through one code path, with a crash-safe run log.

:func:`run_on_rig` drives any object with the rig interface of :class:`hardware.Rig` (``set_pressure``,
``command(lengths, expected_tensions)``, ``advance``, ``measure``, ``check_health``, ``safe_stop``,
``clock``, ``events``/``listeners``).  One cycle::

    readings ← rig.check_health()        drive faults, sensor timeouts, tension and pressure limits
    p_m      ← rig.measure()             tracker: TrackingLost / SensorTimeout on a bad frame
    report   ← controller.step(p_m)      LACC / VF-CC correction (or "within tolerance")
    log one sample (measured, commanded, estimated; the truth too on a simulated rig)
    rig.command(l_c, expected_tensions)  limits are checked before anything is sent
    rig.advance()                        until the drives reach their targets (+ settle time)

Loop timing: every logged sample carries the controller's ``compute_time`` of this cycle and, for the
previous cycle, ``cycle_time`` (wall clock from its start to this one's: the loop period as run) and
``io_time`` (wall clock in rig calls: health check, measurement, command, advance — bus traffic on hardware,
the plant's simulation on a simulated rig); ``bellows log show`` summarises them.

When the error first drops below the controller's tolerance the equilibrium is recorded as a static state
(measured tensions, pressure, tip) in the log's ``/static_states``.  Without ``duration`` the run ends
at convergence (or after ``max_iterations`` corrections); with ``duration`` [s] it holds the target until
the rig clock has advanced that long (``math.inf``: until Ctrl-C), re-measuring every ``idle_period``.
A run's options are one checked object, :class:`RunOptions`: ``run_on_rig(controller, rig, target,
RunOptions(log="run.h5", duration=30.0))``.

A target the actuator cannot reach under the current load does not end the run: the controller commands the
nearest reachable state and reports the step ``saturated`` (status line, the log's ``saturated`` column,
the summary's ``reach`` saturation time) until the load lets it track again.

The steps of a run (:class:`_Run`): check what can be checked without moving (limits, first IK) → open the
log → open the rig → passes of the loop (sample → hold or correct; a new pass only after a recovered drive
fault) → the end (:func:`_finish`: the summary, the log closed, the rig closed if the run opened it).

Faults: any :class:`~ancf.errors.BellowsError` during the run (hardware fault, limit, infeasible IK) makes
the rig safe (:meth:`hardware.Rig.safe_stop`: drives hold — quick stop after a drive fault — pressure held
or vented), writes the reason to the log, closes it and re-raises the error with ``.log_path`` and the
partial ``.result`` attached.

Ending by Ctrl-C: the loop checks a latch every cycle (:mod:`controller.interrupt`), so a Ctrl-C stops it also
when its first KeyboardInterrupt is lost in a finaliser and when the process inherited SIGINT ignored; one that a
compiled kernel turned into another error (numba: a SystemError whose cause is the KeyboardInterrupt) is still a
Ctrl-C (:func:`_from_interrupt`).  The rig is made safe first (drives hold where they are, pressure held or vented).  By default (``on_ctrl_c="abort"``) the log
is then closed as ``interrupted`` and :class:`hardware.errors.RunAborted` is raised with ``.log_path`` and the
partial ``.result``.  With ``on_ctrl_c="end"`` (``bellows control``, whose open-ended run ends by Ctrl-C) a Ctrl-C
after the run started is its normal end: the result, summary and log are those of a run whose duration ended
then (status ``held``, reason "ended by Ctrl-C"; an iteration run: ``not converged``).  SIGTERM (with its
default action) always aborts like Ctrl-C with ``on_ctrl_c="abort"``.

This module, like :mod:`controller.summary`, imports :mod:`hardware` only inside the functions that need it
(the run log, the rig's errors), so that ``import controller`` does not load the rig layer.
"""

from __future__ import annotations

import pathlib
import time
from dataclasses import dataclass, field
from typing import Callable, Optional, Union

import numpy as np

from ancf.errors import BellowsError, InputError

from .errors import check_finite, number

from .base import Controller
from .interrupt import CtrlCLatch
from .summary import RunSummary, summarise


@dataclass
class RunResult:
    """Outcome of :func:`run_on_rig` (SI).  ``status``: converged | not converged | held (duration runs) |
    fault | interrupted; ``reason``: why (a run that Ctrl-C ended, :attr:`RunOptions.on_ctrl_c` "end": "ended by
    Ctrl-C"); ``errors``: measured ‖p_m − p_d‖ per sample [m]; ``true_errors``: the same from the simulated truth
    (empty on hardware); ``times``: the samples' rig time [s]; ``saturation``: per
    sample, what was at a limit; ``reach_gaps``: per sample, how far the controller's IK target was out of
    reach [m] (0 when it was not saturated); ``summary``: the whole-run :class:`~controller.summary.RunSummary`
    (settled error per load period, saturation time, faults; also written to the run log);
    ``log_path``: the run log or None."""
    controller: str
    target: np.ndarray
    status: str = "running"
    reason: str = ""
    iterations: int = 0
    samples: int = 0
    errors: list = field(default_factory=list)
    true_errors: list = field(default_factory=list)
    static_states: int = 0
    estimate: Optional[np.ndarray] = None
    duration: float = 0.0
    log_path: Optional[pathlib.Path] = None
    times: list = field(default_factory=list)
    saturation: list = field(default_factory=list)
    reach_gaps: list = field(default_factory=list)
    summary: Optional[RunSummary] = None
    recoveries: int = 0

    @property
    def converged(self) -> bool:
        return self.status in ("converged", "held")

    @property
    def final_error(self) -> float:
        return self.errors[-1] if self.errors else float("nan")

    def to_dict(self) -> dict:
        return {"controller": self.controller, "target_m": self.target.tolist(), "status": self.status,
                "reason": self.reason, "iterations": self.iterations, "samples": self.samples,
                "final_error_m": self.final_error, "errors_m": [float(e) for e in self.errors],
                "true_errors_m": [float(e) for e in self.true_errors], "static_states": self.static_states,
                "estimate_N": None if self.estimate is None else self.estimate.tolist(),
                "duration_s": self.duration, "log": None if self.log_path is None else str(self.log_path),
                "summary": None if self.summary is None else self.summary.to_dict(), "recoveries": self.recoveries}


def _describe_controller(ctrl: Controller) -> dict:
    out = {"name": ctrl.name, "class": type(ctrl).__name__}
    for k, v in vars(ctrl).items():
        if isinstance(v, (bool, int, float, str)) and not k.startswith("_"):
            out[k] = v
        elif isinstance(v, np.ndarray) and v.size <= 3 and k not in ("target", "command_target"):
            out[k] = v.tolist()
    return out


#: shortest wait between measurements [s] (10 kHz; shorter ones vanish in the rig clock's round-off)
MIN_IDLE_PERIOD = 1e-4

#: what a Ctrl-C does to a run (:attr:`RunOptions.on_ctrl_c`)
CTRL_C_ACTIONS = ("abort", "end")


def _is_int(x) -> bool:
    return not isinstance(x, bool) and isinstance(x, (int, np.integer))


@dataclass(frozen=True, eq=False)
class RunOptions:
    """How :func:`run_on_rig` runs (SI; checked at construction: a value out of range raises
    :class:`~ancf.errors.InputError` before anything moves).  ``dataclasses.replace`` checks again.

    log : path of the run log (``.h5``; refused if it exists unless ``force``), an open
        :class:`hardware.runlog.RunLog` (a run log may hold several runs: the caller closes it), or None
    force : overwrite an existing run log
    max_iterations : corrections before an iteration run stops, an integer ≥ 0 (None: no limit — needs
        ``duration``)
    duration : rig-clock time to hold the target [s], ≥ 0 (``math.inf``: until Ctrl-C); None: stop at
        convergence
    idle_period : wait between measurements while within tolerance [s]; 0 (iteration runs only) or ≥
        :data:`MIN_IDLE_PERIOD`
    initial_load : the load the first IK assumes, (3,) [N]
    sim_compute_time : on a simulated rig, how long a controller step takes on the rig clock: "measured"
        (its wall-clock compute time), a fixed time [s] ≥ 0, or 0
    average_frames : tracker frames averaged per measurement, an integer ≥ 1 (distinct frames; noise / √n)
    record_static : record the first equilibrium within tolerance of each hold as a static state in the log
    applied_load : the tip load the experiment applies, if it is known (calibrated weights; zero): (3,) [N]
        or a callable of the rig time t [s]; it becomes the static states' ``tip_force`` (None: unknown, NaN).
        The controller never sees it.
    status : called with a dict after every sample (for a status line)
    run_info : extra JSON-friendly entries for the run log's ``run`` attribute
    shaper : (A₁ ∈ (0, 1], delay [s] ≥ 0) of :func:`controller.shaping.zv_shaper`: every correction is sent as
        A₁ of the move, then the whole move ``delay`` later — a plant with inertia is left without ringing at
        the mode the shaper was made for (docs/dynamics.md); None: moves as commanded
    recover : after a drive fault has stopped the rig (drives quick-stopped, pressure held or vented), called
        with the fault: True resets the faulted drives and enables them where they stand
        (:meth:`hardware.Rig.recover`), then the run goes on from a new IK with the current load estimate; False
        ends the run on the fault.  Only for a person's decision (``bellows control`` asks); None (default):
        every drive fault ends the run
    on_ctrl_c : "abort" (default): Ctrl-C makes the rig safe, closes the log as ``interrupted`` and raises
        :class:`hardware.errors.RunAborted`; "end": a Ctrl-C after the run has started is the run's normal
        end — the rig is made safe the same way, and the run ends as its duration would have (status
        ``held``; an iteration run ``not converged``) with its summary and its log closed, reason "ended by
        Ctrl-C".  SIGTERM always aborts.
    """
    log: Union[str, pathlib.Path, None, object] = None
    force: bool = False
    max_iterations: Optional[int] = 20
    duration: Optional[float] = None
    idle_period: float = 0.1
    initial_load: object = (0.0, 0.0, 0.0)
    sim_compute_time: Union[str, float] = "measured"
    average_frames: int = 1
    record_static: bool = True
    applied_load: object = None
    status: Optional[Callable[[dict], None]] = None
    run_info: Optional[dict] = None
    shaper: Optional[tuple] = None
    recover: Optional[Callable[[BellowsError], bool]] = None
    on_ctrl_c: str = "abort"

    def __post_init__(self) -> None:
        for name, value in {**_checked_ends(self), **_checked_timing(self), **_checked_loads(self),
                            **_checked_hooks(self)}.items():
            object.__setattr__(self, name, value)


def _checked_ends(o: RunOptions) -> dict:
    """When the run ends: ``max_iterations``, ``duration`` [s], ``idle_period`` [s], ``on_ctrl_c``."""
    if o.max_iterations is not None and (not _is_int(o.max_iterations) or o.max_iterations < 0):
        raise InputError(f"max_iterations must be an integer >= 0 or None, got {o.max_iterations!r}")
    duration = None if o.duration is None else number("duration [s]", o.duration, allow_inf=True)
    if duration is None and o.max_iterations is None:
        raise InputError("give max_iterations or a duration (a run without either never ends)")
    idle_period = number("idle_period [s]", o.idle_period)
    if idle_period == 0 and duration is not None:
        raise InputError("idle_period must be > 0 s when holding for a duration")
    if 0 < idle_period < MIN_IDLE_PERIOD:
        # a smaller wait is lost in the rig clock's round-off (t + 1e-300 == t): the run would never end
        raise InputError(f"idle_period must be 0 or at least {MIN_IDLE_PERIOD:g} s, got {idle_period:g} s")
    if o.on_ctrl_c not in CTRL_C_ACTIONS:
        raise InputError(f"on_ctrl_c must be one of {', '.join(CTRL_C_ACTIONS)}, got {o.on_ctrl_c!r}")
    return {"duration": duration, "idle_period": idle_period}


def _checked_timing(o: RunOptions) -> dict:
    """``sim_compute_time`` [s], ``average_frames``, ``shaper`` (A₁, delay [s])."""
    sim = o.sim_compute_time
    if not (isinstance(sim, str) and sim == "measured"):
        sim = number("sim_compute_time [s] (or 'measured')", sim)
    if not _is_int(o.average_frames) or o.average_frames < 1:
        raise InputError(f"average_frames must be an integer >= 1, got {o.average_frames!r}")
    shaper = o.shaper
    if shaper is not None:
        if not (isinstance(shaper, tuple) and len(shaper) == 2):
            raise InputError(f"shaper must be (A1, delay [s]) from controller.zv_shaper, got {shaper!r}")
        shaper = (number("shaper A1", shaper[0]), number("shaper delay [s]", shaper[1]))
        if not 0 < shaper[0] <= 1:
            raise InputError(f"shaper A1 must be in (0, 1], got {shaper[0]:g}")
    return {"sim_compute_time": sim, "average_frames": int(o.average_frames), "shaper": shaper}


def _checked_loads(o: RunOptions) -> dict:
    """``initial_load`` (3,) [N], ``applied_load`` (3,) [N] or a callable of t [s]."""
    initial = check_finite("initial_load [N]", o.initial_load, (3,))
    initial.setflags(write=False)
    applied = o.applied_load
    if applied is not None and not callable(applied):
        applied = check_finite("applied_load [N]", applied, (3,))
        applied.setflags(write=False)
    return {"initial_load": initial, "applied_load": applied}


def _checked_hooks(o: RunOptions) -> dict:
    """``log``, ``force``, ``record_static``, ``status``, ``recover``, ``run_info``."""
    for name in ("force", "record_static"):
        if not isinstance(getattr(o, name), (bool, np.bool_)):
            raise InputError(f"{name} must be True or False, got {getattr(o, name)!r}")
    log = o.log
    if not (log is None or isinstance(log, (str, pathlib.Path))
            or all(hasattr(log, a) for a in ("sample", "event", "static_state", "path"))):
        raise InputError(f"log must be a path, an open run log (hardware.runlog.RunLog) or None, "
                         f"got {type(log).__name__}")
    for name in ("status", "recover"):
        if getattr(o, name) is not None and not callable(getattr(o, name)):
            what = "(fault -> bool)" if name == "recover" else "(dict -> None)"
            raise InputError(f"{name} must be a callable {what} or None, got {type(getattr(o, name)).__name__}")
    if o.run_info is not None and not isinstance(o.run_info, dict):
        raise InputError(f"run_info must be a dict or None, got {type(o.run_info).__name__}")
    return {"force": bool(o.force), "record_static": bool(o.record_static)}


def run_on_rig(controller: Controller, rig, target, options: Optional[RunOptions] = None) -> RunResult:
    """Run ``controller`` on ``rig`` towards ``target`` (3,) [m] as ``options`` say (None: ``RunOptions()``,
    an iteration run of at most 20 corrections without a log); see the module docstring.

    Everything that can be checked without moving is checked before the run log exists, so that a run refused up
    front (pressure beyond the limit, unreachable target, IK lengths beyond the travel, IK tensions beyond the
    limit) leaves no log behind to block the next try."""
    if not isinstance(controller, Controller):
        raise InputError(f"run_on_rig needs a Controller, got {type(controller).__name__}")
    pd = check_finite("target", target, (3,))
    options = RunOptions() if options is None else options
    if not isinstance(options, RunOptions):
        raise InputError(f"run_on_rig's options must be a controller.RunOptions, got {type(options).__name__}")
    limits = getattr(rig, "limits", None)
    if limits is not None:
        limits.check_pressure_command(controller.pressure)
    lengths = controller.start(pd, options.initial_load)   # first IK: raises if the target is not reachable
    if limits is not None:
        limits.check_lengths(lengths, None, rig.m)
        limits.check_tensions(controller.state.tensions, what="expected")
    run = _Run(controller, rig, pd, options)
    run.open_log()
    return run.execute(lengths)


class _Run:
    """One run of :func:`run_on_rig`: its state and its steps (open the log, the passes of the loop — sample,
    correct or idle —, recovery after a drive fault, the end: normal, Ctrl-C, fault)."""

    def __init__(self, controller: Controller, rig, pd: np.ndarray, options: RunOptions) -> None:
        self.ctrl, self.rig, self.pd, self.opts = controller, rig, pd, options
        self.result = RunResult(controller.name, pd)
        self.runlog = None
        self.own_log = isinstance(options.log, (str, pathlib.Path))
        self.opened_here = not getattr(rig, "_open", True)
        self.simulated = bool(getattr(rig, "simulated", False))
        self.n_events = len(getattr(rig, "events", ()))
        self.t_start: Optional[float] = None
        self.was_converged = False
        self.k = 0                                   # corrections so far (over every pass)
        self.latch: Optional[CtrlCLatch] = None
        # loop timing (wall clock): the previous cycle's start, the rig-call time of the previous and this cycle
        self.prev_start: Optional[float] = None
        self.prev_io = self.io = float("nan")

    # -------------------------------------------------------------------------------------------- the log
    def open_log(self) -> None:
        """Create the run log (a path) or use the open one; it records the rig's events from now on."""
        o = self.opts
        if self.own_log:
            from hardware.runlog import RunLog
            info = {"target_m": self.pd, "pressure_Pa": self.ctrl.pressure, "max_iterations": o.max_iterations,
                    "duration_s": o.duration, "idle_period_s": o.idle_period, **(o.run_info or {})}
            self.runlog = RunLog(o.log, n_tendons=self.rig.m, force=o.force, rig=self.rig.describe(),
                                 controller=_describe_controller(self.ctrl), run=info,
                                 actuator_toml=self.ctrl.model.params.to_toml())
        elif o.log is not None:
            self.runlog = o.log
        if self.runlog is not None:
            self.result.log_path = self.runlog.path
            self.rig.listeners.append(self.runlog.event)

    # --------------------------------------------------------------------------------------- the whole run
    def execute(self, lengths: np.ndarray) -> RunResult:
        """Open the rig, run the loop under the Ctrl-C latch, end the run (normally, by Ctrl-C, by a fault)."""
        # a Ctrl-C lost in a finaliser still stops the loop (controller.interrupt)
        self.latch = CtrlCLatch().__enter__()
        try:
            if self.opened_here:
                self.rig.open()
            self.t_start = self.rig.clock.now()
            self._passes(lengths)
        except KeyboardInterrupt:
            return self._interrupted()
        except BaseException as exc:
            if self.latch.requested and _from_interrupt(exc):
                return self._interrupted()
            self._fault(exc)
            raise
        finally:
            self.latch.__exit__()
        self._finish()
        return self.result

    def _passes(self, lengths: np.ndarray) -> None:
        """One pass of the loop; another only after a drive fault a person chose to recover from."""
        from hardware.errors import DriveFault
        while True:
            try:
                self._loop(lengths)
                return
            except DriveFault as exc:
                if not _recovered(self.rig, self.ctrl, exc, self.opts.recover, self.result):
                    raise
                estimate = self.result.estimate
                lengths = self.ctrl.start(self.pd, estimate if estimate is not None else self.opts.initial_load)
                self.was_converged = False

    def _loop(self, lengths: np.ndarray) -> None:
        """Send the start state, then sample → hold or correct until the run's end sets ``result.status``."""
        rig, ctrl = self.rig, self.ctrl
        rig.set_pressure(ctrl.pressure)
        rig.command(lengths, expected_tensions=ctrl.state.tensions)
        rig.advance(None)
        self.prev_start, self.prev_io, self.io = None, float("nan"), float("nan")
        while True:
            self.latch.check()
            readings, pm, rep, t = self._sample()
            if rep.command is None:
                if self._hold(readings, pm, t, rep):
                    return
                continue
            self.was_converged = False
            if self.opts.duration is None and self.opts.max_iterations is not None \
                    and self.k >= self.opts.max_iterations:
                self.result.status = "not converged"
                self.result.reason = (f"tip error {rep.error_norm * 1e3:.4f} mm after {self.k} corrections "
                                      f"(tolerance {ctrl.tolerance * 1e3:.4f} mm)")
                return
            self._correct(rep)
            if self._held_long_enough():
                return

    def _held_long_enough(self) -> bool:
        if self.opts.duration is not None and self.rig.clock.now() - self.t_start >= self.opts.duration:
            self.result.status = "held"
            return True
        return False

    # ------------------------------------------------------------------------------------- one cycle's steps
    def _sample(self):
        """Health check, measurement, controller step, one logged sample.  Returns (readings, p_m (3,) [m],
        the step report, the rig time t [s])."""
        rig, o = self.rig, self.opts
        start = time.perf_counter()
        cycle_time = float("nan") if self.prev_start is None else start - self.prev_start
        self.prev_start, self.prev_io, self.io = start, self.io, 0.0
        readings = rig.check_health()
        pm = rig.measure(o.average_frames) if o.average_frames > 1 else rig.measure()
        self.io += time.perf_counter() - start
        t = rig.clock.now()
        truth = rig.true_tip() if self.simulated else None
        rep = self.ctrl.step(pm)
        if self.simulated and rep.command is not None and o.sim_compute_time != 0:
            rig.advance(rep.compute_time if o.sim_compute_time == "measured" else float(o.sim_compute_time))
        row = {"t": t, "iteration": self.k, "tip": pm, "error": rep.error, "error_norm": rep.error_norm,
               "command": rep.command, "position": readings["positions"], "tension": readings["tensions"],
               "pressure": readings["pressure"], "estimate": rep.estimate, "compute_time": rep.compute_time,
               "saturated": float(getattr(rep, "saturated", False)), "io_time": self.prev_io,
               "reach_gap": float(getattr(rep, "reach_gap", 0.0)), "cycle_time": cycle_time}
        if self.simulated:
            row["true_tip"], row["true_load"] = truth, rig.load(t)
            self.result.true_errors.append(float(np.linalg.norm(truth - self.pd)))
        self._record(row, readings, rep, t)
        return readings, pm, rep, t

    def _record(self, row: dict, readings: dict, rep, t: float) -> None:
        """The sample into the log, the result and the status callback."""
        res = self.result
        if self.runlog is not None:
            self.runlog.sample(**row)
        res.samples += 1
        res.errors.append(rep.error_norm)
        res.times.append(float(t))
        res.saturation.append(_saturated(self.rig, self.ctrl, readings, rep))
        res.reach_gaps.append(float(getattr(rep, "reach_gap", 0.0)))
        res.estimate = np.asarray(rep.estimate, float).copy()
        if self.opts.status is not None:
            self.opts.status({"t": t - self.t_start, "iteration": self.k, "error_m": rep.error_norm,
                              "mode": rep.mode, "saturated": bool(getattr(rep, "saturated", False)),
                              "estimate_N": rep.estimate, "pressure_Pa": readings["pressure"],
                              "tensions_N": readings["tensions"]})

    def _hold(self, readings: dict, pm, t: float, rep) -> bool:
        """Within tolerance: on arrival record the equilibrium; end the run (convergence, or the duration held)
        or wait ``idle_period`` for the next measurement.  Returns whether the run ended."""
        o = self.opts
        if not self.was_converged:
            self.rig.event("converged", f"tip error {rep.error_norm * 1e3:.4f} mm < tolerance "
                                        f"{self.ctrl.tolerance * 1e3:.4f} mm after {self.k} corrections")
            if o.record_static and self.runlog is not None and np.all(np.isfinite(readings["tensions"])):
                F_known = (None if o.applied_load is None else
                           o.applied_load(t) if callable(o.applied_load) else o.applied_load)
                self.runlog.static_state(time=t, tensions=np.maximum(readings["tensions"], 0.0),
                                         pressure=readings["pressure"], tip=pm, tip_force=F_known,
                                         label=f"converged after {self.k} corrections")
                self.result.static_states += 1
        self.was_converged = True
        if o.duration is None:
            self.result.status = "converged"
            return True
        if self._held_long_enough():
            return True
        t_io = time.perf_counter()
        self.rig.advance(o.idle_period)
        self.io += time.perf_counter() - t_io
        return False

    def _correct(self, rep) -> None:
        """Send the controller's correction (shaped if asked) and wait until the drives reach it."""
        rig, o = self.rig, self.opts
        t_cmd, t_io = rig.clock.now(), time.perf_counter()
        expected = self.ctrl.state.tensions
        if o.shaper is not None and rig.commanded is not None:
            # ZV input shaping: A₁ of the move now, all of it half a damped period later
            a1, delay = o.shaper
            last = np.asarray(rig.commanded, float)
            rig.command(last + a1 * (np.asarray(rep.command, float) - last), expected_tensions=expected)
            rig.advance(delay)
        rig.command(rep.command, expected_tensions=expected)
        period = getattr(self.ctrl, "period", None)
        if period is not None:
            # a controller stepped once per loop period (DynamicLACC): the next sample one period on
            rig.advance(max(period - (rig.clock.now() - t_cmd), 0.0))
        else:
            rig.advance(None)
        if rig.clock.now() <= t_cmd:
            # nothing to move and no time passed (a simulated rig given the same command again, e.g. while
            # saturated): wait like a held target, or the loop would spin at one instant of rig time
            rig.advance(o.idle_period)
        self.io += time.perf_counter() - t_io
        self.k += 1
        self.result.iterations = self.k

    # ---------------------------------------------------------------------------------------------- the end
    def _interrupted(self) -> RunResult:
        """Ctrl-C or SIGTERM: make the rig safe; end the run normally (``on_ctrl_c="end"``, a Ctrl-C after the
        start) or close the log as interrupted and raise :class:`hardware.errors.RunAborted`."""
        from hardware.errors import RunAborted
        res = self.result
        by = self.latch.signal_name or "Ctrl-C"
        if self.opts.on_ctrl_c == "end" and by == "Ctrl-C" and self.t_start is not None:
            self.rig.safe_stop("run ended by Ctrl-C")
            if res.status == "running":          # (not when the run had just ended by itself)
                res.status = "not converged" if self.opts.duration is None else "held"
                res.reason = "ended by Ctrl-C"
            self._finish()
            return res
        self.rig.safe_stop(f"interrupted ({by})")
        res.status, res.reason = "interrupted", by
        where = f"; log: {res.log_path}" if res.log_path else ""
        exc = RunAborted(f"run interrupted by {by} after {res.iterations} corrections; rig made safe{where}")
        exc.log_path, exc.result = res.log_path, res
        self._finish()
        raise exc from None

    def _fault(self, exc: BaseException) -> None:
        """An error ends the run: rig safe (quick stop after a drive fault), reason logged, log closed; a typed
        error (:class:`~ancf.errors.BellowsError`) gets ``.log_path`` and the partial ``.result``."""
        from hardware.errors import DriveFault, HardwareError
        res = self.result
        res.status, res.reason = "fault", f"{type(exc).__name__}: {exc}"
        if not isinstance(exc, BellowsError):
            self.rig.safe_stop(f"run stopped by an unexpected error: {res.reason}")
            self._finish()
            return
        self.rig.safe_stop(f"run stopped: {res.reason}", quick=isinstance(exc, DriveFault))
        if not isinstance(exc, HardwareError):
            self.rig.event("error", res.reason)
        exc.log_path, exc.result = res.log_path, res
        self._finish()

    def _finish(self) -> None:
        _finish(self.rig, self.runlog, self.own_log, self.opened_here, self.result, self.t_start, self.ctrl,
                self.n_events)


def _from_interrupt(exc: BaseException) -> bool:
    """Whether ``exc`` was caused by a KeyboardInterrupt: a C extension that a signal handler's exception landed in
    may turn it into another error (a numba kernel: "SystemError: CPUDispatcher(…) returned a result with an
    exception set", the KeyboardInterrupt its ``__cause__``)."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return True
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return False


def _recovered(rig, controller: Controller, exc, recover, result: RunResult) -> bool:
    """A drive fault inside the loop: stop the rig, ask ``recover`` (a person), and on yes bring the drives back
    (:meth:`hardware.Rig.recover`).  Returns whether the run goes on."""
    if recover is None:
        return False
    reason = f"{type(exc).__name__}: {exc}"
    rig.safe_stop(f"drive fault: {reason}", quick=True)
    if not recover(exc):
        return False
    rig.recover(reason)
    result.recoveries += 1
    return True


def _saturated(rig, controller: Controller, readings: dict, rep) -> tuple:
    """What was at a limit in this sample (see :mod:`controller.summary`): a tuple of reasons."""
    reasons = []
    P = controller.model.params
    band = 0.01 * (P.tension_max - P.tension_min)
    T_ik = None if controller.state is None else np.asarray(controller.state.tensions, float)
    lim = getattr(rig, "limits", None)
    T_meas = np.asarray(readings.get("tensions", ()), float)
    if (T_ik is not None and np.any((T_ik <= P.tension_min + band) | (T_ik >= P.tension_max - band))) or \
            (lim is not None and T_meas.size and np.any(T_meas[np.isfinite(T_meas)] >= 0.95 * lim.tension_max)):
        reasons.append("tension")
    pos = np.asarray(readings.get("positions", ()), float)
    if lim is not None and pos.size:
        edge = 0.01 * (lim.length_max - lim.length_min)
        pos = pos[np.isfinite(pos)]
        if np.any((pos <= lim.length_min + edge) | (pos >= lim.length_max - edge)):
            reasons.append("travel")
    if getattr(rep, "saturated", False):
        reasons.append("reach")
    if rep.command is not None and (rep.mode == "fallback" or rep.backtracks > 0
                                    or any("clipped" in n for n in rep.notes)):
        reasons.append("controller")
    return tuple(reasons)


def _summarise(rig, controller: Controller, result: RunResult, t_start, t_end, n_events: int) -> RunSummary:
    changes = None
    fn = getattr(rig, "load_changes", None)
    if callable(fn) and t_start is not None:
        changes = fn(t_start, t_end)
    faults = [f"{t - (t_start or 0.0):.3f} s {k}: {m}" for t, k, m in list(getattr(rig, "events", ()))[n_events:]
              if k in ("fault", "limit", "error")]
    return summarise(result.times, result.errors, tolerance=controller.tolerance,
                     t_start=t_end if t_start is None else t_start, t_end=t_end,
                     true_errors=result.true_errors, saturation=result.saturation, load_changes=changes,
                     faults=faults, corrections=result.iterations, reach_gaps=result.reach_gaps)


def _finish(rig, runlog, own_log, opened_here, result: RunResult, t_start, controller, n_events) -> None:
    now = rig.clock.now()
    result.duration = 0.0 if t_start is None else now - t_start
    summary_error = None
    try:
        result.summary = _summarise(rig, controller, result, t_start, now, n_events)
    except Exception as exc:                         # noqa: BLE001 - the summary must not lose the log
        summary_error = f"run summary failed: {type(exc).__name__}: {exc}"
    if runlog is not None:
        try:
            rig.listeners.remove(runlog.event)
        except ValueError:
            pass
        if summary_error is not None:
            runlog.event(now, "warning", summary_error)
        elif own_log:                     # a log passed in open may hold several runs: the result has it
            runlog.summary(result.summary.to_dict())
        if own_log:
            runlog.close(result.status, result.reason, t=now)
    if opened_here:
        rig.close()
