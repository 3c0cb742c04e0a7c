"""The identification experiment on a rig: the D-optimal design, the run on a simulated rig (reached tensions,
identification recovers the plant's known stiffness), Ctrl-C and --resume, no overwrite, the command line."""

from __future__ import annotations

import numpy as np
import pytest

from ancf import StiffnessLaw, presets
from ancf.errors import InputError
from hardware.errors import RunAborted
from hardware.simulated import PlantOptions, SimulatedRig
from hardware.static_states import read_static_states
from validation.identification.design_select import d_optimal
from validation.identification.experiment import (candidate_sensitivities, candidate_states, design_experiment,
                                                  logdet_information)
from validation.identification.experiment_run import ExperimentOptions, run_experiment

BASE = presets.paper()
TRAVEL = (0.6 * BASE.length, 1.4 * BASE.length)          # SimulatedRig's default travel


def _softer(params, factor=0.95):
    law = params.stiffness
    return params.replace(stiffness=StiffnessLaw.polynomial(EA=[factor * c for c in law.EA_coeffs],
                                                            EI=[factor * c for c in law.EI_coeffs]))


PLANT = _softer(BASE)


@pytest.fixture(scope="module")
def plan():
    return design_experiment(BASE, 10, form="paper", travel=TRAVEL)


def _rig():
    return SimulatedRig(BASE, options=PlantOptions(params=PLANT))


OPTS = ExperimentOptions(samples=2, settle_s=0.0)


def test_the_design_is_more_informative_than_random_designs():
    from validation.identification.forms import get_form
    from validation.identification.identify import initial_theta
    form = get_form("paper")
    ok, J = candidate_sensitivities(form, candidate_states(BASE, (0.0, 0.05)), BASE, initial_theta(form, None, BASE),
                                    TRAVEL)
    k = 8
    best = logdet_information(J, d_optimal(J, k))
    rng = np.random.default_rng(0)
    randoms = [logdet_information(J, rng.choice(len(ok), k, replace=False)) for _ in range(20)]
    assert best > max(randoms)


def test_the_design_is_ordered_for_a_rig_and_within_range():
    p = design_experiment(BASE, 12, form="paper", masses_kg=(0.0, 0.02, 0.05), travel=TRAVEL)
    masses = [s.mass for s in p.states]
    assert masses == sorted(masses)                             # each mass hung once
    for m in set(masses):                                       # within a mass: pressure ascending
        ps = [s.pressure for s in p.states if s.mass == m]
        assert ps == sorted(ps)
    T = np.array([s.tensions for s in p.states])
    assert T.max() <= BASE.tension_max and T.min() >= 0
    assert all(0 <= s.pressure <= BASE.pressure_max for s in p.states)
    for s in p.states:                                          # the known force is m g
        assert np.allclose(s.tip_force, np.asarray(BASE.gravity) * s.mass)
    with pytest.raises(InputError):
        design_experiment(BASE, 3, form="paper")                # fewer states than parameters
    with pytest.raises(InputError):
        design_experiment(BASE, 10, masses_kg=(2.0,))           # 2 kg


def test_a_run_reaches_the_tensions_and_identifies_the_plant(plan, tmp_path):
    from validation.identification.identify import from_measurements
    log = tmp_path / "exp.h5"
    res = run_experiment(plan, _rig(), BASE, log, options=OPTS)
    assert res.status == "completed" and res.done == len(plan.states) == 10
    st = read_static_states(log)
    designed = np.array([s.tensions for s in plan.states])
    assert np.abs(st.tensions - designed).max() <= OPTS.tension_tolerance + 1e-9
    assert np.all(st.tip_force == np.array([s.tip_force for s in plan.states]))     # 0, not NaN
    assert st.tip_position_std is not None and np.all(st.tip_position_std > 0)
    r = from_measurements(log, BASE, forms=("paper",))
    assert r.values["EA"] == pytest.approx(float(PLANT.stiffness.EA(1.0)), rel=1e-4)
    assert r.values["EI"] == pytest.approx(float(PLANT.stiffness.EI(1.0)), rel=1e-4)
    assert abs(r.values["EA"] / float(BASE.stiffness.EA(1.0)) - 1) > 0.04   # not the model's own value


def test_an_interrupted_run_resumes_to_the_same_states(plan, tmp_path):
    full = tmp_path / "full.h5"
    run_experiment(plan, _rig(), BASE, full, options=OPTS)
    log = tmp_path / "cut.h5"

    def stop_after_3(rec):
        if rec["done"] == 3:
            raise KeyboardInterrupt

    with pytest.raises(RunAborted):
        run_experiment(plan, _rig(), BASE, log, options=OPTS, progress=stop_after_3)
    assert read_static_states(log).n_states == 3
    with pytest.raises(InputError, match="exists"):
        run_experiment(plan, _rig(), BASE, log, options=OPTS)              # no overwrite without force
    with pytest.raises(InputError, match="other options"):
        run_experiment(plan, _rig(), BASE, log, options=ExperimentOptions(samples=3, settle_s=0.0), resume=True)
    res = run_experiment(plan, _rig(), BASE, log, options=OPTS, resume=True)
    assert res.recorded == 7 and res.done == 10
    a, b = read_static_states(full), read_static_states(log)
    assert a.label == b.label
    assert np.allclose(a.tensions, b.tensions, atol=1e-9) and np.allclose(a.tip_position, b.tip_position, atol=1e-9)


def test_the_command_line_end_to_end(tmp_path, monkeypatch, capsys):
    from validation.commands.main import main
    monkeypatch.chdir(tmp_path)
    argv = ["experiment", "--rig", "sim", "--states", "8", "--form", "paper", "--loads-g", "0", "--samples", "2",
            "--log", "exp.h5"]
    with pytest.raises(SystemExit) as e:
        main(argv)
    assert e.value.code == 0
    with pytest.raises(SystemExit) as e:                       # never overwritten without --force
        main(argv)
    assert e.value.code == 2 and "error:" in capsys.readouterr().err
    with pytest.raises(SystemExit) as e:
        main(["identify", "--measurements", "exp.h5", "--base", "paper", "--forms", "paper", "--out", "fit"])
    assert e.value.code == 0
    assert (tmp_path / "fit" / "actuator.toml").is_file()


def test_the_noise_of_a_channel_is_pooled_over_the_states():
    """Standard errors from the pooled variance: exact on given variances, and over 40 states of one instrument far
    steadier than each state's own 3-reading estimate (which is uncertain by ~50 %)."""
    from validation.identification.experiment_run import SE_FLOOR, NoisePool
    pool = NoisePool()
    pool.add({"pressure_std": 4.0e4, "tensions_std": np.array([1e-4, 4e-4, 0.0])})
    pool.add({"pressure_std": 2.0e4, "tensions_std": np.array([3e-4, 0.0, 0.0])})
    se = pool.standard_errors(3)
    assert se["pressure_std"] == pytest.approx(np.sqrt(3.0e4 / 3))
    assert se["tensions_std"] == pytest.approx([np.sqrt(2e-4 / 3), np.sqrt(2e-4 / 3), SE_FLOOR["tensions_std"]])
    rng, sigma, pooled, own = np.random.default_rng(3), 0.02, NoisePool(), []
    for _ in range(40):
        readings = rng.normal(1.0, sigma, 3)
        pooled.add({"tensions_std": readings.var(ddof=1)})
        own.append(readings.std(ddof=1) / np.sqrt(3))
    truth = sigma / np.sqrt(3)
    assert abs(pooled.standard_errors(3)["tensions_std"] / truth - 1) < 0.15
    assert np.std(np.array(own) / truth) > 0.3


def test_a_tendon_left_slack_is_recorded_as_carrying_nothing(plan, tmp_path):
    """Force sensors with 0.02 N of noise: a tendon designed slack reads noise about 0, whose mean clipped at 0 would
    record a pull that is not there (it biased EI by −0.13 % over 50 seeds); it is recorded as 0 N, the taut ones as
    measured (their mean of noisy readings, not the design)."""
    log = tmp_path / "noisy.h5"
    rig = SimulatedRig(BASE, options=PlantOptions(params=PLANT, force_noise_std=0.02, seed=2))
    run_experiment(plan, rig, BASE, log, options=ExperimentOptions(samples=3, settle_s=0.0, tension_tolerance=0.1))
    st = read_static_states(log)
    designed = np.array([s.tensions for s in plan.states])
    slack, taut = designed == 0.0, designed > 0.0
    assert slack.any() and taut.any()
    assert np.all(st.tensions[slack] == 0.0)
    assert np.all(st.tensions[taut] != designed[taut])                  # measured, with their noise
