"""The workspace examples run (on few samples) and keep their physics: they double as regression tests."""

import importlib.util
import pathlib

import numpy as np

EXAMPLES = pathlib.Path(__file__).resolve().parents[2] / "examples"


def load(name):
    spec = importlib.util.spec_from_file_location(name, EXAMPLES / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)        # import-safe: nothing runs on import
    return mod


def test_workspace_example(tmp_path, capsys):
    res = load("workspace_td_vs_tphd").main(samples=24, out=tmp_path, workers=1, progress=False)
    for mode in ("TD", "TPHD"):                # nothing dropped: every sample solved, collapsed or failed
        md = res["modes"][mode]
        assert md["solved"] + md["collapsed"] + md["failures"] == 24 and md["solved"] >= 20
    # pressure lengthens the actuator: the TPHD cloud reaches further along the axis, and its hull is larger
    assert res["modes"]["TPHD"]["bbox_max_m"][0] > res["modes"]["TD"]["bbox_max_m"][0] + 5e-3
    assert res["volume_tphd_m3"] > res["volume_td_m3"] > 0
    assert (tmp_path / "workspace.png").exists() and (tmp_path / "workspace_clouds.npz").exists()
    assert "TPHD vs TD" in capsys.readouterr().out


def test_locked_stiffness_example(tmp_path):
    res = load("workspace_locked_stiffness").main(pressures=(0.0,), tensions=(0.0, 5.0), out=tmp_path)
    k = res["curves_N_per_m"]
    assert np.all(k["locked_nonlinear"] > 1.5 * k["constant_nonlinear"])
    assert (tmp_path / "stiffness.svg").exists()
