"""Design files of an FEM bellows: units converted, unknown keys and missing units rejected, exact round trip."""

import dataclasses

import pytest

pytest.importorskip("skfem")

from ancf.errors import ConfigError  # noqa: E402
from validation.reference.designs import PRESETS, design_to_toml, load_design  # noqa: E402

def _doc_example() -> str:
    """The example design file of the module docstring (the documentation is what is tested)."""
    import textwrap
    import validation.reference.designs as d
    block = d.__doc__.split("::", 1)[1]
    lines = []
    for line in block.splitlines()[1:]:
        if line and not line.startswith("    "):
            break
        lines.append(line)
    text = textwrap.dedent("\n".join(lines))
    return text.split("\n[limits]")[0]


DOC_EXAMPLE = _doc_example()


def test_units_are_converted(tmp_path):
    p = tmp_path / "d.toml"
    p.write_text(DOC_EXAMPLE)
    g, m = load_design(p)
    assert g.length == pytest.approx(0.160) and g.wall_thickness == pytest.approx(1.6e-3)
    assert g.tendon_angles[1] == pytest.approx(2.0943951, rel=1e-7) and g.cap_mass == pytest.approx(0.018)
    assert m.mu == pytest.approx(0.8e6) and m.kappa == pytest.approx(40e6)


@pytest.mark.parametrize("name", PRESETS)
def test_every_preset_round_trips_exactly(tmp_path, name):
    g, m = load_design(name)
    p = tmp_path / f"{name}.toml"
    p.write_text(design_to_toml(g, m, name))
    g2, m2 = load_design(p)
    assert dataclasses.asdict(g2) == dataclasses.asdict(g) and m2 == m


@pytest.mark.parametrize("edit, message", [
    (("wall_thickness_mm = 1.6", "wall_thickness = 1.6"), "unit"),
    (("tip_offset_mm = 0", "tip_offset_mm = 0\ncolour = 'red'"), "colour"),
    (("length_mm = 160", "length_mm = '160'"), "length"),
    (("n_convolutions = 8", "n_convolutions = 8.5"), "n_convolutions"),
    (("mu_MPa = 0.8", "mu_furlongs = 0.8"), "mu"),
    (('model = "neo_hookean"', 'model = "rubbery"'), "model"),
])
def test_bad_files_are_config_errors(tmp_path, edit, message):
    p = tmp_path / "bad.toml"
    p.write_text(DOC_EXAMPLE.replace(*edit))
    with pytest.raises(ConfigError, match=message):
        load_design(p)


def test_unknown_preset_or_suffix_is_a_config_error():
    with pytest.raises(ConfigError, match="preset"):
        load_design("paper_wobbly")


def test_operating_limits_from_presets_and_files(tmp_path):
    from validation.reference.designs import DEFAULT_LIMITS, design_limits
    assert design_limits("paper")["pressure_max"] == pytest.approx(100e3)      # inflation limit point above
    assert design_limits("paper_stiff") == DEFAULT_LIMITS
    p = tmp_path / "d.toml"
    p.write_text(DOC_EXAMPLE + "\n[limits]\ntension_max_N = 4\npressure_max_kPa = 80\n")
    assert design_limits(p) == {"tension_max": 4.0, "pressure_max": 80e3}
    g, m = load_design(p)                                                     # the table is accepted
    back = tmp_path / "back.toml"
    back.write_text(design_to_toml(g, m, "x", limits=design_limits(p)))
    assert design_limits(back) == design_limits(p)
    for bad in ("pressure_max = 80", "pressure_max_kPa = -5", "pressure_max_kPa = true", "speed_max_kPa = 3"):
        p.write_text(DOC_EXAMPLE + f"\n[limits]\n{bad}\n")
        with pytest.raises(ConfigError):
            design_limits(p)
        with pytest.raises(ConfigError):
            load_design(p)


@pytest.mark.parametrize("edit, message", [
    (("wall_thickness_mm = 1.6", "wall_thickness_mm = 5000"), r"wall_thickness_mm = 5000 is implausible: expected 0.05 … 50 mm"),
    (("mu_MPa = 0.8", "mu_Pa = 1e15"), r"mu_Pa = 1000000000000000.0 is implausible: expected 1000 … 1e\+09 Pa"),
    (("n_convolutions = 8", "n_convolutions = 1000000000"), r"n_convolutions must be a whole number in 1 … 100"),
    (("tendon_angles_deg = [0, 120, 240]", "tendon_angles_deg = 0"), "tendon_angles_deg must be a list"),
    (("length_mm = 160", "length_mm = [160]"), "length_mm: expected one number|length_mm must be a single number"),
    (("tendon_angles_deg = [0, 120, 240]", "tendon_angles_deg = [0, 120, 120]"), "tendons 2 and 3 coincide"),
    (("tendon_angles_deg = [0, 120, 240]", "tendon_angles_deg = [0, 360]"), "tendons 1 and 2 coincide"),
    (('name = "my bellows"', "name = 3"), "name: expected text"),
])
def test_implausible_values_are_refused_at_load_naming_the_key(tmp_path, edit, message):
    p = tmp_path / "bad.toml"
    p.write_text(DOC_EXAMPLE.replace(*edit))
    with pytest.raises(ConfigError, match=message):
        load_design(p)


def _profile_design(tmp_path):
    from fem_reference import presets
    from fem_reference.profile import TableProfile, write_profile_csv
    sub = tmp_path / "walls"
    sub.mkdir()
    write_profile_csv(TableProfile.from_geometry(presets.paper_bellows("stiff"), 401), sub / "wall.csv")
    text = DOC_EXAMPLE
    for k in ("length_mm = 160\n", "root_radius_mm = 10.0", "crest_radius_mm = 19.5", "wall_thickness_mm = 1.6"):
        text = text.replace(k, "", 1)
    text = text.replace('name = "my bellows"', 'name = "my bellows"\nprofile_file = "walls/wall.csv"')
    return text


def test_design_with_a_profile_file(tmp_path):
    """The path is relative to the TOML; the table's numbers replace the sine's; the design round-trips."""
    from fem_reference import presets
    p = tmp_path / "d.toml"
    p.write_text(_profile_design(tmp_path))
    g, m = load_design(p)
    ref = presets.paper_bellows("stiff")
    assert g.is_table and g.length == pytest.approx(0.16) and g.n_convolutions == 8
    assert g.wall_thickness == pytest.approx(ref.wall_thickness, rel=1e-4)
    back = tmp_path / "elsewhere.toml"
    back.write_text(design_to_toml(g, m, 'a "quoted" name'))
    g2, m2 = load_design(back)
    assert g2 == g and m2 == m
    bad = tmp_path / "bad.toml"
    for edit, message in ((("n_convolutions = 8", "n_convolutions = 8\nwall_thickness_mm = 2"),
                           "wall_thickness must not be given with profile_file"),
                          (("walls/wall.csv", "walls/nope.csv"), "cannot read profile file .*nope.csv"),
                          (("n_convolutions = 8\n", ""), "missing n_convolutions")):
        bad.write_text(p.read_text().replace(*edit))
        with pytest.raises(ConfigError, match=message):
            load_design(bad)


# --------------------------------------------------------------------------- any file: a design or a ConfigError
from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

_KEYS = ["name", "length_mm", "length", "n_convolutions", "root_radius_mm", "crest_radius_mm", "wall_thickness_mm",
         "collar_length_mm", "tendon_radius_mm", "tendon_angles_deg", "tendon_angles_rad", "cap_mass_g",
         "cap_com_offset_mm", "tip_offset_mm", "profile_file", "colour", "length_m"]
_MAT_KEYS = ["model", "mu_MPa", "kappa_MPa", "c10_MPa", "c01_MPa", "density_kg_per_m3", "formulation", "mu"]
_scalars = st.one_of(st.integers(-10**12, 10**12), st.floats(allow_nan=True, allow_infinity=True),
                     st.booleans(), st.text(st.characters(codec="ascii", exclude_characters='"\\\n\r'), max_size=8),
                     st.sampled_from(["neo_hookean", "mooney_rivlin", "nope.csv", "", "displacement"]))
_values = st.one_of(_scalars, st.lists(_scalars, max_size=4))


def _toml_value(v) -> str:
    import json
    import math
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float) and not math.isfinite(v):
        return "nan" if math.isnan(v) else ("inf" if v > 0 else "-inf")
    if isinstance(v, list):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    return json.dumps(v) if isinstance(v, str) else repr(v)


def _example_values() -> dict:
    import tomllib
    return tomllib.loads(DOC_EXAMPLE)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(top=st.dictionaries(st.sampled_from(_KEYS), _values, max_size=6),
       mat=st.dictionaries(st.sampled_from(_MAT_KEYS), _values, max_size=4),
       drop=st.sets(st.sampled_from(_KEYS + _MAT_KEYS), max_size=3))
def test_any_design_file_gives_a_design_or_a_config_error(tmp_path, top, mat, drop):
    base = _example_values()
    base_mat = base.pop("material")
    base.update(top)
    base_mat.update(mat)
    for k in drop:
        base.pop(k, None)
        base_mat.pop(k, None)
    lines = [f"{k} = {_toml_value(v)}" for k, v in base.items()] + ["[material]"]
    lines += [f"{k} = {_toml_value(v)}" for k, v in base_mat.items()]
    p = tmp_path / "h.toml"
    p.write_text("\n".join(lines) + "\n")
    try:
        g, m = load_design(p)
    except ConfigError:
        return
    assert g.length > 0 and m.mu > 0 and len(set(g.tendon_angles)) == len(g.tendon_angles)


def test_a_design_with_fewer_tendons_than_an_actuator_file_takes_is_refused_before_the_fem():
    """The FEM solves a bellows with 1 or 2 tendons; the reduced model's actuator file takes 3 … 16: identifying it
    is refused up front (no FEM solve, no file that cannot be written)."""
    import dataclasses
    import math

    from ancf.errors import ConfigError
    from fem_reference import presets as fem_presets
    from validation.identification.identify import from_fem
    geo = dataclasses.replace(fem_presets.straight_tube_test(), tendon_angles=(0.0, math.pi))
    with pytest.raises(ConfigError, match="2 tendon"):
        from_fem(geo, fem_presets.paper_material())
