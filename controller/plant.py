"""What the control loops need from a rig, simulated or real: the :class:`Plant` protocol.

The one simulated rig is :class:`hardware.SimulatedRig` (locked FK with a hidden load, sensor noise,
latency, motor limits, model mismatch).  ``controller.SimulatedPlant`` and ``controller.PlantOptions``
are the same objects, imported from :mod:`hardware.simulated` on first use (``controller`` does not
import ``hardware`` when it is imported, so the two packages have no import cycle).
"""

from __future__ import annotations

from typing import Optional, Protocol, runtime_checkable

import numpy as np


@runtime_checkable
class Plant(Protocol):
    """What the loops need from a rig (simulated or real): SI units, seconds."""

    def command(self, lengths) -> float:
        """Send tendon lengths (m,) [m]; return the expected move duration [s]."""

    def advance(self, dt: Optional[float] = None) -> None:
        """Let time pass (None: until the last command is executed)."""

    def measure(self) -> np.ndarray:
        """Measured tip position (3,) [m]."""


def __getattr__(name):
    if name in ("SimulatedPlant", "PlantOptions"):
        from hardware import simulated
        return simulated.SimulatedRig if name == "SimulatedPlant" else simulated.PlantOptions
    raise AttributeError(name)
