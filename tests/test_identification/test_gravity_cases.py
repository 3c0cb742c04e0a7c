"""Gravity as the mounted actuator lives with it: self-weight states in both sets of the default design, the
design's mounting, the masses the reduced model takes from the FEM design (against closed forms), and the actuator
file stating gravity only when held-out states with gravity validated it."""

import dataclasses
import math

import numpy as np
import pytest

from ancf import ActuatorParams, presets
from ancf.errors import ConfigError, InputError
from fem_reference import presets as fem_presets
from validation.identification import identify
from validation.identification.fit import Observations, predict
from validation.identification.forms import get_form
from validation.reference.designs import (MOUNTINGS, design_mounting, design_to_toml, load_design,
                                          mounting_gravity)
from validation.reference.experiments import GRAVITY_HELD_OUT, GRAVITY_TRAINING, default_design


# ------------------------------------------------------------------------------------------- the design
def test_default_design_has_self_weight_states_in_both_sets():
    d = default_design(pressure_max=100e3)
    train_g = [c for c in d.training if c.gravity]
    held_g = [c for c in d.heldout if c.gravity]
    assert len(train_g) == len(GRAVITY_TRAINING) >= 2 and len(held_g) == len(GRAVITY_HELD_OUT) >= 1
    # self-weight alone at 0 and at p_max, and against a tendon
    assert any(c.pressure == 0 and not any(c.tensions) for c in train_g)
    assert any(c.pressure == 100e3 and not any(c.tensions) for c in train_g)
    assert any(any(c.tensions) for c in train_g + held_g)
    assert all(", gravity" in c.label for c in train_g + held_g)
    # the other states stay gravity-free; without self_weight the design has none
    assert sum(c.gravity for c in d.cases) == len(train_g) + len(held_g)
    assert not any(c.gravity for c in default_design(self_weight=False).cases)


# ------------------------------------------------------------------------------------------- mounting
def test_mounting_gravity_vectors_and_unknown_values():
    assert mounting_gravity("horizontal") == (0.0, 0.0, -9.81)           # axis +x, gravity −z (the paper's rig)
    assert mounting_gravity("vertical_down") == (9.81, 0.0, 0.0)         # hanging: gravity along the axis
    assert mounting_gravity("vertical_up") == (-9.81, 0.0, 0.0)
    for bad in ("sideways", "", None, 3):
        with pytest.raises(ConfigError, match="mounting must be one of"):
            mounting_gravity(bad)
    assert design_mounting("paper") == "horizontal"


@pytest.mark.parametrize("mounting", sorted(MOUNTINGS))
def test_design_file_states_its_mounting_and_reads_back(tmp_path, mounting):
    g, m = fem_presets.straight_tube_test(), fem_presets.paper_material()
    p = tmp_path / "d.toml"
    p.write_text(design_to_toml(g, m, "tube", mounting=mounting))
    assert design_mounting(p) == mounting
    g2, _ = load_design(p)
    assert g2 == g


def test_design_file_without_mounting_is_horizontal_and_unknown_mounting_is_refused(tmp_path):
    g, m = fem_presets.straight_tube_test(), fem_presets.paper_material()
    text = design_to_toml(g, m, "tube")
    p = tmp_path / "d.toml"
    p.write_text(text.replace('mounting = "horizontal"\n', ""))
    assert "mounting" not in p.read_text() and design_mounting(p) == "horizontal"
    load_design(p)
    for bad in ('"upside"', "3", "[1, 2]"):
        p.write_text(text.replace('mounting = "horizontal"', f"mounting = {bad}"))
        with pytest.raises(ConfigError, match="mounting"):
            load_design(p)
        with pytest.raises(ConfigError, match="mounting"):
            design_mounting(p)
    with pytest.raises(ConfigError, match="mounting"):
        design_to_toml(g, m, "tube", mounting="sideways")


# ------------------------------------------------------------------------------------------- masses
def test_fem_masses_equal_the_closed_form_of_a_straight_tube():
    """Line mass = π (R_o² − R_i²) ρ of the tube's wall; the cap's mass and its centre of mass beyond the tip
    point (cap_com_offset − tip_offset) as the design states them."""
    g = dataclasses.replace(fem_presets.straight_tube_test(), cap_mass=0.02, cap_com_offset=0.003, tip_offset=0.001)
    m = fem_presets.paper_material()
    Ro, Ri = 0.015 + 0.002, 0.015 - 0.002                 # R_mid = 15 mm, t = 4 mm
    out = identify.fem_masses(g, m)
    assert out["line_mass_kg_per_m"] == pytest.approx(math.pi * (Ro ** 2 - Ri ** 2) * m.density, rel=1e-6)
    assert out["tip_mass_kg"] == 0.02
    assert out["tip_mass_offset_m"] == pytest.approx(0.002, abs=1e-15)
    base = identify.fem_base_params(g, m, gravity=mounting_gravity("vertical_down"))
    assert base.line_mass == out["line_mass_kg_per_m"] and base.tip_mass == 0.02
    assert base.gravity == (9.81, 0.0, 0.0)


# ------------------------------------------------------------------------------------------- the statement
def test_gravity_check_statuses():
    L = 0.16
    ok = identify.gravity_check([True, False], [True, False], [0.001, 0.5], L)      # 0.63 % of L with gravity
    assert ok["status"] == "validated" and ok["stated"] and ok["states"] == 1
    assert ok["max_tip_error_pct"] == pytest.approx(0.625)
    bad = identify.gravity_check([True], [True, True], [0.001, 0.005], L)           # 3.1 % > 2.5 %
    assert bad["status"] == "failed" and not bad["stated"] and "NOT VALIDATED" in bad["text"]
    nan = identify.gravity_check([True], [True], [float("nan")], L)
    assert nan["status"] == "failed" and not nan["stated"]
    assert identify.gravity_check([True], None, None, L)["status"] == "trained"
    absent = identify.gravity_check([False], [False], [0.0], L)
    assert absent["status"] == "absent" and not absent["stated"]
    with pytest.raises(InputError):
        identify.gravity_check([True], [True, False], [0.0], L)


BASE = presets.paper()                  # gravity (0, 0, −9.81) m/s², line and tip mass
TRUTH = [767.2, 0.0839, 0.02605]        # form "constant": EA [N], EI [N m²], D_eff [m]


def _obs(form, cases, gravity: bool = True):
    cases = list(cases)
    obs = Observations([c.tensions for c in cases], [c.pressure for c in cases], [c.tip_force for c in cases],
                       [c.gravity and gravity for c in cases], np.zeros((len(cases), 3)),
                       labels=[c.label for c in cases])
    obs.tip = predict(form.to_params(np.array(TRUTH), BASE), obs)[:, :3]
    return obs


def _identified(heldout_shift_m: float = 0.0, gravity: bool = True):
    d, form = default_design(pressure_max=100e3), get_form("constant")
    train = _obs(form, d.training[::3] + [c for c in d.training if c.gravity], gravity)
    held = _obs(form, d.heldout, gravity)
    held.tip[np.asarray(held.gravity, bool), 2] += heldout_shift_m
    return identify.identify(train, BASE, heldout=held, forms=("constant",))


@pytest.fixture(scope="module")
def validated():
    return _identified()


def test_actuator_file_states_gravity_when_the_gravity_states_validated_it(validated):
    res = validated
    assert res.gravity_validation["status"] == "validated"
    text = res.to_toml()
    p = ActuatorParams.from_toml_string(text)
    assert p.gravity == (0.0, 0.0, -9.81) and p.line_mass == BASE.line_mass and p.tip_mass == BASE.tip_mass
    assert "# gravity validated on" in text and 'gravity = "validated"' in text
    assert p == res.params.replace(name=res.default_name())


def test_actuator_file_does_not_state_gravity_when_the_gravity_states_failed():
    res = _identified(heldout_shift_m=0.01)          # 6 % of L off on the held-out states with gravity
    assert res.gravity_validation["status"] == "failed"
    text = res.to_toml()
    p = ActuatorParams.from_toml_string(text)
    assert p.gravity == (0.0, 0.0, 0.0) and "gravity NOT VALIDATED" in text and 'gravity = "failed"' in text
    assert res.params.gravity == (0.0, 0.0, -9.81)              # the result in memory keeps the design's


def test_actuator_file_does_not_state_gravity_without_gravity_states():
    res = _identified(gravity=False)
    assert res.gravity_validation["status"] == "absent"
    p = ActuatorParams.from_toml_string(res.to_toml())
    assert p.gravity == (0.0, 0.0, 0.0) and p.line_mass == BASE.line_mass


def test_an_old_file_without_the_gravity_statement_still_loads(validated):
    text = validated.to_toml()
    old = "\n".join(ln for ln in text.splitlines() if not ln.startswith(("# gravity", "gravity = ")))
    assert ActuatorParams.from_toml_string(old) == ActuatorParams.from_toml_string(text)
