"""EPOS4 in cyclic synchronous position over PDO + SYNC, against fake drives in another process (their own SYNC
clock): the PDO mapping written at start-up, set-points and read-backs by PDO (no SDO in the loop), a silent
drive and an EMCY as DriveFaults, the options checked.  Timing under host stalls: test_epos4_timing.py."""

import time

import pytest

pytest.importorskip("canopen")

from fakes.canbridge import register  # noqa: E402
from fakes.drive_process import DriveProcess  # noqa: E402
from fakes.fixtures import quiet_canopen  # noqa: E402,F401  (fixture)
from hardware import DriveFault, LimitError  # noqa: E402
from hardware import epos4 as e4  # noqa: E402
from hardware.canbus import CanBus  # noqa: E402
from hardware.epos4_cyclic import Epos4CyclicDrive, interpolation_period  # noqa: E402
from hardware.limits import SafetyLimits  # noqa: E402

CPM = 1e6                                   # counts per metre
LIMITS = SafetyLimits(length_min=0.10, length_max=0.22, speed_max=0.05)


@pytest.fixture
def proc(quiet_canopen):
    register()
    with DriveProcess([{"node_id": 3, "initial_counts": 160_000, "target_counts": 160_000,
                        "max_counts_per_s": 1e6}]) as p:
        yield p


def cyclic_drive(proc, **kw):
    kw = {"sync_period": 0.005, "counts_per_turn": 4096, **kw}
    return Epos4CyclicDrive(3, channel=proc.channel, interface="bellows-bridge", counts_per_metre=CPM,
                            limits=LIMITS, **kw)


def mapping(proc, index):
    n = proc.od(3, index, 0)
    return [((v >> 16), (v >> 8) & 0xFF, v & 0xFF) for v in (proc.od(3, index, k) for k in range(1, n + 1))]


def test_start_up_maps_the_pdos_and_enters_cyclic_synchronous_position(proc):
    with cyclic_drive(proc, heartbeat_time=0.02) as d:
        assert proc.od(3, e4.MODE) == e4.CYCLIC_SYNC_POSITION and proc.state(3) == "OPERATION ENABLED"
        assert proc.nmt_state(3) == "OPERATIONAL"
        assert mapping(proc, e4.RPDO1_MAP) == [(e4.TARGET, 0, 32)]
        assert mapping(proc, e4.TPDO1_MAP) == [(e4.STATUSWORD, 0, 16), (e4.POSITION_DEMAND, 0, 32)]
        assert mapping(proc, e4.TPDO2_MAP) == [(e4.POSITION, 0, 32), (e4.CURRENT, 2, 32)]
        for com, cob, every in ((e4.RPDO1_COM, 0x203, 1), (e4.TPDO1_COM, 0x183, 1), (e4.TPDO2_COM, 0x283, 2)):
            assert proc.od(3, com, 1) == cob and proc.od(3, com, 2) == every       # TPDO 2 every 10 ms (2 × 5 ms)
        assert proc.od(3, e4.HEARTBEAT_TIME) == 20                                   # ms
        assert proc.od(3, e4.PROFILE_VELOCITY) == round(0.05 * CPM * 60 / 4096)     # speed_max in rpm
        assert d.position() == pytest.approx(0.160) and d.state() == "OPERATION ENABLED"


def test_moves_go_by_pdo(proc):
    with cyclic_drive(proc) as d:
        sent = d.sent
        d.move_to(0.162)                                     # 2 mm at 50 mm/s: 8 SYNC periods of 5 ms
        t0 = time.monotonic()
        while not d.target_reached():
            assert time.monotonic() - t0 < 3.0
            time.sleep(0.005)
        assert d.position() == pytest.approx(0.162, abs=2e-6) and d.setpoint == pytest.approx(0.162)
        assert d.sent - sent >= 8
        assert d.current() >= 0 and abs(d.following_error()) <= 1e-6
        with pytest.raises(LimitError):                      # travel limits before anything leaves
            d.move_to(0.25)


def test_a_silent_drive_is_a_drive_fault(proc):
    with cyclic_drive(proc, heartbeat_time=0.02, heartbeat_timeout=0.3, pdo_timeout=0.3) as d:
        d.check()
        proc.silence(3)
        time.sleep(0.5)
        with pytest.raises(DriveFault, match="silent"):
            d.check()
        with pytest.raises(DriveFault, match="silent"):
            d.move_to(0.161)


def test_emcy_is_a_drive_fault(proc):
    with pytest.raises(DriveFault) as info:
        with cyclic_drive(proc) as d:
            proc.inject_fault(3, 0x8611)
            time.sleep(0.1)
            d.check()
    assert info.value.code == 0x8611


def test_cyclic_options_are_checked(proc):
    with pytest.raises(LimitError, match="sync_period"):
        cyclic_drive(proc, sync_period=1.0)
    with pytest.raises(LimitError, match="heartbeat_timeout"):
        cyclic_drive(proc, heartbeat_time=0.1, heartbeat_timeout=0.05)
    with pytest.raises(LimitError, match="127"):
        Epos4CyclicDrive(127, channel=proc.channel, interface="bellows-bridge", counts_per_metre=CPM)
    with pytest.raises(LimitError, match="cyclic"):
        Epos4CyclicDrive(3, channel=proc.channel, interface="bellows-bridge", counts_per_metre=CPM, cyclic=False)
    with pytest.raises(LimitError, match="0x60C2"):
        interpolation_period(0.00235)
    assert interpolation_period(0.002) == (20, -4) and interpolation_period(0.05) == (50, -3)
    for bad in (0, -1e-3, float("nan"), "2 ms", True):
        with pytest.raises(LimitError):
            interpolation_period(bad)
    for kw in ({"bitrate": 0}, {"bitrate": "1M"}, {"channel": ""}, {"interface": None}):
        with pytest.raises(LimitError):
            CanBus(**{"interface": "bellows-bridge", "channel": proc.channel, **kw})


def test_one_sync_per_bus(proc):
    bus = CanBus("bellows-bridge", proc.channel)
    bus.open()
    try:
        bus.start_sync(0.005)
        bus.start_sync(0.005)                                # the same period again: nothing new
        with pytest.raises(LimitError, match="one SYNC per bus"):
            bus.start_sync(0.002)
        for bad in (0.0, float("nan"), 1.0, "5 ms"):
            with pytest.raises(LimitError):
                bus.start_sync(bad)
    finally:
        bus.close()
