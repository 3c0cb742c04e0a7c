"""Ctrl-C is how an open-ended ``bellows control`` ends: a real SIGINT to a running ``bellows control --rig sim``
ends the run normally — the rig made safe, the summary printed, the log closed complete, the exit status the
verdict of the load periods (0 met, 1 missed).  SIGTERM keeps aborting: one ``error:`` line, exit status 2, the rig
made safe and the log closed as interrupted."""

import pathlib
import signal
import sys

import pytest

from hardware.runlog import read_run_log

sys.path.insert(0, str(pathlib.Path(__file__).parents[1]))
from control_process import signal_after_rows  # noqa: E402


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
    code, out, err = signal_after_rows(log, signal.SIGINT, 15, *extra)
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
    code, out, err = signal_after_rows(log, signal.SIGTERM, 5)
    assert code == 2
    last = [ln for ln in err.splitlines() if ln.strip()][-1]
    assert last.startswith("error: run interrupted by SIGTERM") and "rig made safe" in last and str(log) in last
    assert "run summary" not in out
    d = read_run_log(log)
    assert d.ended == "interrupted: SIGTERM"
    assert any(k == "stop" and m.startswith("interrupted (SIGTERM); drives holding") for _, k, m in d.events)
    assert "end: interrupted: SIGTERM" in _log_show(log)
