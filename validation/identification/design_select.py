r"""Informative load cases: the training cases of a design chosen by the information they add to the fit.

The default design (:mod:`validation.reference.experiments`) is a fixed list; its bends reach only half the maximum
pressure, and the states the reduced model misses most are bends at high pressure.  This module builds a
design from a **candidate grid** over the whole operating range and chooses the training cases by
**D-optimality** on the fit's own sensitivities, so that fewer FEM solves identify more.

Candidate grid (fractions of the range, like the default design: tensions / T_max, pressure / p_max, tip
forces in units of F_ref = T_max d / L), at every pressure level p ∈ {0, ¼, ½, ¾, 1} p_max:
one tendon at 0.4, 0.7, 1.0 T_max (tendon 1) and 0.6 T_max (tendon 2); two tendons (0.6, 0.6); lateral tip
forces −0.35 F_ref e_z, +0.35 F_ref e_y, −0.6 F_ref e_z; plus equal tensions 0.2 / 0.6 / 1.0 T_max at p = 0,
pressure alone at p > 0, and equal tensions 0.4 / 0.8 T_max at ½ and 1 p_max.

Selection.  With θ₀ the form's start (:func:`validation.identification.identify.initial_theta` from the closed-form rod
estimate) and J_i (3 × n) the exact sensitivity of candidate i's tip to the form's parameters at θ₀ (the
fit's own Jacobian, :class:`validation.identification.fit._Evaluator`), columns scaled by the parameters' typical sizes, the
information of a set S is M(S) = Σ_{i∈S} J_iᵀ J_i.  Greedy D-optimal selection adds, one at a time, the
candidate that maximises

    log det(M + J_iᵀ J_i) = log det M + log det(I₃ + J_i M⁻¹ J_iᵀ),

starting from M = ε I (ε = 1e-9 × the mean diagonal of the whole grid's information, a prior that only breaks
ties while M is singular).  Greedy selection reaches at least (1 − 1/e) of the optimal log-det gain
(submodularity); it is deterministic (ties go to the earlier candidate).

Held out.  The candidates not chosen, split by the **training hull** — the convex hull of the training cases'
load features (:func:`load_features`: total tension, bending moment at the base, pressure, lateral force —
invariant under a rotation about the axis; each scaled by its largest value on the grid), tested by a linear
program — into held-out states *inside* it
(interpolation: what the report judges the model on; the midpoints of pairs of training cases are candidates
too, since D-optimal training cases sit at the edges of the range) and an *extrapolation* set outside it,
reported apart (:func:`validation.checks.compare.compare_records`: experiment ``"extrapolation"``).  From each, the
states farthest from the training cases and from each other are taken (greedy max–min distance).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Optional, Sequence

import numpy as np

from ancf.errors import InputError

from validation.reference.experiments import (EXTRAPOLATION, Design, LoadCase, _materialise, _Spec, check_range,
                                              force_reference)

__all__ = ["candidate_specs", "candidate_cases", "sensitivities", "d_optimal", "inside_hull", "spread", "load_features",
           "informative_design", "Selection"]

#: training cases beyond the form's parameter count (3 residuals each: the fit keeps 3 × SPARE_CASES + 2 × n
#: degrees of freedom)
SPARE_CASES = 5
#: pressure levels of the grid [fractions of p_max]
PRESSURES = (0.0, 0.25, 0.5, 0.75, 1.0)


def candidate_specs() -> list[_Spec]:
    """The candidate grid in fractions of the range (module docstring)."""
    out = [_Spec("axial", (t, t, t), 0.0) for t in (0.2, 0.6, 1.0)]
    for p in PRESSURES:
        if p > 0:
            out.append(_Spec("pressure", (0, 0, 0), p))
        out += [_Spec("bending", (t, 0, 0), p) for t in (0.4, 0.7, 1.0)]
        out += [_Spec("bending", (0, 0.6, 0), p), _Spec("bending", (0.6, 0.6, 0), p)]
        out += [_Spec("lateral", (0, 0, 0), p, f) for f in ((0, 0, -0.35), (0, 0.35, 0), (0, 0, -0.6))]
    out += [_Spec("combined", (t, t, t), p) for p in (0.5, 1.0) for t in (0.4, 0.8)]
    return out


def candidate_cases(*, tension_max: float, pressure_max: float, tendon_distance: float, length: float,
                    n_tendons: int = 3, role: str = "train") -> list[LoadCase]:
    """The candidate grid materialised for an actuator's range (SI; rounded like the default design)."""
    check_range("candidate_cases", tension_max, pressure_max, tendon_distance, length, n_tendons)
    F_ref = force_reference(tension_max, tendon_distance, length)
    return _materialise(candidate_specs(), role, n_tendons, tension_max, pressure_max, F_ref, False)


def sensitivities(form, cases: Sequence[LoadCase], base, theta0) -> np.ndarray:
    """(N, 3, n) exact sensitivity of each case's tip [m] to the form's parameters at θ₀, columns multiplied by
    the parameters' typical sizes (so every column is in metres per relative change of its parameter).
    Raises the fit's typed error when a case has no verified equilibrium at θ₀ (the candidate is out of the
    model's reach: leave it out of the grid)."""
    from validation.identification.fit import Observations, _Evaluator
    theta0 = np.asarray(theta0, float)
    if theta0.shape != (form.n,) or not np.all(np.isfinite(theta0)):
        raise InputError(f"sensitivities: θ₀ must be {form.n} finite values for form {form.name}")
    n = len(cases)
    if n == 0:
        raise InputError("sensitivities: no cases")
    obs = Observations(np.array([c.tensions for c in cases]), np.array([c.pressure for c in cases]),
                       np.array([c.tip_force for c in cases]), np.array([c.gravity for c in cases]),
                       np.zeros((n, 3)), labels=[c.label for c in cases])
    _, _, J = _Evaluator(form, obs, base).evaluate(theta0, jacobian=True)
    return J[:, :3, :] * form.typical_scale(theta0)[None, None, :]


def d_optimal(J: np.ndarray, k: int, *, start: Sequence[int] = ()) -> list[int]:
    """Greedy D-optimal choice of ``k`` of the N candidates with sensitivities ``J`` (N, r, n) (module docstring);
    ``start``: indices chosen beforehand (counted in k).  Returns the chosen indices in the order chosen."""
    J = np.asarray(J, float)
    if J.ndim != 3 or not np.all(np.isfinite(J)):
        raise InputError("d_optimal: J must be a finite (N, rows, params) array")
    N, _, n = J.shape
    if not isinstance(k, (int, np.integer)) or not 1 <= k <= N:
        raise InputError(f"d_optimal: k must be an integer in 1 … {N}, got {k!r}")
    chosen = [int(i) for i in start]
    if any(not 0 <= i < N for i in chosen) or len(set(chosen)) != len(chosen) or len(chosen) > k:
        raise InputError("d_optimal: start must be distinct candidate indices, at most k of them")
    info = np.einsum("irn,irm->inm", J, J)                    # (N, n, n) per-candidate information
    eps = 1e-9 * max(float(np.trace(info.sum(axis=0))) / n, 1e-300)
    M = eps * np.eye(n) + info[chosen].sum(axis=0)
    while len(chosen) < k:
        Minv = np.linalg.inv(M)
        best, gain = -1, -np.inf
        for i in range(N):
            if i in chosen:
                continue
            G = np.eye(J.shape[1]) + J[i] @ Minv @ J[i].T
            sign, ld = np.linalg.slogdet(G)
            if sign > 0 and ld > gain + 1e-12:
                best, gain = i, ld
        chosen.append(best)
        M = M + info[best]
    return chosen


def load_features(cases: Sequence[LoadCase], tendon_distance: float, length: float,
                  tendon_angles: Optional[Sequence[float]] = None) -> np.ndarray:
    """(N, 4) load features of each case, invariant under a rotation about the axis (the bellows is
    axisymmetric but for the tendons' positions): total tension Σ T_i [N], bending moment at the base
    |Σ T_i d ê_i + L e_x × F| [N m], pressure [Pa], lateral tip force |F_⊥| [N].  Tendon i at angle
    ``tendon_angles[i]`` (default: evenly spaced from 0)."""
    m = len(cases[0].tensions)
    ang = np.asarray(tendon_angles if tendon_angles is not None else 2 * np.pi * np.arange(m) / m, float)
    er = np.stack([np.zeros(m), np.cos(ang), np.sin(ang)], axis=1)          # (m, 3) radial directions
    out = []
    for c in cases:
        T, F = np.asarray(c.tensions, float), np.asarray(c.tip_force, float)
        # a tendon anchored at d ê_i pulls the cap towards the base: moment d ê_i × (−T e_x)
        M = np.sum(np.cross(tendon_distance * er, -T[:, None] * np.array([1.0, 0.0, 0.0])), axis=0)
        M = M + np.cross(np.array([length, 0.0, 0.0]), F)
        out.append([T.sum(), np.linalg.norm(M[1:]), c.pressure, np.linalg.norm(F[1:])])
    return np.array(out, float)


def inside_hull(points: np.ndarray, hull: np.ndarray, tol: float = 1e-9) -> np.ndarray:
    """(P,) bool: which of ``points`` (P, d) lie in the convex hull of ``hull`` (H, d) — a feasibility linear
    program per point (λ ≥ 0, Σλ = 1, hullᵀ λ = x)."""
    import scipy.optimize as so
    points, hull = np.atleast_2d(np.asarray(points, float)), np.atleast_2d(np.asarray(hull, float))
    H = hull.shape[0]
    A_eq = np.vstack([hull.T, np.ones((1, H))])
    out = np.zeros(points.shape[0], bool)
    for j, x in enumerate(points):
        res = so.linprog(np.zeros(H), A_eq=A_eq, b_eq=np.append(x, 1.0), bounds=[(0, None)] * H,
                         method="highs")
        out[j] = res.status == 0 and np.abs(A_eq @ res.x - np.append(x, 1.0)).max() <= tol * max(1.0, np.abs(x).max())
    return out


def spread(points: np.ndarray, fixed: np.ndarray, count: int) -> list[int]:
    """Greedy max–min distance: ``count`` indices of ``points`` (P, d), each the farthest from ``fixed`` and from
    the ones taken before (ties: the earlier point)."""
    points = np.atleast_2d(np.asarray(points, float))
    taken: list[int] = []
    ref = [np.atleast_2d(np.asarray(fixed, float))] if np.size(fixed) else []
    for _ in range(min(count, points.shape[0])):
        R = np.vstack(ref + [points[taken]]) if (ref or taken) else np.zeros((0, points.shape[1]))
        d = (np.full(points.shape[0], np.inf) if R.shape[0] == 0 else
             np.min(np.linalg.norm(points[:, None, :] - R[None, :, :], axis=2), axis=1))
        d[taken] = -np.inf
        taken.append(int(np.argmax(d)))
    return taken


def _midpoint(a: LoadCase, b: LoadCase) -> LoadCase:
    """The load case halfway between ``a`` and ``b`` (rounded like the designs: 0.01 N, 0.1 kPa, 1 mN)."""
    T = np.round(0.5 * (np.asarray(a.tensions) + np.asarray(b.tensions)), 2)
    F = np.round(0.5 * (np.asarray(a.tip_force) + np.asarray(b.tip_force)), 3)
    return LoadCase(tuple(T), round(0.5 * (a.pressure + b.pressure), -2), tuple(F), a.gravity and b.gravity,
                    "heldout", "heldout")


@dataclass
class Selection:
    """What :func:`informative_design` chose: the design, the form and θ₀ it chose for, the log-det information
    of the chosen training set and of the default design's [scaled units], the candidates' count."""
    design: Design
    form: str
    theta0: np.ndarray
    logdet: float
    logdet_default: Optional[float]
    n_candidates: int


def informative_design(form, base, theta0, *, tension_max: float, pressure_max: float, tendon_distance: float,
                       length: float, n_tendons: int = 3, n_train: Optional[int] = None, n_heldout: int = 4,
                       n_extrapolation: int = 2, default: Optional[Design] = None,
                       tendon_angles: Optional[Sequence[float]] = None) -> Selection:
    """A design of ``n_train`` D-optimal training cases for ``form`` at θ₀ (default: its parameters +
    :data:`SPARE_CASES`), up to ``n_heldout`` held-out states inside the training hull and up to ``n_extrapolation``
    outside it (module docstring).  ``default``: a design whose training information is reported beside
    (``Selection.logdet_default``).  Candidates without a verified equilibrium at θ₀ are left out."""
    from ancf.errors import BellowsError
    cands = candidate_cases(tension_max=tension_max, pressure_max=pressure_max, tendon_distance=tendon_distance,
                            length=length, n_tendons=n_tendons)
    k = n_train if n_train is not None else form.n + SPARE_CASES
    J_list, ok = [], []
    for c in cands:
        try:
            J_list.append(sensitivities(form, [c], base, theta0)[0])
            ok.append(c)
        except BellowsError:
            continue
    if len(ok) < k:
        raise InputError(f"informative_design: only {len(ok)} candidates have an equilibrium at the start "
                         f"parameters; {k} training cases asked for")
    J = np.array(J_list)
    chosen = d_optimal(J, k)
    M = np.einsum("irn,irm->nm", J[chosen], J[chosen])
    logdet = float(np.linalg.slogdet(M)[1])
    logdet_default = None
    if default is not None and default.training:
        Jd = sensitivities(form, default.training, base, theta0)
        logdet_default = float(np.linalg.slogdet(np.einsum("irn,irm->nm", Jd, Jd))[1])
    train = [ok[i] for i in sorted(chosen)]
    rest = [c for i, c in enumerate(ok) if i not in set(chosen)]
    feats = lambda cs: load_features(cs, tendon_distance, length, tendon_angles)
    scale = np.maximum(np.abs(feats(ok)).max(axis=0), 1e-12)
    Xt, Xr = feats(train) / scale, feats(rest) / scale
    inside = inside_hull(Xr, Xt)
    outs = [c for c, f in zip(rest, inside) if not f]
    # interpolation candidates: the grid's cases inside the hull and the midpoints of pairs of training cases
    # (D-optimal training cases sit at the edges of the range, so few grid cases fall strictly inside)
    mids = [_midpoint(a, b) for i, a in enumerate(train) for b in train[i + 1:]]
    seen = {c.label for c in ok}
    mids = [c for c in {c.label: c for c in mids}.values() if c.label not in seen]
    Xm = feats(mids) / scale if mids else np.zeros((0, Xt.shape[1]))
    m_in = inside_hull(Xm, Xt) if mids else np.zeros(0, bool)
    ins = [c for c, f in zip(rest, inside) if f] + [c for c, f in zip(mids, m_in) if f]
    Xi = np.vstack([Xr[inside], Xm[m_in]])
    ho = [ins[i] for i in spread(Xi, Xt, n_heldout)] if ins else []
    ex = [outs[i] for i in spread(Xr[~inside], Xt, n_extrapolation)] if outs else []
    cases = tuple([replace(c, role="train") for c in train] + [replace(c, role="heldout", experiment="heldout")
                                                                for c in ho]
                  + [replace(c, role="heldout", experiment=EXTRAPOLATION) for c in ex])
    design = Design(cases, f"informative design: {k} D-optimal training cases for form {form.name} from a grid of "
                           f"{len(ok)}, {len(ho)} held out inside the training hull, {len(ex)} outside "
                           "(extrapolation)",
                    {"tension_max_N": tension_max, "pressure_max_Pa": pressure_max,
                     "force_reference_N": force_reference(tension_max, tendon_distance, length),
                     "selection": "D-optimal", "form": form.name, "logdet": logdet,
                     "logdet_default": logdet_default})
    return Selection(design, form.name, np.asarray(theta0, float), logdet, logdet_default, len(ok))
