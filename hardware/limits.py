"""Safety limits, checked *before* any command leaves the process.

A :class:`SafetyLimits` object holds the rig's hard limits (SI units):

==========================  =======  ==============================================================
field                       unit     meaning
==========================  =======  ==============================================================
``length_min``/``length_max`` m      tendon travel: the shortest / longest commanded tendon length
``max_step``                m        largest change of one tendon length in one command
``speed_max``               m/s      largest tendon speed a drive may be asked for
``tension_max``             N        largest tendon tension (expected by the IK, or measured)
``tension_min``             N        smallest expected tension (≤ 0 disables the check)
``pressure_max``            Pa       largest chamber pressure that may be commanded or measured
``pressure_band``           Pa       allowed |p_measured − p_set| once the supply has settled
``sensor_timeout``          s        oldest reading a sensor or the tracker may return
==========================  =======  ==============================================================

Each ``check_*`` returns the validated value as floats or raises :class:`~hardware.errors.LimitError`
(for a measured pressure out of band: :class:`~hardware.errors.PressureFault`).  A non-numeric or
non-finite command is refused the same way — nothing that is not a finite number in range is sent.
The defaults are the paper's rig: 0–30 N force sensors, a 160 kPa pump.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Optional

import numpy as np

from .errors import LimitError, PressureFault


def _as_vector(name: str, value, n: Optional[int]) -> np.ndarray:
    try:
        a = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise LimitError(f"{name} must be numbers, got {value!r}: refused") from None
    if a.ndim == 0:
        a = a.reshape(1)
    if a.ndim != 1 or (n is not None and a.shape[0] != n):
        raise LimitError(f"{name} must have shape ({n},), got {a.shape}: refused")
    if not np.all(np.isfinite(a)):
        raise LimitError(f"{name} contains NaN or inf ({a.tolist()}): refused")
    return a


def _worst(mask: np.ndarray, excess: np.ndarray) -> Optional[int]:
    """Index of the worst violation (largest ``excess`` where ``mask``), or None."""
    return int(np.argmax(np.where(mask, excess, -np.inf))) if np.any(mask) else None


def _as_scalar(name: str, value) -> float:
    if isinstance(value, (bool, str, bytes)) or value is None:
        raise LimitError(f"{name} must be a number, got {value!r}: refused")
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise LimitError(f"{name} must be a number, got {value!r}: refused") from None
    if not math.isfinite(v):
        raise LimitError(f"{name} must be finite, got {v}: refused")
    return v


@dataclass(frozen=True)
class SafetyLimits:
    """Hard limits of a rig (SI; see the module docstring).  Invalid limits raise LimitError."""
    length_min: float = 0.0
    length_max: float = 1.0
    max_step: float = 0.02
    speed_max: float = 0.05
    tension_max: float = 30.0
    tension_min: float = 0.0
    pressure_max: float = 160e3
    pressure_band: float = 10e3
    sensor_timeout: float = 0.5

    def __post_init__(self):
        for f in fields(self):
            object.__setattr__(self, f.name, _as_scalar(f"limit {f.name}", getattr(self, f.name)))
        if not (0 <= self.length_min < self.length_max):
            raise LimitError(f"limits: need 0 <= length_min < length_max, got {self.length_min}, {self.length_max} m")
        for nm in ("max_step", "speed_max", "tension_max", "pressure_max", "pressure_band", "sensor_timeout"):
            if not getattr(self, nm) > 0:
                raise LimitError(f"limits: {nm} must be > 0, got {getattr(self, nm)}")
        if self.tension_min >= self.tension_max:
            raise LimitError("limits: tension_min must be below tension_max")

    @classmethod
    def around(cls, length: float, **changes) -> "SafetyLimits":
        """Limits for an actuator of free length ``length`` [m]: travel 0.6 … 1.4 × length."""
        L = _as_scalar("length", length)
        if not L > 0:
            raise LimitError(f"actuator length must be > 0 m, got {L}")
        return cls(**{"length_min": 0.6 * L, "length_max": 1.4 * L, **changes})

    # ------------------------------------------------------------------------------------ commands
    def check_lengths(self, lengths, current=None, n: Optional[int] = None) -> np.ndarray:
        """Tendon lengths (n,) [m] inside the travel, and at most ``max_step`` from ``current`` (n,) [m]."""
        a = _as_vector("tendon length command", lengths, n)
        lo, hi = a < self.length_min, a > self.length_max
        if np.any(lo | hi):
            i = int(np.argmax(lo | hi))
            raise LimitError(f"tendon {i + 1} length {a[i] * 1e3:.3f} mm is outside the travel "
                             f"[{self.length_min * 1e3:.3f}, {self.length_max * 1e3:.3f}] mm: nothing sent")
        if current is not None:
            c = _as_vector("current tendon lengths", current, a.shape[0])
            step = np.abs(a - c)
            i = _worst(step > self.max_step, step)
            if i is not None:
                raise LimitError(f"tendon {i + 1} step {step[i] * 1e3:.3f} mm exceeds the largest step "
                                 f"{self.max_step * 1e3:.3f} mm per command: nothing sent")
        return a

    def check_speed(self, speed) -> float:
        v = _as_scalar("tendon speed", speed)
        if not (0 < v <= self.speed_max):
            raise LimitError(f"tendon speed {v * 1e3:.3f} mm/s is outside (0, {self.speed_max * 1e3:.3f}] mm/s")
        return v

    def check_tensions(self, tensions, *, what: str = "expected") -> np.ndarray:
        """Tensions (n,) [N] within [tension_min, tension_max] (min only for expected tensions)."""
        T = _as_vector(f"{what} tensions", tensions, None)
        i = _worst(T > self.tension_max, T)
        if i is not None:
            raise LimitError(f"{what} tension of tendon {i + 1} {T[i]:.3f} N exceeds the limit "
                             f"{self.tension_max:.3f} N")
        i = _worst((T < self.tension_min) & (what == "expected" and self.tension_min > 0), -T)
        if i is not None:
            raise LimitError(f"expected tension of tendon {i + 1} {T[i]:.3f} N is below the minimum "
                             f"{self.tension_min:.3f} N (slack tendon)")
        return T

    def check_pressure_command(self, pressure) -> float:
        p = _as_scalar("pressure command", pressure)
        if not (0 <= p <= self.pressure_max):
            raise LimitError(f"pressure command {p / 1e3:.3f} kPa is outside [0, {self.pressure_max / 1e3:.3f}] kPa: "
                             f"nothing sent")
        return p

    def check_pressure_reading(self, measured, setpoint: Optional[float]) -> float:
        """A measured pressure [Pa]: beyond ``pressure_max`` or outside ``setpoint ± pressure_band`` is a
        :class:`PressureFault`."""
        p = _as_scalar("measured pressure", measured)
        if p > self.pressure_max:
            raise PressureFault(f"measured pressure {p / 1e3:.3f} kPa exceeds the limit {self.pressure_max / 1e3:.3f} kPa")
        if setpoint is not None and abs(p - setpoint) > self.pressure_band:
            raise PressureFault(f"measured pressure {p / 1e3:.3f} kPa is more than {self.pressure_band / 1e3:.3f} kPa "
                                f"from the set point {setpoint / 1e3:.3f} kPa")
        return p

    def to_dict(self) -> dict:
        return {f.name: getattr(self, f.name) for f in fields(self)}
