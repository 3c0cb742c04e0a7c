"""Elastic tendons (series stiffness k_s of rope, sensor and screw) in the locked FK and the exact locked
compliance: closed form (springs in series), finite differences, limits, both locked solvers, TOML."""

import numpy as np
import pytest

from ancf import ActuatorParams, Model, StiffnessLaw, presets
from ancf import compliance as cp
from ancf.errors import ConfigError
from validation.checks import compliance_check
from validation.paper.stiffness import ratio_closed_form, series_stiffness_for_ratio, stiffness_vs_tension

EA, EI, L, D = 767.2, 0.0839, 0.16, 0.0275


def uniform(**kw):
    return presets.paper_unscaled().replace(stiffness=StiffnessLaw.constant(EA=EA, EI=EI), line_mass=0.0,
                                            tip_mass=0.0, tool_offset=0.0, **kw)


@pytest.mark.parametrize("ks", [300.0, 2000.0, 2e4])
def test_springs_in_series_closed_form(ks):
    """Straight weightless beam, top tendon locked at zero tension, downward tip load P: the locked
    tendon obeys d θ(L) − T L/EA = T/k_s with θ(L) = (P L²/2 − T d L)/EI, so
    k_locked = k_c / (1 − ¾ a/(a + b + c)), a = d²/EI, b = 1/EA, c = 1/(k_s L), k_c = 3EI/L³."""
    res = stiffness_vs_tension(pressures=(0.0,), tensions=(0.0,), mass=0.01, params=uniform(tendon_stiffness=ks),
                               methods=("exact",))
    cv = res["curves_N_per_m"]
    a, b, c = D ** 2 / EI, 1 / EA, 1 / (ks * L)
    k_c = 3 * EI / L ** 3
    k_locked = k_c / (1 - 0.75 * a / (a + b + c))
    assert cv["constant_linear"][0, 0] == pytest.approx(k_c, rel=0.01)
    assert cv["locked_linear_exact"][0, 0] == pytest.approx(k_locked, rel=0.02)
    assert cv["locked_nonlinear"][0, 0] == pytest.approx(k_locked, rel=0.02)
    P = 0.01 * 9.81
    assert res["rows"][0]["locked_tensions_N"][0] == pytest.approx(P * L * D / (2 * EI * (a + b + c)), rel=0.03)


def test_exact_locked_compliance_matches_finite_differences():
    model = Model(presets.paper_scaled().replace(tendon_stiffness=800.0))
    rows = compliance_check.compare(model, tensions=((2.0, 0.0, 0.0), (3.0, 0.5, 1.0)), pressures=(0.0, 50e3))
    ex = [r["rel_error"] for r in rows if r["form"] == "locked/exact"]
    assert len(ex) == 12 and max(ex) < 2e-3
    # and the series spring really softens the locked response against the inextensible tendons
    stiff = Model(presets.paper_scaled())
    eq, eqs = model.fk((2.0, 0, 0), 0.0), stiff.fk((2.0, 0, 0), 0.0)
    u = np.array([0, 0, -1.0])
    k_el = cp.directional_stiffness(cp.locked(model, eq, load_direction=u).C_p, u)
    k_in = cp.directional_stiffness(cp.locked(stiff, eqs, load_direction=u).C_p, u)
    k_ct = cp.directional_stiffness(cp.tension(model, eq).C_p, u)
    assert k_ct < k_el < k_in


def test_limits_of_the_series_stiffness():
    """k_s → ∞: the inextensible locked compliance; k_s → 0: the constant-tension compliance — each approached at
    first order (log-log slope ∓1) over the plausible range of an actuator file's tendon stiffness (1 … 1e10 N/m)."""
    base = presets.paper_scaled()
    u = np.array([0.0, 0.0, -1.0])
    ref = Model(base)
    eq = ref.fk((3.0, 1.0, 0.0), 25e3)
    C_in = cp.locked(ref, eq, load_direction=u).C_p
    C_t = cp.tension(ref, eq).C_p

    def gap(ks, target):
        m = Model(base.replace(tendon_stiffness=ks))
        C = cp.locked(m, m.fk((3.0, 1.0, 0.0), 25e3), load_direction=u).C_p
        return np.linalg.norm(C - target) / np.linalg.norm(target)

    stiff = [gap(ks, C_in) for ks in (1e8, 1e10)]
    soft = [gap(ks, C_t) for ks in (10.0, 1.0)]
    assert stiff[1] < 1e-7 and soft[1] < 0.01
    assert np.log10(stiff[0] / stiff[1]) / 2.0 == pytest.approx(1.0, abs=0.05)      # ∝ 1/k_s
    assert np.log10(soft[0] / soft[1]) == pytest.approx(1.0, abs=0.1)               # ∝ k_s


def test_both_locked_solvers_and_the_rest_length():
    model = Model(presets.paper_scaled().replace(tendon_stiffness=500.0))
    eq0 = model.fk((2.5, 0.5, 0.0), 30e3)
    l0 = model.rest_lengths(eq0)
    assert np.allclose(l0, eq0.tendon_lengths - eq0.tensions / 500.0)
    same = model.fk_locked(l0, 30e3, (0, 0, 0), q0=eq0.q, tensions0=eq0.tensions)
    assert np.allclose(same.tip, eq0.tip, atol=1e-9) and np.allclose(same.tensions, eq0.tensions, atol=1e-7)
    F = (0.0, 0.05, -0.5)
    a = model.fk_locked(l0, 30e3, F, q0=eq0.q, tensions0=eq0.tensions)
    g = model.fk_locked(l0, 30e3, F, q0=eq0.q, tensions0=eq0.tensions, method="gamma")
    assert np.allclose(a.tip, g.tip, atol=1e-8) and np.allclose(a.tensions, g.tensions, atol=1e-6)
    taut = list(a.active)
    assert np.allclose(a.tendon_lengths[taut] - a.tensions[taut] / 500.0, l0[taut], atol=1e-10)


def test_toml_key_and_validation():
    p = presets.paper_scaled().replace(tendon_stiffness=1500.0)
    back = ActuatorParams.from_toml_string(p.to_toml())
    assert back.tendon_stiffness == 1500.0
    text = presets.paper_scaled().to_toml()
    assert "tendon_stiffness" not in text and ActuatorParams.from_toml_string(text).tendon_stiffness is None
    assert ActuatorParams.from_toml_string(text.replace("free_base_stretch = false", "free_base_stretch = false\n"
                                                        "tendon_stiffness_N_per_mm = 2")).tendon_stiffness == 2000.0
    for bad in (0.0, -5.0, float("inf")):
        with pytest.raises(ConfigError):
            presets.paper_scaled().replace(tendon_stiffness=bad)


def _weightless(name, **kw):
    return presets.get(name).replace(line_mass=0.0, tip_mass=0.0, tool_offset=0.0, **kw)


def test_ratio_is_fixed_by_geometry_for_every_length_scaling():
    """With EI = D_a² λ k/8 and EA ∝ k, the straight-beam ratio is 1/(1 − ¾ · 8d²/(8d² + D_a²)) whatever
    the length factor: 2.90 for the paper's d and D_a — the model cannot give "about twice" by rescaling k."""
    d, Da = 0.0275, 0.02959
    closed = 1 / (1 - 0.75 * 8 * d ** 2 / (8 * d ** 2 + Da ** 2))
    assert closed == pytest.approx(2.90, abs=0.01)
    for name in ("paper_unscaled", "paper_scaled", "paper_scaled_020"):
        assert ratio_closed_form(name) == pytest.approx(closed, rel=1e-12)
        r = stiffness_vs_tension(pressures=(0.0,), tensions=(0.0,), mass=0.005, params=_weightless(name),
                                 methods=("exact",))
        assert r["ratio_locked_over_constant"]["linear_exact"][0, 0] == pytest.approx(closed, rel=0.03)
    assert ratio_closed_form("paper_diameter") == pytest.approx(1.9, abs=0.05)      # d = 13.75 mm


def test_series_stiffness_for_twice():
    for name in ("paper_unscaled", "paper_scaled"):
        ks = series_stiffness_for_ratio(name, 2.0)
        assert ratio_closed_form(name, tendon_stiffness=ks) == pytest.approx(2.0, rel=1e-12)
        r = stiffness_vs_tension(pressures=(0.0,), tensions=(0.0,), mass=0.005,
                                 params=_weightless(name, tendon_stiffness=ks), methods=("exact",))
        assert r["ratio_locked_over_constant"]["nonlinear"][0, 0] == pytest.approx(2.0, rel=0.03)
    assert series_stiffness_for_ratio("paper_scaled") == pytest.approx(312, rel=0.05)
    assert series_stiffness_for_ratio("paper_diameter") == float("inf")


def test_closed_form_ratio_of_a_pressure_dependent_law():
    """EI × 1.9 at 100 kPa (EA unchanged): a = d²/EI falls, so the straight beam's locked / constant ratio
    falls from the geometry's 2.90 to 1/(1 − ¾ a/(a + b)) with a/b = 8 d²/(1.9 D_a²) — towards the paper's
    "about twice"; at 0 kPa it is the stretch-only law's."""
    from ancf import presets
    p = presets.paper()
    law = p.stiffness.with_pressure(EI=(0.55, 0.35))
    prm = p.replace(stiffness=law)
    assert ratio_closed_form(prm) == pytest.approx(ratio_closed_form(p), rel=1e-14)
    r = 8 * 0.0275 ** 2 / (1.9 * 0.02959 ** 2)
    assert ratio_closed_form(prm, pressure=100e3) == pytest.approx(1 / (1 - 0.75 * r / (r + 1)), rel=1e-12)
    assert ratio_closed_form(prm, pressure=100e3) == pytest.approx(2.43, abs=0.01)
