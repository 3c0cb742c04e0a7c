"""Inverse kinetostatics of a chain with redundant tendons (docs/multisegment.md, "Inverse problem").

Unknowns and inputs.  A chain of K segments has m = 3K tendons (in general m, numbered segment by segment) and K
chambers.  As in :meth:`ancf.Model.ik`, the pressures p (K,) [Pa] and the tip force F (3,) [N] are inputs (each
chamber has its own regulator; they are checked against their limits up front) and the tensions T (m,) [N] are the
unknowns, bounded by each segment's [T_min, T_max].  The state z(T) is the FK's equilibrium ∇_z Π(z, T) = 0.

Targets.  A tip position p_d (3-DoF): c(T) = p_end(z(T)) − p_d ∈ R³ [m].  A pose (5-DoF): besides, the tip
tangent t = a/|a| (a the distal node's slope) along a unit vector d: c_t = L B t ∈ R², with B (2, 3) an orthonormal
basis of d^⊥ and L the chain length (so both parts are in metres; t·d > 0 is checked).  A pose needs m ≥ 5.

Exact first derivatives.  Differentiating ∇_z Π(z(T), T) = 0 gives the FK's tangent

    H dz/dT = −J_lᵀ,     H = ∇²_z Π,  J_l = ∂l/∂z  (∂(∇_z Π)/∂T_j = ∇_z l_j: Π holds Σ T_j l_j),

the H of the compliances (:mod:`ancf.chain_locked`), so ∂c/∂T = J_c dz/dT with J_c = J_p = ∂p_end/∂z (and
L B P/|a| on the slope for the tangent, P = I − t tᵀ).

Redundancy and the secondary objective.  The m − 3 (m − 5) remaining degrees of freedom are fixed by

    min f(T)   s.t.  c(T) = 0,   T_min ≤ T ≤ T_max,

with f one of

* ``"least_tension"``: f = ½ Σ T_j² (the least total tension, Model.ik's rule for more than 3 tendons);
* ``"compliance"``: f = uᵀ C u [m/N], C = J_p H⁻¹ J_pᵀ the tip compliance with the tensions held
  (:meth:`ancf.ChainModel.compliance`), u a given unit vector: the state stiffest along u.  With w = H⁻¹ J_pᵀ u,

      df/dT_j = 2 uᵀ (dJ_p/dT_j) w − wᵀ (dH/dT_j) w,    d/dT_j = ∂/∂T_j + (dz/dT_j)·∂/∂z;

  the total derivatives dH/dT_j, dJ_p/dT_j are one central difference along the tangent (z ± h dz_j, T ± h e_j):
  exact in T (H is affine in T), O(h²) in z (a third derivative of Π, which the kernels do not give).

The solve: (1) the nearest reachable point, min ½|c|² over the bounds (scipy ``least_squares``, trust-region
reflective, with the exact ∂c/∂T): a residual above the tolerance is an unreachable target
(:class:`~ancf.errors.InfeasibleTargetError` naming the saturated tensions and giving the nearest tip); with
m equal to the number of constraints this is the answer (the one-segment chain's IK is then Model.ik's);
(2) SLSQP from that point on f with the exact ∂c/∂T and ∇f; (3) Newton steps on c over the tensions not at a bound
(minimum-norm) to the position tolerance.  The result is a KKT point: with A the tensions at a bound,

    ∇f + (∂c/∂T)ᵀ λ − μ_lo + μ_hi = 0,   c = 0,   μ ≥ 0 on A, 0 off A,

the multipliers λ, μ from a least-squares solve of the stationarity; its residual, |c| and the least multiplier
are returned (``ChainIKEquilibrium.kkt``).  A second-order check (f does not fall along the constraint's null
space) is in the tests.

Obstacles.  ``obstacles`` = spheres (centre c_o (3,) [m], radius R_o [m]) the body must stay out of, with a
``obstacle_margin`` δ [m] (e.g. the body's radius about its centreline).  The body is its centreline sampled at
``obstacle_samples`` + 1 points per element of every segment (ξ = 0, 1/s, …, 1), the midpoint of every cap and the
tool point: x_i(z), each linear in q (x_i = S_i q, S_i the Hermite values at ξ_i) or a tool-point map of a
segment's last node (r + h t).  The inequality constraints are

    g_{i,o}(T) = |x_i(z(T)) − c_o| − (R_o + δ) ≥ 0   [m],
    ∂g_{i,o}/∂T = n_{i,o}ᵀ (∂x_i/∂z) dz/dT,   n = (x_i − c_o)/|x_i − c_o|,   ∂x_i/∂z = S_i J (J = ∂q/∂z),

exact through the FK's tangent, as the target's.  They join SLSQP (step 2) and the KKT conditions (an active
g ≤ 10⁻⁹ m gets a multiplier ν ≥ 0: ∇f + (∂c/∂T)ᵀλ − μ_lo + μ_hi − (∂g/∂T)ᵀν = 0); a result whose body is inside
an obstacle by more than the target's tolerance (10 ``tol_position``, at least 10⁻⁸ m) is refused with
InfeasibleTargetError.  Between two body points the centreline may dip into a sphere by about its sag over one
spacing s, s²/(8(R + δ)); take more samples for a small sphere.  With as many constraints as tendons the target fixes the shape: the obstacles
are then a check, not a choice.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from . import kinematics as kin
from .chain_model import ChainEquilibrium
from .errors import (
    CollapsedStateError,
    ConvergenceError,
    InfeasibleTargetError,
    InputError,
    check_finite,
    check_scalar,
)
from .solvers import minimize_newton
from .textfmt import vector

#: The secondary objectives of :func:`ik` (module docstring).
OBJECTIVES = ("least_tension", "compliance")

#: A tension within this fraction of its range from a bound is at the bound (the KKT conditions' active set).
ACTIVE = 1e-9


@dataclass(repr=False)
class ChainIKEquilibrium(ChainEquilibrium):
    """A :class:`~ancf.chain_model.ChainEquilibrium` returned by the chain's IK, with its optimisation record:
    ``objective`` (a name of :data:`OBJECTIVES`), ``objective_value`` (½ Σ T² [N²] or uᵀ C u [m/N]),
    ``multipliers`` λ (3,) or (5,) of the target constraints [objective units per m], ``bound_multipliers`` μ (m,)
    ≥ 0 of the tension bounds at which a tension sits (0 elsewhere) [objective units per N], ``kkt``: the KKT
    residuals (``stationarity``: ‖∇f + (∂c/∂T)ᵀλ − μ_lo + μ_hi‖ / ‖∇f‖, ``primal_m``: |c| [m], ``bounds_N``: the
    largest bound violation [N], ``multiplier_min``: the least μ on a bound / ‖∇f‖ (≥ 0 at a KKT point), ``active``:
    the tendons at a bound).  ``iterations`` counts the FK solves."""
    objective: str = "least_tension"
    objective_value: float = float("nan")
    multipliers: np.ndarray | None = None
    bound_multipliers: np.ndarray | None = None
    kkt: dict = field(default_factory=dict)


@dataclass
class _Target:
    """p_d (3,) [m]; d (3,) unit tip tangent or None; B (2, 3) basis of d^⊥; L [m] the direction's scale."""
    pd: np.ndarray
    d: np.ndarray | None
    B: np.ndarray | None
    L: float

    @property
    def size(self) -> int:
        return 3 if self.d is None else 5


class _Problem:
    """The reduced problem over T: the FK state z(T) (warm-started from the last one), c(T), ∂c/∂T, f, ∇f."""

    def __init__(self, model, target: _Target, pr, F, u, tol: float, z0, obstacles: _Obstacles | None = None):
        self.model, self.target, self.pr, self.F, self.u, self.tol = model, target, pr, F, u, tol
        self.z, self._key, self._state, self.nfk = z0, None, None, 0
        self.obstacles = obstacles

    def state(self, T, fallback: bool = True):
        """(z (nz,), H (nz, nz), J_p (3, nz), dz/dT (nz, m)) at T (the last one cached).  The FK is Newton from
        the last state, then (``fallback``) load stepping from the straight chain; ConvergenceError otherwise."""
        T = np.asarray(T, float)
        if self._key != T.tobytes():
            if fallback:
                z, _ = self.model._fk_z(self.z, T, self.pr, self.F, self.tol, 60)
            else:
                z, _ = minimize_newton(self.model._fk_fun(T, self.pr, self.F), self.z, tol=self.tol, max_iter=25,
                                       name="fk")
            self.nfk += 1
            _, _, H, _, Jl = self.model.sys.evaluate(z, T, self.pr, self.F, hessian=True, lengths=2)
            self.z, self._key = z, T.tobytes()
            self._state = (z, H, self.model.sys.tip_jacobian(z), -np.linalg.solve(H, Jl.T))
        return self._state

    def c_parts(self, z):
        """(c (n_c,) [m], ∂c/∂z (n_c, nz)) at z."""
        tg, sys = self.target, self.model.sys
        c, Jc = sys.tip(z) - tg.pd, sys.tip_jacobian(z)
        if tg.d is None:
            return c, Jc
        a = z[-3:]
        na = float(np.linalg.norm(a))
        t = a / na
        Jt = np.zeros((2, z.size))
        Jt[:, -3:] = tg.L * tg.B @ (np.eye(3) - np.outer(t, t)) / na
        return np.concatenate([c, tg.L * tg.B @ t]), np.vstack([Jc, Jt])

    def c(self, T) -> np.ndarray:
        return self.c_parts(self.state(T)[0])[0]

    def c_norm(self, T) -> float:
        """|c(T)| [m] of a trial point: inf where Newton's FK from the last state fails (a load past a limit point
        of the chain, a collapsed section, or only a long step: the caller shortens it)."""
        try:
            return float(np.linalg.norm(self.c_parts(self.state(T, fallback=False)[0])[0]))
        except (ConvergenceError, CollapsedStateError):
            return float("inf")

    def jac(self, T) -> np.ndarray:
        z, _, _, dz = self.state(T)
        return self.c_parts(z)[1] @ dz

    def g(self, T) -> np.ndarray:
        """The obstacle clearances g(T) (P n_o,) [m] (empty without obstacles; module docstring)."""
        if self.obstacles is None:
            return np.zeros(0)
        return self.obstacles.g(self.state(T)[0])

    def g_jac(self, T) -> np.ndarray:
        """∂g/∂T (P n_o, m) through the FK's tangent."""
        if self.obstacles is None:
            return np.zeros((0, np.size(T)))
        z, _, _, dz = self.state(T)
        return self.obstacles.g_z(z) @ dz

    def clearance(self, T) -> float:
        """min g(T) [m] (inf without obstacles)."""
        g = self.g(T)
        return float(g.min()) if g.size else float("inf")

    def f(self, T) -> float:
        if self.u is None:
            return 0.5 * float(np.dot(T, T))
        _, H, Jp, _ = self.state(T)
        v = Jp.T @ self.u
        return float(v @ np.linalg.solve(H, v))

    def grad(self, T, h: float = 1e-4) -> np.ndarray:
        """∇f (m,) (module docstring; the compliance's by one central difference along the FK's tangent)."""
        T = np.asarray(T, float)
        if self.u is None:
            return T.copy()
        z, H, Jp, dz = self.state(T)
        w = np.linalg.solve(H, Jp.T @ self.u)
        sys, g = self.model.sys, np.zeros(T.size)
        for j in range(T.size):
            e = np.zeros(T.size)
            e[j] = h
            zp, zm = z + h * dz[:, j], z - h * dz[:, j]
            Hp = sys.evaluate(zp, T + e, self.pr, self.F, hessian=True)[2]
            Hm = sys.evaluate(zm, T - e, self.pr, self.F, hessian=True)[2]
            dJp = (sys.tip_jacobian(zp) - sys.tip_jacobian(zm)) / (2 * h)
            g[j] = 2 * self.u @ dJp @ w - w @ (Hp - Hm) @ w / (2 * h)
        return g


class Body:
    """The chain's body as points for the obstacle constraints (module docstring, "Obstacles"): the centreline at
    ``samples`` + 1 points per element of every segment (shared element ends once), each cap's midpoint and the tool
    point, in order from the base.  ``points(z)`` (P, 3) [m]; ``jacobian(z)`` (P, 3, nz) = ∂x_i/∂z."""

    def __init__(self, model, samples: int = 4):
        sys = model.sys
        self.sys, rows = sys, []
        for k, seg in enumerate(sys.segments):
            n, l0 = seg.params.n_elements, seg.params.element_length
            xi = np.linspace(0.0, 1.0, samples + 1)
            N = kin.hermite(xi, l0)[0]                       # (4, samples + 1)
            for e in range(n):
                for i in range(0 if e == 0 else 1, samples + 1):
                    S = np.zeros((3, sys.ndof))
                    for a in range(4):                       # r_e, a_e, r_{e+1}, a_{e+1}
                        c0 = seg.qo + 6 * e + 3 * a
                        S[:, c0:c0 + 3] = N[a, i] * np.eye(3)
                    rows.append(S)
            self.n_centreline = len(rows)
        self.S = np.array(rows)                              # (P_c, 3, ndof)
        ends = [s.zo + s.nz for s in sys.segments]
        # (z index of a segment's last node's end, offset along its tangent [m]): the caps' midpoints, the tool point
        self.offsets = [(ends[k], 0.5 * h) for k, h in enumerate(sys.caps)] + [(ends[-1],
                                                                               sys.segments[-1].end_offset)]
        self.size = len(rows) + len(self.offsets)

    def points(self, z) -> np.ndarray:
        q = self.sys.to_full(z)
        x = [self.S @ q] + [kin.tip_position(z[e - 6:e], h)[None] for e, h in self.offsets]
        return np.concatenate(x)

    def jacobian(self, z) -> np.ndarray:
        D = np.zeros((self.size, 3, z.size))
        D[:self.S.shape[0]] = np.einsum("pij,jk->pik", self.S, self.sys.jacobian(z))
        for i, (e, h) in enumerate(self.offsets):
            D[self.S.shape[0] + i, :, e - 6:e] = kin.tip_position_jacobian(z[e - 6:e], h)
        return D


@dataclass
class _Obstacles:
    """Sphere centres C (n_o, 3) [m], radii plus margin Rm (n_o,) [m], the body's points."""
    C: np.ndarray
    Rm: np.ndarray
    body: Body

    def g(self, z) -> np.ndarray:
        """g (P n_o,) [m]: every point's clearance from every sphere (point-major)."""
        x = self.body.points(z)
        return (np.linalg.norm(x[:, None, :] - self.C[None], axis=2) - self.Rm[None]).ravel()

    def g_z(self, z) -> np.ndarray:
        """∂g/∂z (P n_o, nz)."""
        x, D = self.body.points(z), self.body.jacobian(z)
        d = x[:, None, :] - self.C[None]
        n = d / np.maximum(np.linalg.norm(d, axis=2, keepdims=True), 1e-300)
        return np.einsum("poi,pik->pok", n, D).reshape(-1, z.size)


# ----------------------------------------------------------------------------- inputs
def _obstacles(model, obstacles, margin, samples) -> _Obstacles | None:
    """The checked ``obstacles`` ([(centre (3,) [m], radius [m]), …]) with ``margin`` [m] and ``samples`` per
    element; None for none."""
    if obstacles is None:
        return None
    try:
        items = list(obstacles)
    except TypeError:
        raise InputError("obstacles must be a list of (centre (3,) [m], radius [m]) pairs") from None
    margin = check_scalar("obstacle_margin", margin, low=0.0, high=1.0, unit="m")
    if isinstance(samples, bool) or not isinstance(samples, (int, np.integer)) or not 1 <= samples <= 64:
        raise InputError(f"obstacle_samples must be an integer in [1, 64] (points per element), got {samples!r}")
    C, R = [], []
    for i, ob in enumerate(items):
        if not (isinstance(ob, (tuple, list)) and len(ob) == 2):
            raise InputError(f"obstacle {i + 1} must be a (centre (3,) [m], radius [m]) pair, got {ob!r}")
        C.append(check_finite(f"obstacle {i + 1} centre", ob[0], (3,)))
        R.append(check_scalar(f"obstacle {i + 1} radius", ob[1], low=0.0, high=10.0, unit="m"))
    if not C:
        return None
    return _Obstacles(np.array(C), np.array(R) + margin, Body(model, int(samples)))


def _target(model, target, tip_direction) -> _Target:
    pd = check_finite("target", target, (3,))
    if tip_direction is None:
        return _Target(pd, None, None, model.chain.length)
    d = check_finite("tip_direction", tip_direction, (3,))
    nd = float(np.linalg.norm(d))
    if not nd > 1e-12:
        raise InputError("tip_direction must be a nonzero vector (the tip tangent asked)")
    if model.m < 5:
        raise InputError(f"a pose (tip position and direction: 5 constraints) needs at least 5 tendons; this chain "
                         f"has {model.m} (pass tip_direction=None for a position target)")
    d = d / nd
    Q, _ = np.linalg.qr(np.column_stack([d, np.eye(3)]))
    return _Target(pd, d, np.ascontiguousarray(Q[:, 1:3].T), model.chain.length)


def _objective(objective: str, compliance_direction):
    if objective not in OBJECTIVES:
        raise InputError(f"objective must be one of {', '.join(OBJECTIVES)}, got {objective!r}")
    if objective == "least_tension":
        if compliance_direction is not None:
            raise InputError("compliance_direction is for objective='compliance'")
        return None
    if compliance_direction is None:
        raise InputError("objective='compliance' needs compliance_direction (3,): the unit vector along which the "
                         "tip compliance is minimised")
    u = check_finite("compliance_direction", compliance_direction, (3,))
    nu = float(np.linalg.norm(u))
    if not nu > 1e-12:
        raise InputError("compliance_direction must be a nonzero vector")
    return u / nu


def _bounds(model):
    """(lo (m,), hi (m,)) [N]: each tendon's segment's tension limits."""
    segs = model.chain.segments
    lo = np.array([segs[k].tension_min for k in model.sys.owner], float)
    hi = np.array([segs[k].tension_max for k in model.sys.owner], float)
    return lo, hi


# ----------------------------------------------------------------------------- the solve
def ik(model, target, pressures=None, tip_force=(0.0, 0.0, 0.0), *, tip_direction=None,
       objective: str = "least_tension", compliance_direction=None, tensions0=None, z0=None,
       tol: float | None = None, tol_position: float = 1e-9, max_iter: int = 200, check_limits: bool = True,
       check_stability: bool = True, obstacles=None, obstacle_margin: float = 0.0,
       obstacle_samples: int = 4) -> ChainIKEquilibrium:
    """Inverse kinetostatics of a chain (module docstring): tool point ``target`` (3,) [m] (and, for a pose, the tip
    tangent along ``tip_direction`` (3,), any length), pressures (K,) [Pa] (inputs; a number for one segment),
    tip_force (3,) [N] → :class:`ChainIKEquilibrium` with tensions inside their bounds, the state reaching the
    target within ``tol_position`` [m] (the tangent's components normal to the direction within
    tol_position / L).  ``objective``: ``"least_tension"`` (min ½ Σ T²) or ``"compliance"`` (min uᵀ C u with
    u = ``compliance_direction``).  Starts from ``tensions0`` (m,) [N] and ``z0`` when given.  ``obstacles``: spheres
    [(centre (3,) [m], radius [m]), …] whose centres the body's points (``obstacle_samples`` per element, module
    docstring) stay at least radius + ``obstacle_margin`` [m] from (``kkt["clearance_m"]``: the least clearance).

    Errors: InputError / LimitError for inputs (pressures outside their limits unless ``check_limits=False``);
    InfeasibleTargetError when no tensions inside the bounds reach the target (``nearest``, ``tensions``,
    ``violated``, ``state``), also when the only shapes found on the target cross an obstacle; ConvergenceError
    when the optimisation ends away from a KKT point;
    UnstableEquilibriumError for an unstable state (unless ``check_stability=False``)."""
    tol, max_iter = model._options(tol, max_iter)
    tol_position = check_scalar("tol_position", tol_position, low=1e-15, high=1e-2, unit="m")
    tg = _target(model, target, tip_direction)
    u = _objective(objective, compliance_direction)
    pressures = np.zeros(model.n_segments) if pressures is None else pressures
    _, pr, F = model._check_inputs(None, pressures, tip_force, check_limits)
    lo, hi = _bounds(model)
    T0 = lo + 0.05 * (hi - lo) if tensions0 is None else np.clip(check_finite("tensions0", tensions0,
                                                                              (model.m,)), lo, hi)
    if z0 is None:
        z0 = model.fk(T0, pr, F, check_limits=False, check_stability=False).z
    obs = _obstacles(model, obstacles, obstacle_margin, obstacle_samples)
    prob = _Problem(model, tg, pr, F, u, tol, model._z0(z0), obs)
    T, nfev = _nearest(prob, T0, lo, hi, tol_position)
    kkt, lam, mu = _kkt(prob, T, lo, hi)
    reach = max(10 * tol_position, 1e-8)
    if model.m > tg.size and not (kkt["stationarity"] < 1e-9 and kkt["multiplier_min"] > 1e-9
                                  and kkt["clearance_m"] >= -reach):
        # (a reachable point that is already a KKT point, e.g. a vertex of the bounds, is not handed to SLSQP:
        # with more active constraints than free tensions its subproblems are degenerate)
        T, nfev = _optimise(prob, T, lo, hi, tol_position, max_iter, nfev)
        kkt, lam, mu = _kkt(prob, T, lo, hi)
    if kkt["clearance_m"] < -reach:
        _blocked(prob, T, kkt["clearance_m"])
    if model.m > tg.size and not (kkt["stationarity"] < 1e-5 and kkt["multiplier_min"] > -1e-5):
        raise ConvergenceError(f"the chain's IK ended away from a KKT point of objective {objective!r}: "
                               f"stationarity {kkt['stationarity']:.3g}, least bound multiplier "
                               f"{kkt['multiplier_min']:.3g} (relative to |∇f|)", solver="ik", iterations=nfev,
                               residual_norm=kkt["stationarity"], tolerance=1e-5)
    z = prob.state(T)[0]
    from .solvers import SolveInfo
    eq = model._result(z, T, pr, F, SolveInfo(nfev, float(np.linalg.norm(model.sys.evaluate(
        z, T, pr, F, hessian=False)[1])), []), "ik", check_stability=check_stability)
    return ChainIKEquilibrium(**eq.__dict__, objective=objective, objective_value=prob.f(T), multipliers=lam,
                              bound_multipliers=mu, kkt=kkt)


def _nearest(prob: _Problem, T0, lo, hi, tol_position: float):
    """(T, FK count): tensions inside the bounds on the target, by bounded Newton steps (:func:`_polish`) from T0,
    else the least |c| inside the bounds (scipy ``least_squares``) and Newton steps from there;
    InfeasibleTargetError when |c| stays above the tolerance.  With as many constraints as tendons this is the
    IK's answer."""
    import scipy.optimize as so
    reach = max(10 * tol_position, 1e-8)
    T = _polish(prob, np.clip(T0, lo, hi), lo, hi, tol_position, steps=30)
    if np.linalg.norm(prob.c(T)) <= reach:
        return T, prob.nfk
    res = so.least_squares(prob.c, np.clip(T0, lo + 1e-9 * (hi - lo), hi - 1e-9 * (hi - lo)), jac=prob.jac,
                           bounds=(lo, hi), method="trf", xtol=1e-15, ftol=1e-15, gtol=1e-15, max_nfev=100)
    # the reflective method stays strictly inside: a tension within 1e-7 of its range from a bound is put on it
    # (the target error this makes, about 1e-7 (T_max − T_min) |∂p/∂T|, is what the Newton steps then remove)
    T = _polish(prob, _snap(res.x, lo, hi, 1e-7), lo, hi, tol_position)
    err = float(np.linalg.norm(prob.c(T)))
    if err <= reach:
        return T, prob.nfk
    _infeasible(prob, T, lo, hi, err)


def _snap(T, lo, hi, rel: float):
    """T clipped to the bounds, a tension within rel × (T_max − T_min) of a bound put on it."""
    edge = rel * (hi - lo)
    T = np.clip(T, lo, hi)
    return np.where(T <= lo + edge, lo, np.where(T >= hi - edge, hi, T))


def _polish(prob: _Problem, T, lo, hi, tol_position: float, steps: int = 8):
    """Bounded Gauss–Newton steps on c(T) = 0 (minimum-norm) over the tensions off their bounds; only when those
    cannot span the constraints does a tension at a bound take part, if the full step moves it inside.  The step
    is halved until |c| falls (Armijo), each iterate clipped to the bounds.  Stops at |c| ≤ tol_position or
    when no step lowers |c|."""
    cn = float(np.linalg.norm(prob.c(T)))
    history = [cn]
    for _ in range(steps):
        if cn <= tol_position or (len(history) > 3 and cn > 0.5 * history[-4]):    # on target, or stalled
            break
        c, J = prob.c(T), prob.jac(T)
        free = (T > lo) & (T < hi)
        if np.linalg.matrix_rank(J[:, free]) < c.size:
            d_all = -np.linalg.lstsq(J, c, rcond=None)[0]
            free = ~(((T <= lo) & (d_all < 0)) | ((T >= hi) & (d_all > 0)))
        if not free.any():
            break
        d = np.zeros_like(T)
        d[free] = -np.linalg.lstsq(J[:, free], c, rcond=None)[0]
        alpha = a0 = min(1.0, 0.25 / max(float(np.max(np.abs(d) / np.maximum(hi - lo, 1e-12))), 1e-300))
        while alpha > 1e-3 * a0:                     # (a step moves a tension by ≤ ¼ of its range)
            T_new = np.clip(T + alpha * d, lo, hi)
            cn_new = prob.c_norm(T_new)
            if cn_new < (1 - 1e-4 * alpha) * cn:
                break
            alpha *= 0.5
        else:
            break
        T, cn = T_new, cn_new
        history.append(cn)
    return T


def _infeasible(prob: _Problem, T, lo, hi, err: float):
    """Raise InfeasibleTargetError at the nearest tensions T (the tensions at a bound named)."""
    from .errors import UnstableEquilibriumError
    model, tg = prob.model, prob.target
    z = prob.state(T)[0]
    near = model.sys.tip(z)
    violated = [f"T{j + 1} {'>=' if T[j] <= lo[j] + 1e-9 else '<='} "
                f"{lo[j] if T[j] <= lo[j] + 1e-9 else hi[j]:g} N" for j in range(model.m)
                if T[j] <= lo[j] + 1e-9 or T[j] >= hi[j] - 1e-9]
    from .solvers import SolveInfo
    try:
        state = model._result(z, T, prob.pr, prob.F, SolveInfo(prob.nfk, 0.0, []), "fk")
    except (CollapsedStateError, UnstableEquilibriumError):
        state = None
    what = "tip" if tg.d is None else f"pose (tip tangent along {vector(tg.d, '', 1.0, 3)})"
    raise InfeasibleTargetError(
        f"chain IK target {what} {vector(tg.pd, 'mm', 1e3, 3)} is not reachable with the tensions inside their "
        f"bounds at p = {vector(prob.pr, 'kPa', 1e-3, 2)}: the nearest reachable state is {err * 1e3:.3f} mm "
        f"(target residual) away, tip {vector(near, 'mm', 1e3, 3)}, tensions {vector(T, 'N', 1.0, 4)}; at a "
        f"bound: {'; '.join(violated) or 'none (the target is outside the workspace)'}", target=tg.pd,
        nearest=near, tensions=T, violated=violated, state=state)


def _blocked(prob: _Problem, T, clearance: float):
    """Raise InfeasibleTargetError: the shape found on the target crosses an obstacle (by -clearance [m])."""
    from .errors import UnstableEquilibriumError
    from .solvers import SolveInfo
    model, tg, obs = prob.model, prob.target, prob.obstacles
    z = prob.state(T)[0]
    gap = obs.g(z).reshape(obs.body.size, -1)
    i, o = np.unravel_index(int(np.argmin(gap)), gap.shape)
    try:
        state = model._result(z, T, prob.pr, prob.F, SolveInfo(prob.nfk, 0.0, []), "ik")
    except (CollapsedStateError, UnstableEquilibriumError):
        state = None
    how = ("the target fixes the shape (as many constraints as tendons)" if model.m <= tg.size
           else "no shape on the target clear of it was found from this start")
    raise InfeasibleTargetError(
        f"chain IK target {vector(tg.pd, 'mm', 1e3, 3)} is reached only with the body inside obstacle {o + 1} "
        f"(centre {vector(obs.C[o], 'mm', 1e3, 3)}, radius plus margin {obs.Rm[o] * 1e3:.3f} mm): body point "
        f"{i + 1} of {obs.body.size} is {-clearance * 1e3:.3f} mm inside; {how}; tensions {vector(T, 'N', 1.0, 4)}",
        target=tg.pd, nearest=model.sys.tip(z), tensions=T, violated=[f"obstacle {o + 1}"], state=state)


class _AtKKT(Exception):
    """Raised from SLSQP's callback at an iterate that is a KKT point to the tolerances (carries it)."""

    def __init__(self, T):
        super().__init__()
        self.T = T


def _optimise(prob: _Problem, T, lo, hi, tol_position: float, max_iter: int, nfev: int):
    """SLSQP on f s.t. c = 0 inside the bounds from a point on the target, then :func:`_polish`; the start is
    kept when SLSQP's end is off the target or not better (f and c scaled to order one).  An iterate that is
    already a KKT point ends it (with more active constraints than free tensions SLSQP's line search can go on
    failing at a vertex of the feasible set until its iteration limit)."""
    import scipy.optimize as so
    f0 = max(abs(prob.f(T)), 1e-30)
    s_c = 1.0 / prob.target.L
    reach = max(10 * tol_position, 1e-8)

    def at_kkt(t):
        t = _snap(t, lo, hi, ACTIVE)
        if np.linalg.norm(prob.c(t)) <= reach and prob.clearance(t) >= -reach:
            kkt = _kkt(prob, t, lo, hi)[0]
            if kkt["stationarity"] < 1e-8 and kkt["multiplier_min"] > -1e-8:
                raise _AtKKT(t)
    constraints = [{"type": "eq", "fun": lambda t: prob.c(t) * s_c, "jac": lambda t: prob.jac(t) * s_c}]
    if prob.obstacles is not None:
        constraints.append({"type": "ineq", "fun": lambda t: prob.g(t) * s_c, "jac": lambda t: prob.g_jac(t) * s_c})
    try:
        opt = so.minimize(lambda t: prob.f(t) / f0, T, jac=lambda t: prob.grad(t) / f0,
                          bounds=list(zip(lo, hi, strict=True)), method="SLSQP", callback=at_kkt,
                          constraints=constraints, options={"ftol": 1e-14, "maxiter": max_iter})
        T_end = opt.x
    except _AtKKT as stop:
        T_end = stop.T
    T_opt = _polish(prob, _snap(T_end, lo, hi, ACTIVE), lo, hi, tol_position)
    on = np.linalg.norm(prob.c(T_opt)) <= reach
    clear_opt, clear0 = prob.clearance(T_opt) >= -reach, prob.clearance(T) >= -reach
    # SLSQP's end replaces the start when it is on the target and clear of the obstacles, and better or the start
    # is not clear
    if on and clear_opt and (not clear0 or prob.f(T_opt) <= prob.f(T) + 1e-12 * f0):
        T = T_opt
    return T, prob.nfk


#: An obstacle clearance g ≤ this [m] is active in the KKT conditions.
ACTIVE_CLEARANCE = 1e-9


def _kkt(prob: _Problem, T, lo, hi):
    """(kkt residuals (dict), λ (n_c,), μ (m,) ≥ 0 at a KKT point) at T (module docstring).  With obstacles, the
    active clearances' multipliers ν ≥ 0 join the stationarity (``obstacle_multipliers``: ν of the active
    constraints, ``obstacle_active``: their (point, obstacle) pairs) and ``clearance_m`` is min g (inf without)."""
    g, Jc, c = prob.grad(T), prob.jac(T), prob.c(T)
    at_lo = T <= lo + ACTIVE * (hi - lo)
    at_hi = (T >= hi - ACTIVE * (hi - lo)) & ~at_lo
    A = np.nonzero(at_lo | at_hi)[0]
    E = np.zeros((T.size, A.size))
    E[A, np.arange(A.size)] = 1.0
    gap = prob.g(T)
    B = np.nonzero(gap <= ACTIVE_CLEARANCE)[0]
    G = prob.g_jac(T)[B] if B.size else np.zeros((0, T.size))
    M = np.hstack([Jc.T, E, -G.T])
    x = np.linalg.lstsq(M, -g, rcond=None)[0]
    nc, na = Jc.shape[0], A.size
    lam, nu, nu_obs = x[:nc], x[nc:nc + na], x[nc + na:]
    mu = np.zeros(T.size)
    mu[A] = np.where(at_lo[A], -nu, nu)
    gn = max(float(np.linalg.norm(g)), 1e-300)
    mult = np.concatenate([mu[A], nu_obs])
    n_o = 0 if prob.obstacles is None else prob.obstacles.C.shape[0]
    kkt = {"stationarity": float(np.linalg.norm(M @ x + g)) / gn,
           "primal_m": float(np.linalg.norm(c)),
           "bounds_N": float(max(np.max(lo - T), np.max(T - hi), 0.0)),
           "multiplier_min": float(np.min(mult)) / gn if mult.size else 0.0,
           "active": tuple(int(j) for j in A),
           "clearance_m": float(gap.min()) if gap.size else float("inf")}
    if prob.obstacles is not None:
        kkt["obstacle_active"] = tuple((int(b) // n_o, int(b) % n_o) for b in B)
        kkt["obstacle_multipliers"] = nu_obs
    return kkt, lam, mu
