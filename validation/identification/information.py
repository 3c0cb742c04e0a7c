r"""What the data can tell, measured before a fit: coverage of the loads and the information of each form.

A fit reports intervals from the curvature of its misfit, which is only as good as the model: data that hold
one tip position, or one pressure, fit any of many parameter vectors equally well, and a small error of the
*known* quantities (the weight, a tension offset, friction) moves the fitted stiffness by far more than its
interval says.  Measured: a 20 s closed-loop run on the simulated rig (34 states, all at 60 kPa, the tip within
0.15 mm of one point) gave EI and D_a 19 % off the plant's with 95 % intervals of ±2.4 % and ±10 %.  So before
any fit the data are checked, and what they do not determine is held at its prior (the base actuator's value)
and reported as *not determined*, with the reason.

**Coverage** (:func:`coverage`, no model): the pressure, tension and tip-load ranges the states span against
the actuator's range, and the tip's spread (largest distance from the mean tip).

* tip spread < :data:`ONE_POINT_FRACTION` × L (0.32 mm on a 160 mm actuator): the data hold **one
  configuration**.  Its three coordinates are all they say about the stiffness; loads that vary while the tip
  stays put (a controller holding a target) measure the ratio of the tendons' lever to the load's — geometry,
  not stiffness — and any error in the known loads moves that one position as a stiffness change does.  Every
  parameter of every form is then not determined (the form is refused: nothing is fitted).
* pressure span < :data:`ONE_PRESSURE_FRACTION` of the actuator's pressure range: **one pressure**.  The
  pressure coefficients (``pI1``, ``pI2``, ``pA1``, ``s1``) describe a change with pressure that the data do
  not contain: not determined.

**Information** (:func:`information`): the scaled sensitivity matrix

    S = W ∂p̂/∂(log θ)  (rows: every weighted prediction of every state; columns: parameters),

W = 1/σ the stated noise of each coordinate (or :data:`ASSUMED_NOISE` when the data state none), log θ in
units of each parameter's typical size (:meth:`ModelForm.typical_scale`, so that a signed slope near 0 is
scaled by the stiffness it is a slope of).  With S = U Σ Vᵀ, a unit step along the right singular vector v_k
(a relative change of the parameters by 100 %) moves the predictions by σ_k noise units, so the data fix that
combination to ±1/σ_k (1σ, relative).  A direction with 1/σ_k > :data:`MAX_RELATIVE_SD` (the data fix it to no
better than 10 %) is **not determined**; so is one with σ_k < 1e-7 σ_1 (rank).  The parameters to hold are
chosen greedily: the one with the largest share of the least-determined direction is held at its prior, the
SVD is taken again over the others, until every remaining direction is determined.  S is evaluated at the
starting point (the base actuator) — one equilibrium and one linear solve per state, no fit — and re-checked at
the solution by the fit's own rank and interval tests (:mod:`validation.identification.fit`).

**Masses** (a form with the line and tip mass, :func:`validation.identification.forms.with_masses`): without known
tip loads the weight's sag and the stiffness trade against each other — a heavier, stiffer actuator bends like a
lighter, softer one.  Before the greedy step, when an undetermined direction has more than :data:`MASS_SHARE`
of its weight on the masses, *both* masses are held at the base actuator's values (what its file states), with
that reason, rather than a stiffness; known tip loads (hung masses) at several pressures separate them.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional

import numpy as np

from ancf import ActuatorParams

__all__ = ["Coverage", "coverage", "information", "Information", "ASSUMED_NOISE", "MAX_RELATIVE_SD",
           "ONE_POINT_FRACTION", "ONE_PRESSURE_FRACTION", "PRESSURE_PARAMETERS"]

#: Tip noise [m] assumed when the data state none (a motion-capture tracker's order; stated in every reason).
ASSUMED_NOISE = 1e-4
#: A direction of the parameters is determined when the data fix it to this relative 1σ or better.
MAX_RELATIVE_SD = 0.10
#: Rank: singular values below this fraction of the largest are zero.
RANK_TOL = 1e-7
#: The tip spread (largest distance from the mean tip) below this fraction of the length is one configuration.
ONE_POINT_FRACTION = 0.002
#: A pressure span below this fraction of the actuator's pressure range is one pressure.
ONE_PRESSURE_FRACTION = 0.05
#: Parameters that describe a change with pressure (not determined by states at one pressure).
PRESSURE_PARAMETERS = frozenset({"pI1", "pI2", "pA1", "s1"})
#: The masses of a rig-data fit (:func:`validation.identification.forms.with_masses`) …
MASS_PARAMETERS = frozenset({"line_mass", "tip_mass"})
#: … held together at the base's values when an undetermined direction has more than this share on them.
MASS_SHARE = 0.1


@dataclass
class Coverage:
    """What the states span (SI): pressure_range (lo, hi) [Pa] against actuator_pressure (lo, hi) [Pa];
    tension_span (m,) [N] per tendon against tension_max [N]; tip_force_span (3,) [N]; tip_spread [m] (largest
    distance of a tip from the mean tip); length [m]; n_states; findings: {key: reason} for "one_point" and
    "one_pressure" (empty when the states cover the range)."""
    pressure_range: tuple
    actuator_pressure: tuple
    tension_span: np.ndarray
    tension_max: float
    tip_force_span: np.ndarray
    tip_spread: float
    length: float
    n_states: int
    findings: dict = field(default_factory=dict)

    def summary(self) -> str:
        """One line: the ranges spanned, in the units of the command line."""
        plo, phi = self.pressure_range
        alo, ahi = self.actuator_pressure
        T = ", ".join(f"{t:.2g}" for t in self.tension_span)
        F = ", ".join(f"{f:.2g}" for f in self.tip_force_span)
        return (f"{self.n_states} states: pressure {plo / 1e3:.4g}–{phi / 1e3:.4g} kPa of the {alo / 1e3:.4g}–"
                f"{ahi / 1e3:.4g} kPa range; tension spans ({T}) N of 0–{self.tension_max:g} N; tip load spans ({F}) N; "
                f"tip spread {1e3 * self.tip_spread:.3g} mm")

    def to_dict(self) -> dict:
        return {"pressure_range_kPa": [v / 1e3 for v in self.pressure_range],
                "actuator_pressure_range_kPa": [v / 1e3 for v in self.actuator_pressure],
                "tension_span_N": self.tension_span.tolist(), "tension_max_N": self.tension_max,
                "tip_force_span_N": self.tip_force_span.tolist(), "tip_spread_mm": 1e3 * self.tip_spread,
                "n_states": self.n_states, "findings": dict(self.findings), "summary": self.summary()}


def coverage(obs, base: ActuatorParams) -> Coverage:
    """The loads and tip positions the observations ``obs`` (:class:`~validation.identification.fit.Observations`)
    span against ``base``'s operating range, with the findings of the module docstring."""
    p = np.asarray(obs.pressure, float)
    plo, phi = float(p.min()), float(p.max())
    alo, ahi = float(base.pressure_min), float(base.pressure_max)
    spread = float(np.max(np.linalg.norm(obs.tip - obs.tip.mean(axis=0), axis=1)))
    cov = Coverage((plo, phi), (alo, ahi), np.ptp(obs.tensions, axis=0), float(base.tension_max),
                   np.ptp(obs.tip_force, axis=0), spread, float(base.length), obs.n)
    if spread < ONE_POINT_FRACTION * base.length:
        cov.findings["one_point"] = (f"the tip lies within {1e3 * spread:.2g} mm of one point (< "
                                     f"{1e3 * ONE_POINT_FRACTION * base.length:.2g} mm = {ONE_POINT_FRACTION:.1%} of "
                                     "L): the data hold one configuration, whose position an error of the known loads "
                                     "(weight, tension offsets, friction) moves as a stiffness change does")
    if phi - plo < ONE_PRESSURE_FRACTION * (ahi - alo):
        at = f"at one pressure ({plo / 1e3:.4g} kPa)" if phi - plo < 1.0 else \
            f"within {plo / 1e3:.4g}–{phi / 1e3:.4g} kPa"
        cov.findings["one_pressure"] = (f"all states {at}, < {ONE_PRESSURE_FRACTION:.0%} of the actuator's "
                                        f"{alo / 1e3:.4g}–{ahi / 1e3:.4g} kPa range: no change with pressure is "
                                        "measured")
    return cov


@dataclass
class Information:
    """The information check of one form (:func:`information`).

    held: {parameter: reason} held at the prior; refused: the form has nothing the data determine (every
    parameter held); singular_values (n,) of the scaled sensitivity matrix over every parameter [noise units per
    unit relative change]; relative_sd (n,) = 1/σ_k; directions (n, n) the right singular vectors (rows, over
    ``names``); noise: "stated" or the assumed σ [m]."""
    form: str
    names: tuple
    held: dict
    singular_values: np.ndarray
    relative_sd: np.ndarray
    directions: np.ndarray
    noise: str
    refused: bool = False

    def to_dict(self) -> dict:
        return {"form": self.form, "held_at_prior": dict(self.held), "refused": self.refused,
                "singular_values": self.singular_values.tolist(), "relative_sd_1sigma": self.relative_sd.tolist(),
                "directions": {"names": list(self.names), "rows": self.directions.tolist()}, "noise": self.noise,
                "rule": f"a direction is determined when the data fix it to ≤ {MAX_RELATIVE_SD:.0%} (1σ) and its "
                        f"singular value is ≥ {RANK_TOL:g} × the largest"}


def scaled_sensitivity(J: np.ndarray, weights: np.ndarray, typical: np.ndarray) -> np.ndarray:
    """S (N (3 + 3k), n) = W ∂p̂/∂(log θ): ``J`` (N, 3 + 3k, n) [m per parameter unit], ``weights`` (N, 3 + 3k)
    [1/m], ``typical`` (n,) parameter sizes."""
    n = J.shape[-1]
    return J.reshape(-1, n) * weights.reshape(-1)[:, None] * np.asarray(typical, float)[None, :]


def weak_directions(S: np.ndarray) -> tuple:
    """(σ (n,), Vᵀ (n, n), undetermined (n,) bool) of ``S`` (rows ≥ 0): the singular values (zeros appended
    when there are fewer rows than columns) and which directions are not determined (module docstring)."""
    n = S.shape[1]
    _, sv, Vt = np.linalg.svd(S, full_matrices=True) if S.shape[0] < n else np.linalg.svd(S, full_matrices=False)
    sv = np.concatenate([sv, np.zeros(n - sv.size)])
    top = sv[0] if sv.size and sv[0] > 0 else 1.0
    with np.errstate(divide="ignore"):
        bad = (sv < RANK_TOL * top) | (1.0 / sv > MAX_RELATIVE_SD)
    return sv, Vt, bad


def information(form, J: np.ndarray, weights: np.ndarray, typical: np.ndarray, cov: Coverage,
                noise: str) -> Information:
    """Which parameters of ``form`` the data determine, from the sensitivities ``J`` (N, 3 + 3k, n) at the
    start, the weights (N, 3 + 3k) [1/m] (1/σ), the typical sizes (n,) and the coverage findings (module
    docstring).  ``noise``: how σ was chosen (for the reasons)."""
    names = tuple(form.names)
    S = scaled_sensitivity(J, weights, typical)
    sv, Vt, _ = weak_directions(S)
    with np.errstate(divide="ignore"):
        rel = np.where(sv > 0, 1.0 / np.where(sv > 0, sv, 1.0), np.inf)
    held: dict = {}
    if "one_point" in cov.findings:
        held = {nm: cov.findings["one_point"] for nm in names}
        return Information(form.name, names, held, sv, rel, Vt, noise, refused=True)
    if "one_pressure" in cov.findings:
        held.update({nm: cov.findings["one_pressure"] for nm in names if nm in PRESSURE_PARAMETERS})
    held.update(_masses_held(names, S, held, cov))
    while len(held) < len(names):
        free = [j for j, nm in enumerate(names) if nm not in held]
        s_f, Vt_f, bad = weak_directions(S[:, free])
        if not bad.any():
            break
        k = int(np.flatnonzero(bad)[-1])                   # the least-determined direction
        j = free[int(np.argmax(Vt_f[k] ** 2))]
        share = f"{100 * Vt_f[k, free.index(j)] ** 2:.0f} %"
        if s_f[k] == 0 or s_f[k] < RANK_TOL * max(s_f[0], 1e-300):
            why = f"the data carry no information on the parameter direction it dominates ({share} of it; rank)"
        else:
            why = (f"the data fix the parameter direction it dominates ({share} of it) only to ±{100 / s_f[k]:.3g} % "
                   f"(1σ, noise {noise}; more than {MAX_RELATIVE_SD:.0%})")
        held[names[j]] = why + f"; {cov.summary()}"
    return Information(form.name, names, held, sv, rel, Vt, noise, refused=len(held) == len(names))


def _masses_held(names: tuple, S: np.ndarray, held: dict, cov: Coverage) -> dict:
    """{mass: reason} for the line and tip mass (:data:`MASS_PARAMETERS`) when the data do not determine them:
    some undetermined direction of S over the parameters not yet ``held`` has a share above
    :data:`MASS_SHARE` on the masses — gravity's sag trading against the stiffness.  Both masses are then held
    (at the base actuator's values), not a stiffness: the masses are what the actuator file states."""
    masses = [nm for nm in names if nm in MASS_PARAMETERS and nm not in held]
    if not masses:
        return {}
    free = [j for j, nm in enumerate(names) if nm not in held]
    mj = [free.index(names.index(nm)) for nm in masses]
    s_f, Vt_f, bad = weak_directions(S[:, free])
    share = np.sum(Vt_f[:, mj] ** 2, axis=1)
    weak = bad & (share > MASS_SHARE)
    if not weak.any():
        return {}
    k = int(np.flatnonzero(weak)[-1])
    fixed = "no" if not s_f[k] > 0 else f"±{100 / s_f[k]:.3g} %"
    why = (f"gravity's sag and the stiffness trade against each other in these data: a parameter direction "
           f"{100 * share[k]:.0f} % masses is fixed to {fixed} (1σ, more than {MAX_RELATIVE_SD:.0%}) — known tip "
           f"loads (hung masses) at several pressures determine the masses; {cov.summary()}")
    return {nm: why for nm in masses}


def noise_text(obs) -> str:
    """How the weights of ``obs`` were chosen, for the reasons: the stated σ, or the assumed one."""
    return "as stated" if obs.has_sigma else f"σ = {1e3 * ASSUMED_NOISE:g} mm assumed (the data state none)"


def information_weights(obs) -> np.ndarray:
    """1/σ (N, 3 + 3k) [1/m]: the stated uncertainties, or :data:`ASSUMED_NOISE` where the data state none."""
    w = obs.weights()
    if not obs.has_sigma:
        w = w / ASSUMED_NOISE
    return w


def check_form(form, obs, base: ActuatorParams, theta0, cov: Optional[Coverage] = None) -> Information:
    """:func:`information` of ``form`` for ``obs`` at ``theta0`` (everything else from ``base``): one FK and one
    linear solve per state.  When the start cannot be solved, only the coverage findings apply."""
    from validation.identification.fit import INFEASIBLE, _Evaluator
    cov = coverage(obs, base) if cov is None else cov
    typical = form.typical_scale(np.asarray(theta0, float))
    n = form.n
    try:
        _, _, J = _Evaluator(form, obs, base).evaluate(np.asarray(theta0, float), jacobian=True)
    except INFEASIBLE:
        J = None
    if J is None:      # no sensitivities: the coverage findings only (the fit reports the start's failure)
        held = {nm: cov.findings["one_point"] for nm in form.names} if "one_point" in cov.findings else \
            {nm: cov.findings["one_pressure"] for nm in form.names
             if "one_pressure" in cov.findings and nm in PRESSURE_PARAMETERS}
        return Information(form.name, tuple(form.names), held, np.full(n, np.nan), np.full(n, np.nan),
                           np.full((n, n), np.nan), noise_text(obs), refused=len(held) == n)
    return information(form, J, information_weights(obs), typical, cov, noise_text(obs))
