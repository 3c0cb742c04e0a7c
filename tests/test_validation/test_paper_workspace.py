"""Workspace study (paper Sec. IV-A): sampling, FK mapping, determinism across back ends, failures, files."""

import json

import numpy as np
import pytest

from ancf import Model, presets
from validation import paper

#: The mechanics of the study (FK mapping, back ends, warm starts, failures) are tested on the unscaled
#: reading, whose box has no collapsed states; collapse is tested in test_paper_readings.py.
PRESET = "paper_unscaled"


@pytest.fixture(scope="module")
def serial():
    return paper.workspace(samples=40, seed=3, params=PRESET, workers=1, progress=False, chunk_size=7)


def test_inputs_follow_the_paper_protocol():
    X = paper.workspace_inputs(2000, seed=5, params=PRESET)
    td, tphd = X["TD"], X["TPHD"]
    assert td.shape == tphd.shape == (2000, 4)
    assert np.all(td[:, 3] == 0.0)                                    # TD: p = 0
    assert td[:, :3].min() >= 0 and td[:, :3].max() <= 5.0           # T in [0, 5] N
    assert tphd[:, 3].min() >= 0 and tphd[:, 3].max() <= 120e3       # p in [0, 120] kPa
    assert tphd[:, 3].max() > 110e3 and td[:, :3].max() > 4.9         # the whole box is covered
    assert np.array_equal(td[:, :3], tphd[:, :3])                     # common tensions (default)
    other = paper.workspace_inputs(2000, seed=5, common_tensions=False)
    assert not np.array_equal(other["TD"][:, :3], other["TPHD"][:, :3])
    assert not np.array_equal(paper.workspace_inputs(10, seed=6)["TD"], paper.workspace_inputs(10, seed=5)["TD"])


def test_tips_are_the_fk_of_the_inputs(serial):
    paper_model = Model(presets.get(PRESET))
    for mode in paper.MODES:
        c = serial["clouds"][mode]
        for i in (0, 13, 39):
            T, p = c["inputs"][i, :3], c["inputs"][i, 3]
            assert np.allclose(c["tips"][i], paper_model.fk(T, p).tip, atol=1e-9)


def test_result_numbers_are_consistent(serial):
    assert serial["failures"] == 0
    for mode in paper.MODES:
        md = serial["modes"][mode]
        assert md["solved"] == 40 and md["failures"] == 0
        assert md["volume_m3"] == pytest.approx(paper.hull_volume(serial["clouds"][mode]["tips"]))
        assert md["volume_cm3"] == pytest.approx(md["volume_m3"] * 1e6)
    assert serial["volume_td_m3"] == serial["modes"]["TD"]["volume_m3"]
    assert serial["ratio"] == pytest.approx(serial["volume_tphd_m3"] / serial["volume_td_m3"])
    assert serial["increase_percent"] == pytest.approx(100 * (serial["ratio"] - 1))


def test_td_is_inside_or_near_tphd(serial):
    """TD inputs are the p = 0 section of the TPHD inputs (same tensions): pressure only extends the
    actuator (more axial force, and EI(λ) grows with the stretch), so each TPHD tip lies further along the
    axis than its TD partner and bends about as far; each TD tip is then no further from the TPHD hull
    than from its own partner (a hull point)."""
    td, tphd = serial["clouds"]["TD"]["tips"], serial["clouds"]["TPHD"]["tips"]
    assert np.all(tphd[:, 0] - td[:, 0] >= -1e-9)
    lateral_gap = np.linalg.norm(tphd[:, 1:] - td[:, 1:], axis=1)
    lateral_range = np.ptp(td[:, 1:], axis=0).min()
    assert lateral_gap.max() < 0.1 * lateral_range
    dist = paper.hull_distance(td, tphd)
    assert np.all(dist <= np.linalg.norm(tphd - td, axis=1) + 1e-12)
    assert serial["volume_tphd_m3"] > serial["volume_td_m3"] > 0


@pytest.mark.parametrize("start_method", ["fork", "spawn"])
def test_parallel_processes_identical_to_serial(serial, start_method):
    par = paper.workspace(samples=40, seed=3, params=PRESET, workers=2, progress=False, chunk_size=7,
                          start_method=start_method)
    assert par["timing"]["backend"] == f"processes ({start_method})" and par["timing"]["workers"] == 2
    for mode in paper.MODES:
        assert np.allclose(par["clouds"][mode]["tips"], serial["clouds"][mode]["tips"], rtol=0, atol=1e-12)
    assert par["volume_tphd_m3"] == pytest.approx(serial["volume_tphd_m3"], rel=1e-9)


def test_dask_local_cluster_identical_to_serial(serial):
    pytest.importorskip("dask.distributed")
    from dask.distributed import Client, LocalCluster

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster, \
            Client(cluster) as client:
        res = paper.workspace(samples=40, seed=3, params=PRESET, scheduler=client, progress=False, chunk_size=7)
        pids = {r for r in client.run(lambda: __import__("os").getpid()).values()}
    assert res["timing"]["backend"].startswith("dask") and res["timing"]["workers"] == 2
    assert len(pids) == 2
    for mode in paper.MODES:
        assert np.allclose(res["clouds"][mode]["tips"], serial["clouds"][mode]["tips"], rtol=0, atol=1e-12)


def test_failures_are_counted_not_dropped():
    """Tensions above the model's 5 N limit are rejected by FK: exactly those samples must be reported."""
    res = paper.workspace(samples=30, seed=1, params=PRESET, workers=1, progress=False, tension_range=(0.0, 6.0))
    total = 0
    for mode in paper.MODES:
        X = res["clouds"][mode]["inputs"]
        bad = np.any(X[:, :3] > 5.0, axis=1)
        assert 0 < bad.sum() < 30
        md = res["modes"][mode]
        assert md["failures"] == bad.sum() and md["solved"] == 30 - bad.sum()
        assert md["failed_indices"] == list(np.flatnonzero(bad))
        assert np.array_equal(md["failed_inputs"], X[bad])
        assert np.array_equal(res["clouds"][mode]["ok"], ~bad)
        assert np.all(np.isnan(res["clouds"][mode]["tips"][bad]))
        assert md["first_errors"] and md["first_errors"][0].startswith(("InputError", "LimitError"))  # LimitError: an InputError subclass
        assert md["volume_m3"] == pytest.approx(paper.hull_volume(res["clouds"][mode]["tips"][~bad]))
        total += bad.sum()
    assert res["failures"] == total


def test_solver_failures_are_counted():
    res = paper.workspace(samples=6, seed=0, params=PRESET, workers=1, progress=False, fk_kwargs={"max_iter": 1})
    assert res["failures"] == res["modes"]["TD"]["failures"] + res["modes"]["TPHD"]["failures"] > 0
    assert "ConvergenceError" in (res["modes"]["TD"]["first_errors"] + res["modes"]["TPHD"]["first_errors"])[0]


def test_warm_start_gives_the_same_equilibria(serial):
    cold = paper.workspace(samples=40, seed=3, params=PRESET, workers=1, progress=False, chunk_size=20,
                           warm_start=False)
    assert serial["timing"]["warm_start"] and not cold["timing"]["warm_start"]
    for mode in paper.MODES:
        assert np.allclose(cold["clouds"][mode]["tips"], serial["clouds"][mode]["tips"], atol=1e-8)


def test_files_written(tmp_path):
    res = paper.workspace(samples=12, seed=0, params=PRESET, workers=1, progress=False, out=tmp_path)
    data = json.loads((tmp_path / "workspace.json").read_text())
    assert data["volume_td_m3"] == pytest.approx(res["volume_td_m3"])
    assert data["failures"] == 0 and data["samples"] == 12 and "clouds" not in data
    z = np.load(tmp_path / "workspace_clouds.npz")
    assert np.array_equal(z["tphd_tips"], res["clouds"]["TPHD"]["tips"])
    assert np.array_equal(z["td_inputs"], res["clouds"]["TD"]["inputs"])
    assert list(z["columns"]) == ["T1_N", "T2_N", "T3_N", "p_Pa"]
    assert (tmp_path / "workspace.png").stat().st_size > 20_000
    assert (tmp_path / "workspace.svg").read_text().lstrip().startswith("<?xml")


@pytest.mark.slow
def test_ratio_settles_with_samples():
    """The Monte Carlo hull converges from below; at 2000 samples per mode the half-sample volume is
    within a few per cent of the full one."""
    res = paper.workspace(samples=2000, seed=0, params=PRESET, progress=False)
    for mode in paper.MODES:
        half = res["modes"][mode]["convergence"]["volume_first_1000_m3"]
        assert half <= res["modes"][mode]["volume_m3"] * (1 + 1e-12)
        assert half >= 0.9 * res["modes"][mode]["volume_m3"]
