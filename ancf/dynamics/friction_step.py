r"""Tendon friction in time: the capstan law of :mod:`ancf.forces.tendon_friction` as the guides' history
through a transient run (:meth:`ancf.Model.simulate` with ``tendon_friction`` μ > 0).

History.  Between two time steps the guides' stick/slip state is the history, as between two static states
of :func:`ancf.friction.fk_history`: the step n → n+1 keeps the segment tensions H_ik = T_ik(t_n) of the step
before, and at the new state q_{n+1} the tension of segment k of tendon i is, walking from the motor,

    T_ik = clip(H_ik, T_i,k−1 e^{−μ α_ik(q)}, T_i,k−1 e^{μ α_ik(q)}),      T_i,−1 = T_i (the motor tension),

the law's slip toward the motor below the cone, reverse slip above it, stick inside (a stuck segment keeps
its tension).  T_i is the prescribed motor tension.  After a step converges its tensions at q_{n+1} become the held
ones of the next step (:meth:`FrictionHistory.commit`); a step that fails (and is halved) leaves them as
they were.  A step is a small quasi-static step of the law, so a slow run walks through ``fk_history``'s
states (tested: the quasi-static limit of a slow, strongly damped run).

Forces.  In the equations of motion the frictionless tendon force Σ_i T_i ∇l_c,i is replaced by the
segments' Q_f = Σ_ik T_ik ∇l_ik, and the iteration matrix's stiffness part gets the law's exact,
non-symmetric tangent

    ∂Q_f/∂q = Σ_ik T_ik ∇²l_ik + Σ_ik ∇l_ik (∂T_ik/∂q)ᵀ.

Tendons held by length (``lengths=``) are refused with friction: with the motors holding the lengths a stuck
guide fixes the tendon's material, so a stuck span keeps its *length* (:func:`ancf.friction.fk_locked_history`),
not its tension as in this law; a time-stepped form of that locked law is not implemented.

Energy.  The run's potential keeps the motors' load potential Σ_i T_i l_c,i, whose
gradient is Σ_i T_i ∇l_c,i; the difference to the force the actuator feels does work at the rate
Σ_ik (T_i − T_ik) l̇_ik, so the energy balance E + D = const holds with the friction's dissipated energy

    D_f = ∫ Σ_ik (T_ik − T_i) dl_ik        (trapezoidal rule in l_ik between output points),

which over a closed quasi-static cycle is −Σ_i ∮ T_i dl_c,i, the static :func:`ancf.friction.tension_cycle`'s
dissipated energy (the segments' forces do no net work around a closed path of equilibria).

Routing: rows with friction are made by the Python path only (:class:`~ancf.dynamics.transient._FastRows`
is not used); μ = 0 makes no :class:`FrictionHistory` at all, so such runs are the frictionless ones, bit for bit.
"""

from __future__ import annotations

from typing import Optional

import numpy as np

from numba import njit

from ..errors import InputError, check_finite
from ..forces import tendon_friction as tf
from .integrator import StepFailed


def friction_history(model, loads, segment_tensions) -> Optional["FrictionHistory"]:
    """The run's :class:`FrictionHistory`, or None when the actuator has no tendon friction (μ = 0).

    ``segment_tensions`` (m, n) [N]: the guides' held tensions at the start state (e.g. a
    :class:`ancf.friction.FrictionState`'s ``segment_tensions`` or a run's last row); None: every segment slack
    before the run, as :func:`ancf.friction.fk_history`'s ``state=None`` (a run from q0 = None then starts at
    rest on that history, :meth:`FrictionHistory.start`).  InputError for tensions given to a frictionless actuator, of the wrong shape or negative, and
    for tendons held by length (module docstring)."""
    mu = float(model.params.tendon_friction)
    if mu == 0.0:
        if segment_tensions is not None:
            raise InputError("segment_tensions is the guides' history of tendon friction: this actuator has "
                             "tendon_friction = 0")
        return None
    if loads.length_mode:
        raise InputError(f"tendon friction (tendon_friction = {mu:g}) with tendons held by length (lengths=) is "
                         "not modelled in time: held lengths make stuck spans keep their length "
                         "(ancf.friction.fk_locked_history), a law with no time-stepped form here; drive the "
                         "tendons by tensions= or use an actuator without tendon_friction")
    hist = FrictionHistory(model, mu)
    if segment_tensions is None:
        held = np.zeros((model.m, model.n))
    else:
        held = check_finite("segment_tensions", segment_tensions, (model.m, model.n))
        if np.any(held < 0):
            raise InputError(f"segment_tensions must be ≥ 0 N (a tendon cannot push), got min {held.min():g} N")
    hist.held0 = np.array(held, float)
    hist.reset()
    return hist


class FrictionHistory:
    """The guides' held segment tensions through a run and the tendon forces they give (module docstring).
    ``held`` (m, n) [N]: the tensions of the last committed step; ``held0`` those at t = 0."""

    def __init__(self, model, mu: float):
        self.model, self.mu = model, mu
        self.held0 = np.zeros((model.m, model.n))
        self.held = self.held0.copy()

    def start(self, loads, pressure: float, check_limits: bool) -> np.ndarray:
        """The start q (ndof,) of a run given no q0: the friction history's equilibrium of the loads at t = 0
        (:func:`ancf.friction.fk_history` from the held tensions — from slack by default), whose segment tensions
        become the held ones: the run starts at rest."""
        from ..friction import FrictionState, fk_history
        m = self.model
        prev = None
        if np.any(self.held0 > 0):               # given tensions: a step of the history from them
            eq = m.fk(loads.T_sig(0.0), pressure, loads.F_sig(0.0), check_limits=check_limits)
            prev = FrictionState(eq, self.held0, np.zeros((m.m, m.n), np.int8), np.zeros((m.m, m.n)), self.mu)
        st = fk_history(m, loads.T_sig(0.0), pressure, loads.F_sig(0.0), prev, check_limits=check_limits)
        self.held0 = np.array(st.segment_tensions, float)
        self.reset()
        return st.q

    def reset(self) -> None:
        """Back to the start's history (a run repeated in substeps starts again from t = 0)."""
        self.held = self.held0.copy()

    def _profile(self, q: np.ndarray, T_motor: np.ndarray, want_dq: bool):
        """(T, codes, ∂T/∂q or None, ∂T/∂T_i) of the law at q from the held tensions; StepFailed outside the
        model's domain (an undefined section frame at a node)."""
        m = self.model
        ok, P, G = tf.guide_points(q, m.n, m._E, m._d, m._co, m._so)
        if not ok:
            raise StepFailed("the state left the model's domain (a node's section frame is undefined)")
        alpha, dalpha = wrap_angles(P, G, m._e1, m.ndof)
        return tf.tension_profile(T_motor, self.held, alpha, self.mu, dalpha if want_dq else None)

    def forces(self, q: np.ndarray, T_motor, pr: float, F) -> tuple[np.ndarray, np.ndarray]:
        """(Q (ndof,) [N], K (ndof, ndof) [N/m]): the model's generalized force at q with the tendons' segment
        forces of the law (module docstring) and its exact tangent, at motor tensions T_motor (m,) [N], pressure
        pr [Pa], tip force F (3,) [N].  StepFailed outside the model's domain."""
        model = self.model
        ev = model._evaluate(q, None, pr, F, True, 1.0, False)              # every tendon slack
        if not np.isfinite(ev.energy):
            raise StepFailed(f"the state left the model's domain ({model.inadmissibility(q)})")
        T, _code, dTq, _dTm = self._profile(q, np.asarray(T_motor, float), True)
        ok, Gs, Hs, _lseg, Jseg = tf.segment_forces(q, model.n, model._N, model._wq, model._E, model._d, model._co,
                                                    model._so, np.ascontiguousarray(T), True)
        if not ok:
            raise StepFailed(f"the state left the model's domain ({model.inadmissibility(q)})")
        return ev.Q + Gs, ev.K + Hs + Jseg.reshape(-1, model.ndof).T @ dTq.reshape(-1, model.ndof)

    def at(self, q: np.ndarray, T_motor: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(segment tensions (m, n) [N], segment lengths l_ik (m, n) [m]) of the law at q from the held tensions
        (at a committed state: its own tensions, which lie in their cone)."""
        m = self.model
        T = self._profile(q, np.asarray(T_motor, float), False)[0]
        ok, _G, _H, lseg, _J = tf.segment_forces(q, m.n, m._N, m._wq, m._E, m._d, m._co, m._so,
                                                 np.ascontiguousarray(T), False)
        return T, lseg

    def commit(self, q: np.ndarray, T_motor) -> None:
        """A step to the state q under the motor tensions T_motor (m,) [N] converged: its segment tensions
        become the held ones."""
        self.held = self._profile(q, np.asarray(T_motor, float), False)[0]


def dissipation_increment(a: dict, b: dict) -> float:
    """The friction's dissipated energy [J] from the output point a to b (:meth:`_Recorder.point` dicts with
    ``T`` (m,) motor tensions, ``Tseg`` (m, n) segment tensions [N] and ``lseg`` (m, n) [m]): the trapezoidal
    rule of Σ_ik (T_ik − T_i) dl_ik (module docstring)."""
    fa = a["Tseg"] - np.asarray(a["T"], float)[:, None]
    fb = b["Tseg"] - np.asarray(b["T"], float)[:, None]
    return float(np.sum(0.5 * (fa + fb) * (b["lseg"] - a["lseg"])))


@njit(cache=True)
def wrap_angles(P, G, e1, ndof):
    """Wrap angles α (m, n) [rad] and their gradients ∂α/∂q (m, n, ndof): :func:`ancf.forces.tendon_friction
    .wrap_angles` (the same formulas, its module docstring) as one compiled loop — the vectorised form spends
    most of a friction step's time in array overhead.  P (m, n+1, 3) [m], G (m, n+1, 3, 3), e1 (3,)."""
    m, n = P.shape[0], P.shape[1] - 1
    alpha = np.zeros((m, n))
    dalpha = np.zeros((m, n, ndof))
    a = np.empty(3)
    b = np.empty(3)
    ga = np.empty(3)
    gb = np.empty(3)
    for i in range(m):
        for k in range(n):
            for c in range(3):
                b[c] = P[i, k + 1, c] - P[i, k, c]
                a[c] = e1[c] if k == 0 else P[i, k, c] - P[i, k - 1, c]
            x0 = a[1] * b[2] - a[2] * b[1]
            x1 = a[2] * b[0] - a[0] * b[2]
            x2 = a[0] * b[1] - a[1] * b[0]
            s = np.sqrt(x0 * x0 + x1 * x1 + x2 * x2)
            p = a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
            na2 = a[0] * a[0] + a[1] * a[1] + a[2] * a[2]
            nb2 = b[0] * b[0] + b[1] * b[1] + b[2] * b[2]
            alpha[i, k] = np.arctan2(s, p)
            if not s > 1e-14 * np.sqrt(na2 * nb2):
                continue                                     # a straight section: gradient taken as zero
            for c in range(3):
                ga[c] = -(b[c] - p / na2 * a[c]) / s
                gb[c] = -(a[c] - p / nb2 * b[c]) / s
            _add_point(dalpha, G, i, k, k + 1, gb, 1.0)      # b = P_k+1 − P_k
            _add_point(dalpha, G, i, k, k, gb, -1.0)
            if k > 0:                                        # a = P_k − P_k−1
                _add_point(dalpha, G, i, k, k, ga, 1.0)
                _add_point(dalpha, G, i, k, k - 1, ga, -1.0)
    return alpha, dalpha


@njit(cache=True)
def _add_point(dalpha, G, i, k, j, g, sign):
    """dalpha[i, k] += sign × ∂(guide point j)/∂q ᵀ g: g on the node's position, G_ijᵀ g on its slope."""
    for c in range(3):
        dalpha[i, k, 6 * j + c] += sign * g[c]
        t = 0.0
        for r in range(3):
            t += G[i, j, r, c] * g[r]
        dalpha[i, k, 6 * j + 3 + c] += sign * t
