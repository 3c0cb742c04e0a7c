"""Infeasible trial parameters in the fit (validation/identification/fit.py, module docstring): a trial θ whose equilibria
cannot be solved is rejected by the optimiser (non-finite residuals → scipy's trf shrinks its trust region),
the fit finishes and reports it; a failure at the initial θ stays a typed error."""

import numpy as np
import pytest
import scipy.optimize as so

from ancf import Model, presets
from ancf.errors import CollapsedStateError, ConvergenceError, UnstableEquilibriumError
from validation.identification import fit as fitmod
from validation.reference.experiments import default_design
from validation.identification.fit import Observations, fit, predict
from validation.identification.forms import get_form

BASE = presets.paper().replace(line_mass=0.0, tip_mass=0.0, gravity=(0.0, 0.0, 0.0))
TRUE = [767.2, 0.0839, 0.02605]          # form "constant": EA, EI, D_eff


def _obs(theta):
    form = get_form("constant")
    cases = list(default_design().training[::4])
    obs = Observations([c.tensions for c in cases], [c.pressure for c in cases], [c.tip_force for c in cases],
                       [False] * len(cases), np.zeros((len(cases), 3)), labels=[c.label for c in cases])
    obs.tip = predict(form.to_params(np.array(theta, float), BASE), obs)[:, :3]
    return form, obs


def test_scipy_trf_rejects_non_finite_trial_residuals():
    """The property the fit relies on: least_squares(method='trf') takes a non-finite residual vector of a
    trial step as a rejected step and still converges.  Residual atan(x − 1) from x = 4: the Gauss–Newton
    step overshoots to x ≈ −27, where the residual is inf (x < 0.5)."""
    calls = {"inf": 0}

    def fun(x):
        if x[0] < 0.5:
            calls["inf"] += 1
            return np.full(1, np.inf)
        return np.arctan(x - 1.0)

    def jac(x):
        return np.array([[1.0 / (1.0 + (x[0] - 1.0) ** 2)]])

    res = so.least_squares(fun, [4.0], jac=jac, method="trf", xtol=1e-12, ftol=1e-12, gtol=1e-12)
    assert calls["inf"] >= 1
    assert res.x[0] == pytest.approx(1.0, abs=1e-8)
    with pytest.raises(ValueError, match="not finite in the initial point"):
        so.least_squares(fun, [0.0], jac=jac, method="trf")


@pytest.mark.parametrize("error", [
    ConvergenceError("stub", solver="fk", iterations=3, residual_norm=1.0, tolerance=1e-9),
    UnstableEquilibriumError("stub", solver="fk", min_eigenvalue=-1.0),
    CollapsedStateError("stub", solver="fk", stretch=0.1),
])
def test_failing_trial_solve_is_rejected_and_the_fit_finishes(monkeypatch, error):
    """Model.fk raises (warm, and cold after a typed error other than ConvergenceError) at the first trial θ away
    from the start: the fit still recovers the
    true parameters, counts the rejected trial, and the warm starts were not taken from the failed θ."""
    form, obs = _obs(TRUE)
    theta0 = np.array(TRUE) * np.array([1.15, 0.85, 1.05])
    state = {"theta": None, "failed": 0, "trial": False}
    real_eval, real_fk = fitmod._Evaluator.evaluate, Model.fk

    def evaluate(self, theta, jacobian=True, **kwargs):
        theta = np.asarray(theta, float)
        state["trial"] = (state["failed"] == 0 and not jacobian
                          and not np.allclose(theta, np.clip(theta0, form.lower, form.upper)))
        q_before = [None if q is None else q.copy() for q in self.q]
        try:
            return real_eval(self, theta, jacobian, **kwargs)
        except type(error):
            # warm starts untouched by the failed θ
            assert all((a is None and b is None) or np.array_equal(a, b) for a, b in zip(q_before, self.q))
            raise

    def fk(self, *args, **kwargs):
        if state["trial"]:
            state["failed"] += 1
            raise error
        return real_fk(self, *args, **kwargs)

    monkeypatch.setattr(fitmod._Evaluator, "evaluate", evaluate)
    monkeypatch.setattr(Model, "fk", fk)
    res = fit(form, obs, BASE, theta0, max_nfev=60)
    # warm start, then the cold retry, both failed — except after a ConvergenceError: Model.fk's own fallback
    # already stepped the load up from the straight reference, which the cold retry would repeat exactly
    assert state["failed"] == (1 if isinstance(error, ConvergenceError) else 2)
    assert res.rejected == 1
    np.testing.assert_allclose(res.theta, TRUE, rtol=1e-6)
    assert res.rms_tip < 1e-9


def test_failure_at_the_initial_parameters_stays_a_typed_error(monkeypatch):
    form, obs = _obs(TRUE)

    def fk(self, *args, **kwargs):
        raise UnstableEquilibriumError("stub", solver="fk", min_eigenvalue=-2.0)

    monkeypatch.setattr(Model, "fk", fk)
    with pytest.raises(UnstableEquilibriumError, match="the fit of form constant cannot start: .* of .* states"):
        fit(form, obs, BASE, TRUE, max_nfev=10)


def test_a_start_that_fails_names_every_failing_state_and_the_parameters(monkeypatch):
    """Two of the states have no equilibrium at the starting parameters (one collapses, one is unstable):
    the fit cannot start, and its typed error names both states with their own failure, the form and every
    starting parameter, and carries them as attributes; the states that solved are not blamed."""
    form, obs = _obs(TRUE)
    bad = {obs.labels[1]: CollapsedStateError("stub collapse", solver="fk", stretch=0.3),
           obs.labels[3]: UnstableEquilibriumError("stub saddle", solver="fk", min_eigenvalue=-2.0)}
    real_fk = Model.fk
    labels_by_load = {(tuple(obs.tensions[i]), float(obs.pressure[i]), tuple(obs.tip_force[i])): obs.labels[i]
                      for i in range(obs.n)}

    def fk(self, T, p, F, *args, **kwargs):
        label = labels_by_load[(tuple(np.asarray(T, float)), float(p), tuple(np.asarray(F, float)))]
        if label in bad:
            raise bad[label]
        return real_fk(self, T, p, F, *args, **kwargs)

    monkeypatch.setattr(Model, "fk", fk)
    with pytest.raises(CollapsedStateError) as info:
        fit(form, obs, BASE, TRUE, max_nfev=10)
    msg = str(info.value)
    assert "cannot start" in msg and "2 of" in msg
    for label, err in bad.items():
        assert f"'{label}'" in msg and type(err).__name__ in msg
    for good in set(obs.labels) - set(bad):
        assert f"'{good}'" not in msg
    assert "EA = 767.2 N" in msg and "EI = 0.0839 N m^2" in msg and "D_eff = 0.02605 m" in msg
    assert [s for s, _ in info.value.failed_states] == [obs.labels[1], obs.labels[3]]
    assert info.value.parameters == dict(zip(form.names, TRUE))


def test_parameters_the_model_refuses_are_named_with_the_form():
    """A pressure factor that is not positive over the actuator's pressure limits (1 − 1.5 p̂ + 0.3 p̂² < 0 above
    79 kPa) is refused by the parameters: at the start of a fit that is a ConfigError naming the form and
    every parameter; at a trial step the same error is a rejected step (``fit.INFEASIBLE``)."""
    from ancf.errors import ConfigError
    form = get_form("pressure_ei")
    cases = list(default_design().training[::4])
    theta = np.array([700.0, 900.0, 0.09, 0.15, 0.8, 0.3, 0.024])
    obs = Observations([c.tensions for c in cases], [c.pressure for c in cases], [c.tip_force for c in cases],
                       [False] * len(cases), np.zeros((len(cases), 3)), labels=[c.label for c in cases])
    obs.tip = predict(form.to_params(theta, BASE), obs)[:, :3]
    bad = theta.copy()
    bad[4] = -1.5
    with pytest.raises(ConfigError, match=r"refuses the pressure_ei parameters \(EA1 = 700 N, .*pI1 = -1.5, "
                                          r"pI2 = 0.3, D_eff = 0.024 m\).*pressure factor of EI"):
        fit(form, obs, BASE, bad, max_nfev=10)
    assert ConfigError in fitmod.INFEASIBLE


def test_the_refit_after_holding_a_parameter_starts_from_the_fits_own_equilibria(monkeypatch):
    """A parameter the data do not determine (D_eff without a pressure state) is held and the others are
    refitted from the first-pass optimum.  States whose equilibria the first pass reached only by warm starts
    (here: every cold FK away from the starting parameters fails, as it can near a limit point) must not make
    the refit fail at its start: it continues from the first pass's equilibria."""
    form = get_form("constant")
    cases = [c for c in default_design().training if c.pressure == 0.0]
    obs = Observations([c.tensions for c in cases], [c.pressure for c in cases], [c.tip_force for c in cases],
                       [False] * len(cases), np.zeros((len(cases), 3)), labels=[c.label for c in cases])
    obs.tip = predict(form.to_params(np.array(TRUE), BASE), obs)[:, :3]
    theta0 = np.array(TRUE) * np.array([1.1, 0.9, 1.0])
    start_law = form.to_params(theta0, BASE).stiffness
    real_fk = Model.fk

    def fk(self, *args, q0=None, **kwargs):
        if q0 is None and self.params.stiffness != start_law:
            raise ConvergenceError("stub: cold start failed", solver="fk", iterations=60, residual_norm=1.0,
                                   tolerance=1e-9)
        return real_fk(self, *args, q0=q0, **kwargs)

    monkeypatch.setattr(Model, "fk", fk)
    res = fit(form, obs, BASE, theta0, max_nfev=60)
    assert res.identifiable["D_eff"] is False and res.held_at["D_eff"] == "first-pass optimum"
    np.testing.assert_allclose(res.theta[:2], TRUE[:2], rtol=1e-6)
