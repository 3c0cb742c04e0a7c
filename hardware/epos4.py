r"""maxon EPOS4 tendon drive over CANopen (CiA 402), with ``canopen`` and ``python-can``.

What is used of the drive (object dictionary built in code — maxon ships XDD files, which ``canopen``
cannot import; these are the standard CiA 402 objects plus one EPOS4 object):

======  ===  ======  ============================================================================
index   sub  type    meaning
======  ===  ======  ============================================================================
0x6040  0    U16     controlword
0x6041  0    U16     statusword
0x6060  0    I8      modes of operation (1 = profile position)
0x6061  0    I8      modes of operation display
0x607A  0    I32     target position [counts]
0x6064  0    I32     position actual value [counts]
0x6081  0    U32     profile velocity [drive velocity units, EPOS4 default rpm]
0x603F  0    U16     error code (CiA 301 / maxon error code of the last fault)
0x30D1  2    I32     current actual value [mA] (EPOS4)
======  ===  ======  ============================================================================

**Power state machine** (statusword bits 0–3, 5, 6 → state; controlword commands): shutdown 0x06 →
*ready to switch on*, switch on 0x07 → *switched on*, enable operation 0x0F → *operation enabled*;
quick stop 0x02; fault reset: a rising edge of bit 7 (0x80).  Every transition is confirmed by reading
the statusword back within ``state_timeout`` s, else :class:`DriveFault`.

**Profile position** (0x6060 = 1): write the target 0x607A, then the new-setpoint handshake — controlword
bit 4 (new setpoint) with bit 5 (change set immediately) set, wait for statusword bit 12 (setpoint
acknowledge), clear bit 4.  Bit 10 (target reached) and bit 12 = 0 mean the move is done; bit 8 (halt)
holds the drive where it is.  Statusword bit 3 is a fault (the code is read from 0x603F), bit 13 in
profile position mode is a following error; an EMCY message with a non-zero error code is a fault too.
All are raised as :class:`~hardware.errors.DriveFault` by :meth:`Epos4Drive.check` (and by every
command).

**Two ways to move.**  Profile position (the default, ``cyclic=False``): every set-point and read-back is a
confirmed SDO transfer with the new-setpoint handshake — about a millisecond per round trip on a 1 Mbit/s
bus, several per command: right for slow, quasi-static moves.  **Cyclic synchronous position**
(``cyclic=True``, 0x6060 = 8), the loop mode: at start-up the PDOs are mapped over SDO (the drive is in
PRE-OPERATIONAL) —

* RPDO 1 (0x1400/0x1600, COB-ID 0x200 + node): controlword 0x6040 + target position 0x607A, applied on SYNC;
* TPDO 1 (0x1800/0x1A00, 0x180 + node): statusword 0x6041 + position actual value 0x6064, sent on every SYNC;
* TPDO 2 (0x1801/0x1A01, 0x280 + node): following error actual value 0x60F4 + current 0x30D1:02, on SYNC;
* producer heartbeat 0x1017 (``heartbeat_time``), then NMT OPERATIONAL and the SYNC producer
  (``sync_period``; one per bus).

A set-point then costs no bus round trip: an interpolator thread sends RPDO 1 every SYNC period with the
set-point stepped towards the commanded target at no more than the rig's speed limit (CSP needs a
set-point per cycle, not a jump), and statusword, position, following error and current arrive by TPDO.  A
drive whose heartbeat stops for ``heartbeat_timeout`` or whose TPDOs stop for ``pdo_timeout`` is a
:class:`~hardware.errors.DriveFault` ("silent drive") at the next :meth:`Epos4Drive.check`, which every command
and the rig's health check call; an EMCY is a DriveFault in both modes.  The mode is chosen per drive for a
whole run (rig file ``cyclic``); why a cyclic run does not switch to profile position for slow moves — the
interpolator already makes every move of a run a speed-limited ramp of at most ``max_step`` — is in
docs/rig.md ("Why a run does not switch a drive ...").

Units at this boundary: tendon length ``l`` [m] ↔ counts ``c = round((l − zero_length) ·
counts_per_metre)``.  Travel limits are checked (:class:`~hardware.limits.SafetyLimits`) before any
target leaves the process.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from typing import Optional

from .errors import CommunicationError, DriveFault, LimitError
from .interfaces import TendonDrive
from .limits import SafetyLimits

CONTROLWORD, STATUSWORD, MODE, MODE_DISPLAY = 0x6040, 0x6041, 0x6060, 0x6061
TARGET, POSITION, PROFILE_VELOCITY, ERROR_CODE, CURRENT = 0x607A, 0x6064, 0x6081, 0x603F, 0x30D1
FOLLOWING_ERROR, HEARTBEAT_TIME = 0x60F4, 0x1017
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
    """The object dictionary of the objects above (used by the drive client and by test fakes)."""
    from canopen import objectdictionary as odm
    from canopen.objectdictionary import datatypes as dt
    od = odm.ObjectDictionary()
    for index, name, dtype, access in ((CONTROLWORD, "Controlword", dt.UNSIGNED16, "rw"),
                                       (STATUSWORD, "Statusword", dt.UNSIGNED16, "ro"),
                                       (MODE, "Modes of operation", dt.INTEGER8, "rw"),
                                       (MODE_DISPLAY, "Modes of operation display", dt.INTEGER8, "ro"),
                                       (TARGET, "Target position", dt.INTEGER32, "rw"),
                                       (POSITION, "Position actual value", dt.INTEGER32, "ro"),
                                       (PROFILE_VELOCITY, "Profile velocity", dt.UNSIGNED32, "rw"),
                                       (ERROR_CODE, "Error code", dt.UNSIGNED16, "ro")):
        v = odm.ODVariable(name, index, 0)
        v.data_type, v.access_type = dtype, access
        od.add_object(v)
    rec = odm.ODRecord("Current actual values", CURRENT)
    for sub, name in ((1, "Current actual value averaged"), (2, "Current actual value")):
        v = odm.ODVariable(name, CURRENT, sub)
        v.data_type, v.access_type = dt.INTEGER32, "ro"
        rec.add_member(v)
    od.add_object(rec)
    # cyclic operation: following error, heartbeat producer time, PDO 1 communication and mapping parameters
    for index, name, dtype, access in ((FOLLOWING_ERROR, "Following error actual value", dt.INTEGER32, "ro"),
                                       (HEARTBEAT_TIME, "Producer heartbeat time", dt.UNSIGNED16, "rw")):
        v = odm.ODVariable(name, index, 0)
        v.data_type, v.access_type = dtype, access
        od.add_object(v)
    for com, name in ((RPDO1_COM, "RPDO 1 communication parameter"), (TPDO1_COM, "TPDO 1 communication parameter"),
                      (TPDO2_COM, "TPDO 2 communication parameter")):
        rec = odm.ODRecord(name, com)
        for sub, sname, dtype in ((0, "Highest sub-index", dt.UNSIGNED8), (1, "COB-ID", dt.UNSIGNED32),
                                  (2, "Transmission type", dt.UNSIGNED8), (3, "Inhibit time", dt.UNSIGNED16),
                                  (5, "Event timer", dt.UNSIGNED16)):
            v = odm.ODVariable(sname, com, sub)
            v.data_type, v.access_type = dtype, "ro" if sub == 0 else "rw"
            v.default = 5 if sub == 0 else 0
            rec.add_member(v)
        od.add_object(rec)
    for mp, name in ((RPDO1_MAP, "RPDO 1 mapping parameter"), (TPDO1_MAP, "TPDO 1 mapping parameter"),
                     (TPDO2_MAP, "TPDO 2 mapping parameter")):
        arr = odm.ODRecord(name, mp)            # a record: canopen writes its entries whatever the count
        for sub in range(9):
            v = odm.ODVariable("Number of mapped objects" if sub == 0 else f"Mapped object {sub}", mp, sub)
            v.data_type, v.access_type, v.default = (dt.UNSIGNED8 if sub == 0 else dt.UNSIGNED32), "rw", 0
            arr.add_member(v)
        od.add_object(arr)
    return od


class Epos4Drive(TendonDrive):
    """One EPOS4 tendon drive (CiA 402 profile position over CANopen SDO).

    Parameters
    ----------
    node_id : CANopen node id (1…127);  channel, interface, bitrate : python-can bus ("can0", "socketcan",
        1 Mbit/s; "virtual" for tests)
    counts_per_metre : encoder counts per metre of tendon length (sign = direction; ≠ 0)
    zero_length : tendon length at count 0 [m]
    limits : :class:`SafetyLimits` (travel is checked before a target is sent)
    speed : tendon speed to configure [m/s] (needs ``counts_per_turn``: the EPOS4 profile velocity is
        in rpm of the motor shaft); None: keep the drive's stored profile velocity
    counts_per_turn : encoder counts per motor revolution (for ``speed``)
    network : an already connected ``canopen.Network`` to share between drives on one bus
    state_timeout, ack_timeout : seconds to wait for a state transition / a setpoint acknowledge
    cyclic : cyclic synchronous position over PDO with SYNC (module docstring) instead of profile position
    sync_period : SYNC and set-point period [s] (cyclic);  heartbeat_time : producer heartbeat the drive is
        given [s];  heartbeat_timeout, pdo_timeout : silence after which the drive is a DriveFault [s]
    position_window : distance from the target within which a cyclic move counts as reached [m]
    """

    def __init__(self, node_id: int, channel: str = "can0", interface: str = "socketcan", bitrate: int = 1_000_000, *,
                 counts_per_metre: float, zero_length: float = 0.0, limits: Optional[SafetyLimits] = None,
                 speed: Optional[float] = None, counts_per_turn: Optional[float] = None, network=None,
                 state_timeout: float = 1.0, ack_timeout: float = 0.5, name: Optional[str] = None,
                 cyclic: bool = False, sync_period: float = 0.002, heartbeat_time: float = 0.05,
                 heartbeat_timeout: float = 0.5, pdo_timeout: float = 0.25, position_window: float = 2e-6):
        if isinstance(node_id, bool) or not isinstance(node_id, int) or not 1 <= node_id <= 127:
            raise LimitError(f"EPOS4 node_id must be an integer 1…127, got {node_id!r}")
        try:
            cpm = float(counts_per_metre)
            zl = float(zero_length)
        except (TypeError, ValueError):
            raise LimitError("counts_per_metre and zero_length must be numbers") from None
        if not (math.isfinite(cpm) and cpm != 0 and math.isfinite(zl)):
            raise LimitError(f"counts_per_metre must be finite and non-zero, got {counts_per_metre!r}")
        self.node_id, self.channel, self.interface, self.bitrate = node_id, str(channel), str(interface), int(bitrate)
        self.counts_per_metre, self.zero_length = cpm, zl
        self.limits = limits or SafetyLimits()
        if speed is not None:
            self.limits.check_speed(speed)
            if not counts_per_turn or counts_per_turn <= 0:
                raise LimitError("speed needs counts_per_turn (> 0) to convert to the drive's rpm")
        self.speed, self.counts_per_turn = speed, counts_per_turn
        self.state_timeout, self.ack_timeout = float(state_timeout), float(ack_timeout)
        self.name = name or f"EPOS4 node {node_id}"
        self._network, self._own_network = network, network is None
        self.node = None
        self._emcy: list = []
        self._lock = threading.RLock()
        self._cw = 0
        for nm, v in (("sync_period", sync_period), ("heartbeat_time", heartbeat_time),
                      ("heartbeat_timeout", heartbeat_timeout), ("pdo_timeout", pdo_timeout),
                      ("position_window", position_window)):
            if not (isinstance(v, (int, float)) and not isinstance(v, bool) and 0 < v < math.inf):
                raise LimitError(f"{nm} must be a positive number of seconds (metres for position_window), got {v!r}")
        if cyclic and not 1e-4 <= sync_period <= 0.1:
            raise LimitError(f"sync_period {sync_period} s is outside 0.1 ms … 100 ms")
        if cyclic and heartbeat_timeout <= heartbeat_time:
            raise LimitError(f"heartbeat_timeout {heartbeat_timeout} s must exceed heartbeat_time {heartbeat_time} s")
        self.cyclic = bool(cyclic)
        self.sync_period, self.heartbeat_time = float(sync_period), float(heartbeat_time)
        self.heartbeat_timeout, self.pdo_timeout = float(heartbeat_timeout), float(pdo_timeout)
        self.position_window = float(position_window)
        self._running = False                 # cyclic: the interpolator runs
        self._goal = self._sp = None          # cyclic: commanded target and current set-point [counts]
        self._stop = threading.Event()
        self._thread = None
        self._own_sync = False

    # ----------------------------------------------------------------------------------- transport
    def open(self) -> None:
        if self.node is not None:
            return
        import canopen
        logging.getLogger("canopen").setLevel(logging.ERROR)
        try:
            if self._network is None:
                self._network = canopen.Network()
                self._network.NOTIFIER_CYCLE = 0.1          # close within 0.1 s, not 1 s
                self._network.connect(interface=self.interface, channel=self.channel, bitrate=self.bitrate)
            node = canopen.RemoteNode(self.node_id, object_dictionary())
            self._network.add_node(node)
            node.emcy.add_callback(self._on_emcy)
            self.node = node
            node.nmt.send_command(0x01)                        # NMT start remote node
        except (OSError, ValueError, ImportError) as exc:
            self.close()
            raise CommunicationError(f"cannot open CAN {self.interface}:{self.channel}: {exc}",
                                     device=self.name) from None

    def close(self) -> None:
        self._stop_cyclic()
        net = self._network
        if self.node is not None and net is not None:
            try:
                del net[self.node_id]
            except (KeyError, AttributeError):
                pass
        self.node = None
        if self._own_network and net is not None:
            try:
                net.disconnect()
            except Exception:                                  # noqa: BLE001 - closing must not raise
                pass
            self._network = None

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

    def _control(self, cw: int) -> None:
        self._cw = cw                   # first: in cyclic mode the next RPDO carries it too
        self._write(CONTROLWORD, cw)

    def statusword(self) -> int:
        if self._running:
            return int(self._tpdo(1)["Statusword"].raw)
        return self._read(STATUSWORD)

    def _tpdo(self, n: int):
        """TPDO ``n`` as last received; DriveFault when none came for ``pdo_timeout`` (a silent drive)."""
        tp = self._node().tpdo[n]
        ts = getattr(tp, "timestamp", None)
        if ts is None or time.time() - ts > self.pdo_timeout:
            raise DriveFault(f"no TPDO {n} for {self.pdo_timeout * 1e3:g} ms: the drive is silent", device=self.name)
        return tp

    def state(self) -> str:
        return state_of(self.statusword())

    # ----------------------------------------------------------------------------------- faults
    def check(self) -> None:
        """Raise DriveFault on statusword fault, following error or a received EMCY."""
        if self._emcy:
            e = self._emcy[-1]
            raise DriveFault(f"EMCY received ({getattr(e, 'get_desc', lambda: '')() or 'emergency'})",
                             device=self.name, code=int(e.code))
        if self._running:
            ts = self._node().nmt.timestamp
            if ts is None or time.time() - ts > self.heartbeat_timeout:
                raise DriveFault(f"no heartbeat for {self.heartbeat_timeout * 1e3:g} ms: the drive is silent",
                                 device=self.name)
        sw = self.statusword()
        if sw & SW_FAULT:
            raise DriveFault(f"drive in state {state_of(sw)}", device=self.name, code=self._read(ERROR_CODE))
        if sw & SW_FOLLOWING_ERROR:
            raise DriveFault("following error", device=self.name, code=0x8611)

    def fault_reset(self) -> None:
        """Clear a fault (rising edge of controlword bit 7); the drive goes to SWITCH ON DISABLED."""
        self._control(0)
        self._control(CW_FAULT_RESET)
        self._emcy.clear()
        self._wait_state(("SWITCH ON DISABLED", "READY TO SWITCH ON", "SWITCHED ON", "OPERATION ENABLED"))

    def _wait_state(self, states, what: str = "fault reset") -> str:
        t0 = time.monotonic()
        while True:
            sw = self.statusword()
            st = state_of(sw)
            if st in states:
                return st
            if sw & SW_FAULT and "FAULT" not in states:
                raise DriveFault(f"{what}: drive entered {st}", device=self.name, code=self._read(ERROR_CODE))
            if time.monotonic() - t0 > self.state_timeout:
                raise DriveFault(f"{what}: drive stayed in {st}, expected {' or '.join(states)} "
                                 f"within {self.state_timeout:g} s", device=self.name)
            time.sleep(0.002)

    # ----------------------------------------------------------------------------------- motion
    def __enter__(self):
        """Connect and enable (profile position mode, OPERATION ENABLED)."""
        self.open()
        try:
            self.enable()
        except BaseException:
            self.__exit__(*__import__("sys").exc_info())
            raise
        return self

    def enable(self) -> None:
        """Profile position mode (cyclic: the PDO mapping, heartbeat and cyclic synchronous position mode), then
        shutdown → switch on → enable operation (each confirmed); cyclic: then NMT OPERATIONAL, SYNC and the
        set-point interpolator.  A drive that is already enabled in its mode is left as it is (no power-stage
        cycle)."""
        self.check()
        mode = CYCLIC_SYNC_POSITION if self.cyclic else PROFILE_POSITION
        if self._running or (not self.cyclic and self.state() == "OPERATION ENABLED"
                             and self._read(MODE_DISPLAY) == mode):
            return
        if self.cyclic:
            self._configure_pdos()
        self._write(MODE, mode)
        t0 = time.monotonic()
        while self._read(MODE_DISPLAY) != mode:
            if time.monotonic() - t0 > self.state_timeout:
                raise DriveFault(f"drive did not enter {'cyclic synchronous' if self.cyclic else 'profile'} "
                                 "position mode", device=self.name)
            time.sleep(0.002)
        if self.speed is not None:
            rpm = abs(self.speed * self.counts_per_metre) * 60.0 / self.counts_per_turn
            self._write(PROFILE_VELOCITY, max(1, int(round(rpm))))
        for cw, target in ((CW_SHUTDOWN, "READY TO SWITCH ON"), (CW_SWITCH_ON, "SWITCHED ON"),
                           (CW_ENABLE, "OPERATION ENABLED")):
            self._control(cw)
            self._wait_state((target,), what=f"controlword 0x{cw:02X}")
        if self.cyclic:
            self._start_cyclic()

    # ----------------------------------------------------------------------------------- cyclic (CSP)
    def _configure_pdos(self) -> None:
        """Map RPDO 1 / TPDO 1 / TPDO 2 over SDO in PRE-OPERATIONAL and set the producer heartbeat."""
        import canopen
        node = self._node()
        node.nmt.send_command(0x80)                            # NMT enter pre-operational
        try:
            for pdo, variables in ((node.rpdo[1], (CONTROLWORD, TARGET)),
                                   (node.tpdo[1], (STATUSWORD, POSITION)),
                                   (node.tpdo[2], ((FOLLOWING_ERROR, 0), (CURRENT, 2)))):
                pdo.clear()
                for v in variables:
                    index, sub = v if isinstance(v, tuple) else (v, 0)
                    pdo.add_variable(index, sub)
                pdo.cob_id = pdo.predefined_cob_id
                pdo.trans_type = SYNC_TRANSMISSION
                pdo.enabled = True
                pdo.save()
        except (canopen.SdoCommunicationError, canopen.SdoAbortedError, OSError) as exc:
            raise CommunicationError(f"PDO mapping failed: {exc}", device=self.name) from None
        self._write(HEARTBEAT_TIME, max(1, int(round(self.heartbeat_time * 1e3))))

    def _start_cyclic(self) -> None:
        node = self._node()
        counts = self._read(POSITION)
        self._sp = self._goal = float(counts)
        step = self.limits.speed_max * abs(self.counts_per_metre) * self.sync_period
        self._max_step = max(step, 1.0)                        # counts per SYNC period
        rp = node.rpdo[1]
        rp["Controlword"].raw, rp["Target position"].raw = self._cw, counts
        node.nmt.send_command(0x01)                            # NMT start: OPERATIONAL, PDOs flow
        net = self._network
        if getattr(net, "_bellows_sync", None) is None:        # one SYNC producer per bus
            net.sync.start(self.sync_period)
            net._bellows_sync = self.name
            self._own_sync = True
        self._stop.clear()
        self._running = True
        self._thread = threading.Thread(target=self._interpolate, name=f"{self.name} set-points", daemon=True)
        self._thread.start()
        t0 = time.monotonic()
        while True:                                            # first TPDO and heartbeat
            tp = node.tpdo[1]
            if getattr(tp, "timestamp", None) is not None and node.nmt.timestamp is not None:
                break
            if time.monotonic() - t0 > self.state_timeout:
                self._stop_cyclic()
                raise DriveFault(f"no TPDO / heartbeat within {self.state_timeout:g} s after NMT start",
                                 device=self.name)
            time.sleep(0.002)

    def _interpolate(self) -> None:
        """Every SYNC period: step the set-point towards the goal (≤ the speed limit) and send RPDO 1."""
        rp = self.node.rpdo[1]
        next_t = time.monotonic()
        while not self._stop.is_set():
            with self._lock:
                d = self._goal - self._sp
                self._sp += max(-self._max_step, min(self._max_step, d))
                rp["Controlword"].raw = self._cw
                rp["Target position"].raw = int(round(self._sp))
                try:
                    rp.transmit()
                except Exception:                              # noqa: BLE001 - a closed bus ends the thread
                    return
            next_t += self.sync_period
            self._stop.wait(max(0.0, next_t - time.monotonic()))

    def _stop_cyclic(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=1.0)
            self._thread = None
        self._running = False
        net = self._network
        if self._own_sync and net is not None:
            try:
                net.sync.stop()
            except Exception:                                  # noqa: BLE001 - stopping must not raise
                pass
            net._bellows_sync = None
            self._own_sync = False

    def to_counts(self, length: float) -> int:
        c = round((float(length) - self.zero_length) * self.counts_per_metre)
        if not -(2 ** 31) <= c < 2 ** 31:
            raise LimitError(f"length {length} m is {c} counts: outside the 32-bit position range", device=self.name)
        return int(c)

    def to_length(self, counts: int) -> float:
        return self.zero_length + counts / self.counts_per_metre

    def move_to(self, length: float) -> None:
        """Check the travel, send the target and complete the new-setpoint handshake."""
        a = self.limits.check_lengths([length], None, 1)
        counts = self.to_counts(a[0])
        if self._running:                                       # CSP: the interpolator takes it from here
            self.check()
            if state_of(self.statusword()) != "OPERATION ENABLED":
                raise DriveFault(f"move commanded in state {self.state()}", device=self.name)
            with self._lock:
                self._goal = float(counts)
            return
        with self._lock:
            self.check()
            if state_of(self.statusword()) != "OPERATION ENABLED":
                raise DriveFault(f"move commanded in state {self.state()}", device=self.name)
            self._write(TARGET, counts)
            self._control(CW_ENABLE | CW_NEW_SETPOINT | CW_CHANGE_IMMEDIATELY)
            t0 = time.monotonic()
            while not self.statusword() & SW_SETPOINT_ACK:
                if time.monotonic() - t0 > self.ack_timeout:
                    self._control(CW_ENABLE)
                    raise DriveFault(f"setpoint not acknowledged within {self.ack_timeout:g} s", device=self.name)
                time.sleep(0.001)
            self._control(CW_ENABLE | CW_CHANGE_IMMEDIATELY)

    def position(self) -> float:
        if self._running:
            return self.to_length(int(self._tpdo(1)["Position actual value"].raw))
        return self.to_length(self._read(POSITION))

    def current(self) -> float:
        """Motor current [A] (EPOS4 0x30D1:02, mA)."""
        if self._running:
            return int(self._tpdo(2)["Current actual values.Current actual value"].raw) * 1e-3
        return self._read(CURRENT, 2) * 1e-3

    def following_error(self) -> float:
        """Following error actual value [m] (0x60F4; by TPDO in cyclic mode)."""
        c = (int(self._tpdo(2)["Following error actual value"].raw) if self._running else self._read(FOLLOWING_ERROR))
        return c / self.counts_per_metre

    def target_reached(self) -> bool:
        if self._running:
            with self._lock:
                done = self._sp == self._goal
                goal = self._goal
            pos = int(self._tpdo(1)["Position actual value"].raw)
            return done and abs(pos - goal) <= self.position_window * abs(self.counts_per_metre)
        sw = self.statusword()
        return bool(sw & SW_TARGET_REACHED) and not sw & SW_SETPOINT_ACK

    def hold(self) -> None:
        """Halt (controlword bit 8): decelerate and hold position, still enabled.

        Only an OPERATION ENABLED drive is halted.  A drive in any other state (QUICK STOP ACTIVE, FAULT,
        switched off) is already stopped and is left alone: the halt controlword 0x10F carries *enable
        operation*, which would take a quick-stopped drive back to OPERATION ENABLED — a safe-stop path must
        never re-enable a stopped drive."""
        with self._lock:
            if state_of(self.statusword()) == "OPERATION ENABLED":
                if self._running:                                 # CSP: hold the set-point where it is
                    self._goal = self._sp
                else:
                    self._control(CW_ENABLE | CW_HALT)

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
        with self._lock:
            st = state_of(self.statusword())
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
