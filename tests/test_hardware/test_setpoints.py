"""The set-point rule of a cyclic drive (hardware/setpoints.py) against a model of the bus's timing: SYNC ticks of
the drive's own clock (with jitter), TPDOs reaching the host late or in bursts after a stall, RPDOs landing a
little after they were sent.  The drive applies the last RPDO that landed before each SYNC (CiA 402 CSP).
Whatever the interleaving, the demand may change by at most one step per SYNC."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hardware import LimitError
from hardware.setpoints import MIN_SPACING, SetpointRamp, next_setpoint

PERIOD = 0.002


def drive_demands(ramp_factory, n_sync, delays, flight, jitter, goals, start=0):
    """Run ``n_sync`` SYNCs; returns the demand the drive applied at each one.

    delays[k] : how late the host handles the TPDO of SYNC k [s] (a stall: large); the host handles TPDOs in
        order, so a handling time is never earlier than the previous one (a burst after a stall)
    flight[k] : how long the RPDO sent for it takes to land [s];  jitter[k] : SYNC k's offset from k·PERIOD [s]
    goals : {sync index: new goal [counts]} given to the ramp when that TPDO is handled
    The TPDO of SYNC k reports the demand applied at SYNC k (0x6062).
    """
    ramp = ramp_factory(start)
    t_sync = np.arange(n_sync) * PERIOD + np.asarray(jitter)
    landed = []                                        # (time it lands, value)
    demands, d = [], start
    handled = -math.inf
    # events in time order: SYNCs (apply, then report) and host handling of each TPDO
    handled_at = []
    for k in range(n_sync):
        handled = max(handled, t_sync[k] + delays[k])
        handled_at.append(handled)
    events = sorted([(t_sync[k], 0, k) for k in range(n_sync)] + [(handled_at[k], 1, k) for k in range(n_sync)])
    reported = {}
    for t, kind, k in events:
        if kind == 0:
            before = [v for tl, v in landed if tl < t]
            if before:
                d = before[-1]
            demands.append(d)
            reported[k] = d
        else:
            if k in goals:
                ramp.goal = goals[k]
            if ramp.due(t):
                sp = ramp.advance(t, reported[k])
                if sp is not None:
                    landed.append((t + flight[k], sp))
                    landed.sort()
    return np.array(demands)


@st.composite
def timings(draw):
    n = draw(st.integers(20, 120))
    # handled in time, late but still fresh (just before the next SYNC), or after a stall
    delays = draw(st.lists(st.one_of(st.floats(0.0, 0.4 * PERIOD), st.floats(0.5 * PERIOD, 2.0 * PERIOD),
                                     st.floats(0.0, 80 * PERIOD)), min_size=n, max_size=n))
    flight = draw(st.lists(st.floats(0.0, 0.3 * PERIOD), min_size=n, max_size=n))
    jitter = draw(st.lists(st.floats(-0.09 * PERIOD, 0.09 * PERIOD), min_size=n, max_size=n))
    goals = draw(st.dictionaries(st.integers(0, n - 1), st.integers(-5000, 5000), max_size=6))
    return n, delays, flight, jitter, goals


@settings(max_examples=300, deadline=None)
@given(timings(), st.floats(1.0, 200.0))
def test_no_interleaving_makes_the_demand_jump(timing, step):
    n, delays, flight, jitter, goals = timing
    demands = drive_demands(lambda s: SetpointRamp(step, PERIOD, s), n, delays, flight, jitter, goals)
    assert np.max(np.abs(np.diff(demands)), initial=0) <= max(1, math.floor(step))


def catch_up_sender(start, step, n_sync, stall_from, stall_len):
    """The former interpolator: a host timer that sends every period and, after a stall, every missed one back to
    back.  Returns the per-SYNC demand steps (the same drive model)."""
    sp, goal, sent, t = start, start + 10_000, [], 0.0
    stall_end = stall_from + stall_len
    for k in range(n_sync):
        due = k * PERIOD
        t = max(due, stall_end if stall_from <= due < stall_end else due)
        sp += max(-step, min(step, goal - sp))
        sent.append((t + 1e-5, sp))
    demands, d = [], start
    for j in range(n_sync):
        before = [v for tl, v in sent if tl < j * PERIOD + 0.5 * PERIOD]
        d = before[-1] if before else d
        demands.append(d)
    return np.diff(demands)


def test_the_model_sees_the_burst_of_a_catch_up_sender():
    # the drive model is not too kind: a sender that catches up after a 140 ms stall makes a 70-step jump
    steps = catch_up_sender(0, 100, 200, 0.05, 0.14)
    assert np.max(np.abs(steps)) >= 60 * 100


def test_a_stall_pauses_the_ramp_and_it_resumes_from_the_held_setpoint():
    n = 200
    delays = [0.0002] * n
    for k in range(40, 110):                             # 140 ms stall: TPDOs 40…109 handled at its end
        delays[k] = (110 - k) * PERIOD
    demands = drive_demands(lambda s: SetpointRamp(100, PERIOD, s), n, delays, [1e-5] * n, [0.0] * n, {0: 100_000})
    steps = np.diff(demands)
    assert np.max(np.abs(steps)) <= 100
    assert np.all(steps[45:105] == 0)                   # the drive held during the stall
    assert steps[115] == 100                            # and goes on at one step per SYNC, no catch-up


def test_next_setpoint_and_ramp_basics():
    assert next_setpoint(1000, [0, 0], 7) == 7
    assert next_setpoint(-1000, [0, 5], 7) == -2          # within 7 of both 0 and 5
    assert next_setpoint(3, [0, 5], 7) == 3
    assert next_setpoint(0, [0, 20], 7) is None           # no value within 7 of both: nothing is sent
    r = SetpointRamp(7.9, PERIOD, 10)
    assert r.step == 7 and r.setpoint == 10 and r.settled
    r.goal = 30
    # every set-point landed in time: the drive reports the previous one, the ramp runs at a full step per SYNC
    sent = []
    for t in range(4):
        sent.append(r.advance(t * PERIOD, sent[-1] if sent else 10))
    assert sent == [17, 24, 30, 30] and r.settled
    # a late RPDO: the drive still reports 10 while 17 may land; the next is within 7 of both
    r2 = SetpointRamp(7, PERIOD, 10)
    r2.goal = 100
    assert r2.advance(0.0, 10) == 17 and r2.advance(PERIOD, 10) == 17 and r2.advance(2 * PERIOD, 17) == 24
    assert not r.due(3 * PERIOD + 0.5 * PERIOD) and r.due(3 * PERIOD + 1.01 * MIN_SPACING * PERIOD)
    r.goal = 0
    r.advance(1.0, 30)
    r.hold()
    assert r.goal == 23
    r.reseed(5)
    assert r.setpoint == 5 and r.goal == 5 and r.demand == 5
    for bad in (0, -1, math.nan, math.inf, "1", True):
        with pytest.raises(LimitError):
            SetpointRamp(bad, PERIOD, 0)
        with pytest.raises(LimitError):
            SetpointRamp(1, bad, 0)
