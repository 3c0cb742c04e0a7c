"""The ANCF examples run and their results obey physics checked independently here."""

import importlib.util
import pathlib

import numpy as np

EXAMPLES = pathlib.Path(__file__).parents[1] / "examples"


def load(name):
    spec = importlib.util.spec_from_file_location(name, EXAMPLES / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_quickstart():
    out = load("ancf_quickstart").main(verbose=False)
    assert out["droop_tip_mm"][2] < 0                      # gravity pulls the tip down
    assert out["bend_tip_mm"][2] > 0                       # the top tendon lifts it
    assert out["ik_error_m"] < 1e-9
    assert np.all(out["ik_tensions_N"] >= 0) and np.all(out["ik_tensions_N"] <= 5)
    assert np.all(out["locked_tensions_N"] >= 0)
    k = out["stiffness_z_N_per_m"]
    assert k["locked"] > k["constant_tension"]
    # the 50 g drift is about load / locked stiffness (linearisation of a small load)
    assert abs(out["locked_drift_mm"] * 1e-3 * k["locked"] / (0.05 * 9.81) - 1) < 0.3
