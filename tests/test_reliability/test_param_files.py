"""Parameter files: values of the wrong type are rejected (never taken without their unit conversion),
implausible magnitudes for the stated unit are rejected, every failure is one ConfigError (no pydantic or
Python traceback), and a file the product writes always reads back to an equal object."""

import math

import numpy as np
import pytest

try:  # Python >= 3.11
    import tomllib
except ModuleNotFoundError:  # pragma: no cover
    import tomli as tomllib
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from ancf import ActuatorParams, StiffnessLaw, Tendon, presets
from ancf.errors import ConfigError

PAPER_TOML = presets.paper().to_toml()

# an engineering-unit file like the README's example
MM_FILE = """
name = "mine"
length_mm = 160
D_eff_mm = 26.05
tip_mass_g = 50
tension_max_N = 5
pressure_max_kPa = 120

[stiffness]
law = "constant"
EA_N = 767.2
EI_N_m2 = 0.084

[[tendons]]
distance_mm = 27.5
angle_deg = 0
[[tendons]]
distance_mm = 27.5
angle_deg = 120
[[tendons]]
distance_mm = 27.5
angle_deg = 240
"""


def test_engineering_units_are_converted():
    p = ActuatorParams.from_toml_string(MM_FILE)
    assert p.length == pytest.approx(0.16) and p.tip_mass == pytest.approx(0.05)
    assert p.tendons[1].angle == pytest.approx(2 * math.pi / 3) and p.pressure_max == pytest.approx(120e3)


@pytest.mark.parametrize("old,new,match", [
    ("tip_mass_g = 50", 'tip_mass_g = "50"', "quoted text"),            # would have been 50 kg
    ("tip_mass_g = 50", "tip_mass_g = true", "bool"),
    ("length_mm = 160", 'length_mm = "160"', "quoted text"),
    ("EA_N = 767.2", 'EA_N = "767.2"', "quoted text"),
    ("distance_mm = 27.5\nangle_deg = 0", 'distance_mm = 27.5\nangle_deg = "0"', "quoted text"),
    ('name = "mine"', "name = 5", "text"),
    ('name = "mine"', 'name = "mine"\nn_elements = 6.0', "whole number"),
    ('name = "mine"', 'name = "mine"\nn_elements = true', "whole number"),
    ('name = "mine"', 'name = "mine"\nfree_base_stretch = 1', "true or false"),
    ('name = "mine"', 'name = "mine"\nbase_axis = ["1", 0, 0]', "quoted text"),
    # implausible magnitudes for the stated unit
    ("length_mm = 160", "length_mm = 0.16", "implausible"),              # metres written under _mm
    ("length_mm = 160", "length_m = 160", "implausible"),                # millimetres under _m
    ("distance_mm = 27.5\nangle_deg = 0", "distance_mm = 0.0275\nangle_deg = 0", "implausible"),
    ("tip_mass_g = 50", "tip_mass_kg = 50", "implausible"),
    ("pressure_max_kPa = 120", "pressure_max_Pa = 120", "implausible"),   # 120 Pa: meant kPa
    ("pressure_max_kPa = 120", "pressure_max_kPa = 120000", "implausible"),
    ("D_eff_mm = 26.05", "D_eff_mm = 0.02605", "implausible"),
    ("distance_mm = 27.5\nangle_deg = 120", "distance_mm = 27.5\nangle_rad = 120", "implausible"),
    ("EA_N = 767.2", "EA_N = 7.672e12", "implausible"),
    ('name = "mine"', 'name = "mine"\ngravity_m_per_s2 = [0, 0, -9810]', "gravity"),
])
def test_wrong_types_and_magnitudes_are_rejected(old, new, match):
    assert old in MM_FILE
    with pytest.raises(ConfigError, match=match):
        ActuatorParams.from_toml_string(MM_FILE.replace(old, new, 1))


def test_python_api_rejects_wrong_types_too():
    p = presets.paper()
    for changes in ({"tip_mass": "0.05"}, {"length": True}, {"n_elements": 6.5}, {"n_elements": True},
                    {"free_base_stretch": 1}, {"name": 3}, {"length": 160.0}, {"gravity": "down"}):
        with pytest.raises(ConfigError):
            p.replace(**changes)
    with pytest.raises(ConfigError):
        Tendon(distance="0.0275", angle=0.0)
    with pytest.raises(ConfigError):
        StiffnessLaw.constant(EA="767", EI=0.08)
    with pytest.raises(ConfigError):
        StiffnessLaw.polynomial(EA=[1.0] * 9, EI=[1.0])
    assert p.replace(n_elements=np.int64(8)).n_elements == 8     # numpy integers are integers


# ------------------------------------------------------------------------------------------ round trip
finite = dict(allow_nan=False, allow_infinity=False)
texts = st.text(st.characters(blacklist_categories=("Cs",)), max_size=30)


@st.composite
def actuator_params(draw):
    law_kind = draw(st.sampled_from(["linear", "constant", "polynomial"]))
    if law_kind == "linear":
        a = draw(st.floats(100.0, 1e4, **finite))
        law = StiffnessLaw.linear(a, draw(st.floats(-0.9 * a, 1e3, **finite)), draw(st.floats(0.005, 0.2, **finite)))
    elif law_kind == "constant":
        law = StiffnessLaw.constant(draw(st.floats(1.0, 1e5, **finite)), draw(st.floats(1e-4, 10.0, **finite)))
    else:
        law = StiffnessLaw.polynomial(EA=draw(st.lists(st.floats(1.0, 1e4, **finite), min_size=1, max_size=4)),
                                      EI=draw(st.lists(st.floats(1e-3, 1.0, **finite), min_size=1, max_size=4)))
    n_t = draw(st.integers(3, 6))
    tendons = tuple(Tendon(distance=draw(st.floats(1e-3, 0.1, **finite)),
                           angle=draw(st.floats(-math.pi, math.pi, **finite))) for _ in range(n_t))
    tmin = draw(st.floats(0.0, 2.0, **finite))
    pmin = draw(st.floats(0.0, 10e3, **finite))
    return ActuatorParams(
        name=draw(texts), description=draw(texts), length=draw(st.floats(0.01, 2.0, **finite)),
        n_elements=draw(st.integers(1, 200)), quadrature_points=draw(st.integers(4, 20)), stiffness=law,
        D_eff=draw(st.floats(0.002, 0.5, **finite)), pressure_area_slope=draw(st.floats(-1.5, 1.5, **finite)),
        tendons=tendons, line_mass=draw(st.sampled_from([0.0]) | st.floats(1e-3, 10.0, **finite)),
        tip_mass=draw(st.sampled_from([0.0]) | st.floats(1e-4, 5.0, **finite)),
        tool_offset=draw(st.sampled_from([0.0]) | st.floats(1e-3, 0.5, **finite)),
        base_axis=draw(st.sampled_from([(1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, -1.0)])),
        reference_direction=(0.0, 0.0, 1.0) if draw(st.booleans()) else (0.0, 0.0, -1.0),
        gravity=tuple(draw(st.floats(-20.0, 20.0, **finite)) for _ in range(3)),
        tension_min=tmin, tension_max=tmin + draw(st.floats(0.01, 100.0, **finite)),
        pressure_min=pmin, pressure_max=pmin + draw(st.floats(1e3, 1e6, **finite)),
        free_base_stretch=draw(st.booleans()))


@st.composite
def valid_params(draw):
    try:
        return draw(actuator_params())
    except ConfigError:
        from hypothesis import reject
        reject()


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.filter_too_much])
@given(valid_params())
def test_to_toml_reads_back_equal(p):
    text = p.to_toml()
    tomllib.loads(text)                                # valid TOML whatever the name and description hold
    back = ActuatorParams.from_toml_string(text)
    assert back == p


def test_shipped_presets_read_back_equal():
    for name in ("paper", "paper_constant", "four_tendon"):
        p = presets.get(name)
        assert ActuatorParams.from_toml_string(p.to_toml()) == p


# ------------------------------------------------------------------------------------------ fuzzing
toml_values = st.one_of(
    st.booleans(), st.integers(-10**6, 10**6), st.floats(allow_nan=False, allow_infinity=False), texts,
    st.lists(st.floats(-10.0, 10.0), max_size=4), st.just({"x": 1}), st.just([{"a": 1}]))


def _toml_value(v):
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, float):
        return repr(v) if math.isfinite(v) else "0.0"
    if isinstance(v, dict):
        return "{ x = 1 }"
    if isinstance(v, list):
        return "[" + ", ".join("{ a = 1 }" if isinstance(x, dict) else repr(float(x)) for x in v) + "]"
    return repr(v)


@settings(max_examples=200, deadline=None)
@given(st.integers(0, 200), toml_values)
def test_any_single_value_change_gives_params_or_one_config_error(line_index, value):
    """Replace the value on one line of a valid file by a value of a random type: the result is valid
    parameters or a ConfigError, never another exception."""
    lines = MM_FILE.strip().splitlines()
    candidates = [i for i, ln in enumerate(lines) if " = " in ln]
    i = candidates[line_index % len(candidates)]
    key = lines[i].split(" = ")[0]
    lines[i] = f"{key} = {_toml_value(value)}"
    text = "\n".join(lines)
    try:
        tomllib.loads(text)
    except tomllib.TOMLDecodeError:
        return                                          # our encoder made invalid TOML; not the product's case
    try:
        p = ActuatorParams.from_toml_string(text)
    except ConfigError as exc:
        assert "\n" not in str(exc) and "Traceback" not in str(exc) and "pydantic" not in str(exc)
        return
    assert isinstance(p, ActuatorParams) and p.length > 0


def test_readme_parameter_example_is_what_bellows_params_writes():
    import pathlib
    import re

    readme = (pathlib.Path(__file__).parents[2] / "README.md").read_text()
    block = re.search(r"```toml\n(.*?)```", readme, re.S).group(1)
    written = presets.paper().to_toml().splitlines()
    lines = [ln.strip() for ln in block.splitlines() if ln.strip()]
    assert len(lines) > 10
    for ln in lines:
        assert ln in written, ln
