"""What the data can tell, checked before a fit (validation.identification.information): data at one pressure
and one tip position identify nothing and say so; informative data raise no alarm and their intervals hold
the truth; the fit's Jacobian reuses the equilibria of the residuals' solve."""

import json

import numpy as np
import pytest

from ancf import Model, StiffnessLaw, presets
from validation.identification import identify as ident
from validation.identification.fit import Observations, _Evaluator
from validation.identification.forms import get_form
from validation.identification.information import (ASSUMED_NOISE, MAX_RELATIVE_SD, check_form, coverage,
                                                    weak_directions)

BASE = presets.paper()


def _truth():
    """The plant: the base law with EA × 0.9 and EI × 0.85 (the paper form holds it: D_a × √(0.85/0.9)) and
    D_eff = 27 mm."""
    law = BASE.stiffness
    return BASE.replace(stiffness=StiffnessLaw.polynomial(EA=[0.9 * c for c in law.EA_coeffs],
                                                         EI=[0.85 * c for c in law.EI_coeffs]), D_eff=0.027)


def _informative(seed: int, sigma: float = 5e-5) -> Observations:
    """40 states of the truth over 0–100 kPa: no tension, single tendons, all three, a known vertical and a
    lateral tip load; tip noise σ stated."""
    m = Model(_truth())
    rng = np.random.default_rng(seed)
    loads = [((0, 0, 0), (0, 0, 0)), ((3, 0, 0), (0, 0, 0)), ((0, 3, 0), (0, 0, 0)), ((0, 0, 3), (0, 0, 0)),
             ((2, 2, 2), (0, 0, 0)), ((4, 1, 1), (0, 0, 0)), ((0, 0, 0), (0, 0, -0.3)), ((2, 0, 0), (0, 0.2, 0))]
    rows = [(T, p, F, m.fk(T, p, F).tip + rng.normal(0, sigma, 3))
            for p in (0.0, 25e3, 50e3, 75e3, 100e3) for T, F in loads]
    T, p, F, tip = map(np.array, zip(*rows))
    return Observations(T, p, F, np.ones(len(p), bool), tip, tip_std=np.full((len(p), 3), sigma),
                        labels=[f"state {i}" for i in range(len(p))])


def _one_point(n: int = 12, seed: int = 0) -> Observations:
    """What a controller holding one target at 60 kPa logs: tensions and a stochastic vertical load vary, the
    tip stays within ≈ 0.1 mm of one point (the tip recorded as the target plus tracker noise)."""
    rng = np.random.default_rng(seed)
    m = Model(_truth())
    T0, p = np.array([3.0, 1.6, 1.7]), 60e3
    target = m.fk(T0, p, (0, 0, -0.4)).tip
    T = T0 + rng.uniform(-0.5, 0.5, (n, 3))
    F = np.zeros((n, 3))
    F[:, 2] = rng.uniform(-0.55, -0.23, n)
    tip = target + rng.normal(0, 3e-5, (n, 3))
    return Observations(T, np.full(n, p), F, np.ones(n, bool), tip, labels=[f"state {i}" for i in range(n)])


def test_coverage_names_one_point_and_one_pressure():
    cov = coverage(_one_point(), BASE)
    assert set(cov.findings) == {"one_point", "one_pressure"}
    assert "one point" in cov.findings["one_point"] and "60 kPa" in cov.findings["one_pressure"]
    assert coverage(_informative(0), BASE).findings == {}


def test_weak_directions_follow_the_noise_rule():
    """A direction is determined when the data fix it to ≤ 10 % (1σ): singular value ≥ 10 noise units per unit
    relative change; below the rank threshold never."""
    S = np.diag([1e3, 1.0 / (0.5 * MAX_RELATIVE_SD), 1.0 / (2 * MAX_RELATIVE_SD), 0.0])
    sv, _, bad = weak_directions(S)
    assert bad.tolist() == [False, False, True, True]
    _, _, bad_rows = weak_directions(np.ones((1, 3)) * 100.0)      # fewer rows than parameters
    assert bad_rows.tolist() == [False, True, True]


def test_one_pressure_one_point_data_identify_nothing_and_say_why(tmp_path):
    """The README's control-log case: every form refused, no number reported for EI or D_a, the reason in the
    result, fit.json and its warnings; the actuator file keeps the base's values."""
    obs = _one_point()
    res = ident.identify(obs.subset(slice(0, 9)), BASE, heldout=obs.subset(slice(9, None)),
                         forms=("paper", "separate"), check_information=True)
    assert res.values["EI"] is None and res.values["D_a"] is None
    assert all(r.get("refused") for r in res.comparison)
    assert any("one point" in w for w in res.warnings) and any("one pressure" in w for w in res.warnings)
    assert "one point" in res.fit.reasons["D_a"]
    assert res.form == "paper"                               # the first form asked for, at the base's values
    assert res.params.stiffness.EI(1.0) == pytest.approx(BASE.stiffness.EI(1.0), rel=1e-9)
    assert res.params.stiffness.EA(1.2) == pytest.approx(BASE.stiffness.EA(1.2), rel=1e-6)
    res.save(tmp_path / "fit.json")
    data = json.loads((tmp_path / "fit.json").read_text())
    assert data["information"]["coverage"]["findings"].keys() == {"one_point", "one_pressure"}
    assert data["information"]["forms"]["paper"]["refused"] is True
    assert data["fits"]["paper"]["held"]["D_a"]["held_at"].startswith("prior")


def test_the_noise_rule_alone_flags_one_configuration_data():
    """Without the one-point rule the sensitivities still find a direction the varying loads (the tip held
    still) fix to no better than 10 %: a parameter is held (the one-point rule then holds them all)."""
    obs = _one_point()
    form = get_form("paper")
    J = _Evaluator(form, obs, BASE).evaluate(ident.initial_theta(form, None, BASE))[2]
    from validation.identification.information import information, information_weights
    cov = coverage(obs, BASE)
    cov.findings.pop("one_point")
    inf = information(form, J, information_weights(obs), form.typical_scale(ident.initial_theta(form, None, BASE)),
                      cov, f"σ = {ASSUMED_NOISE}")
    assert len(inf.held) >= 1 and np.max(inf.relative_sd) > MAX_RELATIVE_SD


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_informative_data_raise_no_alarm_and_the_truth_lies_in_the_intervals(seed):
    obs = _informative(seed)
    form = get_form("paper")
    inf = check_form(form, obs, BASE, ident.initial_theta(form, None, BASE))
    assert inf.held == {} and not inf.refused
    assert np.all(inf.relative_sd < 0.01)                      # every direction fixed to better than 1 %
    res = ident.identify(obs, BASE, forms=("paper",), check_information=True)
    assert res.warnings == []
    f = res.fits["paper"]
    law = _truth().stiffness
    truth = {"k1": law.EA(1.0), "D_a": np.sqrt(8 * law.EI(1.0) / law.EA(1.0)), "D_eff": 0.027,
             "a": (law.EA(1.001) - law.EA(0.999)) / 0.002}
    for nm, v in truth.items():
        lo, hi = f.ci95[nm]
        assert lo <= v <= hi, (nm, lo, v, hi)


def test_the_jacobian_reuses_the_equilibria_of_the_residuals():
    """scipy asks for the residuals, then the Jacobian at the same θ: no FK is solved again for it."""
    obs = _informative(0)
    form = get_form("paper")
    ev = _Evaluator(form, obs, BASE)
    th = ident.initial_theta(form, None, BASE)
    calls = []
    orig = Model.fk

    def counting(self, *a, **k):
        calls.append(1)
        return orig(self, *a, **k)
    Model.fk = counting
    try:
        ev.evaluate(th, jacobian=False)
        n = len(calls)
        _, _, J = ev.evaluate(th, jacobian=True)
    finally:
        Model.fk = orig
    assert n == obs.n and len(calls) == n and J is not None
    _, _, J_fresh = _Evaluator(form, obs, BASE).evaluate(th, jacobian=True)
    assert np.allclose(J, J_fresh, rtol=1e-10, atol=1e-15)


def test_the_command_line_warns_before_its_tables_and_the_report_shows_it(tmp_path):
    """`bellows identify --measurements` on one-point, one-pressure states: exit status 0, the warning lines
    before the first table, fit.json's information record; the report's summary lists what is not determined."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    from hardware.static_states import StaticStates, write_static_states
    obs = _one_point(n=10)
    states = write_static_states(tmp_path / "states.h5", StaticStates(
        tensions=obs.tensions, pressure=obs.pressure, tip_position=obs.tip, tip_force=obs.tip_force,
        label=obs.labels))
    (tmp_path / "base.toml").write_text(BASE.to_toml())
    root = Path(__file__).resolve().parents[2]
    env = dict(os.environ, PYTHONPATH=str(root), COLUMNS="200")
    run = lambda *a: subprocess.run([sys.executable, "-m", "validation.commands.main", *map(str, a)],  # noqa: E731
                                    cwd=tmp_path, capture_output=True, text=True, timeout=600, env=env)
    r = run("identify", "--measurements", states, "--base", tmp_path / "base.toml", "--forms", "paper",
            "--out", tmp_path / "fit")
    assert r.returncode == 0, r.stderr
    out = r.stdout
    assert "warning:" in out and out.index("warning:") < out.index("Identified parameters")
    assert "one point" in out and "refused" in out
    data = json.loads((tmp_path / "fit" / "fit.json").read_text())
    assert data["information"]["forms"]["paper"]["refused"] and data["values"]["EI"] is None
    r = run("report", "--measurements", states, "--base", tmp_path / "base.toml", "--forms", "paper",
            "--out", tmp_path / "rep")
    assert r.returncode == 0, r.stderr
    html = (tmp_path / "rep" / "report.html").read_text()
    assert "What these data do not determine" in html and "one point" in html
