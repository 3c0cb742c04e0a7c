"""Ctrl-C is how an open-ended ``bellows control`` ends: a real SIGINT to a running ``bellows control --rig sim``
ends the run normally — the rig made safe, the summary printed, the log closed complete, the exit status the
verdict of the load periods (0 met, 1 missed).  SIGTERM keeps aborting: one ``error:`` line, exit status 2, the rig
made safe and the log closed as interrupted."""

import os
import signal
import subprocess
import sys
import time

import pytest

from ancf.errors import ConfigError
from hardware.runlog import read_run_log


def _target_mm() -> str:
    """The paper preset's tip with tensions (2.2, 1.6, 1.6) N at 60 kPa (a reachable target) [mm]."""
    from ancf import Model, presets
    tip = Model(presets.paper()).fk((2.2, 1.6, 1.6), 60e3).tip
    return ",".join(f"{1e3 * x:.3f}" for x in tip)


TARGET_MM = _target_mm()


def _default_sigint():
    """In the child: SIGINT back to its default, so Python installs its KeyboardInterrupt handler even when this
    test runs from a shell that started it in the background (which leaves SIGINT ignored in every child)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _start(log, *extra):
    """``bellows control`` on the simulated rig, paced to the wall clock, without a duration (until Ctrl-C)."""
    env = {**os.environ, "PYTHONPATH": os.getcwd()}
    # SIGUSR1 makes the child print every thread's stack (how a test that times out shows where it hung)
    code = ("import faulthandler, signal; faulthandler.register(signal.SIGUSR1); "
            "from validation.commands.main import main; main()")
    return subprocess.Popen([sys.executable, "-c", code, "control", "--rig", "sim", "--target-mm", TARGET_MM,
                             "--pressure-kpa", "60", "--log", str(log), *extra],
                            cwd=os.getcwd(), env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=_default_sigint)  # noqa: PLW1509 (only resets a signal)


def _wait_rows(path, n, proc, timeout=90.0):
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        assert proc.poll() is None, proc.stderr.read()
        if path.exists():
            try:
                if read_run_log(path).rows >= n:                   # a reader while the writer runs (SWMR)
                    return
            except (ConfigError, OSError):
                pass
        time.sleep(0.2)
    raise AssertionError("the run log did not grow")


def _signal_after_rows(log, sig, rows, *extra):
    """Start the run, send ``sig`` once the log holds ``rows`` samples; returns (exit status, stdout, stderr)."""
    proc = _start(log, *extra)
    try:
        _wait_rows(log, rows, proc)
        proc.send_signal(sig)
        try:
            out, err = proc.communicate(timeout=30)
        except subprocess.TimeoutExpired:
            proc.send_signal(signal.SIGUSR1)
            time.sleep(1.0)
            proc.kill()
            out, err = proc.communicate()
            pytest.fail(f"no exit within 30 s of {sig.name}; the child's stderr and stacks:\n" + err)
    finally:
        if proc.poll() is None:
            proc.kill()
    return proc.returncode, out, err


def _log_show(log) -> str:
    """``bellows log show`` of the log (in this process)."""
    from typer.testing import CliRunner

    from validation.commands.main import app
    shown = CliRunner().invoke(app, ["log", "show", str(log)])
    assert shown.exit_code == 0, shown.output
    return shown.output


@pytest.mark.parametrize("extra, met", [
    ((), True),                                            # constant load, noiseless: settles to ~0 mm
    (("--mismatch", "--tolerance-mm", "0.001"), False),    # 0.05 mm tracker noise never settles below 1 µm
])
def test_ctrl_c_ends_the_run_with_its_summary_and_verdict(tmp_path, extra, met):
    log = tmp_path / "run.h5"
    code, out, err = _signal_after_rows(log, signal.SIGINT, 15, *extra)
    assert code == (0 if met else 1), err                 # the verdict of the load periods, not an error
    assert "error:" not in err and "Traceback" not in err
    assert "run summary" in out and "load periods" in out                       # the summary, as for a duration
    last = out.strip().splitlines()[-1]
    assert last.startswith("held: all 1 judged" if met else "held, but 1 of 1 judged")
    assert "ended by Ctrl-C" in last and str(log) in last
    d = read_run_log(log)                                   # closed complete: end event, summary, samples
    assert d.ended == "held: ended by Ctrl-C" and d.rows >= 15
    assert d.summary is not None and d.summary["met_tolerance"] is met and d.summary["periods_judged"] == 1
    # the rig was made safe as before: every drive holds where it is, the pressure held
    assert any(k == "stop" and m.startswith("run ended by Ctrl-C; drives holding") for _, k, m in d.events)
    shown = _log_show(log)
    assert "end: held: ended by Ctrl-C" in shown and "load periods: 1, 1 judged" in shown


def test_sigterm_still_aborts_the_run_safely(tmp_path):
    log = tmp_path / "run.h5"
    code, out, err = _signal_after_rows(log, signal.SIGTERM, 5)
    assert code == 2
    last = [ln for ln in err.splitlines() if ln.strip()][-1]
    assert last.startswith("error: run interrupted by SIGTERM") and "rig made safe" in last and str(log) in last
    assert "run summary" not in out
    d = read_run_log(log)
    assert d.ended == "interrupted: SIGTERM"
    assert any(k == "stop" and m.startswith("interrupted (SIGTERM); drives holding") for _, k, m in d.events)
    assert "end: interrupted: SIGTERM" in _log_show(log)
