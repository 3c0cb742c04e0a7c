"""``bellows fk | locked | compliance`` on a multi-segment actuator (docs/multisegment.md, "Command line").

The numbers are checked three ways: against :class:`ancf.chain_model.ChainModel` called directly; against the
one-segment commands, through a chain file of one segment (a different code path: the one-segment model and
its compliance module); and against the mechanics itself — compliance against finite differences of the
command's own FK, the locked FK's complementarity and its lock-at-a-state round trip, the caps' and tool's rigid
lengths, and the ParaView polylines' lengths against the tendon lengths.  Bad inputs give one ``error:`` line
and exit status 2.
"""

from __future__ import annotations

import json

import meshio
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from ancf import presets
from ancf.chain import ChainParams
from ancf.chain_model import ChainModel
from ancf.cli import parse_pressures
from ancf.errors import InputError
from validation.commands.main import app, main

runner = CliRunner()

T6 = "1,0,0,0.5,0,0"
T6_N = np.array([1.0, 0, 0, 0.5, 0, 0])
P2 = "30,10"
P2_PA = np.array([30e3, 10e3])


def _json(args: list) -> dict:
    res = runner.invoke(app, [*args, "--json"])
    assert res.exit_code == 0, res.output
    return json.loads(res.output)


@pytest.fixture(scope="module")
def two():
    return ChainModel(presets.two_segment())


@pytest.fixture(scope="module")
def one_file(tmp_path_factory):
    """The paper actuator written as a chain file of one [[segment]] table."""
    path = tmp_path_factory.mktemp("chain") / "one.toml"
    path.write_text(ChainParams(name="one", segments=(presets.paper(),)).to_toml())
    return str(path)


# ---- against ChainModel ----------------------------------------------------------------------------------------

def test_fk_matches_the_chain_model(two):
    out = _json(["fk", "--preset", "two_segment", "--tensions-n", T6, "--pressure-kpa", P2,
                 "--tip-force-n", "0,0.1,-0.2"])["fk"]
    eq = two.fk(T6_N, P2_PA, (0, 0.1, -0.2))
    assert np.allclose(out["tip_m"], eq.tip, atol=1e-12)
    assert np.allclose(out["tendon_lengths_m"], eq.tendon_lengths, atol=1e-12)
    assert out["pressures_Pa"] == [30e3, 10e3] and out["tensions_N"] == T6_N.tolist()
    segs, caps = out["segments"], out["caps"]
    assert [s["tendons"] for s in segs] == [[1, 2, 3], [4, 5, 6]]
    assert [s["pressure_Pa"] for s in segs] == [30e3, 10e3]
    assert np.allclose([s["end_m"] for s in segs], eq.segment_ends, atol=1e-12)
    q2 = two.sys.segment_q(eq.q, 1)
    assert np.allclose(segs[1]["start_m"], q2[:3], atol=1e-12) and np.allclose(caps[0]["end_m"], q2[:3], atol=1e-12)
    assert segs[0]["start_m"] == [0.0, 0.0, 0.0] and caps[0]["start_m"] == segs[0]["end_m"]
    assert out["model"]["segments"] == 2 and out["stable"]


def test_the_rigid_parts_keep_their_lengths():
    """A cap is 10 mm long and the tool point sits tool_offset beyond the distal end, at any load."""
    chain = presets.two_segment()
    for args in (["--tensions-n", T6, "--pressure-kpa", P2], ["--tensions-n", "0,0,3,0,2,0", "--tip-force-n", "0.3,0,0"]):
        out = _json(["fk", "--preset", "two_segment", *args])["fk"]
        cap = out["caps"][0]
        assert np.linalg.norm(np.subtract(cap["end_m"], cap["start_m"])) == pytest.approx(chain.caps[0].length,
                                                                                         abs=1e-12)
        assert cap["length_m"] == chain.caps[0].length and cap["mass_kg"] == chain.caps[0].mass
        tool = np.linalg.norm(np.subtract(out["tip_m"], out["segments"][-1]["end_m"]))
        assert tool == pytest.approx(chain.segments[-1].tool_offset, abs=1e-12)


def test_n_elements_sets_every_segment(two):
    out = _json(["fk", "--preset", "two_segment", "--tensions-n", T6, "--n-elements", "4"])["fk"]
    c = presets.two_segment()
    fine = ChainModel(ChainParams(name=c.name, caps=c.caps, segments=tuple(s.replace(n_elements=4)
                                                                           for s in c.segments)))
    assert np.allclose(out["tip_m"], fine.fk(T6_N, np.zeros(2)).tip, atol=1e-12)
    assert not np.allclose(out["tip_m"], two.fk(T6_N, np.zeros(2)).tip, atol=1e-9)


# ---- against the one-segment commands --------------------------------------------------------------------------

def test_a_one_segment_chain_file_gives_the_one_segment_answers(one_file):
    args = ["--tensions-n", "2,0,0", "--pressure-kpa", "30", "--tip-force-n", "0,0,-0.49"]
    chain, rod = _json(["fk", "--preset", one_file, *args])["fk"], _json(["fk", *args])["fk"]
    assert np.allclose(chain["tip_m"], rod["tip_m"], atol=1e-12)
    assert np.allclose(chain["tendon_lengths_m"], rod["tendon_lengths_m"], atol=1e-12)
    assert chain["model"]["kind"] == "ANCF rod chain" and chain["caps"] == []
    lengths = ",".join(f"{x * 1e3:.6f}" for x in rod["tendon_lengths_m"])
    args = ["--lengths-mm", lengths, "--pressure-kpa", "30", "--tip-force-n", "0,0,-0.98"]
    chain, rod = _json(["locked", "--preset", one_file, *args])["locked"], _json(["locked", *args])["locked"]
    assert np.allclose(chain["tip_m"], rod["tip_m"], atol=1e-9)
    assert np.allclose(chain["tensions_N"], rod["tensions_N"], atol=1e-6)
    assert chain["active"] == rod["active"]


def test_a_one_segment_chain_file_gives_the_one_segment_compliances(one_file):
    for args in (["--tensions-n", "2,0,0", "--pressure-kpa", "25"],
                 ["--tensions-n", "1,0.5,0", "--pressure-kpa", "40", "--load-direction", "0,1,0"]):
        chain, rod = _json(["compliance", "--preset", one_file, *args]), _json(["compliance", *args])
        for form in ("tension", "locked/exact"):
            a, b = np.array(chain["forms"][form]["C_p_m_per_N"]), np.array(rod["forms"][form]["C_p_m_per_N"])
            assert np.allclose(a, b, rtol=1e-9, atol=1e-12 * np.abs(b).max()), form
            assert chain["forms"][form]["active"] == rod["forms"][form]["active"]
        assert set(chain["forms"]) == {"tension", "locked/exact"}


# ---- against the mechanics -------------------------------------------------------------------------------------

def test_compliance_is_the_derivative_of_the_fk_tip():
    """C (tensions held) against central differences of ``bellows fk``'s tip in the tip force, column by column."""
    base = ["--preset", "two_segment", "--tensions-n", T6, "--pressure-kpa", P2]
    C = np.array(_json(["compliance", *base])["forms"]["tension"]["C_p_m_per_N"])
    h = 1e-3
    for i in range(3):
        tips = []
        for s in (1, -1):
            F = np.zeros(3)
            F[i] = s * h
            tips.append(_json(["fk", *base, "--tip-force-n", ",".join(map(str, F))])["fk"]["tip_m"])
        fd = (np.array(tips[0]) - np.array(tips[1])) / (2 * h)
        assert np.allclose(C[:, i], fd, rtol=1e-4, atol=1e-4 * np.abs(C).max()), (i, C[:, i], fd)


def test_locked_at_an_fk_state_holds_that_state_and_is_complementary():
    """Lock the tendon lengths of an FK state: the same load gives back its tensions and tip; a heavier load
    keeps T ≥ 0, slack ≥ 0, T·slack = 0 and l + slack = l⁰."""
    T = "2,0,0.5,0,1,0"
    fk = _json(["fk", "--preset", "two_segment", "--tensions-n", T, "--pressure-kpa", P2])["fk"]
    l0 = np.array(fk["tendon_lengths_m"])
    lengths = ",".join(f"{x * 1e3:.9f}" for x in l0)
    same = _json(["locked", "--preset", "two_segment", "--lengths-mm", lengths, "--pressure-kpa", P2])["locked"]
    assert np.allclose(same["tip_m"], fk["tip_m"], atol=1e-8)
    assert np.allclose(same["tensions_N"], fk["tensions_N"], atol=1e-4)
    out = _json(["locked", "--preset", "two_segment", "--lengths-mm", lengths, "--pressure-kpa", P2,
                 "--tip-force-n", "0,0,-0.5"])["locked"]
    Tl, slack = np.array(out["tensions_N"]), np.array(out["slack_m"])
    assert np.all(Tl >= 0) and np.all(slack >= 0) and np.allclose(Tl * slack, 0, atol=1e-12)
    assert np.allclose(np.array(out["tendon_lengths_m"]) + slack, np.round(l0, 12), atol=1e-9)
    assert [s["slack_m"] for s in out["segments"]] == [out["slack_m"][:3], out["slack_m"][3:]]
    assert out["tip_m"][2] < same["tip_m"][2]                          # the load pulls the tip down


def test_vtu_polylines(tmp_path, two):
    """The centreline runs from the base to the distal end through the cap; each tendon's polyline is as long as
    its tendon (to the sampling's chord error); a one-segment chain's mesh is the one-segment rod's."""
    out = _json(["fk", "--preset", "two_segment", "--tensions-n", T6, "--pressure-kpa", P2,
                 "--vtu", str(tmp_path / "c.vtu")])["fk"]
    mesh = meshio.read(tmp_path / "c.vtu")
    curve = np.concatenate(mesh.cell_data["curve"])
    lines = np.concatenate([c.data for c in mesh.cells])
    for j in range(7):
        seg = lines[curve == j]
        pts = mesh.points[np.concatenate([seg[:, 0], seg[-1:, 1]])]
        if j == 0:
            assert np.allclose(pts[0], 0, atol=1e-12)
            assert np.allclose(pts[-1], out["segments"][1]["end_m"], atol=1e-12)
        else:
            length = np.linalg.norm(np.diff(pts, axis=0), axis=1).sum()
            assert length == pytest.approx(out["tendon_lengths_m"][j - 1], rel=2e-4)
            assert np.all(mesh.point_data["tension_N"][seg[:, 0]] == T6_N[j - 1])
    assert set(mesh.point_data["segment"]) == {1.0, 2.0}


def test_one_segment_chain_mesh_is_the_rod_mesh(one_file):
    from ancf import Model
    from ancf.cli_chain import chain_mesh
    from ancf.paraview import rod_mesh
    cm, rod = ChainModel(presets.get_any(one_file)), Model(presets.paper())
    eq = cm.fk((2.0, 0, 0.5), 30e3)
    a, b = chain_mesh(cm, eq), rod_mesh(rod, eq.q, eq.tensions, 30e3)
    assert np.allclose(a.points, b.points, atol=1e-12)
    for name in b.point_data:
        assert np.allclose(a.point_data[name], b.point_data[name], rtol=1e-12, atol=1e-12), name


# ---- bad inputs ------------------------------------------------------------------------------------------------

BAD = [
    (["fk", "--tensions-n", "1,0,0"], "--tensions-n: expected 6 values"),
    (["fk", "--tensions-n", "1,0,0,0,0,0,0"], "T4–T6 of segment 2"),
    (["fk", "--pressure-kpa", "30"], "--pressure-kpa: expected 2 values, one per chamber"),
    (["fk", "--pressure-kpa", "30,10,5"], "--pressure-kpa: expected 2 values"),
    (["fk", "--tensions-n", "0,0,0,-1,0,0"], "T4 = -1 N (segment 2)"),
    (["fk", "--tensions-n", "0,0,0,0,9,0"], "outside its limits"),
    (["fk", "--pressure-kpa", "30,-5"], "chamber 2"),
    (["fk", "--pressure-kpa", "500,0"], "chamber 1"),
    (["fk", "--pressure-kpa", "30,nan"], "--pressure-kpa"),
    (["fk", "--tensions-n", "1,0,0,inf,0,0"], "--tensions-n"),
    (["fk", "--n-elements", "0"], "--n-elements"),
    (["locked", "--lengths-mm", "160,160,160"], "--lengths-mm: expected 6 values"),
    (["locked", "--lengths-mm", "80,80,80,160,0,160"], "> 0 mm"),
    (["locked", "--lengths-mm", "80,80,80,160,-1,160"], "> 0 mm"),
    (["locked", "--lengths-mm", "80,80,80,170,170,170", "--method", "gamma"], "active-set method only"),
    (["locked", "--lengths-mm", "80,80,80,170,170,170", "--pressure-kpa", "0,200"], "chamber 2"),
    (["compliance", "--tensions-n", "1,0"], "--tensions-n: expected 6 values"),
    (["compliance", "--pressure-kpa", "1,2,3"], "--pressure-kpa"),
    (["compliance", "--load-direction", "0,0,0"], "non-zero"),
]


@pytest.mark.parametrize("args, says", BAD, ids=[" ".join(a) for a, _ in BAD])
def test_bad_chain_inputs_are_one_error_line(capsys, tmp_path, monkeypatch, args, says):
    monkeypatch.setenv("BELLOWS_TRACEBACK_DIR", str(tmp_path))
    with pytest.raises(SystemExit) as info:
        main([args[0], "--preset", "two_segment", *args[1:]])
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert info.value.code == 2 and len(err) == 1 and err[0].startswith("error: "), err
    assert says in err[0], err[0]


def test_a_one_segment_actuator_takes_one_pressure(capsys):
    with pytest.raises(SystemExit) as info:
        main(["fk", "--pressure-kpa", "30,10"])
    assert info.value.code == 2 and "expected 1 value (one chamber)" in capsys.readouterr().err


def test_ik_still_refuses_a_chain(capsys):
    with pytest.raises(SystemExit) as info:
        main(["ik", "--preset", "two_segment", "--target-mm", "150,0,0"])
    assert info.value.code == 2 and "multi-segment" in capsys.readouterr().err


# ---- the list parsers ------------------------------------------------------------------------------------------

@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(-1e6, 1e6, allow_nan=False), min_size=1, max_size=9), st.integers(1, 8))
def test_pressures_take_exactly_one_value_per_chamber(values, chambers):
    text = ",".join(repr(v) for v in values)
    if len(values) == chambers:
        assert np.array_equal(parse_pressures(text, chambers), np.array(values) * 1e3)
    else:
        with pytest.raises(InputError, match=rf"--pressure-kpa: expected {chambers} value"):
            parse_pressures(text, chambers)
    assert np.array_equal(parse_pressures(None, chambers), np.zeros(chambers))
