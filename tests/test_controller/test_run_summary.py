"""The whole-run summary of a control run (controller.summary): settled error per load period, judged
periods, saturation time — from synthetic samples whose answer is known."""

import math

import numpy as np
import pytest

from controller.summary import SETTLED_DEFINITION, summarise


def _run(t_end=10.05):
    """Samples every 0.1 s over [0, 10.0]; load changes at 5 and 10 s.  Period 1: the error decays from 5 mm
    to 0.1 mm (settled half 2.5–5 s: 0.1 mm, one noisy 0.3 mm sample); period 2 settles at 0.15 mm; the last
    sample (t = 10.0, just after the change at 10 s) is 9 mm."""
    t = np.round(np.arange(0.0, 10.01, 0.1), 10)
    e = np.where(t < 5, np.maximum(5e-3 * np.exp(-3 * t), 1e-4), np.maximum(4e-3 * np.exp(-3 * (t - 5)), 1.5e-4))
    e[np.isclose(t, 3.0)] = 3e-4
    e[-1] = 9e-3
    return t, e, t_end


def test_last_sample_after_a_load_change_does_not_decide_the_summary():
    t, e, t_end = _run()
    s = summarise(t, e, tolerance=2e-4, t_start=0.0, t_end=t_end, load_changes=[5.0, 10.0, 15.0])
    assert [(p.start, p.end, p.ended_by) for p in s.periods] == [(0.0, 5.0, "load change"), (5.0, 10.0, "load change"),
                                                                  (10.0, t_end, "run end")]
    p1, p2, p3 = s.periods
    assert p1.settled_samples == 25 and p1.settled_error == pytest.approx(1e-4) and p1.settled_max_error == 3e-4
    assert p2.settled_samples == 25 and p2.settled_error == pytest.approx(1.5e-4)
    assert p3.samples == 1 and not p3.judged and "cut short" in p3.note       # the 9 mm sample: not judged
    assert s.met and s.periods_within_tolerance == 2
    assert s.settled_error_median == pytest.approx(1.25e-4) and s.settled_error_max == pytest.approx(1.5e-4)
    assert s.settled_peak_error == pytest.approx(3e-4)
    d = s.to_dict()
    assert d["met_tolerance"] and d["periods"][2]["settled_error_m"] is None and d["definition"] == SETTLED_DEFINITION
    assert any("cut short" in ln for ln in s.lines())


def test_a_period_that_does_not_settle_fails_the_run():
    t, e, t_end = _run()
    e = e.copy()
    e[(t >= 7.5) & (t < 10)] = 5e-4                                        # period 2 stays at 0.5 mm
    s = summarise(t, e, tolerance=2e-4, t_start=0.0, t_end=t_end, load_changes=[5.0, 10.0])
    assert not s.met and [p.within_tolerance for p in s.periods] == [True, False, None]
    assert s.settled_error_max == pytest.approx(5e-4)


def test_unknown_or_constant_load_is_one_period_and_a_long_last_period_is_judged():
    t, e, _ = _run()
    s = summarise(t, e, tolerance=2e-4, t_start=0.0, t_end=10.0, load_changes=None)
    assert len(s.periods) == 1 and not s.load_changes_known and s.periods[0].judged
    assert s.periods[0].settled_samples == 51                                  # 5.0 … 10.0 s, the run's end included
    assert s.periods[0].settled_error == pytest.approx(1.5e-4)
    s = summarise(t, e, tolerance=2e-4, t_start=0.0, t_end=10.0, load_changes=[4.0])
    assert [p.judged for p in s.periods] == [True, True]                      # 6 s >= half of 4 s: judged
    empty = summarise([], [], tolerance=2e-4, t_start=0.0, t_end=1.0)
    assert not empty.met and math.isnan(empty.settled_error_median)


def test_saturation_time_counts_until_the_next_sample():
    t = [0.0, 0.5, 1.0, 2.0]
    s = summarise(t, [1e-4] * 4, tolerance=2e-4, t_start=0.0, t_end=2.5,
                  saturation=[(), ("tension",), ("tension", "controller"), ("travel",)])
    assert s.saturated_samples == 3 and s.saturation_time == pytest.approx(0.5 + 1.0 + 0.5)
    assert s.saturation == pytest.approx({"tension": 1.5, "travel": 0.5, "controller": 1.0})


def test_a_period_out_of_reach_is_not_judged_but_one_saturated_in_part_is():
    """Period 2 stays at 0.5 mm: with every settled sample reach-saturated it is out of reach (not judged; the
    run met its tolerance), with one settled sample tracking again it is judged (and fails)."""
    t, e, t_end = _run()
    e = e.copy()
    e[(t >= 7.5) & (t < 10)] = 5e-4
    sat = [("reach", "tension") if 5.0 <= x < 10 else () for x in t]
    gaps = np.where((t >= 5.0) & (t < 10), np.where(t < 8.0, 4e-4, 6e-4), 0.0)   # settled half: 7.5–10 s
    s = summarise(t, e, tolerance=2e-4, t_start=0.0, t_end=t_end, load_changes=[5.0, 10.0], saturation=sat,
                  reach_gaps=gaps)
    p1, p2, _ = s.periods
    assert p1.judged and p2.out_of_reach and not p2.judged and "out of reach by 0.600 mm" in p2.note
    assert p2.reach_gap == pytest.approx(6e-4) and math.isnan(p1.reach_gap)   # 5 of 25 settled samples at 0.4 mm
    assert s.met and len(s.out_of_reach) == 1 and s.settled_error_max == pytest.approx(1e-4)
    assert s.to_dict()["periods_out_of_reach"] == 1 and s.saturation["reach"] == pytest.approx(5.0)
    sat[int(np.argmin(np.abs(t - 9.0)))] = ("tension",)                    # one settled sample not out of reach
    s = summarise(t, e, tolerance=2e-4, t_start=0.0, t_end=t_end, load_changes=[5.0, 10.0], saturation=sat)
    assert s.periods[1].judged and not s.periods[1].out_of_reach and not s.met
    everywhere = [("reach",)] * len(t)                                     # out of reach throughout: met, none judged
    only = summarise(t, e, tolerance=2e-4, t_start=5.0, t_end=9.95, load_changes=[], saturation=everywhere)
    assert not only.judged and len(only.out_of_reach) == 1 and only.met
