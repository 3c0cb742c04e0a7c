"""μ identified from a pull-through test and from a tension cycle's tip data (validation.identification.friction):
the pull-through model against the capstan closed form, exact recovery without noise, a coverage study of the
95 % intervals on simulated data with known truth, and the tip-data fit."""

import math
import pathlib
import re

import numpy as np
import pytest

from ancf import Model, presets
from ancf.errors import InputError
from ancf.friction import pull_through
from validation.identification import friction as idf

P, MU = 20e3, 0.2


@pytest.fixture(scope="module")
def held():
    """The paper actuator bent by tendon 1 at 20 kPa: the held shape and tendon 1's total wrap W."""
    m = Model(presets.paper().replace(tendon_friction=MU))
    q = m.fk([3.0, 0.0, 0.0], P).q
    return m, q, idf.total_wrap(m, q, 0)


def test_the_pull_through_model_is_the_capstan_closed_form(held):
    m, q, W = held
    Tm = idf.protocol(4.0, 0.2, 20)
    anchor, codes = pull_through(m, q, 0, Tm)
    pull, rel = slice(0, 20), slice(20, None)
    assert np.all(codes[pull] == 1) and np.allclose(anchor[pull], Tm[pull] * math.exp(-MU * W), rtol=1e-13)
    peak = 4.0 * math.exp(-MU * W)                      # releasing: held at the peak until every guide slips out
    assert np.allclose(anchor[rel], np.minimum(peak, Tm[rel] * math.exp(MU * W)), rtol=1e-13)
    slipping = Tm[rel] < 4.0 * math.exp(-2 * MU * W)
    assert np.all(codes[rel][slipping] == -1) and np.all(codes[rel][~slipping][:, -1] == 0)
    pts = m.tendon_paths(q, per_element=1)[0]          # W independently: the turning of the path's node chords
    chords = np.vstack([[1.0, 0.0, 0.0], np.diff(pts, axis=0)])
    c = chords / np.linalg.norm(chords, axis=1)[:, None]
    assert W == pytest.approx(float(np.sum(np.arccos(np.clip(np.sum(c[1:] * c[:-1], axis=1), -1, 1)))), rel=1e-9)


def test_without_noise_the_fit_is_exact(held):
    m, q, _W = held
    motor, anchor, W = idf.simulate_pull_through(m, q, 0, idf.protocol(4.0, 0.2, 20))
    fit = idf.fit_pull_through(motor, anchor, W)
    assert fit.mu == pytest.approx(MU, rel=1e-12) and fit.basis == "residuals"
    assert fit.points < motor.size                       # the stuck start of the release branch left out


def test_the_95_percent_intervals_hold_the_truth_in_95_percent_of_the_seeds(held):
    """Coverage study: 100 seeds, noise on both tensions; the count of intervals holding μ is binomial(100,
    0.95) for a correct interval: 89 … 100 holds it with probability > 0.99."""
    m, q, _W = held
    Tm = idf.protocol(4.0, 0.2, 20)
    anchor, _ = pull_through(m, q, 0, Tm)
    W = idf.total_wrap(m, q, 0)
    hits = {"stated noise": 0, "residuals": 0}
    est = []
    for seed in range(100):
        rng = np.random.default_rng(seed)
        a, b = Tm + rng.normal(0, 0.01, Tm.size), anchor + rng.normal(0, 0.02, Tm.size)
        f = idf.fit_pull_through(a, b, W, motor_std=0.01, anchor_std=0.02)
        g = idf.fit_pull_through(a, b, W)
        hits[f.basis] += f.contains(MU)
        hits[g.basis] += g.contains(MU)
        est.append(f.mu)
    assert 89 <= hits["stated noise"] <= 100 and 89 <= hits["residuals"] <= 100, hits
    doc = (pathlib.Path(__file__).parents[1] / "docs" / "friction.md").read_text(encoding="utf-8")
    row = re.search(r"^\| ([0-9.]+) \| (\d+) of 100 \| (\d+) of 100 \|$", doc, re.MULTILINE)
    assert row and row.group(1) == f"{W:.3f}"                                       # the documented study
    assert (int(row.group(2)), int(row.group(3))) == (hits["stated noise"], hits["residuals"])
    assert abs(np.mean(est) - MU) < 3 * np.std(est) / 10                            # unbiased


def test_a_wrong_wrap_moves_the_estimate_by_its_relative_error(held):
    m, q, _W = held
    motor, anchor, W = idf.simulate_pull_through(m, q, 0, idf.protocol(4.0, 0.2, 20))
    assert idf.fit_pull_through(motor, anchor, 1.1 * W).mu == pytest.approx(MU / 1.1, rel=1e-9)


def test_bad_pull_through_inputs_are_refused(held):
    m, q, W = held
    Tm = idf.protocol(4.0, 0.2, 10)
    a, _ = pull_through(m, q, 0, Tm)
    with pytest.raises(InputError, match="one peak"):
        idf.fit_pull_through(np.concatenate([Tm, Tm]), np.concatenate([a, a]), W)
    with pytest.raises(InputError, match="both"):
        idf.fit_pull_through(Tm, a, W, motor_std=0.01)
    with pytest.raises(InputError, match="anchor_tensions"):
        idf.fit_pull_through(Tm, a[:-1], W)
    with pytest.raises(InputError, match="tendon"):
        pull_through(m, q, 3, Tm)
    with pytest.raises(InputError, match="protocol"):
        idf.protocol(1.0, 2.0, 10)


def test_mu_from_the_tip_data_of_a_tension_cycle():
    truth = Model(presets.paper().replace(tendon_friction=0.1))
    tips = truth.tension_cycle([4.0, 0.0, 0.0], P, steps=5).tip
    rng = np.random.default_rng(4)
    noisy = tips + rng.normal(0.0, 5e-5, tips.shape)
    fit = idf.fit_tension_cycle(Model(presets.paper()), [4.0, 0.0, 0.0], P, noisy, 5, mu0=0.25, tip_std=5e-5)
    assert fit.contains(0.1) and fit.std < 0.005 and fit.basis == "stated noise"
    with pytest.raises(InputError, match="tips"):
        idf.fit_tension_cycle(Model(presets.paper()), [4.0, 0.0, 0.0], P, noisy[:-1], 5)
