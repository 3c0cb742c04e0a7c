"""State diagnostics shared by the studies: where a stiffness law stops being valid, and whether a state
(returned or not) is *collapsed*.

A linear law EA(λ) = a λ + b reaches zero at λ₀ = −b/a (0.426 for the paper's k(λ)).  Long before that the
axial force of the rod, N(λ) = W'(λ) = ½ EA(λ)(λ³ − λ), passes a largest compression
N_c = −min N(λ) at λ_c (where N'(λ) = 0): below λ_c the axial tangent stiffness is negative, so a state
with a section shorter than λ_c is unstable, and a compressive section force above N_c has no equilibrium
at all.  For the unloaded actuator the normal force of every cross-section is exactly
N = p A(λ) − Σ T_i (the tendons pull along the centreline and the pressure pushes on the cap; gravity aside),
so the inputs alone say whether the tendons collapse it:

* ``collapsed`` — a returned state with min λ ≤ λ_c somewhere (past the limit point, including λ ≤ λ₀),
  a :class:`~ancf.errors.CollapsedStateError`, or a failed solve whose inputs compress the rod by more
  than N_c (Σ T − p A_eff > N_c: no equilibrium exists);
* ``failed`` — any other failed solve.

Samples in either class are counted and reported, never dropped silently.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from ancf import ActuatorParams, Model
from ancf.errors import ConfigError


def stretches(model: Model, q) -> np.ndarray:
    """Stretch λ = |r_x| at every quadrature point of every element: array (n · n_gauss,)."""
    qn = np.asarray(q, float).reshape(-1, 6)
    N1 = model._N[:, 1, :]                                  # (n_gauss, 4) derivative shape functions
    out = []
    for e in range(model.n):
        B = np.array([qn[e, :3], qn[e, 3:], qn[e + 1, :3], qn[e + 1, 3:]])
        out.append(np.linalg.norm(N1 @ B, axis=1))
    return np.concatenate(out)


def _law_key(params: ActuatorParams):
    return tuple(params.stiffness.EA_coeffs), tuple(params.stiffness.EI_coeffs)


@lru_cache(maxsize=64)
def _limits(ea: tuple, ei: tuple) -> dict:
    P = np.polynomial.polynomial
    zeros = []
    for c in (ea, ei):
        r = P.polyroots(np.asarray(c, float)) if len(c) > 1 else np.array([])
        r = r[np.abs(r.imag) < 1e-12].real
        r = r[(r > 0) & (r < 1)]
        zeros.append(float(r.max()) if r.size else 0.0)
    lam0 = max(zeros)
    # axial force N(λ) = ½ EA(λ)(λ³ − λ) as a polynomial; its stationary point in (λ0, 1) is λ_c
    n_poly = P.polymul(np.asarray(ea, float), [0.0, -0.5, 0.0, 0.5])
    crit = P.polyroots(P.polyder(n_poly))
    crit = crit[np.abs(crit.imag) < 1e-12].real
    crit = crit[(crit > lam0) & (crit < 1)]
    grid = np.linspace(max(lam0, 1e-3), 1.0, 2001)
    vals = P.polyval(grid, n_poly)
    if crit.size:
        lam_c = float(crit.max())
        n_c = float(-P.polyval(lam_c, n_poly))
    else:                                                   # monotonic on (λ0, 1): the weakest end
        i = int(np.argmin(vals))
        lam_c, n_c = float(grid[i]), float(-vals[i])
    return {"zero_stretch": lam0, "critical_stretch": lam_c, "max_compression_N": n_c}


def law_limits(params: ActuatorParams) -> dict:
    """``zero_stretch`` λ₀ (largest zero of EA or EI in (0, 1); 0 if none), ``critical_stretch`` λ_c and
    ``max_compression_N`` N_c [N] of the preset's stiffness law (module docstring)."""
    return dict(_limits(*_law_key(params)))


def axial_compression(params: ActuatorParams, tensions, pressure: float) -> float:
    """Σ T − p A_eff [N]: the compressive normal force of every section of the unloaded straight-area rod."""
    return float(np.sum(tensions) - pressure * params.A_eff)


def weight_bound(params: ActuatorParams) -> float:
    """Largest axial force the self-weight and tip mass can add to a section [N]: (m' L + m_tip)|g|."""
    return float((params.line_mass * params.length + params.tip_mass) * np.linalg.norm(params.gravity))


def certainly_collapsed(params: ActuatorParams, tensions, pressure: float) -> bool:
    """True when no equilibrium can exist: Σ T − p A_eff exceeds N_c by more than the weight can carry
    (constant pressure area, or p = 0).  Such samples need no solve."""
    if params.pressure_area_slope != 0.0 and pressure != 0.0:
        return False
    T = np.asarray(tensions, float)
    if np.any(T < params.tension_min) or np.any(T > params.tension_max) \
            or not (params.pressure_min <= pressure <= params.pressure_max):
        return False                          # out-of-limit inputs are the model's to reject
    limit = law_limits(params)["max_compression_N"] + weight_bound(params)
    return axial_compression(params, tensions, pressure) > limit


def near_limit(params: ActuatorParams, tensions, pressure: float, fraction: float = 0.85) -> bool:
    """Σ T − p A_eff above ``fraction`` of N_c: a bent section reaches the limit point earlier (EI(λ) adds
    to the axial force), so failed solves here are most likely collapses the straight-rod bound cannot
    certify."""
    return axial_compression(params, tensions, pressure) > fraction * law_limits(params)["max_compression_N"]


def state_collapsed(model: Model, q) -> bool:
    """True if some section of the state is at or past the law's limit point (λ ≤ λ_c)."""
    return bool(stretches(model, q).min() <= law_limits(model.params)["critical_stretch"])


def failure_is_collapse(params: ActuatorParams, tensions, pressure: float, exc: BaseException) -> bool:
    """A failed solve counts as collapsed if the model said so, or if its inputs compress the rod by more
    than the law can carry (no equilibrium exists)."""
    from ancf.errors import CollapsedStateError, InputError
    if isinstance(exc, CollapsedStateError):
        return True
    if isinstance(exc, InputError):           # rejected inputs are failures, whatever their load
        return False
    return axial_compression(params, tensions, pressure) > law_limits(params)["max_compression_N"]


def reading_facts(params: ActuatorParams, *, pressure: float = 120e3, compression: float = 15.0) -> dict:
    """What a reading implies for a straight, weightless rod: EA(1), EI(1), the stretch under the full
    pressure (p A_eff) and under the full tendon compression (``compression`` [N]), and the law's limits."""
    law = params.stiffness
    out = {"EA1_N": float(law.EA(1.0)), "EI1_N_m2": float(law.EI(1.0)), **law_limits(params)}
    out["stretch_at_max_pressure"] = law.stretch_under_force(pressure * params.A_eff)
    try:
        lam = law.stretch_under_force(-compression, lam0=1.0)
        out["stretch_under_compression"] = lam if lam > out["critical_stretch"] else float("nan")
    except ConfigError:                                      # no root: compression beyond N_c
        out["stretch_under_compression"] = float("nan")
    out["compression_N"] = compression
    out["pressure_Pa"] = pressure
    return out
