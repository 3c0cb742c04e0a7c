"""Informative load cases (validation.identification.design_select): greedy D-optimal choice, the training hull, load features,
and the informative design of the paper actuator — more information than the default design from fewer training
cases, bends across the whole pressure range, held-out states inside the hull and an extrapolation set outside."""

import itertools

import numpy as np
import pytest

from ancf import presets
from ancf.errors import InputError
from validation.identification.design_select import (d_optimal, informative_design, inside_hull, load_features, sensitivities,
                                      spread)
from validation.reference.experiments import LoadCase, default_design
from validation.identification.forms import get_form
from validation.identification.identify import initial_theta

RANGE = dict(tension_max=5.0, pressure_max=100e3, tendon_distance=0.0275, length=0.16)


def _logdet(J, idx):
    M = np.einsum("irn,irm->nm", J[idx], J[idx])
    return np.linalg.slogdet(M)[1]


def test_d_optimal_picks_the_strongest_candidate_of_each_direction():
    n = 3
    J = []
    for j in range(n):
        for a in (1.0, 3.0, 2.0):                      # three candidates per parameter direction
            v = np.zeros((1, n))
            v[0, j] = a
            J.append(v)
    J = np.array(J)
    chosen = d_optimal(J, n)
    assert sorted(chosen) == [1, 4, 7]                # the 3.0 of each direction
    with pytest.raises(InputError):
        d_optimal(J, 0)
    with pytest.raises(InputError):
        d_optimal(J, 2, start=[0, 0])


def test_greedy_reaches_the_submodular_guarantee_against_brute_force():
    rng = np.random.default_rng(3)
    J = rng.standard_normal((12, 2, 4))
    k = 4
    best = max(_logdet(J, list(c)) for c in itertools.combinations(range(12), k))
    got = _logdet(J, d_optimal(J, k))
    worst = min(_logdet(J, list(c)) for c in itertools.combinations(range(12), k))
    assert got >= worst + (1 - 1 / np.e) * (best - worst) - 1e-9
    assert got >= best - 1.0                         # in practice close to the optimum (within e× in det)


def test_hull_membership_and_spread():
    sq = np.array([[0, 0], [1, 0], [0, 1], [1, 1]], float)
    pts = np.array([[0.5, 0.5], [1.2, 0.5], [1.0, 1.0], [-0.01, 0.0]])
    assert inside_hull(pts, sq).tolist() == [True, False, True, False]
    got = spread(np.array([[0.0], [0.4], [1.0], [0.9]]), np.array([[0.0]]), 2)
    assert got == [2, 1]                             # the farthest from 0, then the farthest from {0, 1}


def test_load_features_do_not_depend_on_which_tendon_pulls():
    a = LoadCase((3.0, 0.0, 0.0), 50e3)
    b = LoadCase((0.0, 3.0, 0.0), 50e3)
    fa, fb = load_features([a, b], 0.0275, 0.16)
    assert np.allclose(fa, fb) and fa[0] == 3.0 and fa[1] == pytest.approx(3.0 * 0.0275) and fa[3] == 0.0
    eq = load_features([LoadCase((2.0, 2.0, 2.0), 0.0)], 0.0275, 0.16)[0]
    assert eq[1] == pytest.approx(0.0, abs=1e-12)     # equal tensions: no bending moment
    f = load_features([LoadCase((0.0, 0.0, 0.0), 0.0, (0.0, 0.0, -0.5))], 0.0275, 0.16)[0]
    assert f[1] == pytest.approx(0.5 * 0.16) and f[3] == pytest.approx(0.5)


@pytest.fixture(scope="module")
def selection():
    base = presets.get("paper").replace(gravity=(0.0, 0.0, 0.0))
    form = get_form("pressure_ei")
    th = initial_theta(form, None, base)
    dd = default_design(**RANGE)
    return form, base, th, dd, informative_design(form, base, th, default=dd, **RANGE)


def test_the_informative_design_knows_more_from_fewer_cases(selection):
    form, base, th, dd, sel = selection
    d = sel.design
    assert len(d.training) < len(dd.training)
    assert sel.logdet > sel.logdet_default + 1.0       # more than e× the default design's information
    # recomputed independently from the chosen cases
    J = sensitivities(form, d.training, base, th)
    assert np.linalg.slogdet(np.einsum("irn,irm->nm", J, J))[1] == pytest.approx(sel.logdet, rel=1e-9)
    # bends (tendons or a lateral force) across the whole pressure range
    bend_p = {c.pressure for c in d.training if (max(c.tensions) - min(c.tensions) > 0 or any(c.tip_force))}
    assert {0.0, 100e3} <= bend_p and len(bend_p) >= 4


def test_held_out_inside_the_hull_and_extrapolation_outside(selection):
    *_, sel = selection
    d = sel.design
    feats = lambda cs: load_features(cs, RANGE["tendon_distance"], RANGE["length"])
    allc = list(d.cases)
    scale = np.maximum(np.abs(feats(allc)).max(axis=0), 1e-12)
    Xt = feats(d.training) / scale
    ho = [c for c in d.heldout if c.experiment == "heldout"]
    ex = [c for c in d.heldout if c.experiment == "extrapolation"]
    assert ho and all(inside_hull(feats(ho) / scale, Xt))
    assert not any(inside_hull(feats(ex) / scale, Xt)) if ex else True
    labels = [c.label for c in allc]
    assert len(set(labels)) == len(labels)             # no case twice
