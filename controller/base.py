"""What every controller shares: the step report and the abstract interface the loop drives.

A controller is a small state machine driven by tip measurements (all SI: m, N, Pa, s)::

    lengths = ctrl.start(target)          # first IK; tendon lengths [m] to send to the motors
    while True:
        rep = ctrl.step(plant.measure())  # one correction; rep.command is None once ‖p_m − p_d‖ < tol
        if rep.command is None: break
        plant.command(rep.command)

It never sees the plant's state or load: only the measured tip position.
"""

from __future__ import annotations

import abc
import time
from dataclasses import dataclass, field
from typing import Optional

import numpy as np

from ancf import Equilibrium, InfeasibleTargetError, Model
from ancf.errors import InputError

from .errors import check_finite, number


@dataclass
class StepReport:
    """One controller iteration.

    error : (3,) p_m − p_d [m] that the step reacted to;  error_norm [m]
    converged : True when ‖p_m − p_d‖ < tolerance (no correction was made, ``command`` is None)
    command : (m,) tendon lengths to send [m], or None
    estimate : (3,) load estimate F̂ after the step [N] (VF-CC: the virtual force)
    mode : "lacc" | "fallback" | "vfcc" | "idle"
    compute_time : wall-clock seconds spent inside the step (IK + compliance + bookkeeping)
    compliance : (3, 3) C'_p used for the update [m/N] (LACC only), active : taut set used (LACC only)
    ik_iterations : Newton iterations of the IK solve (or function evaluations of the bounded IK)
    backtracks : how often the load step was halved because the IK became infeasible
    saturated : the IK target was out of reach (tension limits) and the nearest reachable state was commanded
    reach_gap : when saturated, how far the IK target is out of reach: ‖tip of the commanded state − IK target‖
        [m] under the load the step assumed; else 0.  For LACC (a load estimate) the part of the tip error no
        controller could remove; for VF-CC the load assumed is its virtual force, so only an indication
    """
    error: np.ndarray
    error_norm: float
    converged: bool
    command: Optional[np.ndarray]
    estimate: np.ndarray
    mode: str
    compute_time: float
    compliance: Optional[np.ndarray] = None
    active: tuple = ()
    ik_iterations: int = 0
    backtracks: int = 0
    notes: list = field(default_factory=list)
    saturated: bool = False
    reach_gap: float = 0.0

    def to_dict(self) -> dict:
        out = {}
        for k, v in self.__dict__.items():
            out[k] = v.tolist() if isinstance(v, np.ndarray) else v
        return out


class Controller(abc.ABC):
    """Base of the quasi-static tip-position controllers (LACC, VF-CC).

    Parameters
    ----------
    model : the controller's own :class:`ancf.Model` (may differ from the plant's)
    pressure : chamber pressure p [Pa], held constant by the controller
    tolerance : stop when ‖p_m − p_d‖ < tolerance [m] (paper: 0.2 mm)
    """

    name = "controller"

    def __init__(self, model: Model, pressure: float, *, tolerance: float = 2e-4):
        if not isinstance(model, Model):
            raise InputError(f"controller needs an ancf.Model, got {type(model).__name__}")
        self.model = model
        self.pressure = number("pressure [Pa]", pressure)
        self.tolerance = number("tolerance [m]", tolerance)
        self.target: Optional[np.ndarray] = None
        self.state: Optional[Equilibrium] = None      # the controller's last IK solution

    # ---------------------------------------------------------------------------------------- API
    @abc.abstractmethod
    def start(self, target, initial_load=(0.0, 0.0, 0.0)) -> np.ndarray:
        """First IK for the desired tip ``target`` (3,) [m]; returns the tendon lengths (m,) [m]."""

    @abc.abstractmethod
    def step(self, measured_tip) -> StepReport:
        """One correction from the measured tip position (3,) [m]."""

    @property
    @abc.abstractmethod
    def estimate(self) -> np.ndarray:
        """Current load estimate / virtual force (3,) [N]."""

    # ---------------------------------------------------------------------------------------- helpers
    def _check_started(self):
        if self.target is None or self.state is None:
            raise InputError(f"{self.name}: call start(target) before step()")

    def _measured(self, measured_tip) -> np.ndarray:
        return check_finite("measured tip position", measured_tip, (3,))

    def _begin_step(self, measured_tip):
        """Shared start of ``step``: check, error e = p_m − p_d, its norm, the clock, and the idle report
        when already within tolerance (else None).  Returns (e, ‖e‖, t0, idle_report)."""
        self._check_started()
        pm = self._measured(measured_tip)
        t0 = time.perf_counter()
        e = pm - self.target
        en = float(np.linalg.norm(e))
        idle = (StepReport(e, en, True, None, self.estimate, "idle", time.perf_counter() - t0)
                if en < self.tolerance else None)
        return e, en, t0, idle

    def _reach(self, target: np.ndarray, load: np.ndarray) -> tuple:
        """The IK state for the tip ``target`` [m] under the tip load ``load`` [N], or — when no tensions inside
        their bounds reach it (:class:`~ancf.errors.InfeasibleTargetError`) — the nearest reachable state: the
        equilibrium at the tensions the bounded IK found (the error's verified ``state``, else the FK there
        warm-started from the last state).  Returns (state, saturated, note)."""
        try:
            eq = self.model.ik(target, self.pressure, load, q0=self.state.q, tensions0=self.state.tensions)
            return eq, False, ""
        except InfeasibleTargetError as exc:
            eq, note = self._nearest(exc, target, load)
            return eq, True, note

    def _nearest(self, exc: InfeasibleTargetError, target: np.ndarray, load: np.ndarray) -> tuple:
        """(state, note) at the tensions of ``exc`` — the nearest reachable point the bounded IK found."""
        if exc.tensions is None:
            raise exc
        # the bounded IK hands on the verified equilibrium at those tensions (else: the FK from the last state)
        eq = exc.state if exc.state is not None else self.model.fk(exc.tensions, self.pressure, load, q0=self.state.q)
        note = (f"saturated: target {1e3 * np.linalg.norm(eq.tip - target):.2f} mm out of reach "
                f"({'; '.join(exc.violated) or 'bounds'}); nearest reachable state commanded")
        return eq, note

    def _warm_start(self) -> Equilibrium:
        """The stored gravity-only droop state at the controller's pressure (paper Sec. III-E)."""
        return self.model.droop(self.pressure)
