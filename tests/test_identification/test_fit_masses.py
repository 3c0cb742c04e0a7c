"""The line and tip mass as parameters of a rig-data fit, and a misfit that is said out loud.

Sensitivities are checked against central differences of equilibrium solves; the recovered masses and
stiffness against the values the synthetic data were made with; the misfit threshold against the χ²
distribution's own quantile."""

import pickle

import numpy as np
import pytest
import scipy.stats as st

from ancf import Model, presets
from ancf.errors import InputError
from hardware.static_states import StaticStates
from validation.identification.fit import Observations, _Evaluator
from validation.identification.forms import MASS_NAMES, get_form, with_masses
from validation.identification.identify import from_measurements, initial_theta
from validation.identification.uncertainty import MISFIT_FACTOR, misfit, misfit_threshold

BASE = presets.paper()
SIG_X = 2e-5


@pytest.mark.parametrize("name,shear", [("paper", False), ("paper", True), ("pressure_ei_shear", True)])
def test_mass_sensitivities_match_finite_differences_of_solves(name, shear):
    """∂tip/∂(m', m_tip) from one assembly of the gravity load of a unit mass, against central differences of
    the nonlinear FK (gravity, a tool offset, tip loads; with a series shear compliance the tip weight's own
    shear offset)."""
    base = BASE.replace(shear_compliance=(5e-4, 3e-3)) if shear else BASE
    form = get_form(name, fit_masses=True)
    assert form.names[-2:] == MASS_NAMES and form.units[-2:] == ("kg/m", "kg") and min(form.lower[-2:]) > 0
    th = initial_theta(form, None, base)
    obs = Observations(tensions=[[2.0, 0.5, 0.5], [0.2, 0.2, 3.0]], pressure=[0.0, 80e3],
                       tip_force=[[0, 0, -0.3], [0.1, 0.2, 0]], gravity=[True, True], tip=np.zeros((2, 3)))
    ev = _Evaluator(form, obs, base)
    _, _, J = ev.evaluate(th)
    for j in (form.n - 2, form.n - 1):
        h = 1e-6 * th[j]
        fd = []
        for s in (1, -1):
            t = th.copy()
            t[j] += s * h
            e2 = _Evaluator(form, obs, base)
            e2.q = list(ev.q)
            fd.append(e2.evaluate(t, jacobian=False)[1])
        fd = (fd[0] - fd[1]) / (2 * h)
        assert np.abs(fd).max() > 1e-3
        assert np.abs(J[..., j] - fd).max() <= 1e-6 * np.abs(fd).max(), form.names[j]


def test_the_mass_form_sets_the_masses_and_keeps_the_law():
    form = get_form("separate", fit_masses=True)
    plain = get_form("separate")
    th = np.concatenate([initial_theta(plain, None, BASE), [0.4, 0.02]])
    p = form.to_params(th, BASE)
    assert (p.line_mass, p.tip_mass) == (0.4, 0.02)
    assert p.stiffness.EA(1.1) == plain.to_params(th[:-2], BASE).stiffness.EA(1.1)
    assert form.derived(th) == plain.derived(th[:-2])
    assert with_masses(form) is form
    again = pickle.loads(pickle.dumps(form))
    assert again.names == form.names and again.fits_masses
    d = get_form("paper", True, True)
    assert d.names[-3:] == ("d",) + MASS_NAMES


def _states(params, cases, seed=0) -> StaticStates:
    """Exact equilibria of ``params`` (under gravity) at ``cases`` with tip noise σ = 0.02 mm, stated."""
    model = Model(params)
    rng = np.random.default_rng(seed)
    tip = np.array([model.fk(T, p, F, check_limits=False).tip for T, p, F in cases])
    n = len(cases)
    return StaticStates(tensions=np.array([c[0] for c in cases], float), pressure=np.array([c[1] for c in cases]),
                        tip_position=tip + rng.normal(0, SIG_X, tip.shape),
                        tip_force=np.array([c[2] for c in cases], float), tip_position_std=np.full((n, 3), SIG_X))


def _cases(loads_N=(0.0, -0.2, -0.5)):
    return [(T, p, (0.0, 0.0, fz)) for p in (0.0, 60e3, 120e3) for fz in loads_N
            for T in ((0.2, 0.2, 0.2), (3.0, 0.2, 0.2), (0.2, 3.0, 0.2), (2.0, 2.0, 2.0))]


PLANT = BASE.replace(line_mass=BASE.line_mass * 1.15, tip_mass=BASE.tip_mass + 0.005)


@pytest.fixture(scope="module")
def hung():
    """States with known tip loads (hung masses) at three pressures, of a plant 15 % heavier with a 5 g heavier
    tip than the nominal base; identified with the masses free and held."""
    states = _states(PLANT, _cases())
    kw = dict(forms=("paper",), heldout_fraction=0.0)
    return from_measurements(states, BASE, **kw), from_measurements(states, BASE, masses="base", **kw)


def test_known_loads_determine_the_masses_and_the_stiffness(hung):
    free, _ = hung
    f = free.fit
    for nm, true in (("line_mass", PLANT.line_mass), ("tip_mass", PLANT.tip_mass), ("EA", 122.752)):
        ok, ci = (f.values_identifiable, f.values_ci95) if nm == "EA" else (f.identifiable, f.ci95)
        assert ok[nm], f.reasons.get(nm)
        lo, hi = ci[nm]
        assert lo <= true <= hi and hi - lo < 0.1 * true, (nm, lo, hi, true)
    assert (free.params.line_mass, free.params.tip_mass) == tuple(f.theta[-2:])
    text = free.to_toml()
    assert "line_mass" in text and f"line_mass_kg_per_m = {float(f.theta[-2])!r}" in text
    assert not f.misfit and not free.warnings


def test_masses_held_at_the_base_give_a_loud_misfit(hung):
    _, held = hung
    f = held.fit
    assert "line_mass" not in f.names
    assert f.chi2_per_dof > misfit_threshold(f.dof)
    assert "does not fit these data within their stated noise" in f.misfit
    assert f"χ²/dof = {f.chi2_per_dof:.3g}" in f.misfit
    assert "NOT the actuator's" in f.interval_basis
    assert any("does not fit" in w for w in held.warnings)
    d = held.to_dict()
    assert d["misfit"] == f.misfit and d["fits"]["paper"]["misfit"] == f.misfit
    assert "# WARNING: the model does not fit" in held.to_toml()


def test_without_known_loads_the_masses_are_held_and_said_so():
    """Equal tensions only, no known tip load: the weight's sag trades against the stiffness — the masses are
    held at the base's values (the information check), not fitted, and the warning says why.  (With single
    tendons the bending states alone separate them at this noise: the check decides, not a rule.)"""
    cases = [(T, p, (0.0, 0.0, 0.0)) for p in (0.0, 30e3, 60e3, 90e3, 120e3)
             for T in ((0.2, 0.2, 0.2), (1.0, 1.0, 1.0), (2.0, 2.0, 2.0))]
    res = from_measurements(_states(BASE, cases), BASE, forms=("paper",), heldout_fraction=0.0)
    f = res.fit
    assert f.held_at.get("line_mass", "").startswith("prior") and f.held_at.get("tip_mass", "").startswith("prior")
    assert f.theta[-2] == BASE.line_mass and f.theta[-1] == BASE.tip_mass
    assert f.values_identifiable["EA"] and f.values_identifiable["EI"]
    assert any("gravity's sag and the stiffness trade" in w for w in res.warnings)


def test_masses_option_is_checked():
    with pytest.raises(InputError, match="masses must be one of"):
        from_measurements(_states(BASE, _cases((0.0,))[:6]), BASE, masses="weighed")


def test_misfit_threshold_is_the_larger_of_the_factor_and_the_chi2_quantile():
    for dof in (1, 3, 5, 20, 146, 1000):
        q = st.chi2.ppf(0.999, dof) / dof
        assert misfit_threshold(dof) == pytest.approx(max(MISFIT_FACTOR, q))
    assert misfit_threshold(2) > MISFIT_FACTOR                 # few dof: noise alone could exceed 4
    assert misfit(30.0 * 146, 146, True).startswith("the model does not fit")
    assert misfit(3.9 * 146, 146, True) == ""
    assert misfit(30.0 * 146, 146, False) == ""                # no stated noise: χ² has no scale


def test_a_mass_the_fit_cannot_determine_is_held_at_the_base_value_not_at_its_first_pass_optimum():
    """States without gravity hold no information on the masses: the fit's own rank rule holds them — at the base
    actuator's (weighed) values, not where the first pass left them (from a start 1.6× too heavy)."""
    from validation.identification.fit import fit
    form = get_form("paper", fit_masses=True)
    model = Model(BASE.replace(gravity=(0.0, 0.0, 0.0)))
    cases = [((T, 0.2, 0.2), p) for p in (0.0, 40e3, 80e3) for T in (0.5, 1.5, 3.0)]
    tips = [model.fk(np.array(T), p).tip for T, p in cases]
    obs = Observations(tensions=[T for T, _ in cases], pressure=[p for _, p in cases], tip_force=np.zeros((9, 3)),
                       gravity=[False] * 9, tip=np.array(tips), tip_std=np.full((9, 3), SIG_X))
    th0 = initial_theta(form, None, BASE)
    th0[-2:] = 1.6 * BASE.line_mass, 1.6 * BASE.tip_mass
    f = fit(form, obs, BASE, th0)
    assert f.held_at["line_mass"] == f.held_at["tip_mass"] == "base actuator's value"
    assert (f.theta[-2], f.theta[-1]) == (BASE.line_mass, BASE.tip_mass)
