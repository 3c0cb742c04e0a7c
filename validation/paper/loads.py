"""Loading checks of the paper's experiments (Sec. V-D/E) that need no controller, and the IK time.

* ``locked_drift`` — the motors hold the tendon lengths of an unloaded configuration and a payload is
  hung at the tip: the tip moves by the drift (paper, continuous loading: "the uncontrolled tip drifts by
  over 10 mm" at 110 g).  Nonlinear locked FK, not a linearisation.
* ``hold_payload`` — can the actuator hold its unloaded tip position under a payload with tensions
  inside the limits?  IK with the payload, solved once with the preset's limits and once with the upper
  limit raised (to report what it would need).  A statics bound: a tendon at distance d holds at most a
  moment T_max d about the section, so 5 N × 27.5 mm = 0.14 N m < the moment of 100 g at 0.15 m.
  A configuration not held even with the raised limit reports no needed tension (NaN), with the solver's reason
  (e.g. the target needs a tendon to push: T < 0).
* ``ik_time`` — wall time of cold and warm IK solves (paper: 2.95 s per IK at n = 6 in MATLAB).

The configurations are the controller studies' (same actuation inputs on every preset; the resulting
tip angle is reported, since a softer reading bends further under the same inputs).  ``bellows paper loads``
writes the three results to ``loads.json`` (``FILES``).
"""

from __future__ import annotations

import statistics
import time
from typing import Optional

import numpy as np

from ancf import Model
from ancf.errors import BellowsError, InfeasibleTargetError

from validation.paper.numbers import LOADING as PAPER_LOADING
from validation.paper.common import G, ParamsLike, resolve_params

#: (tensions [N], pressure [Pa]) of the controller studies' configurations.
CONFIGURATIONS = {"upward": ((3.4, 1.2, 1.2), 60e3), "horizontal": ((2.2, 1.6, 1.6), 60e3),
                  "downward": ((0.8, 3.0, 3.0), 60e3)}
LOADING_CONFIGURATION = ((1.6, 2.2, 2.2), 60e3)
#: files ``bellows paper loads`` writes into its output folder
FILES = ("loads.json",)


def tip_angle_deg(eq) -> float:
    """Elevation of the tip tangent above the horizontal [deg] (gravity along −z)."""
    t = eq.tip_rotation[:, 0]
    return float(np.degrees(np.arcsin(np.clip(t[2] / np.linalg.norm(t), -1, 1))))


def locked_drift(params: ParamsLike = None, mass: float = 0.110,
                 configuration=LOADING_CONFIGURATION) -> dict:
    """Tip displacement [m] when ``mass`` [kg] hangs at the tip of the locked ``configuration``."""
    prm = resolve_params(params)
    model = Model(prm)
    T, p = configuration
    eq0 = model.fk(T, p)
    F = np.array([0.0, 0.0, -mass * G])
    lk = model.fk_locked(model.rest_lengths(eq0), p, F, q0=eq0.q, tensions0=eq0.tensions)
    d = lk.tip - eq0.tip
    return {"preset": prm.name, "mass_kg": mass, "tensions_N": list(T), "pressure_Pa": p,
            "tip_angle_deg": tip_angle_deg(eq0), "drift_m": float(np.linalg.norm(d)), "displacement_m": d,
            "locked_tensions_N": lk.tensions,
            "paper_drift_mm_more_than": PAPER_LOADING["continuous_uncontrolled_drift_mm"]}


def hold_payload(params: ParamsLike = None, mass: float = 0.100,
                 configurations: Optional[dict] = None, relaxed_tension_max: float = 50.0) -> dict:
    """Per configuration: ``held`` (IK with the payload feasible within the tension limits),
    ``tensions_needed_N`` (IK with the upper limit raised to ``relaxed_tension_max``; None if even that
    fails), ``max_tension_needed_N`` and the unloaded ``tip_angle_deg``; ``reason`` / ``relaxed_error`` hold the
    solver's message when a solve fails (:func:`hold_notes` puts them in sentences)."""
    prm = resolve_params(params)
    model = Model(prm)
    relaxed = Model(prm.replace(tension_max=relaxed_tension_max))
    F = np.array([0.0, 0.0, -mass * G])
    out = {"preset": prm.name, "mass_kg": mass, "tension_min_N": prm.tension_min, "tension_max_N": prm.tension_max,
           "configurations": {}}
    for name, (T, p) in (configurations or CONFIGURATIONS).items():
        eq0 = model.fk(T, p)
        row = {"tensions_N": list(T), "pressure_Pa": p, "tip_angle_deg": tip_angle_deg(eq0)}
        try:
            model.ik(eq0.tip, p, F, q0=eq0.q, tensions0=eq0.tensions)
            row["held"] = True
        except InfeasibleTargetError as exc:
            row["held"] = False
            row["reason"] = str(exc)
        except BellowsError as exc:
            row["held"] = None
            row["error"] = f"{type(exc).__name__}: {exc}"
        try:
            need = relaxed.ik(eq0.tip, p, F, q0=eq0.q, tensions0=eq0.tensions)
            row["tensions_needed_N"] = need.tensions
            row["max_tension_needed_N"] = float(need.tensions.max())
        except BellowsError as exc:
            row["tensions_needed_N"] = None
            row["max_tension_needed_N"] = float("nan")
            row["relaxed_error"] = f"{type(exc).__name__}: {exc}"
        out["configurations"][name] = row
    out["relaxed_tension_max_N"] = relaxed_tension_max
    return out


def hold_notes(res: dict) -> list[str]:
    """Sentences for the configurations of :func:`hold_payload`'s result ``res`` that are not held or whose
    needed tensions are unknown: the solver's reason, and what it means for the numbers (no needed tension
    is reported: NaN / null)."""
    notes = []
    hi = res.get("relaxed_tension_max_N", 50.0)
    for name, row in res["configurations"].items():
        if row.get("held") is None:
            notes.append(f"{name}: the IK with the payload failed ({row['error']}); held is unknown")
        elif not row["held"]:
            notes.append(f"{name}: not held within [{res.get('tension_min_N', 0):g}, {res['tension_max_N']:g}] N — "
                         f"{row['reason']}")
        if row["tensions_needed_N"] is None:
            notes.append(f"{name}: not held even with tensions up to {hi:g} N, so no needed tension is reported "
                         f"(max_tension_needed_N is NaN): {row['relaxed_error']}")
    return notes


def ik_time(params: ParamsLike = None, repeats: int = 5, configurations: Optional[dict] = None) -> dict:
    """Median wall time [s] of cold IK solves (from the straight state) and warm ones (from the solution
    of a neighbouring target 1 mm away) to the configurations' tips."""
    prm = resolve_params(params)
    model = Model(prm)
    cold, warm = [], []
    for T, p in (configurations or CONFIGURATIONS).values():
        eq = model.fk(T, p)
        model.ik(eq.tip, p)                       # compile / cache outside the clock
        for _ in range(repeats):
            t0 = time.perf_counter()
            model.ik(eq.tip, p)
            cold.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            model.ik(eq.tip + np.array([0.0, 1e-3, 0.0]), p, q0=eq.q, tensions0=eq.tensions)
            warm.append(time.perf_counter() - t0)
    return {"preset": prm.name, "n_elements": prm.n_elements, "cold_s": statistics.median(cold),
            "warm_s": statistics.median(warm), "solves": len(cold), "paper_s": 2.95}
