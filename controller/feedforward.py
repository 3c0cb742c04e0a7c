r"""Open-loop (feed-forward) control by IK on a rig: trajectory tracking (paper Sec. V-B, Fig. 7) and
holding a position under known, stepped loads (Fig. 8).

For each waypoint p_k [m] the IK gives tendon lengths for the pressure and the load the model is told
about (paper eq. 2; warm-started from the previous waypoint), the rig moves there (limits checked before
anything is sent) and, after the move and its settle time, the tracker measures the tip.  Nothing is
corrected: the error is the model's (and the rig's) error.  Runs on any rig with the
:class:`hardware.Rig` interface and logs like :func:`controller.run_on_rig`.
"""

from __future__ import annotations

import pathlib
from dataclasses import dataclass, field
from typing import Optional, Union

import numpy as np

from ancf import Model
from ancf.errors import InputError

from .errors import check_finite, number


@dataclass
class OpenLoopResult:
    """Per waypoint: ``targets`` (k, 3), ``measured`` (k, 3), ``true`` (k, 3; NaN on hardware) [m];
    ``errors`` measured ‖p_m − p_k‖ [m]; ``true_errors`` (simulated rig) [m]."""
    targets: np.ndarray
    measured: np.ndarray
    true: np.ndarray
    tensions: np.ndarray
    log_path: Optional[pathlib.Path] = None
    notes: list = field(default_factory=list)

    @property
    def errors(self) -> np.ndarray:
        return np.linalg.norm(self.measured - self.targets, axis=1)

    @property
    def true_errors(self) -> np.ndarray:
        return np.linalg.norm(self.true - self.targets, axis=1)

    def rmse(self, truth: bool = True) -> float:
        """Root-mean-square position error [m] (of the simulated truth if available and ``truth``)."""
        e = self.true_errors if truth and np.all(np.isfinite(self.true)) else self.errors
        return float(np.sqrt(np.mean(e ** 2)))


def run_open_loop(model: Model, rig, waypoints, *, pressure: float, load=(0.0, 0.0, 0.0),
                  log: Union[str, pathlib.Path, None, object] = None, force: bool = False,
                  average_frames: int = 1) -> OpenLoopResult:
    """Drive ``rig`` through ``waypoints`` (k, 3) [m] by IK with the model's ``load`` (3,) [N] (or (k, 3):
    one per waypoint) at ``pressure`` [Pa]; see the module docstring."""
    if not isinstance(model, Model):
        raise InputError(f"run_open_loop needs an ancf.Model, got {type(model).__name__}")
    P = check_finite("waypoints", waypoints)
    if P.ndim != 2 or P.shape[1] != 3 or P.shape[0] == 0:
        raise InputError(f"waypoints must have shape (k, 3), got {P.shape}")
    p = number("pressure [Pa]", pressure)
    F = check_finite("load", load)
    F = np.broadcast_to(F, P.shape) if F.shape in ((3,), P.shape) else None
    if F is None:
        raise InputError(f"load must be (3,) or ({P.shape[0]}, 3) [N]")
    from hardware.runlog import RunLog
    runlog = RunLog(log, n_tendons=rig.m, force=force, rig=rig.describe(), controller={"name": "open-loop IK"},
                    run={"waypoints_m": P, "pressure_Pa": p, "load_N": F}, actuator_toml=model.params.to_toml()) \
        if isinstance(log, (str, pathlib.Path)) else log
    simulated = bool(getattr(rig, "simulated", False))
    meas, true, tens = [], [], []
    prev = model.droop(p)
    status, reason = "completed", ""
    try:
        rig.set_pressure(p)
        for k, (pk, Fk) in enumerate(zip(P, F)):
            eq = model.ik(pk, p, Fk, q0=prev.q, tensions0=prev.tensions)
            rig.command(eq.tendon_lengths, expected_tensions=eq.tensions)
            rig.advance(None)
            readings = rig.check_health()
            pm = rig.measure(average_frames) if average_frames > 1 else rig.measure()
            tt = rig.true_tip() if simulated else np.full(3, np.nan)
            meas.append(pm)
            true.append(tt)
            tens.append(eq.tensions)
            if runlog is not None:
                runlog.sample(t=rig.clock.now(), iteration=k, tip=pm, error=pm - pk, error_norm=np.linalg.norm(pm - pk),
                              command=eq.tendon_lengths, position=readings["positions"], tension=readings["tensions"],
                              pressure=readings["pressure"], estimate=Fk, true_tip=tt if simulated else None,
                              true_load=rig.load() if simulated else None)
            prev = eq
    except BaseException as exc:
        status, reason = "fault", f"{type(exc).__name__}: {exc}"
        rig.safe_stop(f"open-loop run stopped: {reason}")
        raise
    finally:
        if runlog is not None and isinstance(log, (str, pathlib.Path)):
            runlog.close(status, reason, t=rig.clock.now())
    return OpenLoopResult(P.copy(), np.array(meas), np.array(true), np.array(tens),
                          getattr(runlog, "path", None))
