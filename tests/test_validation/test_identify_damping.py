"""Damping from a free decay (validation.identification.damping, `bellows identify-damping`): the fit recovers the
model's modal damping ratio and frequency from simulated decays, its 95 % intervals cover the truth about 95 %
of the time on noisy records, it reads `bellows simulate` CSVs and run logs, and refuses what is not a
decay."""

import json
import subprocess
import sys

import numpy as np
import pytest

from ancf import Model, presets
from ancf.dynamics import rayleigh_about
from ancf.errors import InputError
from validation.identification.damping import fit_free_decay, read_decay

P = 30e3


@pytest.fixture(scope="module")
def model():
    return Model(presets.paper())


@pytest.fixture(scope="module")
def decay(model):
    """A 0.5 mm release (T₁ 2.02 → 2 N) with mass-proportional damping α = 1/s."""
    eq = model.fk((2.0, 0, 0), P)
    sim = model.simulate(3.0, 2e-3, q0=model.fk((2.02, 0, 0), P).q, tensions=(2, 0, 0), pressure=P,
                         damping={"alpha": 1.0}, rho_inf=1.0)
    return eq, sim


def test_the_fit_recovers_the_modal_ratio_and_frequency(model, decay):
    eq, sim = decay
    md = model.modes(eq, 1, damping={"alpha": 1.0})
    fit = fit_free_decay(sim.t, sim.tip, t_start=0.2)
    assert fit.damping_ratio == pytest.approx(md.damping_ratios[0], rel=2e-3)
    # the trapezoidal rule at 2 ms lengthens the period by (ωh)²/12
    w = 2 * np.pi * md.frequencies_hz[0]
    assert fit.frequency_hz == pytest.approx(md.frequencies_hz[0] / (1 + (w * 2e-3) ** 2 / 12), rel=1e-4)
    assert fit.alpha_per_s == pytest.approx(1.0, rel=3e-3)
    assert abs(fit.direction[2]) > 0.95                     # the in-plane bending mode moves the tip vertically


def test_the_intervals_cover_the_truth(decay):
    """40 records with 0.02 mm tracker noise: the 95 % interval of ζ holds the noise-free value in 85–100 %."""
    _, sim = decay
    truth = fit_free_decay(sim.t, sim.tip, t_start=0.2).damping_ratio
    rng = np.random.default_rng(1)
    hits = 0
    for _ in range(40):
        f = fit_free_decay(sim.t, sim.tip + rng.normal(0, 2e-5, sim.tip.shape), t_start=0.2)
        hits += f.damping_ratio_ci[0] <= truth <= f.damping_ratio_ci[1]
    assert 34 <= hits <= 40


def test_a_ratio_about_the_settled_equilibrium_is_recovered(model):
    eq = model.fk((2.0, 0, 0), P)
    sim = model.simulate(3.0, 2e-3, q0=model.fk((2.02, 0, 0), P).q, tensions=(2, 0, 0), pressure=P,
                         damping=rayleigh_about(model, eq, 0.03))
    assert fit_free_decay(sim.t, sim.tip, t_start=0.2).damping_ratio == pytest.approx(0.03, rel=1e-3)


def test_not_a_decay_is_refused():
    t = np.linspace(0, 1, 200)
    with pytest.raises(InputError, match="half-periods"):
        fit_free_decay(t, np.column_stack([t, 0 * t, 0 * t]))
    with pytest.raises(InputError, match="at least 20"):
        fit_free_decay(t[:10], np.zeros((10, 3)))
    with pytest.raises(InputError, match="tip"):
        fit_free_decay(t, np.zeros((200, 2)))


def test_a_run_log_is_read(tmp_path, decay):
    from hardware.runlog import RunLog
    _, sim = decay
    with RunLog(tmp_path / "decay.h5", n_tendons=3) as log:
        for i in range(len(sim.t)):
            log.sample(t=sim.t[i], tip=sim.tip[i], tension=sim.tensions[i], pressure=sim.pressure[i])
    t, tip, info = read_decay(tmp_path / "decay.h5")
    assert np.allclose(t, sim.t) and np.allclose(tip, sim.tip)
    assert info["pressure"] == pytest.approx(P)
    (tmp_path / "decay.txt").write_text("x")
    with pytest.raises(InputError, match="expected a .csv"):
        read_decay(tmp_path / "decay.txt")


def run(*args, cwd):
    return subprocess.run([sys.executable, "-m", "validation.commands.main", *args], cwd=cwd, capture_output=True,
                          text=True, timeout=300)


def test_the_command_reads_a_simulate_csv(tmp_path, model):
    r = run("simulate", "--tensions-n", "2,0,0", "--start-tensions-n", "2.02,0,0", "--pressure-kpa", "30",
            "--t-end-s", "2", "--dt-ms", "2", "--damping-ratio", "0.03", "--out", "s", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    r = run("identify-damping", "s/simulation.csv", "--start-s", "0.2", "--json", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out["damping_ratio"] == pytest.approx(0.03, rel=2e-3)
    assert out["frequency_hz"] == pytest.approx(out["model_frequency_hz"], rel=1e-3)
    assert out["model_state"]["tendons"] == "held"
    bad = run("identify-damping", "s/simulation.json", cwd=tmp_path)
    assert bad.returncode == 2 and bad.stderr.count("error:") == 1


# ----------------------------------------------------------------------- records of known truth
T_SYN = np.linspace(0.0, 3.0, 1501)                   # 2 ms samples over 3 s


def synthetic(zeta, f_hz, amplitude=1e-3, noise=0.0, seed=0):
    """A free decay of known ζ and f_n (natural) along (0.2, 0, 1) about a tip at (0.16, 0, 0.01) m, with white
    tracker noise of ``noise`` [m] RMS per axis."""
    w = 2 * np.pi * f_hz
    y = amplitude * np.exp(-zeta * w * T_SYN) * np.cos(w * np.sqrt(1 - zeta ** 2) * T_SYN + 0.3)
    tip = np.array([0.16, 0.0, 0.01]) + np.column_stack([0.2 * y, 0 * y, y])
    return tip + np.random.default_rng(seed).normal(0.0, noise, tip.shape)


def test_a_clean_synthetic_decay_is_recovered_within_its_interval():
    fit = fit_free_decay(T_SYN, synthetic(0.03, 5.0))
    assert fit.damping_ratio_ci[0] <= 0.03 <= fit.damping_ratio_ci[1]
    assert fit.frequency_ci[0] <= 5.0 <= fit.frequency_ci[1]
    assert fit.damping_ratio == pytest.approx(0.03, rel=1e-9) and fit.frequency_hz == pytest.approx(5.0, rel=1e-9)
    assert fit.alpha_per_s == pytest.approx(2 * 0.03 * 2 * np.pi * 5.0, rel=1e-9)
    noisy = fit_free_decay(T_SYN, synthetic(0.03, 5.0, noise=2e-5))
    assert noisy.damping_ratio == pytest.approx(0.03, rel=0.02) and noisy.frequency_hz == pytest.approx(5.0, rel=1e-3)
    assert 30 < noisy.amplitude_to_noise < 70 and noisy.cycles_above_noise > 5    # 1 mm over ≈ 0.02 mm: ≈ 50×


def test_a_growing_oscillation_is_not_a_free_decay():
    from validation.identification.damping import DecayNotDeterminedError
    for noise in (0.0, 2e-5):
        with pytest.raises(DecayNotDeterminedError, match="not a free decay: the oscillation grows") as info:
            fit_free_decay(T_SYN, synthetic(-0.02, 5.0, noise=noise))
        assert info.value.reason == "growing" and info.value.damping_ratio_ci[1] < 0


@pytest.mark.parametrize("amplitude", [0.0, 2e-5])              # pure noise; a decay as large as the noise
def test_noise_is_no_oscillation_above_the_noise(amplitude):
    from validation.identification.damping import MIN_AMPLITUDE_TO_NOISE, DecayNotDeterminedError
    for seed in range(5):
        with pytest.raises(DecayNotDeterminedError, match="no oscillation above the noise") as info:
            fit_free_decay(T_SYN, synthetic(0.03, 5.0, amplitude=amplitude, noise=2e-5, seed=seed))
        assert info.value.reason == "noise" and info.value.amplitude_to_noise < MIN_AMPLITUDE_TO_NOISE
        assert isinstance(info.value, InputError)


def test_an_oscillation_without_measurable_decay_does_not_determine_zeta():
    from validation.identification.damping import DecayNotDeterminedError
    for noise in (0.0, 2e-5):                     # an undamped sine: ζ = 0 is inside the interval
        with pytest.raises(DecayNotDeterminedError, match="contains 0") as info:
            fit_free_decay(T_SYN, synthetic(0.0, 5.0, noise=noise))
        assert info.value.reason == "undetermined"


def test_too_few_cycles_above_the_noise_are_refused():
    """ζ = 0.3: the envelope of a 1 mm release falls below 5 × 0.05 mm within one period (0.7)."""
    from validation.identification.damping import DecayNotDeterminedError
    with pytest.raises(DecayNotDeterminedError, match="periods") as info:
        fit_free_decay(T_SYN, synthetic(0.3, 5.0, noise=5e-5))
    assert info.value.reason == "noise" and info.value.cycles_above_noise < 3


def test_the_intervals_of_synthetic_decays_cover_the_truth():
    """60 records of ζ = 0.03, f_n = 5 Hz with 0.05 mm noise: the nominal 95 % intervals of ζ and of f_n each
    hold the truth in at least 90 % of them (and none is refused)."""
    hits_z = hits_f = 0
    for seed in range(60):
        fit = fit_free_decay(T_SYN, synthetic(0.03, 5.0, noise=5e-5, seed=seed))
        hits_z += fit.damping_ratio_ci[0] <= 0.03 <= fit.damping_ratio_ci[1]
        hits_f += fit.frequency_ci[0] <= 5.0 <= fit.frequency_ci[1]
    assert hits_z >= 54 and hits_f >= 54


def _write_decay_csv(path, tip):
    rows = ["t_s,tip_x_mm,tip_y_mm,tip_z_mm,T1_N,T2_N,T3_N,pressure_kPa"]
    rows += [f"{t:.17g},{x * 1e3:.17g},{y * 1e3:.17g},{z * 1e3:.17g},2,0,0,30" for t, (x, y, z) in zip(T_SYN, tip)]
    path.write_text("\n".join(rows) + "\n")


@pytest.mark.parametrize("zeta, amplitude, match", [(-0.02, 1e-3, "not a free decay"),
                                                    (0.03, 0.0, "no oscillation above the noise")])
def test_the_command_refuses_a_record_without_a_decay(tmp_path, capsys, zeta, amplitude, match):
    from ancf import clitools
    from validation.commands.main import app
    _write_decay_csv(tmp_path / "r.csv", synthetic(zeta, 5.0, amplitude=amplitude, noise=2e-5))
    with pytest.raises(SystemExit) as info:
        clitools.run(app, ["identify-damping", str(tmp_path / "r.csv")])
    err = capsys.readouterr().err.strip()
    assert info.value.code == 2 and err.startswith("error:") and err.count("\n") == 0 and match in err
