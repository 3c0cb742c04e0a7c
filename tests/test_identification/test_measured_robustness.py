"""Rig data with a state past a limit point of the starting parameters: the fit leaves it out of a first pass,
re-admits it from that optimum and says so; with too few states left it fails with a typed error naming it.

The plant is the paper actuator 20 % stiffer; the fit of form pressure_ei starts from the base actuator's law at
rest, on which T = (5, 0, 0) N at 115 kPa with 50 g hung has no equilibrium (its load path ends at a limit point:
checked below on the start itself), while the stiffer plant holds it.  No force or pressure noise is stated."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from ancf import Model, StiffnessLaw, presets
from ancf.errors import BellowsError, ConvergenceError
from hardware.static_states import StaticStates
from validation.identification.forms import get_form
from validation.identification.identify import from_measurements, initial_theta

BASE = presets.paper()
LAW = BASE.stiffness
PLANT = BASE.replace(stiffness=StiffnessLaw.polynomial(EA=[1.2 * c for c in LAW.EA_coeffs],
                                                       EI=[1.2 * c for c in LAW.EI_coeffs]))
HARD = ((5.0, 0.0, 0.0), 115e3, 0.49)            # tensions [N], pressure [Pa], hung weight [N]
HARD_LABEL = "T=5,0,0 N p=115 kPa W=0.49 N"


def _states(n_easy: int) -> StaticStates:
    """``n_easy`` states the start can hold and the hard one, measured on the plant (tip σ 20 µm)."""
    pats = [(0, 0, 0), (0, 5, 0), (0, 0, 5), (2.5, 2.5, 0), (0, 2.5, 2.5), (2.5, 0, 2.5), (2.5, 0, 0), (0, 0, 2.5)]
    cases = [(t, p, w) for p, t, w in itertools.product((0.0, 60e3, 115e3), pats, (0.0, 0.49))][:n_easy] + [HARD]
    m = Model(PLANT)
    rng = np.random.default_rng(5)
    T = np.array([c[0] for c in cases], float)
    P = np.array([c[1] for c in cases])
    F = np.array([(0.0, 0.0, -c[2]) for c in cases])
    tips = np.array([m.fk(T[i], P[i], F[i]).tip for i in range(len(cases))]) + rng.normal(0, 2e-5, (len(cases), 3))
    labels = [f"state {i}" for i in range(n_easy)] + [HARD_LABEL]
    return StaticStates(T, P, tips, tip_force=F, tip_position_std=np.full(tips.shape, 2e-5), label=labels)


def test_the_hard_state_has_no_equilibrium_at_the_start():
    form = get_form("pressure_ei", False, True)
    start = Model(form.to_params(initial_theta(form, None, BASE), BASE))
    with pytest.raises(ConvergenceError):
        start.fk(np.array(HARD[0]), HARD[1], np.array([0.0, 0.0, -HARD[2]]), check_limits=False, max_iter=15)


def test_a_state_past_the_starts_limit_point_is_readmitted():
    lines = []
    res = from_measurements(_states(19), base=BASE, forms=["pressure_ei"], heldout_fraction=0.0,
                            progress=lines.append, workers=1)
    f = res.fits["pressure_ei"]
    assert f.readmitted == [HARD_LABEL]
    assert any(HARD_LABEL in line and "no equilibrium" in line for line in lines)
    assert res.to_dict()["fits"]["pressure_ei"]["readmitted_states"] == [HARD_LABEL]
    # the hard state is in the fit: its residual is the size of the others'
    assert f.residuals.shape[0] == 20 and np.linalg.norm(f.residuals[-1, :3]) < 1e-3
    EA_true = float(PLANT.stiffness.EA(1.0))
    assert res.fit.values["EA"] == pytest.approx(EA_true, rel=0.03)


def test_too_few_states_without_it_is_a_typed_error_naming_it():
    # pressure_ei with masses: 9 parameters, 10 states needed; 9 + the hard one leave 9 for the first pass
    with pytest.raises(BellowsError) as info:
        from_measurements(_states(9), base=BASE, forms=["pressure_ei"], heldout_fraction=0.0, workers=1)
    text = str(info.value)
    assert HARD_LABEL in text and "too few" in text
