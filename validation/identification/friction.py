r"""The tendons' friction coefficient μ identified from a pull-through test or from a tension cycle's tip data.

**Pull-through test** (the paper's).  The actuator is held in a fixed shape (e.g. bent at a given pressure and
clamped); one tendon is pulled through by its motor and released — motor tensions T_m,j in protocol order,
up from slack to a peak, then down — and the tension is measured at the motor and, by a load cell, at the
anchor (T_a,j).  With the shape fixed the guides' total wrap W = Σ_k α_k [rad] is fixed (from the model's FK of
the held shape, :func:`ancf.friction.total_wrap`) and the capstan law (docs/friction.md) gives, wherever every
guide slips,

    y_j = ln(T_a,j / T_m,j) = s_j μ W,        s_j = −1 pulling,  +1 releasing.

**Which points slip.**  Pulling from slack every guide slips.  Releasing from the peak T_m,p the guides stick
first — the anchor keeps its tension T_m,p e^{−μW} — and slip once T_m e^{μW} falls below it, i.e. for
T_m < T_m,p e^{−2μW}.  The fit selects the release points with T_m < (1 − δ) T_m,p e^{−2μ̂W} (δ =
:data:`MARGIN`), from the motor tensions and the current μ̂ only, and iterates (μ̂ from the pull branch
first).  Points whose tensions are below :data:`MIN_SNR` standard deviations are left out (their logarithm is
dominated by noise).

**The fit.**  Weighted least squares through the origin in x_j = s_j W:

    μ̂ = Σ w_j x_j y_j / Σ w_j x_j²,   var(μ̂) = 1 / Σ w_j x_j²,   w_j = 1 / ((σ_a/T̂_a,j)² + (σ_m/T_m,j)²)

with the delta-method variance of y_j at the *predicted* anchor tension T̂_a,j = T_m,j e^{s_j μ̂ W} (iterated:
weights from the measured T_a would correlate with the noise).  With stated noises σ_m, σ_a [N] the 95 %
interval is μ̂ ± 1.96 sd; without, the weights are the relative ones (σ_a = σ_m = 1) and the scale comes from
the residuals, s² = Σ w r² / (n − 1), with Student's t (n − 1).  The interval carries the tension noise only,
not an error of W (the held shape's model) — a relative error ε in W is one of ε in μ̂.

**From tip data of a tension cycle** (:func:`fit_tension_cycle`).  The tool points measured along both branches
of a cycle 0 → T_peak → 0 (:meth:`ancf.Model.tension_cycle`) with the other parameters known: μ minimises
Σ |x_meas − x̂(μ)|² by Gauss–Newton on the one parameter (∂x̂/∂μ by central differences), the interval from
the curvature J ᵀJ and the residual scale (Student's t, N − 1 degrees of freedom) — or, with a stated tracker
noise σ [m], from it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import stats

from ancf import Model
from ancf.errors import ConvergenceError, InputError, check_finite, check_scalar
from ancf.friction import pull_through, total_wrap
from ancf.params import TENDON_FRICTION_MAX

#: relative margin of the release branch's slip threshold (module docstring)
MARGIN = 0.05
#: tensions below this many standard deviations are left out of the fit
MIN_SNR = 10.0


@dataclass
class FrictionFit:
    """μ identified with its 95 % interval.

    mu : the estimate [-];  interval : (low, high) [-];  std : its standard deviation [-]
    points : how many data points the fit used;  wrap : W [rad] (pull-through) or None
    basis : "stated noise" | "residuals" (what the interval's scale comes from)
    residual_rms : RMS of the unweighted residuals (ln-ratio [-] or tip [m])
    """
    mu: float
    interval: tuple
    std: float
    points: int
    wrap: float | None
    basis: str
    residual_rms: float

    def contains(self, value: float) -> bool:
        """True when ``value`` lies inside the interval."""
        return self.interval[0] <= value <= self.interval[1]


def _branches(motor: np.ndarray) -> np.ndarray:
    """s_j (k,): −1 while the motor tension rises (pulling), +1 once it falls (releasing); a protocol is one pull
    then one release (InputError otherwise)."""
    d = np.diff(motor)
    peak = int(np.argmax(motor))
    if np.any(d[:peak] < 0) or np.any(d[peak:] > 0) or peak == 0:
        raise InputError("a pull-through protocol rises from slack to one peak motor tension, then falls")
    return np.where(np.arange(motor.size) <= peak, -1.0, 1.0)


def _ls(x, y, w, sigma_known: bool, n: int):
    """Weighted LS through the origin: (μ̂, sd, quantile, basis, unweighted residual RMS)."""
    sxx = float(np.sum(w * x * x))
    mu = float(np.sum(w * x * y)) / sxx
    r = y - mu * x
    if sigma_known:
        return mu, 1.0 / math.sqrt(sxx), float(stats.norm.ppf(0.975)), "stated noise", float(np.sqrt(np.mean(r ** 2)))
    s2 = float(np.sum(w * r * r)) / (n - 1)
    return mu, math.sqrt(s2 / sxx), float(stats.t.ppf(0.975, n - 1)), "residuals", float(np.sqrt(np.mean(r ** 2)))


def fit_pull_through(motor_tensions, anchor_tensions, wrap: float, *, motor_std: float | None = None,
                     anchor_std: float | None = None, iterations: int = 4) -> FrictionFit:
    """μ with its 95 % interval from a pull-through test (module docstring): ``motor_tensions`` and
    ``anchor_tensions`` (k,) [N] in protocol order (one pull from slack, one release), ``wrap`` W [rad] the held
    shape's total wrap, ``motor_std`` / ``anchor_std`` [N] the stated sensor noises (both or neither)."""
    Tm = check_finite("motor_tensions", motor_tensions, None).ravel()
    Ta = check_finite("anchor_tensions", anchor_tensions, (Tm.size,))
    W = check_scalar("wrap", wrap, low=1e-3, high=4 * math.pi, unit="rad")
    if (motor_std is None) != (anchor_std is None):
        raise InputError("state both motor_std and anchor_std [N], or neither")
    known = motor_std is not None
    sm = check_scalar("motor_std", motor_std, low=0.0, unit="N") if known else 1.0
    sa = check_scalar("anchor_std", anchor_std, low=0.0, unit="N") if known else 1.0
    if known and sm == sa == 0:
        raise InputError("motor_std and anchor_std are both 0 N: an interval needs a stated noise")
    s = _branches(Tm)
    floor = MIN_SNR * max(sm, sa) if known else 0.0
    good = (Tm > floor) & (Ta > floor)
    pull = good & (s < 0)
    if pull.sum() < 2:
        raise InputError(f"the pull branch has {int(pull.sum())} points above {floor:g} N: need at least 2")
    y = np.log(np.where(good, Ta, 1.0) / np.where(good, Tm, 1.0))
    use, mu = pull, float(-np.mean(y[pull]) / W)
    for _ in range(iterations):
        Ta_hat = Tm * np.exp(s * mu * W)
        w = 1.0 / ((sa / Ta_hat) ** 2 + (sm / Tm) ** 2) if known else np.ones(Tm.size)
        thresh = (1 - MARGIN) * Tm.max() * math.exp(-2 * max(mu, 0.0) * W)
        use = pull | (good & (s > 0) & (Tm < thresh))
        mu, sd, qt, basis, rms = _ls(s[use] * W, y[use], w[use], known, int(use.sum()))
    lo, hi = mu - qt * sd, mu + qt * sd
    return FrictionFit(mu, (lo, hi), sd, int(use.sum()), W, basis, rms)


def simulate_pull_through(model: Model, q, tendon: int, motor_tensions, *, mu: float | None = None,
                          motor_std: float = 0.0, anchor_std: float = 0.0, seed: int = 0):
    """A pull-through test in the model (:func:`ancf.friction.pull_through`) with Gaussian sensor noise
    ``motor_std`` / ``anchor_std`` [N] (numpy's default_rng(seed)): returns (measured motor tensions (k,) [N],
    measured anchor tensions (k,) [N], W [rad])."""
    Tm = check_finite("motor_tensions", motor_tensions, None).ravel()
    anchor, _codes = pull_through(model, q, tendon, Tm, mu)
    rng = np.random.default_rng(seed)
    return (Tm + rng.normal(0.0, motor_std, Tm.size), anchor + rng.normal(0.0, anchor_std, Tm.size),
            total_wrap(model, q, tendon))


def protocol(peak: float, low: float, points: int) -> np.ndarray:
    """The standard pull-through protocol: ``points`` motor tensions [N] from ``low`` up to ``peak``, then as
    many back down to ``low`` (0 < low < peak)."""
    if not 0 < low < peak or isinstance(points, bool) or not isinstance(points, (int, np.integer)) or points < 3:
        raise InputError(f"protocol needs 0 < low < peak [N] and points ≥ 3, got {low!r}, {peak!r}, {points!r}")
    up = np.linspace(low, peak, points)
    return np.concatenate([up, up[::-1][1:]])


# ------------------------------------------------------------------------------------------------ tip data
def _cycle_tips(model: Model, mu: float, peak, pressure, steps) -> np.ndarray:
    m = Model(model.params.replace(tendon_friction=float(mu)))
    return m.tension_cycle(peak, pressure, steps=steps).tip


def fit_tension_cycle(model: Model, peak_tensions, pressure: float, tips, steps: int, *, mu0: float = 0.1,
                      tip_std: float | None = None, max_iter: int = 12) -> FrictionFit:
    """μ with its 95 % interval from the tool points ``tips`` (2 steps + 1, 3) [m] measured along a tension cycle
    0 → ``peak_tensions`` (m,) [N] → 0 in ``steps`` steps per branch at ``pressure`` [Pa] (the order of
    :meth:`ancf.Model.tension_cycle`), every other parameter of ``model`` held; ``tip_std`` [m] the stated
    tracker noise per coordinate (None: from the residuals).  Module docstring."""
    X = check_finite("tips", tips, (2 * int(steps) + 1, 3)).ravel()
    mu = float(check_scalar("mu0", mu0, low=1e-3, high=TENDON_FRICTION_MAX))
    hi_bound = TENDON_FRICTION_MAX
    for _ in range(max_iter):
        h = 1e-3 * max(mu, 0.01)
        x0 = _cycle_tips(model, mu, peak_tensions, pressure, steps).ravel()
        J = (_cycle_tips(model, mu + h, peak_tensions, pressure, steps).ravel()
             - _cycle_tips(model, mu - h, peak_tensions, pressure, steps).ravel()) / (2 * h)
        jj = float(J @ J)
        if jj == 0:
            raise InputError("the tip data do not depend on μ (no tension cycle?)")
        step = float(J @ (X - x0)) / jj
        new = min(max(mu + step, 0.5 * mu), min(2 * mu, hi_bound))
        if abs(new - mu) < 1e-6 * max(mu, 1e-3):
            mu = new
            break
        mu = new
    else:
        raise ConvergenceError("the μ fit to the tension cycle's tips did not converge", solver="fit_tension_cycle",
                               iterations=max_iter, residual_norm=float("nan"), tolerance=1e-6)
    r = X - _cycle_tips(model, mu, peak_tensions, pressure, steps).ravel()
    n = r.size
    if tip_std is not None:
        sd, qt, basis = float(check_scalar("tip_std", tip_std, low=1e-12, unit="m")) / math.sqrt(jj), \
            float(stats.norm.ppf(0.975)), "stated noise"
    else:
        sd, qt, basis = math.sqrt(float(r @ r) / (n - 1) / jj), float(stats.t.ppf(0.975, n - 1)), "residuals"
    return FrictionFit(mu, (mu - qt * sd, mu + qt * sd), sd, n // 3, None, basis, float(np.sqrt(np.mean(r ** 2))))
