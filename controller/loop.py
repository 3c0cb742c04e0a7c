r"""Control loops: the iteration protocol of Table I and an event-driven timed loop for time-varying loads.

``run_iterations`` — the quasi-static protocol of Algorithm 1 / Table I: command, wait until the motors
stop, measure, correct; the tip error is recorded after every completed move.

``run_timed`` — the loop in time (Sec. V-E): the load F(t) changes while the controller computes and the
motors move.  One cycle is

    measure p_m(t) → compute (wall-clock time of the real solver × ``compute_scale``, or a fixed time)
    → motors move at their rate limit (``PlantOptions.length_rate``) plus ``actuation_latency``
    → ``settle_time`` (wait for the zero-velocity lock / a fresh tracker frame) → next measurement,

and while idle (error below the tolerance) the loop re-measures every ``idle_period``.  The actuator is
quasi-static (no inertia: paper's assumption); the true tip error is sampled every ``sample_dt`` seconds
through all phases, so the reported maximum includes the error that builds up between corrections.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional, Union

import numpy as np

from ancf.errors import BellowsError, InputError

from .errors import check_finite, number

from .base import Controller, StepReport
from .errors import NotConvergedError
from .plant import Plant


@dataclass
class EpisodeResult:
    """Result of :func:`run_iterations`.

    errors : true tip error ‖p − p_d‖ [m] after the initial IK (index 0) and after each correction
    measured_errors : what the controller saw [m]
    estimates : (k+1, 3) load estimate / virtual force after each step [N]
    reports : the controller's step reports;  converged : error < tolerance at the end
    iterations : corrections made;  compute_times : seconds per step (wall clock)
    true_load : (3,) [N]
    """
    controller: str
    target: np.ndarray
    true_load: np.ndarray
    errors: list
    measured_errors: list
    estimates: list
    reports: list
    converged: bool
    iterations: int
    compute_times: list
    tolerance: float
    failure: Optional[str] = None


    @property
    def final_error(self) -> float:
        return self.errors[-1]

    def iterations_to(self, tol: float) -> Optional[int]:
        """First iteration index whose true error is below ``tol`` [m] (None if never)."""
        for k, e in enumerate(self.errors):
            if e < tol:
                return k
        return None

    def to_dict(self) -> dict:
        return {"controller": self.controller, "target": self.target.tolist(), "true_load": self.true_load.tolist(),
                "errors": list(map(float, self.errors)), "measured_errors": list(map(float, self.measured_errors)),
                "estimates": [list(map(float, e)) for e in self.estimates], "converged": self.converged,
                "iterations": self.iterations, "compute_times": list(map(float, self.compute_times)),
                "tolerance": self.tolerance, "modes": [r.mode for r in self.reports], "failure": self.failure}


def run_iterations(controller: Controller, plant: Plant, target, *, iterations: int = 5,
                   initial_load=(0.0, 0.0, 0.0), stop_at_tolerance: bool = True,
                   require_convergence: bool = False, on_error: str = "raise") -> EpisodeResult:
    """Run Algorithm 1's loop (or VF-CC's) for at most ``iterations`` corrections.

    With ``stop_at_tolerance`` the loop ends when the controller reports ‖p_m − p_d‖ < its tolerance (the
    paper's while-condition); otherwise all iterations are made (controllers with tolerance 0 never stop
    early).  ``require_convergence`` raises :class:`NotConvergedError` if the final error is not below the
    controller's tolerance.  ``on_error="stop"`` ends the episode when a correction step raises a
    :class:`~ancf.errors.BellowsError` (e.g. the load estimate needs tensions beyond their limits) and
    records the message in ``failure`` instead of raising; the initial IK always raises.
    """
    pd = check_finite("target", target, (3,))
    truth = getattr(plant, "true_tip", None) or plant.measure     # a real rig only has its measurement
    if isinstance(iterations, bool) or not isinstance(iterations, (int, np.integer)) or iterations < 0:
        raise InputError(f"iterations must be an integer >= 0, got {iterations!r}")
    plant.command(controller.start(pd, initial_load))
    plant.advance(None)
    errors = [float(np.linalg.norm(truth() - pd))]
    measured, estimates, reports, times = [], [controller.estimate.tolist()], [], []
    converged = False
    failure = None
    k = 0
    if on_error not in ("raise", "stop"):
        raise InputError(f"on_error must be 'raise' or 'stop', got {on_error!r}")
    while k < iterations:
        pm = plant.measure()
        try:
            rep = controller.step(pm)
        except BellowsError as exc:
            if on_error != "stop":
                raise
            failure = f"iteration {k + 1}: {type(exc).__name__}: {exc}"
            break
        measured.append(rep.error_norm)
        if rep.converged:
            converged = True
            if stop_at_tolerance:
                break
            reports.append(rep)
            k += 1
            errors.append(errors[-1])
            estimates.append(rep.estimate.tolist())
            times.append(rep.compute_time)
            continue
        reports.append(rep)
        times.append(rep.compute_time)
        plant.command(rep.command)
        plant.advance(None)
        k += 1
        errors.append(float(np.linalg.norm(truth() - pd)))
        estimates.append(rep.estimate.tolist())
    if not converged:
        pm = plant.measure()
        e = float(np.linalg.norm(pm - pd))
        measured.append(e)
        converged = e < controller.tolerance
    true_load = plant.load() if hasattr(plant, "load") else np.full(3, np.nan)
    res = EpisodeResult(controller.name, pd, true_load, errors, measured, estimates, reports, converged, k,
                        times, controller.tolerance, failure)
    if require_convergence and not converged:
        raise NotConvergedError(f"{controller.name} did not converge", iterations=k, error=measured[-1],
                                tolerance=controller.tolerance, history=errors)
    return res


@dataclass
class TimedResult:
    """Result of :func:`run_timed` (arrays over the sample grid, SI)."""
    controller: str
    t: np.ndarray                 # sample times [s]
    load: np.ndarray              # (k, 3) true load [N]
    error: np.ndarray             # (k, 3) true tip p − p_d [m]
    estimate: np.ndarray          # (k, 3) controller estimate [N]
    cycle_times: list             # (t_measure, compute [s], move [s], settle [s]) per correction
    corrections: int
    compute_times: list           # wall-clock compute of each correcting step [s]
    idle_checks: int = 0          # measurements that found the error below the tolerance

    @property
    def error_norm(self) -> np.ndarray:
        return np.linalg.norm(self.error, axis=1)

    def max_error(self, after: float = 0.0) -> float:
        """Largest ‖p − p_d‖ [m] at t ≥ after [s]."""
        sel = self.t >= after
        return float(np.max(self.error_norm[sel]))

    def to_dict(self) -> dict:
        return {"controller": self.controller, "t": self.t.tolist(), "load": self.load.tolist(),
                "error": self.error.tolist(), "estimate": self.estimate.tolist(),
                "cycle_times": [list(map(float, c)) for c in self.cycle_times], "corrections": self.corrections,
                "compute_times": list(map(float, self.compute_times)),
                "idle_checks": self.idle_checks}


def _ringing(seen: list, since: float) -> float:
    """Peak-to-peak size [m] of what is left of the tip positions measured since ``since`` [s] after taking
    out a straight line in time: the oscillation (ringing) about the load-driven drift."""
    rows = [(t, p) for t, p in seen if t >= since - 1e-12]
    t = np.array([r[0] for r in rows])
    P = np.array([r[1] for r in rows])
    A = np.column_stack([np.ones_like(t), t - t[0]])
    resid = P - A @ np.linalg.lstsq(A, P, rcond=None)[0]
    return float(np.linalg.norm(resid.max(axis=0) - resid.min(axis=0)))


def run_timed(controller: Controller, plant: Plant, target, *, duration: float,
              compute_time: Union[str, float] = "measured", compute_scale: float = 1.0,
              actuation_latency: float = 0.0, settle_time: Union[float, str] = 0.0, idle_period: float = 1.0 / 30,
              sample_dt: float = 0.05, initial_load=(0.0, 0.0, 0.0), still_window: Optional[float] = None,
              still_tol: Optional[float] = None, settle_max: float = 2.0,
              shaper: Optional[tuple] = None) -> TimedResult:
    """Event-driven closed loop over ``duration`` seconds under the plant's load profile F(t).

    compute_time : "measured" (the real wall-clock time of each controller step × ``compute_scale``) or a
        fixed time per step [s];  actuation_latency : fixed extra time per move [s] (command transport,
        motor acceleration);  settle_time : wait after a move before measuring [s];  idle_period : time
        between measurements while the error is below the tolerance [s];  sample_dt : grid on which the true
        tip error is recorded [s].
    """
    pd = check_finite("target", target, (3,))
    duration = number("duration", duration, strict=True)
    sample_dt = number("sample_dt", sample_dt, strict=True)
    idle_period = number("idle_period", idle_period, strict=True)
    compute_scale = number("compute_scale", compute_scale)
    actuation_latency = number("actuation_latency", actuation_latency)
    still = isinstance(settle_time, str) and settle_time == "still"
    if not still:
        settle_time = number("settle_time", settle_time)
    if not (compute_time == "measured" or (isinstance(compute_time, (int, float)) and not isinstance(compute_time, bool)
                                           and 0 <= compute_time < float("inf"))):
        raise InputError(f"compute_time must be 'measured' or a time >= 0 s, got {compute_time!r}")
    settle_max = number("settle_max", settle_max, strict=True)
    if shaper is not None:
        if not (isinstance(shaper, tuple) and len(shaper) == 2):
            raise InputError(f"shaper must be (A1, delay [s]) from controller.shaping.zv_shaper, got {shaper!r}")
        a1, delay = number("shaper A1", shaper[0], strict=True), number("shaper delay [s]", shaper[1])
        if a1 > 1:
            raise InputError(f"shaper A1 must be in (0, 1], got {a1:g}")
    plant.time = 0.0
    lengths0 = controller.start(pd, initial_load)
    plant.command(lengths0)
    if still:
        if still_window is None:
            model = controller.model
            try:
                eq = model.fk_locked(lengths0, controller.pressure, initial_load)
                still_window = 1.0 / float(model.modes(eq, 1).frequencies_hz[0])
            except BellowsError as exc:
                raise InputError(f"settle_time='still' needs still_window [s]: the model's first mode is not "
                                 f"available ({exc})") from None
        still_window = number("still_window", still_window, strict=True)
        still_tol = controller.tolerance if still_tol is None else number("still_tol", still_tol, strict=True)
    ts, loads, errs, ests = [], [], [], []
    next_sample = [0.0]

    def pass_time(dt: float):
        """Advance the plant by dt, recording samples on the grid."""
        t_end = plant.time + dt
        while next_sample[0] <= t_end + 1e-12:
            plant.advance(max(next_sample[0] - plant.time, 0.0))
            ts.append(plant.time)
            loads.append(plant.load())
            errs.append(plant.true_tip() - pd)
            ests.append(controller.estimate)
            next_sample[0] += sample_dt
        plant.advance(max(t_end - plant.time, 0.0))

    cycles, ctimes, corrections, idle = [], [], 0, 0
    while plant.time < duration:
        t_meas = plant.time
        rep: StepReport = controller.step(plant.measure())
        c = rep.compute_time * compute_scale if compute_time == "measured" else float(compute_time)
        if rep.command is None:
            idle += 1
            pass_time(max(idle_period, c))
            continue
        ctimes.append(rep.compute_time)
        pass_time(c)                                  # the old lengths hold while the solver runs
        if shaper is not None:
            # zero-vibration input shaping: the move in two parts, the second half a damped period later,
            # so that the ringing the first part starts is cancelled by the second (controller/shaping.py)
            last = getattr(plant, "commanded", None)
            last = np.asarray(rep.command if last is None else last, float)
            move = plant.command(last + a1 * (np.asarray(rep.command, float) - last))
            pass_time(max(delay, move + actuation_latency))
        move = plant.command(rep.command)
        pass_time(move + actuation_latency)           # motors travel (rate-limited)
        if still:
            t0, poll = plant.time, still_window / 10
            seen = [(plant.time, plant.measure())]
            while plant.time - t0 < settle_max:
                pass_time(poll)
                seen.append((plant.time, plant.measure()))
                if plant.time - t0 >= still_window - 1e-12 and _ringing(seen, plant.time - still_window) < still_tol:
                    break
            waited = plant.time - t0
        else:
            pass_time(settle_time)
            waited = settle_time
        corrections += 1
        cycles.append((t_meas, c, move + actuation_latency, waited))
    n = len(ts)
    return TimedResult(controller.name, np.array(ts), np.array(loads).reshape(n, 3), np.array(errs).reshape(n, 3),
                       np.array(ests).reshape(n, 3), cycles, corrections, ctimes, idle)


def run_periodic(controller: Controller, plant: Plant, target, *, duration: float, latency: float = 1e-3,
                 sample_dt: float = 0.01, initial_load=(0.0, 0.0, 0.0)) -> TimedResult:
    """Fixed-rate closed loop over ``duration`` [s]: every ``controller.period`` seconds the plant is
    measured and the controller stepped; its command reaches the motors ``latency`` [s] later (commands in
    flight queue up), and the motors move at their rate limit.  For controllers that run at the loop rate
    (:class:`controller.DynamicLACC`); the true tip error is sampled every ``sample_dt`` [s]."""
    pd = check_finite("target", target, (3,))
    period = getattr(controller, "period", None)
    if period is None:
        raise InputError(f"run_periodic needs a controller with a loop period (DynamicLACC), got {controller.name}")
    duration = number("duration", duration, strict=True)
    latency = number("latency", latency)
    sample_dt = number("sample_dt", sample_dt, strict=True)
    plant.time = 0.0
    plant.command(controller.start(pd, initial_load))
    ts, loads, errs, ests, pending = [], [], [], [], []
    next_sample, compute = 0.0, []
    k = 0
    while k * period < duration - 1e-12:
        t_k = k * period
        rep = controller.step(plant.measure())
        compute.append(rep.compute_time)
        pending.append((t_k + latency, rep.command))
        t_end = (k + 1) * period
        while True:                                   # advance to the next event: a sample, a command, the period
            t_cmd = pending[0][0] if pending else math.inf
            t_next = min(next_sample, t_cmd, t_end)
            if t_next > plant.time:
                plant.advance(t_next - plant.time)
            if pending and pending[0][0] <= plant.time + 1e-12:
                plant.command(pending.pop(0)[1])
                continue
            if next_sample <= plant.time + 1e-12:
                ts.append(plant.time)
                loads.append(plant.load())
                errs.append(plant.true_tip() - pd)
                ests.append(controller.estimate)
                next_sample += sample_dt
                continue
            if plant.time >= t_end - 1e-12:
                break
        k += 1
    n = len(ts)
    return TimedResult(controller.name, np.array(ts), np.array(loads).reshape(n, 3), np.array(errs).reshape(n, 3),
                       np.array(ests).reshape(n, 3), [], k, compute, 0)
