r"""Identification of damping (and a check of the mass) from a free decay of the tip.

A free decay — the tip released from a displaced state, or settling after a step of the load or of the
tendons — is, after its first instants, dominated by the lowest mode in the direction it moves.  Projected
on that direction (the principal direction of the tip's motion, by SVD), the tip obeys

    y(t) = c + e^{−σ τ} (A cos ω_d τ + B sin ω_d τ),    τ = t − t₀,

with ω_d = ω_n √(1 − ζ²), σ = ζ ω_n.  The five parameters (c, A, B, σ, ω_d) are fitted by nonlinear least
squares (:func:`scipy.optimize.least_squares`, started from the zero crossings and the logarithmic
decrement of the peaks); f_n = √(ω_d² + σ²)/2π and ζ = σ/√(ω_d² + σ²) get confidence intervals by the delta
method on the fit's covariance s² (JᵀJ)⁻¹ with Student's t (as the static parameters do, docs/identification.md).

What it gives the model: the damping ratio of the mode as mass-proportional Rayleigh damping
α = 2 ζ ω_n (``rayleigh_alpha_per_s`` in the actuator file; exact for that mode), or stiffness-proportional
β = 2 ζ/ω_n; and the measured natural frequency beside the model's first mode at the state of the test — a
check of the line mass and the stiffness (a mismatch there is not a damping question).

When a record determines nothing.  A least-squares fit returns numbers from any record — a growing
oscillation (σ < 0, a negative ζ), or pure sensor noise (a "frequency" the fit picks out of it, with an
interval as tight as any).  So a fit is returned only when the record holds a free decay; otherwise
:class:`DecayNotDeterminedError` (an :class:`~ancf.errors.InputError`) says why, checked in this order:

1. *No oscillation above the noise.*  The noise is the fit's residual RMS s (it includes any unmodelled
   higher modes, so the test is conservative).  The envelope a(τ) = √(A² + B²) e^{−στ} must reach
   ``min_amplitude_to_noise`` × s (:data:`MIN_AMPLITUDE_TO_NOISE` = 5) and stay above it for at least
   ``min_cycles`` damped periods (:data:`MIN_CYCLES` = 3).  For white noise of RMS s the fitted amplitude
   is O(s) (the largest periodogram line of k samples is ≈ s √(4 ln k / k)); a short burst fitted at the
   start with a large σ stays above 5 s for a fraction of a cycle.
2. *Not a free decay: the oscillation grows* — ζ's whole interval is below 0.
3. *The decay is not determined* — ζ's interval contains 0 (no decay measurable against the noise over
   this window).  The interval's half-width is never taken below the solver's relative tolerance
   (10⁻⁸ of ω_n in σ and ω_d), so a noise-free undamped sine is "not determined" rather than
   ζ = 10⁻¹⁹ ± 10⁻²⁰.

A returned fit states ``amplitude_to_noise`` (the envelope's largest value over s) and
``cycles_above_noise``.

Inputs: arrays (t [s], tip (k, 3) [m]); a ``bellows simulate`` CSV (``simulation.csv``: t_s, tip_*_mm); a
run log (``.h5``: samples ``t`` and ``tip``, or ``true_tip`` on a simulated rig when asked).  Reading is
strict: a file that is not text, a folder, a missing column or a value that is not a finite number (naming
its row and column) is a :class:`~ancf.errors.ConfigError` before any fit.  In a run log, non-finite tip
samples (a tracker that lost the marker) are skipped by the fit.
"""

from __future__ import annotations

import math
import pathlib
from dataclasses import asdict, dataclass
from typing import Optional

import numpy as np
import scipy.optimize as so
import scipy.stats as st

from ancf.errors import ConfigError, InputError


#: the envelope must reach this multiple of the residual noise (module docstring, check 1)
MIN_AMPLITUDE_TO_NOISE = 5.0
#: … and stay above it for at least this many damped periods
MIN_CYCLES = 3.0
#: relative tolerance of the solver: the floor of σ's and ω_d's standard uncertainty, as a fraction of ω_n
_REL_FLOOR = 1e-8


class DecayNotDeterminedError(InputError):
    """A record that does not determine ζ or f_n (module docstring).  ``reason``: ``"noise"`` (no oscillation
    above the noise), ``"growing"`` (not a free decay) or ``"undetermined"`` (ζ's interval contains 0);
    ``amplitude_to_noise`` [-], ``cycles_above_noise`` [-], ``damping_ratio`` [-] and ``damping_ratio_ci`` (2,)
    of the fit that was refused."""

    def __init__(self, message: str, *, reason: str, amplitude_to_noise: float, cycles_above_noise: float,
                 damping_ratio: float, damping_ratio_ci: tuple):
        self.reason = reason
        self.amplitude_to_noise = float(amplitude_to_noise)
        self.cycles_above_noise = float(cycles_above_noise)
        self.damping_ratio = float(damping_ratio)
        self.damping_ratio_ci = tuple(float(x) for x in damping_ratio_ci)
        super().__init__(message)



@dataclass
class DecayFit:
    """A fitted free decay.  frequency_hz f_n [Hz] and damping_ratio ζ [-] with their confidence intervals
    (2,) at ``confidence``; damped_frequency_hz [Hz]; decay_rate σ [1/s]; amplitude [m] (of the first
    sample); direction (3,) the unit direction of the motion; offset_m (3,) the settled tip c [m];
    residual_rms [m]; samples; t_start, t_end [s] the window fitted; alpha_per_s = 2ζω_n and beta_s = 2ζ/ω_n
    with their intervals (2,); amplitude_to_noise [-] the envelope's largest value over the residual RMS and
    cycles_above_noise [-] the damped periods during which the envelope stays above
    ``MIN_AMPLITUDE_TO_NOISE`` × the residual RMS (inf: a noise-free record)."""
    frequency_hz: float
    frequency_ci: tuple
    damping_ratio: float
    damping_ratio_ci: tuple
    damped_frequency_hz: float
    decay_rate: float
    amplitude: float
    direction: np.ndarray
    offset_m: np.ndarray
    residual_rms: float
    samples: int
    t_start: float
    t_end: float
    confidence: float
    alpha_per_s: float
    alpha_ci: tuple
    beta_s: float
    beta_ci: tuple
    amplitude_to_noise: float = math.inf
    cycles_above_noise: float = math.inf

    def to_dict(self) -> dict:
        out = asdict(self)
        for k, v in out.items():
            if isinstance(v, np.ndarray):
                out[k] = v.tolist()
        return out


def _model(p, tau):
    c, A, B, s, w = p
    e = np.exp(-s * tau)
    return c + e * (A * np.cos(w * tau) + B * np.sin(w * tau))


def _jac(p, tau):
    c, A, B, s, w = p
    e = np.exp(-s * tau)
    cw, sw = np.cos(w * tau), np.sin(w * tau)
    osc = A * cw + B * sw
    return np.column_stack([np.ones_like(tau), e * cw, e * sw, -tau * e * osc, e * tau * (-A * sw + B * cw)])


def _start(tau, y):
    """Initial (c, A, B, σ, ω_d) from the zero crossings and the decrement of the peaks."""
    c = float(np.mean(y[len(y) * 3 // 4:]))
    d = y - c
    i = np.where(np.sign(d[:-1]) != np.sign(d[1:]))[0]
    if len(i) < 3:
        raise InputError("the record holds fewer than two half-periods of oscillation: not a free decay "
                         "(or the window is too short / the motion overdamped)")
    tc = tau[i] - d[i] * (tau[i + 1] - tau[i]) / (d[i + 1] - d[i])
    wd = math.pi * (len(tc) - 1) / (tc[-1] - tc[0])
    peaks = [np.abs(d[a:b + 1]).max() for a, b in zip(i[:-1], i[1:])]
    tp = 0.5 * (tc[:-1] + tc[1:])
    sigma = max(-np.polyfit(tp, np.log(np.maximum(peaks, 1e-300)), 1)[0], 1e-6) if len(peaks) >= 2 else 0.1 * wd
    return np.array([c, d[0], sigma * d[0] / wd, sigma, wd])


def _window(t, tip, t_start, t_end):
    """The finite samples of (t (k,) [s], tip (k, 3) [m]) inside [t_start, t_end], checked."""
    t = np.asarray(t, float)
    tip = np.asarray(tip, float)
    if t.ndim != 1 or tip.shape != (len(t), 3):
        raise InputError(f"need t (k,) and tip (k, 3), got {t.shape} and {tip.shape}")
    sel = np.ones(len(t), bool)
    if t_start is not None:
        sel &= t >= t_start
    if t_end is not None:
        sel &= t <= t_end
    sel &= np.all(np.isfinite(tip), axis=1) & np.isfinite(t)
    t, tip = t[sel], tip[sel]
    if len(t) < 20:
        raise InputError(f"only {len(t)} finite samples in the window: a decay fit needs at least 20")
    if np.any(np.diff(t) <= 0):
        raise InputError("the times must increase")
    return t, tip


def _least_squares(tau, y):
    """Parameters p = (c, A, B, σ, ω_d), residuals r (k,) [m] and covariance (5, 5) of the decay fit."""
    p0 = _start(tau, y)
    scale = max(float(np.ptp(y)), 1e-12)
    res = so.least_squares(lambda p: (_model(p, tau) - y) / scale, p0, jac=lambda p: _jac(p, tau) / scale,
                           method="lm", x_scale="jac")
    if not res.success:
        raise InputError(f"the decay fit did not converge ({res.message})")
    p = res.x
    r = _model(p, tau) - y
    s2 = float(r @ r) / (len(y) - 5)
    J = _jac(p, tau)
    try:
        cov = s2 * np.linalg.inv(J.T @ J)
    except np.linalg.LinAlgError:
        raise InputError("the decay is not identifiable from this record (singular fit)") from None
    return p, r, cov


def _half_widths(s, wd, C2, q):
    """Half-widths of the intervals of f_n, ζ, α = 2σ, β = 2σ/ω_n² by the delta method on C2 = cov(σ, ω_d),
    each at least the solver's tolerance (:data:`_REL_FLOOR`)."""
    wn = math.hypot(wd, s)
    g = {"f": np.array([s / wn, wd / wn]) / (2 * math.pi),
         "z": np.array([wd * wd / wn ** 3, -s * wd / wn ** 3]),
         "a": np.array([2.0, 0.0]),
         "b": np.array([2 / wn ** 2 - 4 * s * s / wn ** 4, -4 * s * wd / wn ** 4])}
    floor = _REL_FLOOR * wn
    return {k: q * max(math.sqrt(max(float(v @ C2 @ v), 0.0)), floor * float(np.abs(v).sum()))
            for k, v in g.items()}


def _noise_measures(tau, amp0, s, wd, noise, ratio):
    """(amplitude_to_noise, cycles_above_noise): the envelope amp0 e^{−στ} over ``noise`` at its largest, and
    the damped periods 2π/ω_d during which it stays above ``ratio`` × ``noise``."""
    env = amp0 * np.exp(-s * tau)
    if noise <= 0:
        return math.inf, math.inf
    above = env[:-1] >= ratio * noise
    return float(env.max() / noise), float(wd / (2 * math.pi) * np.sum(np.diff(tau)[above]))


def _check_determined(zeta, zci, snr, cycles, noise, ratio, min_cycles, confidence):
    """Raise :class:`DecayNotDeterminedError` when the fit does not determine ζ (module docstring)."""
    info = dict(amplitude_to_noise=snr, cycles_above_noise=cycles, damping_ratio=zeta, damping_ratio_ci=zci)
    ci = f"{confidence:.0%} interval {zci[0]:.3g} … {zci[1]:.3g}"
    need = (f"a decay needs at least {ratio:g}× the residual noise ({noise * 1e3:.3g} mm RMS) for {min_cycles:g} "
            "periods")
    if not snr >= ratio:
        raise DecayNotDeterminedError(
            f"no oscillation above the noise: the fitted envelope peaks at {snr:.3g}× the residual noise; {need}",
            reason="noise", **info)
    if not cycles >= min_cycles:       # a fit whose envelope collapses within a period (often: no decay at all)
        raise DecayNotDeterminedError(
            f"too few periods above the noise: the fitted envelope stays above {ratio:g}× the residual noise for "
            f"{cycles:.3g} periods only; {need}", reason="noise", **info)
    if zci[1] < 0:
        raise DecayNotDeterminedError(
            f"not a free decay: the oscillation grows (ζ = {zeta:.3g}, {ci}); fit a window where the tip is "
            "released and left alone", reason="growing", **info)
    if zci[0] <= 0:
        raise DecayNotDeterminedError(
            f"the record does not determine the damping: ζ = {zeta:.3g} with a {ci} that contains 0 (no decay "
            "measurable against the noise in this window; record longer or with less noise)",
            reason="undetermined", **info)


def fit_free_decay(t, tip, *, t_start: Optional[float] = None, t_end: Optional[float] = None,
                   confidence: float = 0.95, min_amplitude_to_noise: float = MIN_AMPLITUDE_TO_NOISE,
                   min_cycles: float = MIN_CYCLES) -> DecayFit:
    """Fit a free decay of the tip: ``t`` (k,) [s], ``tip`` (k, 3) [m] (module docstring), over the window
    [t_start, t_end] (default: the whole record).  InputError for records that are not a decay (too short,
    non-finite, no oscillation); :class:`DecayNotDeterminedError` (an InputError) for a fit that does not
    determine ζ: no oscillation of ``min_amplitude_to_noise`` × the noise for ``min_cycles`` periods, a
    growing oscillation, or a ζ interval containing 0."""
    if not (0 < confidence < 1):
        raise InputError(f"confidence must be in (0, 1), got {confidence!r}")
    t, tip = _window(t, tip, t_start, t_end)
    X = tip - tip.mean(axis=0)
    u = np.linalg.svd(X, full_matrices=False)[2][0]                   # principal direction of the motion
    if u @ X[0] < 0:
        u = -u
    y = tip @ u
    tau = t - t[0]
    p, r, cov = _least_squares(tau, y)
    c, A, B, s, wd = p
    wd = abs(wd)
    wn = math.hypot(wd, s)
    zeta = s / wn
    ci = _half_widths(s, wd, cov[3:, 3:], float(st.t.ppf(0.5 + confidence / 2, len(y) - 5)))
    zci = (zeta - ci["z"], zeta + ci["z"])
    noise = math.sqrt(float(r @ r) / (len(y) - 5))
    snr, cycles = _noise_measures(tau, math.hypot(A, B), s, wd, noise, min_amplitude_to_noise)
    _check_determined(zeta, zci, snr, cycles, noise, min_amplitude_to_noise, min_cycles, confidence)
    f = wn / (2 * math.pi)
    alpha, beta = 2 * s, 2 * s / wn ** 2
    return DecayFit(f, (f - ci["f"], f + ci["f"]), zeta, zci, wd / (2 * math.pi), s,
                    float(math.hypot(A, B)), u, tip.mean(axis=0) + (c - float(tip.mean(axis=0) @ u)) * u,
                    float(np.sqrt(np.mean(r * r))), len(y), float(t[0]), float(t[-1]), confidence,
                    alpha, (alpha - ci["a"], alpha + ci["a"]), beta, (beta - ci["b"], beta + ci["b"]),
                    snr, cycles)


def _read_decay_csv(p: pathlib.Path):
    """(t [s], tip (k, 3) [m], info) of a ``bellows simulate`` CSV, every cell a finite number (else a
    :class:`ConfigError` naming file, row and column)."""
    from hardware.static_states import csv_number, read_csv_rows
    numbered = read_csv_rows(p, "decay CSV file")
    need = ("t_s", "tip_x_mm", "tip_y_mm", "tip_z_mm")
    header = [h.strip() for h in numbered[0][1]] if numbered else []
    if len(numbered) < 2 or any(k not in header for k in need):
        raise ConfigError(f"{p}: a decay CSV needs a header with the columns {', '.join(need)} and rows of numbers "
                          "(the `bellows simulate` format)")
    tens = [k for k in header if k.startswith("T") and k.endswith("_N")]
    used = [*need, *tens, *(["pressure_kPa"] if "pressure_kPa" in header else [])]
    at = {k: header.index(k) for k in used}
    cols = {k: [] for k in used}
    for line, row in numbered[1:]:
        if len(row) != len(header):
            raise ConfigError(f"{p}: row {line} has {len(row)} cells, the header {len(header)}")
        for k in used:
            cols[k].append(csv_number(p, row[at[k]].strip(), line, k))
    t = np.array(cols["t_s"])
    tip = np.column_stack([cols[f"tip_{c}_mm"] for c in "xyz"]) * 1e-3
    info = {"tensions": [cols[k][-1] for k in tens],
            "pressure": cols["pressure_kPa"][-1] * 1e3 if "pressure_kPa" in cols else None}
    return t, tip, info


def read_decay(path, *, true_tip: bool = False):
    """(t [s], tip (k, 3) [m], info) from a ``bellows simulate`` CSV or a run log (.h5); ``true_tip``: a
    simulated rig's noise-free tip instead of the tracker's.  info: tensions [N] and pressure [Pa] of the
    last row where the file has them.  A file that is not what its name says (binary content, a folder, a
    truncated HDF5 file) or a CSV cell that is not a finite number is a :class:`ConfigError` naming it."""
    from hardware.static_states import check_data_file
    p = pathlib.Path(path)
    if p.suffix.lower() not in (".csv", ".h5", ".hdf5"):
        raise InputError(f"{p}: expected a .csv (bellows simulate) or a .h5 run log")
    p = check_data_file(p, "decay record")
    if p.suffix.lower() == ".csv":
        return _read_decay_csv(p)
    from hardware.runlog import read_run_log
    d = read_run_log(p)
    key = "true_tip" if true_tip else "tip"
    if key not in d.samples:
        raise ConfigError(f"{p}: the run log has no '{key}' samples")
    info = {"tensions": d.samples["tension"][-1].tolist() if "tension" in d.samples and len(d.samples["tension"])
            else None,
            "pressure": float(d.samples["pressure"][-1]) if "pressure" in d.samples and len(d.samples["pressure"])
            else None}
    return np.asarray(d.samples["t"], float), np.asarray(d.samples[key], float), info
