"""Run logs: SWMR layout, readable while written and after SIGKILL; 'bellows control' and 'bellows log'."""

import json
import pathlib
import signal
import sys

import numpy as np
import pytest
from typer.testing import CliRunner

from ancf.errors import ConfigError, InputError, OutputExistsError
from hardware.runlog import RunLog, export_csv, read_run_log
from hardware.static_states import read_static_states
from validation.commands.main import app, main

sys.path.insert(0, str(pathlib.Path(__file__).parents[1]))
from control_process import signal_after_rows, start_control, target_mm, wait_rows  # noqa: E402

TARGET_MM = target_mm()
STOCHASTIC = ("--load-profile", "stochastic", "--seed", "1")

runner = CliRunner()


def test_log_layout_units_and_refusals(tmp_path):
    path = tmp_path / "a.h5"
    with RunLog(path, n_tendons=3, rig={"name": "x"}) as log:
        log.sample(t=0.0, tip=[0.1, 0, 0], tension=[1, 2, 3])
        log.event(0.0, "note", "hello")
        log.static_state(time=0.0, tensions=[1, 2, 3], pressure=6e4, tip=[0.17, 0, 0])
        with pytest.raises(InputError):
            log.sample(bogus=1.0)
        with pytest.raises(InputError):
            log.static_state(time=0.0, tensions=[-1, 2, 3], pressure=6e4, tip=[0.17, 0, 0])
        with pytest.raises(InputError):
            log.sample(tip=[1.0, 2.0])                                  # wrong shape: typed error, nothing written
        with pytest.raises(InputError):
            log.static_state(time=0.0, tensions=[1, 2], pressure="x", tip=[0.17, 0, 0])
    d = read_run_log(path)
    assert d.rows == 1 and d.units["tip"] == "m" and d.units["tension"] == "N" and d.units["pressure"] == "Pa"
    np.testing.assert_array_equal(d.samples["tension"][0], [1, 2, 3])
    assert np.all(np.isnan(d.samples["estimate"][0]))                  # not given: NaN, not 0
    assert d.ended == "completed" and ("note" in [k for _, k, _ in d.events])
    st = read_static_states(path)
    assert st.n_states == 1 and st.pressure[0] == 6e4
    with pytest.raises(OutputExistsError):
        RunLog(path, n_tendons=3)
    with pytest.raises(InputError):
        RunLog(tmp_path / "a.txt", n_tendons=3)
    (tmp_path / "x.h5").write_text("not hdf5")
    with pytest.raises(ConfigError):
        read_run_log(tmp_path / "x.h5")
    out = export_csv(path, tmp_path / "a.csv")
    header = out.read_text().splitlines()[0].split(",")
    assert header[0] == "t_s" and "tension3_N" in header and "tip_x_m" in header
    with pytest.raises(OutputExistsError):
        export_csv(path, tmp_path / "a.csv")


def test_log_survives_sigkill_mid_run(tmp_path):
    log = tmp_path / "killed.h5"
    proc = start_control(log, *STOCHASTIC)
    try:
        live = wait_rows(log, 4, proc, timeout=60.0)
        assert live.ended is None
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
    d = read_run_log(log)
    assert d.rows >= live.rows and d.ended is None                 # no end event: the writer was killed
    assert np.all(np.diff(d.samples["t"]) > 0)
    assert np.all(np.isfinite(d.samples["tip"]))
    assert d.attrs["rig"]["simulated"] and d.attrs["controller"]["name"] == "LACC"
    st = read_static_states(log)                                   # converged states recorded so far
    assert st.n_states >= 1 and np.all(st.pressure == 60e3)
    assert "killed" in runner.invoke(app, ["log", "show", str(log)]).output


def test_ctrl_c_ends_the_run_and_says_where_the_log_is(tmp_path):
    """Ctrl-C is the normal end of a run without --duration-s (tests/test_hardware/test_control_ctrl_c.py): the
    summary and the log's place on stdout, the exit status the verdict the log's summary records."""
    log = tmp_path / "int.h5"
    code, out, err = signal_after_rows(log, signal.SIGINT, 3, *STOCHASTIC, timeout=20.0)
    d = read_run_log(log)
    assert code == (0 if d.summary["met_tolerance"] else 1), err
    assert "error:" not in err
    last = out.strip().splitlines()[-1]
    assert last.startswith("held") and "ended by Ctrl-C" in last and str(log) in last
    assert d.ended == "held: ended by Ctrl-C"
    assert any(k == "stop" and "Ctrl-C" in m for _, k, m in d.events)


def test_control_cli_runs_and_logs(tmp_path):
    log = tmp_path / "r.h5"
    res = runner.invoke(app, ["control", "--target-mm", TARGET_MM, "--pressure-kpa", "60", "--load-profile", "step",
                              "--load-mass-g", "40", "--duration-s", "2", "--fast", "--log", str(log), "--json"])
    assert res.exit_code == 0, res.output
    out = json.loads(res.stdout.strip().splitlines()[-1])
    assert out["status"] == "held" and out["final_error_m"] < 2e-4 and out["iterations"] >= 1
    d = read_run_log(log)
    assert d.rows == out["samples"] and d.attrs["run"]["load_profile"] == "step"
    assert max(d.samples["error_norm"]) > 1e-3                     # the 40 g step displaced the tip
    shown = runner.invoke(app, ["log", "show", str(log)])
    assert shown.exit_code == 0 and "static states: 2" in shown.output
    exp = runner.invoke(app, ["log", "export", str(log), "--csv", str(tmp_path / "r.csv")])
    assert exp.exit_code == 0 and (tmp_path / "r.csv").read_text().count("\n") == d.rows + 1


@pytest.mark.parametrize("args, message", [
    (["--target-mm", "169.9,0"], "expected 3 values"),
    (["--pressure-kpa", "-5"], "--pressure-kpa"),
    (["--controller", "pid"], "--controller"),
    (["--controller", "vfcc", "--compliance", "ik"], "LACC only"),
    (["--controller", "vfcc", "--compliance", "exact"], "LACC only"),
    (["--compliance", "magic"], "compliance must be one of"),
    (["--duration-s", "0"], "--duration-s"),
    (["--duration-s", "1", "--max-iterations", "3"], "not both"),
    (["--load-profile", "sine"], "unknown load profile"),
    (["--load-profile", "stochastic", "--load-mass-g", "30"], "does not apply"),
    (["--pressure-kpa", "200"], "outside [0, 160"),
    (["--rig", "nonexistent.toml"], "cannot read rig file"),
    (["--target-mm", "100,0,80"], "not reachable"),
    (["--target-mm", "169.9,0,-2.235"], "not reachable"),                 # an earlier README target
])
def test_control_errors_are_one_line_status_2(monkeypatch, capsys, tmp_path, args, message):
    """Each refused run is one error line, exit 2, and leaves no run log behind (checked before it exists)."""
    log = tmp_path / "run.h5"
    base = {"--target-mm": TARGET_MM, "--pressure-kpa": "60"}
    argv = ["bellows", "control", "--fast", "--log", str(log)] + \
        (["--max-iterations", "2"] if "--duration-s" not in args else [])
    for k, v in base.items():
        if k not in args:
            argv += [k, v]
    monkeypatch.setattr("sys.argv", argv + args)
    with pytest.raises(SystemExit) as info:
        main()
    err = capsys.readouterr().err.strip().splitlines()
    assert info.value.code == 2
    assert err[-1].startswith("error:") and message in err[-1]
    assert not log.exists()


def test_control_refuses_existing_log_before_any_work(monkeypatch, capsys, tmp_path):
    log = tmp_path / "x.h5"
    log.write_bytes(b"keep me")
    monkeypatch.setattr("sys.argv", ["bellows", "control", "--target-mm", TARGET_MM, "--pressure-kpa", "60",
                                     "--max-iterations", "2", "--log", str(log)])
    with pytest.raises(SystemExit) as info:
        main()
    assert info.value.code == 2 and "--force" in capsys.readouterr().err
    assert log.read_bytes() == b"keep me"


def test_control_rejects_sim_options_on_a_hardware_rig(monkeypatch, capsys, tmp_path):
    rig = tmp_path / "rig.toml"
    rig.write_text('backend = "hardware"\n'
                   + "".join(f'[[drives]]\nbackend="epos4"\nnode_id={i}\nchannel="can0"\ncounts_per_mm=100\n'
                             f'counts_per_turn=4096\n'
                             f'zero_length_mm=160\n[[force_sensors]]\nbackend="serial"\nport="/dev/null"\n'
                             f'channel={i}\n' for i in (1, 2, 3))
                   + '[pressure]\nbackend="serial"\nport="/dev/zero"\n[tracker]\nbackend="natnet"\n')
    bad = tmp_path / "bad.toml"
    bad.write_text(rig.read_text().replace("counts_per_mm", "counts"))
    for f, extra, msg in ((rig, ["--seed", "0"], "only for a simulated rig"), (bad, [], "needs an explicit unit")):
        monkeypatch.setattr("sys.argv", ["bellows", "control", "--rig", str(f), "--target-mm", TARGET_MM,
                                         "--pressure-kpa", "60", "--max-iterations", "1", *extra])
        with pytest.raises(SystemExit):
            main()
        assert msg in capsys.readouterr().err


def test_loop_timing_is_logged_and_summarised(tmp_path):
    """Each sample carries the controller's compute time and the previous cycle's period and rig-call time;
    'bellows log show' prints their medians, 99th percentiles, jitter and overruns."""
    from ancf import Model, presets
    from controller import LACC, RunOptions, run_on_rig
    from hardware import SimulatedRig
    from hardware.runlog import loop_timing
    m = Model(presets.paper())
    target = m.fk((2.2, 1.6, 1.6), 60e3).tip
    res = run_on_rig(LACC(m, 60e3), SimulatedRig(m, load=(0, 0, -0.3)), target,
                     RunOptions(log=tmp_path / "t.h5", duration=1.0, idle_period=0.05))
    d = read_run_log(res.log_path)
    c, io, comp = d.samples["cycle_time"], d.samples["io_time"], d.samples["compute_time"]
    assert np.isnan(c[0]) and np.isnan(io[0]) and np.all(np.isfinite(c[1:])) and np.all(io[1:] > 0)
    assert np.all(c[1:] >= io[1:])                       # a cycle contains its rig calls
    lt = loop_timing(d.samples)
    assert lt["cycle_time"]["n"] == d.rows - 1 and lt["cycle_time"]["p99"] >= lt["cycle_time"]["median"] > 0
    assert 0 <= lt["overruns"] < d.rows
    out = runner.invoke(app, ["log", "show", str(res.log_path)]).output
    assert "loop timing [ms]: controller median" in out and "overruns" in out
