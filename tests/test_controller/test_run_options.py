"""controller.RunOptions: a run's options, checked when they are made; ``import controller`` leaves the rig
layer unloaded; ``on_ctrl_c="end"`` makes Ctrl-C a run's normal end (rig safe, summary, log closed), SIGTERM and a
Ctrl-C before the run still abort."""

import dataclasses
import math
import signal
import subprocess
import sys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ancf.errors import InputError
from controller import LACC, RunOptions, run_on_rig
from controller.run import MIN_IDLE_PERIOD

P = 60e3
from fakes.fixtures import target  # noqa: E402,F401  (fixture)


@pytest.mark.parametrize("kw, message", [
    ({"max_iterations": -1}, "max_iterations"),
    ({"max_iterations": 2.5}, "max_iterations"),
    ({"max_iterations": True}, "max_iterations"),
    ({"max_iterations": None}, "max_iterations or a duration"),
    ({"duration": -1.0}, "duration"),
    ({"duration": float("nan")}, "duration"),
    ({"duration": "10"}, "duration"),
    ({"duration": 5.0, "idle_period": 0.0}, "idle_period must be > 0"),
    ({"idle_period": 0.5 * MIN_IDLE_PERIOD}, "idle_period"),
    ({"idle_period": -0.1}, "idle_period"),
    ({"sim_compute_time": "fast"}, "sim_compute_time"),
    ({"sim_compute_time": -1e-3}, "sim_compute_time"),
    ({"average_frames": 0}, "average_frames"),
    ({"average_frames": 2.0}, "average_frames"),
    ({"initial_load": (0.0, 0.0)}, "initial_load"),
    ({"initial_load": (0.0, math.inf, 0.0)}, "initial_load"),
    ({"applied_load": (0.0, 0.0)}, "applied_load"),
    ({"applied_load": "heavy"}, "applied_load"),
    ({"shaper": (0.5,)}, "shaper"),
    ({"shaper": (0.0, 0.1)}, "shaper A1"),
    ({"shaper": (1.5, 0.1)}, "shaper A1"),
    ({"shaper": (0.5, -0.1)}, "shaper delay"),
    ({"recover": True}, "recover"),
    ({"status": "print"}, "status"),
    ({"on_ctrl_c": "ignore"}, "on_ctrl_c"),
    ({"log": 3}, "log"),
    ({"run_info": ["a"]}, "run_info"),
    ({"force": "yes"}, "force"),
    ({"record_static": 1}, "record_static"),
])
def test_out_of_range_options_are_refused_when_made(kw, message):
    with pytest.raises(InputError, match=message):
        RunOptions(**kw)


def test_options_are_frozen_and_checked_again_on_replace():
    o = RunOptions(duration=math.inf, idle_period=0.05, shaper=(np.float64(0.6), 0.01), initial_load=[0, 0, -0.1])
    assert o.duration == math.inf and o.shaper == (0.6, 0.01) and isinstance(o.shaper[0], float)
    np.testing.assert_array_equal(o.initial_load, [0.0, 0.0, -0.1])
    with pytest.raises(dataclasses.FrozenInstanceError):
        o.duration = 1.0
    with pytest.raises(ValueError):
        o.initial_load[2] = 0.0                                    # the array is read-only too
    assert dataclasses.replace(o, duration=2.0).duration == 2.0
    with pytest.raises(InputError, match="idle_period"):
        dataclasses.replace(o, idle_period=0.0)


@settings(max_examples=40, deadline=None)
@given(it=st.one_of(st.none(), st.integers(0, 50)), dur=st.one_of(st.none(), st.floats(0, 1e3), st.just(math.inf)),
       idle=st.one_of(st.just(0.0), st.floats(MIN_IDLE_PERIOD, 10.0)))
def test_options_in_range_are_kept_as_given(it, dur, idle):
    ok = (it is not None or dur is not None) and not (dur is not None and idle == 0.0)
    if not ok:
        with pytest.raises(InputError):
            RunOptions(max_iterations=it, duration=dur, idle_period=idle)
        return
    o = RunOptions(max_iterations=it, duration=dur, idle_period=idle)
    assert (o.max_iterations, o.duration, o.idle_period) == (it, dur, idle)


def test_run_on_rig_takes_only_run_options(paper_model, target):
    from hardware import SimulatedRig
    rig = SimulatedRig(paper_model)
    with pytest.raises(InputError, match="RunOptions"):
        run_on_rig(LACC(paper_model, P), rig, target, {"max_iterations": 2})
    assert rig.lengths is None                                     # refused before anything was commanded
    assert run_on_rig(LACC(paper_model, P), rig, target).status == "converged"     # None: RunOptions()


def test_import_controller_does_not_load_the_rig_layer():
    code = ("import sys, controller, controller.summary, controller.run; "
            "print(sorted(m for m in sys.modules if m == 'hardware' or m.startswith('hardware.')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"
    from controller.summary import SETTLED_DEFINITION               # still there, read on first use
    from hardware.runlog import SUMMARY_DEFINITION
    assert SETTLED_DEFINITION == SUMMARY_DEFINITION


# ---------------------------------------------------------------------------------------- how Ctrl-C ends a run
def _run_stopped_at_sample(paper_model, target, log, signal_it, at=3, **kw):
    """A run on a loaded simulated rig whose status callback calls ``signal_it()`` at sample ``at``; returns
    (rig, the number of samples seen by the callback, the result or the exception raised)."""
    from hardware import PlantOptions, SimulatedRig
    rig = SimulatedRig(paper_model, load=(0, 0, -0.3), options=PlantOptions(length_rate=5e-3))
    calls = []

    def status(s):
        calls.append(s)
        if len(calls) == at:
            signal_it()
    try:
        out = run_on_rig(LACC(paper_model, P), rig, target, RunOptions(log=log, status=status, **kw))
    except Exception as exc:                                       # noqa: BLE001 - returned to the test
        out = exc
    return rig, len(calls), out


def _ctrl_c():
    signal.raise_signal(signal.SIGINT)


def _sigterm():
    signal.raise_signal(signal.SIGTERM)


@pytest.mark.parametrize("duration, status, at", [(math.inf, "held", 3), (None, "not converged", 1)])
def test_ctrl_c_is_the_normal_end_with_on_ctrl_c_end(paper_model, target, tmp_path, duration, status, at):
    # (the iteration run converges at its third sample: it is stopped at the first)
    from hardware.runlog import read_run_log
    log = tmp_path / "r.h5"
    before = signal.getsignal(signal.SIGINT)
    rig, n, res = _run_stopped_at_sample(paper_model, target, log, _ctrl_c, at=at, duration=duration,
                                         max_iterations=None if duration else 20, on_ctrl_c="end")
    assert n == at and res.status == status and res.reason == "ended by Ctrl-C"     # returned, not raised
    assert res.samples == at and res.summary is not None and res.summary.periods
    np.testing.assert_array_equal(rig.target, rig.lengths)                           # drives hold where they are
    d = read_run_log(log)
    assert d.ended == f"{status}: ended by Ctrl-C" and d.rows == at
    assert d.summary is not None and d.summary["corrections"] == res.iterations
    assert any(k == "stop" and "ended by Ctrl-C" in m and "holding" in m for _, k, m in d.events)
    assert signal.getsignal(signal.SIGINT) is before                                 # the latch is gone


def _ctrl_c_in_a_compiled_kernel():
    """What CPython makes of a KeyboardInterrupt raised by the signal handler while a numba kernel runs."""
    try:
        signal.raise_signal(signal.SIGINT)
    except KeyboardInterrupt as ki:
        raise SystemError("CPUDispatcher(<function assemble>) returned a result with an exception set") from ki


@pytest.mark.parametrize("on_ctrl_c", ["end", "abort"])
def test_a_ctrl_c_a_kernel_turned_into_another_error_is_still_a_ctrl_c(paper_model, target, tmp_path, on_ctrl_c):
    from hardware import RunAborted
    from hardware.runlog import read_run_log
    rig, n, out = _run_stopped_at_sample(paper_model, target, tmp_path / "r.h5", _ctrl_c_in_a_compiled_kernel,
                                         duration=60.0, on_ctrl_c=on_ctrl_c)
    if on_ctrl_c == "end":
        assert out.status == "held" and out.reason == "ended by Ctrl-C" and out.summary is not None
    else:
        assert isinstance(out, RunAborted) and "Ctrl-C" in str(out)
    np.testing.assert_array_equal(rig.target, rig.lengths)
    assert read_run_log(tmp_path / "r.h5").ended == ("held: ended by Ctrl-C" if on_ctrl_c == "end"
                                                     else "interrupted: Ctrl-C")


def test_an_unexpected_error_is_still_a_fault(paper_model, target, tmp_path):
    from hardware.runlog import read_run_log

    def broken():
        raise SystemError("not an interrupt")
    rig, n, out = _run_stopped_at_sample(paper_model, target, tmp_path / "r.h5", broken, duration=60.0,
                                         on_ctrl_c="end")
    assert isinstance(out, SystemError) and n == 3
    assert read_run_log(tmp_path / "r.h5").ended == "fault: SystemError: not an interrupt"


def test_sigterm_still_aborts_with_on_ctrl_c_end(paper_model, target, tmp_path):
    from hardware import RunAborted
    from hardware.runlog import read_run_log
    assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL
    rig, n, exc = _run_stopped_at_sample(paper_model, target, tmp_path / "r.h5", _sigterm, duration=60.0,
                                         on_ctrl_c="end")
    assert n == 3 and isinstance(exc, RunAborted) and "SIGTERM" in str(exc)
    assert exc.result.status == "interrupted"
    np.testing.assert_array_equal(rig.target, rig.lengths)
    assert read_run_log(tmp_path / "r.h5").ended == "interrupted: SIGTERM"
    assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL


def test_ctrl_c_before_the_run_started_aborts(paper_model, target, tmp_path):
    """A Ctrl-C while the rig is being opened (the run has not started) aborts even with ``on_ctrl_c="end"``."""
    from hardware import RunAborted, SimulatedRig
    from hardware.runlog import read_run_log

    class CtrlCWhileOpening(SimulatedRig):
        interrupt = False

        def open(self):
            if self.interrupt:
                signal.raise_signal(signal.SIGINT)
            super().open()
    rig = CtrlCWhileOpening(paper_model)
    rig.close()                                            # a rig the run opens itself
    rig.interrupt = True
    with pytest.raises(RunAborted, match="Ctrl-C"):
        run_on_rig(LACC(paper_model, P), rig, target, RunOptions(log=tmp_path / "r.h5", duration=5.0,
                                                                   on_ctrl_c="end"))
    assert read_run_log(tmp_path / "r.h5").ended == "interrupted: Ctrl-C"


def test_ctrl_c_during_the_warm_up_aborts_the_command(monkeypatch):
    """bellows control's kernel warm-up is a short run of its own: a Ctrl-C there (a RunAborted, which is a
    BellowsError) must abort the command, not be taken for a failed warm-up after which the real run starts."""
    import controller
    from hardware import RunAborted
    from validation.commands.control import compile_loop_kernels

    def interrupted(*args, **kw):
        raise RunAborted("run interrupted by Ctrl-C after 0 corrections; rig made safe")
    monkeypatch.setattr(controller, "run_on_rig", interrupted)
    with pytest.raises(KeyboardInterrupt):
        compile_loop_kernels()
