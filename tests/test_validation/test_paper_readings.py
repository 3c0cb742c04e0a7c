"""Readings of the paper's stiffness law (presets), the law's limits and collapsed states."""

import numpy as np
import pytest

from ancf import Model, StiffnessLaw, presets
from ancf.errors import ConfigError
from validation.paper import states
from validation.paper.workspace_volume import sampling_error, workspace

LAM = np.linspace(0.5, 1.5, 11)


def test_length_scaled_readings_scale_both_laws():
    base = presets.paper_unscaled()
    for name, f in (("paper_scaled", 0.16), ("paper_scaled_020", 0.20)):
        p = presets.get(name)
        assert p.name == name
        assert np.allclose(p.stiffness.EA(LAM), f * base.stiffness.EA(LAM), rtol=1e-13)
        assert np.allclose(p.stiffness.EI(LAM), f * base.stiffness.EI(LAM), rtol=1e-13)
        assert (p.length, p.D_eff, p.tendons) == (base.length, base.D_eff, base.tendons)
    # the values the identification calibrates to
    s = presets.paper_scaled().stiffness
    assert s.EA(1.0) == pytest.approx(0.16 * (1336 - 568.8))
    assert s.EI(1.0) == pytest.approx(0.02959 ** 2 * 0.16 * (1336 - 568.8) / 8)
    d = presets.paper_diameter()
    assert np.allclose(d.tendon_distances, base.tendon_distances / 2)
    with pytest.raises(ConfigError):
        presets.length_scaled(-1.0)


def test_law_limits_closed_form():
    p = presets.paper_scaled()
    lim = states.law_limits(p)
    assert lim["zero_stretch"] == pytest.approx(568.8 / 1336)            # λ0 = −b/a, scale-free
    assert states.law_limits(presets.paper_unscaled())["zero_stretch"] == pytest.approx(lim["zero_stretch"])
    N = p.stiffness.axial_force
    lc, h = lim["critical_stretch"], 1e-6
    assert (N(lc + h) - N(lc - h)) / (2 * h) == pytest.approx(0.0, abs=1e-6)   # N'(λ_c) = 0
    assert lim["max_compression_N"] == pytest.approx(-N(lc))
    assert -N(np.linspace(lim["zero_stretch"], 1, 501)).max() <= 1e-12         # no tension below λ = 1
    assert -N(np.linspace(lim["zero_stretch"], 1, 501)).min() >= -lim["max_compression_N"] - 1e-9
    # N_c scales with the length factor; a constant law has no zero
    assert states.law_limits(presets.paper_unscaled())["max_compression_N"] == pytest.approx(
        lim["max_compression_N"] / 0.16)
    const = p.replace(stiffness=StiffnessLaw.constant(EA=100.0, EI=0.01))
    assert states.law_limits(const)["zero_stretch"] == 0.0


def test_reading_facts_are_the_rod_stretches():
    for name in presets.READINGS:
        p = presets.get(name)
        f = states.reading_facts(p)
        assert p.stiffness.axial_force(f["stretch_at_max_pressure"]) == pytest.approx(120e3 * p.A_eff)
    assert states.reading_facts(presets.paper_unscaled())["stretch_under_compression"] == pytest.approx(0.979, abs=1e-3)
    assert np.isnan(states.reading_facts(presets.paper_scaled())["stretch_under_compression"])   # 15 N > N_c


def test_stretches_of_a_uniformly_stretched_rod():
    model = Model(presets.paper_scaled())
    for lam in (0.6, 0.95, 1.2):
        q = model.q_ref.reshape(-1, 6).copy()
        q[:, :3] *= lam
        q[:, 3:] *= lam
        assert np.allclose(states.stretches(model, q.ravel()), lam, rtol=1e-12)
        assert states.state_collapsed(model, q.ravel()) == (lam <= states.law_limits(model.params)["critical_stretch"])


def test_collapsed_samples_are_counted_not_dropped():
    """Scaled reading, TD box T ∈ [3.3, 5] N: where Σ T exceeds the law's largest compression N_c no
    equilibrium exists; those samples must be reported as collapsed (not solved, not silently dropped)."""
    p = presets.paper_scaled()
    nc = states.law_limits(p)["max_compression_N"]
    res = workspace(samples=24, seed=2, workers=1, progress=False, params=p, tension_range=(3.3, 5.0))
    td = res["modes"]["TD"]
    X = res["clouds"]["TD"]["inputs"]
    status = res["clouds"]["TD"]["status"]
    sum_t = X[:, :3].sum(axis=1)
    assert np.all(status[sum_t > nc + 0.3] == "collapsed")
    assert np.all(status[sum_t < nc - 1.0] == "ok")
    assert 0 < td["collapsed"] < 24
    assert td["collapsed"] + td["failures"] + td["solved"] == 24
    assert td["collapsed_indices"] == list(np.flatnonzero(status == "collapsed"))
    assert np.all(np.isnan(res["clouds"]["TD"]["tips"][status != "ok"]))
    assert res["collapsed"] == td["collapsed"] + res["modes"]["TPHD"]["collapsed"]
    assert res["modes"]["TPHD"]["collapsed"] < td["collapsed"]          # pressure offsets the compression
    model = Model(p)
    for i in np.flatnonzero(status == "ok")[:3]:
        eq = model.fk(X[i, :3], 0.0)
        assert states.stretches(model, eq.q).min() > states.law_limits(p)["critical_stretch"]


def test_sampling_error_of_a_known_ratio():
    rng = np.random.default_rng(0)
    a = rng.uniform(0, 1, (4000, 3))
    b = rng.uniform(0, 1, (4000, 3)) * np.array([2.0, 1.0, 1.0])          # exact volume ratio 2
    se = sampling_error(a, b)
    for inc in se["halves_increase_percent"]:
        assert inc == pytest.approx(100.0, abs=4.0)
    assert 0 <= se["half_difference_percent"] < 3.0
    b[1::2] *= 1.5                                                       # the odd half is 1.5³ larger
    assert sampling_error(a, b)["half_difference_percent"] > 100


def test_certain_collapse_needs_no_solve_and_bounds_are_consistent():
    p = presets.paper_scaled()
    nc, w = states.law_limits(p)["max_compression_N"], states.weight_bound(p)
    assert w == pytest.approx((0.3 * 0.16 + 0.01) * 9.81)
    assert states.certainly_collapsed(p, (5.0, 5.0, 5.0), 0.0)                    # 15 N > 11.6 + 0.6
    assert not states.certainly_collapsed(p, (5.0, 5.0, 5.0), 120e3)              # pressure carries it
    assert not states.certainly_collapsed(p, (nc / 3,) * 3, 0.0)
    assert states.near_limit(p, (nc / 3,) * 3, 0.0) and not states.near_limit(p, (1.0, 1.0, 1.0), 0.0)
    assert not states.certainly_collapsed(presets.paper_unscaled(), (5.0, 5.0, 5.0), 0.0)
    with pytest.raises(Exception):                                                # really no equilibrium
        Model(p).fk((4.5, 4.5, 4.5), 0.0)


def test_rejected_inputs_are_failures_not_collapses():
    """Tensions above the limit are rejected by the model (InputError) — counted as failed, even where
    their compression would also collapse the law."""
    res = workspace(samples=20, seed=4, workers=1, progress=False, params=presets.paper_scaled(),
                    tension_range=(4.0, 6.0))
    X, status = res["clouds"]["TD"]["inputs"], res["clouds"]["TD"]["status"]
    over = np.any(X[:, :3] > 5.0, axis=1)
    assert over.any() and np.all(status[over] == "failed")
    assert np.all(status[~over] == "collapsed")                       # Σ T ≥ 12 N > N_c
    assert any(name in res["modes"]["TD"]["first_errors"][0] for name in ("InputError", "LimitError"))  # LimitError is an InputError
