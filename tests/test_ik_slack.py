"""The IK on a state with a slack tendon (T = (2, 0.5, 0) N at 30 kPa, `paper`), warm-started from that state as
a control loop does: targets on the slack tendon's manifold (the tips at T = (2 + δ₁, 0.5 + δ₂, 0) N) give
back those tensions; where the compiled Newton loop ends a round-off below the bound (T₃ ≈ −1e-14 N) and the
tensions are clipped, the energy and tendon lengths are those of the clipped state (Π is linear in T) without
assembling the model again; a start where the last solve started or ended (same pressure and tip force)
reuses the evaluation there and gives the same result to the bit, whatever the caller did to the results."""

import numpy as np
import pytest

from ancf import Model, presets
from ancf import compiled_solvers as _cs

P30 = 30e3


@pytest.fixture(scope="module")
def model():
    return Model(presets.paper())


def test_slack_targets_give_back_their_tensions_and_clipping_costs_no_assembly(model, monkeypatch):
    ref = model.fk((2.0, 0.5, 0.0), P30)
    last = {}
    orig_newton, orig_eval = _cs.ik_newton_reuse, type(model)._evaluate

    def newton(*a):
        out = orig_newton(*a)
        last["T"] = out[1][-model.m:].copy()
        return out
    calls = {"n": 0}

    def evaluate(self, *a, **k):
        calls["n"] += 1
        return orig_eval(self, *a, **k)
    monkeypatch.setattr(_cs, "ik_newton_reuse", newton)
    rng = np.random.default_rng(0)
    clipped = 0
    for d in rng.normal(size=(16, 2)) * 2e-4:
        T_true = np.array([2.0 + d[0], 0.5 + d[1], 0.0])
        target = model.fk(T_true, P30, q0=ref.q).tip
        monkeypatch.setattr(type(model), "_evaluate", evaluate)
        calls["n"] = 0
        eq = model.ik(target, P30, q0=ref.q, tensions0=ref.tensions)
        monkeypatch.setattr(type(model), "_evaluate", orig_eval)
        assert np.allclose(eq.tensions, T_true, atol=1e-7) and np.all(eq.tensions >= 0.0)
        ev = model.evaluate(eq.q, eq.tensions, P30, lengths="values")
        assert abs(eq.energy - ev.energy) <= 1e-12 * abs(ev.energy)
        assert np.allclose(eq.tendon_lengths, ev.lengths, rtol=0, atol=1e-15)
        if last["T"][2] < 0:
            clipped += 1
            assert calls["n"] == 0            # the clipped state's values came from the solver's own
    assert clipped >= 2


def _same(a, b):
    return (np.array_equal(a.q, b.q) and np.array_equal(a.tensions, b.tensions) and a.energy == b.energy
            and np.array_equal(a.tendon_lengths, b.tendon_lengths) and a.iterations == b.iterations)


def test_a_repeated_start_reuses_its_evaluation_and_gives_the_same_result(model):
    ref = model.fk((2.0, 0.5, 0.0), P30)
    rng = np.random.default_rng(2)
    targets = [model.fk((2.0 + a, 0.5 + b, 0.0), P30, q0=ref.q).tip for a, b in rng.normal(size=(4, 2)) * 2e-4]
    start_key = (np.concatenate([ref.q[6:], ref.tensions]).tobytes(), P30)
    for target in targets:
        model._ik_evaluations = {}
        fresh = model.ik(target, P30, q0=ref.q, tensions0=ref.tensions)
        assert any(k[:2] == start_key for k in model._ik_evaluations)         # the start's evaluation is kept
        again = model.ik(target, P30, q0=ref.q, tensions0=ref.tensions)       # reused
        assert _same(fresh, again)
        # the next solve from the state this one ended on (a control loop's chain) reuses its last evaluation
        nxt = model.ik(targets[0], P30, q0=again.q, tensions0=again.tensions)
        model._ik_evaluations = {}
        assert _same(nxt, model.ik(targets[0], P30, q0=again.q, tensions0=again.tensions))


def test_what_a_caller_does_to_a_result_does_not_reach_the_kept_evaluation(model):
    ref = model.fk((2.0, 0.5, 1.0), P30)
    target = model.fk((2.01, 0.5, 1.0), P30, q0=ref.q).tip
    eq = model.ik(target, P30, q0=ref.q, tensions0=ref.tensions)
    parts = model._tangent_parts(eq)
    assert parts is not None
    for a in parts:
        a[...] = 0.0                                  # a caller scribbling over the kept tangent
    eq.tendon_lengths[:] = 0.0
    model_fresh = Model(presets.paper())
    target2 = model.fk((2.02, 0.5, 1.0), P30, q0=ref.q).tip
    assert _same(model.ik(target2, P30, q0=eq.q, tensions0=eq.tensions),
                 model_fresh.ik(target2, P30, q0=eq.q, tensions0=eq.tensions))


def test_the_python_newton_solves_for_the_target_when_the_compiled_loop_hands_over(model, monkeypatch):
    """A compiled loop that hands over (status NOT_CONVERGED) leaves the IK to solve_root on the same system: it
    solves for the target itself (no detour through the bounded solver), and the tip is on target."""
    ref = model.fk((2.0, 0.5, 1.0), P30)
    target = model.fk((2.05, 0.45, 1.0), P30, q0=ref.q).tip
    orig = _cs.ik_newton_reuse

    def hand_over(*a):
        out = list(orig(*a))
        out[0] = _cs.NOT_CONVERGED
        return tuple(out)
    monkeypatch.setattr(_cs, "ik_newton_reuse", hand_over)
    bounded = {"n": 0}
    orig_b = type(model)._ik_bounded

    def spy(self, *a, **k):
        bounded["n"] += 1
        return orig_b(self, *a, **k)
    monkeypatch.setattr(type(model), "_ik_bounded", spy)
    eq = model.ik(target, P30, q0=ref.q, tensions0=ref.tensions)
    assert bounded["n"] == 0
    assert np.linalg.norm(eq.tip - target) < 1e-9 and np.allclose(eq.tensions, (2.05, 0.45, 1.0), atol=1e-6)
