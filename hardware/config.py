"""Rig description files (TOML): which backend drives each device, ports, node ids, unit conversions,
limits and calibration.  Units are part of the key names, as in actuator files (``tension_max_N``,
``pressure_max_kPa``, ``counts_per_mm``); a dimensioned key without a unit, an unknown unit, an unknown
key or a missing required key is a :class:`~hardware.errors.RigConfigError` naming the key.  So is a
setting that contradicts another one or that the rig would ignore (two SYNC periods on one CAN bus, a cyclic
setting on a profile-position drive, ``[simulation]`` in a hardware file, ...; docs/rig.md, "Conflicts and
plausibility"): the message names both keys as written.

A complete file (every key documented in docs/rig.md; the sections of both backends, so not one loadable rig)::

    name = "bench A"
    backend = "sim"                  # "sim" (SimulatedRig) | "hardware" (the device backends below)
    actuator = "paper"               # preset name, or an actuator TOML path (relative to this file)
    on_fault_pressure = "hold"       # "hold" | "vent"
    settle_time_s = 0.1
    speed_mm_per_s = 5               # tendon speed asked of the drives (<= limits.speed_max)
    acceleration_mm_per_s2 = 50      # tendon acceleration and deceleration asked of the drives (> 0)

    [limits]
    length_min_mm = 100
    length_max_mm = 220
    max_step_mm = 10
    speed_max_mm_per_s = 10
    tension_max_N = 30
    pressure_max_kPa = 160
    pressure_band_kPa = 10
    sensor_timeout_s = 0.5

    [simulation]                     # backend = "sim" only
    seed = 0
    plant_actuator = "paper"         # the plant's parameters (model mismatch), default = actuator
    tracker_noise_mm = 0.05
    tracker_latency_s = 0.0
    force_noise_N = 0.02
    pressure_noise_kPa = 0.1
    length_resolution_mm = 0.001
    length_rate_mm_per_s = 5
    tendon_friction_N = 0.1
    tendon_stiffness_N_per_mm = 20

    [[drives]]                       # backend = "hardware": one table per tendon, in tendon order
    backend = "epos4"
    node_id = 1
    interface = "socketcan"
    channel = "can0"
    bitrate = 1000000
    counts_per_mm = 2000.0           # encoder counts per mm of tendon length
    counts_per_turn = 4096           # encoder counts per motor revolution (required: the EPOS4 speaks rpm)
    zero_length_mm = 160.0           # tendon length at encoder count 0
    cyclic = true                    # cyclic synchronous position over PDO + SYNC (default false: profile position)
    sync_period_ms = 2               # cyclic only: SYNC / set-point period, one per bus (default 2 ms)
    heartbeat_timeout_ms = 500       # cyclic only: a drive silent this long is a fault, a silent host stops it
    following_error_window_mm = 1    # cyclic only: the drive faults when it lags its demand by more (default 1 mm)

    [[force_sensors]]
    backend = "serial"
    port = "/dev/ttyUSB0"
    baudrate = 115200
    channel = 1
    scale_N_per_count = 0.001
    offset_N = 0.0

    [pressure]
    backend = "serial"
    port = "/dev/ttyUSB1"
    baudrate = 115200

    [tracker]
    backend = "natnet"
    address = "0.0.0.0"
    port = 1511
    rigid_body_id = 1
    offset_mm = [0.0, 0.0, 0.0]      # p_actuator = rotation · p_tracker + offset
    rotation = [[0, 0, 1], [1, 0, 0], [0, 1, 0]]   # tracker (y up) → actuator axes; default identity
    max_error_mm = 2.0               # larger mean marker error: invalid pose
    natnet_version = "3.0"           # the stream's NatNet version ("3.0" … "4.0" one layout; "4.1"+ byte counts)
"""

from __future__ import annotations

import difflib
import math
import pathlib
from dataclasses import dataclass, field
from typing import Any, Optional

try:  # Python >= 3.11
    import tomllib
except ModuleNotFoundError:  # pragma: no cover
    import tomli as tomllib

from ancf.errors import ConfigError

from .errors import LimitError, RigConfigError
from .limits import SafetyLimits

# dimension -> {unit suffix: factor to SI}
DIMENSIONS = {
    "length": {"m": 1.0, "cm": 1e-2, "mm": 1e-3},
    "force": {"N": 1.0},
    "pressure": {"Pa": 1.0, "kPa": 1e3, "bar": 1e5},
    "time": {"s": 1.0, "ms": 1e-3},
    "speed": {"m_per_s": 1.0, "mm_per_s": 1e-3},
    "stiffness": {"N_per_m": 1.0, "N_per_mm": 1e3},
    "force_per_count": {"N_per_count": 1.0},
    "counts_per_length": {"per_m": 1.0, "per_mm": 1e3},
    "acceleration": {"m_per_s2": 1.0, "mm_per_s2": 1e-3},
}
INT, STR, BOOL, NUM, MATRIX3 = "int", "str", "bool", "num", "matrix3"

TOP = {"name": STR, "backend": STR, "actuator": STR, "on_fault_pressure": STR, "settle_time": "time",
       "speed": "speed", "acceleration": "acceleration"}
LIMITS = {"length_min": "length", "length_max": "length", "max_step": "length", "speed_max": "speed",
          "tension_max": "force", "tension_min": "force", "pressure_max": "pressure", "pressure_band": "pressure",
          "sensor_timeout": "time"}
SIMULATION = {"seed": INT, "plant_actuator": STR, "tracker_noise": "length", "tracker_latency": "time",
              "force_noise": "force", "pressure_noise": "pressure", "length_resolution": "length",
              "length_rate": "speed", "tendon_friction": "force", "tendon_stiffness": "stiffness"}
DRIVE = {"backend": STR, "node_id": INT, "interface": STR, "channel": STR, "bitrate": INT,
         "counts": "counts_per_length", "counts_per_turn": NUM, "zero_length": "length", "current_limit_A": NUM,
         "cyclic": BOOL, "sync_period": "time", "heartbeat_timeout": "time", "following_error_window": "length"}
FORCE = {"backend": STR, "port": STR, "baudrate": INT, "channel": INT, "scale": "force_per_count",
         "offset": "force"}
PRESSURE = {"backend": STR, "port": STR, "baudrate": INT}
TRACKER = {"backend": STR, "address": STR, "port": INT, "rigid_body_id": INT, "offset": "length",
           "rotation": MATRIX3, "multicast_group": STR, "timeout": "time", "max_error": "length",
           "natnet_version": STR}
#: CAN bitrates [bit/s] (CiA 301 bit timing table; the EPOS4 supports all of them)
CAN_BITRATES = (10_000, 20_000, 50_000, 125_000, 250_000, 500_000, 800_000, 1_000_000)
#: accepted encoder scale of a drive [counts per mm of tendon]: a resolution of 0.1 mm … 1 nm
COUNTS_PER_MM_RANGE = (10.0, 1e6)
#: channels of the serial load-cell board
FORCE_CHANNELS = 3
BACKENDS = {"drives": ("sim", "epos4"), "force_sensors": ("sim", "serial"), "pressure": ("sim", "serial"),
            "tracker": ("sim", "natnet")}
#: drive settings of cyclic synchronous position only: refused on a drive without ``cyclic = true``
CYCLIC_ONLY = ("sync_period", "heartbeat_timeout", "following_error_window")
#: node id of the host's own heartbeat on a bus with cyclic drives (COB-ID 0x700 + 127 = 0x77F; the drives consume
#: it): no drive on such a bus may use it (``hardware.canbus.MASTER_NODE_ID``)
HOST_HEARTBEAT_NODE = 127
#: period of the host's heartbeat [s] (``hardware.canbus.MASTER_HEARTBEAT_PERIOD``)
HOST_HEARTBEAT_PERIOD = 0.05
#: producer heartbeat time a cyclic drive is given [s] (``Epos4CyclicDrive(heartbeat_time=)``)
DRIVE_HEARTBEAT_TIME = 0.05
#: SYNC period of a cyclic drive whose rig file gives none [s] (the builder's and ``Epos4CyclicDrive``'s default;
#: used here only to compare drives on one bus, never stored in the parsed table)
SYNC_PERIOD_DEFAULT = 0.002
#: accepted SYNC period [s]
SYNC_PERIOD_RANGE = (1e-4, 0.1)
#: largest heartbeat timeout [ms]: the drive's consumer heartbeat time 0x1016 is 16 bits of ms
HEARTBEAT_TIMEOUT_MAX_MS = 0xFFFF
#: data bytes of the frames one cyclic drive adds to every SYNC cycle (``hardware.epos4_cyclic``): RPDO 1 (target
#: position), TPDO 1 (statusword + position demand), TPDO 2 (position actual + current)
CYCLIC_PDO_BYTES = (4, 6, 8)
#: largest unsigned 32-bit value (profile velocity / acceleration, following error window; as a window it switches
#: the drive's following-error check off)
U32_MAX = 2 ** 32 - 1


def can_frame_bits(n_bytes: int) -> int:
    """Worst-case length [bit] of a CAN 2.0A (11-bit id) data frame with ``n_bytes`` data bytes, stuff bits
    included: 8n + 47 + ⌊(34 + 8n − 1) / 4⌋ (Davis, Burns, Bril, Lukkien 2007)."""
    return 8 * n_bytes + 47 + (34 + 8 * n_bytes - 1) // 4


def sync_period_problem(period: float) -> Optional[str]:
    """Why a SYNC period [s] cannot be used (None: it can): 0.1 … 100 ms, and a whole number of 0.1 ms (up to
    25.5 ms) or of ms — what the drive's interpolation time period 0x60C2 (value ≤ 255 · 10^index) can say."""
    lo, hi = SYNC_PERIOD_RANGE
    if not lo <= period <= hi:
        return f"{period * 1e3:g} ms is outside {lo * 1e3:g} … {hi * 1e3:g} ms"
    for unit in (1e-4, 1e-3):
        v = period / unit
        if abs(v - round(v)) < 1e-6 * max(1.0, v) and 1 <= round(v) <= 255:
            return None
    return (f"{period * 1e3:g} ms is not a whole number of 0.1 ms (up to 25.5 ms) or of ms: the drive's "
            f"interpolation time period 0x60C2 cannot say it")


def _spellings(spec: dict) -> dict:
    out = {}
    for f, kind in spec.items():
        if kind in DIMENSIONS:
            for u, fac in DIMENSIONS[kind].items():
                out[f"{f}_{u}"] = (f, kind, fac)
        else:
            out[f] = (f, kind, 1.0)
    return out


def _value(v: Any, kind: str, fac: float, where: str):
    if kind == MATRIX3:
        import numpy as np
        try:
            R = np.array(v, dtype=float)
        except (TypeError, ValueError):
            raise RigConfigError(f"{where}: expected a 3 × 3 matrix [[...], [...], [...]]") from None
        if R.shape != (3, 3) or not np.all(np.isfinite(R)):
            raise RigConfigError(f"{where}: expected a finite 3 × 3 matrix, got shape {R.shape}")
        if not np.allclose(R @ R.T, np.eye(3), atol=1e-6) or np.linalg.det(R) < 0:
            raise RigConfigError(f"{where}: not a rotation matrix (orthonormal, det +1)")
        return R.tolist()
    if kind == STR:
        if not isinstance(v, str):
            raise RigConfigError(f"{where}: expected text, got {v!r}")
        return v
    if kind == BOOL:
        if not isinstance(v, bool):
            raise RigConfigError(f"{where}: expected true/false, got {v!r}")
        return v
    if kind == INT:
        if isinstance(v, bool) or not isinstance(v, int):
            raise RigConfigError(f"{where}: expected an integer, got {v!r}")
        return v
    if isinstance(v, list):
        if not where.endswith(tuple(f".offset_{u}" for u in DIMENSIONS["length"])):
            raise RigConfigError(f"{where}: expected one number, got a list")
        if len(v) != 3:
            raise RigConfigError(f"{where}: expected 3 numbers [x, y, z], got {len(v)}")
        return [_value(x, kind, fac, where + "[]") for x in v]
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise RigConfigError(f"{where}: expected a number, got {v!r}")
    x = float(v) * fac
    if not math.isfinite(x):
        raise RigConfigError(f"{where}: must be finite, got {v!r}")
    return x


def parse_table(table: Any, spec: dict, where: str, spelled: Optional[dict] = None, prefix: str = "") -> dict:
    """``{key_with_unit: value}`` → ``{field: SI value}``; unknown keys and missing units are errors.
    ``spelled`` (optional) collects ``{"<prefix>.<field>": "<prefix>.<key as written>"}`` for messages."""
    if not isinstance(table, dict):
        raise RigConfigError(f"{where}: expected a table, got {type(table).__name__}")
    sp = _spellings(spec)
    out: dict = {}
    for key, v in table.items():
        if key in sp:
            f, kind, fac = sp[key]
            if f in out:
                raise RigConfigError(f"{where}: '{f}' given twice (e.g. in two units)")
            out[f] = _value(v, kind, fac, f"{where}.{key}")
            if spelled is not None:
                spelled[f"{prefix}.{f}" if prefix else f] = f"{prefix}.{key}" if prefix else key
        elif key in spec and spec[key] in DIMENSIONS:
            opts = ", ".join(f"{key}_{u}" for u in DIMENSIONS[spec[key]])
            raise RigConfigError(f"{where}: '{key}' needs an explicit unit; write one of: {opts}")
        else:
            close = difflib.get_close_matches(key, list(sp), n=3, cutoff=0.5)
            raise RigConfigError(f"{where}: unknown key '{key}'" + (f"; did you mean {', '.join(close)}?" if close else ""))
    return out


def _require(d: dict, keys, where: str) -> None:
    missing = [k for k in keys if k not in d]
    if missing:
        raise RigConfigError(f"{where}: missing {', '.join(missing)}")


@dataclass(frozen=True)
class RigConfig:
    """A parsed rig description (SI values; see the module docstring for the file)."""
    name: str = "rig"
    backend: str = "sim"
    actuator: str = "paper"
    on_fault_pressure: str = "hold"
    settle_time: float = 0.0
    speed: Optional[float] = None
    #: tendon acceleration and deceleration asked of the drives [m/s²] (None: the drives' default)
    acceleration: Optional[float] = None
    limits: dict = field(default_factory=dict)
    simulation: dict = field(default_factory=dict)
    drives: tuple = ()
    force_sensors: tuple = ()
    pressure: dict = field(default_factory=dict)
    tracker: dict = field(default_factory=dict)
    base_dir: str = "."
    #: ``{"drives[1].counts": "drives[1].counts_per_mm", "speed": "speed_mm_per_s"}``: the keys as written in the
    #: file (for messages)
    spelled: dict = field(default_factory=dict, compare=False, repr=False)

    # --------------------------------------------------------------------------------------- loading
    @classmethod
    def from_toml(cls, path) -> "RigConfig":
        p = pathlib.Path(path)
        try:
            text = p.read_text()
        except OSError as exc:
            raise RigConfigError(f"cannot read rig file {p}: {exc.strerror or exc}") from None
        return cls.from_toml_string(text, where=str(p), base_dir=str(p.parent))

    @classmethod
    def from_toml_string(cls, text: str, where: str = "<rig>", base_dir: str = ".") -> "RigConfig":
        if not isinstance(text, str):
            raise RigConfigError(f"{where}: rig description must be text")
        try:
            data = tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise RigConfigError(f"{where}: not valid TOML ({exc})") from None
        return cls.from_dict(data, where=where, base_dir=base_dir)

    @classmethod
    def from_dict(cls, data: dict, where: str = "<rig>", base_dir: str = ".") -> "RigConfig":
        if not isinstance(data, dict):
            raise RigConfigError(f"{where}: expected a table")
        data = dict(data)
        sections = {k: data.pop(k) for k in ("limits", "simulation", "drives", "force_sensors", "pressure", "tracker")
                    if k in data}
        spelled: dict = {}
        top = parse_table(data, TOP, where, spelled)
        backend = top.get("backend", "sim")
        if backend not in ("sim", "hardware"):
            raise RigConfigError(f"{where}.backend: 'sim' or 'hardware', got {backend!r}")
        ofp = top.get("on_fault_pressure", "hold")
        if ofp not in ("hold", "vent"):
            raise RigConfigError(f"{where}.on_fault_pressure: 'hold' or 'vent', got {ofp!r}")
        limits = parse_table(sections.get("limits", {}), LIMITS, f"{where}.limits", spelled, "limits")
        sim = parse_table(sections.get("simulation", {}), SIMULATION, f"{where}.simulation", spelled, "simulation")
        devs = {}
        for key, spec in (("drives", DRIVE), ("force_sensors", FORCE)):
            raw = sections.get(key, [])
            if not isinstance(raw, list):
                raise RigConfigError(f"{where}.{key}: expected an array of tables ([[{key}]])")
            devs[key] = tuple(parse_table(t, spec, f"{where}.{key}[{i}]", spelled, f"{key}[{i}]")
                              for i, t in enumerate(raw))
        for key, spec in (("pressure", PRESSURE), ("tracker", TRACKER)):
            devs[key] = parse_table(sections.get(key, {}), spec, f"{where}.{key}", spelled, key)
        cfg = cls(name=top.get("name", "rig"), backend=backend, actuator=top.get("actuator", "paper"),
                  on_fault_pressure=ofp, settle_time=top.get("settle_time", 0.0), speed=top.get("speed"),
                  acceleration=top.get("acceleration"), limits=limits, simulation=sim, base_dir=base_dir,
                  spelled=spelled, **devs)
        cfg._validate(where)
        return cfg

    def _validate(self, where: str) -> None:
        if self.settle_time < 0:
            raise RigConfigError(f"{where}.settle_time: must be >= 0 s")
        if self.acceleration is not None and not self.acceleration > 0:
            raise RigConfigError(f"{where}: {self._key('', 'acceleration')} ({self.acceleration * 1e3:g} mm/s²): must "
                                 f"be > 0 (the tendon acceleration and deceleration asked of the drives)")
        try:
            lim = self.safety_limits()
            if self.speed is not None:
                lim.check_speed(self.speed)
        except LimitError as exc:
            raise RigConfigError(f"{where}: {exc}") from None
        if self.backend == "sim":
            for k in ("drives", "force_sensors", "pressure", "tracker"):
                items = getattr(self, k)
                for i, d in enumerate(items if isinstance(items, tuple) else (items,)):
                    b = d.get("backend", "sim")
                    if b != "sim":
                        t = f"{k}[{i}]" if isinstance(items, tuple) else k
                        raise RigConfigError(f"{where}: {t}.backend = {b!r} in a backend = 'sim' rig file (a "
                                             f"simulated rig opens no device): set backend = 'hardware', or remove "
                                             f"the device table")
            return
        if self.simulation:
            raise RigConfigError(f"{where}: {self._key('simulation', next(iter(self.simulation)))} in a backend = "
                                 f"'hardware' rig file: [simulation] configures only the simulated rig (remove it, "
                                 f"or set backend = 'sim')")
        for key in ("drives", "force_sensors", "pressure", "tracker"):
            items = getattr(self, key)
            items = items if isinstance(items, tuple) else (items,)
            if not items or any(not d for d in items):
                raise RigConfigError(f"{where}: a hardware rig needs [{key}]" if key in ("pressure", "tracker")
                                     else f"{where}: a hardware rig needs [[{key}]] tables")
            for i, d in enumerate(items):
                b = d.get("backend")
                if b not in BACKENDS[key] or b == "sim":
                    raise RigConfigError(f"{where}.{key}[{i}].backend: one of {[x for x in BACKENDS[key] if x != 'sim']}, "
                                         f"got {b!r}")
        for i, d in enumerate(self.drives):
            _require(d, ("node_id", "channel", "counts", "zero_length"), f"{where}.drives[{i}]")
            if "counts_per_turn" not in d:                   # every drive is an EPOS4 here
                raise RigConfigError(
                    f"{where}: drives[{i}].counts_per_turn is missing (encoder counts per motor revolution; required "
                    f"for a backend = 'epos4' drive): the EPOS4 takes its profile velocity and acceleration in rpm "
                    f"of the motor shaft, so without it the rig file's tendon speed cannot be asked of the drive "
                    f"(it would keep the speed it has stored)")
        for i, d in enumerate(self.force_sensors):
            _require(d, ("port", "channel"), f"{where}.force_sensors[{i}]")
        _require(self.pressure, ("port",), f"{where}.pressure")
        if not isinstance(self.tracker.get("offset", [0, 0, 0]), list):
            raise RigConfigError(f"{where}.tracker.offset_*: needs 3 numbers [x, y, z]")
        self._check_conflicts(where, lim)

    def _key(self, table: str, f: str) -> str:
        """The key ``f`` of ``table`` ("drives[1]", "tracker", "limits"; "" the top level) as written in the file;
        a dimensioned key the file does not give is ``<key>_*``."""
        path = f"{table}.{f}" if table else f
        if path in self.spelled:
            return self.spelled[path]
        spec = {"": TOP, "limits": LIMITS, "simulation": SIMULATION, "drives": DRIVE, "force_sensors": FORCE,
                "pressure": PRESSURE, "tracker": TRACKER}.get(table.split("[")[0], {})
        return path + ("_*" if spec.get(f) in DIMENSIONS else "")

    def _check_conflicts(self, where: str, lim: SafetyLimits) -> None:
        """Hardware rig: values in range and no two devices on one address (see docs/rig.md, "Conflicts")."""
        def bad(msg: str):
            raise RigConfigError(f"{where}: {msg}")

        # one drive and one force sensor per tendon, in tendon order
        m = self.actuator_params().n_tendons
        if len(self.drives) != m:
            bad(f"{len(self.drives)} [[drives]] tables for the {m} tendons of actuator {self.actuator!r} "
                f"(one per tendon, in tendon order)")
        if len(self.force_sensors) != len(self.drives):
            bad(f"{len(self.force_sensors)} [[force_sensors]] tables for {len(self.drives)} [[drives]] "
                f"(one per tendon, the {m} tendons of actuator {self.actuator!r})")
        # drives: node ids, bitrates, encoder scale, speed and acceleration in the drive's units, cyclic settings
        speed = self.speed if self.speed is not None else lim.speed_max        # what the builder asks of the drives
        speed_key = (self._key("", "speed") if self.speed is not None else self._key("limits", "speed_max")) \
            + f" ({speed * 1e3:g} mm/s)"
        buses: dict = {}
        for i, d in enumerate(self.drives):
            t = f"drives[{i}]"
            if not 1 <= d["node_id"] <= 127:
                bad(f"{self._key(t, 'node_id')} = {d['node_id']}: a CANopen node id is 1…127")
            br = d.get("bitrate", 1_000_000)
            if br not in CAN_BITRATES:
                bad(f"{self._key(t, 'bitrate')} = {br}: not a CAN bitrate "
                    f"(one of {', '.join(str(b) for b in CAN_BITRATES)})")
            bus = (d.get("interface", "socketcan"), d["channel"])
            for j in buses.get(bus, ()):
                o = self.drives[j]
                if o["node_id"] == d["node_id"]:
                    bad(f"drives[{j}].node_id and {t}.node_id are both node {d['node_id']} on CAN bus "
                        f"{bus[0]}:{bus[1]} (node ids on one bus must differ)")
                if o.get("bitrate", 1_000_000) != br:
                    bad(f"drives[{j}].bitrate = {o.get('bitrate', 1_000_000)} and {t}.bitrate = {br} differ on "
                        f"CAN bus {bus[0]}:{bus[1]} (one bus has one bitrate)")
            buses.setdefault(bus, []).append(i)
            cpmm = d["counts"] * 1e-3
            key = self._key(t, "counts")
            if not COUNTS_PER_MM_RANGE[0] <= cpmm <= COUNTS_PER_MM_RANGE[1]:
                bad(f"{key}: {cpmm:g} counts per mm is outside the accepted "
                    f"{COUNTS_PER_MM_RANGE[0]:g}…{COUNTS_PER_MM_RANGE[1]:g} counts per mm (tendon resolution "
                    f"0.1 mm … 1 nm; a counts_per_m value written as counts_per_mm, or the reverse, lands outside)")
            reach = max(abs(lim.length_min - d["zero_length"]), abs(lim.length_max - d["zero_length"]))
            if reach * d["counts"] >= 2 ** 31:
                bad(f"{key} with {self._key(t, 'zero_length')}: the travel limits "
                    f"{lim.length_min * 1e3:g}…{lim.length_max * 1e3:g} mm reach {reach * d['counts']:.3g} counts, "
                    f"outside the drive's 32-bit position range")
            self._check_drive_units(t, d, speed, speed_key, bad)
            self._check_cyclic_settings(t, d, speed, speed_key, bad)
        self._check_cyclic_buses(buses, bad)
        # serial instruments: baudrates, load-cell channels, one port per instrument
        channels: dict = {}
        ports: dict = {}
        for i, d in enumerate(self.force_sensors):
            t = f"force_sensors[{i}]"
            if d.get("baudrate", 115200) <= 0:
                bad(f"{self._key(t, 'baudrate')} = {d['baudrate']}: must be > 0")
            if not 1 <= d["channel"] <= FORCE_CHANNELS:
                bad(f"{self._key(t, 'channel')} = {d['channel']}: the load-cell board has channels 1…{FORCE_CHANNELS}")
            key = (d["port"], d["channel"])
            if key in channels:
                bad(f"force_sensors[{channels[key]}].channel and {t}.channel both read channel {d['channel']} "
                    f"of {d['port']} (two tendons on one sensor channel)")
            channels[key] = i
            if d["port"] in ports:
                j = ports[d["port"]]
                o = self.force_sensors[j].get("baudrate", 115200)
                if o != d.get("baudrate", 115200):
                    bad(f"{self._key(f'force_sensors[{j}]', 'baudrate')} = {o} and {self._key(t, 'baudrate')} = "
                        f"{d.get('baudrate', 115200)} differ on {d['port']} (the sensors on one port share one serial "
                        f"line: one baudrate; 115200 when not given)")
            ports.setdefault(d["port"], i)
        if self.pressure.get("baudrate", 115200) <= 0:
            bad(f"pressure.baudrate = {self.pressure['baudrate']}: must be > 0")
        for i, d in enumerate(self.force_sensors):
            if d["port"] == self.pressure["port"]:
                bad(f"pressure.port and force_sensors[{i}].port are both {d['port']} "
                    f"(the valve controller and the load-cell board need their own ports)")
        # tracker
        port = self.tracker.get("port", 1511)
        if not 1 <= port <= 65535:
            bad(f"tracker.port = {port}: a UDP port is 1…65535")
        rb = self.tracker.get("rigid_body_id", 1)
        if rb < 0:
            bad(f"tracker.rigid_body_id = {rb}: must be >= 0")
        if "natnet_version" in self.tracker:
            from .tracking import natnet_version
            try:
                natnet_version(self.tracker["natnet_version"])
            except RigConfigError as exc:
                bad(f"tracker.natnet_version: {exc}")

    def _check_drive_units(self, t: str, d: dict, speed: float, speed_key: str, bad) -> None:
        """``counts_per_turn``, and the tendon speed and acceleration in the drive's units (rpm, rpm/s of the motor:
        v · counts per m · 60 / counts_per_turn; 0x6081, 0x6083/0x6084, unsigned 32 bits)."""
        cpt = d["counts_per_turn"]
        if not cpt > 0:
            bad(f"{self._key(t, 'counts_per_turn')} = {cpt:g}: must be > 0 (encoder counts per motor revolution)")
        cpt_key, counts_key = f"{self._key(t, 'counts_per_turn')} = {cpt:g}", self._counts_key(t, d)
        asked = [(speed_key, speed, "rpm", "profile velocity 0x6081")]
        if self.acceleration is not None:
            asked.append((f"{self._key('', 'acceleration')} ({self.acceleration * 1e3:g} mm/s²)", self.acceleration,
                          "rpm/s", "profile acceleration and deceleration 0x6083/0x6084"))
        for key, v, unit, obj in asked:
            x = v * d["counts"] * 60.0 / cpt
            if not 1.0 <= x <= U32_MAX:
                why = (f"below the drive's unit of 1 {unit}: it cannot be asked of the drive" if x < 1.0
                       else f"beyond the drive's 32-bit {obj}")
                bad(f"{key} with {counts_key} and {cpt_key}: {x:.3g} {unit} of the motor shaft, {why}")

    def _check_cyclic_settings(self, t: str, d: dict, speed: float, speed_key: str, bad) -> None:
        """The settings of cyclic synchronous position: only on a cyclic drive, each in the drive's range."""
        cyclic = d.get("cyclic", False)
        for f in CYCLIC_ONLY:
            if f in d and not cyclic:
                bad(f"{self._key(t, f)} is a setting of cyclic synchronous position, but {t}.cyclic is "
                    f"{'false' if 'cyclic' in d else 'not set (false)'}: profile position would ignore it (set "
                    f"{t}.cyclic = true, or remove the key)")
        if not cyclic:
            return
        counts_key = self._counts_key(t, d)
        if "sync_period" in d:
            problem = sync_period_problem(d["sync_period"])
            if problem:
                bad(f"{self._key(t, 'sync_period')}: {problem}")
        if "heartbeat_timeout" in d:
            hb = d["heartbeat_timeout"]
            if (hb <= DRIVE_HEARTBEAT_TIME or hb < 2 * HOST_HEARTBEAT_PERIOD
                    or round(hb * 1e3) > HEARTBEAT_TIMEOUT_MAX_MS):
                lo = max(DRIVE_HEARTBEAT_TIME, 2 * HOST_HEARTBEAT_PERIOD)
                bad(f"{self._key(t, 'heartbeat_timeout')} ({hb * 1e3:g} ms): it must be longer than the drive's "
                    f"producer heartbeat time ({DRIVE_HEARTBEAT_TIME * 1e3:g} ms), at least twice the host's heartbeat "
                    f"period (2 × {HOST_HEARTBEAT_PERIOD * 1e3:g} ms: the drive stops itself when the host is silent "
                    f"this long) and fit the drive's 16-bit consumer heartbeat time 0x1016: accepted "
                    f"{lo * 1e3:g} … {HEARTBEAT_TIMEOUT_MAX_MS} ms")
        if "following_error_window" in d:
            w = d["following_error_window"]
            key = f"{self._key(t, 'following_error_window')} ({w * 1e3:g} mm)"
            if not w > 0:
                bad(f"{key}: must be > 0 (the drive faults when it lags its demand by more)")
            c = w * d["counts"]
            if round(c) < 1:
                bad(f"{key} with {counts_key}: {c:.3g} counts, less than one count (the drive's following error "
                    f"window 0x6065 is a whole number of counts)")
            if c >= U32_MAX:
                bad(f"{key} with {counts_key}: {c:.3g} counts does not fit the drive's following error window 0x6065 "
                    f"(unsigned 32 bits; 0xFFFFFFFF switches the check off)")
        period = d.get("sync_period", SYNC_PERIOD_DEFAULT)
        step = speed * d["counts"] * period
        if step < 1.0:
            bad(f"{speed_key} with {counts_key} and {self._sync_key(t, d)}: {step:.3g} counts per SYNC period, but "
                f"the cyclic set-point ramp moves whole counts, at least 1 count per SYNC period "
                f"({1e3 / (d['counts'] * period):.3g} mm/s here, faster than the {speed * 1e3:g} mm/s asked)")

    def _counts_key(self, t: str, d: dict) -> str:
        """The encoder scale of drive table ``t`` as written, with its value (for messages)."""
        return f"{self._key(t, 'counts')} ({d['counts'] * 1e-3:g} counts/mm)"

    def _sync_key(self, t: str, d: dict) -> str:
        """The SYNC period of drive table ``t`` as written, or its default (for messages)."""
        if "sync_period" in d:
            return f"{self._key(t, 'sync_period')} ({d['sync_period'] * 1e3:g} ms)"
        return f"{self._key(t, 'sync_period')} (not given: the default {SYNC_PERIOD_DEFAULT * 1e3:g} ms)"

    def _check_cyclic_buses(self, buses: dict, bad) -> None:
        """A bus with cyclic drives: node 127 is the host's heartbeat, one SYNC period, its PDOs fit the period."""
        for bus, members in buses.items():
            cyc = [i for i in members if self.drives[i].get("cyclic", False)]
            if not cyc:
                continue
            name = f"{bus[0]}:{bus[1]}"
            listed = ", ".join(f"drives[{i}]" for i in cyc)
            for i in members:
                if self.drives[i]["node_id"] == HOST_HEARTBEAT_NODE:
                    bad(f"{self._key(f'drives[{i}]', 'node_id')} = {HOST_HEARTBEAT_NODE} on CAN bus {name}, which has "
                        f"cyclic drives ({listed}): node {HOST_HEARTBEAT_NODE} is the host's own heartbeat there "
                        f"(COB-ID 0x{0x700 + HOST_HEARTBEAT_NODE:03X}, consumed by the cyclic drives); give the drive "
                        f"a node id 1…{HOST_HEARTBEAT_NODE - 1}")
            first = self.drives[cyc[0]]
            period = first.get("sync_period", SYNC_PERIOD_DEFAULT)
            for j in cyc[1:]:
                other = self.drives[j]
                if not math.isclose(other.get("sync_period", SYNC_PERIOD_DEFAULT), period, rel_tol=1e-9):
                    bad(f"{self._sync_key(f'drives[{cyc[0]}]', first)} and {self._sync_key(f'drives[{j}]', other)} "
                        f"differ on CAN bus {name}: only one SYNC runs per bus, shared by its cyclic drives (give "
                        f"them one sync_period)")
            bitrate = first.get("bitrate", 1_000_000)
            bits = can_frame_bits(0) + len(cyc) * sum(can_frame_bits(n) for n in CYCLIC_PDO_BYTES)
            if bits / bitrate > period:
                bad(f"{self._key(f'drives[{cyc[0]}]', 'bitrate')} = {bitrate} and "
                    f"{self._sync_key(f'drives[{cyc[0]}]', first)} on CAN bus {name}: one SYNC cycle of its "
                    f"{len(cyc)} cyclic drive{'s' if len(cyc) > 1 else ''} (SYNC, then RPDO 1, TPDO 1 and TPDO 2 of "
                    f"each: {bits} bits at worst-case bit stuffing) takes {bits / bitrate * 1e3:.3g} ms, longer than "
                    f"the SYNC period (raise the bitrate or the sync_period)")

    # --------------------------------------------------------------------------------------- derived
    def actuator_params(self, which: str = "actuator"):
        """The actuator parameters (``which="plant_actuator"``: the simulated plant's)."""
        from ancf import ActuatorParams, presets
        name = self.simulation.get("plant_actuator", self.actuator) if which == "plant_actuator" else self.actuator
        path = pathlib.Path(self.base_dir) / name
        if name.endswith(".toml"):
            try:
                return ActuatorParams.from_toml(path)
            except ConfigError as exc:
                raise RigConfigError(f"rig {self.name}: actuator file: {exc}") from None
        try:
            return presets.get(name)
        except (ConfigError, KeyError, ValueError) as exc:
            raise RigConfigError(f"rig {self.name}: unknown actuator preset {name!r} ({exc})") from None

    def safety_limits(self) -> SafetyLimits:
        if self.backend == "sim" and not ({"length_min", "length_max"} & set(self.limits)):
            return SafetyLimits.around(self.actuator_params().length, **self.limits)
        return SafetyLimits(**self.limits)

    def to_dict(self) -> dict:
        return {k: (list(v) if isinstance(v, tuple) else v) for k, v in self.__dict__.items() if k != "spelled"}
