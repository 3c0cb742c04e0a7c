"""The simulated rig's dynamic plant (PlantOptions(dynamics=True), hardware.sim_dynamics): same start and
same settled state as the static plant, inertia between them (overshoot, ringing at the locked first mode),
the pressure supply's time constant, tracker latency over the dynamic history, options checked up front."""

import numpy as np
import pytest

from ancf import Model, presets
from ancf.errors import InputError
from controller import LACC
from hardware import PlantOptions, SimulatedRig

P = 30e3


@pytest.fixture(scope="module")
def model():
    return Model(presets.paper())


@pytest.fixture(scope="module")
def ref(model):
    return model.fk((2.0, 1.0, 0.5), P)


def step_load(t):
    return np.array([0.0, 0.0, -0.3 if t >= 0.1 else 0.0])


def test_a_load_step_rings_and_settles_on_the_static_plant(model, ref):
    static = SimulatedRig(model, P, load=step_load)
    dyn = SimulatedRig(model, P, load=step_load, dynamics=True, options=PlantOptions(damping=0.05))
    for rig in (static, dyn):
        rig.command(ref.tendon_lengths)
    assert np.linalg.norm(dyn.true_tip() - static.true_tip()) < 1e-5          # same start (µm: stiff tendons)
    z_dyn, z_static, t = [], [], []
    for k in range(300):
        for rig in (static, dyn):
            rig.advance(0.005)
        t.append(dyn.time)
        z_dyn.append(dyn.true_tip()[2])
        z_static.append(static.true_tip()[2])
    z_dyn, z_static, t = map(np.array, (z_dyn, z_static, t))
    drop = z_static[0] - z_static[-1]
    assert drop > 1e-3                                                     # the static plant jumps at once
    assert z_dyn[0] == pytest.approx(z_static[0], abs=1e-5)
    assert z_static[-1] - z_dyn.min() > 0.3 * drop                         # inertia: the dynamic one overshoots
    # it rings at the locked first mode of the loaded state
    after = t > 0.1
    d = z_dyn[after] - z_static[-1]
    i = np.where(np.sign(d[:-1]) != np.sign(d[1:]))[0]
    f_ring = (len(i) - 1) / (2 * (t[after][i[-1]] - t[after][i[0]]))
    eq_loaded = model.fk_locked(ref.tendon_lengths, P, (0, 0, -0.3))
    f1 = model.modes(eq_loaded, 1).frequencies_hz[0]
    assert f_ring == pytest.approx(f1, rel=0.05)
    dyn.advance(3.0)                                                       # damped out: the static state
    static.advance(3.0)
    assert np.linalg.norm(dyn.true_tip() - static.true_tip()) < 2e-5
    assert np.allclose(dyn.equilibrium().tensions, static.equilibrium().tensions, atol=0.02)


def test_the_pressure_supply_lags_by_its_time_constant(model, ref):
    rig = SimulatedRig(model, P, dynamics=True, options=PlantOptions(pressure_tau=0.1, damping=0.2))
    rig.command(ref.tendon_lengths)
    rig.advance(0.01)
    rig.pressure_supply.set(60e3)
    rig.advance(0.1)
    assert rig.pressure_supply.read() == pytest.approx(P + (60e3 - P) * (1 - np.exp(-1.0)), rel=2e-3)


def test_tracker_latency_reads_the_dynamic_past(model, ref):
    rig = SimulatedRig(model, P, load=step_load, dynamics=True, options=PlantOptions(tracker_latency=0.03))
    rig.command(ref.tendon_lengths)
    rig.advance(0.2)
    past = rig._plant.equilibrium(rig.time - 0.03).tip
    assert np.allclose(rig.measure(), past, atol=1e-12)
    assert np.linalg.norm(past - rig.true_tip()) > 1e-5                    # the tip moved in those 30 ms
    with pytest.raises(InputError, match="back in time"):
        rig.time = 0.0


def test_lacc_settles_on_the_dynamic_plant_when_it_waits_for_the_ringing(model, ref):
    """Quasi-static LACC on a plant with inertia: measuring 0.5 s after each move (the ringing of the locked
    first mode has decayed by e^{-ζωt} ≈ 1e-4 at ζ = 0.5), it reaches the target under a hidden tip load as on
    the static plant; measuring right after the motors stop, it corrects on the transient and ends farther."""
    from controller.loop import run_timed
    errs = {}
    for settle, duration in ((0.5, 2.5), (0.0, 1.5)):
        rig = SimulatedRig(model, P, load=(0, 0, -0.2), dynamics=True, options=PlantOptions(damping=0.5))
        r = run_timed(LACC(model, P), rig, ref.tip, duration=duration, compute_time=0.01, settle_time=settle,
                      idle_period=0.1, sample_dt=0.05)
        errs[settle] = float(np.linalg.norm(r.error[r.t > 1.0], axis=1).max())
        assert r.corrections >= 1
    assert errs[0.5] < 0.05e-3                    # measured: 0.014 mm after one correction
    assert errs[0.0] > 20 * errs[0.5]             # measured: 3–4 mm, ~90 corrections on the transient
    static = SimulatedRig(model, P, load=(0, 0, -0.2))
    rs = run_timed(LACC(model, P), static, ref.tip, duration=2.5, compute_time=0.01, settle_time=0.5,
                   idle_period=0.1, sample_dt=0.05)
    assert float(np.linalg.norm(rs.error[-1])) < 0.25e-3


@pytest.mark.parametrize("kw, text", [
    (dict(dynamics=True, tendon_friction=0.1), "friction"),
    (dict(damping=1.5), "damping"),
    (dict(pressure_tau=-1.0), "pressure_tau"),
    (dict(dynamics_step=0.0), "dynamics_step"),
    (dict(dynamics="yes"), "dynamics"),
])
def test_bad_dynamic_options_are_refused(kw, text):
    with pytest.raises(InputError, match=text):
        PlantOptions(**kw)


def test_the_rig_loop_converges_on_the_dynamic_plant_only_with_shaped_moves(model, ref):
    """run_on_rig measures as soon as the motors stop: on the dynamic plant each unshaped correction starts
    a ringing that the next one corrects (not converged, ~10 mm off after 20); ZV-shaped moves at the
    model's first locked mode leave no ringing and LACC converges at once."""
    from controller import LACC, RunOptions, run_on_rig, zv_shaper
    start = model.ik(ref.tip, P)
    f1 = model.modes(model.fk_locked(start.tendon_lengths, P), 1).frequencies_hz[0]
    out = {}
    for name, shaper in (("plain", None), ("shaped", zv_shaper(f1, 0.1))):
        rig = SimulatedRig(model, P, load=(0, 0, -0.2), dynamics=True, options=PlantOptions(damping=0.1))
        out[name] = run_on_rig(LACC(model, P), rig, ref.tip,
                               RunOptions(max_iterations=20, sim_compute_time=0.002, shaper=shaper))
    assert out["plain"].status == "not converged" and out["plain"].final_error > 2e-3
    assert out["shaped"].status == "converged" and out["shaped"].iterations <= 3


def test_control_command_dynamic_options(tmp_path, monkeypatch, capsys):
    """The run as a subprocess (the console command); the refusals in-process through the same entry point
    (``validation.commands.main.main``: the one-line error contract, exit status 2), without an interpreter each."""
    import subprocess
    import sys

    from validation.commands.main import main
    argv = ["control", "--target-mm", "176,-12,3", "--pressure-kpa", "30", "--rig", "sim", "--fast",
            "--max-iterations", "5"]
    ok = subprocess.run([sys.executable, "-m", "validation.commands.main", *argv, "--dynamics",
                         "--shaping-damping-ratio", "0.05"], cwd=tmp_path, capture_output=True, text=True, timeout=300,
                        check=False)
    assert ok.returncode == 0, ok.stderr
    monkeypatch.chdir(tmp_path)
    for args, text in ((("--plant-damping-ratio", "0.1"), "needs --dynamics"),
                       (("--dynamics", "--mismatch"), "friction"),
                       (("--shaping-damping-ratio", "1.5"), "shaping-damping-ratio")):
        capsys.readouterr()
        with pytest.raises(SystemExit) as exit_:
            main([*argv, *args])
        err = capsys.readouterr().err
        assert exit_.value.code == 2 and err.count("error:") == 1 and text in err, err


def test_motors_lag_behind_their_position_loop(model, ref):
    """motor_bandwidth f: after the rate-limited profile ends, the encoder's distance to the target decays
    like e^{−2πf t} (the first-order position loop, solved exactly on each linear piece)."""
    ref2 = model.fk((2.5, 1.0, 0.5), P)
    rig = SimulatedRig(model, P, dynamics=True, options=PlantOptions(damping=0.2, motor_bandwidth=5.0,
                                                                       length_rate=0.05))
    rig.command(ref.tendon_lengths)
    rig.advance(0.01)
    move = rig.command(ref2.tendon_lengths)
    rig.advance(move + 0.001)
    errs = []
    for _ in range(6):
        rig.advance(0.01)
        errs.append(rig.drives[0].position() - ref2.tendon_lengths[0])
    ratios = np.array(errs[1:]) / np.array(errs[:-1])
    assert np.allclose(ratios, np.exp(-2 * np.pi * 5.0 * 0.01), rtol=1e-9)
    assert abs(errs[0]) > 0.3e-3                                            # a visible lag
    with pytest.raises(InputError, match="dynamics=True"):
        SimulatedRig(model, P, options=PlantOptions(motor_bandwidth=5.0))
    with pytest.raises(InputError, match="motor_force_max"):
        PlantOptions(motor_force_max=-1.0)


def test_a_weak_motor_gives_way_on_the_dynamic_plant(model, ref):
    """motor_force_max: a tip load needing more tension than the motor can hold pulls its tendon out — the
    rig's force sensor reads the limit, and the tip sags past where stiff motors would hold it."""
    F = (0.0, 0.0, -1.0)
    strong = SimulatedRig(model, P, load=F, dynamics=True, options=PlantOptions(damping=0.3))
    weak = SimulatedRig(model, P, load=F, dynamics=True, options=PlantOptions(damping=0.3, motor_force_max=2.2))
    for rig in (strong, weak):
        rig.command(ref.tendon_lengths)
        rig.advance(0.01)
    assert strong.equilibrium().tensions[0] > 2.5
    # the weak rig started at the limit-free locked state; let it give way and settle
    weak.advance(2.0)
    assert weak.equilibrium().tensions[0] == pytest.approx(2.2, abs=1e-9)
    assert weak.true_tip()[2] < strong.true_tip()[2] - 1e-4


def test_ctrl_c_inside_the_plant_integration_stops_the_rig_and_keeps_its_rows(model, ref, monkeypatch):
    """A Ctrl-C while the dynamic plant integrates ends Model.simulate between steps with the rows done
    (interrupted=True); the rig must not carry on as if the plant had reached the end of the interval: it raises
    KeyboardInterrupt, with the rows done in its history."""
    import dataclasses
    dyn = SimulatedRig(model, P, load=step_load, dynamics=True, options=PlantOptions(damping=0.05))
    dyn.command(ref.tendon_lengths)
    dyn.advance(0.005)                                       # the plant has started and integrated once
    plant = dyn._plant.dyn
    real = plant.model.simulate

    def interrupted_halfway(t_end, dt, **kw):
        sim = real(t_end / 2, dt, **kw)                    # half the interval done, then "Ctrl-C"
        return dataclasses.replace(sim, interrupted=True)

    monkeypatch.setattr(plant.model, "simulate", interrupted_halfway)
    t_before = plant.state.t
    with pytest.raises(KeyboardInterrupt):
        dyn.advance(0.02)
    assert t_before < plant.state.t < t_before + 0.02        # the rows done are kept, the end was not reached
