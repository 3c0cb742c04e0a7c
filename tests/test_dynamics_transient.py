"""Transient response of the reduced model (Model.simulate, ancf.dynamics.transient) against what it must
obey: second-order convergence in the step (log-log fit), energy conservation without damping, the modal
frequencies and damping ratios of the linearisation, the static equilibrium at the end of a slow, damped
load, the locked-tendon equilibrium, the pressure supply's closed form, and typed errors for bad inputs."""

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from ancf import Model, presets
from ancf.errors import BellowsError, CollapsedStateError, ConvergenceError, InputError, LimitError

P30 = 30e3


@pytest.fixture(scope="module")
def model():
    return Model(presets.paper())


@pytest.fixture(scope="module")
def bent(model):
    return model.fk((2.0, 0.0, 0.0), P30)


def released(model, eq, amplitude=5e-3):
    """The equilibrium of eq's loads plus a vertical tip force that moves the tip by about ``amplitude`` [m]
    (to be released: the force is not applied in the run), and eq's first frequency [Hz]."""
    from ancf import compliance
    Fz = amplitude / compliance.tension(model, eq).C_p[2, 2]
    q0 = model.fk(eq.tensions, eq.pressure, (0.0, 0.0, Fz), q0=eq.q).q
    return q0, model.modes(eq, 1).frequencies_hz[0]


def crossings(t, d):
    i = np.where(np.sign(d[:-1]) != np.sign(d[1:]))[0]
    return t[i] - d[i] * (t[i + 1] - t[i]) / (d[i + 1] - d[i])


@pytest.mark.parametrize("rho", [1.0, 0.6])
def test_the_integrator_converges_at_second_order(model, bent, rho):
    """Tip position after a large, fast release (T₁ smoothly 4 → 1 N in 0.1 s: a swing of several cm,
    nonlinear) against a run with an 8× smaller step: the error falls like dt² for every spectral radius
    once the step resolves the modes the release excites (up to ~100 Hz here)."""
    q0 = model.fk((4.0, 0, 0), P30).q
    f1 = model.modes(bent, 1).frequencies_hz[0]
    t_end = 0.4 / f1
    smooth = lambda x: 6 * x ** 5 - 15 * x ** 4 + 10 * x ** 3
    T = lambda t: np.array([4.0 - 3.0 * smooth(min(t / 0.1, 1.0)), 0, 0])
    run = lambda dt: model.simulate(t_end, dt, q0=q0, tensions=T, pressure=P30, damping=0.0,
                                    rho_inf=rho).tip[-1]
    ref = run(t_end / 1280)
    dts = [t_end / 40, t_end / 80, t_end / 160]
    err = [np.linalg.norm(run(dt) - ref) for dt in dts]
    rate = np.polyfit(np.log(dts), np.log(err), 1)[0]
    assert 1.8 < rate < 2.3, (err, rate)


def test_energy_is_conserved_without_damping(model, bent):
    """20 periods of the first bending mode at the step that resolves its frequency to 1 %: the energy
    (kinetic + elastic + gravity + load potentials) drifts by < 1 % of the vibration energy."""
    q0, f1 = released(model, bent, 5e-3)
    sim = model.simulate(20 / f1, 0.055 / f1, q0=q0, tensions=(2, 0, 0), pressure=P30, damping=0.0,
                         rho_inf=1.0)
    e_vib = sim.kinetic.max()
    assert e_vib > 0
    assert abs(sim.energy[-1] - sim.energy[0]) < 0.01 * e_vib
    assert np.ptp(sim.energy) < 0.02 * e_vib
    assert np.all(sim.dissipated == 0) and np.all(sim.work == 0)
    # ... and with high-frequency dissipation (rho_inf < 1) it loses energy, but little at the first mode
    lossy = model.simulate(20 / f1, 0.055 / f1, q0=q0, tensions=(2, 0, 0), pressure=P30, damping=0.0,
                           rho_inf=0.5)
    assert lossy.energy[-1] < sim.energy[-1]


def test_small_vibrations_have_the_modal_frequency(model, bent):
    q0, f1 = released(model, bent, 0.2e-3)
    sim = model.simulate(10 / f1, 0.01 / f1, q0=q0, tensions=(2, 0, 0), pressure=P30, damping=0.0, rho_inf=1.0)
    tc = crossings(sim.t, sim.tip[:, 2] - bent.tip[2])
    f = (len(tc) - 1) / (2 * (tc[-1] - tc[0]))
    # generalized-α at ρ∞ = 1 (trapezoidal rule) shifts the period by (ωh)²/12
    assert f == pytest.approx(f1 / (1 + (2 * np.pi * 0.01) ** 2 / 12), rel=2e-4)


def test_the_decay_matches_the_modal_damping_ratio(model, bent):
    """Mass-proportional damping α: the logarithmic decrement of the first mode gives ζ = α/(2ω₁), the
    ratio modes() reports; energy + dissipated stays constant."""
    q0, f1 = released(model, bent, 0.2e-3)
    alpha = 0.6
    zeta = model.modes(bent, 1, damping={"alpha": alpha}).damping_ratios[0]
    assert zeta == pytest.approx(alpha / (4 * np.pi * f1), rel=1e-9)
    sim = model.simulate(8 / f1, 0.01 / f1, q0=q0, tensions=(2, 0, 0), pressure=P30, damping={"alpha": alpha},
                         rho_inf=1.0)
    d = sim.tip[:, 2] - bent.tip[2]
    peaks = [i for i in range(1, len(d) - 1) if d[i] > d[i - 1] and d[i] >= d[i + 1] and d[i] > 0]
    rate = np.polyfit(sim.t[peaks], np.log(d[peaks]), 1)[0]               # −ζ ω
    assert -rate / (2 * np.pi * f1) == pytest.approx(zeta, rel=0.02)
    total = sim.energy + sim.dissipated
    assert np.ptp(total) < 5e-3 * sim.dissipated[-1]
    assert sim.dissipated[-1] > 0.5 * (sim.energy[0] - model.fk((2, 0, 0), P30).energy)


def test_axial_damping_dissipates_and_keeps_the_energy_balance(model, bent):
    q0, f1 = released(model, bent, 5e-3)
    sim = model.simulate(2 / f1, 0.002 / f1, q0=q0, tensions=(2, 0, 0), pressure=P30,
                         damping={"axial": 2.0}, rho_inf=1.0)
    assert np.all(np.diff(sim.dissipated) >= 0) and sim.dissipated[-1] > 0
    assert np.ptp(sim.energy + sim.dissipated) < 0.02 * sim.dissipated[-1]


def test_a_slow_damped_load_ends_on_the_static_equilibrium(model):
    """Tension ramped 0 → (2, 1, 0) N and pressure 0 → 30 kPa over 1 s, then held; mass-proportional
    damping α = 20/s (every mode decays like e^{−10 t}): the run ends on fk's equilibrium, and the work of the
    loads is accounted for."""
    ramp = lambda t: min(t / 1.0, 1.0)
    sim = model.simulate(3.0, 5e-3, tensions=lambda t: np.array([2.0, 1.0, 0.0]) * ramp(t),
                         pressure=lambda t: P30 * ramp(t), damping={"alpha": 20.0})
    eq = model.fk((2.0, 1.0, 0.0), P30)
    assert np.linalg.norm(sim.tip[-1] - eq.tip) < 1e-6
    assert sim.kinetic[-1] < 1e-8 * sim.kinetic.max()
    assert np.linalg.norm(sim.tip[-1] - sim.tip[-2]) / sim.dt < 1e-5             # the tool point is at rest
    # energy balance with time-varying loads: energy + dissipated constant
    assert np.ptp(sim.energy + sim.dissipated) < 0.02 * max(sim.dissipated[-1], 1e-12)


def test_locked_tendons_hold_a_tip_load_like_fk_locked():
    """Elastic tendons (k_s = 2 kN/m) held at their rest lengths: a tip force applied and the motion damped
    out ends on fk_locked's equilibrium with the same tendons and force."""
    m = Model(presets.paper().replace(tendon_stiffness=2000.0))
    eq = m.fk((2.0, 1.0, 1.0), P30)
    l0 = m.rest_lengths(eq)
    F = (0.0, 0.0, -0.4)
    sim = m.simulate(3.0, 5e-3, q0=eq.q, lengths=l0, pressure=P30, tip_force=lambda t: np.array(F) * min(t / 0.3, 1),
                     damping=0.3)
    ref = m.fk_locked(l0, P30, F)
    assert np.linalg.norm(sim.tip[-1] - ref.tip) < 1e-6
    assert np.allclose(sim.tensions[-1], ref.tensions, atol=1e-4)
    # at the start the springs carry the equilibrium's tensions
    assert np.allclose(sim.tensions[0], eq.tensions, atol=1e-9)


def test_a_tendon_goes_slack_and_taut_again():
    """Tendon 1 held, its motor paying out 6 mm and reeling it back in: it goes slack (tension 0) and taut
    again, and both are events."""
    m = Model(presets.paper().replace(tendon_stiffness=2000.0))
    eq = m.fk((1.0, 1.0, 1.0), P30)
    l0 = m.rest_lengths(eq)
    prof = lambda t: l0 + np.array([6e-3 * np.sin(np.pi * min(t / 0.6, 1.0)), 0, 0])
    sim = m.simulate(0.8, 2e-3, q0=eq.q, lengths=prof, pressure=P30, damping=0.1)
    kinds = [(e["kind"], e["tendon"]) for e in sim.events if e["kind"] in ("slack", "taut")]
    assert ("slack", 0) in kinds and ("taut", 0) in kinds
    assert kinds.index(("slack", 0)) < kinds.index(("taut", 0))
    assert np.any(sim.tensions[:, 0] == 0) and np.all(sim.tensions >= 0)


def test_energy_balance_under_a_pressure_ramp_with_a_pressure_dependent_law():
    """EI(λ, p) = EI(λ)(1 + 0.9 p̂), EA(λ, p) = EA(λ)(1 + 0.3 p̂): while the pressure ramps 0 → 60 kPa the
    potential's stiffness changes with it; the work of the loads (the change of the potential at fixed
    state) includes that, so kinetic + potential − work + dissipated stays constant, and the run ends on
    fk's equilibrium of the pressure-dependent law."""
    law = presets.paper().stiffness.with_pressure(EA=(0.3,), EI=(0.9,))
    m = Model(presets.paper().replace(stiffness=law))
    ramp = lambda t: min(t / 0.3, 1.0)
    sim = m.simulate(1.5, 2e-3, tensions=(2.0, 0.0, 0.0), pressure=lambda t: 60e3 * ramp(t),
                     q0=m.fk((2.0, 0.0, 0.0), 0.0).q, damping={"alpha": 20.0})
    total = sim.energy + sim.dissipated
    assert abs(sim.work[-1]) > 0
    assert np.ptp(total) < 1e-3 * abs(sim.work[-1])
    assert np.linalg.norm(sim.tip[-1] - m.fk((2.0, 0.0, 0.0), 60e3).tip) < 1e-6


def test_the_pressure_supply_follows_its_first_order_law(model):
    """p' = (p_cmd − p)/τ for a step command: p(t) = p_cmd (1 − e^{−t/τ}) to the trapezoidal rule's
    accuracy."""
    tau = 0.05
    sim = model.simulate(0.2, 1e-3, tensions=(0, 0, 0), pressure=P30, pressure_tau=tau, pressure0=0.0,
                         damping=0.2)
    exact = P30 * (1 - np.exp(-sim.t / tau))
    assert np.abs(sim.pressure - exact).max() < 2e-4 * P30
    with pytest.raises(InputError, match="pressure_tau"):
        model.simulate(0.1, 1e-3, tensions=(0, 0, 0), pressure=P30, pressure0=0.0)


def test_bad_inputs_fail_before_integrating(model, bent):
    q = bent.q
    cases = [
        (dict(tensions=(2, 0, 0), lengths=bent.tendon_lengths), InputError, "exactly one"),
        (dict(), InputError, "exactly one"),
        (dict(tensions=lambda t: np.array([2.0, -1.0 if t > 0.05 else 0.0, 0.0])), InputError, "push"),
        (dict(tensions=(2, 0, 0), pressure=lambda t: 2e6 * t), LimitError, "kPa"),
        (dict(tensions=lambda t: np.array([np.nan, 0, 0])), InputError, "finite"),
        (dict(tensions=(2, 0)), InputError, "shape"),
        (dict(tensions=(2, 0, 0), damping={"gamma": 1}), InputError, "unknown"),
        (dict(tensions=(2, 0, 0), rho_inf=1.5), InputError, "rho_inf"),
        (dict(lengths=bent.tendon_lengths, tendon_penalty=-1.0), InputError, "tendon_penalty"),
    ]
    for kw, exc, msg in cases:
        with pytest.raises(exc, match=msg):
            model.simulate(0.1, 1e-3, q0=q, **kw)
    with pytest.raises(InputError, match="dt"):
        model.simulate(0.1, 0.0, q0=q, tensions=(2, 0, 0))
    with pytest.raises(InputError, match="line mass"):
        Model(presets.paper().replace(line_mass=0.0)).simulate(0.1, 1e-3, q0=q, tensions=(2, 0, 0))
    with pytest.raises(InputError, match="q0"):
        model.simulate(0.1, 1e-3, lengths=bent.tendon_lengths)
    with pytest.raises(InputError, match="v0"):
        model.simulate(0.1, 1e-3, q0=q, v0=np.ones(model.ndof), tensions=(2, 0, 0))


def test_a_run_that_breaks_down_says_when(model):
    """A compressive tip load far beyond buckling: the run fails with a typed error naming the time,
    never returning a blown-up state."""
    with pytest.raises((ConvergenceError, CollapsedStateError)) as info:
        model.simulate(0.5, 2e-3, tensions=(0, 0, 0), tip_force=lambda t: np.array([-300.0 * t, 0, 2.0 * t]),
                       check_limits=False, damping=0.1, max_halvings=3)
    assert "t = " in str(info.value)


def test_ctrl_c_keeps_the_rows_done(model, bent):
    def stop(t, t_end):
        if t > 0.05:
            raise KeyboardInterrupt
    sim = model.simulate(1.0, 1e-2, q0=bent.q, tensions=(2, 0, 0), pressure=P30, damping=0.0, progress=stop)
    assert sim.interrupted and 5 <= len(sim.t) <= 8 and sim.q.shape == (len(sim.t), model.ndof)
    assert np.allclose(sim.tip[0], bent.tip)


@settings(max_examples=12, deadline=None)
@given(T=st.tuples(*[st.floats(0, 5)] * 3), p=st.floats(0, 120e3), Fz=st.floats(-0.5, 0.5),
       zeta=st.floats(0, 0.5))
def test_any_admissible_load_step_gives_a_finite_run_or_a_typed_error(T, p, Fz, zeta):
    m = Model(presets.paper())
    try:
        sim = m.simulate(0.1, 2e-3, q0=m.fk((0, 0, 0), p).q, tensions=T, pressure=p, tip_force=(0, 0, Fz),
                         damping=zeta)
    except BellowsError:
        return
    assert np.all(np.isfinite(sim.q)) and np.all(np.isfinite(sim.energy))
    # constant loads: no blow-up — energy is created only by the scheme's error, mostly in the first step of
    # a violent load step from rest (T = (0, 0, 2) N at 0 kPa: 18 % of the motion's peak kinetic energy at
    # 5 ms, 0.2 % at 1 ms — like dt²; the nonlinear generalized-α is not strictly dissipative); the damping
    # only takes energy out
    assert sim.energy.max() <= sim.energy[0] + 0.1 * sim.kinetic.max() + 1e-12
    assert np.all(np.diff(sim.dissipated) >= 0)


def test_a_motor_gives_way_at_its_holding_force():
    """Held tendons with a holding_force: a tip load that would need 5.4 N on tendon 1 gets 2.5 N — the
    motor gives way (an event) — and the run ends on the equilibrium of tensions (2.5, 0, 0) under the load,
    with energy + dissipated conserved."""
    m = Model(presets.paper().replace(tendon_stiffness=2000.0))
    eq = m.fk((2.0, 1.0, 1.0), P30)
    l0 = m.rest_lengths(eq)
    F = np.array([0.0, 0.0, -1.5])
    sim = m.simulate(2.0, 5e-3, q0=eq.q, lengths=l0, pressure=P30, tip_force=lambda t: F * min(t / 0.3, 1),
                     damping={"alpha": 20.0}, holding_force=2.5)
    assert m.fk_locked(l0, P30, F).tensions[0] > 5.0                      # what a stiff motor would hold
    assert np.allclose(sim.tensions[-1], (2.5, 0, 0), atol=1e-9)
    assert np.linalg.norm(sim.tip[-1] - m.fk((2.5, 0, 0), P30, F).tip) < 1e-6
    assert any(e["kind"] == "overpowered" and e["tendon"] == 0 for e in sim.events)
    assert np.ptp(sim.energy + sim.dissipated) < 2e-3 * sim.dissipated[-1]
    with pytest.raises(InputError, match="holding_force"):
        m.simulate(0.1, 1e-3, q0=eq.q, tensions=(1, 0, 0), holding_force=2.0)


def test_an_undamped_actuator_is_announced_not_taken_silently(model, bent):
    """The paper preset states no damping: a run without damping= warns (UndampedWarning), says
    damping_source "none" and dissipates nothing; damping=0.0 (asked for) is silent.  An actuator that states
    damping has it used: the same run as with its coefficients given, damping_source "actuator"."""
    import warnings
    from ancf.dynamics.damping import UndampedWarning
    q0 = model.fk((0, 0, 0), P30).q
    with pytest.warns(UndampedWarning, match="states no damping"):
        sim = model.simulate(0.05, 5e-3, q0=q0, tensions=(2, 0, 0), pressure=P30)
    assert sim.damping_source == "none" and np.all(sim.dissipated == 0)
    with warnings.catch_warnings():
        warnings.simplefilter("error", UndampedWarning)
        assert model.simulate(0.02, 5e-3, q0=q0, tensions=(2, 0, 0), pressure=P30,
                              damping=0.0).damping_source == "given"
        damped = Model(presets.paper().replace(rayleigh_alpha=4.0, axial_damping=0.2))
        own = damped.simulate(0.05, 5e-3, q0=q0, tensions=(2, 0, 0), pressure=P30)
    given_ = damped.simulate(0.05, 5e-3, q0=q0, tensions=(2, 0, 0), pressure=P30,
                             damping={"alpha": 4.0, "axial": 0.2})
    assert own.damping_source == "actuator" and own.damping == {"alpha": 4.0, "beta": 0.0, "axial": 0.2}
    assert np.array_equal(own.tip, given_.tip) and own.dissipated[-1] > 0
