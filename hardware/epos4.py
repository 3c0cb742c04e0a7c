r"""maxon EPOS4 tendon drive over CANopen (CiA 402), with ``canopen`` and ``python-can``: what both drive
modes share.

Two modes, two classes behind one interface (:class:`~hardware.interfaces.TendonDrive`), each with its own
enable, fault and recovery path:

* :class:`~hardware.epos4_profile.Epos4ProfileDrive` — **profile position** (0x6060 = 1) over SDO: every
  set-point is a confirmed SDO transfer with the new-setpoint handshake, the drive ramps at the profile
  velocity/acceleration the rig file asks for.  Slow, quasi-static moves.
* :class:`~hardware.epos4_cyclic.Epos4CyclicDrive` — **cyclic synchronous position** (0x6060 = 8) over PDO +
  SYNC: the loop mode, with set-points that cannot jump (:mod:`hardware.setpoints`) and drive-side supervision
  of the host (consumer heartbeat, following-error window, software position limits).

(Until this split both were one class, ``Epos4Drive(..., cyclic=False | True)``; ``Epos4Drive`` is now their
shared base, and code names the mode's class.)  Drives on one bus share a :class:`~hardware.canbus.CanBus`.

Objects used (the object dictionary is built in code — maxon ships XDD files, which ``canopen`` cannot
import; standard CiA 301/402 objects plus one EPOS4 object):

======  ===  ======  ============================================================================
index   sub  type    meaning
======  ===  ======  ============================================================================
0x6040  0    U16     controlword
0x6041  0    U16     statusword
0x6060  0    I8      modes of operation (1 = profile position, 8 = cyclic synchronous position)
0x6061  0    I8      modes of operation display
0x607A  0    I32     target position [counts]
0x6064  0    I32     position actual value [counts]
0x6062  0    I32     position demand value [counts] (the target the drive applies; cyclic: by TPDO 1)
0x6081  0    U32     profile velocity [rpm of the motor shaft, the EPOS4 default unit]
0x6083  0    U32     profile acceleration [rpm/s]
0x6084  0    U32     profile deceleration [rpm/s]
0x6065  0    U32     following error window [counts] (cyclic)
0x6066  0    U16     following error time out [ms] (cyclic)
0x607D  1/2  I32     software position limit min / max [counts] (cyclic)
0x60C2  1/2  U8/I8   interpolation time period value / index (period = value · 10^index s) (cyclic)
0x1016  1    U32     consumer heartbeat time: producer node (bits 16–23), time [ms] (bits 0–15) (cyclic)
0x1017  0    U16     producer heartbeat time [ms] (cyclic)
0x60F4  0    I32     following error actual value [counts]
0x603F  0    U16     error code (CiA 301 / maxon error code of the last fault)
0x30D1  2    I32     current actual value [mA] (EPOS4)
======  ===  ======  ============================================================================

**Power state machine** (statusword bits 0–3, 5, 6 → state; controlword commands): shutdown 0x06 →
*ready to switch on*, switch on 0x07 → *switched on*, enable operation 0x0F → *operation enabled*;
quick stop 0x02; fault reset: a rising edge of bit 7 (0x80).  Every transition is written and confirmed over
SDO (a fresh statusword read, in both modes: a cyclic TPDO may be one SYNC old) within ``state_timeout`` s,
else :class:`DriveFault`.  Statusword bit 3 is a fault (the code is read from 0x603F), bit 13 a following
error; an EMCY message with a non-zero error code is a fault too.  All are raised as
:class:`~hardware.errors.DriveFault` by :meth:`Epos4Drive.check` (and by every command).

**The configured speed.**  ``speed`` [m/s] (the rig file's ``speed_mm_per_s``) and ``acceleration`` [m/s²]
are written at enable as profile velocity 0x6081 and acceleration/deceleration 0x6083/0x6084 in the drive's
units (rpm of the motor shaft: ``rpm = v · |counts_per_metre| · 60 / counts_per_turn``), read back and
checked: a drive that keeps another value is a :class:`DriveFault` before anything moves.  In cyclic mode the
host's set-point ramp runs at ``speed`` (capped by the limits' ``speed_max``).

Units at this boundary: tendon length ``l`` [m] ↔ counts ``c = round((l − zero_length) · counts_per_metre)``.
Travel limits are checked (:class:`~hardware.limits.SafetyLimits`) before any target leaves the process.
"""

from __future__ import annotations

import math
import sys
import time
from typing import Optional

from .canbus import CanBus
from .errors import CommunicationError, DriveFault, LimitError
from .interfaces import TendonDrive
from .limits import SafetyLimits

CONTROLWORD, STATUSWORD, MODE, MODE_DISPLAY = 0x6040, 0x6041, 0x6060, 0x6061
TARGET, POSITION, PROFILE_VELOCITY, ERROR_CODE, CURRENT = 0x607A, 0x6064, 0x6081, 0x603F, 0x30D1
POSITION_DEMAND = 0x6062
PROFILE_ACCELERATION, PROFILE_DECELERATION = 0x6083, 0x6084
FOLLOWING_ERROR, HEARTBEAT_TIME, CONSUMER_HEARTBEAT = 0x60F4, 0x1017, 0x1016
FOLLOWING_ERROR_WINDOW, FOLLOWING_ERROR_TIMEOUT, SOFTWARE_LIMITS, INTERPOLATION_PERIOD = 0x6065, 0x6066, 0x607D, 0x60C2
RPDO1_COM, RPDO1_MAP, TPDO1_COM, TPDO1_MAP, TPDO2_COM, TPDO2_MAP = 0x1400, 0x1600, 0x1800, 0x1A00, 0x1801, 0x1A01
PROFILE_POSITION, CYCLIC_SYNC_POSITION = 1, 8
SYNC_TRANSMISSION = 1                     # PDO transmission type: on every SYNC

CW_SHUTDOWN, CW_SWITCH_ON, CW_ENABLE, CW_QUICK_STOP, CW_DISABLE_VOLTAGE, CW_FAULT_RESET = 0x06, 0x07, 0x0F, 0x02, 0x00, 0x80
CW_NEW_SETPOINT, CW_CHANGE_IMMEDIATELY, CW_HALT = 1 << 4, 1 << 5, 1 << 8
SW_FAULT, SW_TARGET_REACHED, SW_SETPOINT_ACK, SW_FOLLOWING_ERROR = 1 << 3, 1 << 10, 1 << 12, 1 << 13


#: (mask, value, state) of the CiA 402 statusword, tried in order
STATES = ((0x4F, 0x00, "NOT READY TO SWITCH ON"), (0x4F, 0x40, "SWITCH ON DISABLED"),
          (0x6F, 0x21, "READY TO SWITCH ON"), (0x6F, 0x23, "SWITCHED ON"), (0x6F, 0x27, "OPERATION ENABLED"),
          (0x6F, 0x07, "QUICK STOP ACTIVE"), (0x4F, 0x0F, "FAULT REACTION ACTIVE"), (0x4F, 0x08, "FAULT"))


def state_of(statusword: int) -> str:
    """CiA 402 power state from the statusword."""
    sw = int(statusword)
    for mask, value, name in STATES:
        if sw & mask == value:
            return name
    return f"UNKNOWN (0x{sw:04X})"


def object_dictionary():
    """The object dictionary of the objects above (the host's view of the drive)."""
    from canopen import objectdictionary as odm
    from canopen.objectdictionary import datatypes as dt
    od = odm.ObjectDictionary()

    def var(index, name, dtype, access, sub=0, default=0):
        v = odm.ODVariable(name, index, sub)
        v.data_type, v.access_type, v.default = dtype, access, default
        return v

    for index, name, dtype, access in ((CONTROLWORD, "Controlword", dt.UNSIGNED16, "rw"),
                                       (STATUSWORD, "Statusword", dt.UNSIGNED16, "ro"),
                                       (MODE, "Modes of operation", dt.INTEGER8, "rw"),
                                       (MODE_DISPLAY, "Modes of operation display", dt.INTEGER8, "ro"),
                                       (TARGET, "Target position", dt.INTEGER32, "rw"),
                                       (POSITION, "Position actual value", dt.INTEGER32, "ro"),
                                       (POSITION_DEMAND, "Position demand value", dt.INTEGER32, "ro"),
                                       (PROFILE_VELOCITY, "Profile velocity", dt.UNSIGNED32, "rw"),
                                       (PROFILE_ACCELERATION, "Profile acceleration", dt.UNSIGNED32, "rw"),
                                       (PROFILE_DECELERATION, "Profile deceleration", dt.UNSIGNED32, "rw"),
                                       (FOLLOWING_ERROR_WINDOW, "Following error window", dt.UNSIGNED32, "rw"),
                                       (FOLLOWING_ERROR_TIMEOUT, "Following error time out", dt.UNSIGNED16, "rw"),
                                       (ERROR_CODE, "Error code", dt.UNSIGNED16, "ro"),
                                       (FOLLOWING_ERROR, "Following error actual value", dt.INTEGER32, "ro"),
                                       (HEARTBEAT_TIME, "Producer heartbeat time", dt.UNSIGNED16, "rw")):
        od.add_object(var(index, name, dtype, access))
    for index, name, members in (
            (CURRENT, "Current actual values", ((1, "Current actual value averaged", dt.INTEGER32, "ro"),
                                                (2, "Current actual value", dt.INTEGER32, "ro"))),
            (SOFTWARE_LIMITS, "Software position limit", ((1, "Min position limit", dt.INTEGER32, "rw"),
                                                          (2, "Max position limit", dt.INTEGER32, "rw"))),
            (INTERPOLATION_PERIOD, "Interpolation time period", ((1, "Interpolation time period value",
                                                                  dt.UNSIGNED8, "rw"),
                                                                 (2, "Interpolation time index", dt.INTEGER8, "rw"))),
            (CONSUMER_HEARTBEAT, "Consumer heartbeat time", ((1, "Consumer heartbeat time 1", dt.UNSIGNED32, "rw"),))):
        rec = odm.ODRecord(name, index)
        rec.add_member(var(index, "Highest sub-index", dt.UNSIGNED8, "ro", 0, len(members)))
        for sub, sname, dtype, access in members:
            rec.add_member(var(index, sname, dtype, access, sub))
        od.add_object(rec)
    for com, name in ((RPDO1_COM, "RPDO 1 communication parameter"), (TPDO1_COM, "TPDO 1 communication parameter"),
                      (TPDO2_COM, "TPDO 2 communication parameter")):
        rec = odm.ODRecord(name, com)
        for sub, sname, dtype in ((0, "Highest sub-index", dt.UNSIGNED8), (1, "COB-ID", dt.UNSIGNED32),
                                  (2, "Transmission type", dt.UNSIGNED8), (3, "Inhibit time", dt.UNSIGNED16),
                                  (5, "Event timer", dt.UNSIGNED16)):
            rec.add_member(var(com, sname, dtype, "ro" if sub == 0 else "rw", sub, 5 if sub == 0 else 0))
        od.add_object(rec)
    for mp, name in ((RPDO1_MAP, "RPDO 1 mapping parameter"), (TPDO1_MAP, "TPDO 1 mapping parameter"),
                     (TPDO2_MAP, "TPDO 2 mapping parameter")):
        arr = odm.ODRecord(name, mp)            # a record: canopen writes its entries whatever the count
        for sub in range(9):
            arr.add_member(var(mp, "Number of mapped objects" if sub == 0 else f"Mapped object {sub}",
                               dt.UNSIGNED8 if sub == 0 else dt.UNSIGNED32, "rw", sub))
        od.add_object(arr)
    return od


def _positive(name: str, v, unit: str) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not 0 < v < math.inf:
        raise LimitError(f"{name} must be a positive number ({unit}), got {v!r}")
    return float(v)


class Epos4Drive(TendonDrive):
    """What both EPOS4 modes share: connection, SDO access, the power state machine, faults, unit conversion.

    Not used alone: build an :class:`~hardware.epos4_profile.Epos4ProfileDrive` or an
    :class:`~hardware.epos4_cyclic.Epos4CyclicDrive` (their docstrings list their own parameters).  Shared
    parameters:

    node_id : CANopen node id (1…127);  channel, interface, bitrate : python-can bus ("can0", "socketcan",
        1 Mbit/s; "virtual" for tests), or ``bus`` : a :class:`~hardware.canbus.CanBus` shared with the other
        drives of the bus, or ``network`` : an already connected ``canopen.Network``
    counts_per_metre : encoder counts per metre of tendon length (sign = direction; ≠ 0)
    zero_length : tendon length at count 0 [m]
    limits : :class:`SafetyLimits` (travel is checked before a target is sent)
    speed : tendon speed asked of the drive [m/s] (≤ ``limits.speed_max``; default ``speed_max``)
    acceleration : tendon acceleration and deceleration asked of the drive [m/s²] (default: ``speed`` / 0.1 s)
    counts_per_turn : encoder counts per motor revolution (the drive's velocity unit is rpm of the motor);
        None: the profile velocity is not written (a drive keeps what it stored) — allowed only for a drive
        built in code; the rig file requires it
    state_timeout : seconds to wait for a state transition
    """

    mode = 0
    mode_name = ""

    def __init__(self, node_id: int, channel: str = "can0", interface: str = "socketcan", bitrate: int = 1_000_000, *,
                 counts_per_metre: float, zero_length: float = 0.0, limits: Optional[SafetyLimits] = None,
                 speed: Optional[float] = None, acceleration: Optional[float] = None,
                 counts_per_turn: Optional[float] = None, network=None, bus: Optional[CanBus] = None,
                 state_timeout: float = 1.0, name: Optional[str] = None):
        if isinstance(node_id, bool) or not isinstance(node_id, int) or not 1 <= node_id <= 127:
            raise LimitError(f"EPOS4 node_id must be an integer 1…127, got {node_id!r}")
        try:
            cpm = float(counts_per_metre)
            zl = float(zero_length)
        except (TypeError, ValueError):
            raise LimitError("counts_per_metre and zero_length must be numbers") from None
        if not (math.isfinite(cpm) and cpm != 0 and math.isfinite(zl)):
            raise LimitError(f"counts_per_metre must be finite and non-zero, got {counts_per_metre!r}")
        self.node_id, self.counts_per_metre, self.zero_length = node_id, cpm, zl
        self.limits = limits or SafetyLimits()
        if speed is not None:
            self.limits.check_speed(speed)
            if counts_per_turn is None:
                raise LimitError("speed needs counts_per_turn (> 0) to convert to the drive's rpm")
        self.speed = float(speed) if speed is not None else self.limits.speed_max
        self.acceleration = (_positive("acceleration", acceleration, "m/s²") if acceleration is not None
                             else self.speed / 0.1)
        self.counts_per_turn = None if counts_per_turn is None else _positive("counts_per_turn", counts_per_turn,
                                                                              "counts per motor revolution")
        self.state_timeout = _positive("state_timeout", state_timeout, "s")
        self.name = name or f"EPOS4 node {node_id}"
        if bus is None:
            bus = CanBus(interface, channel, bitrate, network=network)
        elif network is not None:
            raise LimitError("give either bus or network, not both")
        self.bus = bus
        self.channel, self.interface, self.bitrate = bus.channel, bus.interface, bus.bitrate
        self.node = None
        self._emcy: list = []
        self._cw = 0

    # ----------------------------------------------------------------------------------- transport
    def open(self) -> None:
        if self.node is not None:
            return
        import canopen
        net = self.bus.open()
        try:
            node = canopen.RemoteNode(self.node_id, object_dictionary())
            net.add_node(node)
            node.emcy.add_callback(self._on_emcy)
            self.node = node
        except (OSError, ValueError) as exc:
            self.bus.close()
            raise CommunicationError(f"cannot add node {self.node_id} on {self.bus.name}: {exc}",
                                     device=self.name) from None

    def close(self) -> None:
        if self.node is None:
            return
        net = self.bus.network
        try:
            if net is not None:
                del net[self.node_id]
        except (KeyError, AttributeError):
            pass
        self.node = None
        self.bus.close()

    def _on_emcy(self, err) -> None:
        if getattr(err, "code", 0):
            self._emcy.append(err)

    def _node(self):
        if self.node is None:
            raise CommunicationError("drive is not open (use it as a context manager)", device=self.name)
        return self.node

    def _read(self, index: int, sub: int = 0) -> int:
        import canopen
        node = self._node()
        try:
            obj = node.sdo[index] if sub == 0 else node.sdo[index][sub]
            return int(obj.raw)
        except (canopen.SdoCommunicationError, canopen.SdoAbortedError, OSError) as exc:
            raise CommunicationError(f"SDO read 0x{index:04X}:{sub} failed: {exc}", device=self.name) from None

    def _write(self, index: int, value: int, sub: int = 0) -> None:
        import canopen
        node = self._node()
        try:
            obj = node.sdo[index] if sub == 0 else node.sdo[index][sub]
            obj.raw = int(value)
        except (canopen.SdoCommunicationError, canopen.SdoAbortedError, OSError) as exc:
            raise CommunicationError(f"SDO write 0x{index:04X}:{sub} = {value} failed: {exc}", device=self.name) from None

    def _write_checked(self, index: int, value: int, what: str, sub: int = 0) -> None:
        """Write, read back, and refuse a drive that keeps another value."""
        self._write(index, value, sub)
        got = self._read(index, sub)
        if got != int(value):
            raise DriveFault(f"{what} 0x{index:04X}:{sub}: wrote {int(value)}, the drive keeps {got}", device=self.name)

    def _control(self, cw: int) -> None:
        self._cw = cw
        self._write(CONTROLWORD, cw)

    def statusword(self) -> int:
        """The statusword, read over SDO (fresh)."""
        return self._read(STATUSWORD)

    def state(self) -> str:
        return state_of(self.statusword())

    # ----------------------------------------------------------------------------------- faults
    def _check_emcy(self) -> None:
        if self._emcy:
            e = self._emcy[-1]
            raise DriveFault(f"EMCY received ({getattr(e, 'get_desc', lambda: '')() or 'emergency'})",
                             device=self.name, code=int(e.code))

    def _check_statusword(self, sw: int) -> None:
        if sw & SW_FAULT:
            raise DriveFault(f"drive in state {state_of(sw)}", device=self.name, code=self._read(ERROR_CODE))
        if sw & SW_FOLLOWING_ERROR:
            raise DriveFault("following error", device=self.name, code=0x8611)

    def check(self) -> None:
        """Raise DriveFault on statusword fault, following error or a received EMCY."""
        self._check_emcy()
        self._check_statusword(self.statusword())

    def fault_reset(self) -> None:
        """Clear a fault (rising edge of controlword bit 7, confirmed over SDO); the drive goes to SWITCH ON
        DISABLED and stays disabled until :meth:`enable`."""
        self._control(0)
        self._control(CW_FAULT_RESET)
        self._emcy.clear()
        self._wait_state(("SWITCH ON DISABLED", "READY TO SWITCH ON", "SWITCHED ON", "OPERATION ENABLED"))

    def recover(self) -> bool:
        """Back to OPERATION ENABLED where the drive stands (confirmed by a person: :meth:`hardware.Rig.recover`):
        QUICK STOP ACTIVE → disable voltage 0x00; FAULT → fault reset; then :meth:`enable` (a cyclic drive from
        its actual position: 0x607A := 0x6064, the set-point frozen there).  An enabled drive is left alone."""
        st = state_of(self._read(STATUSWORD))
        if st == "OPERATION ENABLED" and not self._emcy:
            return False
        if st == "QUICK STOP ACTIVE":
            self._control(CW_DISABLE_VOLTAGE)
            self._wait_state(("SWITCH ON DISABLED",), what="recover (controlword 0x00)")
        elif st in ("FAULT", "FAULT REACTION ACTIVE") or self._emcy:
            self.fault_reset()
        self.enable()
        return True

    def _wait_state(self, states, what: str = "fault reset") -> str:
        """Poll the statusword over SDO (fresh in both modes) until the drive is in one of ``states``."""
        t0 = time.monotonic()
        while True:
            sw = self._read(STATUSWORD)
            st = state_of(sw)
            if st in states:
                return st
            if sw & SW_FAULT and "FAULT" not in states:
                raise DriveFault(f"{what}: drive entered {st}", device=self.name, code=self._read(ERROR_CODE))
            if time.monotonic() - t0 > self.state_timeout:
                raise DriveFault(f"{what}: drive stayed in {st}, expected {' or '.join(states)} "
                                 f"within {self.state_timeout:g} s", device=self.name)
            time.sleep(0.002)

    # ----------------------------------------------------------------------------------- enable
    def _enter_mode(self) -> None:
        self._write(MODE, self.mode)
        t0 = time.monotonic()
        while self._read(MODE_DISPLAY) != self.mode:
            if time.monotonic() - t0 > self.state_timeout:
                raise DriveFault(f"drive did not enter {self.mode_name} mode", device=self.name)
            time.sleep(0.002)

    def rpm(self, speed: float) -> int:
        """A tendon speed [m/s] in the drive's velocity unit (rpm of the motor shaft), at least 1."""
        return max(1, int(round(abs(speed * self.counts_per_metre) * 60.0 / self.counts_per_turn)))

    def _write_profile(self) -> None:
        """Profile velocity / acceleration / deceleration from ``speed`` and ``acceleration``, read back."""
        if self.counts_per_turn is None:
            return
        self._write_checked(PROFILE_VELOCITY, self.rpm(self.speed), "profile velocity [rpm]")
        for index, what in ((PROFILE_ACCELERATION, "profile acceleration [rpm/s]"),
                            (PROFILE_DECELERATION, "profile deceleration [rpm/s]")):
            self._write_checked(index, self.rpm(self.acceleration), what)

    def _power_up(self) -> None:
        """shutdown → switch on → enable operation, each confirmed over SDO."""
        for cw, target in ((CW_SHUTDOWN, "READY TO SWITCH ON"), (CW_SWITCH_ON, "SWITCHED ON"),
                           (CW_ENABLE, "OPERATION ENABLED")):
            self._control(cw)
            self._wait_state((target,), what=f"controlword 0x{cw:02X}")

    def start(self) -> None:
        """Begin cyclic operation once every drive of the rig is enabled (nothing to do in profile position)."""

    def __enter__(self):
        """Connect, enable, start."""
        self.open()
        try:
            self.enable()
            self.start()
        except BaseException:
            self.__exit__(*sys.exc_info())
            raise
        return self

    # ----------------------------------------------------------------------------------- conversions
    def to_counts(self, length: float) -> int:
        c = round((float(length) - self.zero_length) * self.counts_per_metre)
        if not -(2 ** 31) <= c < 2 ** 31:
            raise LimitError(f"length {length} m is {c} counts: outside the 32-bit position range", device=self.name)
        return int(c)

    def to_length(self, counts: int) -> float:
        return self.zero_length + counts / self.counts_per_metre

    def _checked_counts(self, length: float) -> int:
        return self.to_counts(self.limits.check_lengths([length], None, 1)[0])

    # ----------------------------------------------------------------------------------- stopping
    def quick_stop(self) -> None:
        self._control(CW_QUICK_STOP)

    def disable(self) -> None:
        """Power stage off, never through OPERATION ENABLED (CiA 402):

        * OPERATION ENABLED / SWITCHED ON / READY TO SWITCH ON: shutdown 0x06 → READY TO SWITCH ON;
        * QUICK STOP ACTIVE: disable voltage 0x00 → SWITCH ON DISABLED (shutdown is no transition from
          quick stop, and enable operation would re-enable the drive);
        * FAULT, FAULT REACTION ACTIVE, SWITCH ON DISABLED, NOT READY TO SWITCH ON: already off — nothing is
          written (a fault is not reset here).

        The new state is confirmed within ``state_timeout``, else :class:`DriveFault`."""
        st = state_of(self._read(STATUSWORD))
        if st in ("OPERATION ENABLED", "SWITCHED ON", "READY TO SWITCH ON"):
            self._control(CW_SHUTDOWN)
            self._wait_state(("READY TO SWITCH ON", "SWITCH ON DISABLED"), what="disable (controlword 0x06)")
        elif st == "QUICK STOP ACTIVE":
            self._control(CW_DISABLE_VOLTAGE)
            self._wait_state(("SWITCH ON DISABLED",), what="disable (controlword 0x00)")

    def __exit__(self, exc_type, exc, tb):
        """On an exception (Ctrl-C included): quick stop; on a normal exit: halt, then disable."""
        try:
            if self.node is not None:
                try:
                    if exc_type is not None:
                        self.quick_stop()
                    else:
                        self.hold()
                        self.disable()
                except Exception:                          # noqa: BLE001 - leave as safe as possible
                    try:
                        self.quick_stop()
                    except Exception:                      # noqa: BLE001
                        pass
        finally:
            self.close()
        return False
