"""Tip error vs the number of elements n (paper Sec. V-A: "the error decreases from 6.1 to 0.3 mm when the
element number n increased from 1 to 6").

The paper gives neither the states nor the reference of its check.  Here: for each n the FK of a fixed
set of states is solved with ``n_elements = n`` (everything else of the preset unchanged), and the error
is the largest tip distance over the states from the same states solved with ``n_ref`` elements
(default 16).  The default states bend the actuator as far as the inputs allow in each mode:
T1 = T_max at p = 0 (largest TD bend), T1 = T_max at p_max/2, and two tendons at T_max at p = 0.

The ANCF cubic Hermite element is C¹; for a smooth solution the tip error falls like n^-r, and ``rate``
is the least-squares slope of log(error) over log(n) from n = 2 on (a closed-form check of the
discretisation lives in the tests).
"""

from __future__ import annotations

from typing import Optional, Sequence

import numpy as np

from ancf import Model
from ancf.errors import BellowsError

from validation.paper.common import ParamsLike, resolve_params

PAPER_CONVERGENCE = {"n": (1, 6), "tip_error_mm": (6.1, 0.3)}


def default_states(params) -> list[tuple[tuple[float, ...], float]]:
    """(tensions [N], pressure [Pa]) of the default states (module docstring)."""
    tmax, m = params.tension_max, params.n_tendons
    one = tuple([tmax] + [0.0] * (m - 1))
    two = tuple([tmax, tmax] + [0.0] * (m - 2))
    return [(one, 0.0), (one, 0.5 * params.pressure_max), (two, 0.0)]


def element_convergence(params: ParamsLike = None, n_values: Sequence[int] = (1, 2, 3, 4, 5, 6, 8),
                        n_ref: int = 16, states: Optional[Sequence] = None) -> dict:
    """``{"n": [...], "tip_error_m": [...] (max over the states), "per_state_m": (n_n, n_states),
    "rate", "states", "failures"}``; a state whose solve fails at some n gives NaN there and is listed."""
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
    err = np.nanmax(per, axis=1)
    n_arr = np.asarray(n_values, float)
    sel = (n_arr >= 2) & np.isfinite(err) & (err > 0)
    rate = float(-np.polyfit(np.log(n_arr[sel]), np.log(err[sel]), 1)[0]) if sel.sum() >= 2 else float("nan")
    return {"study": "tip error vs number of elements (paper Sec. V-A)", "preset": prm.name,
            "n": [int(n) for n in n_values], "n_ref": n_ref, "tip_error_m": err, "per_state_m": per,
            "states": [{"tensions_N": list(T), "pressure_Pa": p} for T, p in states], "rate": rate,
            "failures": failures, "paper": PAPER_CONVERGENCE}
