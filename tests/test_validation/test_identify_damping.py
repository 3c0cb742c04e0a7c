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
