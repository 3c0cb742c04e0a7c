r"""Load-aware compliance controller (LACC), paper Sec. III-E, Algorithm 1.

Per episode (desired tip p_d [m], pressure p [Pa], initial estimate F̂⁰ [N])::

    [q, T] ← IK(p_d, p, F̂⁰)                      warm start: stored gravity-droop state m.droop(p)
    while ‖p_m − p_d‖ ≥ tol (0.2 mm):
        p_m  ← measure
        C_q  ← constant-tension compliance at (q, T, p)                        eq. (8)
        A    ← taut set from δl = J_l C_q δF̂  (δF̂ = C_p⁻¹ e, the constant-
                tension estimate of the load increment, gives the direction)   Sec. III-D
        C'_p ← locked compliance with A (``compliance=``: "exact" KKT — the default —, "ik" eq. 15/16,
                "paper" eq. 13)
        F̂    ← F̂ + C'_p⁻¹ (p_m − p_d)                                          line 10
        [q, T] ← IK(p_d, p, F̂)   warm-started from the previous IK solution
        send l_c(q)                                                              eq. (5)

The controller only sees the measured tip; its model need not be the plant's.

Load-estimate safeguards (all explicit, all parameters):

1. **Regularised inverse.**  ΔF̂ = C'_p⁺ e with the SVD pseudo-inverse, singular values below
   ``rcond`` × σ_max discarded (default 0.05).  A locked actuator is nearly rigid along its axis (C'_p's
   smallest singular value is ≈ 0.5–2 % of the largest), so that direction is cut: an axial position error
   — typically model mismatch, not load — would otherwise be read as a large axial force (measured: with
   the stacked forms and a mismatched plant, ≈ 1.8 N of spurious axial estimate in four steps, leading to
   infeasible IKs).  What is lost is small: an unestimated axial load of 0.1 N leaves ≈ 0.01 mm of error.
   ``rcond=1e-3`` gives the literal inverse.
2. **Trust region.**  ‖ΔF̂‖ ≤ ``max_step_force`` [N] per iteration (default 1.0 N ≈ 100 g); larger steps
   are scaled down along their direction.
3. **Validity range and fallback.**  If the updated estimate would leave ‖F̂‖ ≤ ``validity_force``
   (default 0.2 kg · 9.81 m/s² = 1.962 N, the paper's ≈ 200 g), the estimate is frozen at its last valid
   value and the controller switches — for the rest of the episode — to plain IK position correction:
   the IK target is shifted against the error, p_cmd ← p_cmd − ``fallback_gain`` · (p_m − p_d), with F̂
   unchanged.  That is an integral law on position, effective irrespective of the load magnitude.
4. **Saturation, not abort** (``on_infeasible="saturate"``, the default).  A load the tensions cannot carry
   at the target (the load-compensated IK needs tensions outside their bounds) does not end the run: the
   controller commands the nearest reachable state (the FK at the tensions of the bounded IK, see
   :meth:`ancf.Model.ik`), reports the step ``saturated``, and keeps estimating the load.  Anti-windup: while
   saturated the estimate is updated from the *innovation* — the measured tip minus the tip the model
   expects for the commanded state under F̂ — not from the distance to the unreachable target, so F̂ follows
   the load instead of integrating the unreachable offset; when the load allows, the IK reaches the target
   again and the step is no longer saturated.  In fallback mode (3) the position-correcting IK saturates the
   same way, with the IK target reset to the reachable tip (back-calculation: it does not wind up).
   ``on_infeasible="fallback"`` keeps the earlier behaviour: the load step is halved up to ``backtracks``
   times, then the estimate is frozen and the controller falls back to IK position correction, whose
   infeasibility propagates; ``"raise"`` propagates the first infeasible IK.  (An infeasible *initial*
   target always propagates from :meth:`LACC.start`: a run is refused before it starts.)
5. **Gain.**  ``gain`` multiplies ΔF̂ (default 1.0 = Algorithm 1).

Compliance choices (``compliance=``): ``"exact"`` (the default) is the exact locked linearisation (KKT
of the locked equilibrium), ``"ik"`` the paper's eq. (15/16) (the stacked IK Jacobian by
pseudo-inverse), ``"paper"`` the FK-derived eq. (13).  With the exact compliance each step is a
Newton-like iteration: Table I comes out ≈ 1e-5 mm after five iterations (the paper's form: 0.2–0.44 mm).
With the literal unweighted stacks (``constraint_weight=1``) the two paper forms come out close to the
constant-tension compliance — about 3× the plant's locked compliance — so LACC with them is a stable but
slow integral law (measured error ratio ≈ 0.74 per step for "ik", 0.77 for "paper": 7–8 iterations to
0.2 mm from ≈ 2 mm).  ``validation.paper.control.compliance_ablation`` measures this.  The stacked forms
also misjudge the axial compliance, so with the literal inverse an axial error (e.g. from model mismatch)
builds a spurious axial load estimate; safeguard 1 prevents it.
"""

from __future__ import annotations

import time
from typing import Optional

import numpy as np

from ancf import InfeasibleTargetError, Model
from ancf import compliance as cp
from ancf.errors import InputError

from .errors import check_finite, number

from .base import Controller, StepReport

G = 9.81
COMPLIANCE_METHODS = ("ik", "paper", "exact")


def regularised_solve(C: np.ndarray, e: np.ndarray, rcond: float) -> np.ndarray:
    """ΔF = C⁺ e with singular values below ``rcond`` σ_max discarded.  C (3, 3) [m/N], e (3,) [m] → [N]."""
    U, s, Vt = np.linalg.svd(C)
    keep = s > rcond * s[0]
    return Vt[keep].T @ ((U[:, keep].T @ e) / s[keep])



def safeguards(validity_force, max_step_force, rcond) -> tuple:
    """``(validity_force [N], max_step_force [N] or None, rcond)`` checked (the load-estimate safeguards of the module
    docstring: > 0 each, rcond < 1); InputError naming the first out of range."""
    vf = number("validity_force", validity_force, strict=True)
    ms = None if max_step_force is None else number("max_step_force", max_step_force, strict=True)
    rc = number("rcond", rcond, strict=True)
    if rc >= 1:
        raise InputError(f"rcond must be in (0, 1), got {rcond!r}")
    return vf, ms, rc


def start_inputs(target, initial_load, validity_force: float) -> tuple:
    """``(p_d (3,) [m], F̂⁰ (3,) [N])`` of an episode's start, checked: finite, the right shape, and ‖F̂⁰‖ within the
    load estimate's validity range ``validity_force`` [N]; InputError otherwise."""
    pd = check_finite("target", target, (3,))
    F0 = check_finite("initial_load", initial_load, (3,))
    if np.linalg.norm(F0) > validity_force:
        raise InputError(f"initial load estimate {np.linalg.norm(F0):.3g} N is outside the validity range "
                         f"{validity_force:.3g} N of the compliance linearisation")
    return pd, F0

class LACC(Controller):
    """Load-aware compliance controller (Algorithm 1).

    Parameters (SI)
    ----------
    model : controller's :class:`ancf.Model`;  pressure : p [Pa]
    compliance : "exact" (default, KKT) | "ik" (the paper's eq. 15/16) | "paper" (eq. 13, FK-derived)
    constraint_weight : weight of the constraint rows of the stacked "ik"/"paper" forms [N/m]; 1 = literal
    active_rule : "paper" (δl > 0) | "exact" (complementarity) for the taut set; default "paper" for the
        stacked forms, "exact" for ``compliance="exact"``
    tolerance : stop when ‖p_m − p_d‖ < tolerance [m] (0.2 mm)
    validity_force : ‖F̂‖ beyond which the estimate is not trusted [N] (1.962 N = 200 g)
    max_step_force : trust region on ‖ΔF̂‖ per step [N] (None: off)
    rcond : SVD cut-off of the C'_p inverse, relative to σ_max (0.05: the stiff axial direction is cut)
    gain : multiplier of ΔF̂ (1 = Algorithm 1)
    fallback_gain : gain of the IK position correction once in fallback (1 = full correction)
    backtracks : how many times a load step is halved when the IK becomes infeasible ("fallback" only)
    on_infeasible : "saturate" (command the nearest reachable state, keep estimating; module docstring),
        "fallback" (after the halvings freeze F̂ and correct by IK position) or "raise"
    """

    name = "LACC"

    def __init__(self, model: Model, pressure: float, *, compliance: str = "exact", constraint_weight: float = 1.0,
                 active_rule: Optional[str] = None, tolerance: float = 2e-4, validity_force: float = 0.2 * G,
                 max_step_force: Optional[float] = 1.0, rcond: float = 0.05, gain: float = 1.0,
                 fallback_gain: float = 1.0, backtracks: int = 3, on_infeasible: str = "saturate"):
        super().__init__(model, pressure, tolerance=tolerance)
        if not isinstance(compliance, str) or compliance not in COMPLIANCE_METHODS:
            raise InputError(f"LACC compliance must be one of {COMPLIANCE_METHODS}, got {compliance!r}")
        self.compliance = compliance
        self.constraint_weight = number("constraint_weight", constraint_weight, strict=True)
        self.active_rule = active_rule or ("exact" if compliance == "exact" else "paper")
        if not isinstance(self.active_rule, str) or self.active_rule not in ("paper", "exact"):
            raise InputError(f"active_rule must be 'paper' or 'exact', got {active_rule!r}")
        self.validity_force, self.max_step_force, self.rcond = safeguards(validity_force, max_step_force, rcond)
        self.gain = number("gain", gain, strict=True)
        self.fallback_gain = number("fallback_gain", fallback_gain, strict=True)
        if isinstance(backtracks, bool) or not isinstance(backtracks, (int, np.integer)) or backtracks < 0:
            raise InputError(f"backtracks must be an integer >= 0, got {backtracks!r}")
        self.backtracks = int(backtracks)
        if not isinstance(on_infeasible, str) or on_infeasible not in ("saturate", "fallback", "raise"):
            raise InputError(f"on_infeasible must be 'saturate', 'fallback' or 'raise', got {on_infeasible!r}")
        self.on_infeasible = on_infeasible
        self._F = np.zeros(3)
        self._offset = np.zeros(3)          # tip the model expects for the command − p_d (≠ 0 when saturated)
        self.mode = "lacc"
        self.command_target: Optional[np.ndarray] = None     # IK target (differs from p_d in fallback)

    @property
    def estimate(self) -> np.ndarray:
        """F̂ [N] (3,): the external tip load the controller believes acts (beyond the model's own weight)."""
        return self._F.copy()

    @property
    def in_fallback(self) -> bool:
        return self.mode == "fallback"

    def start(self, target, initial_load=(0.0, 0.0, 0.0)) -> np.ndarray:
        """Algorithm 1 lines 3–4: IK for (p_d, p, F̂⁰) from the stored droop state; returns l_c [m]."""
        pd, F0 = start_inputs(target, initial_load, self.validity_force)
        droop = self._warm_start()
        eq = self.model.ik(pd, self.pressure, F0, q0=droop.q, tensions0=droop.tensions)   # may raise Infeasible
        self.target, self.command_target = pd, pd.copy()
        self._F = F0.copy()
        self._offset = np.zeros(3)
        self.state = eq
        self.mode = "lacc"
        return eq.tendon_lengths.copy()

    def load_increment(self, e: np.ndarray):
        """Lines 7–10 without the IK: (ΔF̂ [N], C'_p [m/N], active set) for the tip error e = p_m − p_d [m]."""
        m, eq = self.model, self.state
        Ct = cp.tension(m, eq)                                           # C_q, eq. (8)
        dF_dir = regularised_solve(Ct.C_p, e, self.rcond)                # constant-tension load increment
        direction = dF_dir if np.linalg.norm(dF_dir) > 0 else None
        A = cp.active_set(m, eq, direction, rule=self.active_rule)       # Sec. III-D
        L = cp.locked(m, eq, method=self.compliance, active=A, constraint_weight=self.constraint_weight)
        dF = self.gain * regularised_solve(L.C_p, e, self.rcond)         # line 10
        return dF, L.C_p, tuple(A)

    def step(self, measured_tip) -> StepReport:
        """Algorithm 1 lines 5–13 for one measurement p_m [m]."""
        e, en, t0, idle = self._begin_step(measured_tip)
        if idle is not None:
            return idle
        notes: list = []
        Cp, A = None, ()
        backtracks = 0
        saturated, gap = False, 0.0
        if self.mode == "lacc":
            # the innovation: measured tip minus the tip the model expects for the last command under F̂
            # (the target itself unless that command was saturated — anti-windup, module docstring)
            dF, Cp, A = self.load_increment(e - self._offset)
            if self.max_step_force is not None and np.linalg.norm(dF) > self.max_step_force:
                notes.append(f"load step {np.linalg.norm(dF):.3g} N clipped to {self.max_step_force:g} N")
                dF *= self.max_step_force / np.linalg.norm(dF)
            if np.linalg.norm(self._F + dF) > self.validity_force:
                notes.append(f"estimate {np.linalg.norm(self._F + dF):.3g} N left the validity range "
                             f"{self.validity_force:.3g} N: IK position correction from now on")
                self.mode = "fallback"
        eq = None
        if self.mode == "lacc":
            while True:
                F_new = self._F + dF
                try:
                    eq = self.model.ik(self.command_target, self.pressure, F_new, q0=self.state.q,
                                       tensions0=self.state.tensions)
                    self._F = F_new
                    break
                except InfeasibleTargetError as exc:
                    if self.on_infeasible == "saturate":
                        eq, note = self._nearest(exc, self.command_target, F_new)
                        self._F, saturated = F_new, True
                        notes.append(note)
                        break
                    if backtracks >= self.backtracks:
                        if self.on_infeasible == "raise":
                            raise
                        notes.append(f"IK infeasible with the estimate after {backtracks} halvings "
                                     f"({exc.violated}): IK position correction from now on")
                        self.mode = "fallback"
                        break
                    backtracks += 1
                    dF = 0.5 * dF
        if eq is None:
            self.command_target = self.command_target - self.fallback_gain * e
            if self.on_infeasible == "saturate":
                eq, saturated, note = self._reach(self.command_target, self._F)
                if saturated:
                    gap = float(np.linalg.norm(eq.tip - self.command_target))
                    self.command_target = eq.tip.copy()      # back-calculation: the IK target does not wind up
                    notes.append(note)
            else:
                eq = self.model.ik(self.command_target, self.pressure, self._F, q0=self.state.q,
                                   tensions0=self.state.tensions)
        self._offset = eq.tip - self.target if (saturated and self.mode == "lacc") else np.zeros(3)
        if saturated and self.mode == "lacc":
            gap = float(np.linalg.norm(self._offset))
        self.state = eq
        cmd = eq.tendon_lengths.copy()
        return StepReport(e, en, False, cmd, self.estimate, self.mode, time.perf_counter() - t0, compliance=Cp,
                          active=A, ik_iterations=eq.iterations, backtracks=backtracks, notes=notes,
                          saturated=saturated, reach_gap=gap)
