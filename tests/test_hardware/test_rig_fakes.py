"""A hardware Rig built from a rig TOML file, running against the fake backends (three CiA 402 drives on a
virtual CAN bus, serial instruments on pseudo-terminals, a NatNet stream over loopback UDP): limits send
nothing; each fault stops motion with its reason."""

import time
import uuid

import numpy as np
import pytest

pytest.importorskip("canopen")
pytest.importorskip("serial")

from fakes.bench import FakeNatNet, free_udp_port  # noqa: E402
from fakes.cia402_drive import FakeEpos4  # noqa: E402
from fakes.serial_instruments import FakeSerialInstrument  # noqa: E402
from hardware import DriveFault, LimitError, PressureFault, RigConfig, SensorTimeout, TrackingLost, build_rig  # noqa: E402
from hardware import epos4 as e4  # noqa: E402
from fakes.fixtures import quiet_canopen  # noqa: E402,F401  (fixture)


@pytest.fixture
def fake_bench(tmp_path, quiet_canopen):
    """The fake instruments running, and a rig file describing them: (path, drives, loadcells, valves, natnet);
    the drives in profile position."""
    ch = f"bench-{uuid.uuid4().hex[:8]}"
    drives = [FakeEpos4(node_id=i + 1, channel=ch, initial_counts=165_000) for i in range(3)]
    port = free_udp_port()
    nat = FakeNatNet(port)
    nat.position = (0.17, 0.0, -0.002)
    with FakeSerialInstrument(forces=[2200, 1600, 1600]) as loadcells, FakeSerialInstrument() as valves:
        for d in drives:
            d.__enter__()
        toml = '''
name = "fake bench"
backend = "hardware"
actuator = "paper_unscaled"
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
counts_per_turn = 4096
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
port = {port}
rotation = [[1, 0, 0], [0, 1, 0], [0, 0, 1]]
'''
        path = tmp_path / "rig.toml"
        path.write_text(toml)
        nat.start()
        try:
            yield path, drives, loadcells, valves, nat
        finally:
            nat.stop()
            for d in drives:
                d.__exit__(None, None, None)


@pytest.fixture
def bench(fake_bench):
    path, drives, loadcells, valves, nat = fake_bench
    with build_rig(RigConfig.from_toml(path)) as rig:
        yield rig, drives, loadcells, valves, nat


def test_rig_runs_against_the_fakes(bench):
    """Profile position over SDO (cyclic synchronous position on the whole fake bench, with the drives in another
    process: test_doc_rig_command.py and test_rig_recovery.py)."""
    rig, drives, loadcells, valves, nat = bench
    time.sleep(0.05)
    assert all(d.state == "OPERATION ENABLED" and d.mode == e4.PROFILE_POSITION for d in drives)
    rig.set_pressure(60e3)
    assert valves.setpoint == 60e3
    rig.command([0.166, 0.165, 0.165])
    rig.advance()
    np.testing.assert_allclose(rig.positions(), [0.166, 0.165, 0.165], rtol=0, atol=1e-9)
    h = rig.check_health()
    np.testing.assert_allclose(h["tensions"], [2.2, 1.6, 1.6])
    assert h["pressure"] == 60e3
    np.testing.assert_allclose(rig.measure(frames=3), [0.17, 0.0, -0.002], atol=1e-7)
    # the rig file's speed (10 mm/s) reached the drives as profile velocity: 10 mm/s · 1000 counts/mm → rpm
    assert all([v for i, v in d.writes if i == e4.PROFILE_VELOCITY][-1] == round(10e-3 * 1e6 * 60 / 4096)
               for d in drives)


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


def test_closing_the_rig_disables_the_drives(fake_bench):
    path, drives, *_ = fake_bench
    with build_rig(RigConfig.from_toml(path)) as rig:
        rig.command([0.166, 0.165, 0.165])
        rig.advance()
    assert [d.state for d in drives] == ["READY TO SWITCH ON"] * 3


def _enable_writes_after_quick_stop(d):
    cws = [v for i, v in d.writes if i == e4.CONTROLWORD]
    k = max((j for j, v in enumerate(cws) if v == e4.CW_QUICK_STOP), default=len(cws))
    return [v for v in cws[k:] if v & 0x0F == 0x0F]


def test_a_drive_fault_leaves_every_drive_stopped_after_close(fake_bench):
    """Rig.__exit__ after a DriveFault quick-stops, then closes: no drive is re-enabled (no 0x0F after the
    quick stop), the faulted drive stays in FAULT, the others end switched off."""
    path, drives, *_ = fake_bench
    with pytest.raises(DriveFault):
        with build_rig(RigConfig.from_toml(path)) as rig:
            rig.command([0.166, 0.165, 0.165])
            rig.advance()
            drives[1].inject_fault(0x8611)
            time.sleep(0.05)
            rig.check_health()
    assert [d.state for d in drives] == ["SWITCH ON DISABLED", "FAULT", "SWITCH ON DISABLED"]
    assert not any(_enable_writes_after_quick_stop(d) for d in drives)


def test_run_on_rig_drive_fault_leaves_the_drives_stopped(fake_bench, tmp_path):
    from ancf import Model, presets
    from controller import LACC, RunOptions, run_on_rig
    path, drives, loadcells, valves, nat = fake_bench
    model = Model(presets.paper_unscaled())
    target = model.fk((2.2, 1.6, 1.6), 60e3).tip
    nat.position = tuple(target + np.array([0.002, 0.0, 0.0]))
    rig = build_rig(RigConfig.from_toml(path))
    orig = rig.check_health

    def faulty():
        drives[0].inject_fault(0x8611)
        time.sleep(0.05)
        return orig()
    rig.check_health = faulty
    with pytest.raises(DriveFault):
        run_on_rig(LACC(model, 60e3), rig, target, RunOptions(log=tmp_path / "run.h5", max_iterations=2))
    assert drives[0].state == "FAULT"
    assert [d.state for d in drives[1:]] == ["SWITCH ON DISABLED"] * 2
    assert not any(_enable_writes_after_quick_stop(d) for d in drives)


def test_bellows_control_on_the_fake_hardware(fake_bench, tmp_path):
    """The CLI drives the fake bench end to end: the tracker reports the target, so LACC converges at once;
    the log holds the hardware readings and a static state; the drives are disabled after the run."""
    import json
    from typer.testing import CliRunner
    from ancf import Model, presets
    from hardware.runlog import read_run_log
    from hardware.static_states import read_static_states
    from validation.commands.main import app
    path, drives, loadcells, valves, nat = fake_bench
    target = Model(presets.paper_unscaled()).fk((2.2, 1.6, 1.6), 60e3).tip
    nat.position = tuple(target)
    log = tmp_path / "hw.h5"
    res = CliRunner().invoke(app, ["control", "--rig", str(path), "--target-mm", ",".join(f"{x * 1e3:.6f}" for x in target),
                                   "--pressure-kpa", "60", "--max-iterations", "3", "--log", str(log), "--json"])
    assert res.exit_code == 0, res.output
    out = json.loads(res.stdout.strip().splitlines()[-1])
    assert out["status"] == "converged" and out["iterations"] == 0
    d = read_run_log(log)
    assert not d.attrs["rig"]["simulated"] and d.attrs["rig"]["drives"] == ["Epos4ProfileDrive"] * 3
    np.testing.assert_allclose(d.samples["tension"][0], [2.2, 1.6, 1.6])
    assert np.all(np.isnan(d.samples["true_tip"]))                         # no truth on hardware
    st = read_static_states(log)
    assert st.n_states == 1 and st.pressure[0] == 60e3
    assert all(d.state == "READY TO SWITCH ON" for d in drives)             # disabled after the run (0x06)
    assert all([v for i, v in d.writes if i == e4.CONTROLWORD][-1] == e4.CW_SHUTDOWN for d in drives)
    with pytest.raises(SystemExit):                                         # sim-only options refused
        from validation.commands.main import main
        import sys
        old = sys.argv
        sys.argv = ["bellows", "control", "--rig", str(path), "--target-mm", "170,0,0", "--pressure-kpa", "60",
                    "--mismatch"]
        try:
            main()
        finally:
            sys.argv = old
