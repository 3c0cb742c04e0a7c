"""How exact is each compliance form?  Every form against finite differences of the nonlinear solvers.

For a grid of states (tensions × pressures) of a model, and several load directions u:

* constant tension: C_p u vs the central difference of FK at constant tension (F = ±h u);
* locked (``exact``, ``paper`` eq. 13, ``ik`` eq. 15/16): C'_p u vs the one-sided second-order
  difference of the locked-length FK along +u (the locked response is piecewise linear in the load: which
  tendons stay taut depends on the load direction, so a central difference across the kink is not a
  derivative).

The relative error is ‖C u − FD‖ / ‖FD‖; the directional stiffness along u is 1/(uᵀ C u).

Findings on the ``paper`` preset (``python -m validation.checks.compliance_check``; 6 states × 3 directions):

* constant tension (eqs. 8–10) is exact: max relative error ≈ 7e-8 (the FD's own error);
* locked ``exact`` (KKT with the LCP active set) is exact: ≈ 1e-4 (the one-sided FD's truncation);
* locked ``paper`` (eq. 13) and ``ik`` (eqs. 15/16) as written — stacked rows, SVD pseudo-inverse, no
  weighting — come out within ~1–10 % of the *constant-tension* compliance, i.e. they miss the
  stiffening by locking (errors 190–570 % against the locked response).  Weighting the constraint rows
  does not fix this: eq. (13) saturates at ≈ 3.5× the locked stiffness for large weights (a constrained
  least-squares solution, not the KKT one), and eq. (15)'s tip rows then forbid any tip motion (stiffness
  → ∞).  The weighting is therefore a free parameter of the paper's forms; use ``exact`` for predictions.
"""

from __future__ import annotations

import itertools
import json
import pathlib
from typing import Iterable, Optional, Sequence

import numpy as np

from ancf import Model, presets
from ancf import compliance as cp

DIRECTIONS = {"-z (gravity)": (0.0, 0.0, -1.0), "+y": (0.0, 1.0, 0.0), "-x (axial push)": (-1.0, 0.0, 0.0)}


def fd_tension(model: Model, eq, u, h: float = 2e-3) -> np.ndarray:
    """Central difference of the constant-tension FK tip along load direction u [m/N]."""
    f = lambda s: model.fk(eq.tensions, eq.pressure, eq.tip_force + s * u, q0=eq.q).tip
    return (f(h) - f(-h)) / (2 * h)


def fd_locked(model: Model, eq, u, h: float = 1e-3) -> np.ndarray:
    """One-sided second-order (Richardson) difference of the locked FK along +u [m/N]."""
    def f(s):
        return model.fk_locked(model.rest_lengths(eq), eq.pressure, eq.tip_force + s * u, q0=eq.q,
                               tensions0=eq.tensions).tip
    return (4 * (f(h) - eq.tip) / h - (f(2 * h) - eq.tip) / (2 * h)) / 3


def compare(model: Optional[Model] = None, tensions: Iterable[Sequence[float]] = ((0, 0, 0), (2, 0, 0), (3, 0.5, 1)),
            pressures: Iterable[float] = (0.0, 50e3), directions: Optional[dict] = None) -> list[dict]:
    """Rows {state, direction, form, rel_error, stiffness_N_per_m, fd_stiffness_N_per_m, active}."""
    model = model or Model(presets.paper())
    directions = directions or DIRECTIONS
    rows = []
    for T, p in itertools.product(tensions, pressures):
        eq = model.fk(T, p)
        for dname, u in directions.items():
            u = np.asarray(u, float) / np.linalg.norm(u)
            forms = {"tension": (cp.tension(model, eq), fd_tension(model, eq, u))}
            fdl = fd_locked(model, eq, u)
            for method in ("exact", "paper", "ik"):
                forms[f"locked/{method}"] = (cp.locked(model, eq, method, load_direction=u), fdl)
            for form, (C, fd) in forms.items():
                cu = C.C_p @ u
                rows.append({
                    "tensions_N": list(map(float, T)), "pressure_Pa": float(p), "direction": dname, "form": form,
                    "rel_error": float(np.linalg.norm(cu - fd) / np.linalg.norm(fd)),
                    "stiffness_N_per_m": float(1.0 / (u @ cu)), "fd_stiffness_N_per_m": float(1.0 / (u @ fd)),
                    "active": list(C.active)})
    return rows


def summary(rows: list[dict]) -> dict:
    """Worst and median relative error per form."""
    out = {}
    for form in dict.fromkeys(r["form"] for r in rows):
        e = np.array([r["rel_error"] for r in rows if r["form"] == form])
        out[form] = {"max_rel_error": float(e.max()), "median_rel_error": float(np.median(e)), "cases": int(e.size)}
    return out


def run(out: Optional[pathlib.Path] = None, model: Optional[Model] = None) -> dict:
    rows = compare(model)
    res = {"rows": rows, "summary": summary(rows)}
    if out is not None:
        out = pathlib.Path(out)
        out.mkdir(parents=True, exist_ok=True)
        (out / "compliance_check.json").write_text(json.dumps(res, indent=2))
    return res


if __name__ == "__main__":  # pragma: no cover
    r = run()
    for form, s in r["summary"].items():
        print(f"{form:>14}: max rel. error {s['max_rel_error']:.2e}, median {s['median_rel_error']:.2e} "
              f"({s['cases']} cases)")
