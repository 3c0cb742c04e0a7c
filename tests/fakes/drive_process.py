r"""Fake CiA 402 drives (maxon EPOS4-like) in a separate process with their own clock.

    register()                                   # fakes.canbridge: the "bellows-bridge" interface
    with DriveProcess([{"node_id": 1, "initial_counts": 1000, "target_counts": 0,
                        "max_counts_per_s": 2e5}]) as proc:
        net = canopen.Network(); net.connect(interface="bellows-bridge", channel=proc.channel)
        ...                                      # the code under test talks CANopen to node 1
        proc.records(1), proc.max_step(1), proc.events(1), proc.positions()

Why a process: the old fake (:mod:`fakes.cia402_drive`) runs its SYNC clock and its motor in threads
of the test process, so when the code under test stalls (GIL held by a compiled kernel, busy threads)
the fake stalls with it and timing defects cannot show.  Here the drives, their motors and the
periodic transmissions (SYNC, heartbeats started with ``send_periodic``) run in a *hub* process
started with ``spawn``; the host reaches it over a Unix stream socket (:class:`fakes.canbridge.BridgeBus`)
and inspects it over a ``multiprocessing.Pipe`` (RPC, every call with a timeout).  This module is
independent of the product code: the object dictionary and the constants below come from the
standards (CiA 301 v4.2, CiA 402 / IEC 61800-7-201) and from maxon's EPOS4 firmware documentation,
not from ``hardware/``.

Hub process
    One event-loop thread owns the bus: it reads and writes the host sockets (non-blocking), hands
    every frame to every drive but its sender and to every host socket but its sender — one bus order
    for everyone — runs the periodic tasks and the servo clock.  Each drive is a canopen
    ``LocalNode`` on its own canopen ``Network`` whose python-can bus is a port of the hub (a
    ``can.BusABC``; the hub delivers frames to it, so no notifier thread per drive: with threads per
    drive the hub's own GIL convoys delayed SYNC ticks by 5-80 ms on a loaded machine).  Drives see
    each other's frames, as on a real bus.  The periodic tasks of the host's
    ``BridgeBus.send_periodic`` (the SYNC producer) and of the drives (heartbeat producers) run on the
    loop with ``time.monotonic()`` deadlines on a fixed grid: a tick the hub itself was late for is
    sent once, late, and the grid points it missed are skipped (counted in
    :meth:`DriveProcess.hub_stats`), never sent in a burst.  The servo clock advances the motors and
    the watchdogs every ``servo_period`` (2 ms); every read of a drive also advances it to "now"
    first, so positions are exact in time.  A second thread answers the RPC calls.

    The hub asks for SCHED_FIFO priority 1 (``realtime=True``, silently normal priority where the
    system refuses): a real drive's clock is hardware and socketcan's broadcast manager runs on
    kernel timers, neither waits for a busy CPU; at normal priority, on a 2-core machine loaded by
    other test processes, ticks came 5-40 ms late.  The hub uses ~10-15 % of a core at a 2 ms SYNC
    with one drive in CSP; if it ever uses more than half a core over a second it drops back to
    normal priority by itself (a hub event says so).

Modelled per drive (the specification in brackets)
    * NMT slave [CiA 301 network management]: boot-up message, PRE-OPERATIONAL, start / stop /
      pre-operational / reset node / reset communication (both send a boot-up and return to PRE-OPERATIONAL;
      reset node also reboots the drive: SWITCH ON DISABLED, 0x607A and all parameters back to their
      power-on values); heartbeat producer 0x1017 (canopen's ``NmtSlave``).
    * SDO server (canopen's ``SdoServer``) with access checks; aborts: 0x06010002 write to read-only,
      0x06020000 no object, 0x06090011 no sub-index, 0x06090030 value range (unsupported mode, reserved
      transmission type, COB-ID change of a valid PDO), 0x06040041 object not mappable, 0x06040042 mapping
      longer than 64 bit, 0x08000022 device state (mapping written while the PDO is valid or its sub-index 0
      is not 0 [CiA 301, PDO mapping procedure], or while NMT OPERATIONAL [EPOS4: mapping only in
      PRE-OPERATIONAL]).
    * PDOs [CiA 301 PDO protocol, objects 0x1400-0x1BFF]: RPDO 1–4 / TPDO 1–4, decoded and encoded
      generically from the mapping parameters the host wrote (byte-aligned entries).  Only in NMT
      OPERATIONAL.  RPDO transmission type 0–240: the data of the LAST frame received before a SYNC is
      applied at that SYNC (an earlier frame of the same period is overwritten, as in a real receive
      buffer); 254/255: applied on reception.  All mapped objects are written, then a mapped controlword is
      processed as a controlword.  TPDO type 1–240: sent every n-th SYNC with data sampled at the SYNC; type
      0: at a SYNC when the data changed; 254/255 with an event timer (sub 5): periodically.  RPDO deadline
      monitoring [CiA 301 event timer of an RPDO; EPOS4 "RPDO timeout" 0x8250]: with 0x140x sub 5 ≠ 0, once
      a first RPDO came, a gap longer than that faults the drive.  An RPDO shorter than its mapping faults
      the drive with 0x8210 (PDO length error).
    * Heartbeat consumer 0x1016 sub 1 [CiA 301 error control, heartbeat consumer]: bits 16–23 producer node,
      bits 0–15 time [ms].  Monitoring starts with the first heartbeat (or boot-up) frame of that producer;
      a gap longer than the consumer time faults the drive (0x603F = 0x8130, heartbeat error, EMCY) and
      stops it; monitoring is then inactive until the next heartbeat.
    * EMCY producer [CiA 301 emergency object]: on every fault (code, error register 0x1001, 5 zero bytes)
      and the "error reset" EMCY (code 0x0000) after a fault reset.
    * CiA 402 power state machine [CiA 402-2 drive state machine, controlword 0x6040, statusword 0x6041]:
      shutdown (cw & 0x07 = 0x06), switch on (cw & 0x0F = 0x07), enable operation (0x0F, also directly from
      READY TO SWITCH ON: transitions 3+4, as the EPOS4 allows), disable voltage (bit 1 = 0), quick stop
      (bit 2 = 0, bit 1 = 1), fault reset (rising edge of bit 7, only in FAULT).  Quick stop option code
      0x605A (stored value 6 here: ramp down and stay in QUICK STOP ACTIVE; 0–4: to SWITCH ON DISABLED
      after the stop; 5–8: stay) — enable operation leaves QUICK STOP ACTIVE (transition 16).  Statusword: state
      bits 0–3, 5, 6; bit 4 voltage enabled (always: the supply is on); bit 9 remote; bit 10 target reached;
      bit 11 internal limit active (software position limit); bit 12 / 13 mode specific. Outside OPERATION
      ENABLED / QUICK STOP ACTIVE the power stage is off: the motor does not move and the position demand
      follows the actual position.  A fault is immediate (no FAULT REACTION ACTIVE phase): demand := actual,
      the motor stops where it is.
    * Profile position (0x6060 = 1) [CiA 402-2 profile position mode]: controlword bit 4 rising edge takes
      0x607A (bit 6: relative to the last target), statusword bit 12 acknowledges, cleared when bit 4 is
      cleared; bit 5 = 1 changes the running move at once, bit 5 = 0 buffers one set-point until the move is
      done (bit 12 stays set while the buffer is full, a further set-point is ignored); bit 8 halt
      decelerates with 0x6084 and resumes the move when cleared.  The trajectory is a trapezoid: profile
      velocity 0x6081, acceleration 0x6083, deceleration 0x6084 [rpm, rpm/s, converted with
      ``counts_per_turn``: counts/s = rpm · counts_per_turn / 60], capped by the motor's
      ``max_counts_per_s``.  Never-written parameters use stored values (1000 rpm, 10000 rpm/s, 10000
      rpm/s).  Bit 10 target reached: the trajectory is at the target, stopped, and the actual position is
      there (or, halted, stopped).  Bit 13: following error.
    * Cyclic synchronous position (0x6060 = 8) [CiA 402-2 cyclic synchronous position mode]: at every SYNC
      while OPERATION ENABLED and NMT OPERATIONAL the position demand becomes 0x607A (written by the last
      RPDO before that SYNC or by an SDO write).  ENTERING OPERATION ENABLED in CSP (or switching to CSP
      while enabled) makes the demand jump to 0x607A as it is at that moment — a stale 0x607A (an old goal,
      or the power-on value) makes the motor jump as on a real drive (recorded as an event and as a step in
      the SYNC records).  Statusword bit 12 "drive follows the command value" (1 in OPERATION ENABLED), bit
      13 following error, bit 10 reserved (0).
    * Motor: the actual position follows the demand at no more than ``max_counts_per_s`` (a large step
      lags).  Velocity actual 0x606C [rpm].  Current 0x30D1 sub 1/2 [mA] is a stand-in (proportional to the
      following error plus a friction term), not a motor model.
    * Following error [CiA 402-2 position control function, objects 0x6065/0x6066/0x60F4]: with 0x6065 ≠ 0
      (and ≠ 0xFFFFFFFF, "off"), |demand − actual| > 0x6065 for longer than 0x6066 ms in OPERATION ENABLED
      faults the drive (0x603F = 0x8611, EMCY, statusword bit 13) and stops it.
    * Software position limits 0x607D [CiA 402-2, "position limit function"]: with min < max, a demand (CSP)
      or a profile target (PP) outside is clamped, statusword bit 11 is set and an event is recorded (once
      per excursion).  The stored limits are the full 32-bit range (no limit).
    * Interpolation time period 0x60C2 is stored; with sub 1 ≠ 0, a SYNC gap longer than twice it in CSP is
      recorded as an event (no fault).

Not modelled: the SDO server answering in NMT STOPPED (it answers in every state); SYNC counter and
SYNC window; PDO inhibit times; bit-packed (non byte-aligned) PDO entries; the error history 0x1003;
homing, velocity and torque modes (modes 3, 6, 9, 10 are accepted and shown in 0x6061 but the drive
only holds its position in them); an interpolated CSP demand between SYNCs (the demand steps at each
SYNC and the motor chases it at its speed limit); a quick stop ramp in CSP (the demand stops at the
actual position); the fault reaction ramp; encoder noise, motor dynamics, current and torque limits;
bus timing (bit rate, arbitration): frames travel as fast as the sockets go.  ``silence(node)``
stops heartbeat, TPDOs and EMCYs of a drive but its SDO server still answers.
"""

from __future__ import annotations

import collections
import itertools
import logging
import math
import multiprocessing
import os
import select
import shutil
import socket
import struct
import tempfile
import threading
import time
import traceback
from typing import Optional

import can
import canopen
from can.broadcastmanager import (LimitedDurationCyclicSendTaskABC, ModifiableCyclicTaskABC,
                                  RestartableCyclicTaskABC)
from canopen import objectdictionary as odm
from canopen.objectdictionary import datatypes as dt
from canopen.sdo import SdoAbortedError

try:                                            # imported as fakes.drive_process (the tests) or top-level
    from . import canbridge as cb
except ImportError:                             # pragma: no cover
    import canbridge as cb

log = logging.getLogger(__name__)

# ---------------------------------------------------------------------------------------------- CiA 301
SYNC_COB, EMCY_BASE, HEARTBEAT_BASE, NMT_COB = 0x080, 0x080, 0x700, 0x000
DEVICE_TYPE, ERROR_REGISTER, COB_ID_SYNC, CYCLE_PERIOD = 0x1000, 0x1001, 0x1005, 0x1006
CONSUMER_HEARTBEAT, PRODUCER_HEARTBEAT, IDENTITY = 0x1016, 0x1017, 0x1018
RPDO_COM, RPDO_MAP, TPDO_COM, TPDO_MAP = 0x1400, 0x1600, 0x1800, 0x1A00
N_PDO = 4
PDO_INVALID = 1 << 31
NMT_START, NMT_STOP, NMT_PREOP, NMT_RESET_NODE, NMT_RESET_COMM = 0x01, 0x02, 0x80, 0x81, 0x82
# SDO abort codes (CiA 301 table "SDO abort codes")
ABORT_VALUE_RANGE, ABORT_NOT_MAPPABLE, ABORT_PDO_LENGTH = 0x06090030, 0x06040041, 0x06040042
ABORT_DEVICE_STATE = 0x08000022
# error codes (CiA 301 / CiA 402 / EPOS4)
ERR_HEARTBEAT, ERR_PDO_LENGTH, ERR_RPDO_TIMEOUT, ERR_FOLLOWING = 0x8130, 0x8210, 0x8250, 0x8611
MAXON_VENDOR_ID = 0x000000FB

# ---------------------------------------------------------------------------------------------- CiA 402
CONTROLWORD, STATUSWORD, QUICK_STOP_OPTION = 0x6040, 0x6041, 0x605A
MODES, MODES_DISPLAY, ERROR_CODE = 0x6060, 0x6061, 0x603F
DEMAND, ACTUAL, FE_WINDOW, FE_TIMEOUT = 0x6062, 0x6064, 0x6065, 0x6066
VELOCITY_ACTUAL, TARGET, SW_LIMITS = 0x606C, 0x607A, 0x607D
PROFILE_VELOCITY, PROFILE_ACCEL, PROFILE_DECEL, QUICK_STOP_DECEL = 0x6081, 0x6083, 0x6084, 0x6085
INTERPOLATION_PERIOD, FOLLOWING_ERROR_ACTUAL, CURRENT_ACTUAL = 0x60C2, 0x60F4, 0x30D1
PP, CSP = 1, 8
SUPPORTED_MODES = (0, 1, 3, 6, 8, 9, 10)

SOD, RTSO, SO, OE, QSA, FAULT = ("SWITCH ON DISABLED", "READY TO SWITCH ON", "SWITCHED ON",
                                 "OPERATION ENABLED", "QUICK STOP ACTIVE", "FAULT")
STATE_BITS = {"NOT READY TO SWITCH ON": 0x00, SOD: 0x40, RTSO: 0x21, SO: 0x23, OE: 0x27, QSA: 0x07,
              "FAULT REACTION ACTIVE": 0x0F, FAULT: 0x08}
SW_VOLTAGE, SW_REMOTE, SW_TARGET_REACHED, SW_LIMIT = 1 << 4, 1 << 9, 1 << 10, 1 << 11
SW_BIT12, SW_FOLLOWING = 1 << 12, 1 << 13
CW_NEW_SETPOINT, CW_IMMEDIATE, CW_RELATIVE, CW_HALT, CW_FAULT_RESET = 1 << 4, 1 << 5, 1 << 6, 1 << 8, 1 << 7

I32_MIN, I32_MAX = -(2 ** 31), 2 ** 31 - 1
SUBSTEP = 1e-3                                   # motor integration step [s]


def object_dictionary(node_id: int = 1) -> odm.ObjectDictionary:
    """The fake drive's object dictionary (CiA 301 communication area, CiA 402 objects, EPOS4 0x30D1).

    Defaults are the drive's stored (power-on) values."""
    od = odm.ObjectDictionary()

    def var(index, sub, name, dtype, access, default=0, mappable=False):
        v = odm.ODVariable(name, index, sub)
        v.data_type, v.access_type, v.default, v.pdo_mappable = dtype, access, default, mappable
        return v

    def record(index, name, members):
        rec = odm.ODRecord(name, index)
        rec.add_member(var(index, 0, "Highest sub-index supported", dt.UNSIGNED8, "ro", max(m[0] for m in members)))
        for sub, sname, dtype, access, default, mappable in members:
            rec.add_member(var(index, sub, sname, dtype, access, default, mappable))
        od.add_object(rec)

    for index, name, dtype, access, default, mappable in (
            (DEVICE_TYPE, "Device type", dt.UNSIGNED32, "ro", 0x00020192, False),     # CiA 402 servo drive
            (ERROR_REGISTER, "Error register", dt.UNSIGNED8, "ro", 0, True),
            (COB_ID_SYNC, "COB-ID SYNC", dt.UNSIGNED32, "rw", SYNC_COB, False),
            (CYCLE_PERIOD, "Communication cycle period", dt.UNSIGNED32, "rw", 0, False),
            (PRODUCER_HEARTBEAT, "Producer heartbeat time", dt.UNSIGNED16, "rw", 0, False),
            (ERROR_CODE, "Error code", dt.UNSIGNED16, "ro", 0, True),
            (CONTROLWORD, "Controlword", dt.UNSIGNED16, "rw", 0, True),
            (STATUSWORD, "Statusword", dt.UNSIGNED16, "ro", 0, True),
            (QUICK_STOP_OPTION, "Quick stop option code", dt.INTEGER16, "rw", 6, False),
            (MODES, "Modes of operation", dt.INTEGER8, "rw", 0, True),
            (MODES_DISPLAY, "Modes of operation display", dt.INTEGER8, "ro", 0, True),
            (DEMAND, "Position demand value", dt.INTEGER32, "ro", 0, True),
            (ACTUAL, "Position actual value", dt.INTEGER32, "ro", 0, True),
            (FE_WINDOW, "Following error window", dt.UNSIGNED32, "rw", 0, False),
            (FE_TIMEOUT, "Following error time out", dt.UNSIGNED16, "rw", 0, False),
            (VELOCITY_ACTUAL, "Velocity actual value", dt.INTEGER32, "ro", 0, True),
            (TARGET, "Target position", dt.INTEGER32, "rw", 0, True),
            (PROFILE_VELOCITY, "Profile velocity", dt.UNSIGNED32, "rw", 1000, True),
            (PROFILE_ACCEL, "Profile acceleration", dt.UNSIGNED32, "rw", 10000, True),
            (PROFILE_DECEL, "Profile deceleration", dt.UNSIGNED32, "rw", 10000, True),
            (QUICK_STOP_DECEL, "Quick stop deceleration", dt.UNSIGNED32, "rw", 10000, False),
            (FOLLOWING_ERROR_ACTUAL, "Following error actual value", dt.INTEGER32, "ro", 0, True)):
        od.add_object(var(index, 0, name, dtype, access, default, mappable))
    record(CONSUMER_HEARTBEAT, "Consumer heartbeat time",
           [(1, "Consumer heartbeat time 1", dt.UNSIGNED32, "rw", 0, False)])
    record(IDENTITY, "Identity object", [(1, "Vendor-ID", dt.UNSIGNED32, "ro", MAXON_VENDOR_ID, False),
                                         (2, "Product code", dt.UNSIGNED32, "ro", 0x60500000, False),
                                         (3, "Revision number", dt.UNSIGNED32, "ro", 0x01700000, False),
                                         (4, "Serial number", dt.UNSIGNED32, "ro", 0x1000 + node_id, False)])
    record(SW_LIMITS, "Software position limit", [(1, "Min position limit", dt.INTEGER32, "rw", I32_MIN, False),
                                                  (2, "Max position limit", dt.INTEGER32, "rw", I32_MAX, False)])
    record(INTERPOLATION_PERIOD, "Interpolation time period",
           [(1, "Interpolation time period value", dt.UNSIGNED8, "rw", 0, False),
            (2, "Interpolation time index", dt.INTEGER8, "rw", -3, False)])
    record(CURRENT_ACTUAL, "Current actual values", [(1, "Current actual value averaged", dt.INTEGER32, "ro", 0, True),
                                                     (2, "Current actual value", dt.INTEGER32, "ro", 0, True)])
    for n in range(N_PDO):
        for com, mp, kind, base in ((RPDO_COM + n, RPDO_MAP + n, "RPDO", 0x200),
                                    (TPDO_COM + n, TPDO_MAP + n, "TPDO", 0x180)):
            cob = PDO_INVALID | (base + 0x100 * n + node_id)         # predefined connection set, not valid
            record(com, f"{kind} {n + 1} communication parameter",
                   [(1, "COB-ID", dt.UNSIGNED32, "rw", cob, False),
                    (2, "Transmission type", dt.UNSIGNED8, "rw", 255, False),
                    (3, "Inhibit time", dt.UNSIGNED16, "rw", 0, False),
                    (5, "Event timer", dt.UNSIGNED16, "rw", 0, False)])
            rec = odm.ODRecord(f"{kind} {n + 1} mapping parameter", mp)
            rec.add_member(var(mp, 0, "Number of mapped objects", dt.UNSIGNED8, "rw", 0))
            for sub in range(1, 9):
                rec.add_member(var(mp, sub, f"Mapped object {sub}", dt.UNSIGNED32, "rw", 0))
            od.add_object(rec)
    return od


def _find(od: odm.ObjectDictionary, index: int, sub: int):
    if index not in od:
        return None
    obj = od[index]
    if isinstance(obj, odm.ODVariable):
        return obj if sub == 0 else None
    return obj[sub] if sub in obj else None


def _clip32(x: float) -> int:
    return int(max(I32_MIN, min(I32_MAX, round(x))))


# ================================================================================================ drive
class FakeDrive:
    """One fake drive in the hub process (see the module docstring for what is modelled).

    Its canopen ``Network`` sends through ``port`` (a python-can bus of the hub); the hub hands it every
    frame of the bus with :meth:`deliver` (canopen's SDO server and NMT slave first, then the drive)."""

    def __init__(self, port: can.BusABC, node_id: int, initial_counts: int, target_counts: int,
                 max_counts_per_s: float, counts_per_turn: float, stored: Optional[dict] = None):
        self.node_id = int(node_id)
        self.cpt = float(counts_per_turn)
        self.vmax = float(max_counts_per_s)
        if not (self.vmax > 0 and self.cpt > 0):
            raise ValueError("max_counts_per_s and counts_per_turn must be > 0")
        self.od = object_dictionary(self.node_id)
        self.defaults = {}                                  # (index, sub) -> stored default of the OD
        for index in self.od:
            obj = self.od[index]
            for v in ([obj] if isinstance(obj, odm.ODVariable) else obj.values()):
                self.defaults[(v.index, v.subindex)] = int(v.default or 0)
        self._maps: dict = {}                               # mapping index -> decoded entries (cache)
        self.power_on = {}                                  # (index, sub) -> stored value
        for key, value in (stored or {}).items():
            index, sub = key if isinstance(key, tuple) else (key, 0)
            if _find(self.od, index, sub) is None:
                raise ValueError(f"stored value for 0x{index:04X}:{sub}: no such object")
            self.power_on[(index, sub)] = int(value)
        self.power_on[(TARGET, 0)] = int(target_counts)
        self.lock = threading.RLock()
        self.records = collections.deque(maxlen=200_000)
        self.events = collections.deque(maxlen=20_000)
        self.silent = False
        self.actual = float(initial_counts)
        self.t = time.monotonic()
        self._power_up()
        self.port = port
        self.network = canopen.Network(port)                # no notifier thread: the hub delivers frames
        self.node = self.network.create_node(self.node_id, self.od)
        self.node.add_read_callback(self._on_read)
        self.node.add_write_callback(self._on_write)
        self._boot()

    # --------------------------------------------------------------------------------- state
    def _power_up(self) -> None:
        """Application state after power-on / reset node (the motor stays where it is)."""
        self.values = dict(self.power_on)
        self._maps = {}
        self.state = SOD                    # NOT READY TO SWITCH ON passes on its own (transition 1)
        self.cw = 0
        self.demand = self.actual
        self.vel = 0.0                      # trajectory (demand) velocity [counts/s]
        self.act_vel = 0.0
        self.pp_target = self.pp_buffer = None
        self.ack = self.halt = self.qs_braking = False
        self.fault_code = self.err_reg = 0
        self.following_flag = self.limit_active = False
        self.ferr_since = None
        self._reset_comm_state()

    def _reset_comm_state(self) -> None:
        self.rpdo_pending = [None] * N_PDO
        self.rpdo_last = [None] * N_PDO
        self.rpdo1_since_sync = 0
        self.tpdo_count = [0] * N_PDO
        self.tpdo_last = [None] * N_PDO
        self.tpdo_next = [None] * N_PDO
        self.hb_last = None
        self.prev_sync_demand = None
        self.last_sync_t = None

    def _boot(self) -> None:
        """Boot-up message, then PRE-OPERATIONAL (heartbeat producer from 0x1017) [CiA 301 NMT]."""
        self.node.nmt.send_command(NMT_RESET_NODE)          # state INITIALISING: canopen sends the boot-up
        self.node.nmt.send_command(NMT_PREOP)               # and starts the heartbeat on 0x1017
        if self.silent:
            self.node.nmt.stop_heartbeat()

    def event(self, text: str) -> None:
        self.events.append((time.time(), text))

    def get(self, index: int, sub: int = 0) -> int:
        """An object's written or stored value (not the computed ones: see :meth:`value`)."""
        v = self.values.get((index, sub))
        return v if v is not None else self.defaults.get((index, sub), 0)

    @property
    def mode(self) -> int:
        return self.get(MODES)

    @property
    def nmt(self) -> str:
        return self.node.nmt.state

    def statusword(self) -> int:
        sw = STATE_BITS[self.state] | SW_VOLTAGE | SW_REMOTE
        if self.limit_active:
            sw |= SW_LIMIT
        if self.following_flag:
            sw |= SW_FOLLOWING
        if self.state == OE:
            if self.mode == PP:
                if self.ack:
                    sw |= SW_BIT12
                if self.halt:
                    done = self.vel == 0.0
                else:
                    done = self.pp_target is None or (self.pp_buffer is None and self.vel == 0.0
                                                       and self.demand == self.pp_target
                                                       and abs(self.actual - self.pp_target) < 0.5)
                if done:
                    sw |= SW_TARGET_REACHED
            elif self.mode == CSP:
                sw |= SW_BIT12                              # drive follows the command value
            elif self.act_vel == 0.0:
                sw |= SW_TARGET_REACHED
        elif self.state == QSA and not self.qs_braking:
            sw |= SW_TARGET_REACHED
        return sw

    def value(self, index: int, sub: int = 0) -> int:
        """Current value of an object (dynamic ones computed, the others as written / stored)."""
        if index == STATUSWORD:
            return self.statusword()
        if index == ACTUAL:
            return _clip32(self.actual)
        if index == DEMAND:
            return _clip32(self.demand)
        if index == FOLLOWING_ERROR_ACTUAL:
            return _clip32(self.demand - self.actual)
        if index == MODES_DISPLAY:
            return self.mode
        if index == ERROR_CODE:
            return self.fault_code
        if index == ERROR_REGISTER:
            return self.err_reg
        if index == CONTROLWORD:
            return self.cw
        if index == VELOCITY_ACTUAL:
            return _clip32(self.act_vel * 60.0 / self.cpt)
        if index == CURRENT_ACTUAL and sub in (1, 2):
            if self.state not in (OE, QSA):
                return 0
            ferr = self.demand - self.actual
            friction = 120.0 * (1 if self.act_vel > 0 else -1 if self.act_vel < 0 else 0)
            return int(max(-10000, min(10000, 0.5 * ferr + friction)))
        return self.get(index, sub)

    # --------------------------------------------------------------------------------- motion
    def cps(self, rpm: float) -> float:
        """rpm (or rpm/s) of the motor shaft → counts/s (counts/s²)."""
        return float(rpm) * self.cpt / 60.0

    def limit(self, counts: float) -> float:
        """Software position limits 0x607D (active when min < max)."""
        lo, hi = self.get(SW_LIMITS, 1), self.get(SW_LIMITS, 2)
        if lo < hi and not lo <= counts <= hi:
            clamped = min(hi, max(lo, counts))
            if not self.limit_active:
                self.event(f"software position limit: demand {counts:.0f} clamped to {clamped:.0f} "
                           f"(0x607D = [{lo}, {hi}])")
            self.limit_active = True
            return float(clamped)
        self.limit_active = False
        return float(counts)

    def advance(self, now: float) -> None:
        """Integrate the trajectory, the motor and the following-error monitor up to ``now``."""
        t = self.t
        while now - t > 1e-9:
            h = min(SUBSTEP, now - t)
            t += h
            self._step(h, t)
        self.t = max(self.t, now)

    def _step(self, h: float, t: float) -> None:
        st = self.state
        if st == OE:
            if self.mode == PP:
                self._profile(h, self.cps(self.get(PROFILE_DECEL)))
        elif st == QSA:
            if self.qs_braking:
                self._brake(h, self.cps(self.get(QUICK_STOP_DECEL)))
                if self.vel == 0.0:
                    self.qs_braking = False
                    if self.get(QUICK_STOP_OPTION) in (0, 1, 2, 3, 4):
                        self._set_state(SOD)
        else:
            self.demand, self.vel = self.actual, 0.0
        if self.state in (OE, QSA):
            err = self.demand - self.actual
            move = max(-self.vmax * h, min(self.vmax * h, err))
            self.actual += move
            self.act_vel = move / h
        else:
            self.act_vel = 0.0
        if self.state == OE:                                   # following error monitor
            window = self.get(FE_WINDOW)
            if window not in (0, 0xFFFFFFFF) and abs(self.demand - self.actual) > window:
                if self.ferr_since is None:
                    self.ferr_since = t
                elif t - self.ferr_since > self.get(FE_TIMEOUT) * 1e-3:
                    self.fault(ERR_FOLLOWING, f"following error {self.demand - self.actual:.0f} counts > window "
                                              f"{window} for {1e3 * (t - self.ferr_since):.1f} ms "
                                              f"(0x6066 = {self.get(FE_TIMEOUT)} ms)", following=True)
            else:
                self.ferr_since = None

    def _brake(self, h: float, dec: float) -> None:
        dv = max(dec, 1.0) * h
        self.vel = 0.0 if abs(self.vel) <= dv else self.vel - math.copysign(dv, self.vel)
        self.demand += self.vel * h

    def _profile(self, h: float, dec: float) -> None:
        """Trapezoidal profile generator of profile position mode (one step ``h``)."""
        if self.halt:
            self._brake(h, dec)
            return
        if self.pp_target is None:
            self.vel = 0.0
            return
        dec = max(dec, 1.0)
        acc = max(self.cps(self.get(PROFILE_ACCEL)), 1.0)
        vcap = max(min(self.cps(self.get(PROFILE_VELOCITY)), self.vmax), 1e-9)
        d = self.pp_target - self.demand
        if d == 0.0 and self.vel == 0.0:
            self._next_setpoint()
            return
        s = math.copysign(1.0, d if d != 0.0 else -self.vel)
        vs = self.vel * s                                       # speed towards the target
        if vs < 0:                                              # moving away: brake first
            vs_new = min(vs + dec * h, 0.0)
        else:
            up = min(vs + acc * h, vcap) if vs <= vcap else max(vs - dec * h, vcap)
            vs_new = min(up, math.sqrt(2.0 * dec * abs(d)))
        move = vs_new * h
        if vs_new > 0 and move >= abs(d):
            self.demand, self.vel = float(self.pp_target), 0.0
            self._next_setpoint()
        else:
            self.demand += s * move
            self.vel = s * vs_new

    def _next_setpoint(self) -> None:
        if self.pp_buffer is not None and self.demand == self.pp_target and self.vel == 0.0:
            self.pp_target, self.pp_buffer = self.pp_buffer, None
            if not self.cw & CW_NEW_SETPOINT:
                self.ack = False

    # --------------------------------------------------------------------------------- state machine
    def _set_state(self, new: str) -> None:
        old = self.state
        if new == old:
            return
        self.state = new
        if new == OE:
            self.ferr_since = None
            self.vel, self.pp_target, self.pp_buffer, self.ack = 0.0, None, None, False
            if self.mode == CSP:
                self._enter_csp("enable operation")
            else:
                self.demand = self.actual
        elif new == QSA:
            if self.mode == PP and self.vel != 0.0:
                self.qs_braking = True
            else:
                self.demand, self.vel = self.actual, 0.0
                if self.get(QUICK_STOP_OPTION) in (0, 1, 2, 3, 4):
                    self.state = SOD
        else:
            self.demand, self.vel, self.qs_braking = self.actual, 0.0, False
            self.pp_target = self.pp_buffer = None
            self.ack = False

    def _enter_csp(self, why: str) -> None:
        """CSP takes the target 0x607A as its demand from now on — whatever 0x607A holds."""
        before = self.demand
        if self.prev_sync_demand is None or self.last_sync_t is None or time.monotonic() - self.last_sync_t > 0.5:
            self.prev_sync_demand = _clip32(before)     # no recent SYNC: the next record's step starts here
        self.demand = self.limit(self.get(TARGET))
        if abs(self.demand - before) >= 0.5:
            self.event(f"{why} in CSP: demand jumps from {before:.0f} to 0x607A = {self.demand:.0f} "
                       f"({self.demand - before:+.0f} counts)")

    def controlword(self, cw: int) -> None:
        prev, self.cw = self.cw, cw
        st = self.state
        if st == FAULT:
            if cw & CW_FAULT_RESET and not prev & CW_FAULT_RESET:
                self.fault_reset()
            return
        new = st
        if not cw & 0x02:                                           # disable voltage
            if st in (RTSO, SO, OE, QSA):
                new = SOD
        elif not cw & 0x04:                                         # quick stop
            if st in (RTSO, SO):
                new = SOD
            elif st == OE:
                new = QSA
        elif cw & 0x07 == 0x06:                                     # shutdown
            if st in (SOD, SO, OE):
                new = RTSO
        elif cw & 0x0F == 0x07:                                     # switch on (disable operation)
            if st in (RTSO, OE):
                new = SO
        elif cw & 0x0F == 0x0F:                                     # enable operation
            if st in (RTSO, SO):
                new = OE
            elif st == QSA and self.get(QUICK_STOP_OPTION) in (5, 6, 7, 8):
                new = OE
        self._set_state(new)
        if self.state == OE and self.mode == PP:
            self.halt = bool(cw & CW_HALT)
            if cw & CW_NEW_SETPOINT and not prev & CW_NEW_SETPOINT:
                if not self.ack:                                    # buffer free: take the set-point
                    base = self.pp_target if self.pp_target is not None else self.demand
                    goal = self.limit(base + self.get(TARGET) if cw & CW_RELATIVE else self.get(TARGET))
                    idle = self.pp_target is None or (self.vel == 0.0 and self.demand == self.pp_target)
                    if cw & CW_IMMEDIATE or idle:
                        self.pp_target, self.pp_buffer = goal, None
                    else:
                        self.pp_buffer = goal
                    self.ack = True
            elif not cw & CW_NEW_SETPOINT and self.pp_buffer is None:
                self.ack = False
        else:
            self.halt = False

    def set_mode(self, mode: int) -> None:
        old = self.mode
        self.values[(MODES, 0)] = mode
        if self.state == OE and mode != old:
            self.vel, self.pp_target, self.pp_buffer, self.ack, self.halt = 0.0, None, None, False, False
            if mode == CSP:
                self._enter_csp("mode switch")

    def fault(self, code: int, text: str, following: bool = False) -> None:
        if self.state == FAULT:
            self.event(f"0x{code:04X} while in FAULT: {text}")
            return
        self.state = FAULT
        self.fault_code = code
        self.err_reg |= 0x01 | (0x10 if code & 0xFF00 in (0x8100, 0x8200) else 0)
        self.following_flag = self.following_flag or following
        self.demand, self.vel = self.actual, 0.0
        self.pp_target = self.pp_buffer = None
        self.ack = self.halt = self.qs_braking = False
        self.ferr_since = None
        self.event(f"FAULT 0x{code:04X}: {text}")
        if not self.silent:
            self.node.emcy.send(code, self.err_reg, b"\0" * 5)

    def fault_reset(self) -> None:
        self.state = SOD
        self.event(f"fault reset (0x603F was 0x{self.fault_code:04X})")
        self.fault_code = self.err_reg = 0
        self.following_flag = False
        if not self.silent:
            self.node.emcy.send(0x0000, 0, b"\0" * 5)           # "error reset / no error" [CiA 301]

    # --------------------------------------------------------------------------------- SDO
    def _on_read(self, index, subindex, od):
        with self.lock:
            self.advance(time.monotonic())
            return self.value(index, subindex)

    def _on_write(self, index, subindex, od, data):
        value = od.decode_raw(data)
        with self.lock:
            self.advance(time.monotonic())
            self._check_write(index, subindex, value)
            self.store(index, subindex, value)
            if index == PRODUCER_HEARTBEAT and self.silent:     # canopen's NmtSlave (re)started it
                self.node.nmt.stop_heartbeat()

    def _check_write(self, index: int, sub: int, value: int) -> None:
        if index == MODES and value not in SUPPORTED_MODES:
            raise SdoAbortedError(ABORT_VALUE_RANGE)
        for com in (RPDO_COM, TPDO_COM):
            if com <= index < com + N_PDO:
                cob = self.get(index, 1)
                if sub == 1 and not cob & PDO_INVALID and not value & PDO_INVALID and (value ^ cob) & 0x1FFFFFFF:
                    raise SdoAbortedError(ABORT_VALUE_RANGE)        # COB-ID of an existing PDO changed
                if sub == 1 and not value & PDO_INVALID:
                    self._check_mapping(index - com + (RPDO_MAP if com == RPDO_COM else TPDO_MAP))
                if sub == 2 and (241 <= value <= 253):
                    raise SdoAbortedError(ABORT_VALUE_RANGE)        # reserved / RTR-only types
        for mp, com in ((RPDO_MAP, RPDO_COM), (TPDO_MAP, TPDO_COM)):
            if mp <= index < mp + N_PDO:
                if self.nmt == "OPERATIONAL":
                    raise SdoAbortedError(ABORT_DEVICE_STATE)       # EPOS4: mapping only in PRE-OPERATIONAL
                if not self.get(com + index - mp, 1) & PDO_INVALID:
                    raise SdoAbortedError(ABORT_DEVICE_STATE)       # PDO still valid
                if sub == 0:
                    if value > 8:
                        raise SdoAbortedError(ABORT_VALUE_RANGE)
                    self._check_mapping(index, count=value)
                else:
                    if self.get(index, 0) != 0:
                        raise SdoAbortedError(ABORT_DEVICE_STATE)   # sub-index 0 must be 0 first
                    if value:
                        self._check_entry(index, value)

    def _check_entry(self, map_index: int, entry: int) -> int:
        index, sub, bits = entry >> 16, (entry >> 8) & 0xFF, entry & 0xFF
        obj = _find(self.od, index, sub)
        rx = RPDO_MAP <= map_index < RPDO_MAP + N_PDO
        if obj is None or not obj.pdo_mappable or (rx and not obj.writable) or (not rx and not obj.readable):
            raise SdoAbortedError(ABORT_NOT_MAPPABLE)
        if bits != len(obj):
            raise SdoAbortedError(ABORT_NOT_MAPPABLE)
        return bits

    def _check_mapping(self, map_index: int, count: Optional[int] = None) -> None:
        n = self.get(map_index, 0) if count is None else count
        total = sum(self._check_entry(map_index, self.get(map_index, k)) for k in range(1, n + 1))
        if total > 64:
            raise SdoAbortedError(ABORT_PDO_LENGTH)

    def store(self, index: int, sub: int, value: int, dispatch_controlword: bool = True) -> None:
        """An object written (by SDO or by an RPDO) and what it does to the drive."""
        if index == CONTROLWORD:
            if dispatch_controlword:
                self.controlword(value)
            else:
                self.values[(CONTROLWORD, 0)] = value
            return
        if index == MODES:
            self.set_mode(value)
            return
        self.values[(index, sub)] = value
        if RPDO_MAP <= index < RPDO_MAP + N_PDO or TPDO_MAP <= index < TPDO_MAP + N_PDO:
            self._maps.pop(index, None)
        if index == CONSUMER_HEARTBEAT:
            self.hb_last = None                     # monitoring starts with the next heartbeat
            if value:
                self.event(f"heartbeat consumer: node {(value >> 16) & 0xFF}, {value & 0xFFFF} ms")
        elif index == SW_LIMITS:
            self.limit_active = False
        elif TPDO_COM <= index < TPDO_COM + N_PDO:
            n = index - TPDO_COM
            self.tpdo_count[n], self.tpdo_last[n], self.tpdo_next[n] = 0, None, None
        elif RPDO_COM <= index < RPDO_COM + N_PDO:
            n = index - RPDO_COM
            self.rpdo_pending[n] = self.rpdo_last[n] = None

    # --------------------------------------------------------------------------------- bus frames
    def deliver(self, msg: can.Message) -> None:
        """A frame on the bus (in the hub's loop thread): canopen's SDO server and NMT slave, then the drive."""
        if msg.is_error_frame or msg.is_remote_frame:
            return
        try:
            self.network.notify(msg.arbitration_id, bytearray(msg.data), msg.timestamp)
        except Exception:                           # noqa: BLE001 - as canopen's MessageListener
            log.exception("fake drive %d: canopen callback", self.node_id)
        try:
            cid = msg.arbitration_id
            if cid == NMT_COB:
                self._on_nmt(bytes(msg.data))
            elif cid == self.get(COB_ID_SYNC) & 0x7FF:
                self._on_sync(msg)
            elif cid & 0x780 == HEARTBEAT_BASE:
                self._on_heartbeat(cid & 0x7F)
            else:
                self._on_pdo(msg)
        except Exception:                           # noqa: BLE001 - keep the notifier alive, but say so
            log.exception("fake drive %d: frame 0x%X", self.node_id, msg.arbitration_id)
            self.event(f"internal error: {traceback.format_exc(limit=3)}")

    def _on_nmt(self, data: bytes) -> None:
        if len(data) < 2 or data[1] not in (0, self.node_id):
            return
        cmd = data[0]
        with self.lock:
            self.advance(time.monotonic())
            if cmd in (NMT_RESET_NODE, NMT_RESET_COMM):
                if cmd == NMT_RESET_NODE:
                    self._power_up()
                    self.event("NMT reset node: rebooted (SWITCH ON DISABLED, power-on parameters)")
                else:
                    for key in [k for k in self.values if 0x1000 <= k[0] <= 0x1FFF]:
                        if key in self.power_on:
                            self.values[key] = self.power_on[key]
                        else:
                            del self.values[key]
                    self._maps = {}
                    self._reset_comm_state()
                    self.event("NMT reset communication")
                self.node.nmt.stop_heartbeat()
                self._boot()
            elif self.nmt != "OPERATIONAL":
                self.rpdo_pending = [None] * N_PDO
                self.rpdo_last = [None] * N_PDO
                self.rpdo1_since_sync = 0

    def _on_heartbeat(self, producer: int) -> None:
        with self.lock:
            cfg = self.get(CONSUMER_HEARTBEAT, 1)
            if cfg & 0xFFFF and (cfg >> 16) & 0xFF == producer:
                self.hb_last = time.monotonic()

    def _pdo_valid(self, com: int) -> Optional[int]:
        cob = self.get(com, 1)
        return None if cob & PDO_INVALID else cob & 0x7FF

    def _mapping(self, map_index: int):
        """(index, sub, bits, OD entry) of the objects mapped by ``map_index`` (as last written)."""
        out = self._maps.get(map_index)
        if out is None:
            out = []
            for k in range(1, self.get(map_index, 0) + 1):
                e = self.get(map_index, k)
                index, sub, bits = e >> 16, (e >> 8) & 0xFF, e & 0xFF
                out.append((index, sub, bits, _find(self.od, index, sub)))
            self._maps[map_index] = out
        return out

    def _on_pdo(self, msg: can.Message) -> None:
        cid = msg.arbitration_id
        with self.lock:
            if self.nmt != "OPERATIONAL":
                return
            for n in range(N_PDO):
                if self._pdo_valid(RPDO_COM + n) != cid:
                    continue
                now = time.monotonic()
                self.advance(now)
                data = bytes(msg.data)
                need = sum(b for _, _, b, _ in self._mapping(RPDO_MAP + n)) // 8
                if len(data) < need:
                    self.fault(ERR_PDO_LENGTH, f"RPDO {n + 1}: {len(data)} bytes, mapping needs {need}")
                    return
                self.rpdo_last[n] = now
                if n == 0:
                    self.rpdo1_since_sync += 1
                if self.get(RPDO_COM + n, 2) <= 240:
                    self.rpdo_pending[n] = data                  # applied at the next SYNC (last one wins)
                else:
                    self._apply_rpdo(n, data)
                return

    def _apply_rpdo(self, n: int, data: bytes) -> None:
        off, cw = 0, None
        for index, sub, bits, obj in self._mapping(RPDO_MAP + n):
            raw = data[off:off + bits // 8]
            off += bits // 8
            value = obj.decode_raw(raw)
            if index == CONTROLWORD:
                cw = value
            else:
                self.store(index, sub, value)
        if cw is not None:
            self.controlword(cw)

    def _tpdo_payload(self, n: int) -> bytes:
        out = bytearray()
        for index, sub, bits, obj in self._mapping(TPDO_MAP + n):
            v = self.value(index, sub)
            if obj.data_type in dt.SIGNED_TYPES:
                lim = 1 << (len(obj) - 1)
                v = max(-lim, min(lim - 1, v))
            out += obj.encode_raw(v)[:bits // 8]
        return bytes(out)

    def _on_sync(self, msg: can.Message) -> None:
        sends = []
        with self.lock:
            now = time.monotonic()
            self.advance(now)
            operational = self.nmt == "OPERATIONAL"
            if self.last_sync_t is not None:
                gap = now - self.last_sync_t
                ip_val, ip_idx = self.get(INTERPOLATION_PERIOD, 1), self.get(INTERPOLATION_PERIOD, 2)
                ref = ip_val * 10.0 ** ip_idx if ip_val else None
                if (ref and gap > 2 * ref and self.state == OE and self.mode == CSP and operational):
                    self.event(f"SYNC gap {gap * 1e3:.1f} ms (interpolation period {ref * 1e3:g} ms)")
            self.last_sync_t = now
            rpdos = 0
            if operational:
                for n in range(N_PDO):
                    data = self.rpdo_pending[n]
                    if data is not None:
                        self.rpdo_pending[n] = None
                        self._apply_rpdo(n, data)
                rpdos, self.rpdo1_since_sync = self.rpdo1_since_sync, 0
                if self.state == OE and self.mode == CSP:
                    self.demand = self.limit(self.get(TARGET))
            demand = _clip32(self.demand)
            prev = self.prev_sync_demand
            self.prev_sync_demand = demand
            if operational:
                self.records.append((msg.timestamp, demand, demand - (prev if prev is not None else demand),
                                     _clip32(self.actual), self.state, rpdos))
                if not self.silent:
                    for n in range(N_PDO):
                        cob = self._pdo_valid(TPDO_COM + n)
                        if cob is None:
                            continue
                        tt = self.get(TPDO_COM + n, 2)
                        if 1 <= tt <= 240:
                            self.tpdo_count[n] += 1
                            if self.tpdo_count[n] >= tt:
                                self.tpdo_count[n] = 0
                                sends.append((cob, self._tpdo_payload(n)))
                        elif tt == 0:
                            payload = self._tpdo_payload(n)
                            if payload != self.tpdo_last[n]:
                                self.tpdo_last[n] = payload
                                sends.append((cob, payload))
        for cob, payload in sends:
            self.network.send_message(cob, payload)

    # --------------------------------------------------------------------------------- servo tick
    def servo(self, now: float) -> None:
        """Periodic work of the drive's own clock: motion, watchdogs, event-timer TPDOs."""
        sends = []
        with self.lock:
            self.advance(now)
            cfg = self.get(CONSUMER_HEARTBEAT, 1)
            if cfg & 0xFFFF and self.hb_last is not None and now - self.hb_last > (cfg & 0xFFFF) * 1e-3:
                gap = now - self.hb_last
                self.hb_last = None
                self.event(f"heartbeat of node {(cfg >> 16) & 0xFF} lost: {gap * 1e3:.1f} ms > {cfg & 0xFFFF} ms")
                self.fault(ERR_HEARTBEAT, f"heartbeat error (node {(cfg >> 16) & 0xFF})")
            if self.nmt == "OPERATIONAL":
                for n in range(N_PDO):
                    ms = self.get(RPDO_COM + n, 5)
                    last = self.rpdo_last[n]
                    if ms and last is not None and self._pdo_valid(RPDO_COM + n) is not None and now - last > ms * 1e-3:
                        self.rpdo_last[n] = None
                        self.fault(ERR_RPDO_TIMEOUT, f"RPDO {n + 1} timeout: {1e3 * (now - last):.1f} ms > {ms} ms")
                    cob = self._pdo_valid(TPDO_COM + n)
                    ev = self.get(TPDO_COM + n, 5)
                    if cob is not None and ev and self.get(TPDO_COM + n, 2) >= 254 and not self.silent:
                        nxt = self.tpdo_next[n]
                        if nxt is None or now >= nxt:
                            self.tpdo_next[n] = (now if nxt is None else nxt) + ev * 1e-3
                            sends.append((cob, self._tpdo_payload(n)))
        for cob, payload in sends:
            self.network.send_message(cob, payload)

    def silence(self) -> None:
        with self.lock:
            self.silent = True
            self.node.nmt.stop_heartbeat()
            self.event("silenced: no heartbeat, TPDO or EMCY from now on")

    def close(self) -> None:
        try:
            self.node.nmt.stop_heartbeat()
            self.network.disconnect()                   # shuts the port down (and its periodic tasks)
        except Exception:                               # noqa: BLE001
            pass


# ================================================================================================ hub
class _Task:
    """A periodic transmission (the hub's broadcast manager): of a host socket or of a drive (heartbeat)."""

    def __init__(self, owner):
        self.owner = owner
        self.msgs, self.idx = [], 0
        self.period, self.next, self.end = 0.0, 0.0, None
        self.running = False


class _PortTask(LimitedDurationCyclicSendTaskABC, ModifiableCyclicTaskABC, RestartableCyclicTaskABC):
    """``send_periodic`` of a drive's port: a task of the hub's scheduler (canopen's heartbeat producer)."""

    def __init__(self, hub: "Hub", port: "_Port", messages, period: float, duration: Optional[float],
                 autostart: bool):
        super().__init__(messages, period, duration)
        self.hub = hub
        with hub.cond:
            self.task = hub.tasks[(port, next(hub.task_ids))] = _Task(port)
            self.task.msgs = list(self.messages)
        if autostart:
            self.start()

    def start(self) -> None:
        self.hub.start_task(self.task, self.period, self.duration)

    def stop(self) -> None:
        with self.hub.cond:
            self.task.running = False

    def modify_data(self, messages) -> None:
        super().modify_data(messages)
        with self.hub.cond:
            self.task.msgs = list(self.messages)


class _Port(can.BusABC):
    """A drive's attachment to the hub's bus: ``send`` puts a frame on the bus (every other drive and
    every host socket gets it, in bus order); periodic transmissions run on the hub's clock."""

    def __init__(self, hub: "Hub", name: str):
        self.hub = hub
        self.channel_info = f"fake drive port {name}"
        super().__init__(channel=name)

    def send(self, msg: can.Message, timeout: Optional[float] = None) -> None:
        if self._is_shutdown:
            raise can.CanOperationError("port is shut down")
        self.hub.route(can.Message(timestamp=time.time(), arbitration_id=msg.arbitration_id,
                                   is_extended_id=msg.is_extended_id, is_remote_frame=msg.is_remote_frame,
                                   dlc=msg.dlc, data=msg.data), src=self)

    def _recv_internal(self, timeout):
        return None, False                                  # frames are delivered by the hub, not read

    def _send_periodic_internal(self, msgs, period, duration=None, autostart=True, modifier_callback=None):
        if modifier_callback is not None:
            return super()._send_periodic_internal(msgs, period, duration, autostart, modifier_callback)
        return _PortTask(self.hub, self, msgs, period, duration, autostart)


class _Client:
    """A host socket (non-blocking; the hub's loop reads and writes it)."""

    def __init__(self, sock: socket.socket, cid: int):
        self.sock, self.id = sock, cid
        self.sock.setblocking(False)
        self.reader = cb.RecordReader()
        self.out = bytearray()

    def fileno(self) -> int:
        return self.sock.fileno()


class Hub:
    """The hub process: one event-loop thread owns the bus — host sockets, drive deliveries, the periodic
    tasks (SYNC, heartbeats) on monotonic deadlines and the servo clock — so nothing in the hub waits for
    another of its threads; the RPC thread only reads and pokes drive state under the drives' locks."""

    #: a real-time hub that uses more than this share of a core (over ~1 s) drops to normal priority
    RT_CPU_GUARD = 0.5

    def __init__(self, path: str, drives: list, counts_per_turn: float, servo_period: float = 0.002,
                 realtime: bool = False):
        self.path = path
        self.servo_period = float(servo_period)
        self.realtime = realtime
        self.stopping = False
        self.cond = threading.RLock()                       # tasks and clients
        self.stats_lock = threading.Lock()
        self.tasks: dict = {}
        self.task_ids = itertools.count(1)
        self.clients: dict = {}
        self._client_ids = itertools.count(1)
        self.pending: collections.deque = collections.deque()
        self.sync_count = self.late = self.skipped = self.paused = 0
        self.sync_times = collections.deque(maxlen=200_000)
        self.pause_until = 0.0
        self.hub_events = collections.deque(maxlen=10_000)
        self._wake_r, self._wake_w = os.pipe()
        os.set_blocking(self._wake_r, False)
        os.set_blocking(self._wake_w, False)
        self._loop_ident = None
        self.drives = {}
        for d in drives:
            nid = int(d["node_id"])
            if nid in self.drives or not 1 <= nid <= 127:
                raise ValueError(f"bad or duplicate node_id {nid}")
            self.drives[nid] = FakeDrive(_Port(self, f"node {nid}"), nid, int(d.get("initial_counts", 0)),
                                         int(d.get("target_counts", 0)), float(d.get("max_counts_per_s", 1e5)),
                                         counts_per_turn, d.get("stored"))
        self.ports = {d.port: d for d in self.drives.values()}
        self._drain()                                       # boot-up messages (nobody listening yet)
        self.server = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        self.server.bind(path)
        self.server.listen(8)
        self.server.setblocking(False)
        self.thread = threading.Thread(target=self._loop, name="hub loop", daemon=True)
        self.thread.start()

    # --------------------------------------------------------------------------------- the bus
    def route(self, msg: can.Message, src=None, record: Optional[bytes] = None) -> None:
        """Put a frame on the bus (any thread); the loop delivers it in order."""
        self.pending.append((msg, src, record))
        if threading.get_ident() != self._loop_ident:
            self._wake()

    def _wake(self) -> None:
        try:
            os.write(self._wake_w, b"x")
        except (BlockingIOError, OSError):
            pass

    def _drain(self) -> None:
        """Deliver queued frames: to every drive but the sender, to every host socket but the sender."""
        while self.pending:
            msg, src, record = self.pending.popleft()
            if msg.arbitration_id == SYNC_COB and not msg.is_extended_id:
                with self.stats_lock:
                    self.sync_count += 1
                    self.sync_times.append(msg.timestamp)
            for port, drive in self.ports.items():
                if port is not src:
                    drive.deliver(msg)
            rec = record if record is not None else cb.pack_frame(msg, timestamp=msg.timestamp)
            for c in list(self.clients.values()):
                if c is not src:
                    c.out += rec

    def start_task(self, task: _Task, period: float, duration: Optional[float]) -> None:
        with self.cond:
            task.period = float(period)
            task.next = time.monotonic()
            task.end = task.next + duration if duration else None
            task.running = task.period > 0 and bool(task.msgs)
        self._wake()

    # --------------------------------------------------------------------------------- host sockets
    def _accept(self) -> None:
        while True:
            try:
                sock, _ = self.server.accept()
            except (BlockingIOError, OSError):
                return
            c = _Client(sock, next(self._client_ids))
            with self.cond:
                self.clients[c.id] = c

    def _drop(self, client: _Client) -> None:
        with self.cond:
            if self.clients.pop(client.id, None) is None:
                return
            for key in [k for k in self.tasks if k[0] == client.id]:   # BCM tasks die with their socket
                del self.tasks[key]
        try:
            client.sock.close()
        except OSError:
            pass

    def _read(self, client: _Client) -> None:
        try:
            chunk = client.sock.recv(1 << 16)
        except BlockingIOError:
            return
        except OSError:
            chunk = b""
        if not chunk:
            self._drop(client)
            return
        for record in client.reader.feed(chunk):
            kind, task_id, first, msg = cb.unpack(record)
            if kind == cb.KIND_FRAME:
                self.route(msg, src=client, record=record)
                continue
            with self.cond:
                key = (client.id, task_id)
                task = self.tasks.get(key)
                if task is None:
                    task = self.tasks[key] = _Task(client.id)
                if kind == cb.KIND_DEFINE:
                    if first:
                        task.msgs = []
                    task.msgs.append(msg)
                    task.idx %= max(1, len(task.msgs))
                elif kind == cb.KIND_START:
                    duration = struct.unpack("<d", record[-8:])[0]      # the 8 data bytes
                    self.start_task(task, struct.unpack("<d", record[:8])[0], duration if duration > 0 else None)
                elif kind == cb.KIND_STOP:
                    task.running = False

    def _write(self, client: _Client) -> None:
        try:
            n = client.sock.send(client.out)
        except BlockingIOError:
            return
        except OSError:
            self._drop(client)
            return
        del client.out[:n]

    # --------------------------------------------------------------------------------- the clock
    def _tick(self, now: float) -> None:
        """Due periodic tasks on a fixed monotonic grid: a late tick is sent once, the grid points missed
        meanwhile are skipped (counted), never sent in a burst."""
        with self.cond:
            for t in list(self.tasks.values()):
                if not t.running or t.next > now:
                    continue
                if t.end is not None and now >= t.end:
                    t.running = False
                    continue
                late = now - t.next
                missed = int(late // t.period)
                is_sync = t.msgs[0].arbitration_id == SYNC_COB
                if is_sync:
                    if missed:
                        self.skipped += missed
                        self.hub_events.append((time.time(), f"hub late by {late * 1e3:.2f} ms: "
                                                             f"{missed} SYNC tick(s) skipped"))
                    if late > t.period / 2:
                        self.late += 1
                t.next += (missed + 1) * t.period
                m = t.msgs[t.idx]
                t.idx = (t.idx + 1) % len(t.msgs)
                if is_sync and now < self.pause_until:
                    self.paused += 1
                    continue
                out = can.Message(timestamp=time.time(), arbitration_id=m.arbitration_id,
                                  is_extended_id=m.is_extended_id, is_remote_frame=m.is_remote_frame,
                                  dlc=m.dlc, data=m.data)
                # a host's task goes to every socket, its own included (BCM frames reach the raw socket)
                self.route(out, src=t.owner if isinstance(t.owner, _Port) else None)

    def _next_deadline(self) -> float:
        with self.cond:
            return min((t.next for t in self.tasks.values() if t.running), default=math.inf)

    def _guard(self, now: float) -> None:
        """A real-time hub must stay a light one: drop to normal priority if it ever burns CPU."""
        cpu = time.process_time()
        if self._guard_at is not None and now - self._guard_at[0] >= 1.0:
            share = (cpu - self._guard_at[1]) / (now - self._guard_at[0])
            if share > self.RT_CPU_GUARD:
                for tid in (os.getpid(), threading.get_native_id()):
                    try:
                        os.sched_setscheduler(tid, os.SCHED_OTHER, os.sched_param(0))
                    except OSError:
                        pass
                self.realtime = False
                self.hub_events.append((time.time(), f"hub used {share:.0%} CPU: back to normal priority"))
            self._guard_at = (now, cpu)
        elif self._guard_at is None:
            self._guard_at = (now, cpu)

    def _loop(self) -> None:
        self._loop_ident = threading.get_ident()
        self._guard_at = None
        servo_next = time.monotonic()
        while not self.stopping:
            now = time.monotonic()
            timeout = max(0.0, min(self._next_deadline(), servo_next, now + 0.1) - now)
            with self.cond:
                clients = list(self.clients.values())
            try:
                readable, writable, _ = select.select([self.server, self._wake_r] + clients,
                                                      [c for c in clients if c.out], [], timeout)
            except (OSError, ValueError):                    # a socket closed under us
                readable, writable = [], []
            if self.stopping:
                break
            if self._wake_r in readable:
                try:
                    os.read(self._wake_r, 4096)
                except BlockingIOError:
                    pass
            if self.server in readable:
                self._accept()
            for c in clients:
                if c in readable:
                    self._read(c)
            self._drain()
            now = time.monotonic()
            self._tick(now)
            self._drain()
            if now >= servo_next:
                for d in self.drives.values():
                    try:
                        d.servo(now)
                    except Exception:                        # noqa: BLE001
                        log.exception("servo of drive %d", d.node_id)
                servo_next += self.servo_period
                if servo_next < now:                         # late: do not catch up in a burst
                    servo_next = now + self.servo_period
                self._drain()
            for c in list(self.clients.values()):
                if c.out:
                    self._write(c)
            if self.realtime:
                self._guard(now)

    # --------------------------------------------------------------------------------- RPC
    def _drive(self, node: int) -> FakeDrive:
        try:
            return self.drives[int(node)]
        except KeyError:
            raise KeyError(f"no fake drive with node id {node}") from None

    def rpc_positions(self):
        out = {}
        for nid, d in self.drives.items():
            with d.lock:
                d.advance(time.monotonic())
                out[nid] = _clip32(d.actual)
        return out

    def rpc_state(self, node):
        d = self._drive(node)
        with d.lock:
            d.advance(time.monotonic())
            return d.state

    def rpc_nmt_state(self, node):
        return self._drive(node).nmt

    def rpc_od(self, node, index, sub=0):
        d = self._drive(node)
        if _find(d.od, index, sub) is None:
            raise KeyError(f"no object 0x{index:04X}:{sub}")
        with d.lock:
            d.advance(time.monotonic())
            return int(d.value(index, sub))

    def rpc_syncs(self):
        with self.stats_lock:
            return self.sync_count

    def rpc_sync_times(self, since_t=None):
        with self.stats_lock:
            ts = list(self.sync_times)
        return [t for t in ts if since_t is None or t >= since_t]

    def rpc_hub_stats(self):
        with self.cond:
            tasks = [{"owner": t.owner if isinstance(t.owner, int) else str(t.owner.channel_info), "task": k[1],
                      "cob_id": t.msgs[0].arbitration_id if t.msgs else None, "period": t.period,
                      "running": t.running} for k, t in self.tasks.items()]
            events = list(self.hub_events)
            stats = {"late": self.late, "skipped": self.skipped, "paused": self.paused, "clients": len(self.clients),
                     "realtime": self.realtime}
        return {"syncs": self.rpc_syncs(), **stats, "tasks": tasks, "events": events}

    def rpc_records(self, node):
        d = self._drive(node)
        with d.lock:
            recs = list(d.records)
        return [{"t": t, "demand": dem, "step": step, "position": pos, "state": st, "rpdos": n}
                for t, dem, step, pos, st, n in recs]

    def rpc_max_step(self, node, since_t=None):
        d = self._drive(node)
        with d.lock:
            recs = list(d.records)
        return max((abs(r[2]) for r in recs if r[4] == OE and (since_t is None or r[0] >= since_t)), default=0)

    def rpc_clear_records(self, node):
        d = self._drive(node)
        with d.lock:
            d.records.clear()

    def rpc_events(self, node):
        d = self._drive(node)
        with d.lock:
            return list(d.events)

    def rpc_inject_fault(self, node, code=ERR_FOLLOWING):
        d = self._drive(node)
        with d.lock:
            d.advance(time.monotonic())
            d.fault(int(code), "injected")

    def rpc_silence(self, node):
        self._drive(node).silence()

    def rpc_pause_sync(self, seconds):
        with self.cond:
            self.pause_until = time.monotonic() + float(seconds)
            self.hub_events.append((time.time(), f"SYNC producer paused for {float(seconds) * 1e3:g} ms"))

    def serve(self, conn) -> None:
        while True:
            try:
                req = conn.recv()
            except (EOFError, OSError):
                break                                       # the host is gone
            rid, method, args, kwargs = req
            if method == "stop":
                conn.send((rid, True, None))
                break
            try:
                result = getattr(self, "rpc_" + method)(*args, **kwargs)
                conn.send((rid, True, result))
            except Exception as exc:                         # noqa: BLE001 - report to the host
                conn.send((rid, False, f"{type(exc).__name__}: {exc}"))

    def close(self) -> None:
        self.stopping = True
        self._wake()
        self.thread.join(2.0)
        for d in self.drives.values():
            d.close()
        for c in list(self.clients.values()):
            self._drop(c)
        for fd in (self.server, ):
            try:
                fd.close()
            except OSError:
                pass
        for fd in (self._wake_r, self._wake_w):
            try:
                os.close(fd)
            except OSError:
                pass
        try:
            os.unlink(self.path)
        except OSError:
            pass

def _realtime(on: bool) -> bool:
    """Put the calling thread (and the threads it starts later) in SCHED_FIFO priority 1, or back to
    SCHED_OTHER.  False when the system does not allow it (then the hub runs at normal priority)."""
    try:
        if on:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(1))
        else:
            os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
        return True
    except (AttributeError, OSError):
        return False


def _hub_main(conn, path: str, drives: list, counts_per_turn: float, servo_period: float,
              realtime: bool = True) -> None:
    """Entry point of the hub process (spawned)."""
    logging.getLogger("canopen").setLevel(logging.ERROR)
    rt = _realtime(True) if realtime else False
    try:
        hub = Hub(path, drives, counts_per_turn, servo_period, realtime=rt)
    except Exception as exc:                                 # noqa: BLE001
        conn.send(("error", f"{type(exc).__name__}: {exc}\n{traceback.format_exc()}"))
        return
    conn.send(("ready", path))
    try:
        hub.serve(conn)
    finally:
        hub.close()


# ================================================================================================ host handle
class DriveProcess:
    """Host-side handle of a hub process with fake drives (a context manager).

    ``drives``: list of dicts ``{"node_id", "initial_counts" (actual position at power-up),
    "target_counts" (what 0x607A holds at power-up: a stale target), "max_counts_per_s" (motor speed
    limit)}``, optional ``"stored": {index or (index, sub): value}`` (other power-on values, e.g.
    ``{0x6065: 2000}``).  ``.channel`` is the Unix socket path for :class:`fakes.canbridge.BridgeBus`.
    Every RPC returns within ``rpc_timeout`` s or raises ``TimeoutError``.  ``realtime``: ask for
    SCHED_FIFO priority 1 for the hub (default: yes, unless the environment variable
    ``BELLOWS_FAKE_DRIVES_REALTIME=0``); ``servo_period``: the drives' servo clock [s]."""

    def __init__(self, drives: list, *, counts_per_turn: float = 4096, rpc_timeout: float = 5.0,
                 start_timeout: float = 30.0, servo_period: float = 0.002, realtime: Optional[bool] = None):
        self.drives = [dict(d) for d in drives]
        for d in self.drives:
            if "node_id" not in d:
                raise ValueError(f"drive without node_id: {d}")
        self.counts_per_turn = float(counts_per_turn)
        self.rpc_timeout, self.start_timeout = float(rpc_timeout), float(start_timeout)
        self.servo_period = float(servo_period)
        if realtime is None:
            realtime = os.environ.get("BELLOWS_FAKE_DRIVES_REALTIME", "1") not in ("0", "", "no", "false")
        self.realtime = bool(realtime)
        self.channel: Optional[str] = None
        self._dir = self._proc = self._conn = None
        self._lock = threading.Lock()
        self._ids = itertools.count(1)

    def __enter__(self) -> "DriveProcess":
        self._dir = tempfile.mkdtemp(prefix="bellows-hub-")
        self.channel = os.path.join(self._dir, "bus.sock")
        ctx = multiprocessing.get_context("spawn")
        self._conn, child = ctx.Pipe()
        self._proc = ctx.Process(target=_hub_main, name="bellows fake drives", daemon=True,
                                 args=(child, self.channel, self.drives, self.counts_per_turn, self.servo_period,
                                       self.realtime))
        try:
            self._proc.start()
            child.close()
            if not self._conn.poll(self.start_timeout):
                raise TimeoutError(f"fake drive process not ready within {self.start_timeout:g} s")
            status, detail = self._conn.recv()
            if status != "ready":
                raise RuntimeError(f"fake drive process failed to start: {detail}")
        except BaseException:
            self._shutdown()
            raise
        return self

    def __exit__(self, *exc) -> bool:
        self._shutdown()
        return False

    def _shutdown(self) -> None:
        if self._proc is not None:
            if self._proc.is_alive():
                try:
                    self._call("stop", timeout=2.0)
                except Exception:                            # noqa: BLE001 - stop it harder below
                    pass
                self._proc.join(3.0)
                if self._proc.is_alive():
                    self._proc.terminate()
                    self._proc.join(2.0)
                if self._proc.is_alive():
                    self._proc.kill()
                    self._proc.join(2.0)
            self._proc = None
        if self._conn is not None:
            self._conn.close()
            self._conn = None
        if self._dir is not None:
            shutil.rmtree(self._dir, ignore_errors=True)
            self._dir = None

    def _call(self, method: str, *args, timeout: Optional[float] = None, **kwargs):
        if self._conn is None:
            raise RuntimeError("the fake drive process is not running")
        timeout = self.rpc_timeout if timeout is None else timeout
        with self._lock:
            rid = next(self._ids)
            self._conn.send((rid, method, args, kwargs))
            deadline = time.monotonic() + timeout
            while True:
                left = deadline - time.monotonic()
                if left <= 0 or not self._conn.poll(left):
                    raise TimeoutError(f"fake drive process: no answer to {method} within {timeout:g} s")
                got, ok, value = self._conn.recv()
                if got != rid:
                    continue                                 # a late answer to a call that timed out
                if not ok:
                    raise RuntimeError(f"fake drive process: {method}: {value}")
                return value

    # --------------------------------------------------------------------------------- RPC
    def positions(self) -> dict:
        """node id → position actual value [counts] now."""
        return self._call("positions")

    def state(self, node: int) -> str:
        """CiA 402 state name of the drive now."""
        return self._call("state", node)

    def nmt_state(self, node: int) -> str:
        """NMT state of the drive ('PRE-OPERATIONAL', 'OPERATIONAL', ...)."""
        return self._call("nmt_state", node)

    def od(self, node: int, index: int, sub: int = 0) -> int:
        """Value of an object of the drive now (what the host wrote, or the computed value)."""
        return self._call("od", node, index, sub)

    def syncs(self) -> int:
        """SYNC frames that went on the hub's bus so far (hub-produced and host-sent)."""
        return self._call("syncs")

    def sync_times(self, since_t: Optional[float] = None) -> list:
        """time.time() of every SYNC on the hub's bus (since ``since_t``)."""
        return self._call("sync_times", since_t)

    def hub_stats(self) -> dict:
        """syncs, late (SYNC ticks sent > half a period late), skipped (grid points not sent because the
        hub was late), paused (ticks suppressed by pause_sync), clients, tasks, hub events."""
        return self._call("hub_stats")

    def records(self, node: int) -> list:
        """One dict per SYNC while the drive was NMT OPERATIONAL: t (time.time() of the SYNC), demand
        (position demand after the SYNC), step (demand − previous SYNC's demand), position (actual at the
        SYNC), state (CiA 402), rpdos (RPDO 1 frames received since the previous SYNC)."""
        return self._call("records", node)

    def max_step(self, node: int, since_t: Optional[float] = None) -> int:
        """Largest |step| of the records taken in OPERATION ENABLED (since ``since_t``); 0 if none."""
        return self._call("max_step", node, since_t)

    def clear_records(self, node: int) -> None:
        self._call("clear_records", node)

    def events(self, node: int) -> list:
        """(time.time(), text) of faults (with codes), heartbeat loss, following error, CSP jumps,
        software limit clamps, SYNC gaps, NMT resets."""
        return self._call("events", node)

    def inject_fault(self, node: int, code: int = ERR_FOLLOWING) -> None:
        """FAULT now: 0x603F = code, EMCY, demand frozen at the actual position."""
        self._call("inject_fault", node, code)

    def silence(self, node: int) -> None:
        """The drive stops sending heartbeat, TPDOs and EMCYs (its SDO server still answers)."""
        self._call("silence", node)

    def pause_sync(self, seconds: float) -> None:
        """The hub's SYNC producer sends nothing for ``seconds`` (lost SYNCs), then resumes on its grid."""
        self._call("pause_sync", seconds)

    def stop(self) -> None:
        """Stop the hub process (also done by ``__exit__``)."""
        self._shutdown()
