r"""Set-points of a cyclic (CSP) drive that cannot jump, whatever the host's timing.

In cyclic synchronous position the drive takes the target of the **last** RPDO it received before each SYNC as
an absolute position demand and computes no ramp of its own.  The host must therefore bound the change of that
demand per SYNC period, and the bound must hold when the host stalls (a compiled kernel holding the GIL, a busy
thread, a slow disk) — a sender that "catches up" missed periods after a stall sends N set-points back to back,
the drive applies only the last one, and N periods of motion happen in one.

The rule (:class:`SetpointRamp`), with ``s`` = the largest step per SYNC period [counts]:

1. **Clocked by the drive, not by a host timer.**  A set-point is sent only in answer to a TPDO the drive sent
   after a SYNC (one per SYNC), at most one per TPDO, and never two closer than :data:`MIN_SPACING` SYNC
   periods on the host clock (a backlog of TPDOs handled at once after a host stall is answered once).
   Nothing is sent while the host is stalled, and nothing is caught up after it.
2. **Within ``s`` of what the drive holds, and of what may still land.**  The TPDO carries the drive's
   *position demand* 0x6062 — the target the drive applied at that SYNC, ``D``.  The RPDO the host sent last,
   ``L``, may still land before the next SYNC (sent late) or may already be ``D``.  The next set-point is the
   value closest to the goal within ``s`` of **both**:

       lo = max(D, L) − s,  hi = min(D, L) + s,  next = clamp(goal, lo, hi)      (nothing is sent if lo > hi)

   In steady operation ``D = L`` (every RPDO lands in time) and the ramp runs at one full ``s`` per SYNC.
   Whichever of ``next``, ``L`` or ``D`` the drive applies at the next SYNC, it is within ``s`` of ``D``.
   A TPDO handled late (a busy host) is still answered: its ``D`` is exact for its SYNC, and the rule holds
   whatever the delay (the property test draws delays of up to 80 periods).  Dropping late TPDOs instead
   would stall the ramp on a loaded machine.
3. **After a stall, from where the drive is.**  The drive held its last demand while the host was silent (it
   applies no RPDO it did not get), and the first TPDO after the stall reports it: the ramp resumes from that
   demand, one ``s`` per SYNC — never from where a clock says it should be.  After a fault, or while the drive
   is not enabled, the set-point is the drive's actual position (:meth:`SetpointRamp.reseed`), so re-enabling
   cannot jump.

Everything is integer counts; ``s`` is rounded down (at least 1 count).  Tested with property-based timings of
SYNCs, late and bursty TPDO handling and late RPDOs (tests/test_hardware/test_setpoints.py) and, against drives
in another process that record every per-SYNC step, under host stalls (tests/test_hardware/test_epos4_timing.py).
"""

from __future__ import annotations

import math

from .errors import LimitError

__all__ = ["next_setpoint", "SetpointRamp", "MIN_SPACING"]

#: shortest time between two set-points, in SYNC periods (rule 1)
MIN_SPACING = 0.6


def next_setpoint(goal: int, holds, step: int):
    """The integer set-point closest to ``goal`` within ``step`` of every value in ``holds`` (rule 2), or None
    when no value is (then nothing is sent)."""
    lo = max(int(r) for r in holds) - step
    hi = min(int(r) for r in holds) + step
    return None if lo > hi else min(max(int(goal), lo), hi)


class SetpointRamp:
    """The host's side of rules 1–3 for one drive (not thread-safe: its owner locks).

    step : largest change per SYNC period [counts] (float; rounded down, at least 1)
    period : SYNC period [s]
    start : the drive's actual position [counts]
    """

    def __init__(self, step: float, period: float, start: int):
        if isinstance(step, bool) or not (isinstance(step, (int, float)) and math.isfinite(step) and step > 0):
            raise LimitError(f"set-point step must be a positive number of counts, got {step!r}")
        if isinstance(period, bool) or not (isinstance(period, (int, float)) and math.isfinite(period) and period > 0):
            raise LimitError(f"SYNC period must be positive, got {period!r}")
        self.step = max(1, int(math.floor(step)))
        self.period = float(period)
        self.reseed(start)
        self.last_sent = -math.inf                 # host time of the last send [s]

    def due(self, now: float) -> bool:
        """May a set-point be sent at host time ``now`` [s] (rule 1's spacing)?"""
        return now - self.last_sent >= MIN_SPACING * self.period

    def advance(self, now: float, demand: int):
        """The next set-point towards the goal (rule 2) given the drive's reported ``demand`` [counts], recorded
        as sent at ``now`` [s]; None when nothing may be sent."""
        self.demand = int(demand)
        sp = next_setpoint(self.goal, (self.demand, self.setpoint), self.step)
        if sp is not None:
            self.setpoint, self.last_sent = sp, now
        return sp

    def reseed(self, actual: int) -> None:
        """Freeze at the drive's actual position (fault, drive not enabled, re-enable): goal, set-point, demand."""
        self.goal = self.setpoint = self.demand = int(actual)

    def hold(self) -> None:
        """Stop where the set-point is: the goal becomes the newest set-point."""
        self.goal = self.setpoint

    @property
    def settled(self) -> bool:
        """The newest set-point is the goal and the drive reports it as its demand."""
        return self.setpoint == self.goal == self.demand
