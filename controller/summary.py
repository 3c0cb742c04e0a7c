r"""The summary of a whole control run: settled tip error per load period, saturation time, faults.

A hold run (``run_on_rig(..., RunOptions(duration=...))``) is judged on all of it, not on its last sample
(which may fall just after a new load was hung on the tip).  Definitions (the ones ``bellows control`` prints and
the run log stores in ``/summary``):

* **load period** — the time between two changes of the tip load: the change times of the simulated
  rig's load profile (``stochastic``: every period; ``step``: the step).  When the load is constant, varies
  continuously (``continuous``, ``cyclic``) or is unknown (a hardware rig), the whole run is one period.
* **settled part** of a period — its second half in time.
* **settled tip error** of a period — the median of the measured tip error ‖p_m − p_d‖ over the samples
  of its settled part (robust to the single noisy frame that triggers a correction); the maximum over
  the settled part is reported too.  On a simulated rig the same is computed from the true tip.
* **judged** — every period that a load change ended is judged; the last period, which the end of the
  run cut short, is judged only if it is the only period or lasted at least half as long as the longest
  period before it (a load hung just before the end had no time to settle: reported, not judged); a
  period without samples in its settled part is not judged either, nor is a period **out of reach**: one
  whose every settled sample was ``reach``-saturated (the load put the target out of the actuator's reach,
  the controller held the nearest reachable state; no controller can meet a tolerance there).  Its *reach
  gap* — the median over the settled half of how far the controller's IK target was out of reach under
  the load it assumed — is reported beside its settled error (LACC: the settled error comes close to it
  when the nearest reachable state is held; VF-CC assumes its virtual force, so its gap is an indication).
* **within tolerance** — the settled tip error is below the controller's tolerance.  The run *met* its
  tolerance when every judged period is within tolerance and at least one period was judged or out of reach
  (a run whose loads kept the target out of reach throughout did what it could: met, with its saturation
  time reported).
* **saturation time** [s] — the rig time spent in samples where something was at a limit: ``tension``
  (a tension the controller's IK expects within 1 % of the actuator's tension range from a bound, or a
  measured tension at or above 95 % of the rig's tension limit), ``travel`` (a drive within 1 % of the
  travel range from a travel limit), ``reach`` (the controller's IK target was out of reach under the
  current load: it commanded the nearest reachable state) or ``controller`` (LACC clipped or halved its load
  step, or corrected in its IK fallback).  A sample counts until the next one.
* **faults** — the rig's ``fault``, ``limit`` and ``error`` events during the run.
* **corrections** — commands the controller sent after the first IK.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Optional, Sequence

import numpy as np


def __getattr__(name: str):
    """``SETTLED_DEFINITION``: the one definition of the summary's terms, stored with every run log's summary
    (:data:`hardware.runlog.SUMMARY_DEFINITION`; controller → hardware is the allowed import direction).  Read
    on first use, so that importing :mod:`controller` does not load the rig layer."""
    if name == "SETTLED_DEFINITION":
        from hardware.runlog import SUMMARY_DEFINITION
        return SUMMARY_DEFINITION
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


SATURATION_REASONS = ("tension", "travel", "controller")


@dataclass
class LoadPeriod:
    """One load period of a run (SI; errors NaN when the settled part has no samples)."""
    start: float
    end: float
    ended_by: str                          # "load change" | "run end"
    samples: int = 0
    settled_samples: int = 0
    settled_error: float = math.nan        # median of the measured error over the settled part [m]
    settled_max_error: float = math.nan    # max of the measured error over the settled part [m]
    true_settled_error: float = math.nan   # the same from the simulated truth [m]
    true_settled_max_error: float = math.nan
    judged: bool = False
    out_of_reach: bool = False             # every settled sample was reach-saturated (not judged)
    reach_gap: float = math.nan            # out of reach: median of the controller's reach gap there [m]
    within_tolerance: Optional[bool] = None
    note: str = ""

    def to_dict(self) -> dict:
        return {"start_s": self.start, "end_s": self.end, "ended_by": self.ended_by, "samples": self.samples,
                "settled_samples": self.settled_samples, "settled_error_m": _f(self.settled_error),
                "settled_max_error_m": _f(self.settled_max_error),
                "true_settled_error_m": _f(self.true_settled_error),
                "true_settled_max_error_m": _f(self.true_settled_max_error), "judged": self.judged,
                "out_of_reach": self.out_of_reach, "reach_gap_m": _f(self.reach_gap),
                "within_tolerance": self.within_tolerance, "note": self.note}


def _f(x) -> Optional[float]:
    """JSON-friendly float (NaN → None)."""
    return None if x is None or not math.isfinite(x) else float(x)


@dataclass
class RunSummary:
    """The whole-run summary (see the module docstring for the definitions)."""
    tolerance: float
    periods: list
    load_changes_known: bool
    saturation: dict = field(default_factory=dict)      # reason → seconds
    saturation_time: float = 0.0
    saturated_samples: int = 0
    faults: list = field(default_factory=list)
    corrections: int = 0
    duration: float = 0.0
    samples: int = 0

    @property
    def judged(self) -> list:
        return [p for p in self.periods if p.judged]

    @property
    def periods_within_tolerance(self) -> int:
        return sum(1 for p in self.judged if p.within_tolerance)

    @property
    def out_of_reach(self) -> list:
        return [p for p in self.periods if p.out_of_reach]

    @property
    def met(self) -> bool:
        """Every judged period within tolerance, and at least one period judged or out of reach."""
        j = self.judged
        return bool(j or self.out_of_reach) and all(p.within_tolerance for p in j)

    def _over(self, attr: str, how) -> float:
        v = [getattr(p, attr) for p in self.judged if math.isfinite(getattr(p, attr))]
        return float(how(v)) if v else math.nan

    @property
    def settled_error_median(self) -> float:
        """Median over the judged periods of their settled tip error [m]."""
        return self._over("settled_error", np.median)

    @property
    def settled_error_max(self) -> float:
        """Largest settled tip error of a judged period [m]."""
        return self._over("settled_error", np.max)

    @property
    def settled_peak_error(self) -> float:
        """Largest single measured error in the settled part of a judged period [m]."""
        return self._over("settled_max_error", np.max)

    @property
    def true_settled_error_median(self) -> float:
        return self._over("true_settled_error", np.median)

    @property
    def true_settled_error_max(self) -> float:
        return self._over("true_settled_error", np.max)

    def to_dict(self) -> dict:
        from hardware.runlog import SUMMARY_DEFINITION
        return {"definition": SUMMARY_DEFINITION, "tolerance_m": self.tolerance,
                "load_changes_known": self.load_changes_known, "periods": [p.to_dict() for p in self.periods],
                "periods_judged": len(self.judged), "periods_out_of_reach": len(self.out_of_reach),
                "periods_within_tolerance": self.periods_within_tolerance,
                "met_tolerance": self.met, "settled_error_median_m": _f(self.settled_error_median),
                "settled_error_max_m": _f(self.settled_error_max),
                "settled_peak_error_m": _f(self.settled_peak_error),
                "true_settled_error_median_m": _f(self.true_settled_error_median),
                "true_settled_error_max_m": _f(self.true_settled_error_max),
                "saturation_time_s": self.saturation_time, "saturated_samples": self.saturated_samples,
                "saturation_s": dict(self.saturation), "faults": list(self.faults),
                "corrections": self.corrections, "duration_s": self.duration, "samples": self.samples}

    def lines(self, max_rows: int = 20) -> list:
        """The summary as short lines with units (what ``bellows control`` prints)."""
        mm = lambda x: "—" if not math.isfinite(x) else f"{x * 1e3:.3f}"      # noqa: E731
        tol = self.tolerance * 1e3
        j = self.judged
        not_judged = [p for p in self.periods if not p.judged]
        src = ("load changes of the simulated load profile" if self.load_changes_known and len(self.periods) > 1
               else "one period: no load changes known" if not self.load_changes_known
               else "one period: constant load")
        out = ["run summary (settled = second half of each load period; settled error = its median tip error)",
               f"  load periods        {len(self.periods)} ({src}); {len(j)} judged, "
               f"{self.periods_within_tolerance} within the tolerance {tol:.3f} mm"
               + (f"; {len(not_judged)} not judged "
                  f"({'; '.join(sorted({'out of reach' if p.out_of_reach else p.note for p in not_judged}))})"
                  if not_judged else ""),
               f"  settled tip error   median {mm(self.settled_error_median)} mm, max "
               f"{mm(self.settled_error_max)} mm over the judged periods (largest settled sample "
               f"{mm(self.settled_peak_error)} mm)"]
        if math.isfinite(self.true_settled_error_median):
            out.append(f"  true settled error  median {mm(self.true_settled_error_median)} mm, max "
                       f"{mm(self.true_settled_error_max)} mm (simulated rig)")
        sat = ", ".join(f"{k} {v:.2f} s" for k, v in self.saturation.items() if v > 0)
        out.append(f"  saturation time     {self.saturation_time:.2f} s of {self.duration:.2f} s"
                   + (f" ({sat})" if sat else ""))
        out.append(f"  faults              {len(self.faults)}" + (f": {self.faults[-1]}" if self.faults else ""))
        out.append(f"  corrections         {self.corrections}")
        if len(self.periods) > 1:
            out.append("  period  from [s]   to [s]  settled samples  settled error [mm]  max [mm]  true [mm]  "
                       "within tolerance")
            for i, p in enumerate(self.periods[:max_rows]):
                ok = ("yes" if p.within_tolerance else "NO") if p.judged else f"not judged ({p.note})"
                out.append(f"  {i + 1:6d}  {p.start:8.2f}  {p.end:7.2f}  {p.settled_samples:15d}  "
                           f"{mm(p.settled_error):>18s}  {mm(p.settled_max_error):>8s}  "
                           f"{mm(p.true_settled_error):>9s}  {ok}")
            if len(self.periods) > max_rows:
                out.append(f"  … {len(self.periods) - max_rows} more periods (in --json and the run log)")
        return out


def summarise(times: Sequence[float], errors: Sequence[float], *, tolerance: float, t_start: float,
              t_end: float, true_errors: Sequence[float] = (), saturation: Sequence = (),
              load_changes: Optional[Sequence[float]] = None, faults: Sequence[str] = (),
              corrections: int = 0, reach_gaps: Sequence[float] = ()) -> RunSummary:
    """Summarise a run from its samples: ``times`` [s] (rig clock), measured ``errors`` [m], optional
    ``true_errors`` [m] (simulated rig), ``saturation`` (per sample: the reasons something was at a limit,
    empty when nothing was), ``reach_gaps`` (per sample: how far the controller's IK target was out of reach
    [m], 0 when it was not), the run's ``t_start``/``t_end`` [s], the load change times [s] (None: unknown
    — the whole run is one period).  See the module docstring for the definitions."""
    t = np.asarray(times, float)
    e = np.asarray(errors, float)
    te = np.asarray(true_errors, float) if len(true_errors) == len(t) else np.full(len(t), np.nan)
    known = load_changes is not None
    reach = (np.array(["reach" in r for r in saturation], bool) if len(saturation) == len(t)
             else np.zeros(len(t), bool))
    gaps = np.asarray(reach_gaps, float) if len(reach_gaps) == len(t) else np.full(len(t), np.nan)
    cuts = sorted(float(c) for c in (load_changes or ()) if t_start < c < t_end)
    bounds = [t_start, *cuts, max(t_end, t_start)]
    periods = []
    for i in range(len(bounds) - 1):
        a, b = bounds[i], bounds[i + 1]
        last = i == len(bounds) - 2
        sel = (t >= a) & ((t <= b) if last else (t < b))
        half = a + 0.5 * (b - a)
        st = sel & (t >= half)
        p = LoadPeriod(a, b, "run end" if last else "load change", int(sel.sum()), int(st.sum()))
        if p.settled_samples:
            es, ts = e[st], te[st]
            p.settled_error, p.settled_max_error = float(np.median(es)), float(np.max(es))
            if np.all(np.isfinite(ts)):
                p.true_settled_error, p.true_settled_max_error = float(np.median(ts)), float(np.max(ts))
        longest_before = max((q.end - q.start for q in periods), default=0.0)
        if last and periods and (b - a) < 0.5 * longest_before:
            p.note = "cut short by the end of the run"
        elif not p.settled_samples:
            p.note = "no samples in its settled half"
        elif np.all(reach[st]):
            p.out_of_reach = True
            p.reach_gap = float(np.median(gaps[st]))
            p.note = ("out of reach: saturated throughout its settled half" if not math.isfinite(p.reach_gap) else
                      f"out of reach by {p.reach_gap * 1e3:.3f} mm: saturated throughout its settled half")
        else:
            p.judged = True
            p.within_tolerance = bool(p.settled_error < tolerance)
        periods.append(p)
    sat = {k: 0.0 for k in SATURATION_REASONS}
    n_sat, total = 0, 0.0
    for i, reasons in enumerate(saturation):
        if not reasons:
            continue
        n_sat += 1
        dt = (t[i + 1] if i + 1 < len(t) else max(t_end, t[i])) - t[i]
        total += dt
        for r in reasons:
            sat[r] = sat.get(r, 0.0) + dt
    return RunSummary(tolerance=float(tolerance), periods=periods, load_changes_known=known, saturation=sat,
                      saturation_time=float(total), saturated_samples=n_sat, faults=list(faults),
                      corrections=int(corrections), duration=float(t_end - t_start), samples=len(t))
