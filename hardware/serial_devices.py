r"""Serial force sensors, pressure sensor and valve controller: line protocols separate from the transport.

The instruments are small microcontroller boards (load-cell amplifiers, a valve driver with a micro
pressure sensor) speaking an ASCII line protocol with an NMEA-style checksum, so that a corrupted line
is detected instead of read as a number:

``<payload>*<HH>\n`` where HH is the XOR of the payload bytes in hexadecimal.

=================================  ==========================================  =================================
request (host → device)            reply (device → host)                       meaning
=================================  ==========================================  =================================
``F?``                             ``F <seq> <c1> <c2> … <cn>``                force channels, raw counts
``P?``                             ``P <seq> <pressure_Pa>``                   chamber pressure [Pa]
``PSET <pressure_Pa>``             ``OK PSET <pressure_Pa>``                   regulate to a set point [Pa]
``HOLD``                           ``OK HOLD``                                 close the valves
``VENT``                           ``OK VENT``                                 open the chamber to atmosphere
(any)                              ``ERR <text>``                              the device refused
=================================  ==========================================  =================================

:class:`ForceProtocol` and :class:`PressureProtocol` only format requests and parse replies (bytes in,
numbers out; unit-tested on bytes).  :class:`LineTransport` moves lines over anything with ``write`` and
``readline`` — a ``serial.Serial`` (a port name) or ``serial.serial_for_url("loop://")`` — with a
timeout: no reply in time is a :class:`~hardware.errors.SensorTimeout`, a malformed or corrupted reply a
:class:`~hardware.errors.CommunicationError`, an ``ERR`` reply a :class:`~hardware.errors.PressureFault`
(valve controller) or CommunicationError.  Several force channels share one port (one transport per
port, reference-counted).
"""

from __future__ import annotations

import math
import threading
from typing import Optional

from .errors import CommunicationError, LimitError, PressureFault, SensorTimeout
from .interfaces import ForceSensor, PressureSupply


# ============================================================================================ protocol
def checksum(payload: bytes) -> int:
    c = 0
    for b in payload:
        c ^= b
    return c


def frame(payload: str) -> bytes:
    """``payload`` → ``b"payload*HH\\n"``."""
    p = payload.encode("ascii")
    return p + b"*%02X\n" % checksum(p)


def unframe(line: bytes, where: str = "device") -> str:
    """Check and strip the checksum of one reply line; CommunicationError if malformed or corrupted."""
    s = line.rstrip(b"\r\n")
    if b"*" not in s:
        raise CommunicationError(f"reply without checksum: {line!r}", device=where)
    payload, _, cs = s.rpartition(b"*")
    try:
        want = int(cs, 16)
    except ValueError:
        raise CommunicationError(f"bad checksum field in {line!r}", device=where) from None
    if checksum(payload) != want or len(cs) != 2:
        raise CommunicationError(f"checksum mismatch in {line!r}", device=where)
    try:
        return payload.decode("ascii")
    except UnicodeDecodeError:
        raise CommunicationError(f"non-ASCII reply {line!r}", device=where) from None


def _fields(text: str, head: str, n: Optional[int], where: str) -> list[str]:
    parts = text.split()
    if not parts:
        raise CommunicationError("empty reply", device=where)
    if parts[0] == "ERR":
        raise CommunicationError(f"device error: {' '.join(parts[1:])}", device=where)
    if parts[0] != head or (n is not None and len(parts) != n + 1):
        raise CommunicationError(f"unexpected reply {text!r} (expected '{head}' with {n} fields)", device=where)
    return parts[1:]


def _number(txt: str, where: str) -> float:
    try:
        v = float(txt)
    except ValueError:
        raise CommunicationError(f"not a number: {txt!r}", device=where) from None
    if not math.isfinite(v):
        raise CommunicationError(f"non-finite value {txt!r}", device=where)
    return v


class ForceProtocol:
    """Load-cell board with ``channels`` channels: ``F?`` → ``F <seq> <counts…>``."""

    def __init__(self, channels: int):
        self.channels = int(channels)

    def request(self) -> bytes:
        return frame("F?")

    def parse(self, line: bytes, where: str = "force sensors") -> tuple[int, list[float]]:
        f = _fields(unframe(line, where), "F", self.channels + 1, where)
        return int(_number(f[0], where)), [_number(x, where) for x in f[1:]]


class PressureProtocol:
    """Valve controller with a pressure sensor (see the module table)."""

    def read_request(self) -> bytes:
        return frame("P?")

    def parse_reading(self, line: bytes, where: str = "pressure") -> tuple[int, float]:
        f = _fields(unframe(line, where), "P", 2, where)
        return int(_number(f[0], where)), _number(f[1], where)

    def set_request(self, pressure: float) -> bytes:
        return frame(f"PSET {pressure:.1f}")

    def command_request(self, name: str) -> bytes:
        if name not in ("HOLD", "VENT"):
            raise LimitError(f"unknown valve command {name!r}")
        return frame(name)

    def parse_ack(self, line: bytes, what: str, where: str = "pressure") -> None:
        text = unframe(line, where)
        if text.startswith("ERR"):
            raise PressureFault(f"valve controller refused {what}: {text[3:].strip()}", device=where)
        if text.split()[:2] != ["OK", what]:
            raise CommunicationError(f"unexpected acknowledgement {text!r} for {what}", device=where)


# ============================================================================================ transport
class LineTransport:
    """Request/reply over a serial port (or any pyserial URL): one line out, one line back."""

    _open: dict = {}
    _lock_all = threading.Lock()

    def __init__(self, port_or_stream, baudrate: int = 115200, timeout: float = 0.5, name: Optional[str] = None):
        self.timeout = float(timeout)
        self.name = name or str(port_or_stream)
        self._lock = threading.Lock()
        if isinstance(port_or_stream, str):
            import serial
            try:
                self.stream = serial.serial_for_url(port_or_stream, baudrate=baudrate, timeout=timeout)
            except (serial.SerialException, OSError, ValueError) as exc:
                raise CommunicationError(f"cannot open serial port {port_or_stream}: {exc}", device=self.name) from None
        else:
            self.stream = port_or_stream
        self.users = 0

    @classmethod
    def shared(cls, port: str, baudrate: int, timeout: float) -> "LineTransport":
        with cls._lock_all:
            t = cls._open.get(port)
            if t is None:
                t = cls._open[port] = cls(port, baudrate, timeout)
            t.users += 1
            return t

    def release(self) -> None:
        with self._lock_all:
            self.users -= 1
            if self.users <= 0:
                self._open.pop(self.name, None)
                try:
                    self.stream.close()
                except Exception:                              # noqa: BLE001
                    pass

    def ask(self, request: bytes) -> bytes:
        """Send one line and return the reply line; SensorTimeout if none arrives in time."""
        with self._lock:
            try:
                self.stream.reset_input_buffer()
                self.stream.write(request)
                line = self.stream.readline()
            except (OSError, ValueError) as exc:
                raise CommunicationError(f"serial transfer failed: {exc}", device=self.name) from None
        if not line or not line.endswith(b"\n"):
            raise SensorTimeout(f"no reply to {request.strip()!r} within {self.timeout:g} s", device=self.name)
        return line


# ============================================================================================ devices
class _SerialDevice:
    """Shared open/close of a device on a (possibly shared) line transport."""

    port: str
    baudrate: int
    timeout: float
    name: str

    def _attach(self, transport: Optional[LineTransport]) -> None:
        self.transport, self._own = transport, transport is None

    def open(self) -> None:
        if self.transport is None:
            self.transport = LineTransport.shared(self.port, self.baudrate, self.timeout)

    def close(self) -> None:
        if self._own and self.transport is not None:
            self.transport.release()
            self.transport = None

    def _t(self) -> LineTransport:
        if self.transport is None:
            raise CommunicationError("device is not open", device=self.name)
        return self.transport


class SerialForceSensor(_SerialDevice, ForceSensor):
    """One channel of a serial load-cell board: tension = scale · counts + offset [N]."""

    def __init__(self, port: str, *, channel: int, channels: int = 3, baudrate: int = 115200, scale: float = 1.0,
                 offset: float = 0.0, timeout: float = 0.5, transport: Optional[LineTransport] = None):
        if not 1 <= int(channel) <= int(channels):
            raise LimitError(f"force channel {channel} outside 1…{channels}")
        self.port, self.channel, self.baudrate, self.timeout = port, int(channel), baudrate, timeout
        self.scale, self.offset = float(scale), float(offset)
        self.protocol = ForceProtocol(channels)
        self._attach(transport)
        self.name = f"force sensor {self.channel} ({port})"
        self.last_seq: Optional[int] = None

    def read(self) -> float:
        seq, counts = self.protocol.parse(self._t().ask(self.protocol.request()), self.name)
        self.last_seq = seq
        return self.scale * counts[self.channel - 1] + self.offset


class SerialPressureSupply(_SerialDevice, PressureSupply):
    """Valve controller with a micro pressure sensor on a serial line."""

    def __init__(self, port: str, *, baudrate: int = 115200, timeout: float = 0.5,
                 transport: Optional[LineTransport] = None):
        self.port, self.baudrate, self.timeout = port, baudrate, timeout
        self.protocol = PressureProtocol()
        self._attach(transport)
        self.name = f"pressure supply ({port})"
        self._setpoint: Optional[float] = None

    def set(self, pressure: float) -> None:
        self.protocol.parse_ack(self._t().ask(self.protocol.set_request(pressure)), "PSET", self.name)
        self._setpoint = float(pressure)

    def read(self) -> float:
        return self.protocol.parse_reading(self._t().ask(self.protocol.read_request()), self.name)[1]

    def hold(self) -> None:
        self.protocol.parse_ack(self._t().ask(self.protocol.command_request("HOLD")), "HOLD", self.name)

    def vent(self) -> None:
        self.protocol.parse_ack(self._t().ask(self.protocol.command_request("VENT")), "VENT", self.name)
        self._setpoint = 0.0
