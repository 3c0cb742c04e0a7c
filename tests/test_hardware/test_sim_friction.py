"""Tendon friction as a plant effect of the simulated rig: the capstan law of the plant actuator's
``tendon_friction`` with its history (ancf.friction.fk_locked_history per step), and the pull-through test the
rig can run, identified back (validation.identification.friction)."""

import numpy as np
import pytest

from ancf import Model, presets
from ancf.errors import InputError
from hardware import PlantOptions, SimulatedRig
from validation.identification import friction as idf

P = 20e3
MU = 0.3


@pytest.fixture(scope="module")
def lengths():
    return Model(presets.paper()).fk([3.0, 1.0, 0.5], P).tendon_lengths


def _load_cycle(mu, lengths, loads):
    rig = SimulatedRig(presets.paper().replace(tendon_friction=mu), P)
    rig.command(lengths)
    tips = []
    for F in loads:
        rig.set_load((0.0, 0.0, F))
        tips.append(rig.true_tip())
    return rig, np.array(tips)


def test_friction_in_the_plant_makes_a_load_hysteresis_and_none_without(lengths):
    loads = [0.0, -0.2, -0.4, -0.2, 0.0]
    _rig0, free = _load_cycle(0.0, lengths, loads)
    rig, tips = _load_cycle(MU, lengths, loads)
    assert np.allclose(free[0], free[-1], rtol=0, atol=1e-9)                        # no friction: it returns
    assert np.allclose(free[1], free[3], rtol=0, atol=1e-9)
    assert np.linalg.norm(tips[1] - tips[3]) > 1e-5                                  # friction: the branches differ
    assert np.linalg.norm(tips[-1] - tips[0]) > 1e-5                                 # and it does not come back
    st = rig._plant.fstate                                                           # the plant's present state
    assert st is not None and st.friction == MU and np.allclose(st.locked_lengths, lengths)
    T, a = st.segment_tensions, st.wrap_angles
    for i in st.equilibrium.active:                                                  # every segment in its cone
        prev = np.concatenate([[st.motor_tensions[i]], T[i, :-1]])
        assert np.all(T[i] >= prev * np.exp(-MU * a[i]) * (1 - 1e-9))
        assert np.all(T[i] <= prev * np.exp(MU * a[i]) * (1 + 1e-9))
    n = rig.solves
    assert np.array_equal(rig.true_tip(), tips[-1]) and rig.solves == n              # a held state is not re-solved


def test_the_force_sensors_read_the_motor_side_and_the_series_stiffness_still_acts(lengths):
    stiff = SimulatedRig(presets.paper().replace(tendon_friction=MU), P)
    soft = SimulatedRig(presets.paper().replace(tendon_friction=MU), P,
                        options=PlantOptions(tendon_stiffness=2e3, tendon_friction=0.05))
    for rig in (stiff, soft):
        rig.command(lengths)
    eq = stiff.equilibrium()
    assert np.allclose(stiff.read_tensions(), eq.tensions)
    assert eq.tensions[0] > 1.0
    assert soft.equilibrium().tensions[0] < eq.tensions[0]                            # the tendon stretched


def test_the_dynamic_plant_takes_a_friction_actuator():
    rig = SimulatedRig(presets.paper().replace(tendon_friction=0.1), P, dynamics=True)   # tests/test_hardware/
    assert rig._plant.dyn.friction is not None                                            # test_dynamic_friction.py


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_pull_through_on_the_rig_identifies_the_plants_friction(lengths, seed):
    rig = SimulatedRig(presets.paper().replace(tendon_friction=MU), P,
                       options=PlantOptions(force_noise_std=0.01, seed=seed))
    rig.command(lengths)
    Tm = idf.protocol(4.0, 0.2, 15)
    motor, anchor = rig.pull_through(0, Tm)
    assert np.array_equal(motor, Tm)                                                 # the motor side: commanded
    W = idf.total_wrap(rig.model, rig.equilibrium().q, 0)
    assert np.allclose(anchor[:15], Tm[:15] * np.exp(-MU * W), rtol=0, atol=0.06)   # pulling: the capstan ratio
    fit = idf.fit_pull_through(motor, anchor, W, motor_std=1e-9, anchor_std=0.01)
    assert fit.contains(MU) and fit.std < 0.01


def test_pull_through_is_refused_on_a_dynamic_plant():
    rig = SimulatedRig(presets.paper(), P, dynamics=True)
    rig.command(Model(presets.paper()).fk([1.0, 1.0, 1.0], P).tendon_lengths)
    with pytest.raises(InputError, match="dynamic"):
        rig.pull_through(0, [1.0, 2.0, 1.0])


def _static_rig(lengths):
    rig = SimulatedRig(presets.paper().replace(tendon_friction=MU), P)
    rig.command(lengths)
    return rig


def _law_path(lengths, path):
    """The locked friction law applied by hand (ancf.friction): rigged from the slack actuator at ``lengths``,
    then one step to each motor state of ``path``; the tip z [m] after each."""
    from ancf.friction import fk_history, fk_locked_history
    m = Model(presets.paper().replace(tendon_friction=MU))
    st = fk_locked_history(m, fk_history(m, np.zeros(3), P, check_limits=False), lengths, P)
    out = []
    for L in path:
        st = fk_locked_history(m, st, L, P)
        out.append(st.tip[2])
    return np.array(out)


def test_the_static_friction_plant_does_not_depend_on_when_it_is_queried(lengths):
    """The static plant is solved lazily; its friction history still starts where the tendons were rigged and
    passes every turn of the motors, so a rig queried only at the end of a cycle 0 → 0.3 mm → 0 on motor 1 is
    in the state of one queried at every move, and both are the law applied at the rigging and the turn."""
    pulled = lengths - np.array([3e-4, 0.0, 0.0])
    every, once = _static_rig(lengths), _static_rig(lengths)
    z_every = [every.true_tip()[2]]
    for rig in (every, once):
        for target in (pulled, lengths):
            rig.command(target)
            rig.advance()
            if rig is every:
                z_every.append(rig.true_tip()[2])
    ref = _law_path(lengths, [pulled, lengths])
    assert once.true_tip()[2] == pytest.approx(z_every[-1], abs=1e-9)
    assert np.allclose(z_every[1:], ref, rtol=0, atol=1e-9)
    assert abs(z_every[1] - z_every[0]) > 5e-4                  # the pull moved the tip (0.8 mm)


def test_the_static_friction_plant_rigs_at_the_first_command(lengths):
    """A static friction plant first queried after a move starts from the state rigged at the first command
    (as the dynamic plant does), not from the slack actuator locked at the moved lengths."""
    pulled = lengths - np.array([3e-4, 0.0, 0.0])
    rig = _static_rig(lengths)
    rig.command(pulled)
    rig.advance()
    assert rig.true_tip()[2] == pytest.approx(_law_path(lengths, [pulled])[0], abs=1e-9)
    assert rig.solves == 2                                       # the rigging and the pull, once each
