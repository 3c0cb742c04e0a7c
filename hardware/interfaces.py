"""Device interfaces of the rig (SI units throughout: m, N, Pa, s).

Every device is a context manager: ``__enter__`` opens it, ``__exit__`` *always* leaves it safe
(:meth:`Device.make_safe`) and closes it — on a normal exit, on an exception and on Ctrl-C
(``KeyboardInterrupt`` passes through ``__exit__`` like any exception).  ``make_safe`` never raises: it is
called when something has already gone wrong; what it could not do is returned as a list of messages.

=================  ====================================================================================
interface          what a backend implements
=================  ====================================================================================
TendonDrive        enable, start (cyclic traffic, once every drive is enabled), move_to(length [m]),
                   position [m], current [A], target_reached, hold, quick_stop, disable, fault_reset,
                   recover, check (raises DriveFault); hold and disable never re-enable a
                   quick-stopped or faulted drive
ForceSensor        read() → tension [N]  (raises SensorTimeout)
PressureSupply     set(p [Pa]), read() → p [Pa], hold(), vent()
TipTracker         read() → :class:`TrackedPose` (timestamp, frame number, position [m], validity)
=================  ====================================================================================
"""

from __future__ import annotations

import abc
from dataclasses import dataclass
from typing import Optional

import numpy as np


class Device(abc.ABC):
    """Base of every device: a name, open/close, and a safe state."""

    name: str = "device"

    def open(self) -> None:
        """Connect (idempotent)."""

    def close(self) -> None:
        """Disconnect (idempotent; the device is made safe first by ``__exit__``)."""

    def make_safe(self) -> list:
        """Put the device in its safe state; never raises.  Returns messages about what failed."""
        return []

    def __enter__(self):
        self.open()
        return self

    def __exit__(self, exc_type, exc, tb):
        try:
            self.make_safe()
        finally:
            self.close()
        return False


class TendonDrive(Device):
    """A position-controlled tendon motor: lengths in metres along the tendon."""

    @abc.abstractmethod
    def enable(self) -> None: ...

    def start(self) -> None:
        """Begin cyclic operation; called once every drive of the rig is enabled (e.g. a bus's SYNC starts only
        when all its drives are enabled).  Nothing to do for a drive without cyclic traffic."""

    @abc.abstractmethod
    def move_to(self, length: float) -> None:
        """Start a move to the tendon length [m] (returns at once; see :meth:`target_reached`)."""

    @abc.abstractmethod
    def position(self) -> float:
        """Actual tendon length [m]."""

    def current(self) -> float:
        """Motor current [A] (NaN if the backend cannot read it)."""
        return float("nan")

    @abc.abstractmethod
    def target_reached(self) -> bool: ...

    @abc.abstractmethod
    def hold(self) -> None:
        """Stop where it is and hold position (locked at zero velocity)."""

    @abc.abstractmethod
    def quick_stop(self) -> None: ...

    def disable(self) -> None:
        """Power stage off (the rig closes with its drives disabled).  Never re-enables a stopped drive."""

    @abc.abstractmethod
    def fault_reset(self) -> None: ...

    def recover(self) -> bool:
        """Bring a stopped or faulted drive back to enabled **where it stands** (it moves again only on the next
        :meth:`move_to`); an enabled drive is left alone.  Only for a person who has confirmed it
        (:meth:`hardware.Rig.recover`).  Returns whether the drive needed it.  Default: reset the fault, enable."""
        self.fault_reset()
        self.enable()
        return True

    @abc.abstractmethod
    def check(self) -> None:
        """Raise :class:`~hardware.errors.DriveFault` if the drive reports a fault."""

    def make_safe(self) -> list:
        try:
            self.hold()
            return []
        except Exception as exc:                      # noqa: BLE001 - make_safe must not raise
            try:
                self.quick_stop()
                return [f"{self.name}: hold failed ({exc}); quick stop sent"]
            except Exception as exc2:                 # noqa: BLE001
                return [f"{self.name}: hold failed ({exc}) and quick stop failed ({exc2})"]


class ForceSensor(Device):
    @abc.abstractmethod
    def read(self) -> float:
        """Tendon tension [N]; raises SensorTimeout without a fresh reading."""


class PressureSupply(Device):
    """Chamber pressure control: a valve set (or regulator) and a pressure sensor."""

    on_fault: str = "hold"            # "hold" | "vent": what make_safe does

    @abc.abstractmethod
    def set(self, pressure: float) -> None: ...

    @abc.abstractmethod
    def read(self) -> float: ...

    @abc.abstractmethod
    def hold(self) -> None:
        """Close the valves: keep the air that is in the chamber."""

    @abc.abstractmethod
    def vent(self) -> None:
        """Open the chamber to atmosphere."""

    @property
    def setpoint(self) -> Optional[float]:
        return getattr(self, "_setpoint", None)

    def make_safe(self) -> list:
        try:
            self.vent() if self.on_fault == "vent" else self.hold()
            return []
        except Exception as exc:                      # noqa: BLE001
            return [f"{self.name}: could not {self.on_fault} ({exc})"]


@dataclass(frozen=True)
class TrackedPose:
    """One tracker frame: host time [s] (monotonic clock of the rig), the tracker's frame number, the tip
    position (3,) [m] in the actuator's world frame, a validity flag and a quality (e.g. marker RMS [m])."""
    time: float
    frame: int
    position: np.ndarray
    valid: bool = True
    quality: float = 0.0
    rotation: Optional[np.ndarray] = None


class TipTracker(Device):
    @abc.abstractmethod
    def read(self) -> TrackedPose: ...
