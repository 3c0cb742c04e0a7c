"""Tip error vs the number of elements n (paper Sec. V-A: "the error decreases from 6.1 to 0.3 mm when the
element number n increased from 1 to 6").

The paper gives neither the states nor the reference of its check.  Here: for each n the FK of a fixed
set of states is solved with ``n_elements = n`` (everything else of the preset unchanged), and the error
is the largest tip distance over the states from the same states solved with ``n_ref`` elements
(default 16).  The default states bend the actuator as far as the inputs allow in each mode:
T1 = T_max at p = 0 (largest TD bend), T1 = T_max at p_max/2, and two tendons at T_max at p = 0.

The ANCF cubic Hermite element is C¹; for a smooth solution the tip error falls like n^-r, and ``rate``
is the least-squares slope of log(error) over log(n) from n = 2 on, over the n at which every state
solved (``rate_n``; a closed-form check of the discretisation lives in the tests).

A coarse mesh may find no equilibrium for a state the reference solves (e.g. two tendons at T_max at
n = 1, 2 on the ``paper`` preset: the coarse rod's equilibrium path ends at a limit point just short of
the full load).  Such a solve is listed in ``failures`` with the solver's message, and the error at that
n is the largest over the *other* states only — a lower bound of the study's error there (``complete``
is False for it); :func:`failure_notes` says so in words.  ``bellows paper convergence`` writes
``convergence.json`` and a log-log figure of the error vs n with the fitted slope (``FILES``).
"""

from __future__ import annotations

from typing import Optional, Sequence

import numpy as np

from ancf import Model
from ancf.errors import BellowsError

from validation.paper.common import ParamsLike, resolve_params

PAPER_CONVERGENCE = {"n": (1, 6), "tip_error_mm": (6.1, 0.3)}
#: files ``bellows paper convergence`` writes into its output folder
FILES = ("convergence.json", "convergence.png", "convergence.svg")


def default_states(params) -> list[tuple[tuple[float, ...], float]]:
    """(tensions [N], pressure [Pa]) of the default states (module docstring)."""
    tmax, m = params.tension_max, params.n_tendons
    one = tuple([tmax] + [0.0] * (m - 1))
    two = tuple([tmax, tmax] + [0.0] * (m - 2))
    return [(one, 0.0), (one, 0.5 * params.pressure_max), (two, 0.0)]


def element_convergence(params: ParamsLike = None, n_values: Sequence[int] = (1, 2, 3, 4, 5, 6, 8),
                        n_ref: int = 16, states: Optional[Sequence] = None) -> dict:
    """``{"n": [...], "tip_error_m": [...] [m] (max over the states), "per_state_m": (n_n, n_states) [m],
    "complete": [...] (every state solved at that n), "rate", "rate_n", "states", "failures", "notes"}``; a
    state whose solve fails at some n gives NaN there and is listed in ``failures`` and ``notes``."""
    prm = resolve_params(params)
    states = list(states) if states is not None else default_states(prm)
    ref = Model(prm.replace(n_elements=n_ref))
    tips_ref = [ref.fk(T, p).tip for T, p in states]
    per = np.full((len(n_values), len(states)), np.nan)
    failures = []
    for i, n in enumerate(n_values):
        model = Model(prm.replace(n_elements=int(n)))
        for j, (T, p) in enumerate(states):
            try:
                per[i, j] = np.linalg.norm(model.fk(T, p).tip - tips_ref[j])
            except BellowsError as exc:
                failures.append({"n": int(n), "state": j, "error": f"{type(exc).__name__}: {exc}"})
    err = np.array([np.nanmax(row) if np.isfinite(row).any() else np.nan for row in per])
    complete = np.isfinite(per).all(axis=1)
    n_arr = np.asarray(n_values, float)
    sel = (n_arr >= 2) & complete & (err > 0)
    rate = float(-np.polyfit(np.log(n_arr[sel]), np.log(err[sel]), 1)[0]) if sel.sum() >= 2 else float("nan")
    res = {"study": "tip error vs number of elements (paper Sec. V-A)", "preset": prm.name,
           "n": [int(n) for n in n_values], "n_ref": n_ref, "tip_error_m": err, "per_state_m": per,
           "complete": complete.tolist(), "states": [{"tensions_N": list(T), "pressure_Pa": p} for T, p in states],
           "rate": rate, "rate_n": [int(n) for n in n_arr[sel]], "failures": failures, "paper": PAPER_CONVERGENCE}
    res["notes"] = failure_notes(res)
    return res


def failure_notes(res: dict) -> list[str]:
    """Sentences saying which (n, state) solves failed, the solver's reason, and what that does to the numbers
    of :func:`element_convergence`'s result ``res`` (the error at that n is a lower bound; the rate leaves it out)."""
    notes = []
    for f in res["failures"]:
        st = res["states"][f["state"]]
        T = ", ".join(f"{t:g}" for t in st["tensions_N"])
        notes.append(f"n = {f['n']}: state {f['state']} (T = ({T}) N, p = {st['pressure_Pa'] / 1e3:g} kPa) has no "
                     f"equilibrium on this mesh — {f['error']}")
    partial = [n for n, ok in zip(res["n"], res["complete"]) if not ok]
    if partial:
        ns = ", ".join(map(str, partial))
        notes.append(f"so the tip error at n = {ns} is the largest over the states that solved, a lower bound of "
                     f"the error over all states, and the rate ({res['rate']:.2f}) is fitted over n = "
                     f"{', '.join(map(str, res['rate_n'])) or 'none'} only (every state solved there)")
    return notes
