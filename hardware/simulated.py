r"""The simulated rig: the locked-tendon ``ancf`` model behind the same device interfaces as a real rig.

The motors hold tendon lengths l_m [m]; the actuator settles to the locked equilibrium
(:meth:`ancf.Model.fk_locked`, paper eqs. 3–6) under the true tip load F(t) [N] — hidden from any
controller — at the chamber pressure the (simulated) supply holds.  A controller only sees what the
devices report: the tracker's tip position (noise, latency), the force sensors' tensions (noise), the
pressure sensor, the drives' positions.

Mismatch and hardware options (:class:`PlantOptions`), so that no result rests on the controller meeting
its own model:

* ``params`` — the plant's own actuator parameters (e.g. ``presets.paper().replace(line_mass=0.35)``).
* ``noise_std`` [m] — white Gaussian tracker noise on each coordinate; ``tracker_latency`` [s] — the pose
  returned is the one of ``tracker_latency`` seconds ago.
* ``force_noise_std`` [N], ``pressure_noise_std`` [Pa] — sensor noise.
* ``length_resolution`` [m] — motor position quantum: commands are rounded to multiples of it.
* ``length_rate`` [m/s] — motor speed; moves take max|Δl| / rate seconds and, in timed runs, the
  actuator passes through the intermediate states.
* ``length_offset`` (m,) [m] — calibration error of the tendon-length zero (added to every command).
* ``dynamics`` — integrate the actuator in time between controller steps instead of jumping to the locked
  equilibrium (:mod:`hardware.sim_dynamics`): inertia, motors at ``length_rate`` (at most, and by default,
  the safety limits' ``speed_max``: never an instant move) behind a position loop of ``motor_bandwidth``
  [Hz] (a first-order lag; inf: ideal) that gives way at ``motor_force_max`` [N] (the current limit; inf:
  never), ``damping`` (a ratio of the first mode, default 0.05,
  or {alpha, beta, axial}), the pressure supply's time constant ``pressure_tau`` [s], integration step
  ``dynamics_step`` [s].
* ``tendon_friction`` [N] and ``tendon_stiffness`` [N/m] — friction in the routing as a tension loss f_c
  between motor and actuator, acting through the series elasticity of tendon and sheath (flagged
  interpretation).  With inextensible tendons a tension loss cannot change a *locked-length* equilibrium
  (the tension is only the constraint multiplier), so friction acts through the stretch: the length the
  actuator sees is l_a = l_m + (T_a + s f_c) / k_s, where T_a is the tension at the actuator and s = +1
  after the motor last pulled (shortened) that tendon, −1 after it released it — a hysteresis of width
  2 f_c / k_s.  Solved by fixed-point iteration on l_a (the actuator is far softer than k_s).
* the plant actuator's own ``tendon_friction`` μ (``params.tendon_friction``; the dynamic plant: docs/friction.md) — the
  capstan law at the routing guides (docs/friction.md): each new state is the locked equilibrium with
  friction (:func:`ancf.friction.fk_locked_history`) solved from the plant's previous
  :class:`~ancf.friction.FrictionState`, so the plant has the tendons' stick/slip hysteresis; the series
  stiffness and the constant loss above act as before (the fixed point on l_a, each iterate solved from the
  same previous state).  The history advances with the plant's present: a state at an earlier time (tracker
  latency) is solved from the present state without becoming the history.  The plant is solved when queried, but
  its history does not depend on when: it is rigged at the first command's lengths and passes every motor record
  where a motor turned back (:meth:`_Plant._friction_turns`).  The force sensors read the motor
  side; :meth:`SimulatedRig.pull_through` measures the anchor side of a pull-through test.

Faults are injected with :meth:`SimulatedRig.inject` (``"tracking_lost"``, ``"invalid_pose"``,
``"tracker_stale"``, ``"sensor_timeout"``, ``"drive_fault"``, ``"pressure_overshoot"``), each from a
simulated time on, so that every fault path of :class:`~hardware.rig.Rig` runs in tests exactly as on
hardware.  Reproducible: all randomness comes from ``numpy.random.default_rng(seed)``.
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass
from typing import Callable, Optional, Sequence, Union

import numpy as np

from ancf import ActuatorParams, ConvergenceError, Equilibrium, Model
from ancf.errors import InputError, check_finite

from .errors import DriveFault, HardwareError, SensorTimeout
from .interfaces import ForceSensor, PressureSupply, TendonDrive, TipTracker, TrackedPose
from .limits import SafetyLimits
from .rig import Rig

LoadLike = Union[Sequence[float], np.ndarray, Callable[[float], np.ndarray]]
FAULTS = ("tracking_lost", "invalid_pose", "tracker_stale", "sensor_timeout", "drive_fault", "pressure_overshoot")


@dataclass(frozen=True)
class PlantOptions:
    """Model-mismatch and hardware options of :class:`SimulatedRig` (all SI; defaults = perfect plant)."""
    params: Optional[ActuatorParams] = None
    noise_std: float = 0.0
    length_resolution: float = 0.0
    length_rate: float = math.inf
    length_offset: Optional[tuple] = None
    tendon_friction: float = 0.0
    tendon_stiffness: float = math.inf
    tracker_latency: float = 0.0
    force_noise_std: float = 0.0
    pressure_noise_std: float = 0.0
    seed: int = 0
    dynamics: bool = False
    damping: Union[float, dict] = 0.05
    pressure_tau: float = 0.0
    dynamics_step: float = 1e-3
    motor_bandwidth: float = math.inf
    motor_force_max: float = math.inf

    def __post_init__(self):
        for nm in ("noise_std", "length_resolution", "tendon_friction", "tracker_latency", "force_noise_std",
                   "pressure_noise_std"):
            v = getattr(self, nm)
            if isinstance(v, (bool, str)) or not (np.isfinite(v) and v >= 0):
                raise InputError(f"PlantOptions.{nm} must be finite and >= 0, got {v!r}")
        for nm in ("length_rate", "tendon_stiffness"):
            v = getattr(self, nm)
            if isinstance(v, (bool, str)) or not (v > 0) or np.isnan(v):
                raise InputError(f"PlantOptions.{nm} must be > 0 (inf allowed), got {v!r}")
        if not isinstance(self.dynamics, bool):
            raise InputError(f"PlantOptions.dynamics must be True or False, got {self.dynamics!r}")
        for nm, hi in (("pressure_tau", 100.0), ("dynamics_step", 0.1)):
            v = getattr(self, nm)
            if isinstance(v, (bool, str)) or not (np.isfinite(v) and 0 <= v <= hi) or (nm == "dynamics_step" and v == 0):
                raise InputError(f"PlantOptions.{nm} must be in {'(0' if nm == 'dynamics_step' else '[0'}, {hi:g}] s, "
                                 f"got {v!r}")
        if not isinstance(self.damping, dict) and (isinstance(self.damping, (bool, str))
                                                   or not (np.isfinite(self.damping) and 0 <= self.damping <= 1)):
            raise InputError(f"PlantOptions.damping must be a ratio in [0, 1] or a dict {{alpha, beta, axial}}, "
                             f"got {self.damping!r}")
        for nm in ("motor_bandwidth", "motor_force_max"):
            v = getattr(self, nm)
            if isinstance(v, (bool, str)) or not (v > 0) or np.isnan(v):
                raise InputError(f"PlantOptions.{nm} must be > 0 (inf: ideal), got {v!r}")
        if self.dynamics and self.tendon_friction > 0:
            raise InputError("PlantOptions: tendon friction is not modelled in the dynamic plant (dynamics=True); "
                             "set tendon_friction=0")
        if self.params is not None and not isinstance(self.params, ActuatorParams):
            raise InputError(f"PlantOptions.params must be ActuatorParams, got {type(self.params).__name__}")

    @classmethod
    def mismatched(cls, seed: int = 0, base: Optional[ActuatorParams] = None, **changes) -> "PlantOptions":
        """A representative imperfect rig around ``base`` (default ``presets.paper()``): +15 % line mass,
        stiffness law scaled by 0.95, 5 g heavier tip, 0.05 mm tracker noise, 1 µm motor resolution, 5 mm/s
        motor speed, 0.1 N friction over a 20 kN/m tendon.  Keyword arguments override any field."""
        from ancf import StiffnessLaw, presets
        base = base or presets.paper()
        law = base.stiffness
        scaled = StiffnessLaw.polynomial(EA=[0.95 * c for c in law.EA_coeffs], EI=[0.95 * c for c in law.EI_coeffs]) \
            .with_pressure(EA=law.EA_pressure, EI=law.EI_pressure)
        params = base.replace(line_mass=base.line_mass * 1.15, tip_mass=base.tip_mass + 0.005, stiffness=scaled)
        opts = dict(params=params, noise_std=5e-5, length_resolution=1e-6, length_rate=5e-3,
                    tendon_friction=0.1, tendon_stiffness=2e4, seed=seed)
        opts.update(changes)
        return cls(**opts)


def _plant_failed(what: str, l_act, F, exc: ConvergenceError) -> ConvergenceError:
    """The plant's own solve ``what`` failed at motor lengths ``l_act`` [m] and tip load ``F`` [N]: a
    ConvergenceError that says where and keeps the solver's record of ``exc``."""
    return ConvergenceError(f"simulated rig: {what} failed at lengths {', '.join(f'{x * 1e3:.3f}' for x in l_act)} "
                            f"mm, tip load ({', '.join(f'{x:.4g}' for x in F)}) N: {exc}", solver=exc.solver,
                            iterations=exc.iterations, residual_norm=exc.residual_norm, tolerance=exc.tolerance,
                            history=exc.history)


class _Plant:
    """The physics: motor lengths, pressure, hidden load, clock; locked FK with friction; fault schedule."""

    def __init__(self, model: Model, pressure: float, options: PlantOptions):
        self.model = model
        self.pressure = pressure
        self.options = options
        self.rng = np.random.default_rng(options.seed)
        m = model.m
        self.offset = (np.zeros(m) if options.length_offset is None
                       else check_finite("length_offset", options.length_offset, (m,)))
        self.time = 0.0
        self.lengths: Optional[np.ndarray] = None
        self.target: Optional[np.ndarray] = None
        self.dir = np.ones(m)
        self.hist: list = []                 # (t, lengths, dir) whenever the motors moved
        self.cache: dict = {}
        self.last_eq: Optional[Equilibrium] = None
        self.fstate = None                   # the friction history's present FrictionState (μ > 0) and its key
        self.fkey: Optional[tuple] = None
        self.flengths: Optional[np.ndarray] = None   # its motor lengths, and the motor records it has passed
        self.fidx = 0
        self.solves = 0
        self.faults: dict = {}
        self.load_fn: Callable = lambda t: np.zeros(3)
        for nm in ("motor_bandwidth", "motor_force_max"):
            if math.isfinite(getattr(options, nm)) and not options.dynamics:
                raise InputError(f"PlantOptions.{nm} is a motor property of the dynamic plant: it needs dynamics=True")
        self.rate = options.length_rate       # motor speed [m/s] (a dynamic plant never moves them at once)
        self.dyn = None
        self.mu = float(model.params.tendon_friction)
        if options.dynamics:
            from .sim_dynamics import DynamicActuator
            self.dyn = DynamicActuator(model, options.tendon_stiffness, options.damping, options.pressure_tau,
                                       options.dynamics_step,
                                       None if math.isinf(options.motor_force_max) else options.motor_force_max)
        self.motor_y: Optional[np.ndarray] = None     # motor positions behind their position loop (dynamic)
        self.motor_t = 0.0

    def quantise(self, lengths):
        r = self.options.length_resolution
        return np.round(lengths / r) * r if r > 0 else lengths

    def fault(self, kind: str) -> Optional[dict]:
        f = self.faults.get(kind)
        return f if f is not None and self.time >= f["at"] else None

    def record(self):
        self.hist.append((self.time, self.lengths.copy(), self.dir.copy()))

    def move_time(self) -> float:
        if self.lengths is None:
            return 0.0
        dl = float(np.max(np.abs(self.target - self.lengths)))
        return 0.0 if dl == 0 else dl / self.rate

    def advance(self, dt: float) -> None:
        """Move the motors for ``dt`` seconds (and, for a dynamic plant, integrate the actuator over them)."""
        t0 = self.time
        if self.dyn is not None and self.dyn.state is None:
            self._start_dynamics()
        self._move(dt)
        if self.dyn is not None:
            self.dyn.advance(t0, self.time, self.motor_at, self.supply_pressure, self.load)
            self.motor_y, self.motor_t = self.motor_at(self.time), self.time

    def _start_dynamics(self) -> None:
        self.dyn.start(self.lengths.copy(), self.pressure, self.load(self.time), self._static(), self.time)
        self.motor_y, self.motor_t = self.lengths.copy(), self.time

    def motor_at(self, t: float) -> np.ndarray:
        """Motor positions (m,) [m] at rig time t ≥ the last advance's start: the commanded (rate-limited,
        piecewise-linear) profile u through the position loop's first-order lag ẏ = ω (u − y), solved exactly
        on each linear piece: y(b) = u(b) − s/ω + (y(a) − u(a) + s/ω) e^{−ω(b − a)}, s its slope."""
        bw = self.options.motor_bandwidth
        if self.motor_y is None or math.isinf(bw):
            return self.lengths_at(t)
        w = 2 * math.pi * bw
        knots = sorted({self.motor_t, t, *(h[0] for h in self.hist if self.motor_t < h[0] < t)})
        y = self.motor_y.copy()
        for a, b in zip(knots[:-1], knots[1:]):
            ua, ub = self.lengths_at(a), self.lengths_at(b)
            sl = (ub - ua) / (b - a)
            y = ub - sl / w + (y - ua + sl / w) * math.exp(-w * (b - a))
        return y

    @property
    def supply_pressure(self) -> float:
        return self.pressure

    def _move(self, dt: float) -> None:
        """Move the motors for ``dt`` seconds.  The history gets a record at the start, at each tendon's
        arrival and at the end, so lengths between records are exactly linear in time (tracker latency)."""
        if self.hist and not np.array_equal(self.hist[-1][1], self.lengths) or not self.hist:
            self.record()
        if math.isinf(self.rate):
            self.lengths = self.target.copy()
            self.time += dt
        else:
            rate = self.rate
            t_end = self.time + dt
            arrivals = sorted({float(x) for x in np.abs(self.target - self.lengths) / rate if 0 < x < dt})
            for stop in [self.time + a for a in arrivals] + [t_end]:
                step = rate * (stop - self.time)
                d = self.target - self.lengths
                self.lengths = np.where(np.abs(d) <= step + 1e-15, self.target, self.lengths + np.sign(d) * step)
                self.time = stop
                self.record()
            self.time = t_end
        if not np.array_equal(self.hist[-1][1], self.lengths) or self.hist[-1][0] != self.time:
            self.record()

    def load(self, t: Optional[float] = None) -> np.ndarray:
        F = np.asarray(self.load_fn(self.time if t is None else t), float)
        if F.shape != (3,) or not np.all(np.isfinite(F)):
            raise InputError(f"load profile returned {F} at t = {t}")
        return F

    def _solve_friction(self, l_act, F, prev=None):
        """The locked state with tendon friction at motor-side lengths l_act (m,) [m] from ``prev`` (default the
        present state; the first: from the slack actuator at this pressure and load)."""
        from ancf.friction import fk_locked_history
        m = self.model
        prev = prev or self.fstate or m.fk_history(np.zeros(m.m), self.pressure, F)
        try:
            return fk_locked_history(m, prev, l_act, self.pressure, F)
        except ConvergenceError as exc:
            raise _plant_failed("locked FK with tendon friction", l_act, F, exc) from exc
        finally:
            self.solves += 1

    def _friction_step(self, lengths, dirs, F, prev=None):
        """One locked friction step to motor lengths (m,) [m] (pull directions ``dirs``, load F (3,) [N]): the
        series-stiffness fixed point, each iterate solved from the same previous state (module docstring)."""
        o = self.options
        la = lengths.copy()
        for _ in range(30 if math.isfinite(o.tendon_stiffness) else 1):
            st = self._solve_friction(la, F, prev)
            if math.isinf(o.tendon_stiffness):
                break
            T = st.equilibrium.tensions
            la_new = lengths + (T + dirs * o.tendon_friction * (T > 0)) / o.tendon_stiffness
            if np.max(np.abs(la_new - la)) < 1e-10:
                break
            la = la_new
        return st

    def _friction_turns(self) -> list:
        """The motor records (t, lengths, dirs) the friction history passes before the present query: the
        rigging (the first record, before any state) and every record since the present state at which a motor
        turns back (its length's change reverses sign).  Between them each motor moves one way — the locked
        step's assumption — so the state does not depend on when the plant is queried."""
        out, start = [], self.fidx
        if self.fstate is None:
            out, start = [self.hist[0]], 1
        prev, way = out[0][1] if out else self.flengths, np.zeros(self.model.m)
        for j in range(start, len(self.hist)):
            d = np.sign(self.hist[j][1] - prev)
            if np.any(d * way < 0):
                out.append(self.hist[j - 1])
                way = np.zeros_like(way)
            way = np.where(d != 0, d, way)
            prev = self.hist[j][1]
        return out

    def _static_friction(self, lengths, dirs, F, now: bool) -> Equilibrium:
        """The plant's state with tendon friction (module docstring): the series-stiffness fixed point from the
        present FrictionState; ``now``: the history first passes the rigging and every turn of the motors since
        the last solved state (:meth:`_friction_turns`), and the result becomes the present."""
        if now:
            for t, lt, dt in self._friction_turns():
                Ft = self.load(t)
                self.fstate = self._friction_step(lt, dt, Ft)
                self.fkey = (lt.tobytes(), dt.tobytes(), Ft.tobytes(), self.pressure)
                self.flengths = lt.copy()
            self.fidx = len(self.hist)
        key = (lengths.tobytes(), dirs.tobytes(), F.tobytes(), self.pressure)
        if key == self.fkey:
            return self.fstate.equilibrium
        st = self._friction_step(lengths, dirs, F)
        if now:
            self.fstate, self.fkey, self.flengths = st, key, lengths.copy()
        return st.equilibrium

    def _solve(self, l_act, F) -> Equilibrium:
        prev = self.last_eq
        try:
            return self.model.fk_locked(l_act, self.pressure, F, q0=None if prev is None else prev.q,
                                        tensions0=None if prev is None else prev.tensions)
        except ConvergenceError:
            try:
                return self.model.fk_locked(l_act, self.pressure, F)
            except ConvergenceError as exc:   # the plant itself failed: say where, keep the solver's record
                raise _plant_failed("locked FK", l_act, F, exc) from exc
        finally:
            self.solves += 1

    def _history_at(self, t: Optional[float]):
        """(motor lengths, pull directions, time) at rig time t (None: now; linear between records)."""
        if t is None or t >= self.time or not self.hist:
            return self.lengths, self.dir, self.time
        times = [h[0] for h in self.hist]
        i = max(bisect.bisect_right(times, t) - 1, 0)
        t0, l0, dirs = self.hist[i]
        if i + 1 < len(self.hist) and self.hist[i + 1][0] > t0 and t > t0:
            t1, l1, _ = self.hist[i + 1]
            return l0 + (l1 - l0) * (min(t, t1) - t0) / (t1 - t0), dirs, t      # linear between records
        return l0, dirs, t

    def lengths_at(self, t: float) -> np.ndarray:
        """Motor lengths (m,) [m] at rig time t."""
        return self._history_at(t)[0]

    def equilibrium(self, t: Optional[float] = None):
        """The actuator at time t (default now; earlier times use the history): the true locked equilibrium,
        or for a dynamic plant its state (:class:`hardware.sim_dynamics.DynamicState`)."""
        if self.lengths is None:
            raise InputError("simulated rig: no tendon lengths commanded yet")
        if self.dyn is not None:
            if self.dyn.state is None:
                self._start_dynamics()
            return self.dyn.at(t)
        return self._static(t)

    def _static(self, t: Optional[float] = None) -> Equilibrium:
        """True locked equilibrium at time t (default now; earlier times use the motor history)."""
        now = t is None or t >= self.time
        lengths, dirs, t = self._history_at(t)
        F = self.load(t)
        if self.mu > 0:
            return self._static_friction(lengths, dirs, F, now)
        key = (lengths.tobytes(), dirs.tobytes(), F.tobytes(), self.pressure)
        if key in self.cache:
            return self.cache[key]
        o = self.options
        if math.isinf(o.tendon_stiffness):
            eq = self._solve(lengths, F)
        else:
            la = lengths.copy()
            eq = None
            for _ in range(30):
                eq = self._solve(la, F)
                self.last_eq = eq
                la_new = lengths + (eq.tensions + dirs * o.tendon_friction * (eq.tensions > 0)) / o.tendon_stiffness
                if np.max(np.abs(la_new - la)) < 1e-10:
                    break
                la = la_new
        self.last_eq = eq
        if len(self.cache) > 64:
            self.cache.clear()
        self.cache[key] = eq
        return eq


# ================================================================================== simulated devices
class SimDrive(TendonDrive):
    def __init__(self, plant: _Plant, index: int):
        self.p, self.i = plant, index
        self.name = f"sim drive {index + 1}"
        self.enabled = False
        self.faulted = False

    def enable(self) -> None:
        self.check()
        self.enabled = True

    def move_to(self, length: float) -> None:
        self.check()
        if not self.enabled:
            raise DriveFault("move commanded while the drive is not enabled", device=self.name)
        p = self.p
        lc = p.quantise(np.array([float(length) + p.offset[self.i]]))[0]
        if p.lengths is None:                      # first command rigs the tendons (no move)
            p.lengths = np.full(p.model.m, np.nan) if p.target is None else p.lengths
        if p.target is None:
            p.target = np.full(p.model.m, np.nan)
        if np.isnan(p.lengths[self.i]):
            p.lengths[self.i] = lc
        else:
            d = lc - p.lengths[self.i]
            p.dir[self.i] = 1.0 if d < 0 else (-1.0 if d > 0 else p.dir[self.i])
        p.target[self.i] = lc

    def position(self) -> float:
        self.check()
        if self.p.lengths is None or np.isnan(self.p.lengths[self.i]):
            return float("nan")
        y = self.p.lengths if self.p.motor_y is None else self.p.motor_y      # the encoder: behind its loop
        return float(y[self.i] - self.p.offset[self.i])

    def target_reached(self) -> bool:
        return self.p.lengths is not None and self.p.lengths[self.i] == self.p.target[self.i]

    def hold(self) -> None:
        if self.p.lengths is not None and self.p.target is not None:
            self.p.target[self.i] = self.p.lengths[self.i]

    def quick_stop(self) -> None:
        self.hold()
        self.enabled = False

    def disable(self) -> None:
        self.hold()
        self.enabled = False

    def fault_reset(self) -> None:
        self.p.faults.pop("drive_fault", None)
        self.faulted = False

    def recover(self) -> bool:
        faulted = self.faulted or self.p.fault("drive_fault") is not None
        if faulted:
            self.fault_reset()
        needed = faulted or not self.enabled
        self.hold()                                # where it stands: the next move_to moves it
        self.enable()
        return needed

    def check(self) -> None:
        f = self.p.fault("drive_fault")
        if f is not None and f.get("drive", 0) == self.i:
            self.faulted = True
        if self.faulted:
            raise DriveFault("following error", device=self.name, code=0x8611)


class SimForceSensor(ForceSensor):
    def __init__(self, plant: _Plant, index: int):
        self.p, self.i = plant, index
        self.name = f"sim force sensor {index + 1}"

    def read(self) -> float:
        if self.p.fault("sensor_timeout") is not None:
            raise SensorTimeout("no reading within the timeout", device=self.name)
        T = float(self.p.equilibrium().tensions[self.i])
        s = self.p.options.force_noise_std
        return T + (self.p.rng.normal(0.0, s) if s > 0 else 0.0)


class SimPressure(PressureSupply):
    def __init__(self, plant: _Plant):
        self.p = plant
        self.name = "sim pressure supply"
        self._setpoint = plant.pressure
        self.vented = False

    def set(self, pressure: float) -> None:
        self._setpoint = float(pressure)
        self.p.pressure = float(pressure)
        self.vented = False

    def read(self) -> float:
        f = self.p.fault("pressure_overshoot")
        s = self.p.options.pressure_noise_std
        p = self.p.pressure
        if self.p.dyn is not None and self.p.dyn.state is not None:
            p = self.p.dyn.state.pressure                  # the chamber, behind the supply's time constant
        return p + (f["delta"] if f else 0.0) + (self.p.rng.normal(0.0, s) if s > 0 else 0.0)

    def hold(self) -> None:
        pass                                       # valves closed: the chamber keeps its air

    def vent(self) -> None:
        self.p.pressure = 0.0
        self._setpoint = 0.0
        self.vented = True


class SimTracker(TipTracker):
    def __init__(self, plant: _Plant):
        self.p = plant
        self.name = "sim tracker"
        self.frame = 0
        self._stale: Optional[TrackedPose] = None

    def read(self) -> TrackedPose:
        p = self.p
        if p.fault("tracker_stale") is not None and self._stale is not None:
            return self._stale
        self.frame += 1
        lat = p.options.tracker_latency
        t_state = p.time - lat
        if p.fault("tracking_lost") is not None:
            pose = TrackedPose(t_state, self.frame, np.full(3, np.nan), valid=False)
        elif p.fault("invalid_pose") is not None:
            pose = TrackedPose(t_state, self.frame, np.array([np.nan, 0.0, 0.0]), valid=True)
        else:
            tip = p.equilibrium(t_state if lat > 0 else None).tip.copy()
            if p.options.noise_std > 0:
                tip = tip + p.rng.normal(0.0, p.options.noise_std, 3)
            pose = TrackedPose(t_state, self.frame, tip, valid=True, quality=p.options.noise_std)
        self._stale = pose
        return pose


class _SimClock:
    def __init__(self, rig: "SimulatedRig"):
        self.rig = rig

    def now(self) -> float:
        return self.rig._plant.time

    def sleep(self, dt: float) -> None:
        self.rig._advance_time(dt)


# ================================================================================== the rig
class SimulatedRig(Rig):
    """The rig in simulation (the default backend): locked-length FK under a hidden load.

    Parameters
    ----------
    model_or_params : the *plant's* model or parameters (``options.params``, if given, wins)
    pressure : initial chamber pressure p [Pa] (a controller run sets its own through the supply)
    load : tip load F [N], (3,) constant or a callable ``F(t)`` of the rig clock t [s]
    options : :class:`PlantOptions`;  seed : overrides ``options.seed``;  dynamics : overrides
        ``options.dynamics`` (True: the actuator is integrated in time, :mod:`hardware.sim_dynamics`)
    limits : :class:`~hardware.limits.SafetyLimits` (default: travel 0.6–1.4 × length, 30 N, 160 kPa)
    on_fault_pressure : "hold" | "vent"
    """

    simulated = True

    def __init__(self, model_or_params: Union[Model, ActuatorParams], pressure: float = 0.0,
                 load: LoadLike = (0.0, 0.0, 0.0), options: Optional[PlantOptions] = None, *,
                 seed: Optional[int] = None, limits: Optional[SafetyLimits] = None, on_fault_pressure: str = "hold",
                 name: str = "simulated rig", config: Optional[dict] = None, dynamics: Optional[bool] = None):
        options = options or PlantOptions()
        if dynamics is not None:
            if not isinstance(options, PlantOptions):
                raise InputError(f"options must be PlantOptions, got {type(options).__name__}")
            options = PlantOptions(**{**options.__dict__, "dynamics": dynamics})
        if not isinstance(options, PlantOptions):
            raise InputError(f"options must be PlantOptions, got {type(options).__name__}")
        if seed is not None:
            if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)):
                raise InputError(f"seed must be an integer, got {seed!r}")
            options = PlantOptions(**{**options.__dict__, "seed": int(seed)})
        if options.params is not None:
            model = Model(options.params)
        elif isinstance(model_or_params, Model):
            model = model_or_params
        elif isinstance(model_or_params, ActuatorParams):
            model = Model(model_or_params)
        else:
            raise InputError(f"simulated rig needs an ancf.Model or ActuatorParams, got "
                             f"{type(model_or_params).__name__}")
        p0 = float(check_finite("pressure", pressure, ()))
        limits = limits or SafetyLimits.around(model.params.length)
        self._plant = _Plant(model, p0, options)
        self.pace = 0.0            # > 0: the rig clock runs at most ``pace`` × the wall clock (1 = real time)
        m = model.m
        speed = options.length_rate if math.isfinite(options.length_rate) else limits.speed_max
        if options.dynamics:
            self._plant.rate = min(speed, limits.speed_max)   # an instant move would jerk the tendons
        super().__init__([SimDrive(self._plant, i) for i in range(m)],
                         [SimForceSensor(self._plant, i) for i in range(m)], SimPressure(self._plant),
                         SimTracker(self._plant), limits=limits, on_fault_pressure=on_fault_pressure,
                         speed=min(speed, limits.speed_max), clock=_SimClock(self), name=name, config=config,
                         params=model.params)
        limits.check_pressure_command(p0)
        self.set_load(load)
        self.open()                                # simulated devices need no connection

    # ------------------------------------------------------------------------------ plant access
    model = property(lambda self: self._plant.model)
    options = property(lambda self: self._plant.options)
    rng = property(lambda self: self._plant.rng)
    lengths = property(lambda self: self._plant.lengths)
    target = property(lambda self: self._plant.target)
    solves = property(lambda self: self._plant.solves)
    pressure = property(lambda self: self._plant.pressure)

    @property
    def time(self) -> float:
        """Rig clock [s]."""
        return self._plant.time

    @time.setter
    def time(self, t: float) -> None:
        t = float(t)
        dyn = self._plant.dyn
        if dyn is not None and dyn.state is not None:
            if t < self._plant.time:
                raise InputError(f"a dynamic plant cannot go back in time (from {self._plant.time:g} s to {t:g} s)")
            self._advance_time(t - self._plant.time)          # integrate up to t
            return
        self._plant.time = t

    def set_load(self, load: LoadLike) -> None:
        """Hidden tip load [N]: a (3,) vector or a callable of time t [s] returning one."""
        if callable(load):
            self._plant.load_fn = load
        else:
            F = check_finite("load", load, (3,))
            fn = lambda t, F=F: F                                          # noqa: E731
            fn.change_times = lambda t0, t1: []
            self._plant.load_fn = fn
        self._plant.load(0.0)

    def load_changes(self, t0: float, t1: float) -> Optional[list]:
        """Times in (t0, t1) [s] at which the hidden load jumps (the load profile's ``change_times``; [] for
        a constant load), or None when the load is a callable that does not say (unknown)."""
        ct = getattr(self._plant.load_fn, "change_times", None)
        return None if ct is None else [float(t) for t in ct(t0, t1)]

    def load(self, t: Optional[float] = None) -> np.ndarray:
        """True tip load at time t [s] (default: now) [N]."""
        return self._plant.load(t)

    def equilibrium(self):
        """The plant's true locked equilibrium now (a dynamic plant: its state — q, v, tip, tensions)."""
        return self._plant.equilibrium()

    def true_tip(self) -> np.ndarray:
        """Noise-free tip position now [m]."""
        return self.equilibrium().tip.copy()

    def pull_through(self, tendon: int, motor_tensions) -> tuple[np.ndarray, np.ndarray]:
        """A pull-through test on the simulated rig (docs/friction.md): the actuator clamped in its present
        shape, tendon ``tendon`` (0-based) pulled through and released by its motor in tension control through
        ``motor_tensions`` (k,) [N] from slack.  Returns (motor-side tensions (k,) [N] — the commanded ones —,
        anchor-side tensions (k,) [N] — the plant's last tendon segment under the capstan law of its
        ``tendon_friction``, read by a load cell at the anchor with the force sensors' noise).  Static plant only."""
        from ancf.friction import pull_through
        if self._plant.dyn is not None:
            raise InputError("pull_through clamps the actuator in a static state: not on a dynamic plant")
        eq = self.equilibrium()
        Tm = check_finite("motor_tensions", motor_tensions, None).ravel()
        anchor, _codes = pull_through(self.model, eq.q, tendon, Tm)
        s = self.options.force_noise_std
        if s > 0:
            anchor = anchor + self.rng.normal(0.0, s, anchor.size)
        return Tm.copy(), anchor

    def move_time(self) -> float:
        """Seconds until the motors reach the commanded lengths."""
        return self._plant.move_time()

    def inject(self, fault: str, at: float = 0.0, **details) -> None:
        """Schedule a fault from rig time ``at`` [s] on: one of :data:`FAULTS`.  ``drive_fault`` takes
        ``drive=`` (index, default 0); ``pressure_overshoot`` takes ``delta=`` [Pa] (default 30 kPa)."""
        if fault not in FAULTS:
            raise InputError(f"unknown fault {fault!r}; one of {', '.join(FAULTS)}")
        if fault == "pressure_overshoot":
            details.setdefault("delta", 30e3)
        self._plant.faults[fault] = {"at": float(at), **details}

    # ------------------------------------------------------------------------------ loop protocol
    def command(self, lengths, expected_tensions=None) -> float:
        """Check and send motor lengths (m,) [m]; returns the move duration [s] (rate limit).  The first
        command rigs the tendons: the plant starts there with no move."""
        if self._plant.lengths is None:
            try:
                a = self.limits.check_lengths(lengths, None, self.m)
            except HardwareError as exc:
                self.event("limit", str(exc))
                raise
            for d, li in zip(self.drives, a):
                d.move_to(float(li))
            self._plant.record()
            self.commanded = a.copy()
            return 0.0
        super().command(lengths, expected_tensions)
        return self._plant.move_time()

    def _advance_time(self, dt: float) -> None:
        if dt < 0 or not math.isfinite(dt):
            raise InputError(f"dt must be a finite time >= 0 s, got {dt}")
        if self._plant.lengths is None:
            self._plant.time += dt
        else:
            self._plant.advance(dt)
        if self.pace > 0 and dt > 0:
            import time
            time.sleep(dt / self.pace)

    def advance(self, dt: Optional[float] = None) -> None:
        """Let ``dt`` seconds pass (None: until the motors reach their command)."""
        if self._plant.lengths is None:
            raise InputError("simulated rig: command tendon lengths before advancing time")
        for d in self.drives:
            d.check()
        self._advance_time(self._plant.move_time() if dt is None else float(dt))

    def describe(self) -> dict:
        out = super().describe()
        o = self.options
        out["plant_options"] = {k: (v if k != "params" else (None if v is None else v.to_toml()))
                                for k, v in o.__dict__.items()}
        return out
