"""Ctrl-C during a parallel ``bellows paper workspace`` run keeps the finished samples on disk."""

import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from ancf import Model, presets
from validation.paper.workspace_volume import read_samples

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def _default_sigint():
    """In the child: SIGINT back to its default, so Python installs its KeyboardInterrupt handler even when this
    test runs from a shell that started it in the background (which leaves SIGINT ignored in every child)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)



def test_sigint_keeps_finished_samples(tmp_path):
    env = dict(os.environ, PYTHONPATH=ROOT + os.pathsep + os.environ.get("PYTHONPATH", ""))
    cmd = [sys.executable, "-m", "validation.commands.main", "paper", "workspace", "--samples", "20000", "--workers", "2",
           "--chunk-size", "10", "--no-progress", "--preset", "paper_unscaled", "--out", str(tmp_path)]
    proc = subprocess.Popen(cmd, cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True,
                            preexec_fn=_default_sigint)  # noqa: PLW1509 (only resets a signal)
    csv_path = tmp_path / "workspace_samples.csv"
    deadline = time.monotonic() + 120
    try:
        while time.monotonic() < deadline:            # wait until a few chunks are on disk
            if csv_path.exists() and csv_path.read_text().count("\n") > 30:
                break
            assert proc.poll() is None, proc.communicate()
            time.sleep(0.2)
        else:
            pytest.fail("no samples written within 120 s")
        t_int = time.monotonic()
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=60)
        stop_s = time.monotonic() - t_int
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == 130, err
    assert "interrupted" in err and str(csv_path) in err.replace("\n", "")
    assert stop_s < 20                                    # prompt: workers are terminated, not drained
    assert not (tmp_path / "workspace.json").exists()     # no half result posing as a finished one
    data = read_samples(csv_path)
    n_done = sum(len(d["index"]) for d in data.values())
    assert 30 <= n_done < 40000
    # what is on disk is the FK of what is on disk
    model = Model(presets.paper_unscaled())
    for mode, d in data.items():
        for k in range(min(2, len(d["index"]))):
            assert d["status"][k] == "ok"
            T, p = d["inputs"][k, :3], d["inputs"][k, 3]
            assert np.allclose(d["tips"][k], model.fk(T, p).tip, atol=1e-9)
