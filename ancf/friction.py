"""Equilibria with tendon friction and their history (the capstan law of :mod:`ancf.forces.tendon_friction`).

With a friction coefficient μ = ``ActuatorParams.tendon_friction`` > 0 the equilibrium depends on the path: the
segment tensions T_ik (one per tendon and element) follow the motor tensions through the capstan law with
stick and slip, starting from the previous state's tensions.  One step of that history, from a state S (None:
the unloaded actuator, every segment slack) to new motor tensions T (m,) [N] at pressure p [Pa] and tip force
F (3,) [N], solves

    R(z) = Pᵀ [ Q_el(q) + Σ_ik T_ik(q) ∇l_ik(q) ] = 0,     T_ik(q) = the profile of S's tensions at α(q)

(Q_el: the model's generalized force with every tendon slack; z the free coordinates, q = q_fix + P z) by
Newton's method with the exact, non-symmetric tangent (module docstring of the law) and a backtracking line
search on |R|, from S's state (or, from None, from the frictionless equilibrium at T).  The result carries its
segment tensions and sliding pattern: the next step's history.  Monotone changes between steps are assumed
(the law is applied once per step); :func:`tension_cycle` takes ``steps`` steps per branch.

Stability: the tangent of a friction state is not the Hessian of a potential; a state is refused
(:class:`~ancf.errors.UnstableEquilibriumError`) when its reduced tangent has an eigenvalue with a negative real
part (a divergence instability under the held slip pattern).

Compliance (:func:`compliance`): the motor tensions held, a tip load δF moves the state by
δz = K⁻¹ Pᵀ J_pᵀ δF with K the full tangent — the slipping segments' tensions follow their wrap angles, the stuck
ones stay — exact for loads small enough to keep the sliding pattern.

Locked tendons (:func:`fk_locked_history`, :func:`locked_compliance`): the motor holds the tendon's length;
stuck guides fix the tendon's material, so a span between them keeps its length (a length constraint with its
tension as multiplier), and across a slipping guide the tension follows the cone (the law in
:func:`fk_locked_history`'s docstring); :func:`locked_length_jacobian` is a step's derivative in the motor
lengths (its pattern held).  :meth:`ancf.Model.fk_locked` and :mod:`ancf.compliance`'s locked forms
stay frictionless whatever μ is.  The pull-through test (:func:`pull_through`): the shape held, the capstan
law applied along a motor-tension protocol.  μ = 0: :meth:`ancf.Model.fk_history` is
:meth:`ancf.Model.fk` (the same call, bit for bit) with every segment at its motor tension.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .assembly import assemble
from .errors import (
    ConvergenceError,
    InputError,
    UnstableEquilibriumError,
    check_finite,
    check_scalar,
)
from .forces import tendon_friction as tf
from .model import Equilibrium, Evaluation, Model
from .solvers import SolveInfo


@dataclass
class FrictionState:
    """One state of the tendons' friction history.

    equilibrium : the equilibrium (``.tip`` [m], ``.q``, ``.tensions`` = the motor tensions [N], …)
    segment_tensions : (m, n) [N] tension of tendon i over element k (k = 0 at the base, next to the motor)
    sliding : (m, n) int8  +1 slipping toward the motor, 0 stuck, −1 slipping away from it (μ = 0: all 0)
    wrap_angles : (m, n) [rad] wrap angle at guide k (the node at the start of element k)
    friction : μ [-]
    locked_lengths : (m,) [m] the tendon lengths the motors held (:func:`fk_locked_history`), else None
    """
    equilibrium: Equilibrium
    segment_tensions: np.ndarray
    sliding: np.ndarray
    wrap_angles: np.ndarray
    friction: float
    locked_lengths: np.ndarray | None = None

    @property
    def tip(self) -> np.ndarray:
        """Tool point [m] (3,)."""
        return self.equilibrium.tip

    @property
    def q(self) -> np.ndarray:
        return self.equilibrium.q

    @property
    def motor_tensions(self) -> np.ndarray:
        return self.equilibrium.tensions


@dataclass
class TensionCycle:
    """A quasi-static tension cycle 0 → T_peak → 0 (:func:`tension_cycle`).

    scale : (2 s + 1,) the load factor of each state (0 … 1 … 0; the motor tensions are scale × T_peak)
    states : the FrictionState of each point (loading: the first s + 1, unloading: the last s + 1, sharing the peak)
    tip : (2 s + 1, 3) [m] tool points
    tendon_lengths : (2 s + 1, m) [m] lengths l_c of the tendons inside the actuator
    frictionless_tip : (s + 1, 3) [m] the frictionless tool point at the loading scales
    loop_area : [N m] area of the loop in the plane (T, u): T the largest peak tension × scale, u the tip
                displacement along the loading branch's direction (start → peak); 0 without friction
    dissipated_energy : [J] the work the motors put in over the cycle, −Σ_i ∮ T_i dl_c,i (trapezoidal rule):
                the energy friction dissipates, ≥ 0
    """
    scale: np.ndarray
    states: list
    tip: np.ndarray
    tendon_lengths: np.ndarray
    frictionless_tip: np.ndarray
    loop_area: float
    dissipated_energy: float
    peak_tensions: np.ndarray = field(default_factory=lambda: np.zeros(0))

    def branches(self) -> tuple[np.ndarray, np.ndarray]:
        """(loading, unloading) tool points [m], each (s + 1, 3) ordered by increasing scale."""
        s = (len(self.scale) - 1) // 2
        return self.tip[:s + 1], self.tip[s:][::-1]

    def displacement(self) -> np.ndarray:
        """u (2 s + 1,) [m]: the tip displacement from the start along the loading direction (start → peak)."""
        s = (len(self.scale) - 1) // 2
        d = self.tip[s] - self.tip[0]
        nd = np.linalg.norm(d)
        return (self.tip - self.tip[0]) @ (d / nd if nd > 0 else d)


# ------------------------------------------------------------------------------------------------ evaluation
def _parts(model: Model, q, motor, held, mu, pr, F, want_K: bool):
    """Residual Q (ndof,), tangent K (ndof, ndof) or None, and the friction quantities at full coordinates q.
    None when q is outside the model's domain."""
    ea, ei = model._coeffs(pr)
    Ftot = model.total_tip_load(F)
    E, Q, K, *_ = assemble(q, model.n, model._N, model._wq, ea, ei, pr * model._vc, model._mg, model._E,
                           model._d, model._co, model._so, np.zeros(model.m), model.params.tool_offset, Ftot,
                           want_K, 0)
    if not np.isfinite(E):
        return None
    ok, P, G = tf.guide_points(q, model.n, model._E, model._d, model._co, model._so)
    if not ok:
        return None
    alpha, dalpha = tf.wrap_angles(P, G, model._e1, model.ndof)
    T, code, dTq, dTm = tf.tension_profile(motor, held, alpha, mu, dalpha if want_K else None)
    ok, Gs, Hs, lseg, Jseg = tf.segment_forces(q, model.n, model._N, model._wq, model._E, model._d, model._co,
                                               model._so, np.ascontiguousarray(T), want_K)
    if not ok:
        return None
    Qt = Q + Gs
    Kt = None
    if want_K:
        Kt = K + Hs + Jseg.reshape(-1, model.ndof).T @ dTq.reshape(-1, model.ndof)
    return {"Q": Qt, "K": Kt, "T": T, "code": code, "alpha": alpha, "dTm": dTm, "lseg": lseg, "Jseg": Jseg,
            "energy": E + float(np.sum(T * lseg))}


def _newton(model: Model, z0, motor, held, mu, pr, F, tol: float, max_iter: int):
    """Newton with backtracking on |R| (module docstring).  Returns (z, parts at z, SolveInfo)."""
    z = z0.copy()
    hist = []
    for it in range(max_iter + 1):
        parts = _parts(model, model._to_full(z), motor, held, mu, pr, F, True)
        if parts is None:
            raise ConvergenceError("the friction solve reached a state outside the model's domain",
                                   solver="fk_history", iterations=it, residual_norm=float("inf"), tolerance=tol,
                                   history=hist + [float("inf")])
        r = model._reduce_vec(parts["Q"])
        nr = float(np.linalg.norm(r))
        hist.append(nr)
        if nr < tol:
            return z, parts, SolveInfo(it, nr, hist)
        if it == max_iter:
            break
        Kr = model._reduce_mat(parts["K"])
        dz = np.linalg.solve(Kr, -r)
        step = 1.0
        while step > 1e-6:
            trial = _parts(model, model._to_full(z + step * dz), motor, held, mu, pr, F, False)
            if trial is not None and np.linalg.norm(model._reduce_vec(trial["Q"])) < (1 - 1e-4 * step) * nr:
                break
            step *= 0.5
        else:
            break
        z = z + step * dz
    raise ConvergenceError("Newton on the equilibrium with tendon friction did not converge", solver="fk_history",
                           iterations=len(hist) - 1, residual_norm=hist[-1], tolerance=tol, history=hist)


def _check_state(model: Model, state: FrictionState | None, mu: float) -> None:
    if state is None:
        return
    if not isinstance(state, FrictionState):
        raise InputError(f"state must be a FrictionState (a result of fk_history) or None, got {type(state).__name__}")
    if state.segment_tensions.shape != (model.m, model.n) or state.q.shape != (model.ndof,):
        raise InputError(f"the friction state has {state.segment_tensions.shape} segment tensions and "
                         f"{state.q.size} coordinates; this model has ({model.m}, {model.n}) and {model.ndof}: it "
                         "comes from another actuator")
    if state.friction != mu:
        raise InputError(f"the friction state was solved with μ = {state.friction:g}, this model has "
                         f"tendon_friction = {mu:g}")


def fk_history(model: Model, tensions, pressure: float = 0.0, tip_force=(0.0, 0.0, 0.0),
               state: FrictionState | None = None, *, tol: float | None = None, max_iter: int = 60,
               check_limits: bool = True, check_stability: bool = True) -> FrictionState:
    """The next equilibrium of the friction history (module docstring): motor tensions ``tensions`` (m,) [N],
    ``pressure`` [Pa], ``tip_force`` (3,) [N], from ``state`` (None: the unloaded actuator, every segment slack).
    Returns a :class:`FrictionState`.  Raises like :meth:`ancf.Model.fk` (InputError, LimitError,
    ConvergenceError, CollapsedStateError, UnstableEquilibriumError)."""
    mu = float(model.params.tendon_friction)
    tol, max_iter = model._check_solver_options(tol, max_iter)
    T = check_finite("tensions", tensions, (model.m,))
    T, pr, F = model._check_inputs(T, pressure, tip_force, check_limits)
    _check_state(model, state, mu)
    q0 = None if state is None else state.q
    if mu == 0.0:                               # the frictionless model itself, bit for bit
        eq = model.fk(T, pr, F, q0, tol=tol, max_iter=max_iter, check_limits=check_limits,
                      check_stability=check_stability)
        return FrictionState(eq, np.repeat(T[:, None], model.n, axis=1), np.zeros((model.m, model.n), np.int8),
                             _alpha(model, eq.q), 0.0)
    held = np.zeros((model.m, model.n)) if state is None else state.segment_tensions
    if state is None:
        q0 = model.fk(T, pr, F, tol=tol, max_iter=max_iter, check_limits=check_limits, check_stability=False).q
    z, parts, info = _newton(model, model._to_free(q0), T, held, mu, pr, F, tol, max_iter)
    q = model._to_full(z)
    ev = Evaluation(parts["energy"], None, None, parts["lseg"].sum(axis=1), None, float("nan"), None)
    stable = _stable(model, parts["K"], check_stability)
    eq = model._result(q, T, pr, F, info, ev, "fk_history", H=None)
    eq.stable = stable
    eq.__dict__["_friction_tangent"] = (parts["K"], parts["Jseg"], parts["dTm"])
    return FrictionState(eq, parts["T"], parts["code"], parts["alpha"], mu)


def _alpha(model: Model, q) -> np.ndarray:
    _ok, P, G = tf.guide_points(q, model.n, model._E, model._d, model._co, model._so)
    return tf.wrap_angles(P, G, model._e1, model.ndof)[0]


def _stable(model: Model, K, check: bool) -> bool:
    """True when every eigenvalue of the reduced tangent has a positive real part (module docstring)."""
    ev = np.linalg.eigvals(model._reduce_mat(K))
    low = float(np.min(ev.real))
    if low > 0:
        return True
    if check:
        raise UnstableEquilibriumError("the friction solve converged to an unstable state (its tangent has an "
                                       "eigenvalue with a negative real part); apply the tensions in smaller steps",
                                       solver="fk_history", min_eigenvalue=low)
    return False


# ------------------------------------------------------------------------------------------------ compliance
def compliance(model: Model, state: FrictionState):
    """Tip compliance with the motor tensions and pressure held under friction: C_p (3, 3) [m/N] as
    :class:`ancf.compliance.Compliance` (mode ``"tension"``, method ``"friction"``), from the full tangent of
    the state (its slipping segments' tensions following their wrap angles, its stuck ones held; module
    docstring).  ``dT_dF`` is None (the motor tensions are held)."""
    from . import compliance as _c
    if not isinstance(state, FrictionState):
        raise InputError(f"compliance needs a FrictionState, got {type(state).__name__}")
    _check_state(model, state, state.friction)
    eq = state.equilibrium
    if state.friction == 0.0:
        return _c.tension(model, eq)
    kept = eq.__dict__.get("_friction_tangent")
    K = kept[0] if kept is not None else _parts(model, eq.q, eq.tensions, state.segment_tensions,
                                                state.friction, float(eq.pressure), eq.tip_force, True)["K"]
    Jp = model._reduce_vec(model._tip_jacobian(eq.q))
    Cq = np.linalg.solve(model._reduce_mat(K), Jp.T)
    return _c.Compliance(C_p=_c._tool(model, eq, Jp, Cq), C_q=_c._full(model, Cq), active=(), mode="tension",
                         method="friction")


# ------------------------------------------------------------------------------------------------ cycles
def tension_cycle(model: Model, peak_tensions, pressure: float = 0.0, tip_force=(0.0, 0.0, 0.0),
                  steps: int = 10, *, check_limits: bool = True) -> TensionCycle:
    """A quasi-static cycle of the motor tensions 0 → ``peak_tensions`` (m,) [N] → 0 in ``steps`` equal steps
    per branch (2 ≤ steps ≤ 1000), at ``pressure`` [Pa] and ``tip_force`` (3,) [N]: both branches, the
    frictionless curve, the loop's area and the energy friction dissipates (:class:`TensionCycle`)."""
    if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or not 2 <= steps <= 1000:
        raise InputError(f"steps must be an integer in [2, 1000], got {steps!r}")
    Tp = check_finite("peak_tensions", peak_tensions, (model.m,))
    if not np.all(Tp >= 0) or not np.any(Tp > 0):
        raise InputError(f"peak_tensions must be ≥ 0 N with at least one > 0, got {Tp.tolist()}")
    model._check_inputs(Tp, pressure, tip_force, check_limits)
    pr = float(check_scalar("pressure", pressure, unit="Pa"))
    s = int(steps)
    scale = np.concatenate([np.linspace(0.0, 1.0, s + 1), np.linspace(1.0, 0.0, s + 1)[1:]])
    states, st = [], None
    for c in scale:
        st = fk_history(model, c * Tp, pr, tip_force, st, check_limits=check_limits)
        states.append(st)
    tip = np.array([x.tip for x in states])
    lengths = np.array([x.equilibrium.tendon_lengths for x in states])
    free, q0 = [], None
    for c in scale[:s + 1]:
        eq = model.fk(c * Tp, pr, tip_force, q0, check_limits=check_limits)
        free.append(eq.tip)
        q0 = eq.q
    cyc = TensionCycle(scale, states, tip, lengths, np.array(free), 0.0, 0.0, Tp.copy())
    x = scale * float(Tp.max())
    u = cyc.displacement()
    cyc.loop_area = float(abs(0.5 * np.sum(x * np.roll(u, -1) - np.roll(x, -1) * u)))     # shoelace, closed
    Tm = scale[:, None] * Tp[None, :]
    cyc.dissipated_energy = float(-np.sum(0.5 * (Tm[1:] + Tm[:-1]) * np.diff(lengths, axis=0)))
    return cyc


# ------------------------------------------------------------------------------------------------ locked
# The locked law (docstring of fk_locked_history).  A pattern is (taut (m,) bool, codes (m, n) int8): the guide
# codes of the taut tendons; guide k of tendon i stuck (STICK) starts a new span at segment k.
@dataclass
class _Lock:
    """The references of a locked step from state S: segment lengths l_ik(S) (m, n) [m], motor tensions T_S (m,)
    [N], the locked lengths l⁰ (m,) [m] and S's own l⁰_S (m,) [m], the tendons without a segment reference (slack
    at S: one span, its length l⁰), the series compliance cs = 1/k_s [m/N]."""
    lseg: np.ndarray
    T_S: np.ndarray
    l0: np.ndarray
    l0_S: np.ndarray
    noref: np.ndarray
    cs: float


def _spans(codes_i: np.ndarray) -> list:
    """Segment ranges [a, b) of one tendon's spans: the motor span [0, first stuck guide) (empty when guide 0 is
    stuck), then one span from each stuck guide to the next (or the anchor)."""
    cuts = [k for k in range(codes_i.size) if codes_i[k] == tf.STICK]
    ends = cuts + [codes_i.size]
    return [(0, ends[0])] + [(ends[j], ends[j + 1]) for j in range(len(cuts))]


def _layout(taut: np.ndarray, codes: np.ndarray) -> list:
    """[(tendon i, a, b, motor)] in unknown order: each taut tendon's spans, the first its motor span (motor
    True, its unknown the motor tension T_i), the others' unknown the tension of their first segment."""
    return [(i, a, b, j == 0) for i in range(taut.size) if taut[i] for j, (a, b) in enumerate(_spans(codes[i]))]


def _span_lengths(lay: list, ref: _Lock) -> np.ndarray:
    """The held length of each span [m]: its segments' lengths at S; the motor span less the tendon's stretch
    cs T_S, plus the motor's change l⁰ − l⁰_S; a tendon without reference: l⁰.  An empty motor span holds the
    motor tension instead: its row is T_i = T_S − (l⁰ − l⁰_S)/cs (cs = 0: T_S)."""
    out = np.zeros(len(lay))
    for u, (i, a, b, motor) in enumerate(lay):
        if ref.noref[i]:
            out[u] = ref.l0[i]
        elif motor and a == b:
            out[u] = ref.T_S[i] - ((ref.l0[i] - ref.l0_S[i]) / ref.cs if ref.cs > 0 else 0.0)
        else:
            out[u] = ref.lseg[i, a:b].sum() + (ref.l0[i] - ref.l0_S[i] - ref.cs * ref.T_S[i] if motor else 0.0)
    return out


def _locked_tensions(lay, lam, codes, alpha, dalpha, mu, m: int):
    """Segment tensions T (m, n) [N] of the pattern at multipliers ``lam`` (one per span), the unknown of each
    segment (m, n) (−1: slack tendon), ∂T_ik/∂λ (m, n) and ∂T/∂q (m, n, ndof) or None: inside a span each
    slipping guide k multiplies by e^{−c_k μ α_k} (c_k = ±1 its code)."""
    n = codes.shape[1]
    T, which, fac = np.zeros((m, n)), np.full((m, n), -1), np.zeros((m, n))
    dTq = None if dalpha is None else np.zeros((m, n, dalpha.shape[2]))
    for u, (i, a, b, motor) in enumerate(lay):
        f, g = 1.0, 0.0 if dalpha is None else np.zeros(dalpha.shape[2])
        for k in range(a, b):
            if k != a or motor:                   # guide a of a stuck span is its start: no factor
                c = float(codes[i, k])
                f *= math.exp(-c * mu * alpha[i, k])
                if dalpha is not None:
                    g = g - c * mu * dalpha[i, k]
            T[i, k], which[i, k], fac[i, k] = lam[u] * f, u, f
            if dTq is not None:
                dTq[i, k] = T[i, k] * g
    return T, which, fac, dTq


def _locked_eval(model: Model, q, lam, lay, codes, L, mu, pr, F, want_J: bool):
    """Residual (nz + spans,) [N | m], Jacobian or None, and the state's quantities at full coordinates q and
    span multipliers lam; None outside the model's domain."""
    ea, ei = model._coeffs(pr)
    E, Q, K, *_ = assemble(q, model.n, model._N, model._wq, ea, ei, pr * model._vc, model._mg, model._E,
                           model._d, model._co, model._so, np.zeros(model.m), model.params.tool_offset,
                           model.total_tip_load(F), want_J, 0)
    ok, P, G = tf.guide_points(q, model.n, model._E, model._d, model._co, model._so)
    if not (np.isfinite(E) and ok):
        return None
    alpha, dalpha = tf.wrap_angles(P, G, model._e1, model.ndof)
    T, _which, fac, dTq = _locked_tensions(lay, lam, codes, alpha, dalpha if want_J else None, mu, model.m)
    ok, Gs, Hs, lseg, Jseg = tf.segment_forces(q, model.n, model._N, model._wq, model._E, model._d, model._co,
                                               model._so, np.ascontiguousarray(T), want_J)
    if not ok:
        return None
    nu, cs = len(lay), model._cs
    con = np.zeros(nu)
    for u, (i, a, b, motor) in enumerate(lay):
        con[u] = lam[u] - L[u] if motor and a == b else lseg[i, a:b].sum() - (cs * lam[u] if motor else 0.0) - L[u]
    R = np.concatenate([model._reduce_vec(Q + Gs), con])
    out = {"R": R, "J": None, "T": T, "alpha": alpha, "lseg": lseg, "energy": E + float(np.sum(T * lseg))}
    if want_J:
        nz = model.nz
        J = np.zeros((nz + nu, nz + nu))
        J[:nz, :nz] = model._reduce_mat(K + Hs + Jseg.reshape(-1, model.ndof).T @ dTq.reshape(-1, model.ndof))
        for u, (i, a, b, motor) in enumerate(lay):
            if motor and a == b:
                J[nz + u, nz + u] = 1.0
                continue
            J[:nz, nz + u] = model._reduce_vec(fac[i, a:b] @ Jseg[i, a:b])
            J[nz + u, :nz] = model._reduce_vec(Jseg[i, a:b].sum(axis=0))
            J[nz + u, nz + u] = -cs if motor else 0.0
        out["J"] = J
    return out


def _reference(model: Model, state: FrictionState, l0) -> _Lock:
    """The references of a locked step from ``state`` with locked lengths ``l0`` (m,) [m] or None (the state's)."""
    q = state.q
    _ok, _G, _H, lseg, _J = tf.segment_forces(q, model.n, model._N, model._wq, model._E, model._d, model._co,
                                              model._so, np.zeros((model.m, model.n)), False)
    T_S = np.array(state.motor_tensions, float)
    l0_S = (state.locked_lengths if state.locked_lengths is not None
            else lseg.sum(axis=1) - model._cs * T_S)
    l0 = l0_S.copy() if l0 is None else l0
    return _Lock(lseg, T_S, l0, np.array(l0_S, float), T_S <= 0.0, model._cs)


def _initial_pattern(model: Model, ref: _Lock, mu: float, tol_length: float):
    """The first pattern of the loop: the tendons taut at S (or stretched beyond l⁰ by S's shape); every guide
    stuck but guide 0 when the motor moved (it slips the way the motor went); μ = 0 or a tendon without
    reference: every guide slipping (one span)."""
    taut = (ref.T_S > 0) | (ref.lseg.sum(axis=1) > ref.l0 + tol_length)
    codes = np.zeros((model.m, model.n), np.int8)
    for i in range(model.m):
        if mu == 0.0 or ref.noref[i]:
            codes[i] = tf.SLIP_OUT if ref.noref[i] else tf.SLIP_IN
        elif ref.l0[i] != ref.l0_S[i]:
            codes[i, 0] = tf.SLIP_IN if ref.l0[i] < ref.l0_S[i] else tf.SLIP_OUT
    return taut, codes


def _flow(ref: _Lock, lseg, T_i: float, i: int, a: int, k: int, motor: bool) -> float:
    """Tendon length [m] that passed guide k toward the motor since S (its span starts at segment a): the growth
    of the span's part on the motor side of k, plus, in the motor span, the tendon's lost stretch and what the
    motor reeled in."""
    grow = float(np.sum(lseg[i, a:k] - ref.lseg[i, a:k]))
    return grow - ref.cs * (T_i - ref.T_S[i]) + (ref.l0_S[i] - ref.l0[i]) if motor else grow


def _pattern_changes(ref: _Lock, lay, lam, parts, taut, codes, mu: float, tol_length: float) -> bool:
    """Update (taut, codes) in place from a solved pattern; True when something changed: a taut tendon whose
    motor tension is negative goes slack, a slack one stretched beyond l⁰ goes taut (no reference, every guide
    slipping); a stuck guide outside its cone slips the way it is pushed, a slipping guide whose tendon moved
    against its code sticks."""
    T, lseg = parts["T"], parts["lseg"]
    tolT = 1e-8 * max(1.0, float(np.max(np.abs(lam), initial=0.0)))
    changed = False
    motor_T = {i: lam[u] for u, (i, a, b, motor) in enumerate(lay) if motor}
    span_of = {}
    for i, a, b, motor in lay:
        for k in range(a, b):
            span_of[(i, k)] = (a, motor)
    for i in range(taut.size):
        if not taut[i]:
            if lseg[i].sum() > ref.l0[i] + tol_length:
                taut[i], ref.noref[i], changed = True, True, True
                codes[i] = tf.SLIP_OUT if mu > 0 else tf.SLIP_IN
            continue
        if motor_T[i] < -tolT:
            taut[i], changed = False, True
            continue
        if mu == 0.0:
            continue
        for k in range(codes.shape[1]):
            prev = motor_T[i] if k == 0 else T[i, k - 1]
            f = math.exp(mu * parts["alpha"][i, k])
            if codes[i, k] == tf.STICK:
                new = tf.SLIP_IN if T[i, k] < prev / f - tolT else tf.SLIP_OUT if T[i, k] > prev * f + tolT else 0
            elif ref.noref[i]:
                continue
            else:
                a, motor = span_of[(i, k)]
                new = tf.STICK if codes[i, k] * _flow(ref, lseg, motor_T[i], i, a, k, motor) < -tol_length \
                    else codes[i, k]
            if new != codes[i, k]:
                codes[i, k], changed = new, True
    return changed


def _solve_pattern(model: Model, x0, lay, codes, L, mu, pr, F, tol, tol_length, max_iter):
    """Newton/LM (:func:`ancf.solvers.solve_root`) on (z, span multipliers) for one pattern."""
    from .solvers import solve_root
    nz = model.nz
    tension_rows = np.array([motor and a == b for _i, a, b, motor in lay], bool)

    def fun(x):
        parts = _locked_eval(model, model._to_full(x[:nz]), x[nz:], lay, codes, L, mu, pr, F, True)
        if parts is None:
            return np.full(x.size, np.nan), None
        return parts["R"], parts["J"]

    def accept(R):
        c = R[nz:]
        return bool(np.linalg.norm(R[:nz]) < tol and np.max(np.abs(c[~tension_rows]), initial=0.0) < tol_length
                    and np.max(np.abs(c[tension_rows]), initial=0.0) < tol)
    w = np.concatenate([np.ones(nz), np.where(tension_rows, 1.0, model._kscale * model.params.length)])
    x, info = solve_root(fun, x0, tol=min(tol, model._kscale * model.params.length * tol_length), max_iter=max_iter,
                         accept=accept, name="fk_locked_history", weights=w)
    return x, info, _locked_eval(model, model._to_full(x[:nz]), x[nz:], lay, codes, L, mu, pr, F, True)


def _start(lay, state: FrictionState, x_prev, lay_prev) -> np.ndarray:
    """Start multipliers of a pattern: the previous pattern's value of the same span, else the tension of the
    span's first segment at S (the motor tension for a motor span)."""
    old = {} if lay_prev is None else {s: v for s, v in zip(lay_prev, x_prev)}
    return np.array([old.get(s, state.motor_tensions[s[0]] if s[3] else state.segment_tensions[s[0], s[1]])
                     for s in lay], float)


def _locked_stable(model: Model, J, lay) -> tuple[bool, float]:
    """Divergence test of a locked friction state under its held pattern: the tangent with the elastic motor
    spans' multipliers eliminated (λ = ∇l·δz / cs), restricted to the null space of the rigid span rows; stable
    when every eigenvalue has a positive real part.  Returns (stable, the smallest real part)."""
    nz = model.nz
    A = J[:nz, :nz].copy()
    rigid = []
    for u, (_i, a, b, motor) in enumerate(lay):
        if motor and a == b:
            continue
        if motor and model._cs > 0:
            A += np.outer(J[:nz, nz + u], J[nz + u, :nz]) / model._cs
        else:
            rigid.append(J[nz + u, :nz])
    if rigid:
        Qf, _ = np.linalg.qr(np.array(rigid).T, mode="complete")
        Z = Qf[:, len(rigid):]
        A = Z.T @ A @ Z
    low = float(np.min(np.linalg.eigvals(A).real))
    return low > 0, low


def fk_locked_history(model: Model, state: FrictionState, tendon_lengths=None, pressure: float = 0.0,
                      tip_force=(0.0, 0.0, 0.0), *, tol: float | None = None, tol_length: float = 1e-10,
                      max_iter: int = 60, check_limits: bool = True, check_stability: bool = True) -> FrictionState:
    """The next equilibrium of the friction history with the motors locked: from ``state`` (a FrictionState of
    :func:`fk_history` or of this function), the motors holding the tendon lengths ``tendon_lengths`` (m,) [m]
    (None: the state's own, l(q) − T/k_s or the lengths it was locked at), at ``pressure`` [Pa] and ``tip_force``
    (3,) [N].  Returns a :class:`FrictionState` (``equilibrium.tensions`` the motor tensions, ``.slack``,
    ``.active``; ``locked_lengths``).

    The locked law.  The tendon is inextensible inside the actuator (its series compliance 1/k_s, when the
    actuator has ``tendon_stiffness``, lumped between the motor and guide 0); its material is fixed at the motor
    and at every *stuck* guide.  Between two such points (a span) the tendon's length is held — a stuck segment
    is a length constraint, l_ik(q) = l_ik(S) — and its tension is the span's multiplier; at a *slipping* guide
    the tension follows the cone, T_ik = T_i,k−1 e^{∓μα_k} (−: the tendon slides toward the motor, +: away),
    the guide's material flowing through.  The motor span holds Σ l_ik − T_i/k_s at S's value plus the motor's
    change of length (with guide 0 stuck it holds the motor tension instead).  Which guides stick or slip (and
    which tendons are taut) is found by an active-set loop from "every guide stuck, guide 0 slipping the way
    the motor moved": a stuck guide whose tension leaves its cone slips the way it is pushed, a slipping guide
    whose tendon moves against its direction sticks, a tendon whose motor tension turns negative goes slack
    along its whole length, a slack one stretched beyond its locked length goes taut slipping everywhere.
    μ = 0: one span per tendon, Σ_k l_ik − T_i/k_s = l⁰_i — :meth:`ancf.Model.fk_locked`'s equations.

    Raises InputError (bad inputs), ConvergenceError (a solve or the pattern loop fails),
    UnstableEquilibriumError (:func:`_locked_stable` fails, unless ``check_stability=False``)."""
    mu = float(model.params.tendon_friction)
    tol, max_iter = model._check_solver_options(tol, max_iter)
    tol_length = check_scalar("tol_length", tol_length, low=1e-15, high=1e-3, unit="m")
    if not isinstance(state, FrictionState):
        raise InputError(f"state must be a FrictionState (of fk_history or fk_locked_history), got "
                         f"{type(state).__name__}")
    _check_state(model, state, mu)
    l0 = None
    if tendon_lengths is not None:
        l0 = check_finite("tendon_lengths", tendon_lengths, (model.m,))
        if np.any(l0 <= 0) or np.any(l0 > 3 * model.params.length):
            raise InputError(f"tendon_lengths {np.round(l0 * 1e3, 3).tolist()} mm must be positive and below "
                             f"3 × the actuator length ({3e3 * model.params.length:g} mm)")
    _, pr, F = model._check_inputs(None, pressure, tip_force, check_limits)
    ref = _reference(model, state, l0)
    taut, codes = _initial_pattern(model, ref, mu, tol_length)
    x_lam, lay_prev, seen, total = None, None, set(), 0
    for _ in range(8 * model.m * model.n + 8):
        key = (taut.tobytes(), codes.tobytes(), ref.noref.tobytes())
        if key in seen:
            break
        seen.add(key)
        lay = _layout(taut, codes)
        x0 = np.concatenate([model._to_free(state.q), _start(lay, state, x_lam, lay_prev)])
        x, info, parts = _solve_pattern(model, x0, lay, codes, _span_lengths(lay, ref), mu, pr, F, tol, tol_length,
                                        max_iter)
        total += info.iterations
        x_lam, lay_prev = x[model.nz:], lay
        if not _pattern_changes(ref, lay, x_lam, parts, taut, codes, mu, tol_length):
            info.iterations = total
            return _locked_result(model, x, info, parts, lay, ref, codes, taut, mu, pr, F, check_stability)
    raise ConvergenceError("the stick/slip pattern of the locked friction solve cycled", solver="fk_locked_history",
                           iterations=total, residual_norm=float("nan"), tolerance=tol)


def _locked_result(model: Model, x, info, parts, lay, ref, codes, taut, mu, pr, F, check_stability) -> FrictionState:
    q = model._to_full(x[:model.nz])
    T_motor = np.zeros(model.m)
    for u, (i, _a, _b, motor) in enumerate(lay):
        if motor:
            T_motor[i] = max(x[model.nz + u], 0.0)
    lengths = parts["lseg"].sum(axis=1)
    ev = Evaluation(parts["energy"], None, None, lengths, None, float("nan"), None)
    slack = np.where(taut, 0.0, np.maximum(ref.l0 - lengths, 0.0))
    eq = model._result(q, T_motor, pr, F, info, ev, "fk_locked_history", slack=slack,
                       active=tuple(int(i) for i in np.flatnonzero(taut)), H=None)
    eq.stable, low = _locked_stable(model, parts["J"], lay)
    if not eq.stable and check_stability:
        raise UnstableEquilibriumError("the locked friction solve converged to an unstable state (its tangent "
                                       "under the held stick/slip pattern has an eigenvalue with a negative real "
                                       "part)", solver="fk_locked_history", min_eigenvalue=low)
    if mu > 0:                                  # the frictionless compliance forms refuse it
        eq.__dict__["_friction_tangent"] = None
    eq.__dict__["_locked_friction"] = (parts["J"], lay)
    T = np.where(taut[:, None], parts["T"], 0.0)
    sliding = np.where(taut[:, None], codes, 0).astype(np.int8)
    return FrictionState(eq, T, sliding, parts["alpha"], mu, locked_lengths=ref.l0.copy())


def locked_compliance(model: Model, state: FrictionState, load_direction=None, *, probe: float = 1e-3):
    """Tip compliance with the motors locked under friction: C_p (3, 3) [m/N] as
    :class:`ancf.compliance.Compliance` (mode ``"locked"``, method ``"friction"``, ``active`` the taut tendons,
    ``dT_dF`` (m, 3) [N/N] the motor tensions' change), the linearisation of :func:`fk_locked_history` at
    ``state`` with the motors holding the state's lengths.

    Stick and slip make the response one-sided: the pattern (which guides slip, which tendons are taut) is the
    one a small extra load ``probe`` [N] along ``load_direction`` (3,) (default: gravity) finds from the state,
    and C_p is exact for loads along directions that keep that pattern.  With the layout's Jacobian 𝒥 of
    (force rows, span rows) in (z, span multipliers λ) at the state, [δz; δλ] = 𝒥⁻¹ [J_pᵀ; 0] δF.
    μ = 0 (one span per tendon): the exact locked compliance of :func:`ancf.compliance.locked`."""
    from . import compliance as _c
    if not isinstance(state, FrictionState):
        raise InputError(f"locked_compliance needs a FrictionState, got {type(state).__name__}")
    _check_state(model, state, float(model.params.tendon_friction))
    eq = state.equilibrium
    d = np.asarray(model.params.gravity if load_direction is None else load_direction, float)
    if d.shape != (3,) or not np.all(np.isfinite(d)) or np.linalg.norm(d) == 0:
        raise InputError(f"load_direction must be a finite non-zero 3-vector, got {d}")
    probe = check_scalar("probe", probe, low=1e-9, high=1.0, unit="N")
    lock = state.locked_lengths
    first = fk_locked_history(model, state, lock, eq.pressure, eq.tip_force, check_limits=False)
    step = fk_locked_history(model, first, None, eq.pressure, eq.tip_force + probe * d / np.linalg.norm(d),
                             check_limits=False)
    taut = np.zeros(model.m, bool)
    taut[list(step.equilibrium.active)] = True
    lay = _layout(taut, step.sliding)
    ref = _reference(model, first, None)            # the probe's pattern solved at the state's own load: the
    x0 = np.concatenate([model._to_free(first.q), _start(lay, first, None, None)])    # multipliers it implies
    x, _info, parts = _solve_pattern(model, x0, lay, step.sliding, _span_lengths(lay, ref), first.friction,
                                     float(eq.pressure), eq.tip_force, model.default_tol, 1e-12, 60)
    nz = model.nz
    Jp = model._reduce_vec(model._tip_jacobian(model._to_full(x[:nz])))
    rhs = np.vstack([Jp.T, np.zeros((len(lay), 3))])
    X = np.linalg.solve(parts["J"], rhs)
    dT = np.zeros((model.m, 3))
    for u, (i, _a, _b, motor) in enumerate(lay):
        if motor:
            dT[i] = X[nz + u]
    Cq = X[:nz]
    return _c.Compliance(C_p=_c._tool(model, first.equilibrium, Jp, Cq), C_q=_c._full(model, Cq),
                         active=tuple(int(i) for i in np.flatnonzero(taut)), mode="locked", method="friction",
                         dT_dF=dT)


def _locked_layout_jacobian(model: Model, state: FrictionState):
    """(𝒥, layout) of a state of :func:`fk_locked_history`: the Jacobian of (force rows, span rows) in (z, span
    multipliers) under the state's own pattern — kept by the solve, else re-evaluated from the state (the
    multipliers: each motor span's motor tension, each other span's first segment tension)."""
    kept = state.equilibrium.__dict__.get("_locked_friction")
    if kept is not None:
        return kept
    eq = state.equilibrium
    taut = np.zeros(model.m, bool)
    taut[list(eq.active)] = True
    lay = _layout(taut, state.sliding)
    lam = np.array([eq.tensions[i] if motor else state.segment_tensions[i, a] for i, a, _b, motor in lay], float)
    parts = _locked_eval(model, eq.q, lam, lay, state.sliding, np.zeros(len(lay)), state.friction,
                         float(eq.pressure), eq.tip_force, True)
    if parts is None:
        raise InputError("the locked friction state lies outside the model's domain")
    return parts["J"], lay


def locked_length_jacobian(model: Model, state: FrictionState) -> tuple[np.ndarray, np.ndarray]:
    """The motors' lengths' effect on a locked friction step: (∂p/∂l⁰ (3, m) [m/m] of the tool point,
    ∂T/∂l⁰ (m, m) [N/m] of the motor tensions) of :func:`fk_locked_history` at its result ``state``, the
    step's stick/slip pattern held (exact for changes of l⁰ that keep it, e.g. a motor moving on the way it
    moved; the response is one-sided like :func:`locked_compliance`'s).

    Implicit function theorem on the converged step R(x; l⁰) = 0, x = (z, span multipliers λ): only the span
    rows depend on l⁰ — a motor span holds Σ l_ik − c_s T_i = L_u with ∂L_u/∂l⁰_i = 1, an empty motor span
    (guide 0 stuck) T_i = L_u with ∂L_u/∂l⁰_i = −1/c_s (0 without a series stiffness), the other spans none —,
    so with 𝒥 = ∂R/∂x (the layout's Jacobian, as in :func:`locked_compliance`)
    δx = 𝒥⁻¹ [0; ∂L/∂l⁰] δl⁰, δp = (J_p + J_u) δz (J_u the shear compliance's part) and δT_i = δλ of tendon i's motor span.  Slack
    tendons have zero columns and rows.  μ = 0: the derivative of :meth:`ancf.Model.fk_locked`."""
    from . import compliance as _c
    if not isinstance(state, FrictionState) or state.locked_lengths is None:
        raise InputError("locked_length_jacobian needs a FrictionState of fk_locked_history (with its locked "
                         f"lengths), got {type(state).__name__}")
    _check_state(model, state, float(model.params.tendon_friction))
    J, lay = _locked_layout_jacobian(model, state)
    nz = model.nz
    rhs = np.zeros((nz + len(lay), model.m))
    for u, (i, a, b, motor) in enumerate(lay):
        if motor:
            rhs[nz + u, i] = (-1.0 / model._cs if model._cs > 0 else 0.0) if a == b else 1.0
    X = np.linalg.solve(J, rhs)
    eq = state.equilibrium
    Jp = model._reduce_vec(model._tip_jacobian(eq.q))
    sh = _c._shear(model, eq)
    dp = (Jp if sh is None else Jp + sh[0]) @ X[:nz]
    dT = np.zeros((model.m, model.m))
    for u, (i, _a, _b, motor) in enumerate(lay):
        if motor and eq.tensions[i] > 0:
            dT[i] = X[nz + u]
    return dp, dT


# ------------------------------------------------------------------------------------------------ pull-through
def total_wrap(model: Model, q, tendon: int) -> float:
    """W = Σ_k α_ik [rad]: the guides' total wrap of tendon ``tendon`` (0-based) in the shape q (ndof,)."""
    if isinstance(tendon, bool) or not isinstance(tendon, (int, np.integer)) or not 0 <= tendon < model.m:
        raise InputError(f"tendon must be an index in 0..{model.m - 1}, got {tendon!r}")
    return float(_alpha(model, model._q(q))[tendon].sum())


def pull_through(model: Model, q, tendon: int, motor_tensions, mu: float | None = None):
    """The pull-through test in the model: the actuator held in the shape q (ndof,) (its wrap angles fixed),
    tendon ``tendon`` pulled and released by its motor through the tensions ``motor_tensions`` (k,) [N] in that
    order, from slack, the capstan law with history applied at each (:func:`ancf.forces.tendon_friction
    .tension_profile`).  ``mu`` defaults to the actuator's ``tendon_friction``.  Returns (anchor tensions (k,)
    [N] — the last segment's, what a load cell at the anchor reads —, sliding codes (k, n)).  While every guide
    slips, T_anchor / T_motor = e^{∓μW} (W = :func:`total_wrap`: − pulling, + releasing)."""
    total_wrap(model, q, tendon)                              # checks q and tendon
    mu = float(model.params.tendon_friction) if mu is None else float(check_scalar("mu", mu, low=0.0, high=1.0))
    Tm = check_finite("motor_tensions", motor_tensions, None).ravel()
    if Tm.size == 0 or np.any(Tm < 0):
        raise InputError(f"motor_tensions must be ≥ 0 N, at least one, got {Tm.tolist()[:5]}")
    alpha = _alpha(model, model._q(q))[tendon:tendon + 1]
    held = np.zeros((1, model.n))
    anchor, codes = np.zeros(Tm.size), np.zeros((Tm.size, model.n), np.int8)
    for j, t in enumerate(Tm):
        T, code, _, _ = tf.tension_profile(np.array([t]), held, alpha, mu)
        held, anchor[j], codes[j] = T, T[0, -1], code[0]
    return anchor, codes
