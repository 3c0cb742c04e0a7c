"""``bellows paper segments``: one segment against two (validation.paper.segments; docs/multisegment.md, "What a
second segment buys").

Checked against independent computations: the existing workspace study's clouds, cold FK solves of the tensions the
study returns (their tip and tip direction), the exact cancellation of a pressure change by equal tendon tensions
(Δp A_eff = 3 ΔT leaves one segment's state unchanged), and the committed table against the committed data."""

import json
import pathlib
import re

import numpy as np
import pytest

from ancf import ChainModel, presets
from ancf.chain import ChainParams
from validation.commands.main import main
from validation.paper import segments as sg
from validation.paper.workspace_volume import workspace

ROOT = pathlib.Path(__file__).resolve().parents[1]
DATA = ROOT / "docs" / "data" / "paper_segments.json"


@pytest.fixture(scope="module")
def models():
    return ChainModel(presets.two_segment()), ChainModel(sg.single_params(0.17))


@pytest.fixture(scope="module")
def point(models):
    T, p = sg.POINTS[0]
    return models[1].fk(T, [p]).tip, p


def test_single_cloud_is_the_workspace_studys():
    """The single segment's cloud is the TPHD cloud of bellows paper workspace for the same samples and seed; the
    chain code run on a one-segment chain draws the same inputs and finds the same tips (to 1e-9 m)."""
    ref = workspace(samples=12, seed=3, params="paper", workers=1, progress=False, figure=False)["clouds"]["TPHD"]
    own = sg.single_workspace(presets.paper(), 12, 3)
    np.testing.assert_array_equal(own["tips"], ref["tips"])
    np.testing.assert_array_equal(own["inputs"], ref["inputs"])
    one = ChainParams(name="paper", segments=(presets.paper(),))
    ch = sg.chain_workspace(one, 12, 3)
    np.testing.assert_array_equal(ch["inputs"], ref["inputs"])
    ok = ref["ok"]
    assert ok.sum() >= 10 and np.array_equal(ch["status"] == 0, ok)
    np.testing.assert_allclose(ch["tips"][ok], ref["tips"][ok], atol=1e-9)


def test_a_collapsed_sample_is_counted_not_solved():
    chain = presets.two_segment()
    assert sg.chain_certainly_collapsed(chain, [5.0] * 6, [0.0, 0.0])
    assert not sg.chain_certainly_collapsed(chain, [1.0] * 6, [60e3, 60e3])
    r = sg.solve_chain_chunk({"chain": chain, "X": np.array([[5.0] * 6 + [0.0, 0.0]]), "start": 0})
    assert r["status"].tolist() == [1] and np.isnan(r["tips"]).all()


def test_one_segment_has_one_direction_at_a_point(models, point):
    """3 tensions, 3 constraints: ∂p/∂T is regular (rank 3) and IK from another start returns the same state; over
    the pressures that reach the point the direction does not move: in this plane bend (T2 = T3) a pressure step Δp
    is cancelled by ΔT = Δp A_eff / 3 on each tendon (the same axial force, the same bending moments)."""
    _, one = models
    target, p = point
    sd = sg.single_direction(one, target, p)
    assert sd["rank"] == 3 and sd["singular_values"].min() > 1e-3 * sd["singular_values"].max()
    other = one.ik(target, [p], tensions0=[4.0, 0.1, 4.0])
    assert sg.angle(other.tip_rotation[:, 0], sd["direction"]) < 1e-7
    dp = 10e3
    up = one.ik(target, [p + dp])
    np.testing.assert_allclose(up.tensions - sd["state"].tensions, dp * one.chain.segments[0].A_eff / 3, atol=1e-6)
    sweep = sg.single_pressure_sweep(one, target, [p, p + dp])
    assert len(sweep["pressures_Pa"]) == 2 and sweep["extent_rad"] < 1e-6


def test_two_segments_have_a_set_of_directions(models, point):
    """At the same point and pressures the chain reaches tip directions several degrees apart; every pose the study
    counts as reachable is checked by a cold FK of its tensions (the target to 1e-8 m, the direction asked)."""
    chain, _ = models
    target, p = point
    ds = sg.direction_set(chain, target, [p, p], rays=4, bisections=0)
    lo, hi = ds["extent_rad"]
    assert np.degrees(lo) >= 8 and hi >= lo
    psis = ds["azimuths_rad"]
    for s in ds["states"][1:]:
        eq = chain.fk(s.tensions, [p, p])
        assert np.linalg.norm(eq.tip - target) < 1e-8
        d = eq.tip_rotation[:, 0]
        asked = [sg.tilt(ds["center_direction"], th, psi) for psi in psis for th in (np.radians(8), np.radians(16),
                                                                                     np.radians(32))]
        assert min(sg.angle(d, a) for a in asked) < 1e-6
    spread = max(sg.angle(a, b) for a in ds["directions"] for b in ds["directions"])
    assert spread >= lo - 1e-9


def test_stiffness_range_at_the_point(models, point):
    """The IK's minimum of uᵀCu lies at or below every sampled state's, and the locked compliance below the held one
    (holding the tendons' lengths stiffens)."""
    chain, _ = models
    target, p = point
    ds = sg.direction_set(chain, target, [p, p], rays=2, bisections=0)
    st = sg.stiffness_range(chain, target, [p, p], ds["states"], [0, 0, 1])
    assert st["min_ik_m_per_N"] <= st["held_m_per_N"][0] + 1e-12
    assert st["held_m_per_N"][1] > st["held_m_per_N"][0]
    assert st["locked_m_per_N"][1] < st["held_m_per_N"][0]


def test_obstacle_case(models):
    """The sphere crosses the single segment's shape; the chain reaches the same tip with every body point outside
    radius + margin (the clearance measured on a cold FK of the chain's tensions, centreline by kin.interpolate)."""
    from ancf import kinematics as kin
    chain, one = models
    T, p = sg.POINTS[sg.OBSTACLE["point"]]
    s_eq = one.fk(T, [p])
    ob = sg.obstacle_case(chain, one, s_eq, [p, p], radius=sg.OBSTACLE["radius_m"], offset=sg.OBSTACLE["offset_m"],
                          margin=sg.OBSTACLE["margin_m"])
    assert ob["single_clearance_m"] < -1e-3 and ob["chain_free_clearance_m"] < 0
    eq = chain.fk(ob["chain_tensions_N"], [p, p])
    assert np.linalg.norm(eq.tip - s_eq.tip) < 1e-8
    pts = np.vstack([kin.interpolate(chain.sys.segment_q(eq.q, k), s.params.n_elements, s.params.length, 4)
                     for k, s in enumerate(chain.sys.segments)])
    dist = np.linalg.norm(pts - ob["centre_m"], axis=1)
    assert dist.min() >= sg.OBSTACLE["radius_m"] + sg.OBSTACLE["margin_m"] - 1e-8


def test_markdown_table_of_the_committed_data_is_in_the_docs():
    """docs/multisegment.md's table is markdown_table of docs/data/paper_segments.json (the default run's
    segments.json), and that data's single-segment numbers are what the program computes today."""
    data = json.loads(DATA.read_text())
    doc = (ROOT / "docs" / "multisegment.md").read_text()
    block = re.search(r"<!-- table:segments begin[^\n]*-->\n(.*?)<!-- table:segments end -->", doc, re.S)
    assert block, "the generated block is missing from docs/multisegment.md"
    assert block.group(1) == sg.markdown_table(data)
    one = ChainModel(sg.single_params(data["single_length_m"]))
    for pt, (T, p) in zip(data["points"], sg.POINTS):
        target = one.fk(T, [p]).tip
        np.testing.assert_allclose(pt["target_m"], target, atol=1e-9)
        sd = sg.single_direction(one, target, p)
        c_t, c_l = sg.directional_compliances(one, sd["state"], [0, 0, 1])
        assert pt["single"]["held_m_per_N"] == pytest.approx(c_t, rel=1e-6)
        assert pt["single"]["locked_m_per_N"] == pytest.approx(c_l, rel=1e-6)


@pytest.mark.parametrize("args", [["--points", "4"], ["--rays", "0"], ["--single-length-mm", "nan"],
                                  ["--bisections", "-1"]])
def test_bad_options_give_one_error_line(args, capsys, tmp_path):
    with pytest.raises(SystemExit) as info:
        main(["paper", "segments", "--quick", "--out", str(tmp_path), *args])
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert info.value.code == 2 and len(lines) == 1 and lines[0].startswith("error: ") and "Traceback" not in err


def test_quick_command_writes_its_files(tmp_path, capsys):
    with pytest.raises(SystemExit) as info:
        main(["paper", "segments", "--quick", "--no-progress", "--out", str(tmp_path)])
    assert info.value.code in (0, None)
    for f in sg.FILES:
        assert (tmp_path / f).stat().st_size > 0
    data = json.loads((tmp_path / "segments.json").read_text())
    assert data["obstacle"]["chain_clearance_m"] >= -1e-8 and data["obstacle"]["single_clearance_m"] < 0
    assert data["points"][0]["single"]["jacobian_rank"] == 3


def test_an_interruption_keeps_the_finished_parts(tmp_path, monkeypatch):
    """Ctrl-C during the points: RunInterrupted naming segments_partial.json, which holds the finished workspace."""
    from validation.infra.runner import RunInterrupted

    def stop(*a, **k):
        raise KeyboardInterrupt
    monkeypatch.setattr(sg, "direction_set", stop)
    with pytest.raises(RunInterrupted) as info:
        sg.segments_study(quick=True, samples=8, out=tmp_path)
    saved = json.loads(pathlib.Path(info.value.saved_to).read_text())
    assert saved["workspace"]["chain"]["samples"] == 8 and saved["points"] == []
    assert not (tmp_path / "segments.json").exists()
