"""Typed errors of the rig layer.

::

    ancf.errors.BellowsError
    ├── ConfigError
    │   └── RigConfigError          a rig TOML file is malformed (unknown key, missing unit, bad value)
    └── HardwareError               something on (or about) the rig went wrong
        ├── LimitError              a command would leave the safety limits: nothing was sent
        ├── DriveFault              a tendon drive reports a fault (statusword fault bit, EMCY, following error)
        ├── SensorTimeout           a sensor gave no (fresh) reading within its timeout
        ├── TrackingLost            the tip tracker reports no valid pose
        ├── PressureFault           the chamber pressure left its band (overshoot, supply lost)
        ├── CommunicationError      a transport failed (CAN, serial, UDP) or a reply was malformed
        └── RunAborted              a run was stopped on purpose (Ctrl-C); the rig was made safe

Every :class:`HardwareError` may carry ``reason`` (one line, for the run log) and ``device`` (its name).
"""

from __future__ import annotations

from typing import Optional

from ancf.errors import ConfigError, HardwareError

__all__ = ["HardwareError", "LimitError", "DriveFault", "SensorTimeout", "TrackingLost", "PressureFault",
           "CommunicationError", "RunAborted", "RigConfigError"]


class _Detailed(HardwareError):
    def __init__(self, message: str, *, device: Optional[str] = None):
        self.device = device
        super().__init__(f"{device}: {message}" if device else message)

    @property
    def reason(self) -> str:
        return f"{type(self).__name__}: {self}"


class LimitError(_Detailed):
    """A command would leave a safety limit (tension, pressure, travel, step or speed): nothing was sent."""


class DriveFault(_Detailed):
    """A drive reports a fault; ``code`` is the device's error code (e.g. EPOS4 0x603F / EMCY), if known."""

    def __init__(self, message: str, *, device: Optional[str] = None, code: Optional[int] = None):
        self.code = code
        super().__init__(message if code is None else f"{message} (error code 0x{code:04X})", device=device)


class SensorTimeout(_Detailed):
    """A sensor gave no fresh reading within its timeout."""


class TrackingLost(_Detailed):
    """The tip tracker has no valid pose (marker occluded, quality too low, stale frame)."""


class PressureFault(_Detailed):
    """The chamber pressure left its allowed band (overshoot beyond the limit, or the supply cannot hold it)."""


class CommunicationError(_Detailed):
    """A transport failed or a device replied with something that is not its protocol."""


class RunAborted(_Detailed):
    """The run was interrupted on purpose (Ctrl-C); the rig was made safe and the log closed."""


class RigConfigError(ConfigError):
    """A rig description (TOML) is invalid."""
