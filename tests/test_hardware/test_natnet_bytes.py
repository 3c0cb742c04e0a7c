"""The NatNet parser against hand-written packets: the bytes are laid out here field by field with
``struct`` from the published frame-of-data layout (NatNet SDK 3.x/4.x packet client) — nothing of
``hardware.tracking`` is used to build them, so the parser is checked against the format, not against
its own builder.

Frame of data (message id 7), little endian, NatNet 3.0 … 4.0::

    uint16 message id = 7, uint16 payload bytes
    int32  frame number
    int32  marker set count;   each: name\\0, int32 marker count, count × float32[3]
    int32  legacy (unlabeled) marker count;   count × float32[3]
    int32  rigid body count;   each: int32 id, float32[3] position, float32[4] quaternion qx qy qz qw,
                               float32 mean marker error, int16 params (bit 0: tracking valid)
    int32  skeleton count;     int32 labeled marker count; each: int32 id, float32[3], float32 size,
                               int16 params, float32 residual
    int32  force plate count;  int32 device count
    uint32 timecode, uint32 subframe, float64 timestamp, uint64 mid-exposure, uint64 received,
    uint64 transmitted, int16 params, int32 end of data

NatNet 4.1 and later: every one of those counts (marker sets, legacy markers, rigid bodies, skeletons,
labeled markers, force plates, devices) is followed by an int32 byte count of the entries that follow.

All float values below are exact in float32, so the parsed values are compared exactly.
"""

import socket
import struct
import time

import numpy as np
import pytest

from hardware.errors import CommunicationError
from hardware.tracking import NatNetTracker, parse_packet


def le(fmt: str, *values) -> bytes:
    return struct.pack("<" + fmt, *values)


BODIES = [  # id, position [m], quaternion (qx, qy, qz, qw), mean marker error [m], params
    (1, (0.5, -0.25, 1.75), (0.0, 0.0, 0.6, 0.8), 2.0 ** -10, 0x0001),
    (7, (0.125, 0.0, -3.0), (0.0, 0.0, 0.0, 1.0), 2.0 ** -9, 0x0000),      # not tracked
    (3, (-0.0625, 2.5, 0.375), (0.5, 0.5, 0.5, 0.5), 2.0 ** -12, 0x0003),  # tracked (bit 0) + another bit
]
FRAME = 123456


def section(count: int, body: bytes, sized: bool) -> bytes:
    """A count, then (NatNet ≥ 4.1) the byte count of the entries, then the entries."""
    return le("i", count) + (le("i", len(body)) if sized else b"") + body


def frame_of_data(version=(3, 0)) -> bytes:
    sized = version >= (4, 1)
    marker_sets = (b"tool\x00" + le("i", 3) + le("3f", 0.5, -0.25, 1.75) + le("3f", 0.25, 0.0, 1.5)
                   + le("3f", 0.75, 0.0, 1.5)
                   + b"all\x00" + le("i", 1) + le("3f", 9.0, 9.0, 9.0))
    legacy = le("3f", 1.0, 2.0, 3.0) + le("3f", -1.0, -2.0, -3.0)
    bodies = b"".join(le("i", rid) + le("3f", *pos) + le("4f", *q) + le("f", err) + le("h", params)
                      for rid, pos, q, err, params in BODIES)
    labeled = le("i", (1 << 16) | 2) + le("3f", 0.5, 0.5, 0.5) + le("f", 0.014) + le("h", 0) + le("f", 0.0001)
    payload = (le("i", FRAME)
               + section(2, marker_sets, sized)
               + section(2, legacy, sized)
               + section(len(BODIES), bodies, sized)
               + section(0, b"", sized)                                  # skeletons
               + section(1, labeled, sized)                              # labeled markers
               + section(0, b"", sized)                                  # force plates
               + section(0, b"", sized)                                  # devices
               + le("I", 0x12345678) + le("I", 0) + le("d", 12.5) + le("Q", 1) + le("Q", 2) + le("Q", 3)
               + le("h", 0) + le("i", 0))
    return le("HH", 7, len(payload)) + payload


def check(fr):
    assert fr is not None and fr.frame == FRAME
    assert sorted(fr.rigid_bodies) == [1, 3, 7]
    for rid, pos, q, err, params in BODIES:
        rb = fr.rigid_bodies[rid]
        assert rb.id == rid
        np.testing.assert_array_equal(rb.position, np.float32(pos))
        np.testing.assert_array_equal(rb.quaternion, np.float32(q))
        assert rb.error == err
        assert rb.tracked == bool(params & 1)


def test_natnet_3_frame_of_data_from_hand_written_bytes():
    check(parse_packet(frame_of_data((3, 0))))


def test_natnet_4_1_frame_of_data_with_byte_counts():
    check(parse_packet(frame_of_data((4, 1)), version=(4, 1)))


def test_other_messages_and_damaged_frames():
    assert parse_packet(le("HH", 5, 4) + le("i", 0)) is None                 # NAT_MODELDEF: not a frame
    assert parse_packet(le("HH", 1, 0)) is None                              # ping response
    pkt = frame_of_data()
    body_start = 4 + 4 + 4 + len(b"tool\x00") + 4 + 36 + len(b"all\x00") + 4 + 12 + 4 + 24 + 4
    cut = pkt[4:body_start + 20]                                             # inside the first rigid body
    with pytest.raises(CommunicationError):
        parse_packet(le("HH", 7, len(cut)) + cut)
    with pytest.raises(CommunicationError):                                 # payload size beyond the datagram
        parse_packet(pkt[:-10])
    bad_count = bytearray(pkt)
    bad_count[8:12] = le("i", -5)                                            # a negative marker-set count
    with pytest.raises(CommunicationError):
        parse_packet(bytes(bad_count))


@pytest.mark.parametrize("version", [(3, 0), (4, 1)])
def test_tracker_reads_the_hand_written_frame_over_udp(version):
    R = np.array([[0, 0, 1], [1, 0, 0], [0, 1, 0]], float)
    trk = NatNetTracker("127.0.0.1", 0, rigid_body_id=3, rotation=R, offset=(0.0, 0.0, 0.01), timeout=2.0,
                        max_error=1e-3, natnet_version=version)
    with trk:
        tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        tx.sendto(frame_of_data(version), ("127.0.0.1", trk.port))
        time.sleep(0.05)
        pose = trk.read()
        tx.close()
    assert pose.frame == FRAME and pose.valid and trk.bad_packets == 0
    np.testing.assert_allclose(pose.position, R @ [-0.0625, 2.5, 0.375] + [0, 0, 0.01], rtol=0, atol=1e-12)
