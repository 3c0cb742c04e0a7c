"""Actuator files that are wrong in form or magnitude are a ConfigError at load naming the key and the accepted
range — never accepted, never another exception, never late (a count is bounded before anything is built) —
and the range table of docs/data-formats.md is the program's."""

import math
import pathlib
import re
import subprocess
import time

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from ancf import ActuatorParams, ConfigError, presets
from ancf.params import PLAUSIBLE, plausible_ranges
from toml_values import toml_literal

ROOT = pathlib.Path(__file__).resolve().parents[2]
PAPER = (ROOT / "ancf" / "presets" / "paper.toml").read_text()


def _edit(old, new, text=PAPER):
    assert old in text, old
    return text.replace(old, new, 1)


def _law(text):
    return _edit('law = "linear"                # EA = k(λ), EI = D_a² λ k(λ) / 8\na_N = 1336\nb_N = -568.8\n'
                 'D_a_mm = 29.59', text)


@pytest.mark.parametrize("text, match", [
    # a scalar where a list belongs, a list where one number belongs
    (_edit("gravity_m_per_s2 = [0, 0, -9.81]", "gravity_m_per_s2 = -9.81"), r"gravity_m_per_s2: expected a list of 3"),
    (_law('law = "polynomial"\nEA_coeffs_N = 700\nEI_coeffs_N_m2 = [0.07]'), r"EA_coeffs_N: expected a list of 1 to 8"),
    (_edit("D_a_mm = 29.59", "D_a_mm = 29.59\nEI_pressure_coeffs_per_100kPa = 0.5"),
     r"EI_pressure_coeffs_per_100kPa: expected a list"),
    (_edit("pressure_max_kPa = 120", "pressure_max_kPa = 120\nshear_compliance_coeffs_mm_per_N_per_100kPa = 2"),
     r"shear_compliance_coeffs_mm_per_N_per_100kPa: expected a list"),
    (_edit("length_mm = 160", "length_mm = [160]"), r"length_mm: expected one number, got a list"),
    (_edit("distance_mm = 27.5", "distance_mm = [27.5, 27.5]"), r"distance_mm: expected one number"),
    (_edit("a_N = 1336", "a_N = [1336]"), r"\[stiffness\]\.a_N: expected one number"),
    # coincident tendons
    (_edit("angle_deg = 120", "angle_deg = 0"), r"tendons 1 and 2 are at the same angle.*at least 1° apart"),
    (_edit("angle_deg = 240", "angle_deg = -240"), r"tendons 2 and 3 are at the same angle"),
    # absurd counts, bounded before anything is built
    (PAPER + "\n[[tendons]]\ndistance_mm = 27.5\nangle_deg = 60\n" * 2_000, r"2003 \[\[tendons\]\].*3 … 16"),
    (_law('law = "polynomial"\nEA_coeffs_N = [700]\nEI_coeffs_N_m2 = [' + "0.07, " * 20_000 + '0.07]'),
     r"EI_coeffs_N_m2: expected a list of 1 to 8 numbers, got 20001"),
    (_edit("n_elements = 6", "n_elements = 100000000"), r"n_elements = 100000000 is outside .* 1 … 200"),
    (_edit("quadrature_points = 5", "quadrature_points = 10000"), r"quadrature_points = 10000 .* 4 … 20"),
    (_edit("n_elements = 6", "n_elements = 1" + "0" * 400), r"n_elements = .* 1 … 200"),
    (_edit("length_mm = 160", "length_mm = 1" + "0" * 400), r"length_mm: value must be a finite number, got 1000000"),
    # magnitudes many orders beyond any bellows, in the unit of the key
    (_edit("pressure_max_kPa = 120", "pressure_max_kPa = 120\nshear_compliance_coeffs_mm_per_N_per_100kPa = [900]"),
     r"shear_compliance_coeffs_mm_per_N_per_100kPa\[0\] = 900 is implausible.*-100 … 100 mm_per_N_per_100kPa"),
    (_edit("D_a_mm = 29.59", "D_a_mm = 29.59\nEI_pressure_coeffs_per_100kPa = [0.5, 1e6]"),
     r"EI_pressure_coeffs_per_100kPa\[1\] = 1000000.0 is implausible.*-100 … 100"),
    (_edit("pressure_max_kPa = 120", "pressure_max_kPa = 120\ntendon_stiffness_N_per_mm = 1e-9"),
     r"tendon_stiffness_N_per_mm = 1e-09 is implausible.*0.001 … 1e\+07 N_per_mm"),
])
def test_a_wrong_actuator_file_is_a_config_error_naming_the_key(text, match):
    t0 = time.perf_counter()
    with pytest.raises(ConfigError, match=match) as info:
        ActuatorParams.from_toml_string(text, where="lab.toml")
    assert str(info.value).startswith("lab.toml") and "\n" not in str(info.value)
    assert time.perf_counter() - t0 < 5.0


def test_the_python_api_applies_the_same_ranges():
    p = presets.paper()
    with pytest.raises(ConfigError, match="same angle"):
        p.replace(tendons=(p.tendons[0], p.tendons[0], p.tendons[2]))
    with pytest.raises(ConfigError, match="at most 16 tendons"):
        p.replace(tendons=tuple(type(p.tendons[0])(distance=0.02, angle=k * 0.3) for k in range(20)))
    with pytest.raises(ConfigError, match="shear_compliance"):
        p.replace(shear_compliance=(0.5,))
    with pytest.raises(ConfigError, match="EI_pressure_coeffs"):
        p.replace(stiffness=p.stiffness.with_pressure(EI=(500.0,)))
    with pytest.raises(ConfigError, match="tendon_stiffness"):
        p.replace(tendon_stiffness=1e-6)
    assert p.replace(tendon_stiffness=2e3, shear_compliance=(0.004,)).tendon_stiffness == 2e3


def test_every_actuator_file_in_the_repository_and_every_preset_loads():
    files = subprocess.run(["git", "ls-files", "*.toml"], cwd=ROOT, capture_output=True, text=True).stdout.split()
    actuator = [f for f in files if "[[tendons]]" in (ROOT / f).read_text(encoding="utf-8")]
    assert "ancf/presets/paper.toml" in actuator
    for f in actuator:
        ActuatorParams.from_toml(ROOT / f)
    for name in presets.names() if hasattr(presets, "names") else ("paper", "paper_constant", "four_tendon"):
        presets.get(name)


def test_the_range_table_in_the_docs_is_the_programs():
    doc = (ROOT / "docs" / "data-formats.md").read_text(encoding="utf-8")
    section = doc[doc.index("### Plausible ranges"):]
    rows = re.findall(r"^\| `([^`]+)` \| `?([^|`]*?)`? \| ([^|]+) \|$", section.split("\n## ")[0], flags=re.M)
    assert [(k, u, r.strip()) for k, u, r in rows] == plausible_ranges()
    assert set(PLAUSIBLE) <= {k for k, _, _ in plausible_ranges()}


# ------------------------------------------------------------------------------------- mutations
_values = st.one_of(
    st.booleans(), st.integers(-10**30, 10**30), st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=8), st.lists(st.floats(-1e12, 1e12), max_size=12), st.lists(st.integers(-5, 5), max_size=3),
    st.just([]), st.just({"x": 1}), st.just([[1, 2], [3]]), st.just([{"a": 1}]))


_LINES = PAPER.splitlines()
_VALUE_LINES = [i for i, ln in enumerate(_LINES) if " = " in ln]
_OPTIONAL = ["shear_compliance_coeffs_mm_per_N_per_100kPa", "tendon_stiffness_N_per_m", "rayleigh_alpha_per_s",
             "pressure_area_slope", "EI_pressure_coeffs_per_100kPa", "angle_deg", "n_elements", "length_mm"]


@st.composite
def mutated_files(draw):
    lines = list(_LINES)
    for _ in range(draw(st.integers(1, 3))):
        kind = draw(st.sampled_from(["replace", "delete", "add", "tendons", "swap_unit"]))
        i = draw(st.sampled_from(_VALUE_LINES))
        key = lines[i].split(" = ")[0] if " = " in lines[i] else None
        if kind == "replace" and key:
            lines[i] = f"{key} = {toml_literal(draw(_values))}"
        elif kind == "delete":
            lines[i] = ""
        elif kind == "add":
            lines.insert(i + 1, f"{draw(st.sampled_from(_OPTIONAL))} = {toml_literal(draw(_values))}")
        elif kind == "tendons":
            n = draw(st.integers(0, 40))
            angle = draw(st.floats(-720, 720, allow_nan=False))
            lines += [f"\n[[tendons]]\ndistance_mm = 27.5\nangle_deg = {angle!r}"] * n
        elif kind == "swap_unit" and key and "_" in key:
            stem, unit = key.rsplit("_", 1)
            other = draw(st.sampled_from(["m", "mm", "kPa", "Pa", "N", "deg", "rad", "g", "kg", "s", "bar"]))
            lines[i] = lines[i].replace(key, f"{stem}_{other}", 1)
    return "\n".join(lines)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(mutated_files())
def test_any_mutation_of_a_valid_file_gives_an_actuator_or_a_config_error(text):
    import tomllib
    try:
        tomllib.loads(text)
    except tomllib.TOMLDecodeError:
        return                                     # not TOML: the loader's own first check, tested elsewhere
    try:
        p = ActuatorParams.from_toml_string(text, where="lab.toml")
    except ConfigError as exc:
        msg = str(exc)
        assert msg.startswith("lab.toml") and "\n" not in msg and "pydantic" not in msg
        return
    assert isinstance(p, ActuatorParams)
    assert 3 <= p.n_tendons <= 16 and 1 <= p.n_elements <= 200
    angles = sorted(a % (2 * math.pi) for a in p.tendon_angles)
    gaps = [b - a for a, b in zip(angles, angles[1:])] + [angles[0] + 2 * math.pi - angles[-1]]
    assert min(gaps) >= math.pi / 180 - 1e-12
    assert all(abs(s) <= 0.1 for s in p.shear_compliance)
    assert ActuatorParams.from_toml_string(p.to_toml()) == p
