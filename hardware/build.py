"""Build a rig from its configuration: the one module that knows both the rig file
(:class:`hardware.config.RigConfig`) and the rig classes (:class:`hardware.rig.Rig`, the simulated rig and the
device backends).  Neither ``config`` nor ``rig`` imports the other: a rig is built here, e.g.
``build_rig(RigConfig.from_toml("rig.toml"))``.  The hardware backends are imported only when a hardware rig
is built (``canopen``, ``pyserial``).
"""

from __future__ import annotations

import math

from .config import RigConfig
from .errors import RigConfigError
from .rig import Rig
from .simulated import PlantOptions, SimulatedRig

__all__ = ["build_rig"]


def build_rig(cfg: RigConfig, **sim_overrides):
    """The rig a config describes.  ``sim_overrides`` (load=, options fields) apply to a simulated rig."""
    if not isinstance(cfg, RigConfig):
        raise RigConfigError(f"build_rig needs a RigConfig, got {type(cfg).__name__}")
    limits = cfg.safety_limits()
    if cfg.backend == "sim":
        s = cfg.simulation
        opts = {"seed": s.get("seed", 0), "noise_std": s.get("tracker_noise", 0.0),
                "tracker_latency": s.get("tracker_latency", 0.0), "force_noise_std": s.get("force_noise", 0.0),
                "pressure_noise_std": s.get("pressure_noise", 0.0),
                "length_resolution": s.get("length_resolution", 0.0),
                "length_rate": s.get("length_rate", math.inf), "tendon_friction": s.get("tendon_friction", 0.0),
                "tendon_stiffness": s.get("tendon_stiffness", math.inf)}
        if "plant_actuator" in s:
            opts["params"] = cfg.actuator_params("plant_actuator")
        load = sim_overrides.pop("load", (0.0, 0.0, 0.0))
        opts.update(sim_overrides)
        return SimulatedRig(cfg.actuator_params(), 0.0, load=load, options=PlantOptions(**opts), limits=limits,
                            on_fault_pressure=cfg.on_fault_pressure, name=cfg.name, config=cfg.to_dict())
    from .canbus import CanBus
    from .epos4_cyclic import Epos4CyclicDrive
    from .epos4_profile import Epos4ProfileDrive
    from .serial_devices import SerialForceSensor, SerialPressureSupply
    from .tracking import NatNetTracker
    buses: dict = {}                                      # one CanBus (socket, SYNC, host heartbeat) per bus
    drives = []
    for d in cfg.drives:
        key = (d.get("interface", "socketcan"), d["channel"])
        if key not in buses:
            buses[key] = CanBus(key[0], key[1], d.get("bitrate", 1_000_000))
        common = dict(bus=buses[key], counts_per_metre=d["counts"], zero_length=d["zero_length"], limits=limits,
                      speed=cfg.speed if cfg.speed is not None else limits.speed_max,
                      acceleration=cfg.acceleration, counts_per_turn=d["counts_per_turn"])
        if d.get("cyclic", False):
            cyc = {k: d[k] for k in ("sync_period", "heartbeat_timeout", "following_error_window") if k in d}
            drives.append(Epos4CyclicDrive(d["node_id"], **common, **cyc))
        else:
            drives.append(Epos4ProfileDrive(d["node_id"], **common))
    forces = [SerialForceSensor(d["port"], channel=d["channel"], baudrate=d.get("baudrate", 115200),
                                scale=d.get("scale", 1.0), offset=d.get("offset", 0.0),
                                timeout=limits.sensor_timeout) for d in cfg.force_sensors]
    pressure = SerialPressureSupply(cfg.pressure["port"], baudrate=cfg.pressure.get("baudrate", 115200),
                                    timeout=limits.sensor_timeout)
    t = cfg.tracker
    tracker = NatNetTracker(address=t.get("address", "0.0.0.0"), port=t.get("port", 1511),
                            rigid_body_id=t.get("rigid_body_id", 1), offset=t.get("offset", (0.0, 0.0, 0.0)),
                            rotation=t.get("rotation"), multicast_group=t.get("multicast_group"),
                            timeout=t.get("timeout", limits.sensor_timeout), max_error=t.get("max_error", 2e-3),
                            natnet_version=t.get("natnet_version", "3.0"))
    return Rig(drives, forces, pressure, tracker, limits=limits, on_fault_pressure=cfg.on_fault_pressure,
               settle_time=cfg.settle_time, speed=cfg.speed, name=cfg.name, config=cfg.to_dict(),
               params=cfg.actuator_params())
