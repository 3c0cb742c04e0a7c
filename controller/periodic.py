r"""Online estimate of a periodic load's fundamental frequency, for the dynamic LACC's internal model.

The load estimate F̂(t) (3,) [N] of the observer is sampled every ``sample_dt``; every ``refit_dt`` the samples
of the last ``window`` periods (at most ``max_window`` s) are projected on their principal direction u (the
largest variance) and fitted by y(t) = a + e t + b cos ωt + c sin ωt (the trend e takes up the estimate's
slow drift): linear least squares in (a, e, b, c) for each ω of a log grid over [``f_min``, ``f_max``],
refined twice on a finer grid about the best ω.  A fit is accepted (``frequency_hz``) when

* the window covers at least ``min_cycles`` (default 1) of the fitted period (a ramp or a step is fitted by
  a sinusoid of a period longer than the record: refused) and the fitted sinusoid passes through an
  extremum inside the window (not within its first or last tenth);
* its amplitude √(b² + c²) is at least ``min_amplitude`` [N] (the noise of F̂ lies well below);
* the residual's RMS is at most ``max_residual`` of the amplitude (a load that is no sinusoid plus a
  constant is refused).

A later fit moves the accepted frequency only when it differs by more than ``retune`` and explains the
record clearly better (its residual at most ``better`` × the residual at the accepted frequency).  Without an
accepted fit the frequency is None (the dynamic LACC then runs without its oscillator).  The estimate never
assumes the load's profile: it reads the frequency from F̂ only.  The dynamic LACC uses it until its first
lock and then follows the frequency from its oscillator's phase (:mod:`controller.dynamic_lacc`).

**Verified** (``tests/test_controller/test_periodic.py``): a sinusoid plus a constant is fitted to 0.1 % in
frequency over 1.5 periods (hypothesis, 0.1–2.5 Hz); the cyclic experiment's 1 − cos load with 3 mN noise
is locked within 1.2 periods, within 0.5 %, at 0.125, 1 and 2 Hz; a step, a ramp, a ramp to a hold and a
constant are refused.
"""

from __future__ import annotations

import math
from typing import Optional

import numpy as np

from ancf.errors import InputError

from .errors import number


def fit_sinusoid(t: np.ndarray, y: np.ndarray, f_min: float, f_max: float, grid: int = 120) -> tuple:
    """(f [Hz], a, b, c, residual RMS) of the least-squares fit y ≈ a + e t + b cos 2πft + c sin 2πft over
    f ∈ [f_min, f_max], t from t[0]: the residual on a log grid of ``grid`` points, twice refined on a grid
    of 41 between the best point's neighbours (normal equations, all frequencies at once)."""
    t = np.asarray(t, float) - float(t[0])
    y = np.asarray(y, float)

    def solve(fs):
        arg = 2 * math.pi * np.asarray(fs, float)[:, None] * t[None, :]
        X = np.stack([np.ones_like(arg), np.broadcast_to(t, arg.shape), np.cos(arg), np.sin(arg)], axis=-1)
        XtX = np.einsum("fni,fnj->fij", X, X) + 1e-12 * np.eye(4)
        coef = np.linalg.solve(XtX, np.einsum("fni,n->fi", X, y)[..., None])[..., 0]
        res = np.sqrt(np.maximum(np.mean((np.einsum("fni,fi->fn", X, coef) - y) ** 2, axis=1), 0.0))
        return res, coef

    fs = np.array([f_min]) if grid == 1 else np.geomspace(f_min, f_max, grid)
    for _ in range(3 if grid > 1 else 1):
        res, coef = solve(fs)
        i = int(np.argmin(res))
        f_best = fs[i]
        fs = np.geomspace(fs[max(i - 1, 0)], fs[min(i + 1, len(fs) - 1)], 41)
    a, _, b, c = coef[i]
    return float(f_best), float(a), float(b), float(c), float(res[i])


class PeriodEstimator:
    """The fundamental frequency of a periodic load from the observer's estimate (module docstring).

    Parameters: f_min, f_max [Hz] the range searched; sample_dt, refit_dt [s]; window [periods] and
    max_window [s] of the record fitted; min_cycles [periods] the record must cover; min_amplitude [N];
    max_residual [-] the residual RMS per amplitude accepted; retune [-] the relative change of the accepted
    frequency that moves the internal model, once the fit at the new frequency leaves at most ``better`` of the
    residual at the accepted one."""

    def __init__(self, *, f_min: float = 0.05, f_max: float = 10.0, sample_dt: float = 0.01,
                 refit_dt: float = 0.05, window: float = 2.0, max_window: float = 40.0, min_cycles: float = 1.0,
                 min_amplitude: float = 0.02, max_residual: float = 0.05, retune: float = 0.003, better: float = 0.7):
        self.f_min = number("f_min [Hz]", f_min, strict=True)
        self.f_max = number("f_max [Hz]", f_max, strict=True)
        if not self.f_min < self.f_max:
            raise InputError(f"f_min must be below f_max, got {self.f_min:g} and {self.f_max:g} Hz")
        self.sample_dt = number("sample_dt [s]", sample_dt, strict=True)
        self.refit_dt = number("refit_dt [s]", refit_dt, strict=True)
        self.window = number("window [periods]", window, strict=True)
        self.max_window = number("max_window [s]", max_window, strict=True)
        self.min_cycles = number("min_cycles", min_cycles, strict=True)
        self.min_amplitude = number("min_amplitude [N]", min_amplitude, strict=True)
        self.max_residual = number("max_residual", max_residual, strict=True)
        self.retune = number("retune", retune, strict=True)
        self.better = number("better", better, strict=True)
        self.t: list = []
        self.y: list = []
        self.frequency_hz: Optional[float] = None
        self.amplitude_N = 0.0
        self.fit: Optional[tuple] = None       # (f [Hz], u (3,), complex amplitude at t = 0) of the last change
        self._next_fit = 0.0

    def add(self, t: float, load) -> bool:
        """Record F̂ (3,) [N] at time t [s]; refit when due.  True when the accepted frequency changed."""
        if self.t and t < self.t[-1] + self.sample_dt - 1e-12:
            return False
        self.t.append(float(t))
        self.y.append(np.asarray(load, float).copy())
        span = self.max_window if self.frequency_hz is None else min(self.max_window, self.window / self.frequency_hz)
        while self.t[-1] - self.t[0] > span:
            del self.t[0], self.y[0]
        if t < self._next_fit or len(self.t) < 10:
            return False
        self._next_fit = t + self.refit_dt
        return self._refit()

    def _refit(self) -> bool:
        t, Y = np.array(self.t), np.array(self.y)
        Yc = Y - Y.mean(axis=0)
        u = np.linalg.svd(Yc, full_matrices=False)[2][0]
        span = t[-1] - t[0]
        f_lo = max(self.f_min, self.min_cycles / span)
        if not f_lo < self.f_max:
            return False
        f, a, b, c, res = fit_sinusoid(t, Yc @ u, f_lo, self.f_max)   # b, c about t[0]
        amp = math.hypot(b, c)
        w = 2 * math.pi * f
        peak = (math.atan2(c, b) / w) % (0.5 / f)          # an extremum of b cos + c sin, repeated every half period
        inside = peak + 0.5 / f * np.arange(0, span * 2 * f + 1)
        ok = (amp >= self.min_amplitude and res <= self.max_residual * amp and span * f >= self.min_cycles
              and np.any((inside > 0.1 * span) & (inside < 0.9 * span)))
        new = f if ok else self.frequency_hz
        changed = ok and (self.frequency_hz is None or abs(new / self.frequency_hz - 1) > self.retune)
        if changed and self.frequency_hz is not None and span * self.frequency_hz >= self.min_cycles:
            res_now = fit_sinusoid(t, Yc @ u, self.frequency_hz, self.frequency_hz, grid=1)[4]
            changed = res < self.better * res_now         # the new frequency must explain F̂ clearly better
        if ok:
            self.amplitude_N = amp
            if changed:
                self.frequency_hz = f
                self.fit = (f, u, complex(b, -c) * np.exp(-1j * w * t[0]))
        return changed

    def phasor(self, t: float) -> np.ndarray:
        """(3,) complex [N]: the fitted sinusoid of the last accepted change, u (b − i c) e^{iω(t − t₀)} at time
        t [s] (its real part is the fitted oscillation of F̂ about its mean and trend)."""
        f, u, p0 = self.fit
        return u * p0 * np.exp(2j * math.pi * f * t)
