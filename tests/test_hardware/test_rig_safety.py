"""Safety limits are checked before anything is sent; every fault stops motion and ends the run with its
reason, on the simulated rig; Ctrl-C leaves the rig safe and the log closed."""

import math
import signal

import numpy as np
import pytest

from controller import LACC, RunOptions, run_on_rig
from hardware import (DriveFault, HardwareError, LimitError, PressureFault, RunAborted, SensorTimeout,
                      SimulatedRig, TrackingLost)
from hardware.limits import SafetyLimits
from hardware.runlog import read_run_log

P = 60e3
from fakes.fixtures import target  # noqa: E402,F401  (fixture)


def fresh_rig(paper_model, target, **kw):
    rig = SimulatedRig(paper_model, P, **kw)
    rig.command(paper_model.ik(target, P).tendon_lengths)
    rig.advance()
    return rig


def test_travel_step_and_tension_limits_send_nothing(paper_model, target):
    rig = fresh_rig(paper_model, target, limits=SafetyLimits.around(0.16, max_step=2e-3, tension_max=4.0))
    before = rig.target.copy()
    for bad, kw in (([0.05, 0.16, 0.16], {}),                                  # beyond the travel
                    (rig.commanded + [3e-3, 0, 0], {}),                         # a 3 mm step > 2 mm
                    (rig.commanded, {"expected_tensions": [4.5, 1.0, 1.0]}),    # IK expects 4.5 N > 4 N
                    ([np.nan, 0.16, 0.16], {}), ("abc", {}), ([0.16, 0.16], {})):
        with pytest.raises(LimitError):
            rig.command(bad, **kw)
        np.testing.assert_array_equal(rig.target, before)                     # nothing reached the drives
    kinds = [k for _, k, _ in rig.events]
    assert kinds.count("limit") == 6
    with pytest.raises(LimitError, match="kPa"):
        rig.set_pressure(200e3)
    assert rig.pressure == P
    rig.command(rig.commanded + [1e-3, 0, 0])                                  # within limits: sent
    assert rig.target[0] == pytest.approx(before[0] + 1e-3)


def test_limits_reject_invalid_limits():
    with pytest.raises(LimitError):
        SafetyLimits(length_min=0.2, length_max=0.1)
    with pytest.raises(LimitError):
        SafetyLimits(tension_max=0.0)
    with pytest.raises(LimitError):
        SafetyLimits(pressure_max=float("nan"))
    with pytest.raises(LimitError):
        SafetyLimits(max_step="1")


def test_measured_tension_beyond_limit_stops_the_run(paper_model, target, tmp_path):
    # the IK expects 2.2 N at most (within 2.5 N); the hidden 0.4 N load makes the measured tension exceed it
    rig = SimulatedRig(paper_model, load=(0, 0, -0.4), limits=SafetyLimits.around(0.16, tension_max=2.5))
    with pytest.raises(LimitError, match="measured tension") as info:
        run_on_rig(LACC(paper_model, P), rig, target, RunOptions(log=tmp_path / "run.h5"))
    assert info.value.log_path == tmp_path / "run.h5"
    d = read_run_log(tmp_path / "run.h5")
    assert d.ended.startswith("fault") and "measured tension" in d.ended
    assert any(k == "stop" for _, k, _ in d.events)


def test_expected_tension_beyond_limit_is_refused_before_the_log(paper_model, target, tmp_path):
    rig = SimulatedRig(paper_model, limits=SafetyLimits.around(0.16, tension_max=2.0))
    with pytest.raises(LimitError, match="expected tension"):
        run_on_rig(LACC(paper_model, P), rig, target, RunOptions(log=tmp_path / "run.h5"))
    assert not (tmp_path / "run.h5").exists() and rig.lengths is None          # no log, nothing commanded


@pytest.mark.parametrize("fault,exc,at", [("tracking_lost", TrackingLost, 0.0), ("invalid_pose", TrackingLost, 0.0),
                                           ("tracker_stale", SensorTimeout, 0.3),
                                           ("sensor_timeout", SensorTimeout, 0.0),
                                           ("drive_fault", DriveFault, 0.0),
                                           ("pressure_overshoot", PressureFault, 0.0)])
def test_each_fault_stops_motion_with_its_reason(paper_model, target, tmp_path, fault, exc, at):
    rig = SimulatedRig(paper_model, load=(0, 0.05, -0.4), on_fault_pressure="vent",
                       options=__import__("hardware").PlantOptions(length_rate=5e-3))
    rig.inject(fault, at=at)
    log = tmp_path / f"{fault}.h5"
    with pytest.raises(exc) as info:
        # tracker_stale: the frame freezes at 0.3 s; the next reads are older than the 0.5 s timeout
        run_on_rig(LACC(paper_model, P), rig, target, RunOptions(log=log, duration=5.0, idle_period=0.3))
    assert isinstance(info.value, HardwareError)
    res = info.value.result
    assert res.status == "fault" and type(info.value).__name__ in res.reason
    # motion stopped: every drive holds where it is; the pressure was vented as configured
    np.testing.assert_array_equal(rig.target, rig.lengths)
    assert rig.pressure == 0.0 and rig.pressure_supply.vented
    d = read_run_log(log)
    assert d.ended.startswith("fault") and type(info.value).__name__ in d.ended
    stops = [m for _, k, m in d.events if k == "stop"]
    assert stops and "vented" in stops[0]
    if fault == "drive_fault":
        assert "quick-stopped" in stops[0] and info.value.code == 0x8611
        assert not rig.drives[0].enabled


def test_pressure_held_by_default(paper_model, target):
    rig = SimulatedRig(paper_model)
    rig.inject("tracking_lost")
    with pytest.raises(TrackingLost):
        run_on_rig(LACC(paper_model, P), rig, target)
    assert rig.pressure == P and not rig.pressure_supply.vented


def _interrupted_run(paper_model, target, log, duration, at_third_sample, by="Ctrl-C"):
    """A held run on a loaded simulated rig whose status callback calls ``at_third_sample()`` at the third
    sample; returns (rig, the samples' status dicts, the RunAborted raised — its message names ``by``)."""
    rig = SimulatedRig(paper_model, load=(0, 0, -0.3), options=__import__("hardware").PlantOptions(length_rate=5e-3))
    calls = []

    def status(s):
        calls.append(s)
        if len(calls) == 3:
            at_third_sample()
    with pytest.raises(RunAborted, match=by) as info:
        run_on_rig(LACC(paper_model, P), rig, target, RunOptions(log=log, duration=duration, status=status))
    return rig, calls, info.value


def _ctrl_c():
    raise KeyboardInterrupt


def test_ctrl_c_leaves_the_rig_safe_and_the_log_closed(paper_model, target, tmp_path):
    rig, _, err = _interrupted_run(paper_model, target, tmp_path / "r.h5", math.inf, _ctrl_c)
    assert str(tmp_path / "r.h5") in str(err)
    np.testing.assert_array_equal(rig.target, rig.lengths)
    d = read_run_log(tmp_path / "r.h5")
    assert d.ended.startswith("interrupted") and d.rows == 3


class _RaisesCtrlCWhenCollected:
    """Ctrl-C arriving while a finaliser runs: Python prints "Exception ignored" and drops the
    KeyboardInterrupt (signal.raise_signal runs the handler before it returns, here inside __del__)."""

    def __del__(self):
        signal.raise_signal(signal.SIGINT)


@pytest.mark.filterwarnings("ignore::pytest.PytestUnraisableExceptionWarning")     # the dropped one
def test_ctrl_c_lost_in_a_finaliser_still_stops_the_run(paper_model, target, tmp_path):
    # the object is made and collected at once: its interrupt is dropped
    before = signal.getsignal(signal.SIGINT)
    _, calls, _ = _interrupted_run(paper_model, target, tmp_path / "r.h5", 60.0, _RaisesCtrlCWhenCollected)
    assert len(calls) == 3                                 # stopped at the next cycle, not after 60 s of holding
    assert read_run_log(tmp_path / "r.h5").ended.startswith("interrupted")
    assert signal.getsignal(signal.SIGINT) is before                        # the handler it had is back


@pytest.mark.filterwarnings("ignore::pytest.PytestUnraisableExceptionWarning")
@pytest.mark.parametrize("disposition", ["ignored", "custom"])
def test_ctrl_c_stops_the_run_whatever_sigint_was_before(paper_model, target, tmp_path, disposition):
    # a process started in the background by a non-interactive shell inherits SIGINT ignored (CI does): Python
    # then installs no KeyboardInterrupt handler; an application's own handler is chained, not replaced
    seen = []
    before = signal.SIG_IGN if disposition == "ignored" else (lambda signum, frame: seen.append(signum))
    old = signal.signal(signal.SIGINT, before)
    try:
        _, calls, _ = _interrupted_run(paper_model, target, tmp_path / "r.h5", 60.0, _RaisesCtrlCWhenCollected)
        assert len(calls) == 3
        assert signal.getsignal(signal.SIGINT) is before                      # restored as it was
    finally:
        signal.signal(signal.SIGINT, old)
    assert seen == ([] if disposition == "ignored" else [signal.SIGINT])


class _SigtermWhenCollected:
    def __del__(self):
        signal.raise_signal(signal.SIGTERM)


@pytest.mark.filterwarnings("ignore::pytest.PytestUnraisableExceptionWarning")
def test_sigterm_stops_the_run_through_the_safe_stop(paper_model, target, tmp_path):
    # SIGTERM's default action would kill the process with the drives enabled and the log open
    assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL
    rig, calls, _ = _interrupted_run(paper_model, target, tmp_path / "r.h5", 60.0, _SigtermWhenCollected,
                                     by="SIGTERM")
    assert len(calls) == 3
    np.testing.assert_array_equal(rig.target, rig.lengths)
    assert read_run_log(tmp_path / "r.h5").ended.startswith("interrupted")
    assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL


def test_context_manager_makes_safe_on_exception(paper_model, target):
    rig = fresh_rig(paper_model, target, options=__import__("hardware").PlantOptions(length_rate=1e-3))
    with pytest.raises(RuntimeError):
        with rig:
            rig.command(rig.commanded + [2e-3, 0, 0])
            rig.advance(0.5)                                   # halfway through a 2 s move
            raise RuntimeError("operator script failed")
    np.testing.assert_array_equal(rig.target, rig.lengths)    # the move was stopped, not completed
    assert any(k == "stop" and "RuntimeError" in m for _, k, m in rig.events)


def test_fault_reset_clears_a_drive_fault(paper_model, target):
    rig = fresh_rig(paper_model, target)
    rig.inject("drive_fault", drive=1)
    with pytest.raises(DriveFault):
        rig.check_health()
    rig.drives[1].fault_reset()
    rig.check_health()


@pytest.mark.parametrize("confirm", [True, False])
def test_a_drive_fault_is_recovered_only_when_a_person_confirms(paper_model, target, tmp_path, confirm):
    rig = SimulatedRig(paper_model, load=(0, 0, -0.3), options=__import__("hardware").PlantOptions(length_rate=5e-3))
    rig.inject("drive_fault", at=0.5, drive=2)
    asked = []

    def person(exc):
        asked.append(exc)
        # asked after the stop: every drive quick-stopped where it was, nothing enabled
        assert not any(d.enabled for d in rig.drives)
        np.testing.assert_array_equal(rig.target, rig.lengths)
        return confirm
    log = tmp_path / "r.h5"
    if confirm:
        res = run_on_rig(LACC(paper_model, P), rig, target,
                         RunOptions(log=log, duration=3.0, idle_period=0.2, recover=person))
        assert res.status == "held" and res.recoveries == 1 and res.final_error < 0.2e-3
        events = read_run_log(log).events
        kinds = [k for _, k, _ in events]
        assert "recovered" in kinds and kinds.index("stop") < kinds.index("recovered")
        # every drive was quick-stopped, so each one was brought back
        assert all(f"sim drive {i}" in events[kinds.index("recovered")][2] for i in (1, 2, 3))
    else:
        with pytest.raises(DriveFault):
            run_on_rig(LACC(paper_model, P), rig, target,
                       RunOptions(log=log, duration=3.0, idle_period=0.2, recover=person))
        assert read_run_log(log).ended.startswith("fault")
    assert len(asked) == 1 and isinstance(asked[0], DriveFault)


def test_recover_must_be_a_callable(paper_model, target):
    from ancf.errors import InputError
    with pytest.raises(InputError, match="recover"):
        run_on_rig(LACC(paper_model, P), SimulatedRig(paper_model), target, RunOptions(recover=True))


def test_without_a_person_a_drive_fault_ends_the_run(paper_model, target):
    rig = SimulatedRig(paper_model, options=__import__("hardware").PlantOptions(length_rate=5e-3))
    rig.inject("drive_fault", at=0.5)
    with pytest.raises(DriveFault):
        run_on_rig(LACC(paper_model, P), rig, target, RunOptions(duration=3.0, idle_period=0.2))
    assert not rig.drives[0].enabled
