r"""Tendon friction in time for tendons HELD BY LENGTH: the capstan law at the routing guides
(docs/friction.md) as an incremental stick/slip problem of the tendon's material, coupled to the
generalized-α step — the dynamic simulated rig's plant with ``tendon_friction`` μ > 0
(:mod:`hardware.sim_dynamics`).

The tendon.  Tendon i runs from its motor through guides k = 0 … n−1 (guide 0 at the base node, guide k at
the start of element k) to its anchor at the tip.  Segment k (over element k) has the geometric length
l_k(q) and holds the unstretched material s_k; its tension is that of a stiff elastic piece,

    T_k = P (l_k − s_k)₊ / s_k,            P = k_in L  [N],   k_in = max(k, 10⁶ N/m)  [N/m],

so the inside of the actuator is nearly inextensible (µm of stretch at a few N: 10⁶ N/m, or the series
spring k if stiffer).
The motor span (motor → guide 0, outside the actuator) carries the series spring k (the actuator's
``tendon_stiffness`` and the plant's, or a stiff penalty for inextensible tendons) and the motor tension

    T_m = min(F_hold, k (X + c − l_m)₊),     X = Σ_k s_k  (the material inside the actuator),

l_m the motor's length, c a rigging constant (set once, so that the start state is an equilibrium), F_hold the
motors' holding force.  Material flows through guide k by f_k (positive toward the anchor); per step

    s_k⁺ = s_k + f_k − f_{k+1}     (f_n = 0 at the anchor; f_0 enters from the motor span, X⁺ = X + f_0).

The capstan cone.  At guide k, between the tension on its motor side T_{k−1} (T_{−1} = T_m) and on its
anchor side T_k:  T_{k−1} e^{−μα_k} ≤ T_k ≤ T_{k−1} e^{μα_k}, α_k(q) the wrap angle.  Stick: f_k = 0 inside
the cone.  Slip: on its edge in the direction of sliding — f_k > 0 (toward the anchor) only with
T_k = T_{k−1} e^{+μα_k}, f_k < 0 only with T_k = T_{k−1} e^{−μα_k}.  The power the guide takes from the
tendon is ḟ_k (T_k − T_{k−1}) ≥ 0: friction only dissipates (per step ΔD = Σ_k f_k (T_k − T_{k−1}), every term
≥ 0 by the slip rule, exactly; over a run it closes the energy balance, :class:`HeldFriction`).

Return mapping (at a state q, from the materials s of the last converged step — the history).  (1)
Predictor: a pattern (every guide stuck, or the last step's), each stuck span keeping its material,
T_k = P(l_k − s_k)₊/s_k, T_m from X.  (2) Check every stuck guide's cone and every slipping guide's direction
(tolerance CONE_TOL).  (3) Release the most violated stuck guide to slip the way its tension pushes (code
c_k = ±1), or re-stick a slipping guide whose material flows against its direction; solve again; repeat.
A time step (:func:`_step`) holds a pattern through its Newton solve (a smooth system, exact tangent), then
checks it at the converged state (tolerance ACCEPT_TOL) and changes the worst violated guide of each tendon only
(a re-stick before a release, so a guide whose slip reverses sticks first: releasing every guide at once at the
fixed state overshoots through the stiff tendon, and the patterns then alternate), and solves again until the
pattern stands (a pattern whose Newton solve fails is retried from every guide stuck; a pattern seen twice: the
step fails and is halved, up to MAX_HALVINGS times).  The loops are compiled (numba) kernels; the public
:func:`return_map`, :func:`tendon_state` and :func:`tension_gradients` check their inputs first.  For a pattern the tendon falls into *spans* between stuck guides (the first
span starts at the motor); in a span every segment's tension is the span's T times the capstan ratios of the
slipping guides it passed, r_k = exp(μ Σ_{j ≤ k, slipping} c_j α_j), and the span's material is conserved:

    inner span a … b−1:   Σ_k l_k P / (P + T r_k) = Σ_k s_k                 (s_k⁺ = l_k P / (P + T r_k))
    motor span 0 … b−1:   T = min(F_hold, k (Σ_{k<b} l_k P / (P + T r_k) + Σ_{k≥b} s_k + c − l_m)₊)

— one scalar equation each, monotone in T (Newton from T = 0 converges monotonically: the left side is convex
decreasing, resp. the motor equation concave increasing).  A span with more material than length is slack
(T = 0): its extra material stays where it was (split in proportion to the segments' old slack), a slack
motor span keeps it outside the actuator.  The fluxes follow backward from the span's stuck end,
f_k = f_{k+1} + s_k⁺ − s_k.

Tangent.  The generalized force of the tendons is Σ_ik T_ik ∇l_ik (as the tension-driven law,
:mod:`.friction_step`), its tangent Σ T_ik ∇²l_ik + Σ ∇l_ik (∇T_ik)ᵀ with ∇T_k = r_k ∇T + T r_k μ Σ c_j ∇α_j
and ∇T from the implicit function theorem on the span equation (pattern held), e.g. for an inner span
∇T = (Σ_k P/(P+Tr_k) ∇l_k − Σ_k l_k P T ∇r_k /(P+Tr_k)²) / Σ_k l_k P r_k /(P+Tr_k)².

μ = 0 never comes here: the dynamic plant keeps :meth:`ancf.Model.simulate`'s frictionless held lengths.
"""

from __future__ import annotations

import math
from typing import Callable, NamedTuple, Optional

import numpy as np
from numba import njit

from ..errors import ConvergenceError, InputError, check_finite
from ..forces import tendon_friction as tf
from .friction_step import wrap_angles
from .integrator import AlphaCoefficients, StepFailed, alpha_step

#: passes of a step's pattern loop (module docstring) and halvings of a step that fails
PATTERN_PASSES, MAX_HALVINGS = 16, 8
#: the inside of the actuator: at least this stiff [N/m] (whole tendon), and as stiff as the series spring
INSIDE_STIFFNESS = 1e6
#: a pattern changes only for a cone violated by more than CONE_TOL (1 + T_max) [N] (or a flux as large
#: against its slip): above the tension error of a converged Newton step, far below any sensor's resolution
CONE_TOL = 1e-6
#: a step's converged pattern is kept unless a cone is violated by more than ACCEPT_TOL (1 + T_max) [N] (or a flux
#: as large runs against its slip): a guide exactly at its cone's edge would otherwise flip stick ↔ slip
#: between two solves of the step whose tensions differ by the Newton tolerance through the stiff tendon
ACCEPT_TOL = 1e-4


#: the kind of a span's tension (:func:`_span_tension`): taut, slack (T = 0), or capped at the holding force
TAUT, SLACK, CAPPED = 0, 1, 2


@njit(cache=True)
def _span_tension(l, r, a, b, P, material, motor, k, F_hold, rest):
    """(T [N], kind) of the span a … b−1 (module docstring): segment lengths l (n,) [m], capstan ratios r (n,),
    P [N]; an inner span's ``material`` [m], or the motor span's k [N/m], F_hold [N] and rest [m] =
    Σ_{k≥b} s_k + c − l_m.  Newton on T from 0 (monotone: module docstring) to 1e-10 (1 + T) N (the round-off
    of Σ l_k P/(P + T r_k) − S is ~1e-18 m, i.e. 1e-10 N)."""
    L = 0.0
    for j in range(a, b):
        L += l[j]
    if (L + rest <= 0.0) if motor else (L <= material):
        return 0.0, SLACK
    T = 0.0
    for _ in range(30):
        sw = 0.0
        dw = 0.0                                             # −∂(Σ l P/(P + T r))/∂T
        for j in range(a, b):
            w = P / (P + T * r[j])
            sw += l[j] * w
            dw += l[j] * w * w * r[j]
        dw /= P
        dT = -(T - k * (sw + rest)) / (1.0 + k * dw) if motor else (sw - material) / dw
        T += dT
        if abs(dT) <= 1e-10 * (1.0 + T):
            break
    if T >= F_hold:
        return F_hold, CAPPED
    return T, TAUT


@njit(cache=True)
def _span_materials(l, s, r, a, b, P, Ts, kind, motor, s_new, f):
    """The span's materials s⁺ (n,) and fluxes f (n,) [m] (module docstring), in place: a taut span's from its
    tension Ts [N]; a slack one keeps its extra material where it was (the motor span: outside)."""
    if kind != SLACK:
        for j in range(a, b):
            s_new[j] = l[j] * P / (P + Ts * r[j])
    elif motor:
        for j in range(a, b):
            s_new[j] = l[j]
    else:
        extra, wsum, lsum = 0.0, 0.0, 0.0
        for j in range(a, b):
            extra += s[j] - l[j]
            wsum += max(s[j] - l[j], 0.0)
            lsum += l[j]
        for j in range(a, b):
            w = max(s[j] - l[j], 0.0) / wsum if wsum > 0 else l[j] / lsum
            s_new[j] = l[j] + extra * w
    acc = 0.0
    for j in range(b - 1, a - 1, -1):
        acc += s_new[j] - s[j]
        f[j] = acc if (motor or j > a) else 0.0


@njit(cache=True)
def _tendon_state(l, alpha, s, c, lm, k, P, mu, F_hold, codes, T, s_new, f, r, span_T, span_b, kind):
    """One tendon under the pattern ``codes`` (n,) (module docstring), in place: segment tensions T (n,) [N],
    materials s⁺ and fluxes f (n,) [m], capstan ratios r (n,); per segment its span's tension span_T [N], end
    span_b and kind (TAUT/SLACK/CAPPED, + 4 in the motor span).  Returns the motor tension T_m [N]."""
    n = l.size
    Tm = 0.0
    a = 0
    motor = True
    while True:
        b = a if motor else a + 1                # an inner span starts at its stuck guide a
        while b < n and codes[b] != 0:
            b += 1
        e = 0.0
        for j in range(a, b):
            e += codes[j] * alpha[j]
            r[j] = math.exp(mu * e)
        rest, material = c - lm, 0.0
        for j in range(b, n):
            rest += s[j]
        for j in range(a, b):
            material += s[j]
        Ts, kd = _span_tension(l, r, a, b, P, material, motor, k if motor else 0.0, F_hold if motor else np.inf,
                               rest if motor else 0.0)
        if motor:
            Tm = Ts
        _span_materials(l, s, r, a, b, P, Ts, kd, motor, s_new, f)
        for j in range(a, b):
            T[j] = Ts * r[j]
            span_T[j] = Ts
            span_b[j] = b
            kind[j] = kd + (4 if motor else 0)
        if b >= n:
            return Tm
        a, motor = b, False


@njit(cache=True)
def _violations(l, alpha, mu, P, codes, T, Tm, f, kind, tol_rel):
    """(guide to release, its slip direction, guide to re-stick), −1 / 0 for none: the worst stuck guide
    outside its cone by more than tol = tol_rel (1 + T_max) [N], else-wise the worst slipping guide whose
    material runs against its slip by a flux that changes its segment's tension by more than tol (f P / l)."""
    n = l.size
    Tmax = Tm
    for j in range(n):
        Tmax = max(Tmax, T[j])
    tol = tol_rel * (1.0 + Tmax)
    release, direction, worst = -1, 0, tol
    stick, worst_f = -1, tol
    for j in range(n):
        Tin = Tm if j == 0 else T[j - 1]
        if codes[j] == 0:
            v_up = T[j] - Tin * math.exp(mu * alpha[j])
            v_dn = Tin * math.exp(-mu * alpha[j]) - T[j]
            if v_up > worst:
                release, direction, worst = j, 1, v_up
            if v_dn > worst:
                release, direction, worst = j, -1, v_dn
        elif kind[j] % 4 != SLACK:
            back = -codes[j] * f[j] * P / l[j]
            if back > worst_f:
                stick, worst_f = j, back
    return release, direction, stick


@njit(cache=True)
def _return_map(l, alpha, s, c, lm, k, P, mu, F_hold, codes, changes, tol_rel, T, s_new, f, r, span_T, span_b,
                kind):
    """The return mapping of one tendon (module docstring) from the pattern ``codes`` (n,), changed in place by
    at most ``changes`` guides (0: kept, unchecked; 1: the worst violation only, the state left at the old
    pattern), the state in the arrays of :func:`_tendon_state`.  Returns (T_m [N], settled): not settled when
    the pattern loop revisits a pattern or runs out of passes."""
    n = l.size
    passes = 4 * n + 8
    seen = np.empty((passes, n), dtype=np.int64)
    for it in range(passes):
        Tm = _tendon_state(l, alpha, s, c, lm, k, P, mu, F_hold, codes, T, s_new, f, r, span_T, span_b, kind)
        if it == changes:
            return Tm, True
        release, direction, stick = _violations(l, alpha, mu, P, codes, T, Tm, f, kind, tol_rel)
        if release < 0 and stick < 0:
            return Tm, True
        seen[it] = codes
        if stick >= 0:
            codes[stick] = 0
        else:
            codes[release] = direction
        for p in range(it + 1):
            same = True
            for j in range(n):
                if seen[p, j] != codes[j]:
                    same = False
                    break
            if same:
                return Tm, False
        if it + 1 == changes:
            return Tm, True
    return 0.0, False


@njit(cache=True)
def _tension_gradients(l, dl, dalpha, mu, P, k, codes, r, span_T, span_b, kind, dT):
    """∂T_k/∂q (n, ndof) of one tendon with its pattern held (module docstring), in place; dl, dalpha (n, ndof)
    the gradients of the segment lengths and wrap angles, the span data of :func:`_tendon_state`."""
    n, ndof = dl.shape
    de = np.empty(ndof)
    num = np.empty(ndof)
    a = 0
    while a < n:
        b = span_b[a]
        kd, motor, Ts = kind[a] % 4, kind[a] >= 4, span_T[a]
        if kd != TAUT:
            dT[a:b] = 0.0
            a = b
            continue
        de[:] = 0.0
        num[:] = 0.0
        wT = 0.0
        for j in range(a, b):
            de += codes[j] * dalpha[j]                             # ∂(Σ c_i α_i)/∂q, then ∂r_j = μ r_j ∂(…)
            den = P + Ts * r[j]
            num += (P / den) * dl[j] - (l[j] * P * Ts / den ** 2) * mu * r[j] * de
            wT -= l[j] * P * r[j] / den ** 2
        dTs = k * num / (1.0 - k * wT) if motor else -num / wT
        de[:] = 0.0
        for j in range(a, b):
            de += codes[j] * dalpha[j]
            dT[j] = r[j] * dTs + Ts * mu * r[j] * de
        a = b


@njit(cache=True)
def _solve_tendons(l, alpha, s, c, lm, k, P, mu, F_hold, codes, changes, tol_rel, want_dq, J, dalpha):
    """Every tendon's return mapping (:func:`_return_map`; ``codes`` (m, n) in place) and, when ``want_dq``, its
    tension gradients: (T (m, n) [N], T_m (m,) [N], s⁺, f (m, n) [m], dT (m, n, ndof), settled).  l, alpha, s
    (m, n); c, lm (m,); J, dalpha (m, n, ndof)."""
    m, n = l.shape
    ndof = J.shape[2]
    T, s_new, f = np.zeros((m, n)), np.zeros((m, n)), np.zeros((m, n))
    Tm = np.zeros(m)
    dT = np.zeros((m, n, ndof if want_dq else 0))
    r, span_T = np.empty(n), np.empty(n)
    span_b, kind = np.empty(n, dtype=np.int64), np.empty(n, dtype=np.int64)
    for i in range(m):
        Tm[i], ok = _return_map(l[i], alpha[i], s[i], c[i], lm[i], k, P, mu, F_hold, codes[i], changes, tol_rel,
                                T[i], s_new[i], f[i], r, span_T, span_b, kind)
        if not ok:
            return T, Tm, s_new, f, dT, False
        if want_dq:
            _tension_gradients(l[i], J[i], dalpha[i], mu, P, k, codes[i], r, span_T, span_b, kind, dT[i])
    return T, Tm, s_new, f, dT, True


class Spans(NamedTuple):
    """A pattern's spans, per segment (n,) of one tendon: the capstan ratio r, its span's tension span_T [N],
    the span's end span_b (index past its last segment) and kind (TAUT/SLACK/CAPPED, + 4 in the motor span)."""
    r: np.ndarray
    span_T: np.ndarray
    span_b: np.ndarray
    kind: np.ndarray


def _tendon_inputs(l, alpha, s, c, lm, k, P, mu, F_hold, codes):
    """The arguments of :func:`tendon_state` checked and converted for the kernels (InputError otherwise)."""
    l = check_finite("segment lengths l", l)
    if l.ndim != 1 or l.size == 0 or not np.all(l > 0):
        raise InputError(f"segment lengths l must be a non-empty 1-D array of lengths > 0 m, got {l!r}")
    n = l.size
    alpha, s = check_finite("wrap angles alpha", alpha, (n,)), check_finite("materials s", s, (n,))
    if not (np.all(alpha >= 0) and np.all(s > 0)):
        raise InputError("wrap angles must be ≥ 0 rad and materials s > 0 m")
    c, lm, k, P, mu = (float(check_finite(nm, v, ())) for nm, v in
                       (("c", c), ("lm", lm), ("k", k), ("P", P), ("mu", mu)))
    F_hold = float(F_hold)
    if not (k > 0 and P > 0 and mu >= 0 and F_hold > 0):
        raise InputError(f"need k > 0 N/m, P > 0 N, μ ≥ 0, F_hold > 0 N (inf: none), got {k}, {P}, {mu}, {F_hold}")
    codes = np.zeros(n, dtype=np.int64) if codes is None else np.array(codes, dtype=np.int64).reshape(-1)
    if codes.size != n or not np.all(np.abs(codes) <= 1):
        raise InputError(f"a guide pattern is (n,) = ({n},) codes in {{-1, 0, 1}}, got {codes!r}")
    return l, alpha, s, c, lm, k, P, mu, F_hold, codes


def tendon_state(l, alpha, s, c, lm, k, P, mu, F_hold, codes):
    """The tendon under one guide pattern ``codes`` (n,) (0 stuck, ±1 slipping): (T (n,) [N] segment tensions,
    T_m [N] motor tension, s⁺ (n,) [m] materials, f (n,) [m] fluxes, :class:`Spans`).  l, alpha (n,) segment
    lengths [m] and wrap angles [rad]; s (n,) held materials [m]; c, lm [m]; k [N/m]; P [N]; μ; F_hold [N]."""
    return return_map(l, alpha, s, c, lm, k, P, mu, F_hold, codes, hold=True)[1]


def return_map(l, alpha, s, c, lm, k, P, mu, F_hold, codes0=None, hold=False, cone_tol=None):
    """The return mapping of one tendon (module docstring): (codes (n,), and :func:`tendon_state`'s tuple) from
    the predictor pattern ``codes0`` (None: every guide stuck); ``hold``: that pattern as it is, unchecked;
    ``cone_tol`` the relative tolerance (default CONE_TOL).  StepFailed when the pattern loop does not settle."""
    l, alpha, s, c, lm, k, P, mu, F_hold, codes = _tendon_inputs(l, alpha, s, c, lm, k, P, mu, F_hold, codes0)
    n = l.size
    T, s_new, f, r, span_T = (np.zeros(n) for _ in range(5))
    span_b, kind = np.zeros(n, dtype=np.int64), np.zeros(n, dtype=np.int64)
    Tm, ok = _return_map(l, alpha, s, c, lm, k, P, mu, F_hold, codes, 0 if hold else 4 * n + 8,
                         CONE_TOL if cone_tol is None else float(cone_tol), T, s_new, f, r, span_T, span_b, kind)
    if not ok:
        raise StepFailed("the guides' stick/slip pattern did not settle")
    return codes, (T, Tm, s_new, f, Spans(r, span_T, span_b, kind))


def tension_gradients(l, dl, dalpha, mu, P, k, spans: Spans, codes) -> np.ndarray:
    """∂T_k/∂q (n, ndof) of one tendon with its pattern held (module docstring): l (n,) [m], dl, dalpha
    (n, ndof) the gradients of the segment lengths and wrap angles; ``spans`` and ``codes`` of
    :func:`return_map`."""
    dl = check_finite("dl", dl)
    dT = np.zeros(dl.shape)
    _tension_gradients(check_finite("l", l, (dl.shape[0],)), dl, check_finite("dalpha", dalpha, dl.shape),
                       float(mu), float(P), float(k), np.asarray(codes, dtype=np.int64), *spans, dT)
    return dT


class HeldFriction:
    """The tendons' material history of the held-length friction law (module docstring) and the forces it
    gives; plays the part of :class:`.friction_step.FrictionHistory` in a time step (``forces``, ``commit``).

    model: the actuator (μ = ``params.tendon_friction`` > 0); k [N/m] the series spring of the motor span;
    F_hold [N] the motors' holding force (inf: they never give way).  State: ``s`` (m, n) [m] the materials,
    ``c`` (m,) [m] the rigging constants, ``codes`` (m, n) the last step's pattern, ``motor_tensions`` (m,) [N];
    ``lm`` (m,) [m] the motor lengths of the step being solved.  Energy bookkeeping [J] over committed steps:
    ``dissipated`` = Σ f_k (T_k − T_{k−1}) ≥ 0, ``motor_work`` = −Σ ½(T_m + T_m⁺)(l_m⁺ − l_m),
    ``damping_dissipated`` (:func:`advance`)."""

    def __init__(self, model, k: float, F_hold: float = math.inf):
        self.model, self.mu = model, float(model.params.tendon_friction)
        if not self.mu > 0:
            raise InputError("HeldFriction is the law with tendon friction: the actuator has tendon_friction = 0")
        self.k, self.F_hold = float(k), float(F_hold)
        self.P = max(self.k, INSIDE_STIFFNESS) * model.params.length
        m, n = model.m, model.n
        self.s, self.c = np.zeros((m, n)), np.zeros(m)
        self.codes = np.zeros((m, n), dtype=np.int64)
        self.trial = self.codes                          # the step's pattern (module docstring)
        self.motor_tensions, self.lm, self.lm_done = np.zeros(m), np.zeros(m), np.zeros(m)
        self.dissipated = self.motor_work = self.damping_dissipated = 0.0
        self.kinetic_energy = 0.0                        # ½ q̇ᵀ M q̇ [J] at the end of the last :func:`advance`

    def start(self, q: np.ndarray, segment_tensions: np.ndarray, motor_tensions: np.ndarray, lm: np.ndarray):
        """Start at rest at an equilibrium q with the given segment and motor tensions (m, n), (m,) [N] (e.g. a
        :class:`ancf.friction.FrictionState`'s) and motor lengths lm (m,) [m]: materials s = l P/(P + T), and
        c so that the motor span carries its tension (a slack tendon: the least c ≤ 0 that keeps it slack)."""
        lseg = self._lengths(q)[0]
        T = np.asarray(segment_tensions, float)
        self.s = lseg * self.P / (self.P + T)
        X = self.s.sum(axis=1)
        Tm = np.asarray(motor_tensions, float)
        self.c = np.where(Tm > 0, Tm / self.k - (X - lm), np.minimum(0.0, lm - X))
        self.lm, self.lm_done = np.array(lm, float), np.array(lm, float)
        self.motor_tensions = Tm.copy()

    def _lengths(self, q):
        model = self.model
        ok, _G, _H, lseg, Jseg = tf.segment_forces(q, model.n, model._N, model._wq, model._E, model._d, model._co,
                                                   model._so, np.zeros((model.m, model.n)), False)
        if not ok:
            raise StepFailed(f"the state left the model's domain ({model.inadmissibility(q)})")
        return lseg, Jseg

    def solve(self, q: np.ndarray, want_dq: bool, hold: bool = False, cone_tol=None, changes=None):
        """The tendons at q under the step's pattern :attr:`trial` (``hold``), or the return mapping at q
        started from it (module docstring; relative tolerance ``cone_tol``, default CONE_TOL; at most ``changes``
        guides per tendon, the state then left at the old pattern), every tendon:
        dict with T (m, n), Tm (m,), s, f (m, n), codes (m, n) and, when ``want_dq``, dT (m, n, ndof) and the
        segment-length gradients J (m, n, ndof).  One compiled call (:func:`_solve_tendons`)."""
        m = self.model
        ok, Pg, Gg = tf.guide_points(q, m.n, m._E, m._d, m._co, m._so)
        if not ok:
            raise StepFailed("the state left the model's domain (a node's section frame is undefined)")
        alpha, dalpha = wrap_angles(Pg, Gg, m._e1, m.ndof)
        lseg, Jseg = self._lengths(q)
        codes = np.array(self.trial, dtype=np.int64)
        T, Tm, s, f, dT, ok = _solve_tendons(lseg, alpha, self.s, self.c, self.lm, self.k, self.P, self.mu,
                                             self.F_hold, codes, 0 if hold else (4 * m.n + 8 if changes is None
                                                                                else int(changes)),
                                             CONE_TOL if cone_tol is None else float(cone_tol), bool(want_dq),
                                             Jseg, dalpha)
        if not ok:
            raise StepFailed("the guides' stick/slip pattern did not settle")
        out = {"T": T, "Tm": Tm, "s": s, "f": f, "codes": codes}
        if want_dq:
            out["dT"], out["J"] = dT, Jseg
        return out

    def forces(self, q: np.ndarray, _T_motor, pr: float, F) -> tuple[np.ndarray, np.ndarray]:
        """(Q (ndof,) [N], K (ndof, ndof) [N/m]): the model's generalized force at q with the tendons' segment
        forces of the law and its tangent (the pattern :attr:`trial` held), at pressure pr [Pa] and tip force
        F (3,) [N]."""
        model = self.model
        ev = model._evaluate(q, None, pr, F, True, 1.0, False)              # every tendon slack
        if not np.isfinite(ev.energy):
            raise StepFailed(f"the state left the model's domain ({model.inadmissibility(q)})")
        out = self.solve(q, True, hold=True)
        ok, Gs, Hs, _l, _J = tf.segment_forces(q, model.n, model._N, model._wq, model._E, model._d, model._co,
                                               model._so, out["T"], True)
        if not ok:
            raise StepFailed(f"the state left the model's domain ({model.inadmissibility(q)})")
        J = out["J"].reshape(-1, model.ndof)
        return ev.Q + Gs, ev.K + Hs + J.T @ out["dT"].reshape(-1, model.ndof)

    def commit(self, q: np.ndarray, _T_motor=None) -> None:
        """A step to q converged (motor lengths ``lm``): its materials become the history; the energy books."""
        out = self.solve(q, False, hold=True)          # the pattern the step converged with
        Tin = np.concatenate([out["Tm"][:, None], out["T"][:, :-1]], axis=1)
        self.dissipated += float(np.sum(out["f"] * (out["T"] - Tin)))
        self.motor_work -= float(np.sum(0.5 * (self.motor_tensions + out["Tm"]) * (self.lm - self.lm_done)))
        self.s, self.codes, self.motor_tensions = out["s"], out["codes"], out["Tm"]
        self.lm_done = self.lm.copy()

    def tendon_energy(self, q: np.ndarray) -> float:
        """Elastic energy [J] of the tendons at q with the committed materials, stuck (the motor span's
        ½ k e² up to F_hold, linear beyond; the segments' P (l − s)₊² / (2 s))."""
        lseg = self._lengths(q)[0]
        e = np.maximum(self.s.sum(axis=1) + self.c - self.lm_done, 0.0)
        ec = np.minimum(e, self.F_hold / self.k)
        motor = 0.5 * self.k * ec ** 2 + (self.F_hold * (e - ec) if math.isfinite(self.F_hold) else 0.0)
        return float(np.sum(motor) + np.sum(self.P * np.maximum(lseg - self.s, 0.0) ** 2 / (2.0 * self.s)))


def _step(plant, law: HeldFriction, st, tt: float, pr: float, t1: float, lengths_at, coeff):
    """(state, pressure [Pa]) at t1 from st at tt [s]: the step's stick/slip pattern loop (module docstring)
    around the generalized-α Newton solve with the pattern held; StepFailed when it does not settle."""
    loads, model = plant.loads, plant.model
    pr1 = loads.pressure_at(t1, tt, pr)
    law.lm = np.array(lengths_at(t1), float)
    system = plant.system(t1, np.zeros(model.m), pr1, loads.F_sig(t1), None)
    law.trial = law.codes.copy()
    seen = set()
    for _ in range(PATTERN_PASSES):
        try:
            st_new, _k = alpha_step(st, t1 - tt, coeff, system, rtol=1e-14, atol=0.0, vtol=1e-7, max_iter=12)
        except StepFailed:
            if not np.any(law.trial) or np.zeros(1, law.trial.dtype).tobytes() * law.trial.size in seen:
                raise
            seen.add(law.trial.tobytes())
            law.trial = np.zeros_like(law.trial)        # a slip pattern with no solution: from every guide stuck
            continue
        q = model._to_full(st_new.z)
        codes = law.solve(q, False, cone_tol=ACCEPT_TOL, changes=1)["codes"]   # the worst guide of each tendon
        if np.array_equal(codes, law.trial):
            law.commit(q)
            C = plant.C_R                       # the Rayleigh damping's ∫ żᵀ C_R ż dt, trapezoid over the step
            if C is not None:
                law.damping_dissipated += 0.5 * (t1 - tt) * float(st.v @ C @ st.v + st_new.v @ C @ st_new.v)
            return st_new, pr1
        seen.add(law.trial.tobytes())
        law.trial = codes
        if codes.tobytes() in seen:
            break
    raise StepFailed("the guides' stick/slip pattern of the step did not settle")


def _advance_to(plant, law, st, tt, pr, t1, lengths_at, coeff, depth=0):
    """:func:`_step`, halved (recursively, up to MAX_HALVINGS times) where it fails; ConvergenceError after."""
    try:
        return _step(plant, law, st, tt, pr, t1, lengths_at, coeff)
    except StepFailed as exc:
        if depth >= MAX_HALVINGS:
            raise ConvergenceError(f"held-length friction: at t = {t1:.6g} s the step did not converge even halved "
                                   f"{depth} times (h = {t1 - tt:.3g} s): {exc.reason}", solver="simulate",
                                   iterations=exc.iterations, residual_norm=exc.residual,
                                   tolerance=max(plant.model.default_tol, 1e-10)) from None
    tm = 0.5 * (tt + t1)
    st, pr = _advance_to(plant, law, st, tt, pr, tm, lengths_at, coeff, depth + 1)
    return _advance_to(plant, law, st, tm, pr, t1, lengths_at, coeff, depth + 1)


def advance(model, law: HeldFriction, t_end: float, dt: float, q0: np.ndarray, v0: np.ndarray,
            lengths_at: Callable[[float], np.ndarray], pressure: float, pressure_tau: Optional[float],
            pressure0: Optional[float], tip_force: Callable[[float], np.ndarray], damping: dict,
            rho_inf: float) -> list:
    """Integrate from q0, v0 (ndof,) over t ∈ [0, t_end] [s] in steps dt [s] with the motors at
    ``lengths_at(t)`` (m,) [m], the pressure set-point [Pa] (through a supply of time constant
    ``pressure_tau`` [s] from ``pressure0``, or at once), the tip force ``tip_force(t)`` (3,) [N] and the
    damping {alpha [1/s], beta [s], axial [N s]}: the generalized-α steps of :meth:`ancf.Model.simulate`
    (its equations of motion and damping) with the tendons' forces of ``law``, each step inside its pattern
    loop and halved where it fails.  Returns rows (t [s], q, v, tip (3,) [m], motor tensions (m,) [N],
    pressure [Pa]), t > 0 only; ``law`` is left at the last step (its history and energy books), and
    ``law.damping_dissipated`` [J] adds the Rayleigh damping's ∫ żᵀ C_R ż dt (trapezoid over each step taken),
    ``law.kinetic_energy`` [J] is the last row's.
    ConvergenceError when a step fails."""
    from .transient import _initial_acceleration, _initial_pressure, _make_loads, _make_plant, _start_state
    loads = _make_loads(model, np.zeros(model.m), None, pressure, tip_force, pressure_tau, None, None, False)
    p_init = _initial_pressure(loads, pressure0)
    z, vz = _start_state(model, loads, q0, v0, p_init)
    law.lm = np.array(lengths_at(0.0), float)
    law.trial = law.codes.copy()
    plant, _coeffs = _make_plant(model, loads, z, p_init, damping)
    plant.friction = law
    st = _initial_acceleration(plant, loads, z, vz, p_init)
    coeff = AlphaCoefficients.from_rho(rho_inf)
    steps = max(1, int(round(t_end / dt)))
    rows, tt, pr = [], 0.0, p_init
    for j in range(1, steps + 1):
        t1 = t_end if j == steps else j * dt
        st, pr = _advance_to(plant, law, st, tt, pr, t1, lengths_at, coeff)
        q = model._to_full(st.z)
        rows.append((t1, q, plant.full_v(st.v), model._tip(q), law.motor_tensions.copy(), float(pr)))
        tt = t1
    v = rows[-1][2]
    law.kinetic_energy = 0.5 * float(v @ plant.mass_full(rows[-1][1])[0] @ v)
    return rows
