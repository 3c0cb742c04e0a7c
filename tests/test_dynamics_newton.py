"""The step's Newton iteration on stiff one-sided springs (ancf.dynamics.integrator: the active-set update, the
line search, the start at the last state; the same in ancf.dynamics.compiled_step).

The class: tendons held by their motors through a stiff series spring (10⁶ N/m, as the dynamic simulated rig
holds inextensible tendons), a motor move at the start of a step, tendons switching slack/taut.  Plain Newton
(full steps, the predictor as its start) lets the tension iterates run away — from a start where a tendon is
slack it stretches that tendon by what the linearisation without its spring asks, then swings back — and
needs its steps halved (or gives up); the globalised Newton keeps the tensions of its iterates at the size of
the step's own and takes the step whole.

References: the piecewise-linear spring model solved by brute force (every branch combination), the quadratic
through three values for the line search's step, and the same run at a step 8× finer."""

import itertools

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from ancf import Model, presets
from ancf.dynamics import compiled_step as cs
from ancf.dynamics import integrator as ig
from ancf.dynamics import transient as tr

P30 = 30e3
K_STIFF = 1e6


@pytest.fixture(scope="module")
def stiff():
    return Model(presets.paper().replace(tendon_stiffness=K_STIFF))


@pytest.fixture(scope="module")
def start(stiff):
    """The locked equilibrium of the motor lengths l0 (T ≈ 2.4, 1.2, 1.2 N) and those lengths [m]."""
    springy = Model(presets.paper().replace(tendon_stiffness=2000.0))
    l0 = springy.rest_lengths(springy.fk((2.0, 1.0, 1.0), P30))
    return stiff.fk_locked(l0, P30, (0, 0, 0)), l0


def motor_move(l0, rate=0.05, t_move=0.04):
    """Motor 1 pulls at ``rate`` [m/s], motors 2 and 3 release at half of it, for ``t_move`` [s]."""
    return lambda t: l0 + rate * np.array([-1.0, 0.5, 0.5]) * min(t, t_move)


def run(model, eq, lengths, t_end=0.01, dt=1e-3):
    return model.simulate(t_end, dt, q0=eq.q, lengths=lengths, pressure=P30, damping={"alpha": 6.0},
                          rho_inf=0.6, check_limits=False)


def plain_newton(monkeypatch):
    """The iteration before globalisation: full Newton steps (halved only while the trial leaves the domain),
    no active set, the predictor always the start."""
    def full_step(evaluate, x, dx, rn, scale, it):
        lam = 1.0
        for _ in range(ig.LINE_SEARCH_TRIES):
            try:
                return x - lam * dx, evaluate(x - lam * dx)
            except ig.StepFailed:
                lam *= 0.5
        raise ig.StepFailed("every Newton trial left the model's domain", rn, it)
    monkeypatch.setattr(ig, "line_search", full_step)
    monkeypatch.setattr(ig, "active_set_update", lambda J, r, dx, springs, bp: dx)
    monkeypatch.setattr(ig, "_spring_start", lambda evaluate, x, pred, x_hold: (x, pred))


def iterate_tensions(monkeypatch):
    """Records the tensions [N] of every state the plant evaluates (the Newton iterates and trials)."""
    seen = []
    orig = tr._Plant.tendons

    def spy(self, q, t, l0=None):
        T, lq = orig(self, q, t, l0)
        seen.append(float(np.max(T)))
        return T, lq
    monkeypatch.setattr(tr._Plant, "tendons", spy)
    return seen


# ------------------------------------------------------------------------------------------------ the run
def test_plain_newton_lets_the_tensions_run_away_on_a_motor_move(stiff, start, monkeypatch):
    """The failing class at its smallest: 10 ms of a 50 mm/s motor move on 10⁶ N/m tendons at 1 ms steps.
    Plain Newton's iterates reach tensions of kN (the step's own are a few N) and its steps are halved."""
    eq, l0 = start
    monkeypatch.setattr(tr, "COMPILED_ROWS", False)
    plain_newton(monkeypatch)
    seen = iterate_tensions(monkeypatch)
    sim = run(stiff, eq, motor_move(l0))
    assert "subdivided" in {e["kind"] for e in sim.events}
    assert max(seen) > 1e3 > 100 * sim.tensions.max()


def test_the_globalised_newton_keeps_the_iterates_bounded_and_the_steps_whole(stiff, start, monkeypatch):
    eq, l0 = start
    monkeypatch.setattr(tr, "COMPILED_ROWS", False)
    seen = iterate_tensions(monkeypatch)
    sim = run(stiff, eq, motor_move(l0))
    assert not sim.events                                               # no step halved
    assert sim.newton_iterations[1:].max() <= 6
    # every iterate's tension below the tension a motor's move over one step puts on a held tendon, plus the
    # step's own (k Δl = 10⁶ N/m × 50 µm = 50 N)
    assert max(seen) <= K_STIFF * 0.05 * 1e-3 + sim.tensions.max() + 5.0


def test_the_whole_steps_follow_the_fine_trajectory(stiff, start):
    """The move at 1 ms steps against the same run at 1/8 ms (where the steps need no globalisation to
    converge): the tool point within 50 µm over the move (the 1 ms step's integration error; the halved steps
    of plain Newton came within 20 µm)."""
    eq, l0 = start
    coarse = run(stiff, eq, motor_move(l0), t_end=0.05)
    fine = run(stiff, eq, motor_move(l0), t_end=0.05, dt=1.25e-4)
    assert not coarse.events
    err = np.abs(coarse.tip - fine.tip[::8]).max()
    assert err < 50e-6, f"{err * 1e6:.1f} µm"
    # the tendons follow their motors: the tension stays near the start's (the actuator takes the move)
    assert coarse.tensions.max() < 10.0


def test_the_compiled_rows_take_the_same_globalised_steps(stiff, start, monkeypatch):
    """The kernel's active set, line search and start choice are the Python path's: the same run to round-off,
    the same Newton iterations (and the rows were made by the kernel)."""
    eq, l0 = start
    rows = {"n": 0}
    orig = tr._FastRows.run

    def spy(self, i, *a):
        j, s, pr = orig(self, i, *a)
        rows["n"] += j - i
        return j, s, pr
    monkeypatch.setattr(tr._FastRows, "run", spy)
    out = []
    for flag in (False, True):
        monkeypatch.setattr(tr, "COMPILED_ROWS", flag)
        out.append(run(stiff, eq, motor_move(l0, rate=0.1, t_move=0.02), t_end=0.03))
    ref, fast = out
    assert rows["n"] == len(fast.t) - 1 and not fast.events
    assert np.array_equal(ref.newton_iterations, fast.newton_iterations)
    for name in ("q", "v", "tensions"):
        a, b = getattr(ref, name), getattr(fast, name)
        assert np.abs(a - b).max() <= 1e-10 * np.abs(a).max(), name


# ------------------------------------------------------------------------------------------------ the pieces
def _model_residual(J, r, dx, springs, bp):
    """The residual of the piecewise-linear spring model after the update dx: r − J dx with each spring's force
    taken from its branch at the predicted stretch instead of its current branch's linearisation."""
    s, G, k, F_hold = springs
    cur, T = ig.spring_branches(s, k, F_hold)
    out = r - J @ dx
    for i in range(len(s)):
        ds = -bp * (G[i] @ dx)
        lin = T[i] + (k * ds if cur[i] == 1 else 0.0)            # what J dx assumed
        out = out + (min(k * max(s[i] + ds, 0.0), F_hold) - lin) * G[i]
    return out


def _brute_force(J, r, springs, bp):
    """The model's root by trying every branch combination (the reference for the active-set update)."""
    s, G, k, F_hold = springs
    cur, T = ig.spring_branches(s, k, F_hold)
    found = []
    n_br = 3 if np.isfinite(F_hold) else 2
    for combo in itertools.product(range(n_br), repeat=len(s)):
        d = ig.branch_solve(J, r, springs, bp, cur, T, np.array(combo))
        if d is not None and np.array_equal(ig.spring_branches(s - bp * (G @ d), k, F_hold)[0], combo):
            found.append(d)
    return found


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2 ** 31 - 1), m=st.integers(1, 3), hold=st.booleans())
def test_the_active_set_update_solves_the_piecewise_linear_model(seed, m, hold):
    """On random problems (J = smooth SPD part + the current taut springs, stretches across the kinks) the
    update zeroes the piecewise-linear model's residual and is the brute-force root — after the passes, and by
    the search over all branches alone —, and the kernel's update is the same."""
    rng = np.random.default_rng(seed)
    n, k, bp = 6, 1e6, 2.5e-7
    A = rng.normal(size=(n, n))
    G = rng.normal(size=(m, n)) * 0.3
    s = rng.normal(size=m) * 3e-6
    F_hold = 4.0 if hold else np.inf
    springs = (s, G, k, F_hold)
    cur = ig.spring_branches(s, k, F_hold)[0]
    J = A @ A.T + np.eye(n)
    for i in range(m):
        if cur[i] == 1:
            J = J + bp * k * np.outer(G[i], G[i])
    r = rng.normal(size=n) * 10.0
    roots = _brute_force(J, r, springs, bp)
    par = np.zeros(cs.N_PAR)
    par[cs.P_KPEN], par[cs.P_FHOLD] = k, F_hold
    # the passes (as the step runs them), and the search over all branches alone (what a cycle falls back to)
    for passes in (ig.ACTIVE_SET_PASSES, 0):
        dx = ig.active_set_update(J, r, np.linalg.solve(J, r), springs, bp, passes)
        res = _model_residual(J, r, dx, springs, bp)
        assert np.linalg.norm(res) <= 1e-8 * (np.linalg.norm(r) + k * np.abs(s).max() * np.abs(G).max())
        assert any(np.allclose(dx, d, rtol=1e-9, atol=1e-12) for d in roots)
        fast = cs._active_set(J, r, np.linalg.solve(J, r), s, G, bp, par, passes)      # the kernel's
        assert np.array_equal(fast, dx) or np.abs(fast - dx).max() <= 1e-12 * np.abs(dx).max()


def test_an_update_that_crosses_no_kink_is_plain_newtons():
    rng = np.random.default_rng(1)
    J = np.eye(4) * 2.0
    r = rng.normal(size=4) * 1e-3
    springs = (np.array([5e-6, -5e-6]), rng.normal(size=(2, 4)), 1e6, np.inf)
    dx = np.linalg.solve(J, r)
    assert ig.active_set_update(J, r, dx, springs, 2.5e-7) is dx


@pytest.mark.parametrize("lam, ft", [(1.0, 50.0), (1.0, 1e6), (0.5, 1.2), (0.1, 0.99)])
def test_the_next_step_length_is_the_quadratics_minimiser_within_its_bounds(lam, ft):
    """f(λ) = f0 (1 − 2λ) + c λ² through f(λ) = ft has its minimum at f0 / c; kept in [λ/10, λ/2]."""
    f0 = 1.0
    c = (ft - f0 * (1 - 2 * lam)) / lam ** 2
    expected = min(0.5 * lam, max(0.1 * lam, f0 / c))
    assert ig.next_lambda(lam, f0, ft) == pytest.approx(expected, rel=1e-12)
    assert ig.next_lambda(lam, f0, float("inf")) == 0.5 * lam


def test_a_line_search_that_finds_no_decrease_fails_the_step():
    """A direction along which the residual only grows: StepFailed (the caller halves the step) after the
    trials, not an accepted worse iterate; all trials outside the domain: the domain's message."""
    def grows(x):
        return None, None, None, (np.array([1.0 + float(np.abs(x).sum())]),)
    with pytest.raises(ig.StepFailed, match="lowered the residual"):
        ig.line_search(grows, np.zeros(1), np.ones(1), 1.0, 1.0, 1)

    def outside(x):
        raise ig.StepFailed("the state left the model's domain")
    with pytest.raises(ig.StepFailed, match="domain"):
        ig.line_search(outside, np.zeros(1), np.ones(1), 1.0, 1.0, 1)
