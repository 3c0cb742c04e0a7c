"""The one criterion of "reproduces the paper": used by the verdicts (the ✓/✗ of the comparison table) and by
the green bands of compare.png, so that the figure and the table cannot disagree.

A headline's criterion is an interval ``[lo, hi]`` of the value itself (either end may be open, ``None``);
:func:`within` judges a value, :func:`ratio_band` gives the same interval in the figure's coordinate, ours /
paper.
"""

from __future__ import annotations

import math
from typing import Optional

__all__ = ["within", "ratio_band"]


def within(value, lo: Optional[float], hi: Optional[float]) -> Optional[bool]:
    """True if ``value`` lies in ``[lo, hi]`` (ends included, ``None`` = open), False if not; None when there
    is no criterion or no finite number to judge."""
    if lo is None and hi is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        return None
    return bool((lo is None or value >= lo) and (hi is None or value <= hi))


def ratio_band(lo: Optional[float], hi: Optional[float], paper: float) -> tuple[float, float]:
    """The interval of ours / ``paper`` in which :func:`within` holds: ``(a, b)`` with ``a`` ≥ 0 (or −inf) and
    ``b`` ≤ inf, for a non-zero paper value (a negative one swaps the ends)."""
    if not paper:
        raise ValueError("a ratio band needs a non-zero paper value")
    lo_r = -math.inf if lo is None else lo / paper
    hi_r = math.inf if hi is None else hi / paper
    if paper < 0:
        lo_r, hi_r = (math.inf if lo is None else lo_r), (-math.inf if hi is None else hi_r)
        lo_r, hi_r = hi_r, lo_r
    return lo_r, hi_r
