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

A target the actuator cannot reach under the current load does not end the run: the controller commands the
nearest reachable state and reports the step ``saturated`` (status line, the log's ``saturated`` column,
the summary's ``reach`` saturation time) until the load lets it track again.

Faults: any :class:`~ancf.errors.BellowsError` during the run (hardware fault, limit, infeasible IK) makes
the rig safe (:meth:`hardware.Rig.safe_stop`: drives hold — quick stop after a drive fault — pressure held
or vented), writes the reason to the log, closes it and re-raises the error with ``.log_path`` and the
partial ``.result`` attached.  Ctrl-C (and SIGTERM) does the same and raises :class:`hardware.errors.RunAborted`,
also when its first KeyboardInterrupt is lost in a finaliser and when the process inherited SIGINT ignored
(the loop checks a latch every cycle: :mod:`controller.interrupt`).

This module imports :mod:`hardware` only inside :func:`run_on_rig` (for the run log and RunAborted).
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
    fault | interrupted; ``errors``: measured ‖p_m − p_d‖ per sample [m]; ``true_errors``: the same from
    the simulated truth (empty on hardware); ``times``: the samples' rig time [s]; ``saturation``: per
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


def run_on_rig(controller: Controller, rig, target, *, log: Union[str, pathlib.Path, None, object] = None,
               force: bool = False, max_iterations: Optional[int] = 20, duration: Optional[float] = None,
               idle_period: float = 0.1, initial_load=(0.0, 0.0, 0.0), sim_compute_time="measured",
               average_frames: int = 1, record_static: bool = True, applied_load=None,
               status: Optional[Callable[[dict], None]] = None,
               run_info: Optional[dict] = None, shaper: Optional[tuple] = None,
               recover: Optional[Callable[[BellowsError], bool]] = None) -> RunResult:
    """Run ``controller`` on ``rig`` towards ``target`` (3,) [m]; see the module docstring.

    log : path of the run log (``.h5``; refused if it exists unless ``force``), an open
        :class:`hardware.runlog.RunLog`, or None
    max_iterations : corrections before an iteration run stops (None: no limit — needs ``duration``)
    duration : rig-clock seconds to hold the target (``math.inf``: until Ctrl-C); None: stop at convergence
    idle_period : wait between measurements while within tolerance [s]; 0 (iteration runs) or ≥
        :data:`MIN_IDLE_PERIOD`
    sim_compute_time : on a simulated rig, how long a controller step takes on the rig clock: "measured"
        (its wall-clock compute time), a fixed time [s], or 0
    average_frames : tracker frames averaged per measurement (distinct frames; noise / √n)
    applied_load : the tip load the experiment applies, if it is known (calibrated weights; zero): (3,) [N]
        or a callable of the rig time t [s]; it becomes the static states' ``tip_force`` (None: unknown, NaN).
        The controller never sees it.
    status : called with a dict after every sample (for a status line)
    shaper : (A₁, delay [s]) of :func:`controller.shaping.zv_shaper`: every correction is sent as A₁ of the
        move, then the whole move ``delay`` later — a plant with inertia is left without ringing at the mode
        the shaper was made for (docs/dynamics.md); None: moves as commanded
    recover : after a drive fault has stopped the rig (drives quick-stopped, pressure held or vented), called
        with the fault: True resets the faulted drives and enables them where they stand
        (:meth:`hardware.Rig.recover`), then the run goes on from a new IK with the current load estimate; False
        ends the run on the fault.  Only for a person's decision (``bellows control`` asks); None (default):
        every drive fault ends the run
    """
    if not isinstance(controller, Controller):
        raise InputError(f"run_on_rig needs a Controller, got {type(controller).__name__}")
    pd = check_finite("target", target, (3,))
    if max_iterations is not None:
        if isinstance(max_iterations, bool) or not isinstance(max_iterations, (int, np.integer)) or max_iterations < 0:
            raise InputError(f"max_iterations must be an integer >= 0 or None, got {max_iterations!r}")
    if duration is not None:
        duration = number("duration [s]", duration, allow_inf=True)
    elif max_iterations is None:
        raise InputError("give max_iterations or a duration (a run without either never ends)")
    idle_period = number("idle_period [s]", idle_period)
    if idle_period == 0 and duration is not None:
        raise InputError("idle_period must be > 0 s when holding for a duration")
    if 0 < idle_period < MIN_IDLE_PERIOD:
        # a smaller wait is lost in the rig clock's round-off (t + 1e-300 == t): the run would never end
        raise InputError(f"idle_period must be 0 or at least {MIN_IDLE_PERIOD:g} s, got {idle_period:g} s")
    if sim_compute_time != "measured":
        sim_compute_time = number("sim_compute_time [s] (or 'measured')", sim_compute_time)
    if isinstance(average_frames, bool) or not isinstance(average_frames, (int, np.integer)) or average_frames < 1:
        raise InputError(f"average_frames must be an integer >= 1, got {average_frames!r}")
    if applied_load is not None and not callable(applied_load):
        applied_load = check_finite("applied_load [N]", applied_load, (3,))
    if shaper is not None:
        if not (isinstance(shaper, tuple) and len(shaper) == 2):
            raise InputError(f"shaper must be (A1, delay [s]) from controller.zv_shaper, got {shaper!r}")
        a1, delay = number("shaper A1", shaper[0]), number("shaper delay [s]", shaper[1])
        if not 0 < a1 <= 1:
            raise InputError(f"shaper A1 must be in (0, 1], got {a1:g}")
    if recover is not None and not callable(recover):
        raise InputError(f"recover must be a callable (fault -> bool) or None, got {type(recover).__name__}")
    from hardware.errors import DriveFault, HardwareError, RunAborted
    from hardware.runlog import RunLog

    result = RunResult(controller.name, pd)
    # Everything that can be checked without moving is checked before the run log exists, so that a run
    # refused up front (pressure beyond the limit, unreachable target, IK lengths beyond the travel, IK
    # tensions beyond the limit) leaves no log behind to block the next try.
    limits = getattr(rig, "limits", None)
    if limits is not None:
        limits.check_pressure_command(controller.pressure)
    lengths = controller.start(pd, initial_load)            # first IK: raises if the target is not reachable
    if limits is not None:
        limits.check_lengths(lengths, None, rig.m)
        limits.check_tensions(controller.state.tensions, what="expected")
    own_log = isinstance(log, (str, pathlib.Path))
    runlog = None
    if own_log:
        info = {"target_m": pd, "pressure_Pa": controller.pressure, "max_iterations": max_iterations,
                "duration_s": duration, "idle_period_s": idle_period, **(run_info or {})}
        runlog = RunLog(log, n_tendons=rig.m, force=force, rig=rig.describe(),
                        controller=_describe_controller(controller), run=info,
                        actuator_toml=controller.model.params.to_toml())
    elif log is not None:
        runlog = log
    if runlog is not None:
        result.log_path = runlog.path
        rig.listeners.append(runlog.event)
    opened_here = not getattr(rig, "_open", True)
    simulated = bool(getattr(rig, "simulated", False))
    t_start = None
    was_converged = False
    n_events = len(getattr(rig, "events", ()))
    latch = CtrlCLatch().__enter__()      # a Ctrl-C lost in a finaliser still stops the loop (controller.interrupt)
    try:
        if opened_here:
            rig.open()
        t_start = rig.clock.now()
        k = 0
        while True:        # one pass; another only after a drive fault a person chose to recover from
            try:
                rig.set_pressure(controller.pressure)
                rig.command(lengths, expected_tensions=controller.state.tensions)
                rig.advance(None)
                prev_start, prev_io, io = None, float("nan"), float("nan")
                while True:
                    latch.check()
                    # loop timing (wall clock): this cycle's start, and the rig-call time of the previous cycle
                    start = time.perf_counter()
                    cycle_time = float("nan") if prev_start is None else start - prev_start
                    prev_start, prev_io, io = start, io, 0.0
                    readings = rig.check_health()
                    pm = rig.measure(average_frames) if average_frames > 1 else rig.measure()
                    io += time.perf_counter() - start
                    t = rig.clock.now()
                    truth = rig.true_tip() if simulated else None
                    rep = controller.step(pm)
                    if simulated and rep.command is not None and sim_compute_time != 0:
                        rig.advance(rep.compute_time if sim_compute_time == "measured" else float(sim_compute_time))
                    row = {"t": t, "iteration": k, "tip": pm, "error": rep.error, "error_norm": rep.error_norm,
                           "command": rep.command, "position": readings["positions"], "tension": readings["tensions"],
                           "pressure": readings["pressure"], "estimate": rep.estimate, "compute_time": rep.compute_time,
                           "saturated": float(getattr(rep, "saturated", False)), "io_time": prev_io,
                           "reach_gap": float(getattr(rep, "reach_gap", 0.0)),
                           "cycle_time": cycle_time}
                    if simulated:
                        row["true_tip"], row["true_load"] = truth, rig.load(t)
                        result.true_errors.append(float(np.linalg.norm(truth - pd)))
                    if runlog is not None:
                        runlog.sample(**row)
                    result.samples += 1
                    result.errors.append(rep.error_norm)
                    result.times.append(float(t))
                    result.saturation.append(_saturated(rig, controller, readings, rep))
                    result.reach_gaps.append(float(getattr(rep, "reach_gap", 0.0)))
                    result.estimate = np.asarray(rep.estimate, float).copy()
                    if status is not None:
                        status({"t": t - t_start, "iteration": k, "error_m": rep.error_norm, "mode": rep.mode,
                                "saturated": bool(getattr(rep, "saturated", False)),
                                "estimate_N": rep.estimate, "pressure_Pa": readings["pressure"],
                                "tensions_N": readings["tensions"]})
                    if rep.command is None:
                        if not was_converged:
                            rig.event("converged", f"tip error {rep.error_norm * 1e3:.4f} mm < tolerance "
                                                   f"{controller.tolerance * 1e3:.4f} mm after {k} corrections")
                            if record_static and runlog is not None and np.all(np.isfinite(readings["tensions"])):
                                F_known = (None if applied_load is None else
                                           applied_load(t) if callable(applied_load) else applied_load)
                                runlog.static_state(time=t, tensions=np.maximum(readings["tensions"], 0.0),
                                                    pressure=readings["pressure"], tip=pm, tip_force=F_known,
                                                    label=f"converged after {k} corrections")
                                result.static_states += 1
                        was_converged = True
                        if duration is None:
                            result.status = "converged"
                            break
                        if rig.clock.now() - t_start >= duration:
                            result.status = "held"
                            break
                        t_io = time.perf_counter()
                        rig.advance(idle_period)
                        io += time.perf_counter() - t_io
                        continue
                    was_converged = False
                    if duration is None and max_iterations is not None and k >= max_iterations:
                        result.status = "not converged"
                        result.reason = (f"tip error {rep.error_norm * 1e3:.4f} mm after {k} corrections "
                                         f"(tolerance {controller.tolerance * 1e3:.4f} mm)")
                        break
                    t_cmd, t_io = rig.clock.now(), time.perf_counter()
                    if shaper is not None and rig.commanded is not None:
                        # ZV input shaping: A₁ of the move now, all of it half a damped period later
                        last = np.asarray(rig.commanded, float)
                        rig.command(last + a1 * (np.asarray(rep.command, float) - last),
                                    expected_tensions=controller.state.tensions)
                        rig.advance(delay)
                    rig.command(rep.command, expected_tensions=controller.state.tensions)
                    rig.advance(None)
                    if rig.clock.now() <= t_cmd:
                        # nothing to move and no time passed (a simulated rig given the same command again, e.g. while
                        # saturated): wait like a held target, or the loop would spin at one instant of rig time
                        rig.advance(idle_period)
                    io += time.perf_counter() - t_io
                    k += 1
                    result.iterations = k
                    if duration is not None and rig.clock.now() - t_start >= duration:
                        result.status = "held"
                        break
                break
            except DriveFault as exc:
                if not _recovered(rig, controller, exc, recover, result):
                    raise
                lengths = controller.start(pd, result.estimate if result.estimate is not None else initial_load)
                was_converged = False
    except KeyboardInterrupt:
        by = latch.signal_name or "Ctrl-C"
        rig.safe_stop(f"interrupted ({by})")
        result.status, result.reason = "interrupted", by
        where = f"; log: {result.log_path}" if result.log_path else ""
        exc = RunAborted(f"run interrupted by {by} after {result.iterations} corrections; rig made safe{where}")
        exc.log_path, exc.result = result.log_path, result
        _finish(rig, runlog, own_log, opened_here, result, t_start, controller, n_events)
        raise exc from None
    except BellowsError as exc:
        result.status, result.reason = "fault", f"{type(exc).__name__}: {exc}"
        rig.safe_stop(f"run stopped: {result.reason}", quick=isinstance(exc, DriveFault))
        if not isinstance(exc, HardwareError):
            rig.event("error", result.reason)
        exc.log_path, exc.result = result.log_path, result
        _finish(rig, runlog, own_log, opened_here, result, t_start, controller, n_events)
        raise
    except BaseException as exc:
        result.status, result.reason = "fault", f"{type(exc).__name__}: {exc}"
        rig.safe_stop(f"run stopped by an unexpected error: {result.reason}")
        _finish(rig, runlog, own_log, opened_here, result, t_start, controller, n_events)
        raise
    finally:
        latch.__exit__()
    _finish(rig, runlog, own_log, opened_here, result, t_start, controller, n_events)
    return result


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
