"""The controller examples run, and their results obey checks made independently here."""

import importlib.util
import pathlib


EXAMPLES = pathlib.Path(__file__).parents[2] / "examples"


def load(name):
    spec = importlib.util.spec_from_file_location(name, EXAMPLES / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)           # import-safe: nothing runs here
    return mod


def test_lacc_quickstart():
    out = load("lacc_quickstart").main(["--preset", "paper_unscaled"], verbose=False)
    lacc, vf = out["lacc"], out["vfcc"]
    assert lacc["errors_mm"][0] > 1.0                          # 40 g visibly displaces the tip
    assert lacc["converged"] and lacc["errors_mm"][-1] < 0.2
    assert not vf["converged"] and vf["errors_mm"][-1] > 0.8 * vf["errors_mm"][0]
    # the vertical estimate has the sign and order of the hidden load
    assert 0.5 < lacc["estimate_N"][2] / out["load_N"][2] < 1.5


def test_lacc_loading():
    out = load("lacc_loading").main(["--seconds", "3"], verbose=False)
    assert out["corrections"] >= 3
    assert out["final_error_mm"] < 0.25                       # held after the ramp (0.2 mm deadband)


def test_rig_quickstart():
    out = load("rig_quickstart").main(["--seconds", "6"], verbose=False)
    assert out["status"] == "held" and out["corrections"] >= 2
    assert out["max_true_error_mm"] > 1.0                     # the loads really move the tip
    assert out["settled_max_true_error_mm"] < 0.2             # and LACC holds it once settled
    assert out["static_states"] >= 2 and out["samples"] > 20
