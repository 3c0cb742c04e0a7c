"""Sec. V-B trajectory tracking, the Fig. 8 feed-forward loading and the loading replay — all through the
rig code path (controller.run_open_loop / run_on_rig on the simulated rig)."""

import numpy as np
import pytest

from ancf import presets
from hardware.runlog import read_run_log
from validation.paper import control as cs

from test_controller_studies import soft_paper


def test_trajectory_geometry():
    c = np.array([0.16, 0.0, 0.0])
    circ = cs.trajectory_points("circle", c, points=401)
    assert np.ptp(circ[:, 1]) == pytest.approx(0.030, rel=1e-3) and np.all(circ[:, 0] == 0.16)
    rose = cs.trajectory_points("rose", c, points=400)
    r = np.linalg.norm(rose[:, 1:], axis=1)
    assert r.max() == pytest.approx(0.025, rel=1e-3) and rose[:, 0].min() < 0.16 - 0.0019    # on a dome
    sjtu = cs.trajectory_points("SJTU", c, points=300)
    assert np.ptp(sjtu[:, 1]) == pytest.approx(0.049, rel=1e-3) and np.ptp(sjtu[:, 2]) == pytest.approx(0.014)
    steps = np.linalg.norm(np.diff(sjtu, axis=0), axis=1)
    assert steps.max() < 1.0001 * np.median(steps)             # evenly resampled along the path (chords)
    with pytest.raises(Exception, match="unknown trajectory"):
        cs.trajectory_points("star", c)


@pytest.mark.parametrize("preset", ["paper", "soft"])
def test_trajectory_tracking(tmp_path, preset):
    params = presets.paper_unscaled() if preset == "paper" else soft_paper()
    exact = cs.trajectory_tracking(params=params, shapes=("circle",), points=12, mismatch=False)
    e = exact["shapes"]["circle"]
    assert e["rmse"] < 1e-6                                    # a perfect plant reproduces the IK
    res = cs.trajectory_tracking(params=params, shapes=("circle", "SJTU"), points=12, out=tmp_path)
    for name in ("circle", "SJTU"):
        s = res["shapes"][name]
        assert 1e-5 < s["rmse"] < 0.01                        # the mismatched rig errs, by millimetres at most
        assert s["rmse_percent_length"] == pytest.approx(100 * s["rmse"] / params.length)
    if preset == "paper":                                      # today's stiff preset cannot reach 30 mm at 0 kPa
        assert 0 < res["shapes"]["circle"]["scale"] < 1
    else:
        assert res["shapes"]["circle"]["scale"] == 1.0
    assert (tmp_path / "trajectories.png").exists()


def test_feedforward_loading_fig8():
    perfect = cs.feedforward_loading(masses=(0.015, 0.065), mismatch=False)
    for cfg in perfect["configurations"].values():
        assert cfg["15g"]["error"] < 1e-7 and cfg["65g"]["error"] < 1e-7
    res = cs.feedforward_loading(masses=(0.015, 0.040, 0.065, 0.115))
    h = res["configurations"]["horizontal"]
    errs = [h[k]["error"] for k in ("15g", "40g", "65g")]
    assert all(0 < a < b for a, b in zip(errs[:-1], errs[1:]))    # mismatch error grows with the load
    assert h["115g"]["error"] is None and "infeasible" in h["115g"]   # beyond 5 N: reported, not dropped


def test_loading_replay_through_the_rig_path(tmp_path):
    res = cs.loading_replay(profile="step", duration=3.0, mass=0.04, log=tmp_path / "replay.h5",
                            sim_compute_time=0.05)
    assert res["status"] == "held" and res["corrections"] >= 1
    d = read_run_log(tmp_path / "replay.h5")
    assert d.rows == res["samples"]
    load = d.samples["true_load"][:, 2]
    assert load[0] == 0 and load[-1] == pytest.approx(-9.81 * 0.04)   # the step happened during the run
    te = np.linalg.norm(d.samples["true_tip"] - np.asarray(res["target_m"]), axis=1)
    assert te.max() > 1e-3 and te[-1] < 2e-4                 # displaced by the step, then corrected
