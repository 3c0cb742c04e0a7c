"""``modes`` (and ``simulate``'s q0 given as an equilibrium) take only an equilibrium of their own model
(ancf.dynamics.modes.check_equilibrium): one solved for another actuator, of another size, or a state that
is not an equilibrium under its loads is refused with an InputError instead of returning its numbers."""

import copy
import dataclasses

import numpy as np
import pytest

from ancf import Model, presets
from ancf.errors import InputError

P30 = 30e3


@pytest.fixture(scope="module")
def model():
    return Model(presets.paper())


@pytest.fixture(scope="module")
def own(model):
    return model.fk((2, 0, 0), P30)


def test_own_equilibria_pass(model, own):
    assert model.modes(own, 2).frequencies_hz[0] > 0
    locked = model.fk_locked(own.tendon_lengths, P30, q0=own.q, tensions0=own.tensions)
    assert model.modes(locked, 2).locked == (0,)           # the one taut tendon
    rebuilt = dataclasses.replace(own)                         # built by hand: judged by its residual alone
    assert model.modes(rebuilt, 1).frequencies_hz[0] == pytest.approx(model.modes(own, 1).frequencies_hz[0])


def test_an_equilibrium_of_another_preset_is_refused(model):
    other = Model(presets.paper_constant())
    assert other.ndof == model.ndof
    eq = other.fk((2, 0, 0), P30)
    with pytest.raises(InputError, match="paper_constant|another actuator|solved for"):
        model.modes(eq, 2)
    # without the actuator it carries, its residual under this model's law gives it away
    ev = model.evaluate(eq.q, eq.tensions, eq.pressure, eq.tip_force)
    assert np.linalg.norm(model.reduce_vec(ev.Q)) > 1.0                    # [N]: not an equilibrium here
    with pytest.raises(InputError, match="not an equilibrium"):
        model.modes(dataclasses.replace(eq), 2)


def test_a_statically_identical_actuator_is_still_another_actuator(model):
    """`paper_scaled` has the same statics (residual ~1e-11 N) but is another parameter set."""
    twin = Model(presets.paper_scaled())
    assert twin.params != model.params
    eq = twin.fk((2, 0, 0), P30)
    with pytest.raises(InputError, match="solved for"):
        model.modes(eq, 2)


def test_another_size_is_refused(model):
    small = Model(presets.paper().replace(n_elements=4))
    with pytest.raises(InputError, match="coordinates"):
        model.modes(small.fk((2, 0, 0), P30), 2)


@pytest.mark.parametrize("where, size", [(-3, 1e-4), (-6, 1e-4), (9, 1e-5)])
def test_a_perturbed_state_is_refused(model, own, where, size):
    bad = copy.copy(own)                                       # keeps the actuator it was solved for
    bad.q = own.q.copy()
    bad.q[where] += size
    with pytest.raises(InputError, match="not an equilibrium"):
        model.modes(bad, 2)


def test_simulate_checks_an_equilibrium_given_as_q0(model, own):
    sim = model.simulate(0.01, 5e-3, q0=own, tensions=(2, 0, 0), pressure=P30, damping=0.0)
    assert np.abs(sim.tip - own.tip).max() < 1e-9
    other = Model(presets.paper_constant()).fk((2, 0, 0), P30)
    with pytest.raises(InputError, match="simulate: q0"):
        model.simulate(0.01, 5e-3, q0=other, tensions=(2, 0, 0), pressure=P30)
    # an array stays any admissible state: a release from a displaced state is a start by design
    assert model.simulate(0.01, 5e-3, q0=other.q, tensions=(2, 0, 0), pressure=P30, damping=0.0).t[-1] == 0.01
