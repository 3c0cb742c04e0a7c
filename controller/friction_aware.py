r"""LACC with tendon friction in the controller's model (docs/friction.md, "Controller on a plant with friction").

With a friction coefficient μ = ``ActuatorParams.tendon_friction`` > 0 the locked actuator has a history: the
state after a command depends on the state before it (:func:`ancf.friction.fk_locked_history`).  Plain LACC
(:mod:`controller.lacc`) uses the frictionless IK and locked compliance; on a plant with friction its load
estimate then absorbs the friction's effect and it converges only linearly.  This controller keeps its model's
:class:`~ancf.friction.FrictionState` along the episode, the way the plant keeps its own.

The model's history.  The episode starts from the slack actuator (every tendon unloaded, the state
:meth:`ancf.Model.fk_history` at zero tensions under the initial estimate, as the simulated rig starts) or
from a given ``initial_state``.  Let S_{k−1} be the model's state before command k, l_k the commanded motor
lengths [m], F̂ the load estimate [N] and

    g_k(F) = tip of fk_locked_history(S_{k−1}, l_k, p, F)       (3,) [m]

the tip the model predicts for command k under a load F.

1. **Load estimate (the measurement matched).**  F̂_k solves g_k(F̂) = p_m (the measured tip): Broyden's
   method from F̂_{k−1} with the Jacobian ∂g_k/∂F by forward differences at F̂_{k−1} (three friction solves,
   step ``fd_force``; the pattern of stick and slip is the one command k set up, so the difference quotient
   is the compliance of that step, not the stiffer one of a locked state at rest that
   :func:`ancf.friction.locked_compliance` gives).  The inverse is regularised like LACC's (singular values
   below ``rcond`` σ_max cut: the axial direction) and each step kept within ``max_step_force``.  Then S_k =
   fk_locked_history(S_{k−1}, l_k, p, F̂_k): the model's history re-solved with the estimate, so that its tip
   is the measured one.
2. **IK with friction** (:func:`friction_ik`; ancf has none).  l_{k+1} solves h(l) = tip of
   fk_locked_history(S_k, l, p, F̂_k) = p_d by Newton's method from the frictionless IK's lengths for
   (p_d, F̂_k), with the exact Jacobian ∂h/∂l of the step each iterate solved
   (:func:`ancf.friction.locked_length_jacobian`: the implicit function theorem on the converged locked
   friction equilibrium, its stick/slip pattern held — stuck spans make the actuator stiffer, pulling and
   releasing differ), each step's motor changes kept within :data:`MAX_LENGTH_STEP`.  The Jacobian is
   one-sided (exact for motor changes that keep the pattern); where a step changes the pattern the next
   iterate's Jacobian is that of the new one.  The motor tensions of the solution must lie within the
   actuator's tension limits, else :class:`~ancf.errors.InfeasibleTargetError`.

On a perfect plant (the controller's model) the first step is history-free (from slack every guide slips), so
the first measurement gives F̂ up to the cut axial component and the next command lands within the IK
tolerance; what is left comes from the axial cut and the history's remaining differences.  Safeguard: an
estimate beyond ``validity_force`` is not taken — the estimate is frozen and the IK target is shifted
against the error instead (position correction, as LACC's fallback).  Cost per correction: ≈ 12–14 locked
friction solves (each ≈ 10× a frictionless FK; docs/friction.md states the measured times).  At μ = 0 the same
loop runs on the frictionless locked equations (fk_locked_history is fk_locked's there).
"""

from __future__ import annotations

import time
from typing import Optional

import numpy as np

from ancf import InfeasibleTargetError, Model
from ancf import friction as fr
from ancf.errors import InputError

from .base import Controller, StepReport
from .errors import ControllerError, check_finite, number
from .lacc import G, regularised_solve, safeguards, start_inputs


def _free_twin(model: Model) -> Model:
    """The same actuator without tendon friction (its IK starts the friction IK)."""
    if model.params.tendon_friction == 0.0:
        return model
    return Model(model.params.replace(tendon_friction=0.0))


def _broyden(B: np.ndarray, dx: np.ndarray, df: np.ndarray) -> np.ndarray:
    """Broyden's ("good") rank-one update of the Jacobian B so that B dx = df."""
    nx = float(dx @ dx)
    return B if nx == 0 else B + np.outer(df - B @ dx, dx) / nx


#: largest change of a motor length in one step of :func:`friction_ik` [m] (a Newton step is scaled down to it)
MAX_LENGTH_STEP = 5e-3


def friction_ik(model: Model, free: Model, state: fr.FrictionState, target, pressure: float, load, *,
                tol: float = 1e-6, max_iter: int = 12, free_eq=None):
    """IK with friction: motor lengths l (m,) [m] such that the locked friction step from ``state`` under
    ``load`` (3,) [N] at ``pressure`` [Pa] puts the tool point on ``target`` (3,) [m] within ``tol`` [m]
    (module docstring, step 2: Newton steps on the motor lengths with the exact Jacobian of the step,
    :func:`ancf.friction.locked_length_jacobian`, each length changed by at most :data:`MAX_LENGTH_STEP` per
    step).  ``free`` is the frictionless twin of ``model``; ``free_eq`` its IK state for (target, load) if
    known.  Returns (lengths, FrictionState, frictionless IK state, iterations: the locked friction solves
    made).  Raises InfeasibleTargetError (the frictionless IK's, or motor tensions outside the limits) or
    :class:`~controller.errors.ControllerError` (no convergence in ``max_iter`` friction solves)."""
    pd = check_finite("target", target, (3,))
    F = check_finite("load", load, (3,))
    if free_eq is None:
        free_eq = free.ik(pd, pressure, F, q0=state.q, tensions0=np.maximum(state.motor_tensions, 0.0))
    lengths = free_eq.tendon_lengths.copy()
    st = fr.fk_locked_history(model, state, lengths, pressure, F)
    r = st.tip - pd
    for it in range(1, max_iter + 1):
        if np.linalg.norm(r) < tol:
            _check_tensions(model, st, pd)
            return lengths, st, free_eq, it
        if it == max_iter:
            break
        Jl, _ = fr.locked_length_jacobian(model, st)
        dl = -np.linalg.lstsq(Jl, r, rcond=None)[0]
        dl *= min(1.0, MAX_LENGTH_STEP / max(float(np.abs(dl).max()), 1e-300))   # a trust region on the lengths
        lengths = lengths + dl
        st = fr.fk_locked_history(model, state, lengths, pressure, F)
        r = st.tip - pd
    raise ControllerError(f"IK with friction did not reach the target within {tol * 1e3:g} mm in {max_iter} "
                          f"solves (left {np.linalg.norm(r) * 1e3:.4g} mm)")


def _check_tensions(model: Model, st: fr.FrictionState, target) -> None:
    p = model.params
    T = st.motor_tensions
    bad = [f"T{i + 1} = {t:.3f} N outside [{p.tension_min:g}, {p.tension_max:g}] N" for i, t in enumerate(T)
           if t > p.tension_max or (t < p.tension_min and i in st.equilibrium.active)]
    if bad:
        raise InfeasibleTargetError(f"IK with friction: target {np.round(np.asarray(target) * 1e3, 3).tolist()} mm "
                                    f"needs {'; '.join(bad)}", target=target, nearest=None, tensions=T,
                                    violated=bad)


def match_load(model: Model, state: fr.FrictionState, lengths, pressure: float, load0, measured, *,
               rcond: float = 0.05, max_step_force: Optional[float] = 1.0, fd_force: float = 0.01,
               tol: float = 1e-7, max_iter: int = 6):
    """The load estimate F (3,) [N] that makes the locked friction step from ``state`` to motor lengths
    ``lengths`` (m,) [m] at ``pressure`` [Pa] put the tool point on ``measured`` (3,) [m] (module docstring,
    step 1), from ``load0``.  Returns (F, FrictionState at F, the Jacobian ∂tip/∂F (3, 3) [m/N] used,
    solves).  Stops at ‖tip − measured‖ < ``tol`` [m], after ``max_iter`` Broyden steps, or when the
    regularised step vanishes (the residual lies in the cut direction)."""
    F = check_finite("load", load0, (3,)).copy()
    st = fr.fk_locked_history(model, state, lengths, pressure, F)
    B = np.zeros((3, 3))
    for j in range(3):
        dF = np.zeros(3)
        dF[j] = fd_force
        B[:, j] = (fr.fk_locked_history(model, state, lengths, pressure, F + dF).tip - st.tip) / fd_force
    r, solves = st.tip - measured, 4
    C = B.copy()
    for _ in range(max_iter):
        if np.linalg.norm(r) < tol:
            break
        dF = -regularised_solve(B, r, rcond)
        if max_step_force is not None and np.linalg.norm(dF) > max_step_force:
            dF *= max_step_force / np.linalg.norm(dF)
        if np.linalg.norm(dF) < 1e-9:
            break
        st_new = fr.fk_locked_history(model, state, lengths, pressure, F + dF)
        solves += 1
        r_new = st_new.tip - measured
        B = _broyden(B, dF, r_new - r)
        F, st, r = F + dF, st_new, r_new
    return F, st, C, solves


class FrictionAwareLACC(Controller):
    """LACC whose model carries tendon friction and its history (module docstring).

    Parameters (SI)
    ----------
    model : controller's :class:`ancf.Model` (its ``tendon_friction`` μ ≥ 0);  pressure : p [Pa]
    tolerance : stop when ‖p_m − p_d‖ < tolerance [m] (0.2 mm)
    validity_force : ‖F̂‖ beyond which the estimate is not taken [N] (1.962 N = 200 g)
    max_step_force : trust region of each load-estimate step [N] (None: off)
    rcond : SVD cut-off of the load-estimate inverse, relative to σ_max (0.05, as LACC)
    ik_tol : tip tolerance of the IK with friction [m] (1 µm);  ik_max_iter : its friction solves
    fd_force : force step of the difference quotient ∂tip/∂F [N]
    initial_state : the model's FrictionState at the start of the episode (None: the slack actuator)
    """

    name = "LACC (friction-aware)"

    def __init__(self, model: Model, pressure: float, *, tolerance: float = 2e-4, validity_force: float = 0.2 * G,
                 max_step_force: Optional[float] = 1.0, rcond: float = 0.05, ik_tol: float = 1e-6,
                 ik_max_iter: int = 12, fd_force: float = 0.01, initial_state: Optional[fr.FrictionState] = None):
        super().__init__(model, pressure, tolerance=tolerance)
        self.validity_force, self.max_step_force, self.rcond = safeguards(validity_force, max_step_force, rcond)
        self.ik_tol = number("ik_tol [m]", ik_tol, strict=True)
        if isinstance(ik_max_iter, bool) or not isinstance(ik_max_iter, (int, np.integer)) or ik_max_iter < 1:
            raise InputError(f"ik_max_iter must be an integer >= 1, got {ik_max_iter!r}")
        self.ik_max_iter = int(ik_max_iter)
        self.fd_force = number("fd_force [N]", fd_force, strict=True)
        if initial_state is not None and not isinstance(initial_state, fr.FrictionState):
            raise InputError(f"initial_state must be a FrictionState or None, got {type(initial_state).__name__}")
        self.initial_state = initial_state
        self.free = _free_twin(model)
        self._F = np.zeros(3)
        self.mode = "lacc"
        self.history: Optional[fr.FrictionState] = None     # S_{k−1}: the model's state before the last command
        self.prediction: Optional[fr.FrictionState] = None  # the state the model expects for the last command
        self.lengths: Optional[np.ndarray] = None           # the last command [m]
        self.command_target: Optional[np.ndarray] = None

    @property
    def estimate(self) -> np.ndarray:
        """F̂ [N] (3,): the external tip load the controller believes acts."""
        return self._F.copy()

    def start(self, target, initial_load=(0.0, 0.0, 0.0)) -> np.ndarray:
        """The friction IK for (p_d, p, F̂⁰) from the episode's initial state; returns l_c [m]."""
        pd, F0 = start_inputs(target, initial_load, self.validity_force)
        S0 = self.initial_state or self.model.fk_history(np.zeros(self.model.m), self.pressure, F0)
        droop = self._warm_start()
        free_eq = self.free.ik(pd, self.pressure, F0, q0=droop.q, tensions0=droop.tensions)
        lengths, st, free_eq, _ = friction_ik(self.model, self.free, S0, pd, self.pressure, F0, tol=self.ik_tol,
                                              max_iter=self.ik_max_iter, free_eq=free_eq)
        self.target, self.command_target, self._F, self.mode = pd, pd.copy(), F0.copy(), "lacc"
        self.history, self.prediction, self.lengths = S0, st, lengths
        self.state = free_eq
        return lengths.copy()

    def step(self, measured_tip) -> StepReport:
        """One correction from the measured tip p_m (3,) [m]: match the load to the measurement, re-solve the
        history, IK with friction (module docstring).  The report's ``compliance`` is the difference quotient
        ∂tip/∂F (3, 3) [m/N] of the last command's step.  Raises InfeasibleTargetError (the target needs tensions
        outside the limits under F̂) or ControllerError (the IK with friction did not converge)."""
        e, en, t0, idle = self._begin_step(measured_tip)
        if idle is not None:
            return idle
        pm = self.target + e
        notes: list = []
        C = None
        if self.mode == "lacc":
            F, st, C, solves = match_load(self.model, self.history, self.lengths, self.pressure, self._F, pm,
                                          rcond=self.rcond, max_step_force=self.max_step_force,
                                          fd_force=self.fd_force)
            if np.linalg.norm(F) > self.validity_force:
                notes.append(f"estimate {np.linalg.norm(F):.3g} N left the validity range "
                             f"{self.validity_force:.3g} N: IK position correction from now on")
                self.mode = "fallback"
            else:
                self._F = F
        if self.mode == "fallback":
            st = fr.fk_locked_history(self.model, self.history, self.lengths, self.pressure, self._F)
            self.command_target = self.command_target - e
        lengths, pred, free_eq, its = friction_ik(self.model, self.free, st, self.command_target, self.pressure,
                                                  self._F, tol=self.ik_tol, max_iter=self.ik_max_iter)
        self.history, self.prediction, self.lengths, self.state = st, pred, lengths, free_eq
        return StepReport(e, en, False, lengths.copy(), self.estimate, self.mode, time.perf_counter() - t0,
                          compliance=C, active=tuple(pred.equilibrium.active), ik_iterations=its, notes=notes)
