"""Rig layer: device interfaces, the simulated rig, real drivers, safety limits, run logs, and the
static-states file format (:mod:`hardware.static_states`; docs/rig.md, docs/data-formats.md).

::

    from hardware import Rig, SimulatedRig, RigConfig, HardwareError, LimitError, DriveFault
    rig = SimulatedRig(presets.paper(), load=(0, 0, -0.4), seed=0)      # or build_rig(RigConfig.from_toml(...))

Submodules are imported on first use (``hardware.epos4`` needs ``canopen``; serial devices need
``pyserial``): importing ``hardware`` itself is cheap.
"""

from __future__ import annotations

from .errors import (CommunicationError, DriveFault, HardwareError, LimitError, PressureFault, RigConfigError,
                     RunAborted, SensorTimeout, TrackingLost)

__all__ = ["Rig", "SimulatedRig", "build_rig", "PlantOptions", "RigConfig", "SafetyLimits", "RunLog", "HardwareError",
           "LimitError", "DriveFault", "SensorTimeout", "TrackingLost", "PressureFault", "CommunicationError",
           "RunAborted", "RigConfigError", "TrackedPose"]

_LAZY = {"Rig": "rig", "build_rig": "build", "SimulatedRig": "simulated", "PlantOptions": "simulated", "RigConfig": "config",
         "SafetyLimits": "limits", "RunLog": "runlog", "TrackedPose": "interfaces"}


def __getattr__(name):
    if name in _LAZY:
        import importlib
        return getattr(importlib.import_module(f".{_LAZY[name]}", __name__), name)
    raise AttributeError(f"module 'hardware' has no attribute {name!r}")
