r"""EPOS4 in **cyclic synchronous position** (CiA 402, 0x6060 = 8) over PDO + SYNC: the loop mode.

In CSP the drive takes the target of the last RPDO before each SYNC as its absolute position demand and ramps
nothing itself, so everything that keeps a motor from jumping is on this page.

**Start-up** (:meth:`Epos4CyclicDrive.enable`, then :meth:`~Epos4CyclicDrive.start` once every drive of the bus
is enabled — :meth:`hardware.Rig.open` does both in that order):

1. NMT pre-operational; the PDOs are mapped over SDO, all with transmission type 1 (every SYNC):
   RPDO 1 (0x200 + node): target position 0x607A only — the controlword goes by SDO, confirmed (a controlword
   in a synchronous RPDO would be re-applied at every SYNC and undo an SDO command written between two RPDOs);
   TPDO 1 (0x180 + node): statusword 0x6041 + position demand value 0x6062 (the target the drive applied at
   this SYNC: what the set-point rule needs);
   TPDO 2 (0x280 + node): position actual value 0x6064 + current 0x30D1:02 (following error = demand − actual),
   every n-th SYNC (transmission type n, about every 10 ms: :data:`TPDO2_PERIOD`).
2. Drive-side supervision, each written and read back (a drive that keeps another value is a DriveFault):
   producer heartbeat 0x1017 (``heartbeat_time``); **consumer heartbeat 0x1016** of the host's heartbeat
   (node :data:`~hardware.canbus.MASTER_NODE_ID`, time ``heartbeat_timeout``) — a host silent that long
   stops the drive by itself; **following-error window 0x6065** (``following_error_window``) — a demand the
   motor cannot follow is a fault, not a lunge; **software position limits 0x607D** from the rig's travel
   limits — the drive refuses a demand outside them whatever the host sends; interpolation time period
   0x60C2 = the SYNC period; profile velocity/acceleration as in profile position.
3. Mode 8 (confirmed on 0x6061).  **A known start**: 0x607A := 0x6064 over SDO, before the power state machine
   — a drive that follows a stale target on enable (an old goal, or 0 after power-up) then follows its own
   position.  The set-point ramp is seeded from the same actual position.
4. NMT operational, then shutdown → switch on → enable operation over SDO, each confirmed by an SDO read of the
   statusword, then one RPDO with the actual position (before SYNC starts, the drive holds 0x607A anyway).
5. :meth:`start`: the bus's SYNC (:meth:`hardware.canbus.CanBus.start_sync`; one per bus, after every drive of
   the bus is enabled), then the first TPDOs and heartbeat of the drive within ``state_timeout``.

**Set-points** are sent by :meth:`_on_tpdo1`, the callback of the drive's TPDO 1 — one per SYNC, from the
drive — by the rule of :mod:`hardware.setpoints`: at most one step of ``speed · sync_period`` per SYNC period
(``speed`` the rig file's tendon speed, ≤ ``speed_max``), counted in the drive's SYNCs, never in wall-clock
catch-up, and each within one step of the demand the drive reports in that TPDO (0x6062) and of the last
set-point sent; a backlog of TPDOs handled at once after a host stall is answered once.  While the drive
is not OPERATION ENABLED (fault, quick stop, switched off) the set-point is frozen at its actual position, so
that nothing is left to catch up and re-enabling cannot jump.  The same callback sends the host's heartbeat
(:meth:`~hardware.canbus.CanBus.beat`): set-points and heartbeat stop together.

**Faults.**  The statusword of the latest TPDO (fault bit, following error bit), an EMCY, the drive's heartbeat
missing for ``heartbeat_timeout`` or its TPDOs for ``pdo_timeout`` (a drive gone quiet, or the bus's SYNC lost)
are :class:`~hardware.errors.DriveFault` at the next :meth:`check` — every command and the rig's health check
make one.  **Recovery**: :meth:`fault_reset` (controlword over SDO, the new state confirmed over SDO — a TPDO
may be a SYNC old) then :meth:`enable` (0x607A := 0x6064 again, the power state machine over SDO, PDOs and
SYNC left running) bring the drive back to OPERATION ENABLED where it stands; it moves again only on the next
:meth:`move_to`.

Guarantees and how they are tested: docs/rig.md, "Cyclic synchronous position: what keeps a motor from jumping".
"""

from __future__ import annotations

import math
import threading
import time

from .canbus import MASTER_HEARTBEAT_PERIOD, MASTER_NODE_ID
from .epos4 import (CONSUMER_HEARTBEAT, CURRENT, CYCLIC_SYNC_POSITION, FOLLOWING_ERROR, FOLLOWING_ERROR_WINDOW,
                    HEARTBEAT_TIME, INTERPOLATION_PERIOD, POSITION, POSITION_DEMAND, SOFTWARE_LIMITS, STATUSWORD,
                    SW_FAULT, SYNC_TRANSMISSION, TARGET, Epos4Drive, state_of)
from .errors import CommunicationError, DriveFault, LimitError
from .setpoints import SetpointRamp

__all__ = ["Epos4CyclicDrive", "interpolation_period"]

_ENABLED = "OPERATION ENABLED"
#: about how often TPDO 2 (position actual, current) is sent [s]
TPDO2_PERIOD = 0.01


def interpolation_period(period: float) -> tuple:
    """0x60C2 (value, index) for a SYNC period [s]: period = value · 10^index, value ≤ 255."""
    if isinstance(period, bool) or not isinstance(period, (int, float)) or not 0 < period < math.inf:
        raise LimitError(f"SYNC period must be a positive number of seconds, got {period!r}")
    for index in (-4, -3):
        value = period / 10.0 ** index
        if abs(value - round(value)) < 1e-6 * max(1.0, value) and 1 <= round(value) <= 255:
            return int(round(value)), index
    raise LimitError(f"SYNC period {period * 1e3:g} ms is not a whole number of 0.1 ms (≤ 25.5 ms) or of ms "
                     f"(≤ 255 ms): the drive's interpolation period 0x60C2 cannot say it")


class Epos4CyclicDrive(Epos4Drive):
    """One EPOS4 tendon drive in cyclic synchronous position (module docstring; shared parameters in
    :class:`Epos4Drive`).

    sync_period : SYNC and set-point period [s] (0.1 ms … 100 ms; one per bus)
    heartbeat_time : producer heartbeat the drive is given [s]
    heartbeat_timeout : the drive's heartbeat missing this long is a DriveFault on the host, and the host's
        heartbeat missing this long stops the drive (its consumer heartbeat time) [s]
    pdo_timeout : no TPDO for this long is a DriveFault (drive silent or SYNC lost) [s]
    position_window : distance from the target within which a move counts as reached [m]
    following_error_window : the drive faults when its position lags the demand by more [m]
    """

    mode, mode_name = CYCLIC_SYNC_POSITION, "cyclic synchronous position"

    def __init__(self, node_id: int, channel: str = "can0", interface: str = "socketcan", bitrate: int = 1_000_000, *,
                 sync_period: float = 0.002, heartbeat_time: float = 0.05, heartbeat_timeout: float = 0.5,
                 pdo_timeout: float = 0.25, position_window: float = 2e-6, following_error_window: float = 1e-3,
                 cyclic: bool = True, **kw):
        if not cyclic:
            raise LimitError("Epos4CyclicDrive is cyclic; use Epos4ProfileDrive for profile position")
        super().__init__(node_id, channel, interface, bitrate, **kw)
        for nm, v in (("sync_period", sync_period), ("heartbeat_time", heartbeat_time),
                      ("heartbeat_timeout", heartbeat_timeout), ("pdo_timeout", pdo_timeout),
                      ("position_window", position_window), ("following_error_window", following_error_window)):
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not 0 < v < math.inf:
                raise LimitError(f"{nm} must be a positive number of seconds (metres for the windows), got {v!r}")
        if not 1e-4 <= sync_period <= 0.1:
            raise LimitError(f"sync_period {sync_period} s is outside 0.1 ms … 100 ms")
        if heartbeat_timeout <= heartbeat_time:
            raise LimitError(f"heartbeat_timeout {heartbeat_timeout} s must exceed heartbeat_time {heartbeat_time} s")
        if heartbeat_timeout < 2 * MASTER_HEARTBEAT_PERIOD:
            raise LimitError(f"heartbeat_timeout {heartbeat_timeout} s must be at least twice the host's heartbeat "
                             f"period {MASTER_HEARTBEAT_PERIOD} s")
        if node_id == MASTER_NODE_ID:
            raise LimitError(f"node {MASTER_NODE_ID} is the host's heartbeat on a cyclic bus; give the drive another id")
        self.sync_period, self.heartbeat_time = float(sync_period), float(heartbeat_time)
        self.heartbeat_timeout, self.pdo_timeout = float(heartbeat_timeout), float(pdo_timeout)
        self.position_window, self.following_error_window = float(position_window), float(following_error_window)
        self.interpolation = interpolation_period(self.sync_period)
        self.max_step = self.speed * abs(self.counts_per_metre) * self.sync_period      # counts per SYNC period
        # TPDO 2 (actual position, current) every n-th SYNC, about every 10 ms: read-backs, not the loop's clock —
        # fewer frames for a Python host to handle (its CANopen callbacks compete for the GIL)
        self.tpdo2_every = max(1, min(240, round(TPDO2_PERIOD / self.sync_period)))
        self._lock = threading.RLock()
        self._ramp = None                 # SetpointRamp, from the first enable on
        self._operational = False         # PDOs mapped, NMT operational, TPDO callback in place
        self.sent = 0                     # set-points sent (RPDO 1)

    # ----------------------------------------------------------------------------------- start-up
    def _configure(self) -> None:
        """Steps 1–2 of the start-up: PDO mapping and drive-side supervision, in PRE-OPERATIONAL."""
        import canopen
        node = self._node()
        node.nmt.send_command(0x80)                            # NMT enter pre-operational
        try:
            for pdo, variables, every in ((node.rpdo[1], (TARGET,), SYNC_TRANSMISSION),
                                          (node.tpdo[1], (STATUSWORD, POSITION_DEMAND), SYNC_TRANSMISSION),
                                          (node.tpdo[2], ((POSITION, 0), (CURRENT, 2)), self.tpdo2_every)):
                pdo.clear()
                for v in variables:
                    index, sub = v if isinstance(v, tuple) else (v, 0)
                    pdo.add_variable(index, sub)
                pdo.cob_id = pdo.predefined_cob_id
                pdo.trans_type = every
                pdo.enabled = True
                pdo.save()
        except (canopen.SdoCommunicationError, canopen.SdoAbortedError, OSError) as exc:
            raise CommunicationError(f"PDO mapping failed: {exc}", device=self.name) from None
        cpm = abs(self.counts_per_metre)
        lo, hi = sorted((self.to_counts(self.limits.length_min), self.to_counts(self.limits.length_max)))
        for index, sub, value, what in (
                (HEARTBEAT_TIME, 0, max(1, round(self.heartbeat_time * 1e3)), "producer heartbeat [ms]"),
                (CONSUMER_HEARTBEAT, 1, (MASTER_NODE_ID << 16) | min(0xFFFF, round(self.heartbeat_timeout * 1e3)),
                 "consumer heartbeat of the host"),
                (FOLLOWING_ERROR_WINDOW, 0, max(1, round(self.following_error_window * cpm)),
                 "following error window [counts]"),
                (SOFTWARE_LIMITS, 1, lo, "software position limit min [counts]"),
                (SOFTWARE_LIMITS, 2, hi, "software position limit max [counts]"),
                (INTERPOLATION_PERIOD, 1, self.interpolation[0], "interpolation time period value"),
                (INTERPOLATION_PERIOD, 2, self.interpolation[1], "interpolation time index")):
            self._write_checked(index, value, what, sub)
        self._write_profile()
        self._enter_mode()

    def enable(self) -> None:
        """Start-up steps 1–4 (module docstring); after a fault reset: steps 3–4 only (PDOs and SYNC keep
        running).  A drive already enabled in CSP is left as it is."""
        self._check_emcy()
        sw = self._read(STATUSWORD)
        self._check_statusword(sw)
        if self._operational and state_of(sw) == _ENABLED:
            return
        if not self._operational:
            self._configure()
        actual = self._read(POSITION)
        with self._lock:                                        # frozen at the actual position from here on
            if self._ramp is None:
                self._ramp = SetpointRamp(self.max_step, self.sync_period, actual)
            else:
                self._ramp.reseed(actual)
        self._write(TARGET, actual)                             # a known start: 0x607A := 0x6064
        if not self._operational:
            node = self._node()
            node.rpdo[1]["Target position"].raw = actual
            node.tpdo[1].add_callback(self._on_tpdo1)
            node.nmt.send_command(0x01)                         # NMT start: OPERATIONAL, PDOs flow on SYNC
            self._operational = True
        self._power_up()
        with self._lock:                                        # the RPDO the next SYNC applies: where it stands
            rp = self._node().rpdo[1]
            rp["Target position"].raw = self._ramp.setpoint
            rp.transmit()

    def start(self) -> None:
        """Step 5: the bus's SYNC, then the drive's first TPDOs (1 and 2) and heartbeat within ``state_timeout``."""
        node = self._node()
        t_asked = time.time()
        self.bus.start_sync(self.sync_period)
        t0 = time.monotonic()
        while True:
            ts = [node.tpdo[n].timestamp for n in (1, 2)]
            if all(t is not None and t >= t_asked for t in ts) and node.nmt.timestamp is not None:
                return
            if time.monotonic() - t0 > self.state_timeout:
                raise DriveFault(f"no TPDO / heartbeat within {self.state_timeout:g} s after SYNC started",
                                 device=self.name)
            time.sleep(0.002)

    # ----------------------------------------------------------------------------------- set-points
    def _on_tpdo1(self, tp) -> None:
        """Every TPDO 1 (one per SYNC): the next set-point by :mod:`hardware.setpoints`, and the host's heartbeat."""
        now = time.monotonic()
        try:
            sw = int(tp["Statusword"].raw)
            demand = int(tp["Position demand value"].raw)
            with self._lock:
                ramp = self._ramp
                if ramp is None:
                    return
                if state_of(sw) != _ENABLED or sw & SW_FAULT:
                    # not following set-points: its demand follows its position; frozen where the drive is
                    ramp.reseed(self._actual_counts(demand))
                if ramp.due(now):
                    sp = ramp.advance(now, demand)
                    if sp is not None:
                        rp = self.node.rpdo[1]
                        rp["Target position"].raw = sp
                        rp.transmit()
                        self.sent += 1
            self.bus.beat(now)
        except Exception:                                      # noqa: BLE001 - a closed bus: nothing more to send
            return

    # ----------------------------------------------------------------------------------- read-backs
    def _tpdo(self, n: int):
        """TPDO ``n`` as last received; DriveFault when none came for ``pdo_timeout``."""
        tp = self._node().tpdo[n]
        ts = tp.timestamp
        if ts is None or time.time() - ts > self.pdo_timeout:
            raise DriveFault(f"no TPDO {n} for {self.pdo_timeout * 1e3:g} ms: the drive is silent or the bus's "
                             f"SYNC stopped", device=self.name)
        return tp

    def statusword(self) -> int:
        if self._operational:
            return int(self._tpdo(1)["Statusword"].raw)
        return self._read(STATUSWORD)

    def check(self) -> None:
        """DriveFault on an EMCY, a silent drive (heartbeat or TPDOs missing), a fault or following error."""
        self._check_emcy()
        if self._operational:
            ts = self._node().nmt.timestamp
            if ts is None or time.time() - ts > self.heartbeat_timeout:
                raise DriveFault(f"no heartbeat for {self.heartbeat_timeout * 1e3:g} ms: the drive is silent",
                                 device=self.name)
        self._check_statusword(self.statusword())

    def _actual_counts(self, default: int) -> int:
        """Position actual value [counts] from the latest TPDO 2 (``default`` before the first one)."""
        tp = self._node().tpdo[2]
        return default if tp.timestamp is None else int(tp["Position actual value"].raw)

    def position(self) -> float:
        if self._operational:
            return self.to_length(int(self._tpdo(2)["Position actual value"].raw))
        return self.to_length(self._read(POSITION))

    def current(self) -> float:
        """Motor current [A] (0x30D1:02 by TPDO 2)."""
        if self._operational:
            return int(self._tpdo(2)["Current actual values.Current actual value"].raw) * 1e-3
        return self._read(CURRENT, 2) * 1e-3

    def following_error(self) -> float:
        """Following error [m]: position demand (TPDO 1) − position actual (TPDO 2); 0x60F4 over SDO before the
        PDOs run."""
        if not self._operational:
            return self._read(FOLLOWING_ERROR) / self.counts_per_metre
        c = int(self._tpdo(1)["Position demand value"].raw) - int(self._tpdo(2)["Position actual value"].raw)
        return c / self.counts_per_metre

    @property
    def setpoint(self) -> float:
        """The newest set-point sent [m] (NaN before the first enable)."""
        with self._lock:
            return math.nan if self._ramp is None else self.to_length(self._ramp.setpoint)

    # ----------------------------------------------------------------------------------- motion
    def move_to(self, length: float) -> None:
        """Check the travel, then give the set-point ramp its new goal (sent from the next TPDO on)."""
        counts = self._checked_counts(length)
        self.check()
        if state_of(self.statusword()) != _ENABLED:
            raise DriveFault(f"move commanded in state {self.state()}", device=self.name)
        with self._lock:
            self._ramp.goal = counts

    def target_reached(self) -> bool:
        with self._lock:
            if self._ramp is None:
                return False
            done, goal = self._ramp.settled, self._ramp.goal
        pos = int(self._tpdo(2)["Position actual value"].raw)
        return done and abs(pos - goal) <= self.position_window * abs(self.counts_per_metre)

    def hold(self) -> None:
        """Hold the set-point where it is (the drive stays enabled).  A drive that is not OPERATION ENABLED is
        already stopped and is left alone (its set-point follows its actual position)."""
        with self._lock:
            if self._ramp is not None:
                self._ramp.hold()

    def close(self) -> None:
        """Stop watching the host's heartbeat (the drive would fault once it stops), then leave the bus."""
        if self.node is not None and self._operational:
            try:
                self.node.tpdo[1].callbacks.remove(self._on_tpdo1)
            except ValueError:
                pass
            try:
                self._write(CONSUMER_HEARTBEAT, 0, 1)
            except Exception:                                  # noqa: BLE001 - a silent drive: nothing to stop
                pass
            self._operational = False
        super().close()
