"""The forms fitted side by side (``identify(workers=…)``) give the result of the sequential order.

1. The schedule (:class:`validation.identification.identify._FitPlan`) against the sequential loop it replaces —
   every form from its own start, then rounds of refits in form order from the nested forms' optima until a round
   improves nothing — with a stand-in fit (a deterministic pseudo-random residual per start) and the batches
   finished in random orders, as processes finish them: the same starts tried, the same fits kept.
2. The real fits on synthetic states: 1 and 2 worker processes, the same parameters and residuals."""

from __future__ import annotations

import hashlib
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from ancf import Model, presets
from validation.identification import identify as I
from validation.identification.fit import Observations
from validation.identification.forms import FORMS, get_form

FORMS_M = [get_form(name, False, True) for name in FORMS]
BASE = presets.paper()


def _fake_fit(form, start, salt: int):
    """A stand-in fit: θ moved by a pseudo-random amount and a pseudo-random residual, both set by (form, start,
    salt) only — as a real fit's result is set by its form and start."""
    h = hashlib.sha256(form.name.encode() + np.asarray(start, float).tobytes() + bytes([salt])).digest()
    u = np.frombuffer(h, np.uint8).astype(float) / 255.0
    theta = np.asarray(start, float) * (1.0 + 0.1 * (u[:form.n] - 0.5))
    # few distinct residuals: ties, where the first fit kept wins, make the order of the starts matter
    return SimpleNamespace(form=form, theta=theta, rss=float(int(u[-1] * 4)), intervals="full", held_at={})


def _sequential(forms, salt: int):
    """The sequential loop (the order the schedule must reproduce): (fits, {form: starts in the order fitted})."""
    fits, tried = {}, {}

    def attempt(form, start):
        start = np.asarray(start, float)
        seen = tried.setdefault(form.name, [])
        if start.tobytes() in seen:
            return False
        seen.append(start.tobytes())
        g = _fake_fit(form, start, salt)
        if form.name not in fits or g.rss < fits[form.name].rss * (1 - 1e-9):
            fits[form.name] = g
            return True
        return False

    th0 = {f.name: I.initial_theta(f, None, BASE) for f in forms}
    for form in forms:
        attempt(form, th0[form.name])
    for _ in range(I.NESTED_ROUNDS):
        improved = False
        for form in forms:
            for start in I.starting_points(form, th0[form.name], fits)[1:] + I.restricted_starts(form, fits):
                improved |= attempt(form, start)
        if not improved:
            break
    return fits, tried


def _scheduled(forms, salt: int, rng):
    """The schedule, its ready batches finished in a random order."""
    plan = I._FitPlan(forms, None, BASE, {}, {f.name: () for f in forms})
    running, order = [], {}
    while True:
        running += plan.ready()
        if not running:
            return plan.fits, order
        i, _, starts = running.pop(int(rng.integers(len(running))))
        order.setdefault(forms[i].name, []).extend(s.tobytes() for s in starts)
        plan.merge(i, [(_fake_fit(forms[i], s, salt), 0.0) for s in starts])


@settings(max_examples=40, deadline=None)
@given(salt=st.integers(0, 255), seed=st.integers(0, 2 ** 32 - 1),
       subset=st.lists(st.sampled_from(range(len(FORMS_M))), min_size=1, max_size=len(FORMS_M), unique=True))
def test_the_schedule_keeps_the_sequential_result(salt, seed, subset):
    forms = [FORMS_M[i] for i in sorted(subset)]
    seq_fits, seq_tried = _sequential(forms, salt)
    par_fits, par_tried = _scheduled(forms, salt, np.random.default_rng(seed))
    assert seq_tried == par_tried                       # the same starts, in the same order per form
    assert list(seq_fits) == list(par_fits)
    for name, f in seq_fits.items():
        assert np.array_equal(f.theta, par_fits[name].theta) and f.rss == par_fits[name].rss


def test_the_groups_of_nested_forms():
    groups = [[FORMS_M[i].name for i in g] for g in I._groups(
        [[I._related(a, b) for b in FORMS_M] for a in FORMS_M])]
    assert ["paper", "paper_area"] in groups and ["constant"] in groups
    assert ["separate", "separate_area", "quadratic", "pressure_ei", "pressure_ei_ea",
            "pressure_ei_shear"] in groups


# ------------------------------------------------------------------------------- real fits, 1 and 2 processes
def _states(n=16, seed=3) -> Observations:
    """Noisy synthetic states of a plant 8 % stiffer than the paper preset (tip σ 0.1 mm)."""
    from ancf import StiffnessLaw
    law = BASE.stiffness
    plant = BASE.replace(stiffness=StiffnessLaw.polynomial(EA=[1.08 * c for c in law.EA_coeffs],
                                                           EI=[1.08 * c for c in law.EI_coeffs]))
    rng = np.random.default_rng(seed)
    T = rng.uniform(0, 4, (n, 3)) * (rng.uniform(size=(n, 3)) < 0.7)
    p = rng.choice([0.0, 30e3, 60e3, 90e3], n)
    m = Model(plant)
    tips = np.array([m.fk(T[i], p[i], np.zeros(3)).tip for i in range(n)])
    tips += rng.normal(0, 1e-4, tips.shape)
    return Observations(T, p, np.zeros((n, 3)), np.ones(n, bool), tips, tip_std=np.full((n, 3), 1e-4))


def test_one_and_two_processes_give_the_same_fits():
    obs = _states()
    forms = ("paper", "paper_area", "separate", "pressure_ei", "constant")
    lines = {1: [], 2: []}
    res = {w: I.identify(obs, BASE, forms=forms, workers=w, progress=lines[w].append) for w in (1, 2)}
    assert res[1].form == res[2].form
    assert set(res[1].fits) == set(res[2].fits)
    for name, f in res[1].fits.items():
        g = res[2].fits[name]
        np.testing.assert_allclose(g.theta, f.theta, rtol=1e-10, atol=0, err_msg=name)
        assert g.rss == pytest.approx(f.rss, rel=1e-10)
    for w in (1, 2):       # one line per form fitted, then the refits
        assert sorted(x.split(":")[0] for x in lines[w][:len(forms)]) == sorted(f"form {n}" for n in forms)
    assert any("refit(s)" in x for x in lines[1]) and any("refit(s)" in x for x in lines[2])


def test_the_number_of_workers_is_checked():
    from ancf.errors import InputError
    with pytest.raises(InputError, match="workers"):
        I._fit_workers(0, 3)
    assert I._fit_workers(None, 1) == 1 and I._fit_workers(8, 3) == 3


def test_ctrl_c_stops_the_worker_processes():
    """A Ctrl-C (KeyboardInterrupt in the parent, here raised from the progress line of the first form done)
    reaches the caller, and no fit process is left running."""
    import multiprocessing as mp
    obs = _states(10)
    before = set(mp.active_children())

    def interrupt(line):
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        I.identify(obs, BASE, forms=("paper", "separate", "pressure_ei"), workers=2, progress=interrupt)
    assert not [p for p in mp.active_children() if p not in before and p.is_alive()]
