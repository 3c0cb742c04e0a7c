r"""Optical tip tracking: a NatNet (OptiTrack Motive) rigid-body client with its own frame parser.

NatNet streams UDP packets (data port 1511, multicast 239.255.42.99 by default, or unicast).  Every
packet starts with ``uint16 message id, uint16 payload size`` (little endian); message 7 is a frame of
data.  This parser reads the part of a frame-of-data payload (NatNet 3.x/4.x layout) it needs:

=====================  ===============================================================================
field                  layout
=====================  ===============================================================================
frame number           int32
marker sets            int32 count; each: NUL-terminated name, int32 n, n × 3 float32 [m]
unlabeled markers      int32 count; count × 3 float32 [m]  (legacy "other markers")
rigid bodies           int32 count; each: int32 id, 3 float32 position [m], 4 float32 quaternion
                       (qx, qy, qz, qw), float32 mean marker error [m], int16 params (bit 0: tracked)
=====================  ===============================================================================

and stops there (skeletons, labeled markers, timing follow).  From NatNet 4.1 on, every count is
followed by an int32 byte count of its entries: pass ``version=(4, 1)`` (rig file: ``natnet_version =
"4.1"``); the default (3, 0) reads the 3.0 … 4.0 layout.  NatNet 2.x (rigid-body markers inside the rigid
body) is not supported.  A rigid body whose params bit 0 is clear
is an *invalid* pose (occluded): :class:`NatNetTracker` returns it with ``valid=False`` and the rig
raises :class:`~hardware.errors.TrackingLost`; no packet within the timeout is a
:class:`~hardware.errors.SensorTimeout`.  The tracker frame is mapped to the actuator frame by
``rotation`` (3×3) and ``offset`` [m]: p_actuator = R · p_tracker + offset.  (The vendor's sample
client is not used: it is under a restrictive licence and does more than this needs.)
"""

from __future__ import annotations

import socket
import struct
import time
from dataclasses import dataclass
from typing import Optional

import numpy as np

from .errors import CommunicationError, RigConfigError, SensorTimeout
from .interfaces import TipTracker, TrackedPose

NAT_FRAMEOFDATA = 7
_I32, _U16, _F3, _F4, _F, _I16 = (struct.Struct(f) for f in ("<i", "<H", "<3f", "<4f", "<f", "<h"))


@dataclass(frozen=True)
class RigidBody:
    id: int
    position: np.ndarray          # (3,) [m], tracker frame
    quaternion: np.ndarray        # (4,) qx, qy, qz, qw
    error: float                  # mean marker error [m]
    tracked: bool


@dataclass(frozen=True)
class NatNetFrame:
    frame: int
    rigid_bodies: dict            # id → RigidBody


def natnet_version(version) -> tuple:
    """``(major, minor)`` from a tuple or a "4.1" string; NatNet 3.0 or later, else RigConfigError."""
    try:
        v = tuple(int(x) for x in (version.split(".") if isinstance(version, str) else version))
    except (TypeError, ValueError, AttributeError):
        raise RigConfigError(f"NatNet version must be 'major.minor' (e.g. '4.1'), got {version!r}") from None
    if len(v) < 2 or v[:2] < (3, 0):
        raise RigConfigError(f"NatNet version {version!r}: 3.0 or later is supported (2.x has another layout)")
    return v[:2]


class _Reader:
    def __init__(self, data: bytes, sized: bool = False):
        self.data, self.pos, self.sized = data, 0, sized

    def take(self, st: struct.Struct):
        if self.pos + st.size > len(self.data):
            raise CommunicationError(f"NatNet packet truncated at byte {self.pos}", device="NatNet")
        out = st.unpack_from(self.data, self.pos)
        self.pos += st.size
        return out

    def cstring(self) -> str:
        end = self.data.find(b"\0", self.pos)
        if end < 0:
            raise CommunicationError("NatNet packet: unterminated name", device="NatNet")
        s = self.data[self.pos:end].decode("utf-8", "replace")
        self.pos = end + 1
        return s

    def count(self, what: str, limit: int = 10_000, top: bool = True) -> int:
        """A count; for a top-level section (``top``) of a NatNet >= 4.1 frame, then its byte count."""
        (n,) = self.take(_I32)
        if not 0 <= n <= limit:
            raise CommunicationError(f"NatNet packet: implausible {what} count {n}", device="NatNet")
        if self.sized and top:                         # NatNet >= 4.1: byte count of the entries
            (size,) = self.take(_I32)
            if not 0 <= size <= len(self.data) - self.pos:
                raise CommunicationError(f"NatNet packet: {what} data of {size} bytes, "
                                         f"{len(self.data) - self.pos} left", device="NatNet")
        return n


def parse_packet(data: bytes, version=(3, 0)) -> Optional[NatNetFrame]:
    """Parse one NatNet packet of the stream version ``version`` (major, minor); returns None for messages
    other than frame-of-data.  Malformed packets raise CommunicationError."""
    sized = natnet_version(version) >= (4, 1)
    if not isinstance(data, (bytes, bytearray)) or len(data) < 4:
        raise CommunicationError("NatNet packet shorter than its header", device="NatNet")
    msg_id, size = struct.unpack_from("<HH", data, 0)
    if msg_id != NAT_FRAMEOFDATA:
        return None
    if size > len(data) - 4:
        raise CommunicationError(f"NatNet packet: payload size {size} > {len(data) - 4} bytes received", device="NatNet")
    r = _Reader(bytes(data[4:4 + size]), sized)
    (frame_no,) = r.take(_I32)
    for _ in range(r.count("marker set")):
        r.cstring()
        for _ in range(r.count("marker", top=False)):
            r.take(_F3)
    for _ in range(r.count("unlabeled marker")):
        r.take(_F3)
    bodies = {}
    for _ in range(r.count("rigid body")):
        (rid,) = r.take(_I32)
        pos = np.array(r.take(_F3), float)
        quat = np.array(r.take(_F4), float)
        (err,) = r.take(_F)
        (params,) = r.take(_I16)
        bodies[rid] = RigidBody(rid, pos, quat, float(err), bool(params & 0x01))
    return NatNetFrame(frame_no, bodies)


def build_frame_packet(frame_no: int, bodies=(), marker_sets=(), unlabeled=()) -> bytes:
    """The inverse of :func:`parse_packet` (for replaying recorded poses and for tests).
    ``bodies``: (id, (x, y, z), (qx, qy, qz, qw), error, tracked)."""
    out = [_I32.pack(frame_no), _I32.pack(len(marker_sets))]
    for name, markers in marker_sets:
        out += [name.encode() + b"\0", _I32.pack(len(markers))] + [_F3.pack(*m) for m in markers]
    out += [_I32.pack(len(unlabeled))] + [_F3.pack(*m) for m in unlabeled]
    out.append(_I32.pack(len(bodies)))
    for rid, pos, quat, err, tracked in bodies:
        out += [_I32.pack(rid), _F3.pack(*pos), _F4.pack(*quat), _F.pack(err), _I16.pack(1 if tracked else 0)]
    out.append(b"\0" * 8)                      # the rest of a real frame (not parsed)
    payload = b"".join(out)
    return struct.pack("<HH", NAT_FRAMEOFDATA, len(payload)) + payload


class NatNetTracker(TipTracker):
    """Tip pose from one NatNet rigid body over UDP.

    address, port : local address and data port to bind ("0.0.0.0", 1511); multicast_group : join this
    group (None: unicast); rigid_body_id : the tool's rigid body; rotation (3, 3), offset (3,) [m] : tracker
    → actuator frame; timeout : how long :meth:`read` waits for a first frame [s]; natnet_version : the
    stream's NatNet version (Motive's streaming settings), (3, 0) … (4, 0) share a layout, (4, 1)+ adds byte
    counts
    """

    def __init__(self, address: str = "0.0.0.0", port: int = 1511, *, rigid_body_id: int = 1,
                 multicast_group: Optional[str] = None, rotation=None, offset=(0.0, 0.0, 0.0), timeout: float = 0.5,
                 max_error: float = 2e-3, natnet_version=(3, 0)):
        self.version = globals()["natnet_version"](natnet_version)
        self.address, self.port, self.group = address, int(port), multicast_group
        self.rigid_body_id = int(rigid_body_id)
        self.R = np.eye(3) if rotation is None else np.asarray(rotation, float).reshape(3, 3)
        self.offset = np.asarray(offset, float).reshape(3)
        self.timeout, self.max_error = float(timeout), float(max_error)
        self.name = f"NatNet rigid body {rigid_body_id}"
        self.sock: Optional[socket.socket] = None
        self.latest: Optional[TrackedPose] = None
        self.bad_packets = 0

    def open(self) -> None:
        if self.sock is not None:
            return
        s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM, socket.IPPROTO_UDP)
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            s.bind((self.address, self.port))
            if self.group:
                mreq = socket.inet_aton(self.group) + socket.inet_aton(self.address)
                s.setsockopt(socket.IPPROTO_IP, socket.IP_ADD_MEMBERSHIP, mreq)
        except OSError as exc:
            s.close()
            raise CommunicationError(f"cannot listen on UDP {self.address}:{self.port}: {exc}", device=self.name) from None
        s.setblocking(False)
        self.sock = s
        self.port = s.getsockname()[1]

    def close(self) -> None:
        if self.sock is not None:
            self.sock.close()
            self.sock = None

    def _drain(self) -> None:
        while True:
            try:
                data = self.sock.recv(65536)
            except BlockingIOError:
                return
            try:
                fr = parse_packet(data, self.version)
            except CommunicationError:
                self.bad_packets += 1
                continue
            if fr is None or self.rigid_body_id not in fr.rigid_bodies:
                continue
            rb = fr.rigid_bodies[self.rigid_body_id]
            valid = rb.tracked and rb.error <= self.max_error and bool(np.all(np.isfinite(rb.position)))
            self.latest = TrackedPose(time.monotonic(), fr.frame, self.R @ rb.position + self.offset, valid=valid,
                                      quality=rb.error)

    def read(self) -> TrackedPose:
        """The newest pose received (waits up to ``timeout`` for a first one)."""
        if self.sock is None:
            raise CommunicationError("tracker is not open", device=self.name)
        t0 = time.monotonic()
        self._drain()
        while self.latest is None:
            if time.monotonic() - t0 > self.timeout:
                raise SensorTimeout(f"no frame with rigid body {self.rigid_body_id} within {self.timeout:g} s",
                                    device=self.name)
            time.sleep(0.002)
            self._drain()
        return self.latest
