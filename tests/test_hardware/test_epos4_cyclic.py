"""EPOS4 in cyclic synchronous position mode over PDO + SYNC, against the fake drive on python-can's virtual
bus: the PDO mapping written at start-up, set-points and read-backs by PDO (no SDO in the loop), the speed
limit of the set-point interpolation, a silent drive and an EMCY as DriveFaults."""

import struct
import time
import uuid

import pytest

pytest.importorskip("canopen")

from fakes.cia402_drive import FakeEpos4  # noqa: E402
from fakes.fixtures import quiet_canopen  # noqa: E402,F401  (fixture)
from hardware import DriveFault, LimitError  # noqa: E402
from hardware import epos4 as e4  # noqa: E402
from hardware.epos4 import Epos4Drive  # noqa: E402
from hardware.limits import SafetyLimits  # noqa: E402

CPM = 1e6                                   # counts per metre
LIMITS = SafetyLimits(length_min=0.10, length_max=0.22, speed_max=0.05)


@pytest.fixture
def bus(quiet_canopen):
    channel = f"csp-{uuid.uuid4().hex[:8]}"
    with FakeEpos4(node_id=3, channel=channel, initial_counts=160_000, counts_per_second=1e6) as fake:
        yield fake, channel


def cyclic_drive(channel, **kw):
    kw = {"sync_period": 0.005, **kw}                  # 200 Hz: the Python fake keeps up on a loaded machine
    return Epos4Drive(node_id=3, channel=channel, interface="virtual", counts_per_metre=CPM, limits=LIMITS,
                      cyclic=True, **kw)


def wait_reached(d, timeout=3.0):
    t0 = time.monotonic()
    while not d.target_reached():
        assert time.monotonic() - t0 < timeout, "move did not finish"
        time.sleep(0.002)
    return time.monotonic() - t0


def test_start_up_maps_the_pdos_and_enters_cyclic_synchronous_position(bus):
    fake, ch = bus
    with cyclic_drive(ch, heartbeat_time=0.02) as d:
        assert fake.mode == e4.CYCLIC_SYNC_POSITION and fake.state == "OPERATION ENABLED"
        assert fake.node.nmt.state == "OPERATIONAL"
        assert fake.mapping(e4.RPDO1_MAP) == [(e4.CONTROLWORD, 0, 16), (e4.TARGET, 0, 32)]
        assert fake.mapping(e4.TPDO1_MAP) == [(e4.STATUSWORD, 0, 16), (e4.POSITION, 0, 32)]
        assert fake.mapping(e4.TPDO2_MAP) == [(e4.FOLLOWING_ERROR, 0, 32), (e4.CURRENT, 2, 32)]
        for com, cob in ((e4.RPDO1_COM, 0x203), (e4.TPDO1_COM, 0x183), (e4.TPDO2_COM, 0x283)):
            assert fake.node.sdo[com][1].raw == cob and fake.node.sdo[com][2].raw == e4.SYNC_TRANSMISSION
        assert fake.node.sdo[e4.HEARTBEAT_TIME].raw == 20                                  # ms
        assert d.position() == pytest.approx(0.160) and d.state() == "OPERATION ENABLED"


def test_moves_go_by_pdo_at_the_speed_limit(bus):
    fake, ch = bus
    with cyclic_drive(ch) as d:
        n_sdo, syncs = len(fake.writes), fake.syncs
        d.move_to(0.165)                                     # 5 mm at 50 mm/s: the set-points take ≥ 0.1 s
        took = wait_reached(d)
        assert took >= 0.09
        assert d.position() == pytest.approx(0.165, abs=2e-6)
        assert len(fake.writes) == n_sdo                     # no SDO transfer in the loop
        assert fake.syncs - syncs >= 0.09 / d.sync_period * 0.5
        assert d.current() == pytest.approx(0.15) and abs(d.following_error()) <= 1e-6
        with pytest.raises(LimitError):                      # travel limits before anything leaves
            d.move_to(0.25)


def test_a_silent_drive_is_a_drive_fault(bus):
    fake, ch = bus
    with cyclic_drive(ch, heartbeat_time=0.02, heartbeat_timeout=0.3, pdo_timeout=0.3) as d:
        d.check()
        fake.silence()
        time.sleep(0.5)
        with pytest.raises(DriveFault, match="silent"):
            d.check()
        with pytest.raises(DriveFault, match="silent"):
            d.move_to(0.161)


def test_emcy_is_still_a_drive_fault(bus):
    fake, ch = bus
    with pytest.raises(DriveFault) as info:
        with cyclic_drive(ch) as d:
            fake.node.emcy.send(0x8611, 0x01, struct.pack("<5B", 0, 0, 0, 0, 0))
            time.sleep(0.05)
            d.check()
    assert info.value.code == 0x8611


def test_cyclic_options_are_checked(bus):
    _, ch = bus
    with pytest.raises(LimitError, match="sync_period"):
        cyclic_drive(ch, sync_period=1.0)
    with pytest.raises(LimitError, match="heartbeat_timeout"):
        cyclic_drive(ch, heartbeat_time=0.1, heartbeat_timeout=0.05)
