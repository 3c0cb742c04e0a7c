"""The rig: tendon drives, force sensors, a pressure supply and a tip tracker behind one safe interface.

:class:`Rig` implements the loop protocol of :class:`controller.Plant` (``command``, ``advance``,
``measure``), so the controllers run on a real rig and on :class:`hardware.SimulatedRig` through the
same code.  What it adds to the devices:

* **Limits before commands.**  :meth:`Rig.command` checks travel, step, and (when given) the tensions the
  IK expects against :class:`~hardware.limits.SafetyLimits`; :meth:`Rig.set_pressure` checks the pressure.
  A violation raises :class:`~hardware.errors.LimitError`, sends nothing, and is recorded as an event.
* **Health checks.**  :meth:`Rig.check_health` reads every force sensor, the pressure and each drive's
  status and raises on a sensor timeout, a measured tension beyond the limit, a pressure out of band or a
  drive fault; :meth:`Rig.measure` raises :class:`~hardware.errors.TrackingLost` for an invalid pose and
  :class:`~hardware.errors.SensorTimeout` for a stale one.
* **Safe stop.**  :meth:`Rig.safe_stop` holds the drives (quick stop after a drive fault), holds or vents
  the pressure (``on_fault_pressure``), never raises, and records the reason.  A quick-stopped or faulted
  drive is never re-enabled by a safe stop (the halt is sent only to an OPERATION ENABLED drive).
  Leaving ``with rig:`` — normally, by an exception or by Ctrl-C — makes every device safe, **disables the
  drives** (:meth:`Rig.close`: CiA 402 shutdown 0x06 → READY TO SWITCH ON; a quick-stopped drive gets
  disable voltage 0x00 → SWITCH ON DISABLED; a faulted drive stays in FAULT) and closes every device.

Events (limit violations, faults, stops) go to ``rig.events`` and to every listener in ``rig.listeners``
(a run log registers itself there).
"""

from __future__ import annotations

import time
from typing import Callable, Optional, Sequence

import numpy as np

from .errors import DriveFault, HardwareError, LimitError, SensorTimeout, TrackingLost
from .interfaces import ForceSensor, PressureSupply, TendonDrive, TipTracker, TrackedPose
from .limits import SafetyLimits


class Clock:
    """Wall clock of a real rig: monotonic seconds and sleeping."""

    def now(self) -> float:
        return time.monotonic()

    def sleep(self, dt: float) -> None:
        if dt > 0:
            time.sleep(dt)


class Rig:
    """A set of devices with limits, health checks and a safe stop.

    Parameters
    ----------
    drives : (m,) tendon drives, in the actuator's tendon order
    force_sensors : (m,) force sensors (or an empty sequence: no tension measurement)
    pressure : the pressure supply
    tracker : the tip tracker
    limits : :class:`SafetyLimits`
    on_fault_pressure : "hold" (keep the air in) or "vent" after a fault
    settle_time : wait after a move before a measurement counts [s]
    move_timeout : extra time a move may take beyond distance / speed before it is a fault [s]
    speed : tendon speed the drives are asked for [m/s] (≤ limits.speed_max)
    """

    simulated = False

    def __init__(self, drives: Sequence[TendonDrive], force_sensors: Sequence[ForceSensor],
                 pressure: PressureSupply, tracker: TipTracker, *, limits: SafetyLimits = SafetyLimits(),
                 on_fault_pressure: str = "hold", settle_time: float = 0.0, move_timeout: float = 2.0,
                 speed: Optional[float] = None, clock: Optional[Clock] = None, name: str = "rig",
                 config: Optional[dict] = None, params=None):
        if not drives:
            raise LimitError("a rig needs at least one tendon drive")
        if force_sensors and len(force_sensors) != len(drives):
            raise LimitError(f"{len(force_sensors)} force sensors for {len(drives)} drives")
        if on_fault_pressure not in ("hold", "vent"):
            raise LimitError(f"on_fault_pressure must be 'hold' or 'vent', got {on_fault_pressure!r}")
        self.drives = list(drives)
        self.force_sensors = list(force_sensors)
        self.pressure_supply = pressure
        self.tracker = tracker
        self.limits = limits
        pressure.on_fault = on_fault_pressure
        self.on_fault_pressure = on_fault_pressure
        self.settle_time = float(settle_time)
        self.move_timeout = float(move_timeout)
        self.speed = limits.check_speed(speed if speed is not None else limits.speed_max)
        self.clock = clock or Clock()
        self.name = name
        self.config = config or {}
        self.params = params
        self.events: list = []
        self.listeners: list[Callable[[float, str, str], None]] = []
        self.commanded: Optional[np.ndarray] = None
        self._open = False
        self._last_pose: Optional[TrackedPose] = None

    # ------------------------------------------------------------------------------------ lifecycle
    @property
    def m(self) -> int:
        return len(self.drives)

    def devices(self) -> list:
        return [*self.drives, *self.force_sensors, self.pressure_supply, self.tracker]

    def open(self) -> None:
        if self._open:
            return
        opened = []
        try:
            for d in self.devices():
                d.open()
                opened.append(d)
            for d in self.drives:
                d.enable()
            for d in self.drives:                     # cyclic traffic (a bus's SYNC) once every drive is enabled
                d.start()
        except BaseException:
            for d in reversed(opened):
                d.make_safe()
                if d in self.drives:
                    try:
                        d.disable()
                    except Exception:                 # noqa: BLE001 - the original error is the one to raise
                        pass
                d.close()
            raise
        self._open = True
        self.event("open", f"{self.name}: {self.m} drives enabled")

    def close(self) -> None:
        if not self._open:
            return
        self.safe_stop("rig closed", quiet=True)
        for d in self.drives:                         # closing disables the drives (a stopped one stays stopped)
            try:
                d.disable()
            except Exception as exc:                  # noqa: BLE001 - closing must reach every device
                self.event("warning", f"disabling {d.name}: {exc}")
        for d in reversed(self.devices()):
            try:
                d.close()
            except Exception as exc:                  # noqa: BLE001 - closing must reach every device
                self.event("warning", f"closing {d.name}: {exc}")
        self._open = False

    def __enter__(self):
        self.open()
        return self

    def __exit__(self, exc_type, exc, tb):
        if exc_type is not None and self._open:
            self.safe_stop(f"{exc_type.__name__}: {exc}" if exc else exc_type.__name__,
                           quick=issubclass(exc_type, DriveFault))
        self.close()
        return False

    # ------------------------------------------------------------------------------------ events
    def event(self, kind: str, message: str) -> None:
        t = self.clock.now()
        self.events.append((t, kind, message))
        for cb in list(self.listeners):
            cb(t, kind, message)

    # ------------------------------------------------------------------------------------ commands
    def positions(self) -> np.ndarray:
        """Actual tendon lengths (m,) [m]."""
        return np.array([d.position() for d in self.drives])

    def command(self, lengths, expected_tensions=None) -> float:
        """Check, then send tendon lengths (m,) [m].  Returns the expected move time [s].

        ``expected_tensions`` (m,) [N] (the controller's IK tensions) are checked against the tension limit
        too.  Any violation raises LimitError and sends nothing."""
        try:
            cur = self.commanded if self.commanded is not None else self.positions()
            a = self.limits.check_lengths(lengths, cur, self.m)
            if expected_tensions is not None:
                self.limits.check_tensions(expected_tensions, what="expected")
        except LimitError as exc:
            self.event("limit", str(exc))
            raise
        for d, li in zip(self.drives, a):
            d.move_to(float(li))
        self.commanded = a.copy()
        return float(np.max(np.abs(a - cur))) / self.speed

    def set_pressure(self, pressure: float) -> None:
        try:
            p = self.limits.check_pressure_command(pressure)
        except LimitError as exc:
            self.event("limit", str(exc))
            raise
        self.pressure_supply.set(p)
        self.event("pressure", f"set {p / 1e3:.3f} kPa")

    def advance(self, dt: Optional[float] = None) -> None:
        """Wait ``dt`` seconds, or (None) until every drive reports its target reached plus the settle time.
        A move that takes longer than distance / speed + ``move_timeout`` is a DriveFault."""
        if dt is not None:
            self.clock.sleep(float(dt))
            return
        t0 = self.clock.now()
        cur = self.positions()
        budget = (0.0 if self.commanded is None else float(np.max(np.abs(self.commanded - cur))) / self.speed)
        deadline = t0 + budget + self.move_timeout
        while not all(d.target_reached() for d in self.drives):
            for d in self.drives:
                d.check()
            if self.clock.now() > deadline:
                raise DriveFault(f"drives did not reach their targets within {budget + self.move_timeout:.2f} s",
                                 device=self.name)
            self.clock.sleep(min(0.01, max(budget, 1e-3)))
        if self.settle_time > 0:
            self.clock.sleep(self.settle_time)

    # ------------------------------------------------------------------------------------ readings
    def read_pose(self) -> TrackedPose:
        pose = self.tracker.read()
        self._last_pose = pose
        return pose

    def measure(self, frames: int = 1) -> np.ndarray:
        """Tip position (3,) [m] from a valid, fresh tracker frame — the mean of ``frames`` distinct frames
        (tracker noise / √frames) — else TrackingLost / SensorTimeout."""
        if frames == 1:
            return self._measure_one()
        tips, seen, t0 = [], set(), self.clock.now()
        while len(tips) < frames:
            tip = self._measure_one()
            if self._last_pose.frame not in seen:
                seen.add(self._last_pose.frame)
                tips.append(tip)
            elif self.clock.now() - t0 > self.limits.sensor_timeout:
                exc = SensorTimeout(f"tracker gave {len(tips)} distinct frames of {frames} within "
                                    f"{self.limits.sensor_timeout:g} s", device=self.tracker.name)
                self.event("fault", exc.reason)
                raise exc
            else:
                self.clock.sleep(0.002)
        return np.mean(tips, axis=0)

    def _measure_one(self) -> np.ndarray:
        pose = self.read_pose()
        if not pose.valid or not np.all(np.isfinite(pose.position)):
            exc = TrackingLost(f"no valid tip pose (frame {pose.frame})", device=self.tracker.name)
            self.event("fault", exc.reason)
            raise exc
        age = self.clock.now() - pose.time
        if age > self.limits.sensor_timeout:
            exc = SensorTimeout(f"tip pose is {age:.3f} s old (timeout {self.limits.sensor_timeout:g} s)",
                                device=self.tracker.name)
            self.event("fault", exc.reason)
            raise exc
        return np.asarray(pose.position, float).copy()

    def read_tensions(self) -> np.ndarray:
        """Measured tensions (m,) [N] (NaN without force sensors)."""
        if not self.force_sensors:
            return np.full(self.m, np.nan)
        return np.array([s.read() for s in self.force_sensors])

    def read_pressure(self) -> float:
        return float(self.pressure_supply.read())

    def check_health(self) -> dict:
        """Read everything once and raise on a fault (see the module docstring).  Returns the readings
        ``{"tensions": (m,) N, "pressure": Pa, "positions": (m,) m, "currents": (m,) A}``."""
        try:
            for d in self.drives:
                d.check()
            T = self.read_tensions()
            if self.force_sensors:
                self.limits.check_tensions(T, what="measured")
            p = self.read_pressure()
            self.limits.check_pressure_reading(p, self.pressure_supply.setpoint)
            return {"tensions": T, "pressure": p, "positions": self.positions(),
                    "currents": np.array([d.current() for d in self.drives])}
        except HardwareError as exc:
            self.event("fault", f"{type(exc).__name__}: {exc}")
            raise

    # ------------------------------------------------------------------------------------ stop
    def safe_stop(self, reason: str, *, quick: bool = False, quiet: bool = False) -> list:
        """Stop motion (hold, or quick stop), hold or vent the pressure; never raises.  Returns problems."""
        problems = []
        for d in self.drives:
            if quick:
                try:
                    d.quick_stop()
                except Exception as exc:              # noqa: BLE001
                    problems.append(f"{d.name}: quick stop failed ({exc})")
            else:
                problems += d.make_safe()
        problems += self.pressure_supply.make_safe()
        if not quiet or problems:
            self.event("stop", f"{reason}; drives {'quick-stopped' if quick else 'holding'}, pressure "
                               f"{'vented' if self.on_fault_pressure == 'vent' else 'held'}"
                       + (f"; problems: {'; '.join(problems)}" if problems else ""))
        return problems

    def recover(self, reason: str = "") -> list:
        """After a drive fault, and only when a person has confirmed it: bring every stopped or faulted drive back
        to enabled **where it stands** (:meth:`TendonDrive.recover`; a cyclic EPOS4 from its actual position, its
        set-point frozen there — no jump), restart cyclic traffic, and forget the last command (the next one is
        checked against the drives' actual positions).  Nothing moves until the next :meth:`command`.  Returns the
        names of the drives it touched; a drive that does not come back raises :class:`DriveFault` (the rig
        stays stopped)."""
        touched = [d.name for d in self.drives if d.recover()]
        for d in self.drives:
            d.start()
        for d in self.drives:
            d.check()
        self.commanded = None
        self.event("recovered", f"drives {', '.join(touched) or 'none'} reset and enabled where they stand"
                   + (f" ({reason})" if reason else ""))
        return touched

    def describe(self) -> dict:
        """JSON-friendly description (for run logs)."""
        return {"name": self.name, "simulated": self.simulated, "tendons": self.m,
                "drives": [type(d).__name__ for d in self.drives],
                "force_sensors": [type(s).__name__ for s in self.force_sensors],
                "pressure": type(self.pressure_supply).__name__, "tracker": type(self.tracker).__name__,
                "limits": self.limits.to_dict(), "on_fault_pressure": self.on_fault_pressure,
                "speed_m_per_s": self.speed, "settle_time_s": self.settle_time, "config": self.config}

