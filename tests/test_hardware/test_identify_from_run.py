"""Static states recorded by control runs on the simulated rig feed validation.identification.identify.from_measurements,
which recovers the plant's stiffness law from them."""

import pytest

from ancf import Model, presets
from controller import LACC, RunOptions, run_on_rig
from hardware import PlantOptions, SimulatedRig
from hardware.runlog import RunLog


def test_identification_from_a_run_log(tmp_path):
    from validation.identification.identify import from_measurements
    model = Model(presets.paper_unscaled())
    path = tmp_path / "identification.h5"
    with RunLog(path, n_tendons=3) as log:
        for T in ((2.2, 1.6, 1.6), (1.2, 3.0, 1.0), (1.0, 1.0, 3.0), (3.5, 1.0, 1.0), (2.0, 2.0, 2.0)):
            for p in (40e3, 60e3, 80e3):
                tip = model.fk(T, p, (0, 0, 0)).tip
                rig = SimulatedRig(model, options=PlantOptions(force_noise_std=0.001, seed=int(p) + int(10 * T[0])))
                res = run_on_rig(LACC(model, p, compliance="exact"), rig, tip,
                                 RunOptions(log=log, applied_load=(0, 0, 0)))
                assert res.status == "converged"
    r = from_measurements(path, presets.paper(), heldout_fraction=0, forms=("paper",))
    law = presets.paper_unscaled().stiffness.source
    fit = r.fits["paper"]
    assert abs(fit.values["a"] - law["a"]) < 0.02 * law["a"]
    assert abs(fit.values["a"] + fit.values["b"] - (law["a"] + law["b"])) < 0.02 * (law["a"] + law["b"])
    for name, true in (("a", law["a"]), ("k1", law["a"] + law["b"]), ("D_a", law["D_a"])):
        lo, hi = fit.ci95[name]
        assert lo <= true <= hi, (name, lo, true, hi)       # the truth lies in the stated 95 % interval


def test_identification_uses_the_complete_states_of_a_log_with_a_torn_state(tmp_path):
    """A writer killed while recording a static state leaves a torn last row: the identification uses the
    complete states and reports the torn one (it used to refuse the whole log)."""
    from validation.identification.identify import from_measurements
    model = Model(presets.paper_unscaled())
    path = tmp_path / "torn.h5"
    log = RunLog(path, n_tendons=3)
    k = 0
    for T in ((2.2, 1.6, 1.6), (1.2, 3.0, 1.0), (1.0, 1.0, 3.0), (3.5, 1.0, 1.0)):
        for p in (40e3, 80e3):
            log.static_state(time=k, tensions=T, pressure=p, tip=model.fk(T, p, (0, 0, 0)).tip, tip_force=(0, 0, 0))
            k += 1
    log.flush()                                                       # the finished states are on disk
    RunLog._append(log.static["tensions"], [2.0, 2.0, 2.0])           # the next state: killed after its tensions
    log.f.flush()
    log.close()
    r = from_measurements(path, presets.paper(), heldout_fraction=0, forms=("paper",))
    assert r.meta["n_states"] == 8 and r.meta["torn_rows"] == [8]


def test_measured_states_need_the_actuator_they_were_measured_on(tmp_path):
    """No default actuator: identifying rig data against the wrong one gives wrong numbers silently."""
    from ancf.errors import InputError
    from validation.identification.identify import from_measurements
    with pytest.raises(InputError, match="needs base="):
        from_measurements(tmp_path / "never_read.h5")
    with pytest.raises(InputError, match="ActuatorParams"):
        from_measurements(tmp_path / "never_read.h5", "paper")
