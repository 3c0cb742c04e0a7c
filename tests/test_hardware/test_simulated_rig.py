"""The simulated rig (the one simulated plant): hidden load, mismatch options, reproducibility; LACC holds
the tip on a mismatched rig under stochastic loading; static states of a run read back."""

import math

import numpy as np
import pytest

from ancf.errors import InputError
from ancf import presets
from controller import LACC, RunOptions, run_iterations, run_on_rig
from hardware import PlantOptions, SimulatedRig
from hardware.loads import load_profile
from hardware.static_states import read_static_states

SimulatedPlant = SimulatedRig

P = 60e3
TENSIONS = (2.5, 2.2, 2.2)


@pytest.fixture(scope="module")
def ref(paper_model):
    return paper_model.fk(TENSIONS, P, (0, 0, 0))


def test_perfect_plant_reproduces_the_model(paper_model, ref):
    plant = SimulatedPlant(paper_model, P)
    plant.command(ref.tendon_lengths)
    np.testing.assert_allclose(plant.true_tip(), ref.tip, atol=1e-9)
    plant.set_load((0, 0, -0.5))
    assert plant.true_tip()[2] < ref.tip[2] - 1e-3           # the hidden load moves it down


def test_mismatched_parameters_change_the_plant(paper_model, ref):
    plant = SimulatedPlant(paper_model, P, options=PlantOptions.mismatched(noise_std=0.0, tendon_friction=0.0,
                                                                          tendon_stiffness=math.inf))
    plant.command(ref.tendon_lengths)
    assert np.linalg.norm(plant.true_tip() - ref.tip) > 3e-4


def test_resolution_rate_limit_and_noise(paper_model, ref):
    opts = PlantOptions(length_resolution=1e-5, length_rate=2e-3, noise_std=1e-4, seed=7)
    plant = SimulatedPlant(paper_model, P, options=opts)
    plant.command(ref.tendon_lengths)
    assert np.allclose(plant.lengths / 1e-5, np.round(plant.lengths / 1e-5), atol=1e-6)
    new = ref.tendon_lengths + np.array([-1e-3, 4e-4, 0.0])
    assert plant.command(new) == pytest.approx(1e-3 / 2e-3, rel=1e-2)
    plant.advance(0.25)                                      # halfway
    np.testing.assert_allclose(plant.lengths[0], ref.tendon_lengths[0] - 5e-4, atol=1e-5)
    plant.advance()
    np.testing.assert_allclose(plant.lengths, np.round(new / 1e-5) * 1e-5)
    a = [plant.measure() for _ in range(200)]
    assert 5e-5 < np.std(np.array(a)[:, 2]) < 2e-4
    p2 = SimulatedPlant(paper_model, P, options=opts)
    p2.command(plant.lengths)
    p3 = SimulatedPlant(paper_model, P, options=opts)
    p3.command(plant.lengths)
    np.testing.assert_array_equal(p2.measure(), p3.measure())  # same seed, same noise


def test_friction_makes_a_hysteresis(paper_model, ref):
    opts = PlantOptions(tendon_friction=0.3, tendon_stiffness=2e4)
    tips = []
    for sign in (+1, -1):
        plant = SimulatedPlant(paper_model, P, options=opts)
        plant.command(ref.tendon_lengths + sign * 1e-3)
        plant.command(ref.tendon_lengths)                   # approach from above (pull) / below (release)
        plant.advance()
        tips.append(plant.true_tip())
    assert np.linalg.norm(tips[0] - tips[1]) > 1e-5


def test_lacc_converges_on_a_mismatched_plant(paper_model, ref):
    m = paper_model
    plant = SimulatedPlant(m, P, load=(0, 0.05, -0.4), options=PlantOptions.mismatched(base=m.params, seed=3))
    res = run_iterations(LACC(m, P, compliance="exact"), plant, ref.tip, iterations=12)
    assert res.errors[0] > 1e-3
    assert res.converged and res.final_error < 3e-4          # 0.2 mm measured, with 0.05 mm noise


@pytest.mark.slow
def test_default_lacc_converges_on_a_mismatched_plant(paper_model, ref):
    m = paper_model
    plant = SimulatedPlant(m, P, load=(0, 0.05, -0.4), options=PlantOptions.mismatched(base=m.params, seed=3))
    res = run_iterations(LACC(m, P), plant, ref.tip, iterations=40)
    assert res.converged


def test_plant_rejects_bad_options(paper_model):
    with pytest.raises(InputError):
        PlantOptions(noise_std=-1.0)
    with pytest.raises(InputError):
        PlantOptions(length_rate=0.0)
    with pytest.raises(InputError):
        SimulatedPlant(paper_model, P, load=(0, np.nan, 0))
    plant = SimulatedPlant(paper_model, P)
    with pytest.raises(InputError):
        plant.true_tip()                                     # nothing commanded yet


def test_controller_aliases_are_the_one_simulated_rig():
    import controller
    assert controller.SimulatedPlant is SimulatedRig and controller.PlantOptions is PlantOptions


def test_public_constructor_and_seed(paper_model, ref):
    a = SimulatedRig(presets.paper(), load=(0, 0, -0.2), seed=4, options=PlantOptions(noise_std=1e-4))
    b = SimulatedRig(presets.paper(), load=(0, 0, -0.2), seed=4, options=PlantOptions(noise_std=1e-4))
    for r in (a, b):
        r.set_pressure(P)
        r.command(ref.tendon_lengths)
    np.testing.assert_array_equal(a.measure(), b.measure())
    assert a.options.seed == 4


def test_tracker_latency_reports_the_past(paper_model, ref):
    rig = SimulatedRig(paper_model, P, options=PlantOptions(length_rate=1e-3, tracker_latency=0.5))
    rig.command(ref.tendon_lengths)
    rig.advance(1.0)
    before = rig.true_tip()
    rig.command(ref.tendon_lengths + [-1e-3, 0, 0])
    rig.advance(0.3)
    np.testing.assert_allclose(rig.measure(), before, atol=1e-12)           # 0.5 s old: before the move
    rig.advance(0.45)                      # t = 1.75: the pose is the state at 1.25 s, 0.25 mm into the move
    mid = SimulatedRig(paper_model, P)
    mid.command(ref.tendon_lengths + [-0.25e-3, 0, 0])
    np.testing.assert_allclose(rig.measure(), mid.true_tip(), atol=1e-9)
    rig.advance(1.0)                       # the move ended at 2.0 s; at 2.75 s the pose shows its end
    np.testing.assert_allclose(rig.measure(), rig.true_tip(), atol=1e-12)


def test_lacc_holds_within_0_2_mm_under_stochastic_loading_on_a_mismatched_rig(paper_model, ref, tmp_path):
    """Other parameters, tendon friction, 0.05 mm tracker noise, motor rate; a new stochastic load
    (20–60 g + lateral) every 3 s.  LACC (default compliance) holds the *true* tip within 0.2 mm once it has
    settled after each change.  Each measurement averages 4 tracker frames (noise 0.025 mm per axis) and the
    controller's deadband is 0.1 mm on the measured error, so the true error stays below 0.2 mm despite the
    tracker noise."""
    opts = PlantOptions.mismatched(base=paper_model.params, seed=5)
    load = load_profile("stochastic", period=3.0, seed=11)
    rig = SimulatedRig(paper_model, load=load, options=opts)
    res = run_on_rig(LACC(paper_model, P, tolerance=1e-4), rig, ref.tip,
                     RunOptions(log=tmp_path / "hold.h5", duration=12.0, idle_period=0.1, sim_compute_time=0.05,
                                average_frames=4))
    assert res.status == "held"
    assert res.true_errors[0] > 1e-3                          # the loads really displace the tip
    from hardware.runlog import read_run_log
    d = read_run_log(tmp_path / "hold.h5")
    t, tip = d.samples["t"], d.samples["true_tip"]
    err = np.linalg.norm(tip - ref.tip, axis=1)
    settled = np.array([(ti % 3.0) > 1.5 for ti in t])         # second half of each load period
    assert settled.sum() > 10
    assert err[settled].max() < 2e-4
    assert len({round(float(x), 3) for x in d.samples["true_load"][:, 2]}) >= 4   # the load did change
    st = read_static_states(tmp_path / "hold.h5")
    assert st.n_states >= 3


def test_static_states_of_a_run_read_back(paper_model, ref, tmp_path):
    rig = SimulatedRig(paper_model, load=(0, 0.05, -0.4), options=PlantOptions(force_noise_std=0.01))
    res = run_on_rig(LACC(paper_model, P, compliance="exact"), rig, ref.tip, RunOptions(log=tmp_path / "s.h5"))
    assert res.status == "converged" and res.static_states == 1
    st = read_static_states(tmp_path / "s.h5")
    eq = rig.equilibrium()
    assert st.n_states == 1 and st.n_tendons == 3
    np.testing.assert_allclose(st.tensions[0], eq.tensions, atol=0.05)       # measured with 0.01 N noise
    assert st.pressure[0] == P
    np.testing.assert_allclose(st.tip_position[0], eq.tip, atol=1e-12)
    assert np.all(np.isnan(st.tip_force))                                    # the rig does not know the load
    assert np.linalg.norm(st.tip_position[0] - ref.tip) < 2e-4


def test_mismatched_plant_keeps_a_pressure_dependent_law():
    from ancf import presets as _presets
    law = _presets.paper().stiffness.with_pressure(EI=(0.8, 0.2))
    opts = PlantOptions.mismatched(base=_presets.paper().replace(stiffness=law))
    assert opts.params.stiffness.EI_pressure == (0.8, 0.2)
    assert float(opts.params.stiffness.EI(1.0, 100e3)) == pytest.approx(0.95 * 2.0 * float(law.EI(1.0)), rel=1e-12)
