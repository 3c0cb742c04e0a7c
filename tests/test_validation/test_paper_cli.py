"""``bellows paper ...`` (validation.commands.paper.app) and the controller-study wrappers of validation.paper."""

import json
import sys
import types

import numpy as np
import pytest
from typer.testing import CliRunner

from ancf import Model, presets
from validation import paper
from validation.commands.paper import app

runner = CliRunner()


def test_workspace_command_writes_files(tmp_path):
    res = runner.invoke(app, ["workspace", "--samples", "16", "--workers", "1", "--no-progress", "--out",
                              str(tmp_path)])
    assert res.exit_code == 0, res.output
    assert "TPHD vs TD" in res.output and "+108.6 %" in res.output
    for f in ("workspace.json", "workspace_clouds.npz", "workspace.png", "workspace.svg"):
        assert (tmp_path / f).stat().st_size > 0
    data = json.loads((tmp_path / "workspace.json").read_text())
    z = np.load(tmp_path / "workspace_clouds.npz")
    # the saved cloud is the model's FK of the saved inputs, and the JSON volume is its hull volume
    m = Model(presets.paper())
    T, p = z["tphd_inputs"][5, :3], z["tphd_inputs"][5, 3]
    assert np.allclose(z["tphd_tips"][5], m.fk(T, p).tip, atol=1e-9)
    assert data["volume_tphd_m3"] == pytest.approx(paper.hull_volume(z["tphd_tips"]))


def test_workspace_json_on_stdout(tmp_path):
    res = runner.invoke(app, ["workspace", "--samples", "8", "--workers", "1", "--json", "--out", str(tmp_path)])
    assert res.exit_code == 0, res.output
    data = json.loads(res.stdout)
    assert data["samples"] == 8 and data["failures"] == 0 and data["ratio"] > 1


def test_stiffness_command(tmp_path):
    res = runner.invoke(app, ["stiffness", "--pressures-kpa", "0,50", "--tensions-n", "0,5", "--mass-kg", "0.05",
                              "--out", str(tmp_path), "--json"])
    assert res.exit_code == 0, res.output
    data = json.loads(res.stdout)
    assert data["pressures_Pa"] == [0.0, 50e3] and data["tensions_N"] == [0.0, 5.0]
    assert np.array(data["curves_N_per_m"]["locked_nonlinear"]).shape == (2, 2)
    assert (tmp_path / "stiffness.png").exists() and (tmp_path / "stiffness.json").exists()
    bad = runner.invoke(app, ["stiffness", "--pressures-kpa", "zero", "--out", str(tmp_path)])
    assert bad.exit_code != 0


def _no_control_studies(monkeypatch):
    import importlib.util
    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: None if name == "validation.paper.control" else real(name, *a))
    monkeypatch.delitem(sys.modules, "validation.paper.control", raising=False)


@pytest.mark.parametrize("cmd", ["table1", "ablation", "loading"])
def test_missing_control_studies_give_a_clear_message(cmd, tmp_path, monkeypatch):
    _no_control_studies(monkeypatch)
    res = runner.invoke(app, [cmd, "--out", str(tmp_path)])
    assert res.exit_code == 2
    assert "paper/control.py" in res.output and "Traceback" not in res.output
    with pytest.raises(paper.StudyUnavailableError):
        paper.CONTROL_STUDIES[cmd]()


def test_wrappers_forward_to_control_studies(tmp_path, monkeypatch):
    calls = {}

    def table1(out=None, iterations=5, params=None):
        calls["table1"] = (out, iterations)
        return {"upward": {"lacc_error_m": 2e-5, "vfcc_error_m": 9e-3}}

    def loading(**kw):
        calls["loading"] = kw
        return {"rms_error_m": 1e-4}

    fake = types.ModuleType("validation.paper.control")
    fake.table1, fake.loading = table1, loading
    monkeypatch.setitem(sys.modules, "validation.paper.control", fake)
    import importlib.util
    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: object() if name == "validation.paper.control" else real(name, *a))
    assert paper.table1() == table1()
    assert calls["table1"] == (None, 5)
    paper.table1(iterations=3, out=tmp_path)
    assert calls["table1"] == (tmp_path, 3)
    with pytest.raises(TypeError):
        paper.table1(iteratoins=3)            # typos are not swallowed
    paper.loading(out=tmp_path, anything=1)   # out passed on to **kw
    assert calls["loading"] == {"out": tmp_path, "anything": 1}
    with pytest.raises(paper.StudyUnavailableError, match="compliance_ablation"):
        paper.compliance_ablation()
    res = runner.invoke(app, ["table1", "--out", str(tmp_path)])
    assert res.exit_code == 0, res.output
    assert json.loads((tmp_path / "table1.json").read_text())["upward"]["lacc_error_m"] == 2e-5
    assert "upward.lacc_error_m" in res.output
    # a study that brings its own printable comparison ("table") is printed as is
    fake.table1 = lambda out=None, params=None: {"upward": {"lacc_mm": 0.02},
                                                 "table": "config  LACC [mm]  paper\nupward  0.020  0.020"}
    res = runner.invoke(app, ["table1", "--out", str(tmp_path)])
    assert res.exit_code == 2 and "--force" in res.output          # the first run's result is kept
    res = runner.invoke(app, ["table1", "--out", str(tmp_path), "--force"])
    assert res.exit_code == 0 and "LACC [mm]" in res.output
    # a study that cannot take a preset is not run on the default one silently
    fake.table1 = lambda out=None: {}
    res = runner.invoke(app, ["table1", "--preset", "paper_scaled", "--out", str(tmp_path), "--force"])
    assert res.exit_code == 2 and "does not take a preset" in res.output


def test_all_runs_and_skips_missing(tmp_path, monkeypatch):
    _no_control_studies(monkeypatch)
    res = runner.invoke(app, ["all", "--samples", "8", "--workers", "1", "--no-progress", "--out", str(tmp_path)])
    assert res.exit_code == 0, res.output
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["table1"] == summary["ablation"] == summary["loading"] == "skipped"
    assert not (tmp_path / "table1.json").exists()
    assert summary["workspace"]["samples"] == 8
    assert summary["stiffness"]["mean_ratio_nonlinear"] > 1
    for f in ("workspace.json", "workspace.png", "stiffness.json", "stiffness.svg"):
        assert (tmp_path / f).exists()
    assert "skipped" in res.output


def test_unreachable_scheduler_is_a_clear_error(tmp_path, monkeypatch):
    pytest.importorskip("dask.distributed")
    import dask
    with dask.config.set({"distributed.comm.timeouts.connect": "1s"}):
        res = runner.invoke(app, ["workspace", "--samples", "4", "--scheduler", "tcp://127.0.0.1:9",
                                  "--no-progress", "--out", str(tmp_path)])
    assert res.exit_code == 2
    assert "dask scheduler" in res.output and "Traceback" not in res.output


def test_tracking_command_reports_rmse_per_trajectory(tmp_path):
    """``bellows paper tracking``: the Sec. V-B trajectories, RMSE in mm and % of L, written as JSON."""
    import json
    import subprocess
    import sys
    r = subprocess.run([sys.executable, "-m", "validation.commands.main", "paper", "tracking", "--out", str(tmp_path)],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    data = json.loads((tmp_path / "trajectories.json").read_text())
    text = json.dumps(data)
    for name in ("circle", "rose", "SJTU"):
        assert name in text and name in r.stdout


# ----------------------------------------------------------------------------- convergence and loads write files
def test_convergence_command_writes_json_and_figure_and_explains_failures(tmp_path):
    """n = 1 cannot solve the third default state (two tendons at T_max): the output says which state, why (the
    solver's limit-point message) and what it does to the numbers; the JSON has the units in its keys; the rate
    is the least-squares log-log slope over the n where every state solved."""
    res = runner.invoke(app, ["convergence", "--n-values", "1,3,4,6", "--n-ref", "8", "--out", str(tmp_path)])
    assert res.exit_code == 0, res.output
    out = " ".join(res.output.split())
    assert "n = 1: state 2 (T = (5, 5, 0) N, p = 0 kPa)" in out
    assert "% of the asked load" in out and "limit point" in out and "lower bound" in out
    data = json.loads((tmp_path / "convergence.json").read_text())
    assert {"tip_error_m", "per_state_m", "n_ref", "rate", "rate_n", "complete", "notes"} <= set(data)
    assert data["complete"] == [False, True, True, True] and data["rate_n"] == [3, 4, 6]
    assert data["per_state_m"][0][2] is None and data["tip_error_m"][0] == pytest.approx(
        max(data["per_state_m"][0][:2]))                                  # the max over the states that solved
    n, e = np.array([3.0, 4.0, 6.0]), np.array(data["tip_error_m"][1:])
    slope = np.sum((np.log(n) - np.log(n).mean()) * (np.log(e) - np.log(e).mean())) / np.sum((np.log(n) - np.log(n).mean()) ** 2)
    assert data["rate"] == pytest.approx(-slope, rel=1e-9)
    for f in ("convergence.png", "convergence.svg"):
        assert (tmp_path / f).stat().st_size > 1000
    again = runner.invoke(app, ["convergence", "--n-values", "3", "--out", str(tmp_path)])
    assert again.exit_code == 2 and "--force" in again.output          # the first result is kept
    assert json.loads((tmp_path / "convergence.json").read_text())["n"] == [1, 3, 4, 6]
    forced = runner.invoke(app, ["convergence", "--n-values", "3,4", "--n-ref", "8", "--out", str(tmp_path), "--force"])
    assert forced.exit_code == 0 and json.loads((tmp_path / "convergence.json").read_text())["n"] == [3, 4]


def test_loads_command_writes_json_and_says_why_a_payload_is_not_held(tmp_path):
    res = runner.invoke(app, ["loads", "--out", str(tmp_path)])
    assert res.exit_code == 0, res.output
    data = json.loads((tmp_path / "loads.json").read_text())
    assert {"drift", "hold", "ik_time", "notes"} <= set(data)
    assert data["drift"]["drift_m"] > 0.01 and data["ik_time"]["cold_s"] > 0
    up = data["hold"]["configurations"]["upward"]
    assert up["held"] is False and up["max_tension_needed_N"] is None     # NaN → null
    assert "T2 >= 0" in up["reason"] and "[0, 50] N" in up["relaxed_error"]
    out = " ".join(res.output.split())
    assert "nan N" not in out and "none ≤ 50 N" in out
    assert "upward: not held even with tensions up to 50 N" in out and "unconstrained solution needs" in out
    again = runner.invoke(app, ["loads", "--out", str(tmp_path)])
    assert again.exit_code == 2 and "--force" in again.output


def test_table1_mismatch_runs_on_the_imperfect_simulated_rig(tmp_path, monkeypatch):
    """``table1 --mismatch`` hands the study PlantOptions.mismatched around the preset; without it, none."""
    from controller import PlantOptions
    seen = {}

    def fake(**kw):
        seen.update(kw)
        return {"table": "t"}
    monkeypatch.setitem(paper.CONTROL_STUDIES, "table1", fake)
    assert runner.invoke(app, ["table1", "--out", str(tmp_path / "a")]).exit_code == 0
    assert "plant_options" not in seen
    res = runner.invoke(app, ["table1", "--mismatch", "--preset", "paper_unscaled", "--out", str(tmp_path / "b")])
    assert res.exit_code == 0, res.output
    opts = seen["plant_options"]
    assert opts == PlantOptions.mismatched(base=presets.paper_unscaled())
    assert opts.noise_std > 0 and opts.params.line_mass > presets.paper_unscaled().line_mass
