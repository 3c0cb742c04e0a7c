"""Identification from the FEM against closed forms, and from noisy FEM "measurements".

A straight circular tube of a compressible neo-Hookean solid (ν = 0.3) under small loads is a linear-elastic
thick-walled tube, for which the rod values are known exactly:

* EA = E π (R_o² − R_i²),  EI = E π (R_o⁴ − R_i⁴)/4  ⇒  D_a = √(8 EI/EA) = √(2 (R_o² + R_i²));
* closed ends under internal pressure p (Lamé): σ_r + σ_θ = 2 p R_i²/(R_o² − R_i²) is constant through the
  wall and σ_z = p R_i²/(R_o² − R_i²), so ε_z = (σ_z − ν(σ_r + σ_θ))/E = p R_i² (1 − 2ν)/(E (R_o² − R_i²)).
  The reduced model's pressure force p A_eff must give the same strain: A_eff = π R_i² (1 − 2ν), i.e.
  D_eff = 2 R_i √(1 − 2ν) — it vanishes for an incompressible wall (ν → 0.5).

"Small" matters: the hoop strain p R/(E t) of this soft tube is 7 % at 40 kPa, and the follower pressure on the
widened cavity then lengthens it 25 % more than the linear limit, so the design stays below 5 kPa (hoop
strain < 1 %).  The rigid end caps suppress the Poisson contraction near the ends: by shell theory each end
adds ν (w/R)/β of elongation (β⁴ = 3(1 − ν²)/(R t)²), here ≈ +10 % on A_eff, +5 % on D_eff — hence 10 % on
D_eff and 3 % on EA and D_a.
"""

import math

import numpy as np
import pytest

from ancf import ActuatorParams
from hardware.static_states import StaticStates, write_static_states
from validation.identification import identify
from validation.reference.experiments import Design, LoadCase

pytest.importorskip("skfem")

from fem_reference import BellowsGeometry, Material  # noqa: E402

NU = 0.3
MU = 0.8e6
E = 2 * MU * (1 + NU)
KAPPA = 2 * MU * (1 + NU) / (3 * (1 - 2 * NU))
R_MID, T_WALL = 0.015, 0.004
R_I, R_O = R_MID - T_WALL / 2, R_MID + T_WALL / 2
D_T = 0.02            # tendon distance [m]


def _design() -> Design:
    z = (0.0, 0.0, 0.0)
    train = [LoadCase((1.0, 1.0, 1.0), 0.0, z, False, "axial"),
             LoadCase((0.0, 0.0, 0.0), 2e3, z, False, "pressure"),
             LoadCase((0.0, 0.0, 0.0), 4e3, z, False, "pressure"),
             LoadCase((1.0, 1.0, 1.0), 4e3, z, False, "combined"),
             LoadCase((1.0, 0.0, 0.0), 0.0, z, False, "bending"),
             LoadCase((0.0, 0.8, 0.0), 2e3, z, False, "bending")]
    held = [LoadCase((0.6, 0.0, 0.3), 3e3, z, False, "mixed", "heldout"),
            LoadCase((0.5, 0.5, 0.0), 1e3, z, False, "mixed", "heldout")]
    return Design(tuple(train + held), "straight tube, small loads")


@pytest.fixture(scope="module")
def tube_identification(tmp_path_factory):
    geo = BellowsGeometry.straight_tube(0.16, R_MID, T_WALL, n_segments=8, tendon_radius=D_T)
    mat = Material.neo_hookean(mu=MU, kappa=KAPPA)
    cache = tmp_path_factory.mktemp("fem_cache")
    res = identify.from_fem(geo, mat, "coarse", workers=2, cache_dir=cache, design=_design(),
                            forms=("constant",), progress=False, compliance=False)
    return res, cache, geo, mat


def test_straight_tube_matches_the_closed_forms(tube_identification):
    res, *_ = tube_identification
    v = res.values
    assert res.form == "constant" and not res.not_identifiable
    assert v["EA"] == pytest.approx(E * math.pi * (R_O ** 2 - R_I ** 2), rel=0.03)
    assert v["D_a"] == pytest.approx(math.sqrt(2 * (R_O ** 2 + R_I ** 2)), rel=0.03)
    assert v["D_eff"] == pytest.approx(2 * R_I * math.sqrt(1 - 2 * NU), rel=0.10)
    # the closed-form values sit inside (or within 3 % of) the reported 95 % intervals
    lo, hi = res.ci95["EA"]
    assert lo < hi and hi - lo < 0.05 * v["EA"]


def test_cached_sweep_is_reused(tube_identification):
    """A re-run with the same cache computes nothing: every FEM case comes from the cache."""
    from validation.reference.fem_sweep import FemSpec, run_cases
    res, cache, geo, mat = tube_identification
    recs = run_cases(FemSpec(geo, mat, "coarse"), _design().cases, cache_dir=cache, workers=1, progress=False)
    # solve times are stored with each record: a recomputation would not reproduce them
    assert [r.seconds for r in recs] == [r.seconds for r in res.records]
    assert [r.tip_position.tolist() for r in recs] == [r.tip_position.tolist() for r in res.records]


def test_noisy_fem_measurements_identify_the_same_rod(tube_identification, tmp_path):
    """The FEM states written as 'measurements' (0.02 mm noise, stated: the pressure elongation of
    these small states is only ≈ 0.2 mm) through the file format give back the
    FEM identification within its confidence intervals."""
    res, *_ = tube_identification
    recs = res.records
    rng = np.random.default_rng(7)
    sigma = 2e-5
    tip = np.array([r.tip_position for r in recs]) + rng.normal(0, sigma, (len(recs), 3))
    ms = np.array([0.04, 0.08, 0.12])
    markers = np.array([r.centreline_at(ms) for r in recs]) + rng.normal(0, sigma, (len(recs), 3, 3))
    states = StaticStates(tensions=np.array([r.case.tensions for r in recs]),
                          pressure=np.array([r.case.pressure for r in recs]), tip_position=tip,
                          tip_force=np.array([r.case.tip_force for r in recs]),
                          tip_position_std=np.full_like(tip, sigma), markers=markers, marker_arclength=ms,
                          markers_std=np.full_like(markers, sigma),
                          label=[("heldout " if r.case.role == "heldout" else "") + r.case.label for r in recs])
    path = write_static_states(tmp_path / "tube_states.h5", states)
    base: ActuatorParams = res.params
    meas = identify.from_measurements(path, base, forms=("constant",), gravity=False)
    for key in ("EA", "EI", "D_eff"):
        lo, hi = meas.ci95[key]
        assert lo <= res.values[key] <= hi, (key, res.values[key], (lo, hi))
        assert (hi - lo) < 0.2 * res.values[key]


def test_too_few_solved_training_cases_is_a_typed_error(tube_identification, monkeypatch):
    """When the FEM fails on most training cases, the identification stops with one typed error naming a
    failed case (it used to build a ConvergenceError without its required fields: a TypeError)."""
    from ancf.errors import ConfigError
    from validation.reference import fem_sweep
    _, cache, geo, mat = tube_identification

    def failing(spec, cases, **kw):
        s = np.linspace(0.0, geo.length, 5)
        return [fem_sweep.FemRecord(c, np.full(3, np.nan), np.full((3, 3), np.nan), np.full((5, 3), np.nan), s,
                                    np.full(3, np.nan), np.full(3, np.nan), error="ConvergenceError: stalled")
                for c in cases]

    monkeypatch.setattr(fem_sweep, "run_cases", failing)
    with pytest.raises(ConfigError, match=r"failed on 6 of 6 training cases .*stalled"):
        identify.from_fem(geo, mat, "coarse", workers=1, cache_dir=cache, design=_design(), forms=("constant",),
                          progress=False, compliance=False)
