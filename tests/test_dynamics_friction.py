"""Tendon friction in the transient response (Model.simulate with tendon_friction μ > 0,
ancf.dynamics.friction_step) against what it must obey: μ = 0 untouched (no friction path, no friction
outputs), the friction path at μ → 0 reproduces the frictionless run (an independent force assembly), its
non-symmetric tangent against finite differences, the quasi-static limit of a slow, damped run on
``fk_history``'s states, an energy balance that counts the friction's dissipation and meets the static
``tension_cycle``'s in the slow limit, the capstan cone (stick inside it, holding its tension), and typed
errors.

The slow runs use a light actuator (line mass 1e-4 kg/m, first mode ≈ 175 Hz, critically damped by α = 2ω₁):
a run lags its quasi-static path by about (rate × 1/ω₁), and the history law makes that lag stick (a segment
whose wrap angle grows while its tension is held stays stuck), so the distance to the quasi-static states
falls like the loading rate (measured on the paper actuator at line mass 3e-3 kg/m: 26 µm at a 1 s ramp,
13 µm at 2 s)."""

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from ancf import Model, presets
from ancf.dynamics import friction_step, transient
from ancf.errors import InputError
from ancf.forces import tendon_friction as tf

P20 = 20e3
LIGHT = dict(line_mass=1e-4, tip_mass=0.0)
ALPHA = 2200.0                         # ≈ 2 ω₁ of the light actuator at 20 kPa [1/s]


def light(mu):
    return Model(presets.paper().replace(tendon_friction=mu, **LIGHT))


def ramp(a, b, t1):
    return lambda t: np.array([a + (b - a) * min(t / t1, 1.0), 0.0, 0.0])


def cone(model, q, T_motor, T_seg, mu):
    """(lo, hi) (m, n): the capstan cone of every segment at q given the tensions before it."""
    ok, P, G = tf.guide_points(q, model.n, model._E, model._d, model._co, model._so)
    assert ok
    alpha = tf.wrap_angles(P, G, model._e1, model.ndof)[0]
    before = np.concatenate([np.asarray(T_motor, float)[:, None], T_seg[:, :-1]], axis=1)
    f = np.exp(mu * alpha)
    return before / f, before * f


# ------------------------------------------------------------------------------------------------ μ = 0 untouched
def test_mu_zero_takes_no_friction_path(monkeypatch):
    """μ = 0: no friction history is made (the run is the frictionless one, compiled rows and all) and the
    friction outputs are None; giving segment tensions is refused."""
    m = Model(presets.paper())
    def boom(*a, **k):
        raise AssertionError("the friction path ran at μ = 0")
    monkeypatch.setattr(friction_step.FrictionHistory, "forces", boom)
    a = m.simulate(0.05, 1e-3, tensions=ramp(1.0, 2.0, 0.05), pressure=P20, damping=0.05)
    assert a.segment_tensions is None and a.friction_dissipated is None
    monkeypatch.setattr(transient, "COMPILED_ROWS", False)
    b = m.simulate(0.05, 1e-3, tensions=ramp(1.0, 2.0, 0.05), pressure=P20, damping=0.05)
    assert np.allclose(a.q, b.q, rtol=0, atol=1e-12)
    with pytest.raises(InputError, match="tendon_friction = 0"):
        m.simulate(0.01, 1e-3, tensions=(1.0, 0, 0), segment_tensions=np.ones((m.m, m.n)))


def test_vanishing_friction_reproduces_the_frictionless_run():
    """μ = 1e-12 runs the friction path (segment forces and the law's tangent) and must give the frictionless
    run (the assembled tendon force) to the Newton tolerance."""
    base = presets.paper()
    m0, m1 = Model(base), Model(base.replace(tendon_friction=1e-12))
    eq = m0.fk((2.0, 0.5, 0.0), P20)
    kw = dict(pressure=P20, damping={"alpha": 20.0}, tensions=ramp(2.0, 3.0, 0.05))
    a = m0.simulate(0.08, 1e-3, q0=eq.q, **kw)
    b = m1.simulate(0.08, 1e-3, q0=eq.q, **kw)
    assert b.segment_tensions is not None and a.segment_tensions is None
    assert np.max(np.abs(a.tip - b.tip)) < 1e-9, np.max(np.abs(a.tip - b.tip))
    assert np.allclose(b.segment_tensions, b.tensions[:, :, None], rtol=1e-9, atol=0)
    assert abs(b.friction_dissipated[-1]) < 1e-12


def test_the_friction_tangent_is_the_derivative_of_the_force():
    """The iteration matrix's stiffness part with friction (non-symmetric: slipping segments follow their
    wrap angles) against central differences, in a mixed pattern (slip in, stick, reverse slip)."""
    m = Model(presets.paper().replace(tendon_friction=0.3))
    s = m.fk_history((3.0, 1.0, 0.0), P20)
    h = friction_step.FrictionHistory(m, 0.3)
    h.held = s.segment_tensions.copy()
    h.held[0] *= 1.01 ** np.arange(m.n)               # tendon 1 off its cone's edges (a loaded state is on them)
    T = np.array([2.9, 1.2, 0.0])                     # tendon 1 released, tendon 2 pulled on
    codes = h._profile(s.q, T, False)[1]
    assert codes[0].tolist() == [-1] + [0] * (m.n - 1) and np.all(codes[1] == 1), codes
    Q, K = h.forces(s.q, T, P20, np.zeros(3))
    assert np.max(np.abs(K - K.T)) > 1e-4 * np.max(np.abs(K))          # friction is not conservative
    rng = np.random.default_rng(1)
    d = np.zeros(m.ndof)
    d[6:] = rng.standard_normal(m.ndof - 6)
    eps = 1e-7
    fd = (h.forces(s.q + eps * d, T, P20, np.zeros(3))[0] - h.forces(s.q - eps * d, T, P20, np.zeros(3))[0]) / (2 * eps)
    assert np.linalg.norm(K @ d - fd) < 1e-5 * np.linalg.norm(fd), np.linalg.norm(K @ d - fd) / np.linalg.norm(fd)


def test_the_compiled_wrap_angles_are_the_laws():
    """friction_step.wrap_angles (one compiled loop) against the law's vectorised tendon_friction.wrap_angles,
    on a bent state and on the straight one (gradients zero where α = 0)."""
    m = Model(presets.paper().replace(tendon_friction=0.3))
    for q in (m.fk_history((3.0, 1.0, 0.0), P20).q, m.q_ref):
        ok, P, G = tf.guide_points(q, m.n, m._E, m._d, m._co, m._so)
        a_ref, d_ref = tf.wrap_angles(P, G, m._e1, m.ndof)
        a, d = friction_step.wrap_angles(P, G, m._e1, m.ndof)
        assert np.allclose(a, a_ref, rtol=1e-13, atol=1e-15)
        assert np.allclose(d, d_ref, rtol=1e-12, atol=1e-12 * max(np.abs(d_ref).max(), 1.0))


def test_a_run_without_a_history_starts_at_rest_on_fk_history():
    """No q0, no segment_tensions: the run starts at rest at fk_history's state of the t = 0 loads (loaded
    from slack) and stays there under constant loads — not at the frictionless fk's state."""
    m = Model(presets.paper().replace(tendon_friction=0.3))
    sim = m.simulate(0.05, 1e-3, tensions=(2.0, 0.5, 0.0), pressure=P20, damping={"alpha": 20.0})
    st = m.fk_history((2.0, 0.5, 0.0), P20)
    assert np.max(np.abs(sim.tip - st.tip)) < 1e-9
    assert np.allclose(sim.segment_tensions[-1], st.segment_tensions, rtol=0, atol=1e-9)
    assert np.linalg.norm(st.tip - m.fk((2.0, 0.5, 0.0), P20).tip) > 1e-3
    again = m.simulate(0.02, 1e-3, tensions=(2.0, 0.5, 0.0), pressure=P20, damping={"alpha": 20.0},
                       segment_tensions=st.segment_tensions)         # a given history, no q0: a step from it
    assert np.max(np.abs(again.tip - st.tip)) < 1e-9


def test_a_step_from_the_straight_state_slips_and_dissipates():
    """A tension step 0 → 2 N from the straight actuator (q0 given, no history: every segment slack before):
    the guides slip toward the motor (segment tensions below the motor's), friction dissipates energy, and
    the balance holds as in the frictionless run of the same step."""
    m0, m = Model(presets.paper()), Model(presets.paper().replace(tendon_friction=0.2))
    q0 = m0.fk((0.0, 0.0, 0.0), P20).q
    kw = dict(q0=q0, tensions=(2.0, 0.0, 0.0), pressure=P20, damping={"alpha": 40.0})
    a, b = m0.simulate(0.3, 0.5e-3, **kw), m.simulate(0.3, 0.5e-3, **kw)
    T = b.segment_tensions[-1, 0]
    assert np.all(T <= 2.0) and np.all(np.diff(T) < 0) and T[-1] < 1.95, T
    assert b.friction_dissipated[-1] > 1e-4
    drift = lambda s: abs((s.energy + s.dissipated)[-1] - (s.energy + s.dissipated)[0])
    assert drift(b) < 2 * drift(a) + 1e-3 * b.friction_dissipated[-1], (drift(a), drift(b))


_BENT = {}


def _bent():
    if not _BENT:
        m = Model(presets.paper().replace(tendon_friction=0.3))
        _BENT["m"], _BENT["q"] = m, m.fk_history((3.0, 1.0, 0.5), P20).q
    return _BENT["m"], _BENT["q"]


@settings(max_examples=40, deadline=None)
@given(held=st.lists(st.floats(0.0, 5.0), min_size=18, max_size=18),
       motor=st.lists(st.floats(0.0, 5.0), min_size=3, max_size=3))
def test_a_committed_step_is_in_the_cone_and_holds_itself(held, motor):
    """Any held tensions and motor tensions: the step's segment tensions lie in their cones, and once
    committed they are the law's own answer at that state (evaluating again changes nothing, bit for bit)."""
    m, q = _bent()
    h = friction_step.FrictionHistory(m, 0.3)
    h.held = np.array(held).reshape(m.m, m.n)
    T_m = np.array(motor)
    T, _ = h.at(q, T_m)
    lo, hi = cone(m, q, T_m, T, 0.3)
    assert np.all(T >= lo * (1 - 1e-12)) and np.all(T <= hi * (1 + 1e-12))
    h.commit(q, T_m)
    assert np.array_equal(h.held, T)
    assert np.array_equal(h.at(q, T_m)[0], T)


# ------------------------------------------------------------------------------------------------ quasi-static limit
@pytest.fixture(scope="module")
def slow_runs():
    """Tendon 1 from 0.5 N (loaded from slack) up to 3 N and down to 1.5 N, each ramp 1 s then 0.3 s held."""
    m = light(0.3)
    s0 = m.fk_history((0.5, 0, 0), P20)
    up = m.simulate(1.3, 2e-3, q0=s0.q, tensions=ramp(0.5, 3.0, 1.0), pressure=P20, damping={"alpha": ALPHA},
                    segment_tensions=s0.segment_tensions)
    down = m.simulate(1.3, 2e-3, q0=up.q[-1], tensions=ramp(3.0, 1.5, 1.0), pressure=P20,
                      damping={"alpha": ALPHA}, segment_tensions=up.segment_tensions[-1])
    s1 = m.fk_history((3.0, 0, 0), P20, state=s0)
    s2 = m.fk_history((1.5, 0, 0), P20, state=s1)
    return m, (up, s1), (down, s2)


def test_a_slow_damped_run_ends_on_the_static_history(slow_runs):
    """Loading and unloading at a slow rate end on fk_history's states: the tips within 10 µm and 2 µm
    (measured 4.7 and 0.5 µm) of a 68 and 39 mm move, the segment tensions within 2 mN."""
    _m, (up, s1), (down, s2) = slow_runs
    assert np.linalg.norm(s1.tip - up.tip[0]) > 0.05
    d_up, d_down = (np.linalg.norm(r.tip[-1] - st.tip) * 1e6 for r, st in ((up, s1), (down, s2)))
    assert (f"{d_up:.1f}", f"{d_down:.1f}") == ("4.7", "0.5"), (d_up, d_down)      # docs/friction.md's digits
    for sim, st, tol in ((up, s1, 10e-6), (down, s2, 2e-6)):
        assert np.linalg.norm(sim.tip[-1] - st.tip) < tol, np.linalg.norm(sim.tip[-1] - st.tip)
        assert np.max(np.abs(sim.segment_tensions[-1] - st.segment_tensions)) < 2e-3
        assert np.max(np.abs(sim.v[-1])) < 1e-3


def test_every_segment_stays_in_its_cone(slow_runs):
    """Along both runs, every segment tension lies in the capstan cone of the tension before it."""
    m, (up, _), (down, _) = slow_runs
    for sim in (up, down):
        for i in range(0, len(sim.t), 50):
            lo, hi = cone(m, sim.q[i], sim.tensions[i], sim.segment_tensions[i], 0.3)
            T = sim.segment_tensions[i]
            assert np.all(T >= lo - 1e-9) and np.all(T <= hi + 1e-9)


def test_stick_holds_a_tension_ratio_inside_the_cone():
    """A small release (3 → 2.8 N) after loading: the guide next to the motor slips back (segment 0 on its
    cone's upper edge), segment 1 sticks — its tension the loaded state's, its ratio strictly inside the cone —
    and the far segments stay on their lower edges (loaded); the same pattern, tensions and tip (within 1 µm)
    as fk_history's step."""
    m = light(0.3)
    s1 = m.fk_history((3.0, 0, 0), P20)
    sim = m.simulate(0.5, 2e-3, q0=s1.q, tensions=ramp(3.0, 2.8, 0.3), pressure=P20, damping={"alpha": ALPHA},
                     segment_tensions=s1.segment_tensions)
    T = sim.segment_tensions[-1]
    lo, hi = cone(m, sim.q[-1], sim.tensions[-1], T, 0.3)
    inside = (T > lo * (1 + 1e-4)) & (T < hi * (1 - 1e-4))
    assert inside[0].tolist() == [False, True] + [False] * (m.n - 2), (T[0], lo[0], hi[0])
    assert abs(T[0, 1] - s1.segment_tensions[0, 1]) < 1e-12 * T[0, 1]      # held since the release began
    assert abs(T[0, 0] - hi[0, 0]) < 1e-5 * T[0, 0]        # on the edge, up to the run's lag (measured 8e-7)
    st = m.fk_history((2.8, 0, 0), P20, state=s1)
    assert st.sliding[0, 0] == tf.SLIP_OUT and st.sliding[0, 1] == tf.STICK
    assert np.max(np.abs(T - st.segment_tensions)) < 1e-5
    assert np.linalg.norm(sim.tip[-1] - st.tip) < 1e-6


# ------------------------------------------------------------------------------------------------ energy
def test_the_energy_balance_counts_the_friction():
    """A slow cycle 0 → 4 N → 0 (μ = 0.1): energy + dissipated constant to 1e-6 of the dissipation; the
    friction's dissipated energy never decreases (beyond 1e-3 of itself) and equals the static
    tension_cycle's (128 steps per branch) within 0.5 % (measured 0.07 %); the loop closes."""
    m = light(0.1)
    tri = lambda t: np.array([4.0 * max(1.0 - abs(t - 1.0), 0.0), 0.0, 0.0])
    sim = m.simulate(2.2, 2e-3, tensions=tri, pressure=P20, damping={"alpha": ALPHA})
    bal = sim.energy + sim.dissipated
    Df = sim.friction_dissipated
    assert np.ptp(bal) < 1e-4 * Df[-1], (np.ptp(bal), Df[-1])
    assert np.all(np.diff(Df) > -1e-3 * Df[-1])
    static = m.tension_cycle((4.0, 0, 0), P20, steps=128).dissipated_energy
    assert abs(Df[-1] - static) < 5e-3 * static, (Df[-1], static)
    assert (f"{Df[-1] * 1e3:.3f}", f"{static * 1e3:.3f}") == ("5.249", "5.246")     # docs/friction.md's digits
    assert np.linalg.norm(sim.tip[-1] - sim.tip[0]) < 1e-6
    assert Df[-1] < sim.dissipated[-1]


# ------------------------------------------------------------------------------------------------ errors
def test_bad_segment_tensions_are_refused():
    m = Model(presets.paper().replace(tendon_friction=0.2))
    with pytest.raises(InputError, match="segment_tensions"):
        m.simulate(0.01, 1e-3, tensions=(1.0, 0, 0), segment_tensions=np.ones((m.m, m.n + 1)))
    with pytest.raises(InputError, match="≥ 0 N"):
        m.simulate(0.01, 1e-3, tensions=(1.0, 0, 0), segment_tensions=-np.ones((m.m, m.n)))
    with pytest.raises(InputError):
        m.simulate(0.01, 1e-3, tensions=(1.0, 0, 0), segment_tensions=np.full((m.m, m.n), np.nan))


def test_friction_with_tendons_held_by_length_is_refused_up_front(monkeypatch):
    """Held lengths make stuck spans keep their length (fk_locked_history), a law the time steps do not have:
    refused before any solve."""
    m = Model(presets.paper().replace(tendon_friction=0.2))
    eq = Model(presets.paper()).fk((1.0, 0, 0), P20)
    monkeypatch.setattr(transient, "_start_state", lambda *a, **k: (_ for _ in ()).throw(AssertionError("solved")))
    with pytest.raises(InputError, match="held by length"):
        m.simulate(0.01, 1e-3, q0=eq.q, lengths=eq.tendon_lengths, pressure=P20)


def test_the_simulate_command_starts_on_the_history_and_reports_no_static_reference(tmp_path):
    """`bellows simulate` with an actuator file with tendon friction: the run starts at rest on
    fk_history's state of the start tensions, and the summary has no static end state (with friction the
    state a step settles on depends on its path): static_tip_mm and overshoot_mm are null."""
    import json
    import subprocess
    import sys
    par = presets.paper().replace(tendon_friction=0.2)
    (tmp_path / "act.toml").write_text(par.to_toml())
    r = subprocess.run([sys.executable, "-m", "validation.commands.main", "simulate", "--preset", "act.toml",
                        "--start-tensions-n", "1,0,0", "--tensions-n", "2,0,0", "--pressure-kpa", "30", "--t-end-s",
                        "0.02", "--dt-ms", "2", "--out", "s"], cwd=tmp_path, capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0, r.stderr
    d = json.loads((tmp_path / "s" / "simulation.json").read_text())
    assert d["static_tip_mm"] is None and d["overshoot_mm"] is None
    start = Model(par).fk_history((1.0, 0.0, 0.0), 30e3)
    assert np.allclose(d["tip_start_mm"], start.tip * 1e3, rtol=0, atol=1e-6)
