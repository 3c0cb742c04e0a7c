"""FEM sweep plumbing without the FEM: warm-start chains cover every case once, and an interrupted sweep says
how much is finished and where it is kept."""

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from validation import fem_sweep
from validation.experiments import LoadCase, default_design
from validation.runner import RunInterrupted

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


def test_interrupted_sweep_says_what_is_kept(monkeypatch, tmp_path):
    cases = default_design().cases[:6]

    def interrupted(fn, tasks, **kw):
        raise RunInterrupted("stopped", completed={0: [None] * len(tasks[0]["cases"])}, total=len(tasks))

    monkeypatch.setattr(fem_sweep, "run_tasks", interrupted)
    from validation.designs import load_design
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
    from validation.identify import from_fem
    with pytest.raises(ConfigError, match="mesh level"):
        fem_sweep.FemSpec(None, None, "bogus")
    with pytest.raises(InputError, match="workers"):
        from_fem(None, None, "coarse", workers=0)
