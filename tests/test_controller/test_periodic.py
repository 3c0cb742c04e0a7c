"""The periodic load's frequency estimate (controller/periodic.py): a sinusoid plus a constant (and tracker-like
noise) is found to a fraction of a percent once a period is recorded; a step, a ramp, a ramp to a hold and
noise alone are refused (no internal model for a load that is not periodic)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ancf.errors import InputError
from controller.periodic import PeriodEstimator, fit_sinusoid


def _feed(est, load, t_end, dt=1e-3, noise=0.0, seed=0):
    """Feed ``load(t)`` (scalar along −z) [N] at 1 kHz; returns the times at which the frequency changed."""
    rng = np.random.default_rng(seed)
    changes = []
    for t in np.arange(0.0, t_end, dt):
        F = np.array([0.0, 0.0, -load(t)]) + rng.normal(0.0, noise, 3)
        if est.add(t, F):
            changes.append(t)
    return changes


@settings(max_examples=25, deadline=None)
@given(f=st.floats(0.1, 2.5), phase=st.floats(0.0, 2 * math.pi), mean=st.floats(-0.5, 0.5),
       amp=st.floats(0.05, 0.5))
def test_fit_recovers_a_sinusoid(f, phase, mean, amp):
    t = np.arange(0.0, 1.5 / f, 0.01)
    y = mean + amp * np.cos(2 * math.pi * f * t + phase)
    f_fit, a, b, c, res = fit_sinusoid(t, y, 0.05, 5.0)
    assert f_fit == pytest.approx(f, rel=1e-3)
    assert math.hypot(b, c) == pytest.approx(amp, rel=1e-2)
    assert res < 1e-3 * amp


@pytest.mark.parametrize("f", [0.125, 1.0, 2.0])
def test_the_paper_load_is_found_after_one_period(f):
    """80 g as 1 − cos (the cyclic experiment) with 3 mN of noise on the estimate: locked within 1.2 periods,
    at the load's frequency within 0.5 %; the fitted phasor's real part is the load's oscillation."""
    A = 0.5 * 9.81 * 0.08
    est = PeriodEstimator()
    changes = _feed(est, lambda t: A * (1 - math.cos(2 * math.pi * f * t)), 1.5 / f, noise=3e-3)
    assert changes and changes[0] <= 1.2 / f
    assert est.frequency_hz == pytest.approx(f, rel=5e-3)
    t = changes[-1]
    ph = est.phasor(t)
    assert abs(ph.real[2] - A * math.cos(2 * math.pi * f * t)) < 0.05 * A     # F_z = −A + A cos: the sign of u
    # aside, the oscillation's size and phase come back


@pytest.mark.parametrize("name,load", [
    ("step", lambda t: 0.3 * (t > 0.2)),
    ("ramp", lambda t: 0.3 * t),
    ("ramp and hold", lambda t: 0.3 * min(t / 0.5, 1.0)),
    ("constant", lambda t: 0.2),
])
def test_non_periodic_loads_are_refused(name, load):
    est = PeriodEstimator()
    assert _feed(est, load, 6.0, noise=3e-3) == [], name
    assert est.frequency_hz is None


def test_refusals():
    with pytest.raises(InputError):
        PeriodEstimator(f_min=2.0, f_max=1.0)
    with pytest.raises(InputError):
        PeriodEstimator(min_amplitude=-1.0)
