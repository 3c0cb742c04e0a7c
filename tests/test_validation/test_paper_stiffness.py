"""Stiffness vs T1, constant tension vs locked tendons (paper Sec. V-C, Fig. 9).

Checked against closed forms of a straight, weightless, uniform beam (Euler–Bernoulli cantilever; one
inextensible tendon at distance d locked), against the theory of constrained minimisation (locked ≥ free),
and the secant (nonlinear) vs tangent (compliance matrix) consistency to first order in the payload.
"""

import json

import numpy as np
import pytest

from ancf import StiffnessLaw, presets
from validation import paper

EA, EI, L, D = 767.2, 0.0839, 0.16, 0.0275


def uniform():
    return presets.paper().replace(stiffness=StiffnessLaw.constant(EA=EA, EI=EI), line_mass=0.0, tip_mass=0.0,
                                   tool_offset=0.0)


@pytest.fixture(scope="module")
def grid():
    return paper.stiffness_vs_tension(pressures=(0.0, 50e3), tensions=(0.0, 2.5, 5.0), params="paper_unscaled")


def test_closed_forms_straight_beam():
    res = paper.stiffness_vs_tension(pressures=(0.0,), tensions=(0.0,), mass=0.01, params=uniform())
    cv = res["curves_N_per_m"]
    k_cant = 3 * EI / L ** 3
    a, b = D ** 2 / EI, 1 / EA
    k_locked = k_cant / (1 - 0.75 * a / (a + b))
    assert cv["constant_linear"][0, 0] == pytest.approx(k_cant, rel=0.01)
    assert cv["constant_nonlinear"][0, 0] == pytest.approx(k_cant, rel=0.01)
    assert cv["locked_linear_exact"][0, 0] == pytest.approx(k_locked, rel=0.02)
    assert cv["locked_nonlinear"][0, 0] == pytest.approx(k_locked, rel=0.02)
    # the top tendon carries the payload moment: T = P L d / (2 EI (a + b))
    row = res["rows"][0]
    P = 0.01 * paper.G
    assert row["locked_tensions_N"][0] == pytest.approx(P * L * D / (2 * EI * (a + b)), rel=0.03)
    assert row["locked_active"] == [0]


def test_locked_is_stiffer_than_constant_tension(grid):
    cv = grid["curves_N_per_m"]
    assert np.all(cv["locked_nonlinear"] > cv["constant_nonlinear"])
    assert np.all(cv["locked_linear_exact"] >= cv["constant_linear"] * (1 - 1e-12))
    assert np.all(grid["ratio_locked_over_constant"]["nonlinear"] > 1.5)
    assert grid["failures"] == 0


def test_downward_payload_tightens_only_the_top_tendon(grid):
    for row in grid["rows"]:
        assert row["locked_active"] == [0] and row["active_exact"] == [0]
        T = row["locked_tensions_N"]
        assert T[0] > row["tension_N"]            # the load pulls on the top tendon
        assert T[1] == T[2] == 0.0                # the lower two go slack


def test_secant_matches_tangent_to_first_order_in_the_payload():
    """k_secant − k_tangent = O(m g): the gap is small at the paper's 50 g and halves with the payload."""
    r = paper.stiffness_vs_tension(pressures=(25e3,), tensions=(0.0, 5.0), mass=0.05, methods=("exact",),
                                 params="paper_unscaled")
    cv = r["curves_N_per_m"]
    assert np.allclose(cv["constant_nonlinear"], cv["constant_linear"], rtol=0.02)
    assert np.allclose(cv["locked_nonlinear"], cv["locked_linear_exact"], rtol=0.02)
    for T1 in (0.0, 5.0):
        gaps = np.abs(np.array([_gaps(T1, mass) for mass in (0.025, 0.0125, 0.00625)]))
        assert np.all(gaps[1:] / gaps[:-1] == pytest.approx(0.5, abs=0.1))


def _gaps(T1, mass):
    r = paper.stiffness_vs_tension(pressures=(25e3,), tensions=(T1,), mass=mass, methods=("exact",),
                                 params="paper_unscaled")
    cv = r["curves_N_per_m"]
    return [cv["constant_nonlinear"][0, 0] - cv["constant_linear"][0, 0],
            cv["locked_nonlinear"][0, 0] - cv["locked_linear_exact"][0, 0]]


def test_paper_protocol_numbers(grid):
    assert grid["mass_kg"] == 0.05 and grid["payload_N"] == pytest.approx(0.4905)
    cv = grid["curves_N_per_m"]
    for row, (i, j) in zip(grid["rows"], [(i, j) for i in range(2) for j in range(3)]):
        assert row["k_locked_nonlinear_N_per_m"] == cv["locked_nonlinear"][i, j]
        z0, zl = row["tip_unloaded_m"][2], row["tip_loaded_locked_m"][2]
        assert cv["locked_nonlinear"][i, j] == pytest.approx(0.05 * 9.81 / (z0 - zl))
    assert grid["summary"]["mean_ratio_nonlinear"] == pytest.approx(
        np.mean(cv["locked_nonlinear"] / cv["constant_nonlinear"]))


def test_files_and_table(tmp_path, capsys):
    res = paper.stiffness_vs_tension(pressures=(0.0,), tensions=(0.0, 5.0), out=tmp_path)
    data = json.loads((tmp_path / "stiffness.json").read_text())
    assert data["curves_N_per_m"]["locked_nonlinear"] == res["curves_N_per_m"]["locked_nonlinear"].tolist()
    assert (tmp_path / "stiffness.png").stat().st_size > 20_000
    assert (tmp_path / "stiffness.svg").exists()
    paper.print_stiffness(res)
    out = capsys.readouterr().out
    assert "locked" in out and "≈ 2" in out
