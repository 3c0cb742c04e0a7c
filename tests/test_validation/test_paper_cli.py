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
