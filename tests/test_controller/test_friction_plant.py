"""Controllers on a plant with tendon friction (docs/friction.md, "Controller on a plant with friction").

The plant is the simulated rig whose actuator has ``tendon_friction`` μ > 0 (each state the locked friction step
from the previous one, :mod:`hardware.simulated`).  Checked here: Table I with friction in the plant only (errors
grow with μ; μ = 0 is Table I itself, bit for bit), the friction-aware LACC (:mod:`controller.friction_aware`)
within 0.1 mm in ≤ 10 iterations at μ = 0.2 where plain LACC is not, its IK with friction against the plant and
the frictionless IK, its load estimate against the hidden load, the input errors, and the documented table
against the program.
"""

from __future__ import annotations

import pathlib
import re

import numpy as np
import pytest

from ancf import InfeasibleTargetError, Model, presets
from ancf import friction as fr
from ancf.errors import InputError
from controller import LACC, SimulatedPlant, run_iterations
from controller.friction_aware import FrictionAwareLACC, friction_ik, match_load
from validation.paper import control as pc

P = 60e3
DOC = pathlib.Path(__file__).resolve().parents[2] / "docs" / "friction.md"


def _case(name: str = "upward"):
    """The Table I configuration ``name`` and its seeded load (the first draw of seed 0 for "upward")."""
    params = presets.paper()
    cfg = pc.configurations(params, pressure=P, directions={name: pc.DIRECTIONS[name]}, max_load_mass=0.06)[name]
    free = Model(params)
    ref = free.fk(cfg["tensions"], P, (0, 0, 0))
    F, _ = pc._draw_load(free, ref.tip, P, np.random.default_rng(0), (0.02, 0.06), 0.03, ref.q, ref.tensions)
    return params, ref.tip, F


def test_plant_only_errors_grow_with_mu():
    """Friction the controllers' model does not know: LACC's error after 3 corrections grows with the plant's μ
    (a short seeded run, one configuration)."""
    res = pc.table1_friction(friction=(0.0, 0.1, 0.3), iterations=3, reach_iterations=3,
                             configurations={"upward": pc.DIRECTIONS["upward"]})
    block = res["friction"]
    err = [block[k]["upward"]["lacc_error"] for k in ("0", "0.1", "0.3")]
    assert err[0] < 1e-5 < err[1] < err[2], err
    assert block["0.3"]["upward"]["lacc_history"][3] == err[2]      # iterations = reach_iterations here
    assert "plant μ" in res["table"]


def test_mu_zero_is_table1_bit_for_bit():
    """μ = 0 in the friction study reproduces Table I's numbers exactly (the errors after the stated iterations are
    the prefix of the longer runs: a deterministic plant and controllers)."""
    cfg = {"horizontal": pc.DIRECTIONS["horizontal"]}
    base = pc.table1(configurations=cfg, compare=None)
    sweep = pc.table1(friction=(0.0,), configurations=cfg)["friction"]["0"]["horizontal"]
    assert sweep["lacc_error"] == base["horizontal"]["lacc_error"]
    assert sweep["vfcc_error"] == base["horizontal"]["vfcc_error"]
    assert sweep["lacc_history"][:6] == base["horizontal"]["lacc_history"]
    np.testing.assert_array_equal(sweep["load"], base["horizontal"]["load"])


def test_friction_aware_lacc_reaches_a_tenth_of_a_millimetre_at_mu_02():
    """μ = 0.2 in plant and model: the friction-aware LACC is within 0.1 mm in ≤ 10 iterations; plain LACC on the
    same plant is not, after as many."""
    params, target, F = _case()
    truth = Model(params.replace(tendon_friction=0.2))
    aware = run_iterations(FrictionAwareLACC(truth, P, tolerance=1e-4), SimulatedPlant(truth, P, load=F), target,
                           iterations=10)
    assert aware.converged and aware.failure is None
    assert aware.errors[-1] < 1e-4                      # the plant's true tip, not the measurement
    k = aware.iterations
    assert k <= 10
    plain = run_iterations(LACC(Model(params), P, tolerance=0.0), SimulatedPlant(truth, P, load=F), target,
                           iterations=max(k, 1), stop_at_tolerance=False)
    assert plain.errors[-1] > 1e-4


def test_estimate_beyond_the_validity_range_falls_back_to_position_correction():
    """An estimate beyond ``validity_force`` is not taken: the step says so, the estimate stays, and the IK target
    is shifted against the error instead — the error still falls."""
    params, target, F = _case()
    truth = Model(params.replace(tendon_friction=0.2))
    ctrl = FrictionAwareLACC(truth, P, tolerance=0.0, validity_force=0.1)
    r = run_iterations(ctrl, SimulatedPlant(truth, P, load=F), target, iterations=3, stop_at_tolerance=False)
    assert r.reports[0].mode == "fallback" and "validity range" in r.reports[0].notes[0]
    assert np.allclose(r.estimates[-1], 0.0)
    assert r.errors[-1] < 0.5 * r.errors[0]


def test_friction_ik_lands_the_plant_on_the_target():
    """IK with friction from a friction state: the plant (started in that state) commanded to the lengths puts its
    tip on the target within the IK tolerance; at μ = 0 the lengths are the frictionless IK's."""
    params, target, F = _case()
    m = Model(params.replace(tendon_friction=0.3))
    free = Model(params)
    slack = m.fk_history(np.zeros(3), P, F)
    lengths, st, _free_eq, _ = friction_ik(m, free, slack, target, P, F, tol=1e-7)
    plant = SimulatedPlant(m, P, load=F)                # starts from the slack actuator too
    plant.command(lengths)
    plant.advance(None)
    assert np.linalg.norm(plant.true_tip() - target) < 2e-7
    assert np.all(st.motor_tensions > 0)
    # a second IK from that state (the history moves on) lands as well
    target2 = target + np.array([0.0, 1e-3, -1e-3])
    lengths2, _, _, _ = friction_ik(m, free, st, target2, P, F, tol=1e-7)
    plant.command(lengths2)
    plant.advance(None)
    assert np.linalg.norm(plant.true_tip() - target2) < 2e-7
    # μ = 0: the friction IK is the frictionless IK
    s0 = free.fk_history(np.zeros(3), P, F)
    l0, _, _, its = friction_ik(free, free, s0, target, P, F, tol=1e-7)
    np.testing.assert_allclose(l0, free.ik(target, P, F).tendon_lengths, atol=1e-9)
    assert its == 1


def test_match_load_recovers_the_hidden_load():
    """The load that makes the model's locked friction step match a measured tip is the load the plant had (the
    lateral components; the axial one is cut by the regularised inverse, as in LACC)."""
    params, target, F = _case()
    m = Model(params.replace(tendon_friction=0.2))
    slack = m.fk_history(np.zeros(3), P, (0, 0, 0))
    lengths = Model(params).ik(target, P, (0, 0, 0)).tendon_lengths
    measured = fr.fk_locked_history(m, slack, lengths, P, F).tip
    Fh, st, C, _ = match_load(m, slack, lengths, P, np.zeros(3), measured)
    assert np.linalg.norm(st.tip - measured) < 1e-6
    assert abs(Fh[1] - F[1]) < 2e-3 and abs(Fh[2] - F[2]) < 2e-3, (Fh, F)
    assert C.shape == (3, 3) and C[2, 2] > 0


def test_input_errors():
    m = Model(presets.paper().replace(tendon_friction=0.2))
    with pytest.raises(InputError):
        FrictionAwareLACC(m, P, rcond=2.0)
    with pytest.raises(InputError):
        FrictionAwareLACC(m, P, ik_max_iter=0)
    with pytest.raises(InputError):
        FrictionAwareLACC(m, P, initial_state="slack")
    with pytest.raises(InputError):
        FrictionAwareLACC(m, P).step([0.18, 0.0, 0.0])          # before start
    with pytest.raises(InputError):
        FrictionAwareLACC(m, P).start([0.18, 0.0, 0.0], initial_load=(0, 0, -5.0))   # outside the validity range
    with pytest.raises(InfeasibleTargetError):
        FrictionAwareLACC(m, P).start([0.10, 0.0, 0.0])         # out of reach
    for bad in ((), (1.5,), (-0.1,), ("x",), 0.1):
        with pytest.raises(InputError):
            pc.table1_friction(friction=bad)
    with pytest.raises(InputError):
        pc.table1_friction(friction=(0.1,), iterations=5, reach_iterations=3)


def _doc_rows() -> dict:
    """{(μ, configuration): row cells} of the documented table."""
    text = DOC.read_text()
    sec = text[text.index("## Controller on a plant with friction"):]
    sec = sec[:sec.index("\n#", 1)]                     # up to the next heading (the loading subsection's table)
    rows = {}
    for line in sec.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) >= 7 and re.fullmatch(r"[0-9.]+", cells[0]):
            rows[(cells[0], cells[1])] = cells
    return rows


def _program_row(mu: str, name: str, e: dict) -> list:
    return pc._friction_row(float(mu), name, e, True)


def test_documented_row_is_the_programs():
    """The documented row μ = 0.2, upward (the first seeded draw, so the run needs only that configuration) is the
    program's output digit for digit."""
    rows = _doc_rows()
    assert len(rows) == 12, sorted(rows)
    res = pc.table1(friction=(0.2,), friction_aware=True, configurations={"upward": pc.DIRECTIONS["upward"]})
    assert rows[("0.2", "upward")] == _program_row("0.2", "upward", res["friction"]["0.2"]["upward"])


@pytest.mark.slow
def test_documented_table_is_the_programs():
    """The whole documented table (≈ 2 min on 2 cores): ``bellows paper table1 --plant-friction 0,0.1,0.2,0.3
    --friction-aware``."""
    rows = _doc_rows()
    res = pc.table1(friction=(0.0, 0.1, 0.2, 0.3), friction_aware=True)
    for mu, block in res["friction"].items():
        for name, e in block.items():
            assert rows[(mu, name)] == _program_row(mu, name, e)


def test_friction_ik_from_a_state_with_a_slack_tendon():
    """From a state with a slack tendon to a target that makes it just taut under friction: without a bound on
    the Broyden step, one step sent that tendon's motor length to -2e9 mm and the locked solve refused it; the
    steps are now at most MAX_LENGTH_STEP per motor."""
    from ancf import Model, presets
    from controller.friction_aware import MAX_LENGTH_STEP, friction_ik
    free = Model(presets.paper())
    fric = Model(presets.paper().replace(tendon_friction=0.3))
    prev = fric.fk_history((2.0, 0.5, 0.0), 30e3)
    target = free.fk((2.05, 0.52, 0.0), 30e3).tip
    lengths, st, free_eq, its = friction_ik(fric, free, prev, target, 30e3, np.zeros(3))
    assert np.linalg.norm(st.tip - target) < 1e-6 and its <= 12
    assert np.abs(lengths - free_eq.tendon_lengths).max() <= its * MAX_LENGTH_STEP
