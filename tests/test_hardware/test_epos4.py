"""EPOS4 CiA 402 backend against a fake drive (canopen LocalNode) on python-can's virtual bus."""

import time
import uuid

import pytest

pytest.importorskip("canopen")

from fakes.cia402_drive import FakeEpos4  # noqa: E402
from hardware import DriveFault, LimitError  # noqa: E402
from hardware import epos4 as e4  # noqa: E402
from hardware.epos4_profile import Epos4ProfileDrive as Epos4Drive  # noqa: E402
from hardware.errors import CommunicationError  # noqa: E402
from hardware.limits import SafetyLimits  # noqa: E402

CPM = 1e6                                   # counts per metre (1 count = 1 µm of tendon)
LIMITS = SafetyLimits(length_min=0.10, length_max=0.22)
from fakes.fixtures import quiet_canopen  # noqa: E402,F401  (fixture)


@pytest.fixture
def bus(quiet_canopen):
    channel = f"rig-{uuid.uuid4().hex[:8]}"
    with FakeEpos4(node_id=1, channel=channel, initial_counts=160_000) as fake:
        yield fake, channel


def drive(channel, **kw):
    return Epos4Drive(node_id=1, channel=channel, interface="virtual", counts_per_metre=CPM, limits=LIMITS, **kw)


def wait_reached(d, timeout=2.0):
    t0 = time.monotonic()
    while not d.target_reached():
        assert time.monotonic() - t0 < timeout, "move did not finish"
        time.sleep(0.005)


def test_state_machine_and_profile_position(bus):
    fake, ch = bus
    with drive(ch) as d:                                               # connects and enables
        assert d.state() == "OPERATION ENABLED" and fake.mode == e4.PROFILE_POSITION
        cws = [v for i, v in fake.writes if i == e4.CONTROLWORD]
        assert cws == [0x06, 0x07, 0x0F]                                # shutdown → switch on → enable
        d.enable()                                                      # idempotent: no power-stage cycle
        assert [v for i, v in fake.writes if i == e4.CONTROLWORD] == cws
        assert d.position() == pytest.approx(0.160)
        d.move_to(0.1605)
        assert fake.target == 160_500
        cws = [v for i, v in fake.writes if i == e4.CONTROLWORD]
        assert cws[-2:] == [0x3F, 0x2F]                                 # new setpoint (bit 4) set, then cleared
        wait_reached(d)
        assert d.position() == pytest.approx(0.1605, abs=1e-9)
        assert d.current() == pytest.approx(0.15)
    assert fake.state == "READY TO SWITCH ON"                          # normal exit: halted, then disabled


def test_travel_limit_sends_nothing(bus):
    fake, ch = bus
    with drive(ch) as d:
        d.enable()
        n = len(fake.writes)
        with pytest.raises(LimitError):
            d.move_to(0.30)
        with pytest.raises(LimitError):
            d.move_to(float("nan"))
        assert len(fake.writes) == n


def test_fault_emcy_reset_and_reenable(bus):
    fake, ch = bus
    with drive(ch) as d:
        d.enable()
        fake.inject_fault(0x8611)
        time.sleep(0.05)                                               # EMCY arrives on the bus thread
        with pytest.raises(DriveFault) as info:
            d.check()
        assert info.value.code == 0x8611
        with pytest.raises(DriveFault):
            d.move_to(0.161)
        d.fault_reset()
        assert d.state() == "SWITCH ON DISABLED"
        d.enable()
        d.move_to(0.161)
        wait_reached(d)
        assert d.position() == pytest.approx(0.161)


def test_statusword_fault_without_emcy_and_following_error(bus):
    fake, ch = bus
    with drive(ch) as d:
        d.enable()
        fake.following_error()
        with pytest.raises(DriveFault, match="following error"):
            d.check()
        fake.following = False
        fake.inject_fault(0x3210, emcy=False)
        with pytest.raises(DriveFault) as info:
            d.check()
        assert info.value.code == 0x3210 and "FAULT" in str(info.value)


def test_unacknowledged_setpoint_is_a_fault(bus):
    fake, ch = bus
    fake.ignore_setpoints = True
    with drive(ch, ack_timeout=0.05) as d:
        d.enable()
        with pytest.raises(DriveFault, match="not acknowledged"):
            d.move_to(0.161)


def test_exception_inside_quick_stops(bus):
    fake, ch = bus
    with pytest.raises(KeyboardInterrupt):
        with drive(ch) as d:
            d.enable()
            d.move_to(0.2)
            raise KeyboardInterrupt
    assert fake.state == "QUICK STOP ACTIVE"
    assert abs(fake.target - fake.pos) < 0.5                           # the move was stopped


def test_hold_halts_the_move(bus):
    fake, ch = bus
    fake.rate = 2e3                                                     # slow: 2 mm/s
    with drive(ch) as d:
        d.enable()
        d.move_to(0.170)
        time.sleep(0.05)
        d.hold()
        p = d.position()
        time.sleep(0.05)
        assert d.position() == pytest.approx(p) and p < 0.1605
        assert d.target_reached()


def test_no_drive_on_the_bus_is_a_communication_error(quiet_canopen):
    d = Epos4Drive(node_id=5, channel=f"empty-{uuid.uuid4().hex[:6]}", interface="virtual", counts_per_metre=CPM)
    with pytest.raises(CommunicationError):
        with d:
            pass


def test_bad_parameters():
    with pytest.raises(LimitError):
        Epos4Drive(node_id=0, counts_per_metre=CPM)
    with pytest.raises(LimitError):
        Epos4Drive(node_id=1, counts_per_metre=0)
    with pytest.raises(LimitError):
        Epos4Drive(node_id=1, counts_per_metre=CPM, speed=0.01)       # speed needs counts_per_turn
    assert e4.state_of(0x0237) == "OPERATION ENABLED" and e4.state_of(0x0008) == "FAULT"


def _wait_state(fake, state, timeout=1.0):
    t0 = time.monotonic()
    while fake.state != state:
        assert time.monotonic() - t0 < timeout, f"fake drive stayed in {fake.state}, expected {state}"
        time.sleep(0.002)


def test_safe_stop_never_re_enables_a_quick_stopped_drive(bus):
    """hold()/make_safe() on a QUICK STOP ACTIVE drive must not write enable operation (0x0F) again."""
    fake, ch = bus
    with pytest.raises(DriveFault):
        with drive(ch) as d:
            d.quick_stop()
            _wait_state(fake, "QUICK STOP ACTIVE")
            n = len(fake.writes)
            assert d.make_safe() == []
            d.hold()
            assert fake.state == "QUICK STOP ACTIVE"
            assert not [v for i, v in fake.writes[n:] if i == e4.CONTROLWORD and v & 0x0F == 0x0F]
            raise DriveFault("test")
    assert fake.state == "QUICK STOP ACTIVE"


def test_disable_from_each_state(bus):
    """disable(): enabled → READY TO SWITCH ON (0x06); quick stop → SWITCH ON DISABLED (0x00); fault: left off."""
    fake, ch = bus
    with drive(ch) as d:
        d.disable()
        assert fake.state == "READY TO SWITCH ON" and d.state() == "READY TO SWITCH ON"
        d.enable()
        d.quick_stop()
        _wait_state(fake, "QUICK STOP ACTIVE")
        d.disable()
        assert fake.state == "SWITCH ON DISABLED"
        fake.inject_fault(0x8611, emcy=False)
        d.disable()                                                     # no exception, no reset, no enable
        assert fake.state == "FAULT"
