"""A fake EPOS4: a ``canopen.LocalNode`` on python-can's virtual bus running the CiA 402 power state
machine and profile position mode (new-setpoint handshake, target reached), with fault injection.

    with FakeEpos4(node_id=1, channel="rig0") as fake:
        ...  # an Epos4ProfileDrive(node_id=1, channel="rig0", interface="virtual", ...) talks to it

The motor moves at ``counts_per_second`` in a background thread; ``inject_fault(code)`` sets the fault
bit, stores the error code in 0x603F and sends an EMCY; ``following_error()`` sets statusword bit 13;
``ignore_setpoints`` makes it never acknowledge a new setpoint.

Cyclic synchronous position (0x6060 = 8): the PDO mapping the master writes over SDO lands in the node's
data store; in NMT OPERATIONAL, on every SYNC the fake applies the last RPDO 1 (controlword + target
position, decoded with the mapping it was given), then sends TPDO 1 (statusword + position) and TPDO 2
(following error + current) if they are enabled.  The heartbeat runs when 0x1017 is written (canopen's
``NmtSlave``); ``silence()`` stops heartbeat and TPDOs (a drive that went quiet).
"""

from __future__ import annotations

import struct
import threading
import time

import canopen

from hardware import epos4 as e4


class FakeEpos4:
    def __init__(self, node_id: int = 1, channel: str = "rig0", counts_per_second: float = 2e5,
                 initial_counts: int = 0):
        self.node_id, self.channel = node_id, channel
        self.rate = counts_per_second
        self.state = "SWITCH ON DISABLED"
        self.cw = 0
        self.mode = 0
        self.pos = float(initial_counts)
        self.target = float(initial_counts)
        self.ack = False
        self.halt = False
        self.fault_code = 0
        self.following = False
        self.ignore_setpoints = False
        self.writes: list = []                 # (index, value) in order
        self._lock = threading.RLock()
        self._stop = threading.Event()

    # ------------------------------------------------------------------------------------ lifecycle
    def __enter__(self):
        self.network = canopen.Network()
        self.network.NOTIFIER_CYCLE = 0.05
        self.network.connect(interface="virtual", channel=self.channel)
        self.node = self.network.create_node(self.node_id, e4.object_dictionary())
        self.node.add_write_callback(self._on_write)
        self.node.add_read_callback(self._on_read)
        self.rpdo_data = None
        self.silent = False
        self.syncs = 0
        self.network.subscribe(0x200 + self.node_id, self._on_rpdo)
        self.network.subscribe(0x80, self._on_sync)
        self._thread = threading.Thread(target=self._motor, daemon=True)
        self._thread.start()
        return self

    def __exit__(self, *exc):
        self._stop.set()
        self._thread.join(timeout=1)
        self.network.disconnect()
        return False

    # ------------------------------------------------------------------------------------ behaviour
    def statusword(self) -> int:
        base = {"NOT READY TO SWITCH ON": 0x00, "SWITCH ON DISABLED": 0x40, "READY TO SWITCH ON": 0x21,
                "SWITCHED ON": 0x23, "OPERATION ENABLED": 0x27, "QUICK STOP ACTIVE": 0x07, "FAULT": 0x08}[self.state]
        sw = base | 0x10                                       # voltage enabled
        if self.state == "OPERATION ENABLED" and abs(self.target - self.pos) < 0.5 or self.halt:
            sw |= e4.SW_TARGET_REACHED
        if self.ack:
            sw |= e4.SW_SETPOINT_ACK
        if self.following:
            sw |= e4.SW_FOLLOWING_ERROR
        return sw

    def _on_read(self, index, subindex, od):
        with self._lock:
            if index == e4.STATUSWORD:
                return self.statusword()
            if index == e4.POSITION:
                return int(round(self.pos))
            if index == e4.MODE_DISPLAY:
                return self.mode
            if index == e4.ERROR_CODE:
                return self.fault_code
            if index == e4.CURRENT:
                return 150 + int(abs(self.target - self.pos) > 0.5) * 500     # mA
        return None

    def _on_write(self, index, subindex, od, data):
        value = od.decode_raw(data)
        with self._lock:
            self.writes.append((index, value))
            if index == e4.MODE:
                self.mode = value
            elif index == e4.TARGET:
                self._pending_target = value
            elif index == e4.CONTROLWORD:
                self._controlword(value)

    def _controlword(self, cw: int) -> None:
        prev, self.cw = self.cw, cw
        s = self.state
        if s == "FAULT":
            if cw & e4.CW_FAULT_RESET and not prev & e4.CW_FAULT_RESET:
                self.state, self.fault_code, self.following = "SWITCH ON DISABLED", 0, False
            return
        low = cw & 0x8F
        if low & 0x0F == 0x06 and s in ("SWITCH ON DISABLED", "READY TO SWITCH ON", "SWITCHED ON", "OPERATION ENABLED"):
            self.state = "READY TO SWITCH ON"
        elif low & 0x0F == 0x07 and s in ("READY TO SWITCH ON", "SWITCHED ON", "OPERATION ENABLED"):
            self.state = "SWITCHED ON"
        elif low & 0x0F == 0x0F and s in ("SWITCHED ON", "OPERATION ENABLED", "QUICK STOP ACTIVE"):
            self.state = "OPERATION ENABLED"
        elif low & 0x07 == 0x02 and s == "OPERATION ENABLED":
            self.state, self.target = "QUICK STOP ACTIVE", self.pos
        elif low & 0x02 == 0:
            self.state = "SWITCH ON DISABLED"
        self.halt = bool(cw & e4.CW_HALT)
        if self.halt:
            self.target = self.pos
        if self.state == "OPERATION ENABLED" and self.mode == e4.PROFILE_POSITION:
            if cw & e4.CW_NEW_SETPOINT and not prev & e4.CW_NEW_SETPOINT and not self.ignore_setpoints:
                self.target = float(getattr(self, "_pending_target", self.target))
                self.ack = True
            elif not cw & e4.CW_NEW_SETPOINT:
                self.ack = False

    def _motor(self):
        last = time.monotonic()
        while not self._stop.is_set():
            time.sleep(0.002)
            now = time.monotonic()
            with self._lock:
                if self.state == "OPERATION ENABLED" and not self.halt:
                    step = self.rate * (now - last)
                    d = self.target - self.pos
                    self.pos = self.target if abs(d) <= step else self.pos + step * (1 if d > 0 else -1)
            last = now

    # ------------------------------------------------------------------------------------ cyclic (CSP)
    def mapping(self, index: int) -> list:
        """Mapped objects (index, subindex, bits) of the PDO mapping parameter ``index`` in the data store."""
        n = self.node.sdo[index][0].raw
        return [((v >> 16), (v >> 8) & 0xFF, v & 0xFF) for v in (self.node.sdo[index][k].raw for k in range(1, n + 1))]

    def _pdo_enabled(self, com: int) -> bool:
        return not self.node.sdo[com][1].raw & 0x80000000 and self.node.sdo[com][2].raw == e4.SYNC_TRANSMISSION

    def _on_rpdo(self, can_id, data, timestamp):
        self.rpdo_data = bytes(data)

    def _on_sync(self, can_id, data, timestamp):
        if self.silent or self.node.nmt.state != "OPERATIONAL":
            return
        with self._lock:
            self.syncs += 1
            if self.rpdo_data is not None and self._pdo_enabled(e4.RPDO1_COM):
                off, vals = 0, {}
                for index, _, bits in self.mapping(e4.RPDO1_MAP):
                    n = bits // 8
                    vals[index] = int.from_bytes(self.rpdo_data[off:off + n], "little", signed=index == e4.TARGET)
                    off += n
                if e4.CONTROLWORD in vals and vals[e4.CONTROLWORD] != self.cw:
                    self._controlword(vals[e4.CONTROLWORD])
                if e4.TARGET in vals and self.mode == e4.CYCLIC_SYNC_POSITION and self.state == "OPERATION ENABLED":
                    self.target = float(vals[e4.TARGET])
            sw, pos = self.statusword(), int(round(self.pos))
            ferr, cur = int(round(self.target - self.pos)), 150 + int(abs(self.target - self.pos) > 0.5) * 500
        if self._pdo_enabled(e4.TPDO1_COM):
            self.network.send_message(0x180 + self.node_id, struct.pack("<Hi", sw, pos))
        if self._pdo_enabled(e4.TPDO2_COM):
            self.network.send_message(0x280 + self.node_id, struct.pack("<ii", ferr, cur))

    def silence(self) -> None:
        """The drive goes quiet: no heartbeat, no TPDOs (a cable pulled, a drive reset)."""
        self.silent = True
        self.node.nmt.stop_heartbeat()

    # ------------------------------------------------------------------------------------ faults
    def inject_fault(self, code: int = 0x8611, emcy: bool = True) -> None:
        with self._lock:
            self.state, self.fault_code, self.target = "FAULT", code, self.pos
        if emcy:
            self.node.emcy.send(code, 0x01, struct.pack("<5B", 0, 0, 0, 0, 0))

    def following_error(self) -> None:
        with self._lock:
            self.following = True
