"""FEM sweep plumbing without the FEM: warm-start chains cover every case once, and an interrupted sweep says
how much is finished and where it is kept."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from validation.reference import fem_sweep
from validation.reference.experiments import LoadCase, default_design
from validation.infra.runner import RunInterrupted

loads = st.lists(st.tuples(st.floats(0, 5), st.floats(0, 5), st.floats(0, 5), st.floats(0, 120e3)),
                 min_size=1, max_size=30)


@settings(max_examples=40, deadline=None)
@given(loads, st.integers(1, 6))
def test_chains_cover_every_case_exactly_once(rows, length):
    cases = [LoadCase((a, b, c), p) for a, b, c, p in rows]
    chains = fem_sweep.plan_chains(cases, length)
    flat = [i for ch in chains for i in ch]
    assert sorted(flat) == list(range(len(cases)))
    assert all(1 <= len(ch) <= length for ch in chains)


@settings(max_examples=40, deadline=None)
@given(loads, st.integers(1, 6))
def test_axisymmetric_cases_are_chained_apart_and_last(rows, length):
    """A chain never passes between an axisymmetric case (equal tensions, no tip force) and another one (the
    FEM's symmetric subspace needs a symmetric start), and the axisymmetric chains come after the others."""
    cases = [LoadCase((a, a, a) if p > 60e3 else (a, b, c), p) for a, b, c, p in rows]
    chains = fem_sweep.plan_chains(cases, length)
    kinds = [{fem_sweep.axisymmetric(cases[i]) for i in ch} for ch in chains]
    assert all(len(k) == 1 for k in kinds)
    flags = [k.pop() for k in kinds]
    assert flags == sorted(flags)


@settings(max_examples=40, deadline=None)
@given(loads, st.lists(st.booleans(), min_size=30, max_size=30), st.integers(1, 6))
def test_gravity_cases_are_chained_apart(rows, weights, length):
    """A chain never passes between a case with gravity and one without (the self-weight is no small step:
    a warm start across it took three times the Newton iterations of a cold start)."""
    cases = [LoadCase((a, b, c), p, gravity=g) for (a, b, c, p), g in zip(rows, weights)]
    for ch in fem_sweep.plan_chains(cases, length):
        assert len({cases[i].gravity for i in ch}) == 1


@settings(max_examples=40, deadline=None)
@given(loads, st.integers(2, 6))
def test_a_chain_never_steps_farther_than_a_cold_start(rows, length):
    """Each warm start of a chain is at most as far (in the scaled load space) as a start from the unloaded
    state would be."""
    cases = [LoadCase((a, b, c), p) for a, b, c, p in rows]
    raw = np.array([fem_sweep._load_vector(c, 1.0) for c in cases])
    X = raw / np.maximum(np.abs(raw).max(axis=0), 1e-12)
    for ch in fem_sweep.plan_chains(cases, length):
        for a, b in zip(ch, ch[1:]):
            assert np.linalg.norm(X[b] - X[a]) <= np.linalg.norm(X[b])


def test_the_default_design_starts_the_lateral_force_cold():
    d = default_design(tension_max=5.0, pressure_max=100e3)
    for ch in fem_sweep.plan_chains(d.cases, 4):
        for a, b in zip(ch, ch[1:]):
            assert not (d.cases[b].label.startswith("T=0/0/0 N, p=0 kPa, F=") and d.cases[a].tensions[0] > 0)


def test_axisymmetric_load_cases():
    assert fem_sweep.axisymmetric(LoadCase((2.0, 2.0, 2.0), 5e4))
    assert fem_sweep.axisymmetric(LoadCase((0.0, 0.0, 0.0), 0.0))
    assert not fem_sweep.axisymmetric(LoadCase((2.0, 2.0, 2.1), 5e4))
    assert not fem_sweep.axisymmetric(LoadCase((2.0, 2.0, 2.0), 5e4, (0.0, 0.1, 0.0)))
    assert not fem_sweep.axisymmetric(LoadCase((2.0, 2.0, 2.0), 5e4, gravity=True))
    d = default_design(tension_max=5.0, pressure_max=100e3)
    assert sum(fem_sweep.axisymmetric(c) for c in d.cases) == 12


def test_interrupted_sweep_says_what_is_kept(monkeypatch, tmp_path):
    cases = default_design().cases[:6]

    def interrupted(fn, tasks, **kw):
        raise RunInterrupted("stopped", completed={0: [None] * len(tasks[0]["cases"])}, total=len(tasks))

    monkeypatch.setattr(fem_sweep, "run_tasks", interrupted)
    from validation.reference.designs import load_design
    spec = fem_sweep.FemSpec(*load_design("paper"), "coarse")
    monkeypatch.setattr(fem_sweep.FemSpec, "key", lambda self: {"mesh": "coarse"})
    with pytest.raises(RunInterrupted, match=rf"of 6 FEM cases were finished; they are cached in {tmp_path}") as exc:
        fem_sweep.run_cases(spec, cases, cache_dir=tmp_path, progress=False)
    assert exc.value.saved_to == tmp_path and exc.value.completed
    with pytest.raises(RunInterrupted, match="not kept"):
        fem_sweep.run_cases(spec, cases, cache_dir=None, progress=False)


def test_bad_run_options_fail_before_any_fem_work():
    """An unknown mesh level or a worker count of 0 is rejected when the run is set up, not in a worker."""
    from ancf.errors import ConfigError, InputError
    from validation.identification.identify import from_fem
    with pytest.raises(ConfigError, match="mesh level"):
        fem_sweep.FemSpec(None, None, "bogus")
    with pytest.raises(InputError, match="workers"):
        from_fem(None, None, "coarse", workers=0)
