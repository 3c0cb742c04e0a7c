"""A hardware Rig built from a rig TOML file, running against the fake backends (three CiA 402 drives on a
virtual CAN bus, serial instruments on pseudo-terminals, a NatNet stream over loopback UDP): limits send
nothing; each fault stops motion with its reason."""

import socket
import threading
import time
import uuid

import numpy as np
import pytest

pytest.importorskip("canopen")
pytest.importorskip("serial")

from fakes.cia402_drive import FakeEpos4  # noqa: E402
from fakes.serial_instruments import FakeSerialInstrument  # noqa: E402
from hardware import DriveFault, LimitError, PressureFault, Rig, RigConfig, SensorTimeout, TrackingLost  # noqa: E402
from hardware import epos4 as e4  # noqa: E402
from hardware.tracking import build_frame_packet  # noqa: E402


class FakeNatNet:
    """Streams a rigid body at 100 Hz to a UDP port; ``tracked`` switches occlusion."""

    def __init__(self):
        self.port, self.tracked, self.position = None, True, (0.17, 0.0, -0.002)
        self._stop = threading.Event()

    def start(self, port):
        self.port = port
        self._t = threading.Thread(target=self._run, daemon=True)
        self._t.start()

    def _run(self):
        tx, k = socket.socket(socket.AF_INET, socket.SOCK_DGRAM), 0
        while not self._stop.is_set():
            tx.sendto(build_frame_packet(k, bodies=[(1, self.position, (0, 0, 0, 1), 1e-4, self.tracked)]),
                      ("127.0.0.1", self.port))
            k += 1
            time.sleep(0.01)
        tx.close()

    def stop(self):
        self._stop.set()
        self._t.join(timeout=1)


@pytest.fixture
def bench(tmp_path, quiet_canopen):
    ch = f"bench-{uuid.uuid4().hex[:8]}"
    drives = [FakeEpos4(node_id=i + 1, channel=ch, initial_counts=165_000) for i in range(3)]
    with FakeSerialInstrument(forces=[2200, 1600, 1600]) as loadcells, FakeSerialInstrument() as valves:
        for d in drives:
            d.__enter__()
        toml = '''
name = "fake bench"
backend = "hardware"
actuator = "paper"
on_fault_pressure = "vent"
speed_mm_per_s = 10
[limits]
length_min_mm = 140
length_max_mm = 190
max_step_mm = 5
tension_max_N = 10
pressure_max_kPa = 100
sensor_timeout_s = 0.3
''' + "".join(f'''
[[drives]]
backend = "epos4"
node_id = {i + 1}
interface = "virtual"
channel = "{ch}"
counts_per_mm = 1000
zero_length_mm = 0
''' for i in range(3)) + "".join(f'''
[[force_sensors]]
backend = "serial"
port = "{loadcells.port}"
channel = {i + 1}
scale_N_per_count = 0.001
''' for i in range(3)) + f'''
[pressure]
backend = "serial"
port = "{valves.port}"
[tracker]
backend = "natnet"
address = "127.0.0.1"
port = 0
'''
        path = tmp_path / "rig.toml"
        path.write_text(toml)
        rig = Rig.from_config(RigConfig.from_toml(path))
        nat = FakeNatNet()
        try:
            with rig:
                nat.start(rig.tracker.port)
                yield rig, drives, loadcells, valves, nat
        finally:
            nat.stop()
            for d in drives:
                d.__exit__(None, None, None)


def test_rig_runs_against_the_fakes(bench):
    rig, drives, loadcells, valves, nat = bench
    assert all(d.state == "OPERATION ENABLED" for d in drives)
    rig.set_pressure(60e3)
    assert valves.setpoint == 60e3
    rig.command([0.166, 0.165, 0.165])
    rig.advance()
    np.testing.assert_allclose(rig.positions(), [0.166, 0.165, 0.165], atol=1e-9)
    h = rig.check_health()
    np.testing.assert_allclose(h["tensions"], [2.2, 1.6, 1.6])
    assert h["pressure"] == 60e3
    time.sleep(0.05)
    np.testing.assert_allclose(rig.measure(frames=3), [0.17, 0.0, -0.002], atol=1e-7)


def test_limits_send_nothing_to_the_drives(bench):
    rig, drives, *_ = bench
    n = [len(d.writes) for d in drives]
    for bad in ([0.20, 0.165, 0.165], [0.172, 0.165, 0.165]):          # beyond travel; a 7 mm step
        with pytest.raises(LimitError):
            rig.command(bad)
    with pytest.raises(LimitError):
        rig.command([0.166, 0.165, 0.165], expected_tensions=[12.0, 1.0, 1.0])
    with pytest.raises(LimitError):
        rig.set_pressure(120e3)
    assert [len(d.writes) for d in drives] == n


@pytest.mark.parametrize("fault", ["drive", "sensor_timeout", "pressure_overshoot", "tracking_lost", "tension"])
def test_each_fault_on_the_fake_backends(bench, fault):
    rig, drives, loadcells, valves, nat = bench
    rig.set_pressure(60e3)
    rig.command([0.166, 0.165, 0.165])
    rig.advance()
    time.sleep(0.05)
    exc = {"drive": DriveFault, "sensor_timeout": SensorTimeout, "pressure_overshoot": PressureFault,
           "tracking_lost": TrackingLost, "tension": LimitError}[fault]
    if fault == "drive":
        drives[1].inject_fault(0x8611)
        time.sleep(0.05)
    elif fault == "sensor_timeout":
        loadcells.silent = True
    elif fault == "pressure_overshoot":
        valves.overshoot_Pa = 25e3
    elif fault == "tracking_lost":
        nat.tracked = False
        time.sleep(0.05)
    else:
        loadcells.forces = [12000, 1600, 1600]                               # 12 N measured > 10 N
    with pytest.raises(exc) as info:
        rig.check_health()
        rig.measure()
    rig.safe_stop(info.value.reason, quick=isinstance(info.value, DriveFault))
    assert valves.valves == "VENT" and valves.pressure == 0.0               # pressure vented as configured
    cws = [[v for i, v in d.writes if i == e4.CONTROLWORD][-1] for d in drives]
    if fault == "drive":
        assert all(cw == e4.CW_QUICK_STOP for cw in cws)
    else:
        assert all(cw & e4.CW_HALT for cw in cws)                           # drives halted, holding
    assert any(k == "stop" for _, k, _ in rig.events)
