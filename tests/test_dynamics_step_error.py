"""A time step too coarse for the motion (ancf.dynamics.transient: the energy check).

The reference is the same run at a step fine enough to need no refinement (1 ms, 50× finer), not the
code's own coarse output: on the `paper` actuator, a 0 → 2 N tension step at 30 kPa with 5 % damping
integrated at dt = 50 ms used to end 52 mm away from it with the energy balance showing 1.4 J created
(the motion's kinetic energy peaks at 6 mJ), and no error."""

import numpy as np
import pytest

from ancf import Model, presets
from ancf.dynamics import transient
from ancf.errors import ConvergenceError

P30 = 30e3


@pytest.fixture(scope="module")
def model():
    return Model(presets.paper())


@pytest.fixture(scope="module")
def start(model):
    return model.fk((0, 0, 0), P30)


def step(model, start, dt, t_end=0.5):
    return model.simulate(t_end, dt, q0=start.q, tensions=(2, 0, 0), pressure=P30, damping=0.05)


@pytest.fixture(scope="module")
def reference(model, start):
    ref = step(model, start, 1e-3)
    assert not [e for e in ref.events if e["kind"] == "refined"]          # fine enough as it is
    return ref


def created_energy(sim):
    """Energy created by the integration (E + D growing) against the motion's largest kinetic energy [J]."""
    bal = sim.energy + sim.dissipated
    return float(bal.max() - bal[0]), float(sim.kinetic.max())


def test_a_coarse_step_is_refined_to_the_fine_trajectory(model, start, reference):
    sim = step(model, start, 0.05)
    np.testing.assert_allclose(sim.t, np.linspace(0.0, 0.5, 11), atol=1e-12)     # the output grid is kept
    assert sim.dt == pytest.approx(0.05)
    assert any(e["kind"] == "refined" for e in sim.events)
    err = np.abs(sim.tip - reference.tip[::50]).max()
    assert err < 1e-3, f"tip {err * 1e3:.2f} mm from the fine run"                 # was 52.6 mm
    created, k_max = created_energy(sim)
    created_ref, k_ref = created_energy(reference)
    assert created < 2.0 * k_ref                                                   # was 1.4 J against 6 mJ
    assert k_max == pytest.approx(k_ref, rel=0.05)


def test_a_step_too_coarse_even_refined_is_refused_with_the_step_that_would_do(model, start, monkeypatch):
    monkeypatch.setattr(transient, "MAX_REFINE", 0)
    with pytest.raises(ConvergenceError, match=r"too coarse.*use dt ≤") as info:
        step(model, start, 0.05)
    dt_ok = float(str(info.value).split("use dt ≤ ")[1].split(" s")[0])
    assert 1e-4 < dt_ok < 0.05
    sim = step(model, start, dt_ok)                                                # the named step passes unrefined
    assert not [e for e in sim.events if e["kind"] == "refined"]


def test_the_normal_path_is_not_refined(model, start):
    """At 1 ms (a 1 kHz loop's step) the step response and a state at rest pass the check untouched."""
    sim = step(model, start, 1e-3, t_end=0.05)
    assert not [e for e in sim.events if e["kind"] == "refined"]
    eq = model.fk((2, 0, 0), P30)
    rest = model.simulate(0.02, 1e-3, q0=eq.q, tensions=(2, 0, 0), pressure=P30, damping=0.0)
    assert not rest.events and np.abs(rest.tip - eq.tip).max() < 1e-9
