"""Tendon friction in the dynamic simulated rig (ancf.dynamics.held_friction, hardware.sim_dynamics): the
held-length stick/slip law per time step (cones, slip directions, material, dissipation), its tangent against
finite differences, μ = 0 untouched, the start at rest on the static friction plant's state, a load step
that stuck guides resist, and the quasi-static limit (a slow motor cycle follows the static plant's loop)."""

import numpy as np
import pytest

from ancf import Model, presets
from ancf.dynamics.held_friction import return_map, tendon_state
from hardware import PlantOptions, SimulatedRig

P = 30e3
MU = 0.3


def _random_tendon(rng, n=6, Pn=1.6e5, k=1e6):
    """A tendon state near equilibrium: lengths l, wrap angles, held materials s, motor length lm."""
    l = 0.027 + 1e-3 * rng.random(n)
    alpha = 0.3 * rng.random(n)
    T0 = 2 * rng.random() * np.exp(MU * np.cumsum(alpha * rng.choice([-1, 0, 1], n)))
    s = l * Pn / (Pn + T0) + 2e-6 * rng.standard_normal(n)
    lm = s.sum() - T0[0] / k + 1e-5 * rng.standard_normal()
    return l, alpha, s, lm, Pn, k


@pytest.mark.parametrize("seed", range(40))
def test_the_return_mapping_obeys_the_capstan_law(seed):
    rng = np.random.default_rng(seed)
    l, alpha, s, lm, Pn, k = _random_tendon(rng)
    codes0 = None if seed % 2 else rng.choice([-1, 0, 1], len(l))
    codes, (T, Tm, s1, f, _spans) = return_map(l, alpha, s, 0.0, lm, k, Pn, MU, np.inf, codes0)
    Tin = np.concatenate(([Tm], T[:-1]))
    tol = 1e-5 * (1 + T.max())
    assert np.all(T <= Tin * np.exp(MU * alpha) + tol) and np.all(T >= Tin * np.exp(-MU * alpha) - tol)  # cones
    for j in np.flatnonzero(codes):                                   # slip on the edge, the way it slides
        assert T[j] == pytest.approx(Tin[j] * np.exp(codes[j] * MU * alpha[j]), rel=1e-9, abs=1e-12)
        assert codes[j] * f[j] >= -1e-12 or T[j] == 0                # (a slack span's material is free)
    assert np.all(f[codes == 0] == 0)                                 # stuck: no material crosses
    assert np.all(f * (T - Tin) >= -1e-12)                            # friction only dissipates
    assert np.allclose(s1 - s, f - np.append(f[1:], 0.0), atol=1e-15)  # material balance at every guide
    taut = T > 0                                                      # each segment's tension from its stretch
    assert np.allclose(T[taut], Pn * (l[taut] - s1[taut]) / s1[taut], rtol=1e-7)
    assert Tm == pytest.approx(max(0.0, k * (s1.sum() - lm)), rel=1e-7, abs=1e-9)


def test_without_slip_a_held_tendon_is_two_springs_in_series():
    n, Pn, k = 3, 1e5, 2e4
    l = np.full(n, 0.05)
    s = l.copy()
    T, Tm, *_ = tendon_state(l, np.zeros(n), s, 0.0, s.sum() - 1e-4, k, Pn, 0.3, np.inf, np.zeros(n, int))
    assert Tm == pytest.approx(2.0) and np.all(T == 0)               # k × 0.1 mm; the inside unstretched
    codes, (T, Tm, *_r) = return_map(l, np.zeros(n), s, 0.0, s.sum() - 1e-4, k, Pn, 0.3, np.inf)
    # straight (α = 0): the cone is a point, the tendon slips through; one tension, compliance 1/k + L/P
    assert np.allclose(T, Tm) and Tm == pytest.approx(1e-4 / (1 / k + 0.15 / Pn), rel=1e-6)


@pytest.fixture(scope="module")
def ref():
    return Model(presets.paper()).fk((2.0, 1.0, 0.5), P)


def _rig(mu, ref, **kw):
    rig = SimulatedRig(presets.paper().replace(tendon_friction=mu), P, dynamics=True,
                       options=PlantOptions(damping=1.0), **kw)
    rig.command(ref.tendon_lengths)
    return rig


def test_the_tangent_is_the_derivative_of_the_tendon_forces(ref):
    rig = _rig(MU, ref)
    rig.true_tip()
    law, q = rig._plant.dyn.friction, rig._plant.dyn.state.q.copy()
    law.lm = law.lm_done - np.array([2e-5, 0.0, 0.0])               # the motor pulled tendon 1: guides slip
    law.trial = law.solve(q, False)["codes"]
    assert np.any(law.trial != 0) and np.any(law.trial == 0)
    _Q, K = law.forces(q, None, P, np.zeros(3))
    h = 1e-8
    for j in range(6, q.size, 5):
        e = np.zeros(q.size)
        e[j] = h
        fd = (law.forces(q + e, None, P, np.zeros(3))[0] - law.forces(q - e, None, P, np.zeros(3))[0]) / (2 * h)
        assert np.allclose(fd, K[:, j], rtol=0, atol=1e-5 * np.abs(K).max())


def test_mu_zero_is_the_frictionless_dynamic_plant(ref):
    rig = _rig(0.0, ref)
    assert rig._plant.dyn.friction is None
    rig.true_tip()
    d = rig._plant.dyn
    s = d.state
    rig.advance(0.004)
    sim = d.model.simulate(0.004, 1e-3, q0=s.q, v0=s.v, lengths=lambda t: ref.tendon_lengths, pressure=P,
                           tip_force=lambda t: np.zeros(3), damping=d.damping, rho_inf=d.rho_inf,
                           check_limits=False)
    assert np.array_equal(rig.true_tip(), sim.tip[-1])


def test_the_friction_plant_starts_on_the_static_state_and_stays_at_rest(ref):
    static = SimulatedRig(presets.paper().replace(tendon_friction=MU), P)
    static.command(ref.tendon_lengths)
    rig = _rig(MU, ref)
    tip0 = rig.true_tip()
    assert np.linalg.norm(tip0 - static.true_tip()) < 1e-5           # µm: the stiff tendon's stretch
    rig.advance(0.01)
    assert np.linalg.norm(rig.true_tip() - tip0) < 1e-9
    assert rig._plant.dyn.friction.dissipated == pytest.approx(0.0, abs=1e-12)


def test_stuck_guides_resist_a_small_load_step(ref):
    """A 0.05 N load step at fixed motor lengths: the frictionless locked actuator gives 0.39 mm; with μ = 0.3
    the guides hold part of it, the dynamic plant 30 ms later within 0.06 mm of the static friction plant."""
    F = lambda t: np.array([0.0, 0.0, -0.05 if t >= 0.002 else 0.0])
    m = Model(presets.paper())
    free = m.fk_locked(ref.tendon_lengths, P, (0, 0, -0.05)).tip - m.fk_locked(ref.tendon_lengths, P).tip
    static = SimulatedRig(presets.paper().replace(tendon_friction=MU), P, load=F)
    static.command(ref.tendon_lengths)
    a = static.true_tip()
    static.advance(0.03)
    rig = _rig(MU, ref, load=F)
    tip0 = rig.true_tip()
    rig.advance(0.03)
    moved = rig.true_tip() - tip0
    assert abs(moved[2]) < 0.7 * abs(free[2])
    assert np.linalg.norm(moved - (static.true_tip() - a)) < 6e-5
    law = rig._plant.dyn.friction
    assert law.dissipated >= 0.0


def _potential(rig):
    """Π [J] of the dynamic friction plant now: the actuator's elastic energy − p V (no tip load), the tendons'
    elastic energy with the held materials, and the kinetic energy."""
    from ancf.dynamics.transient import _EnergyParts
    import types
    d = rig._plant.dyn
    ep = _EnergyParts(d.model, types.SimpleNamespace(length_mode=False))
    q = d.state.q
    return (ep.potential(ep.parts(q), np.zeros(d.model.m), P, np.zeros(3), None) + d.friction.tendon_energy(q)
            + d.friction.kinetic_energy)


def test_energy_closes_over_a_closed_motor_cycle(ref):
    """Motor 1 pulls 0.2 mm and returns (10 mm/s, 30 ms holds, ζ = 1): the motor's work equals the friction's
    and the damping's dissipation plus the change of kinetic + potential energy to 2 % of the work (measured
    −0.9 %), and the friction dissipates ≥ 0 in every period."""
    rig = SimulatedRig(presets.paper().replace(tendon_friction=MU), P, dynamics=True,
                       options=PlantOptions(damping=1.0, length_rate=0.01))
    rig.command(ref.tendon_lengths)
    rig.true_tip()
    law = rig._plant.dyn.friction
    E0 = _potential(rig)
    pulled = ref.tendon_lengths - np.array([2e-4, 0.0, 0.0])
    for target in (pulled, ref.tendon_lengths):
        rig.command(target)
        for _ in range(50):
            d0 = law.dissipated
            rig.advance(1e-3)
            assert law.dissipated - d0 >= -1e-15
    W = law.motor_work
    assert W > 1e-5 and law.dissipated > 0.3 * W
    balance = W - law.dissipated - law.damping_dissipated - (_potential(rig) - E0)
    assert abs(balance) < 0.02 * W


def test_small_friction_approaches_the_frictionless_plant(ref):
    """A 0.2 mm pull of motor 1 (10 mm/s, 30 ms): the tip's distance to the μ = 0 plant's falls with μ, about in
    proportion (measured 8.7 µm at μ = 0.01, 0.95 µm at μ = 0.001)."""
    l1 = ref.tendon_lengths - np.array([2e-4, 0.0, 0.0])
    moved = {}
    for mu in (0.0, 0.01, 0.02):
        rig = SimulatedRig(presets.paper().replace(tendon_friction=mu), P, dynamics=True,
                           options=PlantOptions(damping=1.0, length_rate=0.01))
        rig.command(ref.tendon_lengths)
        a = rig.true_tip()
        rig.command(l1)
        rig.advance(0.03)
        moved[mu] = rig.true_tip() - a
    d1, d2 = (np.linalg.norm(moved[mu] - moved[0.0]) for mu in (0.01, 0.02))
    assert d1 < 15e-6 and 0.3 * d2 < d1 < 0.7 * d2
    assert np.linalg.norm(moved[0.0]) > 1e-4                          # the pull moved the tip (0.18 mm)


@pytest.mark.parametrize("bad", [dict(l=[0.03, -0.01]), dict(alpha=[0.1, np.nan]), dict(codes0=[0, 2]),
                                 dict(mu=-0.1), dict(s=[0.03])])
def test_the_return_mapping_refuses_bad_input(bad):
    from ancf.errors import InputError
    args = dict(l=[0.03, 0.03], alpha=[0.1, 0.1], s=[0.03, 0.03], c=0.0, lm=0.06, k=1e6, P=3e4, mu=0.3,
                F_hold=np.inf, codes0=None)
    args.update(bad)
    with pytest.raises(InputError):
        return_map(**args)


def _cycle_tips(rig, lengths, path, hold):
    """Tip (k + 1, 3) [m] at rest after each move of a motor cycle: command, let the move run, hold [s]."""
    tips = [rig.true_tip()]
    for L in path:
        rig.command(L)
        rig.advance()
        rig.advance(hold)
        tips.append(rig.true_tip())
    return np.array(tips)


def _quasi_static_gap(amplitude, steps, rates, hold=0.05):
    """Motor 1 pulls ``amplitude`` [m] and returns in ``steps`` moves each way from the rest state of
    fk((1, 0.5, 0.5) N) at 30 kPa, μ = 0.3: the largest distance [m] between the dynamic plant (ζ = 1, at each of
    ``rates`` [m/s], ``hold`` after each move) and the static friction plant queried after each move, per rate;
    and the static loop's gap [m] between its loading and unloading branches at half the amplitude."""
    lengths = Model(presets.paper()).fk((1.0, 0.5, 0.5), P).tendon_lengths
    e = np.array([1.0, 0.0, 0.0])
    path = [lengths - amplitude * j / steps * e for j in [*range(1, steps + 1), *range(steps - 1, -1, -1)]]
    params = presets.paper().replace(tendon_friction=MU)
    static = SimulatedRig(params, P)
    static.command(lengths)
    ref = _cycle_tips(static, lengths, path, 0.0)
    gaps = []
    for rate in rates:
        rig = SimulatedRig(params, P, dynamics=True, options=PlantOptions(damping=1.0, length_rate=rate))
        rig.command(lengths)
        gaps.append(float(np.max(np.linalg.norm(_cycle_tips(rig, lengths, path, hold) - ref, axis=1))))
    half = steps // 2
    return gaps, float(np.linalg.norm(ref[half] - ref[2 * steps - half]))


def _check_quasi_static_limit(gaps, rates, loop):
    """The gap shrinks with the rate, about in proportion (the damping force the moving actuator carries is
    left locked in by the guides that stick when it stops): within 100 µm per mm/s of motor speed (measured
    62 µm at 1 mm/s), and at a quarter of the speed at most half the gap; the loop it resolves is far wider."""
    for g, r in zip(gaps, rates):
        assert g < 0.1 * r                                    # 100 µm per mm/s
    assert gaps[1] < 0.5 * gaps[0]
    assert gaps[-1] < 0.25 * loop


def test_a_slow_motor_cycle_follows_the_static_friction_loop():
    """The quasi-static limit: 0 → 0.2 mm → 0 in 0.1 mm moves at 1 and 0.25 mm/s (measured gaps 62 µm and
    21 µm; the static loop's branches 0.12 mm apart at 0.1 mm)."""
    rates = (1e-3, 2.5e-4)
    gaps, loop = _quasi_static_gap(2e-4, 2, rates)
    _check_quasi_static_limit(gaps, rates, loop)


@pytest.mark.slow
def test_a_slower_motor_cycle_follows_the_static_friction_loop_closer():
    """0 → 0.5 mm → 0 on motor 1 in 0.1 mm moves at 0.5 and 0.125 mm/s (measured gaps 34 µm and 12 µm; the
    static loop's branches 0.17 mm apart at 0.2 mm)."""
    rates = (5e-4, 1.25e-4)
    gaps, loop = _quasi_static_gap(5e-4, 5, rates)
    _check_quasi_static_limit(gaps, rates, loop)
