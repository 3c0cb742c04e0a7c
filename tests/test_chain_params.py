"""The multi-segment actuator description (ancf.chain): TOML round trip, today's files unchanged, typed errors
that name the key, and `bellows params` for a chain (docs/multisegment.md)."""

import math
import pathlib

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from ancf import ActuatorParams, Tendon, presets
from ancf.chain import Cap, ChainParams, load_actuator, load_actuator_string
from ancf.errors import ConfigError
from validation.commands.main import app, main
from toml_values import toml_literal

PRESETS = pathlib.Path(presets.__file__).parent
runner = CliRunner()


def _two(cap=None, angles2=(60.0, 180.0, 300.0), **chain):
    p = presets.paper()
    s1 = p.replace(length=0.08, n_elements=3, tip_mass=0.0, tool_offset=0.0, name="s1")
    s2 = p.replace(length=0.08, n_elements=3, name="s2",
                   tendons=tuple(Tendon(distance=0.0275, angle=math.radians(a)) for a in angles2))
    return ChainParams(segments=(s1, s2), caps=(cap or Cap(mass=0.01, length=0.01),), **chain)


def test_todays_file_loads_as_actuator_params():
    for name in ("paper", "four_tendon"):
        path = PRESETS / f"{name}.toml"
        out = load_actuator(path)
        assert isinstance(out, ActuatorParams)
        assert out == ActuatorParams.from_toml(path)
        one = ChainParams.from_toml(path)
        assert one.n_segments == 1 and one.segments[0] == out and one.caps == ()


def test_two_segment_preset_round_trips_and_states_its_choice():
    c = presets.two_segment()
    assert c.n_segments == 2 and c.n_tendons == 6 and c.tendon_segment == (0, 0, 0, 1, 1, 1)
    # each segment is the paper bellows at half length: the same section law, half the length and elements
    paper = presets.paper()
    for s in c.segments:
        assert s.length == pytest.approx(paper.length / 2) and s.n_elements == paper.n_elements // 2
        np.testing.assert_allclose(s.stiffness.ea, paper.stiffness.ea, rtol=1e-12)
        np.testing.assert_allclose(s.stiffness.ei, paper.stiffness.ei, rtol=1e-12)
    assert c.length == pytest.approx(0.17)
    assert ChainParams.from_toml_string(c.to_toml()) == c


@settings(max_examples=25, deadline=None)
@given(mass=st.floats(0.0, 0.5), length=st.floats(0.0, 0.05), frac=st.floats(0.0, 1.0),
       l1=st.floats(0.02, 0.3), n1=st.integers(1, 8), junction=st.sampled_from(["free", "continuous"]))
def test_chain_toml_round_trip(mass, length, frac, l1, n1, junction):
    base = _two(Cap(mass=mass, length=length, mass_offset=frac * length), junction_stretch=junction)
    c = base.model_copy(update={"segments": (base.segments[0].replace(length=l1, n_elements=n1),
                                             base.segments[1])})
    c = ChainParams(**{k: getattr(c, k) for k in ("name", "segments", "caps", "junction_stretch")})
    back = load_actuator_string(c.to_toml())
    assert isinstance(back, ChainParams) and back == c


def test_cap_offset_defaults_to_the_middle():
    assert Cap(mass=0.01, length=0.02).mass_offset == 0.01


CHAIN = (PRESETS / "two_segment.toml").read_text()


@pytest.mark.parametrize("edit, words", [
    (lambda t: t[:t.index("[[cap]]")], ["2 [[segment]] tables need 1 [[cap]]"]),
    (lambda t: t.replace("length_mm = 10 ", "length = 10 "), ["[[cap]][0]", "'length' needs an explicit unit"]),
    (lambda t: t.replace("mass_offset_mm = 5", "mass_offset_mm = 50"), ["mass_offset", "within the cap's length"]),
    (lambda t: t.replace("\nmass_g = 10 ", "\nmas_g = 10 "), ["[[cap]][0]", "unknown key 'mas_g'"]),
    (lambda t: t.replace('name = "distal"\nlength_mm = 80', 'name = "distal"\nlength = 80'),
     ["[[segment]][1]", "'length' needs an explicit unit"]),
    (lambda t: t.replace("angle_deg = 60", "angle_deg = 120.5"), ["segment 1 tendon 2", "segment 2 tendon 1"]),
    (lambda t: t.replace('name = "proximal"', 'name = "proximal"\ntool_offset_mm = 5'), ["segment 1", "tool_offset"]),
    (lambda t: t.replace('name = "distal"', 'name = "distal"\nfree_base_stretch = true'),
     ["segment 2", "free_base_stretch"]),
    (lambda t: t.replace('name = "distal"', 'name = "distal"\ngravity_m_per_s2 = [0, 0, -9.81]'),
     ["[[segment]][1]", "gravity_m_per_s2", "the chain's"]),
    (lambda t: t.replace('junction_stretch = "free"', 'junction_stretch = "loose"'), ["junction_stretch", "free"]),
    (lambda t: t.replace('a_N = 213.76\nb_N = -91.008\nD_a_mm = 29.59\n\n[[segment.tendons]]\ndistance_mm = 27.5\n'
                         'angle_deg = 60', 'a_N = 213.76\nb_N = -91.008\nD_a_mm = 29.59\n\n[[segment.tendons]]\n'
                         'distance_mm = 27500\nangle_deg = 60'), ["[[segment]][1]", "distance_mm", "implausible"]),
])
def test_bad_chain_files_name_the_key(edit, words):
    text = edit(CHAIN)
    assert text != CHAIN
    with pytest.raises(ConfigError) as err:
        load_actuator_string(text, "chain.toml")
    for w in words:
        assert w in str(err.value), (w, str(err.value))


def test_cap_without_segments_is_an_error():
    text = (PRESETS / "paper.toml").read_text() + "\n[[cap]]\nmass_g = 1\n"
    with pytest.raises(ConfigError, match=r"\[\[cap\]\] tables need \[\[segment\]\]"):
        load_actuator_string(text)


def test_python_api_rules():
    with pytest.raises(ConfigError, match="2 segments need 1 caps"):
        ChainParams(segments=_two().segments)
    with pytest.raises(ConfigError, match="same angle"):
        _two(angles2=(0.5, 180.0, 300.0))
    with pytest.raises(ConfigError, match="mass"):
        Cap(mass=-1.0)


def test_cli_params_writes_a_chain_file_that_reads_back(tmp_path, capsys):
    out = tmp_path / "chain.toml"
    res = runner.invoke(app, ["params", "--preset", "two_segment", "--out", str(out)])
    assert res.exit_code == 0, res.output
    assert load_actuator(out) == presets.two_segment()
    res = runner.invoke(app, ["params", "--preset", str(out)])          # a chain file prints back the same
    assert res.exit_code == 0 and load_actuator_string(res.output) == presets.two_segment()
    with pytest.raises(SystemExit) as info:                              # never overwritten without --force
        main(["params", "--preset", "two_segment", "--out", str(out)])
    assert info.value.code == 2
    assert "--force" in capsys.readouterr().err


def test_single_segment_commands_refuse_a_chain_clearly(capsys):
    with pytest.raises(SystemExit) as info:                              # fk / locked / compliance take chains
        main(["ik", "--preset", "two_segment", "--target-mm", "0,0,150"])
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and "multi-segment" in err
    with pytest.raises(ConfigError, match="multi-segment"):
        presets.get(str(PRESETS / "two_segment.toml"))


_VALUES = st.one_of(st.booleans(), st.integers(-10**20, 10**20), st.floats(allow_nan=True, allow_infinity=True),
                    st.text(max_size=6), st.lists(st.floats(-1e9, 1e9), max_size=5), st.just({"x": 1}),
                    st.just([{"a": 1}]), st.just([[1, 2]]))


_LINES = CHAIN.splitlines()
_KEYED = [i for i, ln in enumerate(_LINES) if " = " in ln]


@settings(max_examples=150, deadline=None)
@given(data=st.data())
def test_a_mutated_chain_file_loads_or_raises_config_error(data):
    """Any value in any key (and deleted or repeated tables): a chain, or a ConfigError — never another error."""
    lines = list(_LINES)
    for _ in range(data.draw(st.integers(1, 3))):
        i = data.draw(st.sampled_from(_KEYED))
        kind = data.draw(st.sampled_from(["replace", "delete", "table"]))
        if kind == "replace":
            lines[i] = f"{lines[i].split(' = ')[0]} = {toml_literal(data.draw(_VALUES))}"
        elif kind == "delete":
            lines[i] = ""
        else:
            lines.append(data.draw(st.sampled_from(["[[segment]]\nlength_mm = 80", "[[cap]]\nmass_g = 1",
                                                    "[[segment.tendons]]\nangle_deg = 7\ndistance_mm = 20"])))
    try:
        out = load_actuator_string("\n".join(lines) + "\n", "m.toml")
    except ConfigError as exc:
        assert str(exc).startswith("m.toml"), str(exc)
        return
    assert isinstance(out, ChainParams) and load_actuator_string(out.to_toml()) == out
