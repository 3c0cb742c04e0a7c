r"""The fit: least squares of the reduced model's equilibria against observed static states.

Given observed states i (loads T_i, p_i, F_i; tip position and optionally marker positions along the
body, each with its standard deviation σ) and a model form θ ↦ ActuatorParams (:mod:`validation.identification.forms`),
minimise

    Σ_i ‖(p̂_i(θ) − p_i) / σ_i‖²,   p̂_i(θ) = tip / markers of the equilibrium FK(T_i, p_i, F_i; θ),

with :func:`scipy.optimize.least_squares` (trust-region reflective, bounds from the form) and the exact
Jacobian ∂p̂/∂θ = −J_p H⁻¹ ∂Q/∂θ at each equilibrium (:mod:`validation.identification.forms`).  Each FK warm-starts from
the state's previous equilibrium.

Uncertainty (reported for every parameter):

* covariance  Cov(θ) = s² (JᵀJ)⁻¹ with J the whitened Jacobian at the optimum — each state's residuals
  whitened by its covariance: the stated tip/marker σ's plus the stated noise of the tensions, pressure and
  tip load propagated through the model's input sensitivities (errors in variables,
  :mod:`validation.identification.uncertainty`; the whitening is recomputed at the optimum and the fit
  repeated until θ stops moving) — and s² = RSS/(n − k) when the data carry no stated uncertainties
  (``absolute_sigma=False``: FEM data, whose misfit is model error), or s² = max(1, RSS/(n − k)) when they
  do (``absolute_sigma=True``: measured data with known σ; a reduced χ² above 1 is misfit the stated noise
  does not explain — model-form error — and widens the intervals, never narrows them);
* 95 % confidence intervals θ ± t₀.₉₇₅(n − k) √Cov_jj (the normal quantile with absolute σ and χ²/dof ≤ 1);
  derived values (``a``, ``b``, ``EA``, ``EI``, ``D_a``, ``D_eff``) by the delta method through their
  closed-form maps; ``FitResult.interval_basis`` says in words what the intervals contain;
* the correlation matrix of θ.

Identifiability: a parameter is *not identifiable* when the data do not determine it — (1) it has a share
> 1 % in a direction of the column-scaled, row-equilibrated Jacobian whose singular value is below 1e-7 of the
largest (:func:`null_share`)
(rank deficiency; e.g. D_eff without any pressure state), or (2) its 95 % CI is wider than its value
(|half-width| > |value|; not for the signed parameters ``SIGNED``, for which 0 is a meaningful value).  The
columns of (1) are scaled by a fixed typical size of each parameter
(:meth:`~validation.identification.forms.ModelForm.typical_scale`: its starting value, or for a signed slope the size of the
stiffness it is a slope of), never by the fitted value, so the verdict is a property of the data: a slope
whose true value is 0 is as identifiable as one of 1e-6 or 1000.  Such a parameter is held at its *first-pass optimum* (recorded in
``FitResult.held`` / ``held_at`` and in fit.json and the actuator file), the others are refitted without it,
and it is reported as not identifiable, never as a number.  The intervals of the others
(``FitResult.intervals`` says which):

* held by rule (2): *marginal* — their block of the first-pass covariance, which includes the held
  parameter's uncertainty (the conditional covariance given the held value is narrower and undercovers
  when they are correlated with it);
* held by rule (1): *conditional on the held value* — the data carry no information along the held
  direction, so no interval can include it; a parameter with a share > 1 % in that direction is itself
  held.

The refit after holding parameters starts from the first pass's equilibria (warm starts), not cold: a state
reached only along the first pass's path stays reachable.

Too few data.  With fewer states than the free parameters + ``MIN_SPARE_STATES`` or fewer residual degrees
of freedom than ``MIN_DOF`` (weighted residuals − free parameters) a fit is an interpolation: its residuals
say nothing about its error and its intervals are meaningless (two states can be matched exactly by a wrong
D_eff).  Then every parameter and derived value is reported as not identifiable, with that reason in
``FitResult.reasons``, and no interval is given.

Infeasible trial parameters.  A trial θ of the optimiser for which some state has no verified equilibrium
(:class:`~ancf.errors.ConvergenceError`, :class:`~ancf.errors.UnstableEquilibriumError`,
:class:`~ancf.errors.CollapsedStateError`, or parameters the model refuses: ``InputError``/``ConfigError``)
is *infeasible*: the residual function answers it with non-finite residuals, which scipy's trust-region
reflective method rejects, shrinking the trust region to a quarter of the step (scipy/optimize/_lsq/trf.py:
``if not np.all(np.isfinite(f_new)): Delta = 0.25 * step_h_norm; continue``).  The warm starts are only
updated from a θ whose states all solved.  At the initial θ the same failure is an error (scipy needs finite
residuals there): the fit cannot start, and the error — the first failure's type — names every state without an
equilibrium there, each with its own failure, and the starting parameters (attributes ``failed_states``,
``parameters``).  Those states are then left out of a first pass and re-admitted from its optimum
(``FitResult.readmitted``: a state past a limit point of the start — a start softer than the actuator, a
pressure near the maximum with high tensions — is reached once the parameters moved); the error stands, with
the reason added, when too few states remain without them or when they have no equilibrium at that optimum
either.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Optional, Sequence

import numpy as np
import scipy.optimize as so

from ancf import ActuatorParams, Model
from ancf.errors import (
    CollapsedStateError,
    ConfigError,
    ConvergenceError,
    InputError,
    UnstableEquilibriumError,
)
from ancf.shear import offset as shear_offset

from validation.identification.forms import MASS_NAMES, ModelForm, distance_column, position_matrix
from validation.identification.uncertainty import (WEIGHT_ITERATIONS, WEIGHT_RTOL, diagonal_whitening, misfit,
                                                   state_covariance, variance_scale, whiten, whitening)

__all__ = ["Observations", "FitResult", "fit", "predict", "prior_result"]

RANK_TOL = 1e-7
NULL_SHARE = 0.01
#: A fit claims nothing (every parameter not identifiable) with fewer states than free parameters + this …
MIN_SPARE_STATES = 1
#: … or with fewer residual degrees of freedom (weighted residuals − free parameters) than this.
MIN_DOF = 5
#: Weighted residual returned for a trial step whose equilibria cannot be solved: non-finite, so scipy's trf
#: rejects the step and shrinks its trust region (module docstring).
REJECTED_RESIDUAL = np.inf
#: equilibria of this many recent feasible θ's are kept by the fit's evaluator (restarts of a θ seen before)
STATES_KEPT = 64
#: Failures of a trial θ that make it infeasible (the step is rejected) rather than end the fit.
INFEASIBLE = (ConvergenceError, UnstableEquilibriumError, CollapsedStateError, InputError, ConfigError)
#: Failures of one state's FK that a cold start from the straight reference may avoid.
_RETRY = (ConvergenceError, UnstableEquilibriumError, CollapsedStateError)
#: Newton iterations an FK of a fit may take (the warm start's and the last load step's; ancf's default is 60).
#: Measured on the default design's quick fits: the FKs that did not converge were trial θ past a fold of the
#: model, whose last load step drifted for all 60 iterations, in a cascade of shrinking load steps — 68 % of
#: the fits' Newton iterations; 99 % of the warm starts that converged took ≤ 5 iterations, the rest falls back
#: to load stepping (the same equilibria: the fitted θ agree to 6 digits with 60, 25 and 15).  Fits of the quick
#: report: 27 s at 60, 20 s at 25, 17 s at 15.
FIT_FK_MAX_ITER = 15
#: Relative tolerances (x, f, gradient) of the least squares.  Measured on 38 informative synthetic states
#: (0–100 kPa, tensions, known loads; paper, separate, pressure_ei): 1e-13 took 9337 FK solves, 1e-10 4894, and
#: moved no parameter by more than 2e-4 of its 95 % half-width.
FIT_TOL = 1e-10
#: Signed parameters (slopes, intercepts) for which zero is a meaningful value: rule (2) of the module
#: docstring (CI wider than the value) does not apply to them.
SIGNED = frozenset({"a", "b", "beta", "sA", "sI", "pI1", "pI2", "pA1", "s0", "s1"})


@dataclass
class Observations:
    """Observed static states (SI).  N states, m tendons, k markers.

    tensions (N, m) [N]; pressure (N,) [Pa]; tip_force (N, 3) [N]; gravity (N,) bool; tip (N, 3) [m];
    tip_std (N, 3) [m] or None; markers (N, k, 3) [m] or None with marker_s (k,) [m] their undeformed arc
    lengths and markers_std; labels (N,).  The stated noise of the inputs (each None or ≥ 0): tensions_std
    (N, m) [N], pressure_std (N,) [Pa], tip_force_std (N, 3) [N]; propagated to the predictions by the fit
    (:mod:`validation.identification.uncertainty`).
    """
    tensions: np.ndarray
    pressure: np.ndarray
    tip_force: np.ndarray
    gravity: np.ndarray
    tip: np.ndarray
    tip_std: Optional[np.ndarray] = None
    markers: Optional[np.ndarray] = None
    marker_s: Optional[np.ndarray] = None
    markers_std: Optional[np.ndarray] = None
    labels: list = field(default_factory=list)
    tensions_std: Optional[np.ndarray] = None
    pressure_std: Optional[np.ndarray] = None
    tip_force_std: Optional[np.ndarray] = None

    def __post_init__(self):
        self.tensions = np.atleast_2d(np.asarray(self.tensions, float))
        N = self.tensions.shape[0]
        self.pressure = np.asarray(self.pressure, float).reshape(N)
        self.tip_force = np.asarray(self.tip_force, float).reshape(N, 3)
        self.gravity = np.asarray(self.gravity, bool).reshape(N)
        self.tip = np.asarray(self.tip, float).reshape(N, 3)
        for name in ("tensions", "pressure", "tip_force", "tip"):
            if not np.all(np.isfinite(getattr(self, name))):
                raise InputError(f"observations: {name} must be finite (NaN/inf found)")
        if self.markers is not None:
            self.markers = np.asarray(self.markers, float)
            self.marker_s = np.asarray(self.marker_s, float)
            if self.markers.shape != (N, self.marker_s.size, 3):
                raise InputError(f"observations: markers must have shape (N, k, 3), got {self.markers.shape}")
        if not self.labels:
            self.labels = [f"state {i}" for i in range(N)]
        for name, like in (("tensions_std", self.tensions), ("pressure_std", self.pressure),
                           ("tip_force_std", self.tip_force)):
            v = getattr(self, name)
            if v is None:
                continue
            try:
                a = np.broadcast_to(np.asarray(v, float), like.shape).copy()
            except ValueError:
                raise InputError(f"observations: {name} must broadcast to {like.shape}, got shape "
                                 f"{np.shape(v)}") from None
            if not np.all(np.isfinite(a) & (a >= 0)):
                raise InputError(f"observations: {name} must be finite and >= 0")
            setattr(self, name, a)

    @property
    def n(self) -> int:
        return self.tensions.shape[0]

    @property
    def has_sigma(self) -> bool:
        return self.tip_std is not None

    @property
    def has_input_sigma(self) -> bool:
        """Whether any input (tension, pressure, tip load) has a stated noise > 0."""
        return any(v is not None and np.any(v > 0) for v in (self.tensions_std, self.pressure_std,
                                                              self.tip_force_std))

    def input_std(self) -> np.ndarray:
        """(N, m + 4) standard deviations of the inputs u = (T_1 … T_m [N], p [Pa], F_x, F_y, F_z [N]); 0 where
        none is stated."""
        m = self.tensions.shape[1]
        out = np.zeros((self.n, m + 4))
        if self.tensions_std is not None:
            out[:, :m] = self.tensions_std
        if self.pressure_std is not None:
            out[:, m] = self.pressure_std
        if self.tip_force_std is not None:
            out[:, m + 1:] = self.tip_force_std
        return out

    def subset(self, idx) -> "Observations":
        idx = np.arange(self.n)[idx]
        pick = lambda a: None if a is None else a[idx]      # noqa: E731
        return Observations(self.tensions[idx], self.pressure[idx], self.tip_force[idx], self.gravity[idx],
                            self.tip[idx], pick(self.tip_std), pick(self.markers), self.marker_s,
                            pick(self.markers_std), [self.labels[i] for i in idx], pick(self.tensions_std),
                            pick(self.pressure_std), pick(self.tip_force_std))

    def weights(self) -> np.ndarray:
        """1/σ for every residual entry, stacked per state as [tip (3), markers (3k)]."""
        k = 0 if self.markers is None else self.marker_s.size
        w = np.ones((self.n, 3 + 3 * k))
        if self.tip_std is not None:
            sd = np.broadcast_to(self.tip_std, (self.n, 3))
            if np.any(sd <= 0):
                raise InputError("observations: tip_std must be > 0")
            w[:, :3] = 1.0 / sd
        if k and self.markers_std is not None:
            sd = np.broadcast_to(self.markers_std, (self.n, k, 3)).reshape(self.n, 3 * k)
            if np.any(sd <= 0):
                raise InputError("observations: markers_std must be > 0")
            w[:, 3:] = 1.0 / sd
        elif k and self.tip_std is not None:
            w[:, 3:] = w[:, :1]
        return w


@dataclass
class FitResult:
    """Outcome of :func:`fit` for one model form (SI; see the module docstring).

    theta (n,), names, units; cov (n, n) with NaN rows for parameters that are not identifiable;
    ci95 {name: (lo, hi)}; identifiable {name: bool}; correlation (n, n); values / values_ci95 /
    values_identifiable: the same for the derived, reported values; residuals (N, 3 + 3k) [m]
    (prediction − observation); params: the ActuatorParams at θ; rms_tip [m]; rss (weighted);
    dof; s2 (variance scale used); singular_values (of the column-scaled Jacobian); nfev; rejected: trial
    parameter vectors answered as infeasible (module docstring), summed over the refit; reasons: {name: why
    it is not identifiable} for the parameters and values that are not; held: {name: value} of the parameters
    held in the fit, held_at: {name: "first-pass optimum" | "base actuator's value" (a mass) | "value given to the fit"}; intervals: what the
    intervals are ("full", "marginal …", "conditional on the held value(s) of …", "none: too few data …").
    """
    form: ModelForm
    theta: np.ndarray
    cov: np.ndarray
    ci95: dict
    identifiable: dict
    correlation: np.ndarray
    values: dict
    values_ci95: dict
    values_identifiable: dict
    residuals: np.ndarray
    params: ActuatorParams
    rms_tip: float
    rss: float
    dof: int
    s2: float
    singular_values: np.ndarray
    nfev: int
    message: str = ""
    rejected: int = 0
    reasons: dict = field(default_factory=dict)
    held: dict = field(default_factory=dict)
    held_at: dict = field(default_factory=dict)
    intervals: str = "full"
    #: what the intervals contain: the stated noise (tip, markers, inputs propagated) and any χ² scaling
    #: (:mod:`validation.identification.uncertainty`)
    interval_basis: str = ""
    #: "" or the warning that the form does not fit the data within their stated noise
    #: (:func:`validation.identification.uncertainty.misfit`)
    misfit: str = ""
    #: labels of the states without an equilibrium at the start: fitted first without them, then re-admitted
    #: from that optimum (:func:`_fit_readmitting`); empty when every state solved at the start
    readmitted: list = field(default_factory=list)

    @property
    def chi2_per_dof(self) -> float:
        """The reduced χ² = rss / dof of the whitened residuals (≈ 1 when the stated noise explains them)."""
        return float(self.rss) / max(int(self.dof), 1)

    @property
    def names(self) -> tuple:
        return self.form.names

    def tip_errors(self) -> np.ndarray:
        """‖tip prediction − observation‖ per state [m]."""
        return np.linalg.norm(self.residuals[:, :3], axis=1)


class _Evaluator:
    """FK of every observed state at θ, with warm starts, and the exact sensitivities."""

    def __init__(self, form: ModelForm, obs: Observations, base: ActuatorParams):
        self.form, self.obs, self.base = form, obs, base
        self.q: list = [None] * obs.n
        self._cache_theta = None
        self._cache = None
        self.nfev = 0
        self.rejected = 0          # trial θ answered as infeasible
        # the equilibria of the last feasible θ's (θ bytes → states): a θ evaluated again — the optimiser's
        # result after other trials — restarts from its own states, not from the last trial's (near a fold of
        # the model a warm start from another θ's equilibrium can converge to the saddle branch: measured on
        # T = 5/0/0 N at 0 kPa, the pressure_ei fit's optimum)
        self._states: dict = {}

    def _models(self, theta):
        params = self.form.to_params(theta, self.base)
        m_g = Model(params)
        m_0 = m_g if not np.any(params.gravity) else Model(params.replace(gravity=(0.0, 0.0, 0.0)))
        return params, m_g, m_0

    def evaluate(self, theta, jacobian: bool = True, all_failures: bool = False):
        """(params, predictions (N, 3 + 3k), ∂predictions/∂θ (N, 3 + 3k, n) or None) at θ.  A state without a
        verified equilibrium raises its typed error (``all_failures``: after trying every state, naming all
        that failed — the start of a fit, :func:`_start_failure`).

        The Jacobian of a θ whose equilibria were just solved (scipy asks for the residuals, then for the
        Jacobian at the same accepted θ) reuses them: one linear solve per state, no new FK
        (:meth:`_sensitivities`)."""
        theta = np.asarray(theta, float)
        if self._cache_theta is not None and np.array_equal(theta, self._cache_theta):
            params, pred, J, models, qs = self._cache
            if jacobian and J is None:
                J = self._sensitivities(theta, models, qs)
                self._cache = (params, pred, J, models, qs)
            return params, pred, J
        self.nfev += 1
        params, models, qs, pred = self._solve(theta, all_failures)
        J = self._sensitivities(theta, models, qs) if jacobian else None
        self._cache_theta, self._cache = theta.copy(), (params, pred, J, models, qs)
        return params, pred, J

    def _solve(self, theta, all_failures: bool):
        """(params, (model with gravity, model without), equilibria q per state, predictions (N, 3 + 3k)) at θ,
        each FK warm-started from the state's last equilibrium; committed as the warm starts when every state
        solved."""
        obs, form = self.obs, self.form
        try:
            params, m_g, m_0 = self._models(theta)
        except (InputError, ConfigError) as exc:
            raise type(exc)(f"the model refuses the {form.name} parameters ({_parameter_text(form, theta)}): "
                            f"{exc}") from None
        k = 0 if obs.markers is None else obs.marker_s.size
        S = None if k == 0 else position_matrix(params.n_elements, params.length, obs.marker_s)
        pred = np.zeros((obs.n, 3 + 3 * k))
        own = self._states.get(theta.tobytes())
        if own is not None:
            self.q = list(own)
        q_new = list(self.q)          # committed only when every state solved (warm starts of a feasible θ)
        failures = []
        for i in range(obs.n):
            model = m_g if obs.gravity[i] else m_0
            eq, err = self._fk(model, i)
            if eq is None:
                failures.append((obs.labels[i], err, i))
                if all_failures:
                    continue
                raise _retyped(err, f"FK of state '{obs.labels[i]}' failed for {form.name} parameters "
                                    f"{_parameter_text(form, theta)}: {err}") from None
            q_new[i] = eq.q
            pred[i, :3] = eq.tip
            if k:
                pred[i, 3:] = S @ eq.q
        if failures:
            raise _start_failure(form, theta, failures, obs.n)
        self.q = q_new
        self._states[theta.tobytes()] = list(q_new)
        if len(self._states) > STATES_KEPT:
            self._states.pop(next(iter(self._states)))
        return params, (m_g, m_0), list(q_new), pred

    def _fk(self, model, i: int):
        """(equilibrium or None, the failure) of state i, warm-started from its last equilibrium."""
        T, p, F = self.obs.tensions[i], self.obs.pressure[i], self.obs.tip_force[i]
        err = None
        for q0 in ((self.q[i], None) if self.q[i] is not None else (None,)):
            try:
                return model.fk(T, p, F, q0=q0, check_limits=False, max_iter=FIT_FK_MAX_ITER), None
            except _RETRY as exc:
                err = exc
                if isinstance(exc, ConvergenceError):
                    # the failed FK already stepped the load up from the straight reference (ancf Model.fk):
                    # a cold retry would repeat that stepping exactly (measured: a third of the fits' time)
                    break
        return None, err

    def input_jacobian(self, theta) -> np.ndarray:
        """∂predictions/∂u (N, 3 + 3k, m + 4) at θ, u = (tensions, pressure, tip load) of each state
        (:func:`validation.identification.uncertainty.input_jacobian`), at the equilibria of θ (solved if not
        cached)."""
        from validation.identification.uncertainty import input_jacobian
        self.evaluate(theta, jacobian=False)
        _, _, _, (m_g, m_0), qs = self._cache
        obs = self.obs
        k = 0 if obs.markers is None else obs.marker_s.size
        S = None if k == 0 else position_matrix(m_g.params.n_elements, m_g.params.length, obs.marker_s)
        return np.stack([input_jacobian(m_g if obs.gravity[i] else m_0, qs[i], obs.tensions[i], obs.pressure[i],
                                        obs.tip_force[i], S) for i in range(obs.n)])

    def _sensitivities(self, theta, models, qs) -> np.ndarray:
        """∂predictions/∂θ (N, 3 + 3k, n) at the equilibria ``qs``: ∂z/∂θ = −H⁻¹ ∂Q/∂θ, one linear solve per
        state (the implicit-function theorem at the equilibrium; no Newton solve)."""
        obs, form = self.obs, self.form
        m_g, m_0 = models
        k = 0 if obs.markers is None else obs.marker_s.size
        S = None if k == 0 else position_matrix(m_g.params.n_elements, m_g.params.length, obs.marker_s)
        J = np.zeros((obs.n, 3 + 3 * k, form.n))
        for i in range(obs.n):
            model = m_g if obs.gravity[i] else m_0
            T, p, F = obs.tensions[i], obs.pressure[i], obs.tip_force[i]
            q = qs[i]
            ev = model.evaluate(q, T, p, F)
            H = model.reduce_mat(ev.K)
            dQ = form.dQ_dtheta(model, q, p, theta)
            if form.fits_distance:
                dQ[:, form.names.index("d")] = distance_column(model, q, T, p, F)
            dz = -np.linalg.solve(H, model.reduce_vec(dQ.T).T)          # (nz, n)
            Jp = model.reduce_vec(model.tool_jacobian(q, p, F))         # (3, nz): p_end + shear offset
            J[i, :3] = Jp @ dz
            if form.shear is not None:        # ∂x/∂s = P⊥F_tot times ∂s/∂θ (validation.identification.forms docstring)
                PF = shear_offset(q[-3:], 1.0, model.total_tip_load(F))
                J[i, :3] += np.outer(PF, form.shear_columns(theta, p))
            if form.fits_masses and model.params.shear_compliance:
                # the tip weight's own shear offset s(p) P⊥ g per kg (linear in the tip load)
                J[i, :3, -1] += model.shear_offset(q, p, F + model._g) - model.shear_offset(q, p, F)
            if k:
                J[i, 3:] = model.reduce_vec(S) @ dz
        return J


def _parameter_text(form: ModelForm, theta) -> str:
    """'EA = 767.2 N, EI = 0.0839 N m^2, …': a form's parameters with their SI units."""
    return ", ".join(f"{nm} = {float(v):.6g} {u}".rstrip(" -") for nm, v, u in zip(form.names, theta, form.units))


def _retyped(err: Exception, message: str) -> Exception:
    """``err``'s type (ConvergenceError, UnstableEquilibriumError, CollapsedStateError) with ``message``."""
    if isinstance(err, ConvergenceError):
        return ConvergenceError(message, solver="fit", iterations=err.iterations, residual_norm=err.residual_norm,
                                tolerance=err.tolerance, history=err.history)
    if isinstance(err, UnstableEquilibriumError):
        return UnstableEquilibriumError(message, solver="fit", min_eigenvalue=err.min_eigenvalue)
    return CollapsedStateError(message, solver="fit", stretch=getattr(err, "stretch", float("nan")))


def _start_failure(form: ModelForm, theta, failures: list, n_states: int) -> Exception:
    """The typed error of a fit that cannot start: every state without an equilibrium at the starting θ, with
    its own failure, and the parameters (the type is the first failure's; ``failed_states`` [(label, text)]
    and ``parameters`` {name: value [SI]} as attributes)."""
    listed = "; ".join(f"'{label}' ({type(e).__name__}: {e})" for label, e, _ in failures)
    message = (f"the fit of form {form.name} cannot start: {len(failures)} of {n_states} states have no "
               f"verified equilibrium at the starting parameters ({_parameter_text(form, theta)}): {listed}. "
               "Start closer to the data (other starting values) or leave these states out")
    exc = _retyped(failures[0][1], message)
    exc.start_message = message
    exc.failed_states = [(label, f"{type(e).__name__}: {e}") for label, e, _ in failures]
    exc.failed_index = [i for _, _, i in failures]
    exc.parameters = {nm: float(v) for nm, v in zip(form.names, theta)}
    return exc


def _observed(obs: Observations) -> np.ndarray:
    k = 0 if obs.markers is None else obs.marker_s.size
    out = np.zeros((obs.n, 3 + 3 * k))
    out[:, :3] = obs.tip
    if k:
        out[:, 3:] = obs.markers.reshape(obs.n, 3 * k)
    return out


def fit(form: ModelForm, obs: Observations, base: ActuatorParams, theta0, *, absolute_sigma: Optional[bool] = None,
        fixed: Sequence[str] = (), max_nfev: int = 200, scale=None, _refit: bool = True,
        _marginal: Optional[np.ndarray] = None, _warm: Optional[list] = None, _readmit: bool = True) -> FitResult:
    """Fit ``form`` to ``obs`` from ``theta0`` (everything else from ``base``); see the module docstring.

    ``absolute_sigma`` (default: whether ``obs`` states uncertainties) — treat σ as known.
    ``fixed`` — parameter names held at ``theta0``.
    ``scale`` — typical size of each parameter (default :meth:`ModelForm.typical_scale` of ``theta0``): the
    column scaling of the identifiability test and the optimiser's step scale.
    Raises :class:`~ancf.errors.InputError` on inconsistent inputs, :class:`~ancf.errors.ConvergenceError`
    when an equilibrium cannot be solved along the way.

    Steps: check the inputs (:func:`_checked_start`), minimise (:func:`_optimise`), then at the optimum either
    claim nothing (too few data, :func:`_too_few_data`), or test identifiability and hold the parameters the data
    do not determine (:func:`_refit_holding`), or report every interval (:func:`_full_result`).  States without
    an equilibrium at ``theta0`` are left out of a first pass and re-admitted from its optimum
    (:func:`_fit_readmitting`; ``FitResult.readmitted``)."""
    if _readmit and _refit and _warm is None:
        kw = dict(absolute_sigma=absolute_sigma, fixed=fixed, max_nfev=max_nfev, scale=scale)
        try:
            return fit(form, obs, base, theta0, _readmit=False, **kw)
        except INFEASIBLE as exc:
            if not getattr(exc, "failed_index", None):
                raise
            return _fit_readmitting(form, obs, base, theta0, exc, kw)
    theta0, lo, hi, typical = _checked_start(form, obs, base, theta0, fixed, scale)
    absolute = obs.has_sigma if absolute_sigma is None else bool(absolute_sigma)
    free = np.array([nm not in fixed for nm in form.names])
    w = obs.weights().ravel()
    ev = _Evaluator(form, obs, base)
    if _warm is not None:           # the refit: from the first pass's equilibria (a cold start may not reach them)
        ev.q = list(_warm)
    if free.sum() > w.size:
        raise InputError(f"form {form.name}: {free.sum()} free parameters but only {w.size} observations")
    res, theta, W = _optimise_weighted(ev, theta0, free, lo, hi, typical, max_nfev)
    params, pred, J3 = ev.evaluate(theta, jacobian=True)
    r = pred - _observed(obs)
    Jw = whiten(W, J3.reshape(-1, form.n))
    rw = whiten(W, r.ravel())
    rss = float(rw @ rw)
    n_obs = rw.size
    n_free = int(free.sum())
    short = _too_few_data(obs.n, n_obs, n_free)
    if short:       # no spare degrees of freedom: a CI from such a fit is meaningless, claim nothing
        return _claim_nothing(form, theta, r, params, rss, n_obs - n_free, ev, str(res.message),
                              "too few data: " + "; ".join(short))
    # identifiability 1: rank of the Jacobian over the free parameters, columns scaled by the parameters'
    # fixed typical sizes (not by their values: a signed parameter near 0 would look undetermined)
    idx_free = np.flatnonzero(free)
    share, sv = null_share(Jw[:, idx_free] * typical[idx_free], singular_values=True)
    ident = np.zeros(form.n, bool)
    ident[idx_free] = share <= NULL_SHARE
    dof = max(n_obs - int(ident.sum()), 1)
    s2, q, basis = variance_scale(rss, dof, absolute)
    loud = misfit(rss, dof, absolute)
    cov = _covariance(Jw, ident, s2, _marginal)
    sd = np.sqrt(np.clip(np.diag(cov), 0, None))
    # identifiability 2: CI wider than the value
    signed = np.array([nm in SIGNED for nm in form.names])
    wide = ident & ~signed & (q * sd > np.abs(theta))
    if _refit and (wide.any() or (~ident & free).any()):
        return _refit_holding(form, obs, base, theta, ident, wide, free, cov, q, ev, absolute=absolute,
                              fixed=fixed, max_nfev=max_nfev, typical=typical)
    out = _full_result(form, theta, cov, sd, q, ident & ~wide, r, params, rss, dof, s2, sv, ev, str(res.message),
                       fixed)
    out.interval_basis = _basis_text(obs, absolute, basis) + (
        "; NOT the actuator's: the model does not fit these data within their stated noise (the intervals "
        "describe the best compromise)" if loud else "")
    out.misfit = loud
    return out


def _fit_readmitting(form: ModelForm, obs: Observations, base: ActuatorParams, theta0, exc: Exception,
                     kw: dict) -> FitResult:
    """The fit when states have no equilibrium at ``theta0`` (``exc``: that start failure, with ``failed_index``):
    first without them, then with every state from the first pass's optimum — a state past a limit point of the
    start (a start softer than the actuator, a pressure near its maximum with high tensions) is reached once
    the parameters moved.  Raises the start failure's type naming the states when too few remain for the first
    pass (:func:`_too_few_data`), or when they have no equilibrium at its optimum either."""
    out_idx = sorted(set(exc.failed_index))
    labels = [obs.labels[i] for i in out_idx]
    keep = np.setdiff1d(np.arange(obs.n), out_idx)
    n_free = form.n - len(kw.get("fixed") or ())
    short = _too_few_data(keep.size, keep.size * obs.weights().shape[1], n_free)
    if short:
        raise _readmit_failure(exc, f"{exc.start_message}; without them too few states remain for a first pass "
                               f"({'; '.join(short)})", labels)
    first = fit(form, obs.subset(keep), base, theta0, _readmit=False, **kw)
    try:
        out = fit(form, obs, base, first.theta, _readmit=False, **kw)
    except INFEASIBLE as again:
        if not getattr(again, "failed_index", None):
            raise
        still = [obs.labels[i] for i in again.failed_index]
        raise _readmit_failure(exc, f"{exc.start_message}; left out of a first pass, state(s) {still} have no "
                               f"equilibrium at its optimum either ({_parameter_text(form, first.theta)}): the "
                               "model cannot hold them — check their loads, or leave them out", still) from None
    out.readmitted = labels
    out.rejected += first.rejected
    return out


def _readmit_failure(exc: Exception, message: str, labels: list) -> Exception:
    """``exc``'s type (a typed error) with ``message``; its ``failed_states`` and starting ``parameters`` kept,
    ``failed_labels``: the states the message is about."""
    new = _retyped(exc, message) if isinstance(exc, _RETRY) else type(exc)(message)
    new.failed_states = list(getattr(exc, "failed_states", []))
    new.parameters = dict(getattr(exc, "parameters", {}))
    new.failed_labels = list(labels)
    return new


def _basis_text(obs: Observations, absolute: bool, scale_text: str) -> str:
    """What the intervals contain, in words (:mod:`validation.identification.uncertainty`)."""
    if not absolute:
        return "95 % intervals from " + scale_text
    inputs = [nm for nm, v in (("tensions", obs.tensions_std), ("pressure", obs.pressure_std),
                               ("tip load", obs.tip_force_std)) if v is not None and np.any(v > 0)]
    prop = (" with the stated noise of the " + ", ".join(inputs) + " propagated through the model's input "
            "sensitivities") if inputs and obs.has_sigma else " (no input noise stated)"
    return f"95 % intervals from {scale_text}; tip/marker noise{prop}"


def _whitening_at(ev: _Evaluator, theta) -> np.ndarray:
    """Per-state whitening blocks (N, d, d) of the residuals at θ: the tip and marker σ's plus the stated input
    noise propagated through ∂prediction/∂u at θ's equilibria (:mod:`validation.identification.uncertainty`)."""
    obs = ev.obs
    G = ev.input_jacobian(theta)
    usd = obs.input_std()
    osd = 1.0 / obs.weights()
    return np.stack([whitening(state_covariance(G[i], osd[i], usd[i])) for i in range(obs.n)])


def _optimise_weighted(ev: _Evaluator, theta0, free, lo, hi, typical, max_nfev: int):
    """(scipy's result, θ (n,), whitening blocks (N, d, d) at θ): :func:`_optimise` with the tip and marker
    weights; with stated input noise (and stated tip noise) again with the whitening recomputed at the optimum
    until θ moves by less than :data:`~validation.identification.uncertainty.WEIGHT_RTOL` of its standard deviation
    (at most :data:`~validation.identification.uncertainty.WEIGHT_ITERATIONS` refits)."""
    obs = ev.obs
    y = _observed(obs).ravel()
    if not (obs.has_sigma and obs.has_input_sigma):
        W = diagonal_whitening(obs.weights())
        res, theta = _optimise(ev, y, W, theta0, free, lo, hi, typical, max_nfev)
        return res, theta, W
    ev.evaluate(theta0, jacobian=False, all_failures=True)     # the start's failures named as the fit's would be
    theta = theta0
    for _ in range(WEIGHT_ITERATIONS):
        W = _whitening_at(ev, theta)
        res, new = _optimise(ev, y, W, theta, free, lo, hi, typical, max_nfev)
        moved = _moved((new - theta)[free], res.jac)
        theta = new
        if moved <= WEIGHT_RTOL:
            break
    return res, theta, _whitening_at(ev, theta)


def _moved(step: np.ndarray, jac_free: np.ndarray) -> float:
    """Largest |step| (over the free parameters, in the order of the columns of ``jac_free``) in units of the
    parameter's standard deviation from that whitened Jacobian (inf when it is singular: not converged)."""
    try:
        sd = np.sqrt(np.diag(np.linalg.inv(jac_free.T @ jac_free)))
    except np.linalg.LinAlgError:
        return float("inf")
    with np.errstate(invalid="ignore", divide="ignore"):
        r = np.abs(step) / sd
    return float(np.max(r)) if np.all(np.isfinite(r)) else float("inf")


def _checked_start(form: ModelForm, obs: Observations, base: ActuatorParams, theta0, fixed: Sequence[str], scale):
    """(θ₀ clipped into the bounds, lower (n,), upper (n,), typical sizes (n,)) of a fit, after checking its
    inputs (:class:`~ancf.errors.InputError` naming the inconsistent one)."""
    theta0 = np.asarray(theta0, float)
    if theta0.shape != (form.n,) or not np.all(np.isfinite(theta0)):
        raise InputError(f"initial parameters for form {form.name} must be {form.n} finite values, got {theta0}")
    if obs.tensions.shape[1] != base.n_tendons:
        raise InputError(f"observations have {obs.tensions.shape[1]} tensions per state; the actuator has "
                         f"{base.n_tendons} tendons")
    unknown = set(fixed) - set(form.names)
    if unknown:
        raise InputError(f"cannot fix unknown parameter(s) {sorted(unknown)} of form {form.name}")
    lo, hi = np.array(form.lower, float), np.array(form.upper, float)
    typical = form.typical_scale(theta0) if scale is None else np.asarray(scale, float)
    if typical.shape != (form.n,) or not np.all(np.isfinite(typical) & (typical > 0)):
        raise InputError(f"typical sizes of the parameters of form {form.name} must be {form.n} positive values, "
                         f"got {typical}")
    theta0 = np.clip(theta0, lo + 1e-12 * np.abs(lo), hi - 1e-12 * np.abs(hi))
    return theta0, lo, hi, typical


def _optimise(ev: _Evaluator, y: np.ndarray, W: np.ndarray, theta0: np.ndarray, free: np.ndarray, lo: np.ndarray,
              hi: np.ndarray, typical: np.ndarray, max_nfev: int):
    """(scipy's result, θ at the optimum (n,)): trust-region reflective least squares of the whitened residuals
    ``W`` (prediction − ``y``) (``W`` (N, d, d) per-state blocks, :func:`~validation.identification.uncertainty.whiten`)
    over the ``free`` parameters, the others held at ``theta0``.  With signed and unsigned free parameters, a
    continuation first fits the magnitudes with the signed ones held at their start."""
    form = ev.form

    def full(x):
        th = theta0.copy()
        th[free] = x
        return th

    first = [True]

    def fun(x):
        # an infeasible trial θ (module docstring) is answered with non-finite residuals: trf rejects the
        # step and shrinks the trust region; at the initial θ the failure is re-raised with its type
        try:
            _, pred, _ = ev.evaluate(full(x), jacobian=False, all_failures=first[0])
        except INFEASIBLE:
            if first[0]:
                raise
            ev.rejected += 1
            return np.full(y.size, REJECTED_RESIDUAL)
        first[0] = False
        return whiten(W, pred.ravel() - y)

    def jac(x):
        _, _, J = ev.evaluate(full(x), jacobian=True)
        return whiten(W, J.reshape(-1, form.n)[:, free])

    x0 = theta0[free].copy()
    signed_free = np.array([nm in SIGNED for nm in np.array(form.names)[free]])
    if signed_free.any() and not signed_free.all():
        # continuation: the magnitudes first with the signed slopes held at their start, then everything —
        # from a start far off (a slope of 0, a stiffness several times too small) a joint first step can
        # fall into a distant local minimum with a huge slope
        keep = ~signed_free

        def fun0(x):
            xx = x0.copy()
            xx[keep] = x
            return fun(xx)

        def jac0(x):
            xx = x0.copy()
            xx[keep] = x
            return jac(xx)[:, keep]

        pre = so.least_squares(fun0, x0[keep], jac=jac0, bounds=(lo[free][keep], hi[free][keep]), method="trf",
                               x_scale=typical[free][keep], xtol=FIT_TOL, ftol=FIT_TOL, gtol=FIT_TOL, max_nfev=max_nfev)
        x0[keep] = pre.x
    res = so.least_squares(fun, x0, jac=jac, bounds=(lo[free], hi[free]), method="trf",
                           x_scale=typical[free], xtol=FIT_TOL, ftol=FIT_TOL, gtol=FIT_TOL, max_nfev=max_nfev)
    return res, full(res.x)


def _too_few_data(n_states: int, n_obs: int, n_free: int) -> list[str]:
    """Why a fit of ``n_free`` parameters to ``n_states`` states (``n_obs`` weighted residuals) can claim nothing
    (:data:`MIN_SPARE_STATES`, :data:`MIN_DOF`); empty when it has data to spare."""
    short = []
    if n_states < n_free + MIN_SPARE_STATES:
        short.append(f"{n_states} state(s) for {n_free} free parameter(s) (at least {n_free + MIN_SPARE_STATES} "
                     f"needed: free parameters + {MIN_SPARE_STATES})")
    if n_obs - n_free < MIN_DOF:
        short.append(f"{n_obs - n_free} residual degree(s) of freedom ({n_obs} residuals − {n_free} free "
                     f"parameters; at least {MIN_DOF} needed)")
    return short


def _rms_tip(r: np.ndarray) -> float:
    """RMS of the tip errors [m] of residuals ``r`` (N, 3 + 3k)."""
    return float(np.sqrt(np.mean(np.sum(r[:, :3] ** 2, axis=1))))


def _claim_nothing(form: ModelForm, theta, r, params, rss: float, dof: int, ev: _Evaluator, message: str,
                   why: str) -> FitResult:
    """The result of a fit with too few data: every parameter and derived value not identifiable (reason
    ``why``), no covariance, no interval."""
    nan2 = (float("nan"), float("nan"))
    names = form.names
    keys = list(form.derived(theta))
    return FitResult(form, theta, np.full((form.n, form.n), np.nan), {nm: nan2 for nm in names},
                     {nm: False for nm in names}, np.full((form.n, form.n), np.nan), {k: None for k in keys},
                     {k: nan2 for k in keys}, {k: False for k in keys}, r, params, _rms_tip(r), rss, dof, float("nan"),
                     np.zeros(0), ev.nfev, message, ev.rejected,
                     reasons={nm: why for nm in names} | {k: why for k in keys}, intervals="none: " + why)


def prior_result(form: ModelForm, obs: Observations, base: ActuatorParams, theta0, reasons: dict) -> FitResult:
    """The result of a form the data determine nothing of (``reasons``: {parameter: why}; e.g. the tip within a
    fraction of a millimetre of one point, :mod:`validation.identification.information`): no fit — the
    predictions and residuals at ``theta0`` (the prior, the base actuator's values), every parameter and derived
    value not identifiable with its reason, held at the prior, no interval.  Raises like :func:`fit` when the
    states have no equilibrium at ``theta0``."""
    theta0 = np.asarray(theta0, float)
    ev = _Evaluator(form, obs, base)
    params, pred, _ = ev.evaluate(theta0, jacobian=False, all_failures=True)
    r = pred - _observed(obs)
    rw = r.ravel() * obs.weights().ravel()
    why = "; ".join(dict.fromkeys(reasons.values()))
    out = _claim_nothing(form, theta0, r, params, float(rw @ rw), rw.size, ev, "not fitted",
                         "not determined by the data: " + why)
    for nm in form.names:
        out.reasons[nm] = "not determined by the data: " + reasons.get(nm, why)
        out.held[nm] = float(theta0[form.names.index(nm)])
        out.held_at[nm] = "prior (the base actuator's value: not determined by the data)"
    return out


def _covariance(Jw: np.ndarray, ident: np.ndarray, s2: float, marginal: Optional[np.ndarray]) -> np.ndarray:
    """Cov(θ) (n, n) = s² (JᵀJ)⁻¹ over the identifiable parameters ``ident`` (NaN rows and columns for the
    others); with ``marginal`` (the first pass's covariance), its block of the identifiable parameters instead."""
    n = ident.size
    cov = np.full((n, n), np.nan)
    if ident.any():
        ii = np.flatnonzero(ident)
        A = Jw[:, ii]
        try:
            cov_id = s2 * np.linalg.inv(A.T @ A)
        except np.linalg.LinAlgError:
            cov_id = s2 * np.linalg.pinv(A.T @ A)
        cov[np.ix_(ii, ii)] = cov_id
        if marginal is not None:
            # after holding parameters whose interval was wider than their value: the others' covariance is
            # their marginal block of the first pass (the held parameter's uncertainty included), not the
            # narrower covariance conditional on the held value
            blk = np.asarray(marginal)[np.ix_(ii, ii)]
            if np.all(np.isfinite(blk)):
                cov[np.ix_(ii, ii)] = blk
    return cov


def _refit_holding(form: ModelForm, obs: Observations, base: ActuatorParams, theta, ident, wide, free, cov, q: float,
                   ev: _Evaluator, *, absolute: bool, fixed: Sequence[str], max_nfev: int, typical) -> FitResult:
    """The fit again with the parameters the data do not determine (``~ident``: rank; ``wide``: CI wider than
    the value) held at this first-pass optimum ``theta``, from its equilibria; they are reported as not
    identifiable, and the intervals of the others say how they were made (module docstring)."""
    newly = [nm for nm, bad in zip(form.names, (~ident | wide) & free) if bad]
    why = {nm: ("the data do not determine it (a direction of the scaled Jacobian with singular value "
                f"< {RANK_TOL:g} × the largest)" if not ident[j] else
                "its 95 % confidence interval is wider than its value")
           for j, nm in enumerate(form.names) if nm in newly}
    # a mass the data do not determine is held at the base actuator's (weighed) value, not at a first-pass
    # optimum that absorbed what the model misses (seen: 0.94 kg/m against 0.53 on a misfit of χ²/dof 6e3)
    start = np.array(theta, float)
    weighed = {"line_mass": base.line_mass, "tip_mass": base.tip_mass}
    for nm in newly:
        if nm in MASS_NAMES:
            start[form.names.index(nm)] = weighed[nm]
    out = fit(form, obs, base, start, absolute_sigma=absolute, fixed=tuple(fixed) + tuple(newly),
              max_nfev=max_nfev, scale=typical, _refit=False, _marginal=cov, _warm=ev.q)
    out.rejected += ev.rejected
    for nm in newly:
        out.identifiable[nm] = False
        out.ci95[nm] = (float("nan"), float("nan"))
        out.reasons.setdefault(nm, why[nm])
        out.held[nm] = float(out.theta[form.names.index(nm)])
        out.held_at[nm] = "base actuator's value" if nm in MASS_NAMES else "first-pass optimum"
    rank_held = [nm for nm in newly if not ident[form.names.index(nm)]]
    out.intervals = ("conditional on the held value(s) of " + ", ".join(rank_held)) if rank_held else \
        "marginal (first-pass covariance; the held parameters' uncertainty included)"
    out.values_identifiable, out.values_ci95 = _derived_identifiability(form, out.theta, out.cov,
                                                                        out.identifiable, q)
    out.values = {k: (v if out.values_identifiable[k] else None) for k, v in form.derived(out.theta).items()}
    return out


def _full_result(form: ModelForm, theta, cov, sd, q: float, ok, r, params, rss: float, dof: int, s2: float, sv,
                 ev: _Evaluator, message: str, fixed: Sequence[str]) -> FitResult:
    """The result with every interval: θ ± q sd for the identifiable parameters ``ok`` (n,), the derived values
    by the delta method; parameters given as ``fixed`` recorded as held at the value given."""
    ident_map = {nm: bool(ok[j]) for j, nm in enumerate(form.names)}
    ci = {nm: ((float(theta[j] - q * sd[j]), float(theta[j] + q * sd[j])) if ident_map[nm]
               else (float("nan"), float("nan"))) for j, nm in enumerate(form.names)}
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov / np.outer(sd, sd)
    vid, vci = _derived_identifiability(form, theta, cov, ident_map, q)
    values = {k: (v if vid[k] else None) for k, v in form.derived(theta).items()}
    return FitResult(form, theta, cov, ci, ident_map, corr, values, vci, vid, r, params, _rms_tip(r), rss, dof, s2,
                     sv, ev.nfev, message, ev.rejected,
                     held={nm: float(theta[form.names.index(nm)]) for nm in fixed},
                     held_at={nm: "value given to the fit" for nm in fixed},
                     intervals=("conditional on the held value(s) of " + ", ".join(fixed)) if fixed else "full")


def null_share(Js: np.ndarray, singular_values: bool = False):
    """Share (n,) of each column in the numerically rank-deficient directions of ``Js`` (N, n): the squared
    components of the right singular vectors whose singular value is below :data:`RANK_TOL` × the largest (and
    of the directions the rows do not reach when N < n); with ``singular_values`` also those singular values.

    The rows are equilibrated first (each divided by its norm; zero rows stay zero).  A left scaling by a
    non-singular diagonal does not change the null space, but it stops one hypersensitive state (a state near a
    fold of the reduced model, whose tip moves 10⁴× more per parameter than the others' — measured) from pushing
    every other direction below the relative threshold: without it the verdict flipped between FEM data sets that
    differ by 1e-9."""
    Js = np.asarray(Js, float)
    n = Js.shape[1]
    rn = np.linalg.norm(Js, axis=1)
    Jr = Js / np.where(rn > 0, rn, 1.0)[:, None]
    # the full V only when rows are fewer than columns (then U is small); never an N × N U for many rows
    _, sv, Vt = np.linalg.svd(Jr, full_matrices=Jr.shape[0] < n)
    k = sv.size
    tiny = np.zeros(n, bool)
    tiny[:k] = sv < RANK_TOL * (sv[0] if k and sv[0] > 0 else 1.0)
    tiny[k:] = True                           # fewer rows than columns: the directions no row reaches
    share = np.sum(Vt[tiny] ** 2, axis=0)
    return (share, sv) if singular_values else share


def _derived_identifiability(form, theta, cov, ident: dict, q: float):
    keys, D = form.derived_jacobian(theta)
    vals = form.derived(theta)
    bad = np.array([not ident[nm] for nm in form.names])
    out_id, out_ci = {}, {}
    for i, k in enumerate(keys):
        depends_on_bad = np.any(np.abs(D[i, bad]) > 1e-12 * (np.abs(D[i]).max() + 1e-300)) if bad.any() else False
        if depends_on_bad or not math.isfinite(vals[k]):
            out_id[k], out_ci[k] = False, (float("nan"), float("nan"))
            continue
        g = D[i, ~bad]
        c = cov[np.ix_(~bad, ~bad)]
        sd = math.sqrt(max(float(g @ c @ g), 0.0))
        half = q * sd
        out_id[k] = bool(np.isfinite(half)) and (k in SIGNED or half <= abs(vals[k]))
        out_ci[k] = (vals[k] - half, vals[k] + half) if out_id[k] else (float("nan"), float("nan"))
    return out_id, out_ci


def predict(params: ActuatorParams, obs: Observations) -> np.ndarray:
    """Predictions (N, 3 + 3k) [m] of the reduced model with ``params`` for the states of ``obs`` (tip, then
    markers), FK cold from the straight reference.  A state whose FK fails raises."""
    m_g = Model(params)
    m_0 = Model(params.replace(gravity=(0.0, 0.0, 0.0))) if np.any(params.gravity) else m_g
    k = 0 if obs.markers is None else obs.marker_s.size
    S = None if k == 0 else position_matrix(params.n_elements, params.length, obs.marker_s)
    out = np.zeros((obs.n, 3 + 3 * k))
    for i in range(obs.n):
        model = m_g if obs.gravity[i] else m_0
        eq = model.fk(obs.tensions[i], obs.pressure[i], obs.tip_force[i], check_limits=False)
        out[i, :3] = eq.tip
        if k:
            out[i, 3:] = S @ eq.q
    return out
