r"""Calibrate an FEM bellows design to target rod values (EA, EI, D_eff): an outer fit over its dimensions.

A lab with measured rod values (or a reading of the paper's law) wants an FEM of a *plausible* bellows that
has them.  :func:`calibrate` adjusts chosen geometry/material parameters within physical bounds so that the
FEM's quick rod measures match the targets, in the least-squares sense of the log-ratios

    r = [log(EA/EA*), log(EI/EI*), log(D_eff/D_eff*)]     (D_a = √(8 EI/EA) follows from EA and EI).

Quick rod measures of one design (:func:`rod_measures`, one FEM model, two solves):

* EA, EI from the condensed cap tangent of the unloaded FEM (pure axial force, pure moment);
* D_eff as the *secant* pressure diameter at ``p_mid`` (default half the pressure range): the free
  elongation λ under p_mid with no tendon load gives the axial force that the reduced model's axial law
  needs for that stretch, F = ½ EA (λ³ − λ) (Green strain), and A_eff = F / p_mid, D_eff = √(4 A_eff/π).
  This matches what the full identification fits over the pressure range better than the blocked-force
  area at p = 0 (the FEM's pressure area grows with pressure).

The search is Levenberg–Marquardt in the logarithms of the free parameters, with a forward-difference
Jacobian whose columns run in parallel (:func:`validation.infra.runner.run_tasks`, cached).  A design the
geometry rejects (convolutions too tight for the wall) is an infeasible step: the damping grows.  The full
identification (:func:`validation.identification.identify.from_fem`) of the calibrated design reports the remaining
mismatch honestly; the calibration itself reports its own.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Optional

import numpy as np

from ancf.errors import BellowsError, ConfigError, InputError

from validation.reference.fem_sweep import fem_fingerprint
from validation.infra.runner import ResultCache, run_tasks, source_fingerprint

__all__ = ["CalibrationResult", "calibrate", "rod_measures", "GEOMETRY_PARAMETERS", "MATERIAL_PARAMETERS"]

#: Geometry fields a calibration may adjust (continuous) and material fields ("mu": κ scales along).
GEOMETRY_PARAMETERS = ("wall_thickness", "root_radius", "crest_radius", "collar_length")
MATERIAL_PARAMETERS = ("mu",)
TARGET_KEYS = ("EA", "EI", "D_eff")


def _apply(geometry, material, names, values):
    g_changes = {n: float(v) for n, v in zip(names, values) if n in GEOMETRY_PARAMETERS}
    geo = geometry.replace(**g_changes) if g_changes else geometry
    mat = material
    for n, v in zip(names, values):
        if n == "mu":                    # κ/μ and c01/μ kept: the same material law, scaled
            s = float(v) / material.mu
            mat = replace(material, mu=float(v), kappa=material.kappa * s, c01=material.c01 * s)
    return geo, mat


def rod_measures(task: dict) -> dict:
    """Worker: quick rod measures of one design (see the module docstring).  ``task``: geometry, material,
    mesh, p_mid [Pa].  Returns EA [N], EI [N m²], D_a [m], D_eff [m] (secant at p_mid), D_eff_blocked [m],
    stretch_mid [-]; or {"error": message} if the design cannot be built or solved."""
    from fem_reference import BellowsModel
    try:
        model = BellowsModel(task["geometry"], task["material"], mesh=task["mesh"])
        rod = model.equivalent_rod()
        p = float(task["p_mid"])
        res = model.solve(pressure=p)
    except BellowsError as exc:
        return {"error": f"{type(exc).__name__}: {exc}"}
    L = task["geometry"].length
    lam = float(res.tip_position[0] - model.geometry.tip_offset) / L
    F = 0.5 * rod["EA"] * (lam ** 3 - lam)
    A = F / p if p > 0 else float("nan")
    return {"EA": float(rod["EA"]), "EI": float(rod["EI"]), "D_a": float(rod["D_a"]),
            "D_eff": math.sqrt(4 * A / math.pi) if A > 0 else float("nan"), "D_eff_blocked": float(rod["D_eff"]),
            "stretch_mid": lam, "EI_tip_force": float(rod["EI_tip_force"])}


@dataclass
class CalibrationResult:
    """Outcome of :func:`calibrate`.

    geometry, material : the calibrated design;  names / values : the free parameters and their values (SI);
    measures : the design's quick rod measures;  target : what was asked;  mismatch_pct : {key: 100 (v/v* − 1)};
    history : one row per evaluated design;  converged : whether the log-ratio norm fell below ``tol``.
    """
    geometry: object
    material: object
    names: tuple
    values: tuple
    measures: dict
    target: dict
    mismatch_pct: dict
    history: list = field(default_factory=list)
    converged: bool = False


def calibrate(target: dict, geometry, material, free: dict, *, mesh: str = "coarse", p_mid: float = 60e3,
              workers: Optional[int] = None, cache_dir=None, max_iter: int = 12, tol: float = 0.01,
              progress: bool = True, weights: Optional[dict] = None) -> CalibrationResult:
    """Adjust the ``free`` parameters ({name: (low, high)} in SI; names from :data:`GEOMETRY_PARAMETERS` and
    :data:`MATERIAL_PARAMETERS`) of ``geometry``/``material`` so that the FEM's quick rod measures match
    ``target`` ({"EA": N, "EI": N m², "D_eff": m}; a missing key is not fitted).  ``tol``: stop when the RMS
    log-ratio is below it (0.01 ≈ 1 %)."""
    keys = [k for k in TARGET_KEYS if k in target]
    if not keys:
        raise InputError(f"calibrate: target needs at least one of {TARGET_KEYS}, got {sorted(target)}")
    for k in keys:
        if not (isinstance(target[k], (int, float)) and target[k] > 0 and math.isfinite(target[k])):
            raise InputError(f"calibrate: target {k} must be a positive number, got {target[k]!r}")
    names = tuple(free)
    if not names:
        raise InputError("calibrate: no free parameter given")
    for n in names:
        if n not in GEOMETRY_PARAMETERS + MATERIAL_PARAMETERS:
            raise InputError(f"calibrate: cannot adjust {n!r}; choose from {GEOMETRY_PARAMETERS + MATERIAL_PARAMETERS}")
        lo, hi = free[n]
        if not (0 < lo < hi):
            raise InputError(f"calibrate: bounds of {n} must satisfy 0 < low < high, got {free[n]}")
    fixed = [n for n in names if n in GEOMETRY_PARAMETERS] if getattr(geometry, "is_table", False) else []
    if fixed:
        raise InputError(f"calibrate: cannot adjust {', '.join(fixed)} of a design whose wall profile is a table "
                         f"({geometry.profile.source or 'profile_file'}): the wall's shape is the table's (change the "
                         f"table instead); adjust {', '.join(MATERIAL_PARAMETERS)}")
    w = np.array([(weights or {}).get(k, 1.0) for k in keys])
    lo = np.log([free[n][0] for n in names])
    hi = np.log([free[n][1] for n in names])
    start = [getattr(geometry, n) if n in GEOMETRY_PARAMETERS else getattr(material, n) for n in names]
    x = np.clip(np.log(start), lo, hi)
    cache = None if cache_dir is None else ResultCache(cache_dir, "calib-" + fem_fingerprint()
                                                       + source_fingerprint(files=("validation.identification.calibrate",)))
    history: list = []

    def evaluate(xs: list) -> list:
        tasks = []
        for xi in xs:
            try:
                geo, mat = _apply(geometry, material, names, np.exp(xi))
                tasks.append({"geometry": geo, "material": mat, "mesh": mesh, "p_mid": p_mid})
            except (ConfigError, InputError) as exc:
                tasks.append({"invalid": str(exc)})
        valid = [i for i, t in enumerate(tasks) if "invalid" not in t]
        out = [{"error": tasks[i]["invalid"]} if "invalid" in tasks[i] else None for i in range(len(xs))]
        if valid:
            res = run_tasks(rod_measures, [tasks[i] for i in valid], workers=workers, progress=progress,
                            description="calibration (FEM rod measures)", cache=cache,
                            key_inputs=lambda t: {k: t[k] for k in ("geometry", "material", "mesh", "p_mid")})
            for i, r in zip(valid, res.results):
                out[i] = r
        for xi, r in zip(xs, out):
            history.append({"parameters": dict(zip(names, np.exp(xi).tolist())), **r})
        return out

    def resid(meas: dict) -> Optional[np.ndarray]:
        if "error" in meas or not all(math.isfinite(meas.get(k, float("nan"))) and meas[k] > 0 for k in keys):
            return None
        return w * np.log([meas[k] / target[k] for k in keys])

    cur = evaluate([x])[0]
    r = resid(cur)
    if r is None:
        raise ConfigError(f"calibrate: the starting design cannot be evaluated: {cur.get('error', cur)}")
    mu = 1e-2
    converged = False
    for _ in range(max_iter):
        if np.sqrt(np.mean(r ** 2)) < tol:
            converged = True
            break
        h = 0.02
        xs = []
        for j in range(len(x)):
            xp = x.copy()
            xp[j] = xp[j] + h if xp[j] + h <= hi[j] else xp[j] - h
            xs.append(xp)
        cols = evaluate(xs)
        J = np.zeros((len(keys), len(x)))
        for j, (xp, m) in enumerate(zip(xs, cols)):
            rp = resid(m)
            J[:, j] = 0.0 if rp is None else (rp - r) / (xp[j] - x[j])
        improved = False
        for _ in range(6):
            A = J.T @ J + mu * np.diag(np.diag(J.T @ J) + 1e-12)
            step = np.linalg.lstsq(A, -J.T @ r, rcond=None)[0]
            x_new = np.clip(x + step, lo, hi)
            m_new = evaluate([x_new])[0]
            r_new = resid(m_new)
            if r_new is not None and r_new @ r_new < r @ r:
                x, r, cur, improved = x_new, r_new, m_new, True
                mu = max(mu / 3, 1e-6)
                break
            mu *= 4
        if not improved:
            break
    geo, mat = _apply(geometry, material, names, np.exp(x))
    mismatch = {k: 100 * (cur[k] / target[k] - 1) for k in keys}
    return CalibrationResult(geo, mat, names, tuple(np.exp(x).tolist()), cur, dict(target), mismatch, history,
                             converged or bool(np.sqrt(np.mean(r ** 2)) < tol))
