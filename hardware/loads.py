"""Hidden tip-load profiles F(t) [N] for the simulated rig (the paper's loading protocols, Sec. IV-B, V-D/E).

============  ===========================================================================================
profile       F(t)
============  ===========================================================================================
step          0 until ``t_step``, then ``mass`` along gravity (a weight hung on the tip)
stochastic    piecewise constant: every ``period`` s a new seeded draw, mass ~ U(mass_range) along gravity
              plus lateral components ~ N(0, lateral_std) (Table I's "stochastic tip load")
continuous    0 → ``mass`` linearly over ``ramp_up`` s, back to 0 over ``ramp_down`` s (Sec. V-E, 110 g)
cyclic        mass · ½ (1 − cos 2π f t) (Sec. V-E, 0.125 Hz)
============  ===========================================================================================

Every profile is a pure function of t (deterministic for a seed), so a replay is reproducible.  Each
callable also has ``change_times(t0, t1)``: the times in (t0, t1) at which the load jumps to a new value
(``stochastic``: every ``period``; ``step``: ``t_step``; none for ``none`` and for the continuously varying
``continuous`` and ``cyclic``).  A control run's summary judges the settled tip error per period between
these changes (:mod:`controller.summary`).
"""

from __future__ import annotations

import math
from typing import Callable

import numpy as np

from ancf.errors import InputError

G = 9.81
PROFILES = ("none", "step", "stochastic", "continuous", "cyclic")


def _pos(name, v, allow_zero=False) -> float:
    if isinstance(v, (bool, str)) or v is None:
        raise InputError(f"load profile: {name} must be a number, got {v!r}")
    x = float(v)
    if not math.isfinite(x) or x < 0 or (x == 0 and not allow_zero):
        raise InputError(f"load profile: {name} must be {'>= 0' if allow_zero else '> 0'} and finite, got {v!r}")
    return x


def load_profile(name: str, *, mass: float = 0.05, t_step: float = 1.0, period: float = 5.0,
                 mass_range=(0.02, 0.06), lateral_std: float = 0.03, ramp_up: float = 35.0, ramp_down: float = 15.0,
                 frequency: float = 0.125, seed: int = 0) -> Callable[[float], np.ndarray]:
    """The load profile ``name`` (see the module docstring) as a callable F(t) → (3,) [N].  Masses in kg."""
    if name not in PROFILES:
        raise InputError(f"unknown load profile {name!r}; one of {', '.join(PROFILES)}")
    mass = _pos("mass", mass, allow_zero=True)
    return _with_changes(name, _profile(name, mass, t_step, period, mass_range, lateral_std, ramp_up, ramp_down,
                                        frequency, seed), t_step, period)


def _with_changes(name, fn, t_step, period):
    """Attach ``change_times(t0, t1)`` (the load jumps in (t0, t1) [s]) to the profile ``fn``."""
    if name == "step":
        fn.change_times = lambda t0, t1: [float(t_step)] if t0 < t_step < t1 else []
    elif name == "stochastic":
        def change_times(t0, t1):
            k0 = max(int(math.floor(max(t0, 0.0) / period)) + 1, 1)
            return [k * period for k in range(k0, int(math.ceil(t1 / period)) + 1) if t0 < k * period < t1]
        fn.change_times = change_times
    else:
        fn.change_times = lambda t0, t1: []
    fn.profile = name
    return fn


def _profile(name, mass, t_step, period, mass_range, lateral_std, ramp_up, ramp_down, frequency, seed):
    if name == "none":
        return lambda t: np.zeros(3)
    if name == "step":
        t_step = _pos("t_step", t_step, allow_zero=True)
        return lambda t: np.array([0.0, 0.0, -G * mass if t >= t_step else 0.0])
    if name == "stochastic":
        period = _pos("period", period)
        lo, hi = (_pos("mass_range", x, allow_zero=True) for x in mass_range)
        lateral_std = _pos("lateral_std", lateral_std, allow_zero=True)
        if hi < lo:
            raise InputError(f"load profile: mass_range must be (low, high), got {mass_range}")

        def stochastic(t: float) -> np.ndarray:
            k = int(math.floor(max(t, 0.0) / period))
            rng = np.random.default_rng([int(seed), k])
            m = rng.uniform(lo, hi)
            return np.array([rng.normal(0, lateral_std), rng.normal(0, lateral_std), -G * m])
        return stochastic
    if name == "continuous":
        up, down = _pos("ramp_up", ramp_up), _pos("ramp_down", ramp_down)

        def continuous(t: float) -> np.ndarray:
            m = mass * t / up if t <= up else mass * max(0.0, 1.0 - (t - up) / down)
            return np.array([0.0, 0.0, -G * max(m, 0.0)])
        return continuous
    f = _pos("frequency", frequency)
    return lambda t: np.array([0.0, 0.0, -G * mass * 0.5 * (1.0 - math.cos(2 * math.pi * f * t))])
