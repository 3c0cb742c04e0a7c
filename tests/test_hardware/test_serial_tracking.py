"""Serial instruments (protocol on bytes; devices through a pseudo-terminal and pyserial's loop://) and the
NatNet tracker (parser on packets; client over loopback UDP)."""

import socket
import time

import numpy as np
import pytest

pytest.importorskip("serial")

from fakes.serial_instruments import FakeSerialInstrument  # noqa: E402
from hardware.errors import CommunicationError, PressureFault, SensorTimeout  # noqa: E402
from hardware.serial_devices import (ForceProtocol, LineTransport, PressureProtocol, SerialForceSensor,  # noqa: E402
                                     SerialPressureSupply, frame, unframe)
from hardware.tracking import NatNetTracker, build_frame_packet, parse_packet  # noqa: E402


def test_framing_and_protocols_on_bytes():
    assert frame("F?") == b"F?*" + b"%02X" % (ord("F") ^ ord("?")) + b"\n"
    assert unframe(frame("P 3 60000.0")) == "P 3 60000.0"
    for bad in (b"P 3 60000.0\n", b"P 3 60000.0*ZZ\n", frame("P 3 60000.0").replace(b"6", b"7", 1)):
        with pytest.raises(CommunicationError):
            unframe(bad)
    fp = ForceProtocol(3)
    assert fp.parse(frame("F 7 100 -20 3.5")) == (7, [100.0, -20.0, 3.5])
    for bad in ("F 7 100 -20", "X 7 1 2 3", "F 7 1 2 nan", "ERR overload"):
        with pytest.raises(CommunicationError):
            fp.parse(frame(bad))
    pp = PressureProtocol()
    assert pp.set_request(60e3) == frame("PSET 60000.0")
    assert pp.parse_reading(frame("P 1 59990.5")) == (1, 59990.5)
    with pytest.raises(PressureFault):
        pp.parse_ack(frame("ERR valve stuck"), "PSET")
    with pytest.raises(CommunicationError):
        pp.parse_ack(frame("OK VENT"), "PSET")


def test_loop_url_transport():
    t = LineTransport("loop://", timeout=0.1)
    assert t.ask(b"hello*00\n") == b"hello*00\n"            # loop:// echoes the request
    t.release()


def test_devices_through_a_pseudo_terminal():
    with FakeSerialInstrument(forces=[1500, 800, -5]) as inst:
        sensors = [SerialForceSensor(inst.port, channel=i + 1, scale=2e-3, offset=0.01, timeout=0.2) for i in range(3)]
        supply = SerialPressureSupply(inst.port, timeout=0.2)
        for d in (*sensors, supply):
            d.open()
        assert sensors[0].transport is sensors[2].transport is supply.transport      # one port, one transport
        assert [s.read() for s in sensors] == pytest.approx([3.01, 1.61, 0.0])
        supply.set(60e3)
        assert supply.read() == pytest.approx(60e3) and supply.setpoint == 60e3
        supply.vent()
        assert inst.valves == "VENT" and supply.read() == 0.0
        inst.corrupt = True
        with pytest.raises(CommunicationError, match="checksum"):
            sensors[0].read()
        inst.corrupt, inst.silent = False, True
        with pytest.raises(SensorTimeout):
            sensors[1].read()
        inst.silent, inst.refuse = False, True
        with pytest.raises(PressureFault, match="overcurrent"):
            supply.set(50e3)
        for d in (*sensors, supply):
            d.close()
        assert inst.port not in LineTransport._open


def test_natnet_parser():
    pkt = build_frame_packet(42, bodies=[(3, (0.1, 0.2, 0.3), (0, 0, 0, 1), 1e-4, True),
                                         (1, (0.17, 0.0, -0.002), (0, 0, 0, 1), 2e-4, False)],
                             marker_sets=[("tool", [(1, 2, 3), (4, 5, 6)])], unlabeled=[(7, 8, 9)])
    fr = parse_packet(pkt)
    assert fr.frame == 42 and set(fr.rigid_bodies) == {1, 3}
    np.testing.assert_allclose(fr.rigid_bodies[3].position, [0.1, 0.2, 0.3], rtol=1e-6)
    assert fr.rigid_bodies[3].tracked and not fr.rigid_bodies[1].tracked
    assert parse_packet(b"\x01\x00\x00\x00") is None                     # not a frame of data
    for bad in (pkt[:30], pkt[:2], b"\x07\x00\xff\x00" + pkt[4:20]):
        with pytest.raises(CommunicationError):
            parse_packet(bad)


def test_natnet_client_over_udp():
    R = np.array([[0, 0, 1], [1, 0, 0], [0, 1, 0]], float)                # tracker y-up → actuator frame
    trk = NatNetTracker("127.0.0.1", 0, rigid_body_id=1, rotation=R, offset=(0.0, 0.0, 0.01), timeout=0.2)
    with trk:
        with pytest.raises(SensorTimeout):
            trk.read()
        tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        for k, (pos, ok) in enumerate((((0.0, 0.0, 0.17), True), ((0.001, 0.0, 0.17), True))):
            tx.sendto(build_frame_packet(k, bodies=[(1, pos, (0, 0, 0, 1), 1e-4, ok)]), ("127.0.0.1", trk.port))
        tx.sendto(b"\x07\x00\x40\x00garbage", ("127.0.0.1", trk.port))      # a truncated frame
        time.sleep(0.05)
        pose = trk.read()
        assert pose.frame == 1 and pose.valid and trk.bad_packets == 1
        np.testing.assert_allclose(pose.position, R @ [0.001, 0.0, 0.17] + [0, 0, 0.01], atol=1e-7)
        tx.sendto(build_frame_packet(2, bodies=[(1, (0, 0, 0.17), (0, 0, 0, 1), 1e-4, False)]), ("127.0.0.1", trk.port))
        time.sleep(0.05)
        assert not trk.read().valid
        tx.close()
