"""Recovery from a drive fault needs a person: ``bellows control`` on the documented rig file, its drives in cyclic
synchronous position in another process (fakes.bench.ProcessModelBench); a drive faults mid-run.  The command
asks; "y" resets the drives where they stand and the run goes on (no set-point jump on re-enable), "n" (or no
answer) ends it with the fault and the drives stopped.

The fault is injected once drive 2 has followed set-points for a while (not at a fixed wall-clock time: on a busy
machine the command may still be starting then, and a fault before the run is an error, not a question); a failing
assertion prints what the drives saw (their event lists: faults with codes, heartbeat loss, jumps)."""

import json
import threading
import time

import pytest

pytest.importorskip("canopen")
pytest.importorskip("serial")

from fakes.fixtures import quiet_canopen  # noqa: E402,F401  (fixture)
from fakes.doc_commands import DocumentedCspRun  # noqa: E402


@pytest.mark.parametrize("answer", ["y\n", "n\n", ""], ids=["yes", "no", "no answer"])
def test_bellows_control_asks_before_recovering_a_drive_fault(tmp_path, monkeypatch, capsys, quiet_canopen, answer):
    import io
    from hardware.runlog import read_run_log
    from validation.commands.main import main

    run = DocumentedCspRun(duration_s=4)
    with run.bench(tmp_path, monkeypatch) as bench:
        injected, stop = threading.Event(), threading.Event()
        fault = threading.Thread(target=_fault_once_running, args=(bench.proc, 2, injected, stop), daemon=True)
        fault.start()
        monkeypatch.setattr("sys.stdin", io.StringIO(answer))      # the person at the terminal
        try:
            with pytest.raises(SystemExit) as info:
                main(run.args)
        finally:
            stop.set()
            fault.join(5)
        records = bench.proc.records(2)
        states = {n: bench.proc.state(n) for n in bench.nodes}
        events = {n: bench.proc.events(n) for n in bench.nodes}
    out, err = capsys.readouterr()
    assert injected.is_set(), f"drive 2 never ran for {RUNNING_S} s: {out + err}"
    log = read_run_log(tmp_path / run.opt("--log"))
    kinds = [k for _, k, _ in log.events]
    assert "Reset the faulted drives" in err, (err, events)            # it asked
    enabled = [abs(r["step"]) for r in records if r["state"] == "OPERATION ENABLED"]
    assert max(enabled) <= run.step                                   # no jump, before or after the recovery
    if answer == "y\n":
        assert info.value.code == 0, out + err
        res = json.loads(out.strip().splitlines()[-1])
        assert res["status"] == "held" and res["recoveries"] == 1
        assert "recovered" in kinds and log.ended == "held"
        assert all(st != "FAULT" for st in states.values()), (states, events)
    else:
        errors = [line for line in err.splitlines() if line.startswith("error:")]
        assert info.value.code == 2 and len(errors) == 1 and "0x8611" in errors[0], out + err
        assert "recovered" not in kinds and log.ended.startswith("fault")
        assert states[2] == "FAULT" and all(states[n] != "OPERATION ENABLED" for n in (1, 3))


#: how long drive 2 follows set-points before the fault [s]
RUNNING_S = 1.0


def _fault_once_running(proc, node: int, injected: threading.Event, stop: threading.Event) -> None:
    """Inject a following error (0x8611) into ``node`` once it has been OPERATION ENABLED for RUNNING_S."""
    since = None
    while not stop.is_set():
        if proc.state(node) == "OPERATION ENABLED":
            since = since or time.monotonic()
            if time.monotonic() - since >= RUNNING_S:
                proc.inject_fault(node, 0x8611)
                injected.set()
                return
        else:
            since = None
        time.sleep(0.05)
