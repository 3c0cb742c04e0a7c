"""The simulated plant: hidden load, mismatch options, reproducibility."""

import math

import numpy as np
import pytest

from ancf.errors import InputError
from controller import LACC, PlantOptions, SimulatedPlant, run_iterations

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
    plant = SimulatedPlant(m, P, load=(0, 0.05, -0.4), options=PlantOptions.mismatched(seed=3))
    res = run_iterations(LACC(m, P, compliance="exact"), plant, ref.tip, iterations=12)
    assert res.errors[0] > 1e-3
    assert res.converged and res.final_error < 3e-4          # 0.2 mm measured, with 0.05 mm noise


@pytest.mark.slow
def test_default_lacc_converges_on_a_mismatched_plant(paper_model, ref):
    m = paper_model
    plant = SimulatedPlant(m, P, load=(0, 0.05, -0.4), options=PlantOptions.mismatched(seed=3))
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
