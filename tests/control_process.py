"""``bellows control`` on the simulated rig as a child process, for tests that signal or kill a running run.

The child runs until signalled (no duration), prints every thread's stack on SIGUSR1 (how a test that times
out shows where it hung) and has SIGINT at its default, so Python installs its KeyboardInterrupt handler even
when the tests run from a shell that started them in the background (which leaves SIGINT ignored in every child).
"""

from __future__ import annotations

import functools
import os
import signal
import subprocess
import sys
import time

import pytest

from ancf.errors import ConfigError
from hardware.runlog import read_run_log


@functools.lru_cache(maxsize=None)
def target_mm() -> str:
    """The paper preset's tip with tensions (2.2, 1.6, 1.6) N at 60 kPa (a reachable target) [mm]."""
    from ancf import Model, presets
    tip = Model(presets.paper()).fk((2.2, 1.6, 1.6), 60e3).tip
    return ",".join(f"{1e3 * x:.3f}" for x in tip)


def _default_sigint():
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def start_control(log, *extra) -> subprocess.Popen:
    """``bellows control --rig sim`` towards :func:`target_mm` at 60 kPa, logging to ``log``, paced to the wall
    clock, until signalled; ``extra``: more options."""
    env = {**os.environ, "PYTHONPATH": os.getcwd()}
    code = ("import faulthandler, signal; faulthandler.register(signal.SIGUSR1); "
            "from validation.commands.main import main; main()")
    return subprocess.Popen([sys.executable, "-c", code, "control", "--rig", "sim", "--target-mm", target_mm(),
                             "--pressure-kpa", "60", "--log", str(log), *extra],
                            cwd=os.getcwd(), env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=_default_sigint)  # noqa: PLW1509 (only resets a signal)


def wait_rows(path, n, proc, timeout=90.0):
    """The run log at ``path`` once it holds ``n`` samples (read while the child writes: SWMR)."""
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        assert proc.poll() is None, proc.stderr.read()
        if path.exists():
            try:
                d = read_run_log(path)
                if d.rows >= n:
                    return d
            except (ConfigError, OSError):
                pass
        time.sleep(0.2)
    raise AssertionError("the run log did not grow")


def signal_after_rows(log, sig, rows, *extra, timeout=30.0):
    """Start the run, send ``sig`` once the log holds ``rows`` samples; (exit status, stdout, stderr).  A child
    that does not exit within ``timeout`` s fails the test with its threads' stacks."""
    proc = start_control(log, *extra)
    try:
        wait_rows(log, rows, proc)
        proc.send_signal(sig)
        try:
            out, err = proc.communicate(timeout=timeout)
        except subprocess.TimeoutExpired:
            proc.send_signal(signal.SIGUSR1)
            time.sleep(1.0)
            proc.kill()
            out, err = proc.communicate()
            pytest.fail(f"no exit within {timeout:g} s of {sig.name}; the child's stderr and stacks:\n" + err)
    finally:
        if proc.poll() is None:
            proc.kill()
    return proc.returncode, out, err
