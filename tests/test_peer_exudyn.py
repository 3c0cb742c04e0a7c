"""Checks that the Exudyn benchmark peer solves the same cantilever problem as our model:
Euler-Bernoulli closed forms in the small-load limit, plus basic peer hygiene."""
from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("exudyn")

_PEER_PATH = Path(__file__).resolve().parents[1] / "benchmarks" / "peer_exudyn.py"


def _load_peer():
    spec = importlib.util.spec_from_file_location("peer_exudyn", _PEER_PATH)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


peer = _load_peer()

L = 0.16  # m
EA = 767.2  # N
EI = 0.0839  # N m^2


def test_available():
    assert peer.available()


@pytest.mark.parametrize("n", [6, 12])
def test_small_tip_load_matches_euler_bernoulli(n):
    F = 1e-3  # N -> delta/L ~ 1e-4, deep in the linear regime
    res = peer.solve_cantilever(n, L, EA, EI, tip_force=(0.0, 0.0, -F))
    delta_eb = F * L**3 / (3.0 * EI)
    tip = res["tip"]
    assert tip.shape == (3,)
    assert -tip[2] == pytest.approx(delta_eb, rel=0.01)
    assert abs(tip[1]) < 1e-12
    assert abs(tip[0] - L) < 1e-3 * delta_eb + 1e-12 * L  # only 2nd-order shortening
    assert res["build_s"] > 0 and res["solve_s"] > 0
    assert isinstance(res["newton_iterations"], int) and res["newton_iterations"] >= 1


@pytest.mark.parametrize("n", [6, 12])
def test_small_line_load_matches_euler_bernoulli(n):
    q = 1e-2  # N/m
    res = peer.solve_cantilever(n, L, EA, EI, tip_force=(0.0, 0.0, 0.0),
                                line_load=(0.0, 0.0, -q))
    delta_eb = q * L**4 / (8.0 * EI)
    assert -res["tip"][2] == pytest.approx(delta_eb, rel=0.01)
    assert abs(res["tip"][1]) < 1e-12


def test_3d_bending_and_rotated_base_axis():
    """Out-of-plane load bends in y as well; rotating axis + loads rotates the tip."""
    F = np.array([0.05, 0.2, -0.49])
    q = np.array([0.0, 0.3, -1.0])
    a = peer.solve_cantilever(12, L, EA, EI, tuple(F), tuple(q))["tip"]
    assert a[1] > 1e-4 and a[2] < -1e-3

    axis = np.array([1.0, 2.0, 3.0]) / np.sqrt(14.0)
    ex = np.array([1.0, 0.0, 0.0])
    v, c = np.cross(ex, axis), ex @ axis
    K = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    R = np.eye(3) + K + K @ K / (1.0 + c)  # rotation taking ex -> axis
    b = peer.solve_cantilever(12, L, EA, EI, tuple(R @ F), tuple(R @ q), base_axis=tuple(axis))["tip"]
    np.testing.assert_allclose(b, R @ a, atol=1e-11)


def test_quiet_no_files_and_time_solve(tmp_path, monkeypatch, capfd):
    monkeypatch.chdir(tmp_path)
    r = peer.time_solve(6, L, EA, EI, (0.0, 0.0, -0.49), repeats=3)
    out, err = capfd.readouterr()
    assert out == "" and err == ""
    assert list(tmp_path.iterdir()) == []
    assert r["repeats"] == 3 and r["build_s"] > 0 and r["solve_s"] > 0
    # finite rotation: clearly nonlinear but well-posed; x shortens, z deflects ~5 % of L
    assert 0.15 < r["tip"][0] < L and -0.01 < r["tip"][2] < -0.007


def test_large_swinging_cable_matches_exudyn_in_time():
    """The transient model against Exudyn's ANCF cable dynamics in the same run: a soft cable released
    straight under gravity swings its tip down by ~85 mm (half its length); the two tip trajectories agree to
    < 0.1 % of the length at every step, for two step sizes — the difference is the cables' strain measures
    (module docstring of the peer), not the time integration."""
    import math
    from ancf import Model, StiffnessLaw, presets
    from ancf.params import Tendon

    EA_, EI_, mp = 1000.0, 0.005, 0.3
    m = Model(presets.paper().replace(
        stiffness=StiffnessLaw.constant(EA=EA_, EI=EI_), line_mass=mp, tip_mass=0.0, tool_offset=0.0,
        n_elements=6, tendons=tuple(Tendon(distance=1e-3, angle=a) for a in (0.0, 2 * math.pi / 3, 4 * math.pi / 3))))
    for dt in (2e-3, 5e-4):
        ref = peer.simulate_cantilever(6, L, EA_, EI_, mp, t_end=0.4, dt=dt)
        sim = m.simulate(0.4, dt, q0=m.q_ref, tensions=(0, 0, 0), damping=0.0, check_limits=False)
        assert np.allclose(ref["t"], sim.t, atol=1e-12)
        assert sim.tip[:, 2].min() < -0.08                             # a large, nonlinear swing
        assert np.abs(sim.tip - ref["tip"]).max() < 1e-3 * L
