r"""The simulated rig's dynamic plant: the actuator integrated in time between controller steps.

With ``PlantOptions(dynamics=True)`` the simulated rig no longer jumps to the locked equilibrium of the
motor lengths: it integrates the reduced model's equations of motion (:meth:`ancf.Model.simulate`,
docs/dynamics.md) over every interval the rig clock advances —

* tendons held by the motors at their lengths l_m(t) (rate-limited, linear between records, behind the
  position loop's lag when ``motor_bandwidth`` is finite; a motor gives way at ``motor_force_max``), as one-sided
  springs T = k max(0, l(q) − l_m): k the series stiffness of the plant's tendons (the actuator's
  ``tendon_stiffness`` and ``PlantOptions.tendon_stiffness`` in series) or, for inextensible tendons, a stiff
  spring (:data:`TENDON_PENALTY`, 1e6 N/m: 5 µm of stretch at 5 N); slack tendons go slack;
* the chamber pressure following the supply's set-point through p' = (p_set − p)/τ
  (``PlantOptions.pressure_tau``; 0: at once);
* the hidden tip load F(t) of the load profile;
* damping: ``PlantOptions.damping`` — a damping ratio ζ of the first mode about the start state, applied as
  mass-proportional damping α = 2ζω₁ (every mode decays at the rate ζω₁; stiffness-proportional damping
  would make dashpots of the stiff tendon springs and let the actuator creep), or a dict {alpha [1/s],
  beta [s], axial [N s]} (β then multiplies each interval's start tangent).

It starts at rest at the locked equilibrium of the first command (the static plant's, up to the stiff
tendons' µm stretch), so a controller sees the same start on both plants; ``state`` carries q, q̇, the pressure and the tensions, and a
short history serves the tracker's latency.  With tendon friction (the actuator's ``tendon_friction`` μ > 0) the
tendons follow the held-length stick/slip law of :mod:`ancf.dynamics.held_friction` instead of one spring
each, starting at the static plant's friction state (docs/friction.md).
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass
from typing import Callable, Optional

import numpy as np

from ancf import Model
from ancf.dynamics import held_friction
from ancf.dynamics.held_friction import HeldFriction
from ancf.errors import InputError

#: penalty stiffness of inextensible tendons in the dynamic plant [N/m]
TENDON_PENALTY = 1e6


@dataclass
class DynamicState:
    """The dynamic plant at one time: q (ndof,), v (ndof,) [m/s], tip (3,) [m], tensions (m,) [N],
    pressure [Pa], t [s].  Duck-types the fields of an Equilibrium the rig's devices read."""
    t: float
    q: np.ndarray
    v: np.ndarray
    tip: np.ndarray
    tensions: np.ndarray
    pressure: float


class DynamicActuator:
    """State and integration of the dynamic plant (module docstring)."""

    def __init__(self, model: Model, series_stiffness: float, damping, pressure_tau: float, step: float,
                 holding_force: Optional[float] = None):
        p = model.params
        compliance = (0.0 if not math.isfinite(series_stiffness) else 1.0 / series_stiffness) + \
            (0.0 if not p.tendon_stiffness else 1.0 / p.tendon_stiffness)
        k = TENDON_PENALTY if compliance == 0 else 1.0 / compliance
        self.model = Model(p.replace(tendon_stiffness=k))     # the tendons as the springs they are (or stiff)
        self.damping_option = damping
        self.damping: Optional[dict] = None
        self.tau = float(pressure_tau)
        self.holding_force = holding_force           # the motors' force limit [N] (None: they never give way)
        self.step = float(step)
        # the integrator's spectral radius: 0.6 damps the stiff tendon springs' modes (kHz), which would
        # otherwise pump energy at every slack/taut switch (measured: a 0.3 N load step blew up at ρ∞ = 0.9);
        # the bending modes (3–40 Hz) at 1 ms steps lose < 0.1 % per period to it
        self.rho_inf = 0.6
        self.state: Optional[DynamicState] = None
        self.history: list = []                       # DynamicState rows, oldest first (bounded)
        # tendon friction (μ > 0): the held-length stick/slip law in time (ancf.dynamics.held_friction)
        self.friction: Optional[HeldFriction] = None
        if p.tendon_friction > 0:
            self.friction = HeldFriction(self.model, k, math.inf if holding_force is None else holding_force)

    def start(self, lengths: np.ndarray, pressure: float, load: np.ndarray, near, t: float) -> None:
        """Start at rest at the locked equilibrium of motor ``lengths`` (m,) [m], ``pressure`` [Pa] and tip
        ``load`` (3,) [N] at rig time t [s] (``near``: the static plant's equilibrium there, a warm start)."""
        if self.friction is None:
            eq = self.model.fk_locked(lengths, pressure, load, q0=near.q, tensions0=near.tensions)
        else:
            eq = self._start_friction(lengths, pressure, load)
        v = np.zeros(self.model.ndof)
        self.state = DynamicState(t, eq.q.copy(), v, eq.tip.copy(), np.array(eq.tensions, float), float(eq.pressure))
        self.history = [self.state]
        if self.damping is None:
            if isinstance(self.damping_option, dict):
                self.damping = dict(self.damping_option)
            else:
                # a ratio ζ: mass-proportional damping α = 2 ζ ω₁ with ω₁ the first mode of this start, tendons
                # held by the motors (every mode then decays at the rate ζ ω₁; stiffness-proportional damping
                # would turn the stiff tendon springs into dashpots and make the actuator creep)
                # (with tendon friction: of the frictionless locked state, the modes' reference)
                ref = eq if self.friction is None else self.model.fk_locked(lengths, pressure, load, q0=eq.q,
                                                                            tensions0=eq.tensions)
                f1 = self.model.modes(ref, 1).frequencies_hz[0]
                self.damping = {"alpha": 2.0 * float(self.damping_option) * 2 * math.pi * f1}

    def _start_friction(self, lengths: np.ndarray, pressure: float, load: np.ndarray):
        """The start with tendon friction: the static plant's state (the locked friction step from the slack
        actuator, :func:`ancf.friction.fk_locked_history`, series spring k lumped at the motor), whose
        segment and motor tensions start the law's material history at rest."""
        from ancf import ConvergenceError
        from ancf.friction import fk_locked_history
        m = self.model
        try:
            st = fk_locked_history(m, m.fk_history(np.zeros(m.m), pressure, load, check_limits=False), lengths,
                                   pressure, load, check_limits=False)
        except ConvergenceError as exc:
            raise ConvergenceError(f"dynamic plant: the start with tendon friction failed: {exc}", solver=exc.solver,
                                   iterations=exc.iterations, residual_norm=exc.residual_norm,
                                   tolerance=exc.tolerance, history=exc.history) from exc
        self.friction.start(st.q, st.segment_tensions, st.equilibrium.tensions, lengths)
        return st.equilibrium

    def advance(self, t0: float, t1: float, lengths_at: Callable[[float], np.ndarray], p_set: float,
                load_at: Callable[[float], np.ndarray]) -> None:
        """Integrate from rig time t0 to t1 [s] (motor lengths, pressure set-point and load as given)."""
        if self.state is None:
            raise InputError("dynamic plant: not started (command tendon lengths first)")
        dt = t1 - t0
        if dt <= 0:
            return
        s = self.state
        if self.friction is not None:
            rows = held_friction.advance(
                self.model, self.friction, dt, min(self.step, dt), s.q, s.v, lambda t: lengths_at(t0 + t), p_set,
                self.tau if self.tau > 0 else None, s.pressure if self.tau > 0 else None,
                lambda t: load_at(t0 + t), self.damping, self.rho_inf)
            self.history.extend(DynamicState(t0 + r[0], *r[1:5], r[5]) for r in rows)
            self._trim()
            return
        sim = self.model.simulate(
            dt, min(self.step, dt), q0=s.q, v0=s.v, lengths=lambda t: lengths_at(t0 + t),
            pressure=p_set, pressure_tau=self.tau if self.tau > 0 else None,
            pressure0=s.pressure if self.tau > 0 else None, tip_force=lambda t: load_at(t0 + t),
            damping=self.damping, rho_inf=self.rho_inf, holding_force=self.holding_force, check_limits=False)
        for i in range(1, len(sim.t)):
            self.history.append(DynamicState(t0 + float(sim.t[i]), sim.q[i], sim.v[i], sim.tip[i],
                                             sim.tensions[i], float(sim.pressure[i])))
        self._trim()
        if sim.interrupted:
            # Ctrl-C during the integration ends the run between steps with the rows done (ancf.dynamics.interrupt):
            # the plant has not reached t1, so the rig must not go on as if it had — the interrupt is raised here
            raise KeyboardInterrupt

    def _trim(self) -> None:
        """Bound the history; its last row is the present state."""
        if len(self.history) > 4000:
            del self.history[:-2000]
        self.state = self.history[-1]

    def at(self, t: Optional[float]) -> DynamicState:
        """The state at rig time t (None: now); earlier times interpolate the history linearly."""
        s = self.state
        if t is None or t >= s.t or len(self.history) < 2:
            return s
        times = [h.t for h in self.history]
        i = bisect.bisect_right(times, t) - 1
        if i < 0:
            return self.history[0]
        a, b = self.history[i], self.history[min(i + 1, len(self.history) - 1)]
        w = 0.0 if b.t == a.t else (t - a.t) / (b.t - a.t)
        def mix(x, y):
            return x + w * (y - x)
        return DynamicState(t, mix(a.q, b.q), mix(a.v, b.v), mix(a.tip, b.tip), mix(a.tensions, b.tensions),
                            mix(a.pressure, b.pressure))
