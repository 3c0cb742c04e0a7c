"""Clear errors: bad inputs, unreachable targets, non-convergence; the timed loop runs."""

import numpy as np
import pytest

from ancf import BellowsError, InfeasibleTargetError, InputError
from controller import (LACC, VFCC, ControllerError, NotConvergedError, SimulatedPlant, run_iterations,
                        run_timed)

P = 60e3


@pytest.fixture(scope="module")
def target(paper_model):
    return paper_model.fk((2.5, 2.2, 2.2), P, (0, 0, 0)).tip


def test_error_tree():
    assert issubclass(ControllerError, BellowsError)
    assert issubclass(NotConvergedError, ControllerError)


@pytest.mark.parametrize("cls", [LACC, VFCC])
def test_bad_inputs(paper_model, target, cls):
    c = cls(paper_model, P)
    with pytest.raises(InputError):
        c.step(target)                                       # not started
    with pytest.raises(InputError):
        c.start([np.nan, 0, 0])
    c.start(target)
    with pytest.raises(InputError):
        c.step([0.1, np.inf, 0.0])
    with pytest.raises(InputError):
        c.step([0.1, 0.0])


def test_bad_parameters(paper_model):
    with pytest.raises(InputError):
        LACC(paper_model, P, compliance="magic")
    with pytest.raises(InputError):
        LACC(paper_model, P, validity_force=-1)
    with pytest.raises(InputError):
        VFCC(paper_model, P, chi=[1.0, np.nan, 1.0])
    with pytest.raises(InputError):
        VFCC(paper_model, P, law="derivative")


def test_unreachable_target_propagates(paper_model):
    with pytest.raises(InfeasibleTargetError) as info:
        LACC(paper_model, P).start([0.10, 0.0, 0.08])
    assert info.value.nearest is not None


def test_load_beyond_tension_limits_propagates_when_asked(paper_model, target):
    # 300 g cannot be carried with ≤ 5 N tendons here: with on_infeasible="fallback", after back-tracking and
    # the IK position correction, the IK error propagates
    plant = SimulatedPlant(paper_model, P, load=(0, 0, -2.9))
    with pytest.raises(InfeasibleTargetError):
        run_iterations(LACC(paper_model, P, compliance="exact", validity_force=5.0, max_step_force=None,
                            on_infeasible="fallback"), plant, target, iterations=10)


def test_load_beyond_tension_limits_saturates_by_default(paper_model, target):
    """The same load with the default: every step after the first commands the nearest reachable state; the
    estimate converges to the true load (the innovation is measured against the commanded state, so it does
    not integrate the unreachable offset) and the error settles where the bounds put it."""
    plant = SimulatedPlant(paper_model, P, load=(0, 0, -2.9))
    ctrl = LACC(paper_model, P, compliance="exact", validity_force=5.0, max_step_force=None)
    res = run_iterations(ctrl, plant, target, iterations=10)
    assert not res.converged and all(r.saturated for r in res.reports[1:])
    assert any("saturated" in n for r in res.reports for n in r.notes)
    np.testing.assert_allclose(ctrl.estimate, (0, 0, -2.9), atol=0.05)
    assert abs(res.errors[-1] - res.errors[-2]) < 1e-6                # settled at the bound, not drifting
    assert np.all(ctrl.state.tensions >= -1e-12) and np.all(ctrl.state.tensions <= 5.0 + 1e-12)


def test_non_convergence_says_by_how_much(paper_model, target):
    plant = SimulatedPlant(paper_model, P, load=(0, 0, -0.45))
    with pytest.raises(NotConvergedError) as info:
        run_iterations(LACC(paper_model, P, compliance="ik"), plant, target, iterations=2, require_convergence=True)
    e = info.value
    assert e.iterations == 2 and e.error > e.tolerance == 2e-4
    assert "after 2 iterations" in str(e) and "mm" in str(e)
    assert len(e.history) == 3


def test_timed_loop_holds_a_slow_ramp(paper_model, target):
    ramp = lambda t: np.array([0.0, 0.0, -0.4 * min(t / 2.0, 1.0)])    # 0 → 41 g in 2 s, then hold
    plant = SimulatedPlant(paper_model, P, load=ramp)
    res = run_timed(LACC(paper_model, P, compliance="exact"), plant, target, duration=3.0,
                    compute_time=0.05, settle_time=0.05, sample_dt=0.1)
    assert res.corrections >= 3
    assert res.t[-1] >= 2.9
    assert res.max_error(after=2.6) < 3e-4                      # converged during the hold
    open_loop = SimulatedPlant(paper_model, P, load=ramp(3.0))
    open_loop.command(paper_model.ik(target, P).tendon_lengths)
    assert np.linalg.norm(open_loop.true_tip() - target) > 5 * res.max_error(after=2.6)


def test_on_error_stop_records_the_failure(paper_model, target):
    plant = SimulatedPlant(paper_model, P, load=(0, 0, -2.9))
    res = run_iterations(LACC(paper_model, P, compliance="exact", validity_force=5.0, max_step_force=None,
                              on_infeasible="fallback"), plant, target, iterations=10, on_error="stop")
    assert res.failure and "InfeasibleTargetError" in res.failure
    assert not res.converged
    assert len(res.errors) >= 1


def test_infeasible_estimate_raise_option(paper_model, target):
    plant = SimulatedPlant(paper_model, P, load=(0, 0, -2.9))
    ctrl = LACC(paper_model, P, compliance="exact", validity_force=5.0, max_step_force=None,
                on_infeasible="raise", backtracks=0)
    with pytest.raises(InfeasibleTargetError):
        run_iterations(ctrl, plant, target, iterations=3)
    with pytest.raises(InputError):
        LACC(paper_model, P, on_infeasible="ignore")
