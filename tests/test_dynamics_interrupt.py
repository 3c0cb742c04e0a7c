"""Ctrl-C during a transient run (ancf.dynamics.interrupt): the run ends between two steps and keeps the rows
done, every time — a SIGINT that lands while a compiled kernel runs must not surface as a SystemError.

The defect is a race (where in the step the signal lands), so each test interrupts several runs at
different delays."""

import csv
import json
import os
import re
import select
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

from ancf import Model, presets

P30 = 30e3


@pytest.fixture(scope="module")
def model():
    return Model(presets.paper())


def test_sigint_in_process_keeps_the_rows_done(model, python_sigint):
    start = model.fk((0, 0, 0), P30)
    model.simulate(2e-3, 1e-3, q0=start.q, tensions=(2, 0, 0), pressure=P30, damping=0.05)   # imports done
    before = signal.getsignal(signal.SIGINT)
    for delay in (0.05, 0.13, 0.31, 0.52, 0.77):
        timer = threading.Timer(delay, signal.raise_signal, (signal.SIGINT,))
        timer.start()
        try:
            sim = model.simulate(60.0, 1e-3, q0=start.q, tensions=(2, 0, 0), pressure=P30, damping=0.05)  # longer than
            # the latest interrupt even at 20× real time
        except BaseException as exc:                       # noqa: BLE001 - a KeyboardInterrupt would end pytest
            timer.cancel()
            pytest.fail(f"interrupt at {delay} s surfaced as {type(exc).__name__}: {exc}")
        timer.join()
        assert sim.interrupted and 1 <= len(sim.t) < 60001, delay
        n = len(sim.t)
        assert sim.q.shape == (n, model.ndof) and np.all(np.isfinite(sim.tip))
        np.testing.assert_allclose(sim.t, np.arange(n) * 1e-3, atol=1e-12)
        assert signal.getsignal(signal.SIGINT) is before             # the run's handler is gone


def test_an_applications_handler_is_restored_and_told(model):
    """A handler of the caller's own (a control loop's latch) sees the Ctrl-C once, after the run, in Python."""
    calls = []

    def handler(signum, frame):
        calls.append(signum)
    previous = signal.signal(signal.SIGINT, handler)
    try:
        timer = threading.Timer(0.1, signal.raise_signal, (signal.SIGINT,))
        timer.start()
        sim = model.simulate(10.0, 1e-3, tensions=(2, 0, 0), pressure=P30, damping=0.05)
        timer.join()
        assert sim.interrupted and calls == [signal.SIGINT]
        assert signal.getsignal(signal.SIGINT) is handler
    finally:
        signal.signal(signal.SIGINT, previous)


def _run_and_interrupt(out, delay: float):
    """Start `bellows simulate` with a long t_end, wait until its progress bar shows simulated time (the time
    loop runs), then send SIGINT after ``delay`` [s]."""
    env = dict(os.environ, TTY_COMPATIBLE="1", COLUMNS="100")          # rich draws its bar into the pipe
    cmd = ["bellows", "simulate", "--tensions-n", "2,0,0", "--pressure-kpa", "30", "--t-end-s", "100",
           "--dt-ms", "1", "--damping-ratio", "0.05", "--out", str(out)]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    seen, t0 = b"", time.monotonic()
    while not any(float(t) > 0 for t in re.findall(rb"(\d+\.\d{3}) / 100\.000 s", seen)):
        assert time.monotonic() - t0 < 120 and proc.poll() is None, (seen, proc.stderr.read())
        if select.select([proc.stdout], [], [], 0.5)[0]:
            seen += os.read(proc.stdout.fileno(), 65536)
    time.sleep(delay)
    proc.send_signal(signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=120)
    return proc.returncode, (seen + stdout).decode(errors="replace"), stderr.decode(errors="replace")


@pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")
def test_ctrl_c_on_the_command_line_writes_the_rows_done(tmp_path):
    for k, delay in enumerate((0.0, 0.23, 0.61)):
        out = tmp_path / f"run{k}"
        code, stdout, stderr = _run_and_interrupt(out, delay)
        assert code == 130, (code, stderr)
        assert "SystemError" not in stderr + stdout and "Traceback" not in stderr + stdout, stderr
        assert "interrupted at t =" in stderr and "error: interrupted" in stderr
        with open(out / "simulation.csv") as f:
            rows = list(csv.reader(f))
        assert rows[0][0] == "t_s" and 2 <= len(rows) - 1 < 100_001
        t = np.array([float(r[0]) for r in rows[1:]])
        np.testing.assert_allclose(t, np.arange(len(t)) * 1e-3, atol=1e-9)
        summary = json.loads((out / "simulation.json").read_text())
        assert summary["interrupted"] is True and summary["steps"] == len(t) - 1
