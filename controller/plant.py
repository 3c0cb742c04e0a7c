r"""Simulated plant: the locked-tendon-length FK with a load the controller never sees.

The motors hold tendon lengths l_m [m]; the actuator settles to the locked equilibrium
(:meth:`ancf.Model.fk_locked`, paper eqs. 3–6) under the true tip load F(t) [N] and its own parameters.
A controller only gets :meth:`SimulatedPlant.measure`.

Mismatch options (:class:`PlantOptions`), so that no result rests on the controller meeting its own model:

* ``params`` — the plant's own actuator parameters (e.g. ``presets.paper().replace(line_mass=0.35)``).
* ``noise_std`` [m] — white Gaussian noise on each measured coordinate (tracker noise).
* ``length_resolution`` [m] — motor position quantum: commands are rounded to multiples of it.
* ``length_rate`` [m/s] — motor speed limit on each tendon length; moves take max|Δl| / rate seconds and,
  in timed simulations, the actuator passes through the intermediate states.
* ``length_offset`` (m,) [m] — calibration error of the tendon-length zero (added to every command).
* ``tendon_friction`` [N] and ``tendon_stiffness`` [N/m] — friction in the routing as a tension loss
  f_c between motor and actuator, acting through the series elasticity of tendon and sheath (flagged
  interpretation).  With inextensible tendons a tension loss cannot change a *locked-length* equilibrium
  (the tension is only the constraint multiplier), so friction acts through the stretch: the length the
  actuator sees is l_a = l_m + (T_a + s f_c) / k_s, where T_a is the tension at the actuator and s = +1
  after the motor last pulled (shortened) that tendon, −1 after it released it — a hysteresis of width
  2 f_c / k_s.  Solved by fixed-point iteration on l_a (the actuator is far softer than k_s).

Reproducible: all randomness comes from ``numpy.random.default_rng(seed)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Optional, Protocol, Sequence, Union, runtime_checkable

import numpy as np

from ancf import ActuatorParams, ConvergenceError, Equilibrium, Model
from ancf.errors import InputError, check_finite

from .errors import ControllerError

LoadLike = Union[Sequence[float], np.ndarray, Callable[[float], np.ndarray]]


@runtime_checkable
class Plant(Protocol):
    """What the loops need from a rig (simulated or real): SI units, seconds."""

    def command(self, lengths) -> float:
        """Send tendon lengths (m,) [m]; return the expected move duration [s]."""

    def advance(self, dt: Optional[float] = None) -> None:
        """Let time pass (None: until the last command is executed)."""

    def measure(self) -> np.ndarray:
        """Measured tip position (3,) [m]."""


@dataclass(frozen=True)
class PlantOptions:
    """Model-mismatch and hardware options of :class:`SimulatedPlant` (all SI; defaults = perfect plant)."""
    params: Optional[ActuatorParams] = None
    noise_std: float = 0.0
    length_resolution: float = 0.0
    length_rate: float = math.inf
    length_offset: Optional[tuple] = None
    tendon_friction: float = 0.0
    tendon_stiffness: float = math.inf
    seed: int = 0

    def __post_init__(self):
        for nm in ("noise_std", "length_resolution", "tendon_friction"):
            v = getattr(self, nm)
            if not (np.isfinite(v) and v >= 0):
                raise InputError(f"PlantOptions.{nm} must be finite and >= 0, got {v}")
        for nm in ("length_rate", "tendon_stiffness"):
            v = getattr(self, nm)
            if not (v > 0) or np.isnan(v):
                raise InputError(f"PlantOptions.{nm} must be > 0 (inf allowed), got {v}")

    @classmethod
    def mismatched(cls, seed: int = 0, **changes) -> "PlantOptions":
        """A representative imperfect rig: +15 % line mass, k(λ) scaled by 0.95, 5 g heavier tip,
        0.05 mm tracker noise, 1 µm motor resolution, 5 mm/s motor speed, 0.1 N friction over a 20 kN/m
        tendon.  Keyword arguments override any field."""
        from ancf import presets, StiffnessLaw
        base = presets.paper()
        src = base.stiffness.source
        law = StiffnessLaw.linear(0.95 * src["a"], 0.95 * src["b"], src["D_a"])
        params = base.replace(line_mass=base.line_mass * 1.15, tip_mass=base.tip_mass + 0.005, stiffness=law)
        opts = dict(params=params, noise_std=5e-5, length_resolution=1e-6, length_rate=5e-3,
                    tendon_friction=0.1, tendon_stiffness=2e4, seed=seed)
        opts.update(changes)
        return cls(**opts)


class SimulatedPlant:
    """The rig in simulation: locked-length FK under a hidden load, with optional mismatch.

    Parameters
    ----------
    model_or_params : the *plant's* model or parameters.  (If ``options.params`` is given it wins.)
    pressure : p [Pa], held constant
    load : tip load F [N], (3,) constant or a callable ``F(t)`` of the plant clock t [s]
    options : :class:`PlantOptions`
    """

    def __init__(self, model_or_params: Union[Model, ActuatorParams], pressure: float,
                 load: LoadLike = (0.0, 0.0, 0.0), options: PlantOptions = PlantOptions()):
        if options.params is not None:
            self.model = Model(options.params)
        elif isinstance(model_or_params, Model):
            self.model = model_or_params
        elif isinstance(model_or_params, ActuatorParams):
            self.model = Model(model_or_params)
        else:
            raise InputError(f"plant needs an ancf.Model or ActuatorParams, got {type(model_or_params).__name__}")
        self.pressure = float(check_finite("pressure", pressure, ()))
        self.options = options
        self.rng = np.random.default_rng(options.seed)
        m = self.model.m
        self._offset = (np.zeros(m) if options.length_offset is None
                        else check_finite("length_offset", options.length_offset, (m,)))
        self.time = 0.0
        self.lengths: Optional[np.ndarray] = None        # motor-side lengths now [m]
        self.target: Optional[np.ndarray] = None         # commanded motor lengths [m]
        self._dir = np.ones(m)                           # +1 after pulling, −1 after releasing
        self._eq: Optional[Equilibrium] = None
        self._key = None
        self.solves = 0
        self.set_load(load)

    # ----------------------------------------------------------------------------------------- load
    def set_load(self, load: LoadLike) -> None:
        """Hidden tip load [N]: a (3,) vector or a callable of time t [s] returning one."""
        if callable(load):
            self._load_fn = load
        else:
            F = check_finite("load", load, (3,))
            self._load_fn = lambda t, F=F: F
        self._key = None

    def load(self, t: Optional[float] = None) -> np.ndarray:
        """True tip load at time t [s] (default: now) [N]."""
        F = np.asarray(self._load_fn(self.time if t is None else t), float)
        if F.shape != (3,) or not np.all(np.isfinite(F)):
            raise InputError(f"load profile returned {F} at t = {t}")
        return F

    # ----------------------------------------------------------------------------------------- motors
    def _quantise(self, lengths: np.ndarray) -> np.ndarray:
        r = self.options.length_resolution
        return np.round(lengths / r) * r if r > 0 else lengths

    def command(self, lengths) -> float:
        """Send motor lengths (m,) [m].  Returns the move duration [s] (rate limit).  The first command
        rigs the tendons: the plant starts there with no move."""
        lc = self._quantise(check_finite("tendon lengths command", lengths, (self.model.m,)) + self._offset)
        if self.lengths is None:
            self.lengths = lc.copy()
            self.target = lc.copy()
            self._key = None
            return 0.0
        d = lc - self.lengths
        self._dir = np.where(d < 0, 1.0, np.where(d > 0, -1.0, self._dir))
        self.target = lc
        return self.move_time()

    def move_time(self) -> float:
        """Seconds until the motors reach the commanded lengths."""
        if self.lengths is None:
            return 0.0
        dl = float(np.max(np.abs(self.target - self.lengths)))
        return 0.0 if dl == 0 else dl / self.options.length_rate

    def advance(self, dt: Optional[float] = None) -> None:
        """Let ``dt`` seconds pass (None: until the motors reach their command)."""
        if self.lengths is None:
            raise InputError("plant: command tendon lengths before advancing time")
        if dt is None:
            dt = self.move_time()
        if dt < 0:
            raise InputError(f"dt must be >= 0 s, got {dt}")
        if dt > 0 or not np.array_equal(self.lengths, self.target):
            if math.isinf(self.options.length_rate):
                self.lengths = self.target.copy()
            else:
                step = self.options.length_rate * dt
                d = self.target - self.lengths
                self.lengths = np.where(np.abs(d) <= step, self.target, self.lengths + np.sign(d) * step)
            self._key = None
        self.time += dt

    # ----------------------------------------------------------------------------------------- state
    def _solve(self, l_act: np.ndarray, F: np.ndarray) -> Equilibrium:
        m = self.model
        prev = self._eq
        try:
            return m.fk_locked(l_act, self.pressure, F, q0=None if prev is None else prev.q,
                               tensions0=None if prev is None else prev.tensions)
        except ConvergenceError:
            try:
                return m.fk_locked(l_act, self.pressure, F)
            except ConvergenceError as exc:
                raise ControllerError(f"plant: locked FK failed at lengths {l_act.tolist()} m, load {F.tolist()} N: "
                                      f"{exc}") from exc
        finally:
            self.solves += 1

    def equilibrium(self) -> Equilibrium:
        """The plant's true locked equilibrium now (cached)."""
        if self.lengths is None:
            raise InputError("plant: no tendon lengths commanded yet")
        F = self.load()
        key = (self.lengths.tobytes(), F.tobytes())
        if key == self._key:
            return self._eq
        o = self.options
        if math.isinf(o.tendon_stiffness):
            eq = self._solve(self.lengths, F)
        else:
            la = self.lengths.copy()
            eq = None
            for _ in range(30):
                eq = self._solve(la, F)
                self._eq = eq
                la_new = self.lengths + (eq.tensions + self._dir * o.tendon_friction * (eq.tensions > 0)) \
                    / o.tendon_stiffness
                if np.max(np.abs(la_new - la)) < 1e-10:
                    break
                la = la_new
        self._eq, self._key = eq, key
        return eq

    def true_tip(self) -> np.ndarray:
        """Noise-free tip position [m]."""
        return self.equilibrium().tip.copy()

    def measure(self) -> np.ndarray:
        """Tip position as the tracker reports it [m] (true tip + noise)."""
        tip = self.true_tip()
        if self.options.noise_std > 0:
            tip = tip + self.rng.normal(0.0, self.options.noise_std, 3)
        return tip
