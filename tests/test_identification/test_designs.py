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
