"""Parameter object, TOML loading with explicit units, presets."""

import math

import numpy as np
import pytest
from pydantic import ValidationError

from ancf import ActuatorParams, ConfigError, StiffnessLaw, presets


def test_paper_preset_values():
    p = presets.paper_unscaled()
    assert p.length == pytest.approx(0.16)
    assert p.n_elements == 6
    assert p.D_eff == pytest.approx(26.05e-3)
    assert p.tendon_distances == pytest.approx([27.5e-3] * 3)
    assert p.tendon_angles == pytest.approx([0, 2 * math.pi / 3, 4 * math.pi / 3])
    # EA = k(1) = a + b, EI = D_a² k(1) / 8 (docs/design.md §3)
    assert p.stiffness.EA(1.0) == pytest.approx(1336 - 568.8)
    assert p.stiffness.EI(1.0) == pytest.approx(0.02959 ** 2 * (1336 - 568.8) / 8)
    assert p.pressure_max == pytest.approx(120e3) and p.tension_max == pytest.approx(5.0)


def test_linear_law_matches_paper_formula():
    law = StiffnessLaw.linear(a=1336.0, b=-568.8, D_a=0.02959)
    for lam in (0.9, 1.0, 1.1):
        k = 1336 * lam - 568.8
        assert law.EA(lam) == pytest.approx(k)
        assert law.EI(lam) == pytest.approx(0.02959 ** 2 * lam * k / 8)
        # W' = EA ε λ and W = ∫ W' (trapezoid check of the closed form)
        x = np.linspace(1.0, lam, 2001)
        assert law.axial_energy(lam) == pytest.approx(np.trapezoid(law.axial_force(x), x), rel=1e-6, abs=1e-12)


def test_toml_round_trip_and_presets():
    for p in (presets.paper(), presets.paper_constant(), presets.four_tendon()):
        assert ActuatorParams.from_toml_string(p.to_toml()) == p
    assert presets.four_tendon().n_tendons == 4


def test_frozen_and_replace():
    p = presets.paper()
    with pytest.raises(ValidationError, match="frozen"):
        p.length = 0.2
    q = p.replace(n_elements=8, length=0.2)
    assert (q.n_elements, q.length, p.n_elements) == (8, 0.2, 6)
    with pytest.raises(ConfigError, match="unknown parameter"):
        p.replace(n_elemnts=8)


@pytest.mark.parametrize("edit, match", [
    (("length_m", "lenght_m"), "unknown key 'lenght_m'.*did you mean length_m"),
    (("length_m = 0.16", "length = 0.16"), "needs an explicit unit"),
    (("length_m = 0.16", "length_furlong = 0.16"), "unknown key"),
    (("length_m = 0.16", "length_mm = 160\nlength_m = 0.16"), "given twice"),
    (('law = "linear"', 'law = "cubic"'), "law must be"),
    (("n_elements = 6", "n_elements = 0"), "n_elements"),
    (("length_m = 0.16", "length_m = -1"), "length"),
    (("length_m = 0.16", 'length_m = "long"'), "expected a number|length"),
])
def test_bad_toml_is_rejected_clearly(edit, match):
    text = presets.paper().to_toml()
    assert edit[0] in text
    with pytest.raises(ConfigError, match=match):
        ActuatorParams.from_toml_string(text.replace(edit[0], edit[1], 1))


def test_units_are_converted():
    text = presets.paper().to_toml().replace("length_m = 0.16", "length_mm = 160").replace(
        "pressure_max_Pa = 120000.0", "pressure_max_kPa = 120")
    p = ActuatorParams.from_toml_string(text)
    assert p.length == pytest.approx(0.16) and p.pressure_max == pytest.approx(120e3)


def test_invalid_frame_and_tendons():
    p = presets.paper()
    with pytest.raises(ConfigError, match="reference_direction"):
        p.replace(reference_direction=(1.0, 0.0, 0.0))
    with pytest.raises(ConfigError, match="at least 3 tendons"):
        p.replace(tendons=p.tendons[:2])
    with pytest.raises(ConfigError, match="D_a"):
        StiffnessLaw.linear(a=1336, b=-568.8, D_a=29.59)   # millimetres by mistake


def test_preset_lookup(tmp_path):
    f = tmp_path / "mine.toml"
    f.write_text(presets.paper().replace(name="mine").to_toml())
    assert presets.get(str(f)).name == "mine"
    with pytest.raises(ConfigError, match="unknown preset"):
        presets.get("nope")


def test_damping_coefficients_in_the_actuator_file():
    """rayleigh_alpha [1/s], rayleigh_beta [s or ms], axial_damping [N s]: read in their units, written back in
    SI, implausible magnitudes (a unit mistake) and negative values refused."""
    base = presets.paper().to_toml()
    text = base.replace("tip_mass_kg", "rayleigh_alpha_per_s = 2.5\nrayleigh_beta_ms = 4\naxial_damping_N_s = 0.3\ntip_mass_kg")
    p = ActuatorParams.from_toml_string(text)
    assert (p.rayleigh_alpha, p.rayleigh_beta, p.axial_damping) == (2.5, pytest.approx(4e-3), 0.3)
    assert ActuatorParams.from_toml_string(p.to_toml()) == p
    assert "rayleigh_beta_s = 0.004" in p.to_toml()
    with pytest.raises(ConfigError, match="implausible"):
        ActuatorParams.from_toml_string(base.replace("tip_mass_kg", "rayleigh_beta_s = 40\ntip_mass_kg"))
    with pytest.raises(ConfigError, match="needs an explicit unit"):
        ActuatorParams.from_toml_string(base.replace("tip_mass_kg", "axial_damping = 0.3\ntip_mass_kg"))
    with pytest.raises((ConfigError, ValidationError)):
        presets.paper().replace(rayleigh_alpha=-1.0)


def test_pressure_dependent_stiffness_in_the_actuator_file():
    """EI(λ, p) = EI(λ)(1 + c₁ p̂ + c₂ p̂²), p̂ = p/100 kPa: keys with their unit, round trip, the factor
    evaluated, a factor that is not positive inside the pressure limits refused naming the pressure in kPa."""
    law = presets.paper().stiffness.with_pressure(EA=(0.2,), EI=(0.8, 0.1))
    p = presets.paper().replace(stiffness=law)
    text = p.to_toml()
    assert "EI_pressure_coeffs_per_100kPa = [0.8, 0.1]" in text and "EA_pressure_coeffs_per_100kPa = [0.2]" in text
    assert ActuatorParams.from_toml_string(text) == p
    assert p.stiffness.EI(1.0, 50e3) == pytest.approx(p.stiffness.EI(1.0) * (1 + 0.8 * 0.5 + 0.1 * 0.25), rel=1e-14)
    assert p.stiffness.EA(1.1, 100e3) == pytest.approx(p.stiffness.EA(1.1) * 1.2, rel=1e-14)
    assert "EI × (1 + 0.8 p̂ + 0.1 p̂^2)" in p.stiffness.describe()
    # without the unit suffix: rejected, naming the accepted spelling
    with pytest.raises(ConfigError, match="EI_pressure_coeffs_per_100kPa"):
        ActuatorParams.from_toml_string(text.replace("EI_pressure_coeffs_per_100kPa", "EI_pressure_coeffs"))
    with pytest.raises(ConfigError, match="expected a list"):
        ActuatorParams.from_toml_string(text.replace("= [0.8, 0.1]", "= 0.8"))
    # a factor reaching zero inside [0, 120] kPa: 1 − 0.9 p̂ is 0 at 111 kPa
    with pytest.raises(ConfigError, match=r"pressure factor of EI is -0.08 ≤ 0 at p = 120 kPa.*\[0, 120\] kPa"):
        presets.paper().replace(stiffness=presets.paper().stiffness.with_pressure(EI=(-0.9,)))
    # a minimum inside the range is found (1 − 2 p̂ + 1.2 p̂²: minimum 1/6 at 83 kPa is fine; 1 − 2.2 p̂ + 1.2 p̂²: −0.0083 at 92 kPa)
    ok = presets.paper().stiffness.with_pressure(EI=(-2.0, 1.2))
    f, at, which = ok.pressure_factor_minimum(0.0, 120e3)
    assert (f, at / 1e3, which) == (pytest.approx(1 / 6), pytest.approx(250 / 3), "EI")
    with pytest.raises(ConfigError, match="-0.008333 ≤ 0 at p = 91.6667 kPa"):
        presets.paper().replace(stiffness=presets.paper().stiffness.with_pressure(EI=(-2.2, 1.2)))
    with pytest.raises(ConfigError, match="at most 4 coefficients"):
        law.with_pressure(EI=(0.1,) * 5)
    with pytest.raises(ConfigError, match="must be a number"):
        law.with_pressure(EI=("0.1",))


def test_a_pressure_outside_the_limits_where_the_factor_vanishes_is_refused():
    from ancf import InputError, Model
    law = presets.paper().stiffness.with_pressure(EI=(-0.8,))          # 0 at 125 kPa, limits 0–120 kPa
    m = Model(presets.paper().replace(stiffness=law))
    with pytest.raises(InputError, match="pressure factor of EI .* at p = 130 kPa"):
        m.fk((0, 0, 0), 130e3, check_limits=False)
    with pytest.raises(InputError, match="at p = 130 kPa"):
        m.dQ_dp(m.q_ref, 130e3)
    ea, ei = m.stiffness_coefficients(100e3)
    np.testing.assert_allclose(ei, law.ei * 0.2, rtol=1e-14)
    np.testing.assert_array_equal(ea, law.ea)


def test_the_stiffness_example_of_the_format_documentation_loads():
    import pathlib
    import re
    doc = (pathlib.Path(__file__).resolve().parents[1] / "docs" / "data-formats.md").read_text()
    section = doc.split("## Actuator files (TOML)", 1)[1].split("\n## ", 1)[0]
    example = re.search(r"```toml\n(.*?)```", section, re.S).group(1)
    text = presets.paper().to_toml()
    head, tail = text.split("[stiffness]", 1)
    p = ActuatorParams.from_toml_string(head + example + tail[tail.index("[[tendons]]"):])
    assert p.stiffness.EI_pressure == (0.55, 0.35)
    assert p.stiffness.EI(1.0, 100e3) == pytest.approx(0.0179 * 1.9, rel=1e-3)
