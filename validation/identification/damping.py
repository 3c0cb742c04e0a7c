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

Inputs: arrays (t [s], tip (k, 3) [m]); a ``bellows simulate`` CSV (``simulation.csv``: t_s, tip_*_mm); a
run log (``.h5``: samples ``t`` and ``tip``, or ``true_tip`` on a simulated rig when asked).
"""

from __future__ import annotations

import csv
import math
import pathlib
from dataclasses import asdict, dataclass
from typing import Optional

import numpy as np
import scipy.optimize as so
import scipy.stats as st

from ancf.errors import ConfigError, InputError


@dataclass
class DecayFit:
    """A fitted free decay.  frequency_hz f_n [Hz] and damping_ratio ζ [-] with their confidence intervals
    (2,) at ``confidence``; damped_frequency_hz [Hz]; decay_rate σ [1/s]; amplitude [m] (of the first
    sample); direction (3,) the unit direction of the motion; offset_m (3,) the settled tip c [m];
    residual_rms [m]; samples; t_start, t_end [s] the window fitted; alpha_per_s = 2ζω_n and beta_s = 2ζ/ω_n
    with their intervals (2,)."""
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


def fit_free_decay(t, tip, *, t_start: Optional[float] = None, t_end: Optional[float] = None,
                   confidence: float = 0.95) -> DecayFit:
    """Fit a free decay of the tip: ``t`` (k,) [s], ``tip`` (k, 3) [m] (module docstring), over the window
    [t_start, t_end] (default: the whole record).  InputError for records that are not a decay (too short,
    non-finite, no oscillation)."""
    t = np.asarray(t, float)
    tip = np.asarray(tip, float)
    if t.ndim != 1 or tip.shape != (len(t), 3):
        raise InputError(f"need t (k,) and tip (k, 3), got {t.shape} and {tip.shape}")
    if not (0 < confidence < 1):
        raise InputError(f"confidence must be in (0, 1), got {confidence!r}")
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
    X = tip - tip.mean(axis=0)
    u = np.linalg.svd(X, full_matrices=False)[2][0]                   # principal direction of the motion
    if u @ X[0] < 0:
        u = -u
    y = tip @ u
    tau = t - t[0]
    p0 = _start(tau, y)
    scale = max(float(np.ptp(y)), 1e-12)
    res = so.least_squares(lambda p: (_model(p, tau) - y) / scale, p0, jac=lambda p: _jac(p, tau) / scale,
                           method="lm", x_scale="jac")
    if not res.success:
        raise InputError(f"the decay fit did not converge ({res.message})")
    p = res.x
    r = _model(p, tau) - y
    dof = len(y) - 5
    s2 = float(r @ r) / dof
    J = _jac(p, tau)
    try:
        cov = s2 * np.linalg.inv(J.T @ J)
    except np.linalg.LinAlgError:
        raise InputError("the decay is not identifiable from this record (singular fit)") from None
    c, A, B, s, wd = p
    wd = abs(wd)
    wn = math.hypot(wd, s)
    zeta = s / wn
    # delta method: gradients of f_n, ζ, α = 2σ, β = 2σ/ω_n² w.r.t. (σ, ω_d)
    g = {"f": np.array([s / wn, wd / wn]) / (2 * math.pi),
         "z": np.array([wd * wd / wn ** 3, -s * wd / wn ** 3]),
         "a": np.array([2.0, 0.0]),
         "b": np.array([2 / wn ** 2 - 4 * s * s / wn ** 4, -4 * s * wd / wn ** 4])}
    C2 = cov[3:, 3:]
    q = float(st.t.ppf(0.5 + confidence / 2, dof))
    ci = {k: q * math.sqrt(max(float(v @ C2 @ v), 0.0)) for k, v in g.items()}
    f = wn / (2 * math.pi)
    alpha, beta = 2 * s, 2 * s / wn ** 2
    return DecayFit(f, (f - ci["f"], f + ci["f"]), zeta, (zeta - ci["z"], zeta + ci["z"]), wd / (2 * math.pi), s,
                    float(math.hypot(A, B)), u, tip.mean(axis=0) + (c - float(tip.mean(axis=0) @ u)) * u,
                    float(np.sqrt(np.mean(r * r))), len(y), float(t[0]), float(t[-1]), confidence,
                    alpha, (alpha - ci["a"], alpha + ci["a"]), beta, (beta - ci["b"], beta + ci["b"]))


def read_decay(path, *, true_tip: bool = False):
    """(t [s], tip (k, 3) [m], info) from a ``bellows simulate`` CSV or a run log (.h5); ``true_tip``: a
    simulated rig's noise-free tip instead of the tracker's.  info: tensions [N] and pressure [Pa] of the
    last row where the file has them."""
    p = pathlib.Path(path)
    if not p.exists():
        raise InputError(f"{p} does not exist")
    if p.suffix.lower() == ".csv":
        with open(p, newline="") as fh:
            rows = list(csv.DictReader(fh))
        need = ("t_s", "tip_x_mm", "tip_y_mm", "tip_z_mm")
        if not rows or any(k not in rows[0] for k in need):
            raise ConfigError(f"{p}: a decay CSV needs the columns {', '.join(need)} (the `bellows simulate` "
                              "format)")
        try:
            t = np.array([float(r["t_s"]) for r in rows])
            tip = np.array([[float(r[f"tip_{c}_mm"]) for c in "xyz"] for r in rows]) * 1e-3
            tens = [k for k in rows[0] if k.startswith("T") and k.endswith("_N")]
            info = {"tensions": [float(rows[-1][k]) for k in tens],
                    "pressure": float(rows[-1]["pressure_kPa"]) * 1e3 if "pressure_kPa" in rows[0] else None}
        except ValueError as exc:
            raise ConfigError(f"{p}: not a number in the decay CSV ({exc})") from None
        return t, tip, info
    if p.suffix.lower() in (".h5", ".hdf5"):
        from hardware.runlog import read_run_log
        d = read_run_log(p)
        key = "true_tip" if true_tip else "tip"
        if key not in d.samples:
            raise ConfigError(f"{p}: the run log has no '{key}' samples")
        info = {"tensions": d.samples["tension"][-1].tolist() if "tension" in d.samples else None,
                "pressure": float(d.samples["pressure"][-1]) if "pressure" in d.samples else None}
        return np.asarray(d.samples["t"], float), np.asarray(d.samples[key], float), info
    raise InputError(f"{p}: expected a .csv (bellows simulate) or a .h5 run log")
