r"""Transient response of the reduced model: :meth:`ancf.Model.simulate`.

Equations of motion in the free coordinates z (q = q_fix + P z, docs/dynamics.md):

    Pᵀ M(q) P z̈ + Pᵀ [Q(q, T, p, F) + Q_d(q, q̇) + m J_pᵀ (∇²p_end[q̇, q̇])] + C_R ż = 0

* M: consistent ANCF mass (:mod:`.mass`) plus the tool-point mass m J_pᵀ J_p; Q = ∂Π/∂q, the static
  model's generalized force (axial, bending, tendons, pressure, gravity, tip force) with its exact tangent;
  Q_d the Kelvin–Voigt axial damping and C_R the Rayleigh matrix (:mod:`.damping`); the last term is the
  tool point's centripetal acceleration (d'Alembert force −m p̈, p̈ = J_p q̈ + ∇²p_end[q̇, q̇]; zero without a
  tool offset).
* Tendons: prescribed tensions T(t) ≥ 0 (slack is T = 0), or prescribed lengths l⁰(t) (motor positions,
  locked or moving) as a one-sided spring T_i = k max(0, l_i(q) − l⁰_i) — k the actuator's
  ``tendon_stiffness`` when it has one (then this *is* the tendon), else the penalty ``tendon_penalty`` —
  with the exact tangent k ∇l ∇lᵀ + T ∇²l; a tendon goes slack and taut again by itself (events).
  With tendon friction (``tendon_friction`` μ > 0, tensions prescribed; held lengths refused) the tendon force
  is the capstan law's per-segment one, the guides' stick/slip history carried from step to step
  (:mod:`.friction_step`; its rows run on the Python path, and its dissipation is in D below).
* Pressure: a prescribed signal p(t), or a first-order supply p' = (p_cmd(t) − p)/τ (``pressure_tau``),
  integrated with the trapezoidal rule.
* Tip force F(t), a dead load at the tool point.

Integration: generalized-α (:mod:`.integrator`), fixed step h = t_end / ceil(t_end / dt) with automatic
halving (up to ``max_halvings`` times) of a step whose Newton iteration fails; a run that still fails
raises :class:`~ancf.errors.ConvergenceError` at the time it happened, a state leaving the model's domain
:class:`~ancf.errors.CollapsedStateError` — never a silent blow-up.  A step too coarse for the motion is found
by the energy balance below (:class:`_EnergyWatch`: the energy the integration created against the energy of
the motion, after every output row) and the run repeated in halved substeps (:func:`_run_refined`; output rows
stay at dt), or refused with a ConvergenceError naming a step that would do.  Ctrl-C sets a flag read between
steps (:mod:`.interrupt`), never an exception inside a compiled kernel: the rows done are returned.

Speed: the output rows of a run are made in chunks by compiled kernels (:mod:`.compiled_step`: the step, its
Newton iterations and the rows' energies; the same numbers as the Python path to round-off), the load signals
sampled here on the chunk's substep grid (:meth:`_FastRows._table`: constant or time-varying tensions, tendon
lengths, pressure command — with or without the supply's ``pressure_tau`` —, tip force, and a pressure-dependent
law's factors), Python touched between chunks (Ctrl-C, progress, the energy check, events) and for a row whose
step fails there or whose loads fail their checks (a halving, an error: :class:`_Stepper`, :class:`_Recorder`).

Energy bookkeeping (all [J]): kinetic K = ½ q̇ᵀ M q̇; potential Π(q; loads(t)) (elastic + gravity + the load
potentials Σ T_i l_i − p V − F·p_end + the length springs); the work of the time-varying loads
W = ∫ ∂Π/∂t dt; the dissipated energy D = ∫ q̇ᵀ(C_R q̇ + Q_d) dt.  ``energy`` = K + Π − W obeys
d(energy)/dt = −dD/dt exactly in time, so energy + dissipated is constant up to the integrator's error
(trapezoidal sums, second order).
"""

from __future__ import annotations

import math
import time as _time
import warnings
from dataclasses import dataclass, field
from typing import Callable, Optional

import numpy as np

from ..assembly import assemble
from ..errors import CollapsedStateError, ConvergenceError, InputError, LimitError, check_finite, check_scalar
from .damping import UndampedWarning, axial_damping, damping_source, undamped_message
from .friction_step import dissipation_increment, friction_history
from .integrator import AlphaCoefficients, StepFailed, StepState, alpha_step
from .interrupt import StopFlag
from .mass import consistent_mass, tool_point_inertia
from .signals import Signal


@dataclass
class Simulation:
    """A transient run.  Rows are output times.

    t (N,) [s]; q, v (N, ndof) coordinates and velocities; tip (N, 3) tool point [m]; tensions (N, m) [N]
    (prescribed, or the length springs'); pressure (N,) [Pa]; energy, kinetic, potential, work, dissipated
    (N,) [J] (module docstring: energy + dissipated is conserved); events: list of dicts (t [s], kind,
    tendon, text) — tendons going slack/taut, steps subdivided, the run refined (the energy check);
    newton_iterations (N,) per output step;
    dt [s] the step used; damping: the coefficients used {alpha [1/s], beta [s], axial [N s]};
    damping_source: where they come from — "given" (the call's ``damping=``), "actuator" (the actuator's
    coefficients) or "none" (the actuator states no damping and none was given: an undamped run, announced
    by an :class:`~ancf.dynamics.damping.UndampedWarning`); rho_inf; wall_time [s].
    With tendon friction (μ > 0, :mod:`.friction_step`): segment_tensions (N, m, n) [N] the guides' segment
    tensions (the next run's history: ``simulate(..., segment_tensions=sim.segment_tensions[-1])``) and
    friction_dissipated (N,) [J] the friction's share of ``dissipated``; None without friction."""
    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    tip: np.ndarray
    tensions: np.ndarray
    pressure: np.ndarray
    energy: np.ndarray
    kinetic: np.ndarray
    potential: np.ndarray
    work: np.ndarray
    dissipated: np.ndarray
    newton_iterations: np.ndarray
    dt: float
    damping: dict
    rho_inf: float
    events: list = field(default_factory=list)
    wall_time: float = 0.0
    interrupted: bool = False
    damping_source: str = "given"
    segment_tensions: Optional[np.ndarray] = None
    friction_dissipated: Optional[np.ndarray] = None

    @property
    def real_time_factor(self) -> float:
        """Simulated time per wall-clock second (> 1: faster than real time)."""
        return float(self.t[-1] - self.t[0]) / self.wall_time if self.wall_time > 0 else float("inf")


#: most time steps of one transient run (t_end / dt)
MAX_STEPS = 10_000_000


def resolve_damping(model, damping, K0: np.ndarray, Mz: np.ndarray) -> dict:
    """The damping coefficients {alpha [1/s], beta [s], axial [N s]} of a run (module docstring of
    :meth:`ancf.Model.simulate` for the accepted forms)."""
    p = model.params
    if damping is None:
        return {"alpha": p.rayleigh_alpha, "beta": p.rayleigh_beta, "axial": p.axial_damping}
    if isinstance(damping, dict):
        unknown = set(damping) - {"alpha", "beta", "axial", "stiffness"}
        if unknown:
            raise InputError(f"damping: unknown keys {sorted(unknown)}; use alpha [1/s], beta [s], axial [N s] "
                             "(and optionally stiffness: the (nz, nz) matrix β multiplies)")
        out = {"alpha": 0.0, "beta": 0.0, "axial": 0.0}
        for k, v in damping.items():
            if k == "stiffness":
                out[k] = check_finite("damping['stiffness']", v, (model.nz, model.nz))
            else:
                out[k] = check_scalar(f"damping[{k!r}]", v, low=0.0, high=1e6)
        return out
    zeta = check_scalar("damping", damping, low=0.0, high=1.0)
    if zeta == 0.0:
        return {"alpha": 0.0, "beta": 0.0, "axial": 0.0}
    import scipy.linalg as sla
    w2 = sla.eigh(K0, Mz, eigvals_only=True, subset_by_index=[0, 0])[0]
    if not w2 > 0:
        raise InputError("damping given as a ratio needs a stable start state (its lowest mode sets "
                         "β = 2ζ/ω₁); start from an equilibrium or give {'alpha', 'beta', 'axial'}")
    return {"alpha": 0.0, "beta": 2.0 * zeta / math.sqrt(w2), "axial": 0.0}


def rayleigh_about(model, eq, ratio: float) -> dict:
    """Stiffness-proportional damping with ratio ``ratio`` at the first mode about the equilibrium ``eq``
    (tensions held): ``{"alpha": 0, "beta": 2ζ/ω₁, "axial": 0, "stiffness": K}`` with K (nz, nz) the tangent
    at ``eq``, the matrix β multiplies for the whole run — e.g. the equilibrium a step response settles on,
    where a ratio given as a number would be taken about the (moving) start state."""
    zeta = check_scalar("ratio", ratio, low=0.0, high=1.0)
    ev = model.evaluate(eq.q, eq.tensions, eq.pressure, eq.tip_force)
    K = model.reduce_mat(ev.K)
    K = 0.5 * (K + K.T)
    M = consistent_mass(model.n, model._N, model._wq, model.params.line_mass)
    if model.params.tip_mass > 0:
        from .mass import tip_mass_matrix
        M = M + tip_mass_matrix(eq.q, model.params.tool_offset, model.params.tip_mass)
    out = resolve_damping(model, zeta, K, model.reduce_mat(M))
    out["stiffness"] = K
    return out


def simulate(model, t_end: float, dt: float, q0=None, v0=None, *, tensions=None, lengths=None,
             pressure=0.0, pressure_tau: Optional[float] = None, pressure0: Optional[float] = None,
             tip_force=(0.0, 0.0, 0.0), damping=None, rho_inf: float = 0.9,
             tendon_penalty: Optional[float] = None, holding_force: Optional[float] = None,
             check_limits: bool = True, max_halvings: int = 8,
             max_iter: int = 12, progress: Optional[Callable[[float, float], None]] = None,
             segment_tensions=None) -> Simulation:
    """Integrate the model in time (module docstring); see :meth:`ancf.Model.simulate` for the arguments.

    The steps: the run's inputs checked (:func:`_check_run`), the loads made and checked on the whole output
    grid (:func:`_make_loads`), the start state (:func:`_start_state`), the equations of motion with their
    damping (:func:`_make_plant`), then the time loop (:func:`_integrate`: substeps in :class:`_Stepper`,
    output rows and the energy bookkeeping in :class:`_Recorder`), stopped early by Ctrl-C."""
    wall0 = _time.perf_counter()
    with StopFlag() as stop:         # a Ctrl-C from here on ends the run between two steps, with row 0 at least
        t_end, rho_inf, h, times = _check_run(model, t_end, dt, rho_inf, max_halvings, tensions, lengths)
        loads = _make_loads(model, tensions, lengths, pressure, tip_force, pressure_tau, tendon_penalty,
                            holding_force, check_limits)
        loads.check_grid(times)
        fric = friction_history(model, loads, segment_tensions)      # tendon friction's history, None at μ = 0
        p_init = _initial_pressure(loads, pressure0)
        if fric is not None and q0 is None:                             # at rest on the friction history
            q0 = fric.start(loads, p_init, check_limits)
        z, vz = _start_state(model, loads, q0, v0, p_init)
        source = damping_source(model.params, damping)
        if source == "none":
            warnings.warn(UndampedWarning(undamped_message(model.params, "the run is undamped apart from the "
                                                           "integrator's numerical dissipation (rho_inf < 1)")),
                          stacklevel=3)
        plant, coeffs = _make_plant(model, loads, z, p_init, damping)
        plant.friction = fric
        n_out, rec, stepper = _run_refined(plant, loads, z, vz, p_init, times, h, rho_inf, max_halvings, max_iter,
                                           progress, stop)
    sl = slice(0, n_out)
    return Simulation(t=times[sl].copy(), q=rec.q[sl], v=rec.v[sl], tip=rec.tip[sl], tensions=rec.T[sl],
                      pressure=rec.p[sl], energy=rec.kinetic[sl] + rec.potential[sl] - rec.work[sl],
                      kinetic=rec.kinetic[sl], potential=rec.potential[sl], work=rec.work[sl],
                      dissipated=rec.dissipated[sl], newton_iterations=rec.iterations[sl], dt=h, damping=coeffs,
                      rho_inf=rho_inf, events=stepper.events, wall_time=_time.perf_counter() - wall0,
                      interrupted=n_out < len(times), damping_source=source,
                      segment_tensions=None if rec.Tseg is None else rec.Tseg[sl],
                      friction_dissipated=None if rec.Tseg is None else rec.friction_dissipated[sl])


def _run_refined(plant, loads, z, vz, p_init: float, times: np.ndarray, h: float, rho_inf: float, max_halvings: int,
                 max_iter: int, progress, stop):
    """The time loop (:func:`_integrate`) at substeps h / 2^k, k = 0, 1, … until the energy check passes (each
    refinement an event, the output rows stay at h); ConvergenceError naming the step that would do when it
    still fails at k = MAX_REFINE.  Returns (rows done, the :class:`_Recorder`, the :class:`_Stepper`)."""
    model, events = plant.model, []
    for base in range(MAX_REFINE + 1):
        if plant.friction is not None:
            plant.friction.reset()
        stepper = _Stepper(h, AlphaCoefficients.from_rho(rho_inf), max_halvings, max_iter,
                           max(model.default_tol, 1e-10), base=base)
        rec = _Recorder(plant, _EnergyParts(model, loads), len(times))
        n_out, bad = _integrate(plant, loads, stepper, rec, _initial_acceleration(plant, loads, z, vz, p_init),
                                times, p_init, progress, stop)
        if bad is None:
            stepper.events[:0] = events
            return n_out, rec, stepper
        t_bad, hs = float(times[bad["row"]]), h / 2 ** base
        if base == MAX_REFINE:
            # the energy created grows faster than linearly in the step: a linear estimate with a factor 8 (the
            # `paper` actuator's 2 N step at 50 ms, its first step converged whole: 0.27 of the budget created
            # names 3.4 ms with a factor 4, where 3.0 ms is the largest step that passes)
            h_ok = hs * min(0.5, 0.125 * ENERGY_RTOL * bad["budget"] / bad["created"])
            raise ConvergenceError(
                f"the time step is too coarse for this motion: by t = {t_bad:.6g} s the integration created "
                f"{bad['created']:.3g} J of energy, more than the motion's {bad['budget']:.3g} J, even in "
                f"substeps of {hs:.3g} s (dt / {2 ** base}); use dt ≤ {h_ok:.2g} s", solver="simulate",
                iterations=base, residual_norm=bad["created"], tolerance=ENERGY_RTOL * bad["budget"])
        events.append({"t": t_bad, "kind": "refined", "tendon": None,
                       "text": f"run repeated in substeps of {h / 2 ** (base + 1):.3g} s: at t = {t_bad:.6g} s "
                               f"steps of {hs:.3g} s had created {bad['created']:.3g} J of energy (> the "
                               f"motion's {bad['budget']:.3g} J)"})
    raise AssertionError("unreachable")


# ------------------------------------------------------------------------------------------------ inputs
def _check_run(model, t_end, dt, rho_inf, max_halvings, tensions, lengths):
    """The run's scalar inputs checked up front: (t_end [s], rho_inf, h [s] the step, times (N,) [s] the
    output grid, N = ceil(t_end / dt) + 1).  InputError for anything out of range, for an actuator without
    line mass and unless exactly one of tensions / lengths is given."""
    p = model.params
    t_end = check_scalar("t_end", t_end, low=0.0, high=1e6, unit="s")
    dt = check_scalar("dt", dt, low=0.0, high=t_end, unit="s")
    if not (t_end > 0 and dt > 0):
        raise InputError(f"t_end and dt must be > 0 s, got t_end = {t_end:g} s, dt = {dt:g} s")
    rho_inf = check_scalar("rho_inf", rho_inf, low=0.0, high=1.0)
    nsteps = int(math.ceil(t_end / dt - 1e-9))
    if nsteps > MAX_STEPS:
        raise InputError(f"t_end / dt = {nsteps} steps is more than 10⁷; use a larger dt")
    if isinstance(max_halvings, bool) or not isinstance(max_halvings, int) or not 0 <= max_halvings <= 20:
        raise InputError(f"max_halvings must be an integer 0…20, got {max_halvings!r}")
    if not p.line_mass > 0 and not p.tip_mass > 0:
        raise InputError("a transient run needs mass: the actuator has line_mass = 0 and tip_mass = 0")
    if not p.line_mass > 0:
        raise InputError("a transient run needs the actuator's line mass (line_mass > 0 kg/m): without it "
                         "the mass matrix is singular")
    if (tensions is None) == (lengths is None):
        raise InputError("give exactly one of tensions= (prescribed tension [N]) or lengths= (prescribed "
                         "tendon lengths [m], e.g. locked at eq.tendon_lengths)")
    return t_end, rho_inf, t_end / nsteps, np.linspace(0.0, t_end, nsteps + 1)


@dataclass
class _Loads:
    """The load signals of a run and the rules they obey.  Tendons by tension (``T_sig`` (m,) [N]) or by length
    (``l0_sig`` (m,) [m]: one-sided springs of stiffness ``k_pen`` [N/m], the motors giving way at ``F_hold``
    [N], i.e. at the stretch ``s_hold`` [m]); ``pc_sig`` the pressure (command, with a supply of time constant
    ``tau`` [s]) [Pa]; ``F_sig`` (3,) the tip force [N]."""
    params: object
    check_limits: bool
    T_sig: Optional[Signal]
    l0_sig: Optional[Signal]
    pc_sig: Signal
    F_sig: Signal
    tau: Optional[float]
    k_pen: float
    F_hold: float
    s_hold: float

    @property
    def length_mode(self) -> bool:
        return self.l0_sig is not None

    @property
    def varying(self) -> bool:
        """True when Π depends on time (loads that change, a pressure supply, tendons held by length)."""
        return (self.length_mode or not (self.T_sig.constant and self.pc_sig.constant and self.F_sig.constant)
                or self.tau is not None)

    def tensions(self, t: float) -> Optional[np.ndarray]:
        """The prescribed tensions [N] at t, None for tendons held by length."""
        return None if self.length_mode else self.T_sig(t)

    def lengths(self, t: float) -> Optional[np.ndarray]:
        """The prescribed tendon lengths [m] at t, None for tendons driven by tension."""
        return self.l0_sig(t) if self.length_mode else None

    def check(self, t: float, T=None, pr=None, l0=None) -> None:
        """InputError / LimitError (naming t [s]) for tensions T [N], pressure pr [Pa] or lengths l0 [m] the
        actuator cannot take."""
        p = self.params
        if T is not None:
            if np.any(T < -1e-12):
                raise InputError(f"tensions at t = {t:.6g} s: a tendon cannot push (T = {T} N)")
            if self.check_limits and np.any(T > p.tension_max + 1e-12):
                raise LimitError(f"tensions at t = {t:.6g} s: {T} N above the actuator's tension_max "
                                 f"{p.tension_max:g} N (check_limits=False analyses it anyway)")
        if pr is not None and self.check_limits and not p.pressure_min - 1e-9 <= pr <= p.pressure_max + 1e-9:
            raise LimitError(f"pressure at t = {t:.6g} s: {pr / 1e3:g} kPa outside the actuator's limits "
                             f"[{p.pressure_min / 1e3:g}, {p.pressure_max / 1e3:g}] kPa (the Python API takes "
                             "pascals; check_limits=False analyses it anyway)")
        if l0 is not None and np.any(l0 <= 0):
            raise InputError(f"lengths at t = {t:.6g} s must be > 0 m, got {l0}")

    def check_grid(self, times: np.ndarray) -> None:
        """Fail fast: every signal on the output grid before integrating (at t = 0 only when every signal is
        constant: the same values at every time)."""
        sigs = (self.pc_sig, self.F_sig, self.l0_sig if self.length_mode else self.T_sig)
        for t in (times[:1] if all(s.constant for s in sigs) else times):
            self.check(t, T=self.tensions(t), pr=float(self.pc_sig(t)), l0=self.lengths(t))
            self.F_sig(t)

    def pressure_at(self, t_new: float, t_old: float, p_old: float) -> float:
        """The pressure [Pa] at t_new: the prescribed one, or the supply's (trapezoidal rule from p_old at
        t_old)."""
        if self.tau is None:
            return float(self.pc_sig(t_new))
        c = (t_new - t_old) / (2 * self.tau)
        return (p_old * (1 - c) + c * (float(self.pc_sig(t_old)) + float(self.pc_sig(t_new)))) / (1 + c)

    def springy(self, T: np.ndarray) -> np.ndarray:
        """Tendons whose tension follows their stretch (taut, below the motors' holding force)."""
        return (T > 0) & (T < self.F_hold)


def _make_loads(model, tensions, lengths, pressure, tip_force, pressure_tau, tendon_penalty, holding_force,
                check_limits) -> _Loads:
    """The run's :class:`_Loads`, every argument checked (InputError)."""
    p = model.params
    T_sig = l0_sig = None
    if lengths is not None:
        l0_sig = Signal("lengths", lengths, (model.m,), "m")
        k_pen = p.tendon_stiffness if p.tendon_stiffness else (
            1e5 if tendon_penalty is None else check_scalar("tendon_penalty", tendon_penalty, low=1.0, high=1e12,
                                                            unit="N/m"))
        if p.tendon_stiffness and tendon_penalty is not None:
            raise InputError("tendon_penalty is for inextensible tendons; this actuator's tendons have "
                             f"tendon_stiffness = {p.tendon_stiffness:g} N/m, which is used")
    else:
        T_sig = Signal("tensions", tensions, (model.m,), "N")
        k_pen = 0.0
    if holding_force is not None:
        if lengths is None:
            raise InputError("holding_force is the motors' force limit for tendons held by length (lengths=)")
        holding_force = check_scalar("holding_force", holding_force, low=1e-6, high=1e5, unit="N")
    F_hold = math.inf if holding_force is None else holding_force
    s_hold = F_hold / k_pen if lengths is not None else math.inf      # the stretch at which a motor gives way
    pc_sig = Signal("pressure", pressure, (), "Pa")
    F_sig = Signal("tip_force", tip_force, (3,), "N")
    tau = None if pressure_tau is None else check_scalar("pressure_tau", pressure_tau, low=1e-6, high=1e4,
                                                          unit="s")
    return _Loads(p, check_limits, T_sig, l0_sig, pc_sig, F_sig, tau, k_pen, F_hold, s_hold)


def _initial_pressure(loads: _Loads, pressure0) -> float:
    """The chamber pressure [Pa] at t = 0: the signal's, or the supply's ``pressure0``."""
    p_init = float(loads.pc_sig(0.0)) if pressure0 is None else float(check_scalar("pressure0", pressure0,
                                                                                     unit="Pa"))
    if pressure0 is not None and loads.tau is None:
        raise InputError("pressure0 is the supply's initial pressure: it needs pressure_tau")
    loads.check(0.0, pr=p_init)
    return p_init


def _start_state(model, loads: _Loads, q0, v0, p_init: float) -> tuple[np.ndarray, np.ndarray]:
    """Free coordinates z (nz,) and velocities (nz,) at t = 0: q0 (default: the equilibrium of the start loads)
    and v0 (default 0); InputError for a v0 that moves the clamp.  q0 may be an equilibrium object: then it must
    be one of this model (:func:`.modes.check_equilibrium`: its actuator and its residual under its own loads);
    an array is any admissible state (a release from a displaced state is a start that is no equilibrium)."""
    if q0 is not None and hasattr(q0, "q") and hasattr(q0, "tensions"):
        from .modes import check_equilibrium
        check_equilibrium(model, q0, "simulate: q0")
        q0 = q0.q
    if q0 is None:
        if loads.length_mode:
            raise InputError("lengths= needs q0 (e.g. the equilibrium whose tendon lengths you lock)")
        q0 = model.fk(loads.T_sig(0.0), p_init, loads.F_sig(0.0), check_limits=loads.check_limits).q
    z = model._initial_z(q0)
    if v0 is None:
        return z, np.zeros(model.nz)
    v0 = model._q(v0, "v0")
    vz = model._to_free(v0)
    if not np.allclose(_full_v(model, vz), v0, rtol=0, atol=1e-12 * max(1.0, np.abs(v0).max())):
        raise InputError("v0 moves the clamped base node (its first 6 entries must be 0, or only the base "
                         "stretch along the base axis with free_base_stretch)")
    return z, vz


def _full_v(model, vz: np.ndarray) -> np.ndarray:
    """Full velocities (ndof,) from the free ones (nz,)."""
    if model._P is None:
        v = np.zeros(model.ndof)
        v[6:] = vz
        return v
    return model._P @ vz


# ------------------------------------------------------------------------------------------------ the plant
@dataclass
class _Plant:
    """The equations of motion in the free coordinates (module docstring): the residual and its iteration
    matrices for the integrator (:meth:`system`), the mass, the tendon forces and the dissipated power.
    M0 (ndof, ndof) the consistent mass [kg]; Mz_const (nz, nz) its constant reduced part (with a tool-point
    mass without offset); C_R (nz, nz) the Rayleigh matrix or None; c_ax [N s] the axial damping; force_scale
    [N] the Newton tolerance's scale."""
    model: object
    loads: _Loads
    M0: np.ndarray
    Mz_const: np.ndarray
    C_R: Optional[np.ndarray] = None
    Ct_const: Optional[np.ndarray] = None
    c_ax: float = 0.0
    force_scale: float = 0.0
    friction: Optional[object] = None           # the guides' history (:mod:`.friction_step`), None at μ = 0

    @property
    def tip_moves_mass(self) -> bool:
        p = self.model.params
        return p.tip_mass > 0 and p.tool_offset > 0

    def full_v(self, vz: np.ndarray) -> np.ndarray:
        return _full_v(self.model, vz)

    def mass_full(self, q: np.ndarray):
        """(M (ndof, ndof) [kg] with the tool-point mass at q, its Jacobian J_p (3, ndof) or None)."""
        mtip = self.model.params.tip_mass
        if mtip > 0:
            Jp = self.model._tip_jacobian(q)
            return self.M0 + mtip * Jp.T @ Jp, Jp
        return self.M0, None

    def tendons(self, q: np.ndarray, t: float, l0=None):
        """(tensions (m,) [N], tendon lengths (m,) [m] or None) at q and t: the prescribed ones, or the length
        springs' k max(0, l − l0) capped at the holding force."""
        ld = self.loads
        if not ld.length_mode:
            return ld.T_sig(t), None
        lq = self.model._evaluate(q, None, 0.0, (0.0, 0.0, 0.0), False, 1.0, "values").lengths
        return np.minimum(ld.k_pen * np.maximum(lq - l0, 0.0), ld.F_hold), lq

    def add_springs(self, K: np.ndarray, J_l: np.ndarray, T: np.ndarray) -> np.ndarray:
        """K plus k JᵀJ of the taut length springs (reduced; J_l (m, ndof) the tendon-length gradients)."""
        ld = self.loads
        if not ld.length_mode:
            return K
        taut = ld.springy(T)
        if np.any(taut):
            JA = self.model._reduce_vec(J_l)[taut]
            K = K + ld.k_pen * JA.T @ JA
        return K

    def system(self, t1: float, T1_fixed, pr1: float, F1, l01):
        """The integrator's system at t1 (:func:`.integrator.alpha_step`): (z, ż, z̈) → (residual (nz,) [N],
        M, K_t, C_t (nz, nz), force scale [N])."""
        model, length_mode = self.model, self.loads.length_mode
        red_v, red_m = model._reduce_vec, model._reduce_mat
        fric = self.friction

        def system(z1, v1, x):
            q = model._to_full(z1)
            springs = None
            if fric is None:
                T1, lq = self.tendons(q, t1, l01) if length_mode else (T1_fixed, None)
                ev = model._evaluate(q, T1, pr1, F1, True, 1.0, bool(length_mode))
                if not np.isfinite(ev.energy):
                    raise StepFailed(f"the state left the model's domain ({model.inadmissibility(q)})")
                Q, K = ev.Q, ev.K
            else:                                # the segments' forces and tangent (tensions prescribed)
                Q, K = fric.forces(q, T1_fixed, pr1, F1)
            r = self.Mz_const @ x + red_v(Q)
            Kt = red_m(K)
            Mz = self.Mz_const
            Ct = self.Ct_const
            if self.C_R is not None:
                r += self.C_R @ v1
            if self.c_ax > 0:
                Qd, Dq, Dv = axial_damping(q, self.full_v(v1), model.n, model._N, model._wq, self.c_ax)
                r += red_v(Qd)
                Kt = Kt + red_m(Dq)
                Ct = Ct + red_m(Dv)
            if self.tip_moves_mass:
                r, Mz, Kt, Ct = self._tool_point(q, v1, x, r, Kt, Ct)
            if fric is None:
                Kt = self.add_springs(Kt, ev.J_l, T1)
                if length_mode:          # the one-sided springs for the Newton's active set (:mod:`.integrator`)
                    ld = self.loads
                    springs = (lq - l01, red_v(ev.J_l), ld.k_pen, ld.F_hold)
            return r, Mz, Kt, Ct, self.force_scale + float(np.linalg.norm(Mz @ x)), springs
        return system

    def _tool_point(self, q, v1, x, r, Kt, Ct):
        """The tool point's inertia m J_pᵀ p̈ on the tip node's 6 coordinates (the last 6 of z) and its
        tangents: (r, M, K_t, C_t)."""
        p = self.model.params
        fi, Ds, Dvs, B = tool_point_inertia(q[-3:], v1[-3:], x[-6:-3], x[-3:], p.tool_offset, p.tip_mass)
        r[-6:] += fi
        Mz = self.Mz_const.copy()
        Mz[-6:, -6:] += B
        Kt = Kt.copy()
        Kt[-6:, -3:] += Ds
        Ct = Ct.copy()
        Ct[-6:, -3:] += Dvs
        return r, Mz, Kt, Ct

    def dissipation_power(self, q: np.ndarray, vq: np.ndarray, vz: np.ndarray) -> float:
        """q̇ᵀ(C_R q̇ + Q_d) [W] at the state (q, vq (ndof,)), vz the free velocities."""
        pw = 0.0
        if self.C_R is not None:
            pw += float(vz @ self.C_R @ vz)
        if self.c_ax > 0:
            m = self.model
            pw += float(vq @ axial_damping(q, vq, m.n, m._N, m._wq, self.c_ax)[0])
        return pw


def _make_plant(model, loads: _Loads, z: np.ndarray, p_init: float, damping) -> tuple[_Plant, dict]:
    """The run's :class:`_Plant` and its damping coefficients {alpha [1/s], beta [s], axial [N s]}: Rayleigh's
    stiffness is the linearisation's at the start state under the start loads (or the one ``damping`` gives)."""
    p = model.params
    M0 = consistent_mass(model.n, model._N, model._wq, p.line_mass)
    Mz_const = model._reduce_mat(M0).copy()
    if p.tip_mass > 0 and p.tool_offset == 0:
        Mz_const[-6:-3, -6:-3] += p.tip_mass * np.eye(3)
    plant = _Plant(model, loads, M0, Mz_const)
    q_start = model._to_full(z)
    T_start, _ = plant.tendons(q_start, 0.0, loads.lengths(0.0))
    tangent = _damping_needs_tangent(p, damping)
    ev0 = model._evaluate(q_start, T_start, p_init, loads.F_sig(0.0), tangent, 1.0, tangent)
    if not np.isfinite(ev0.energy):
        raise InputError(f"q0 is outside the model's domain: {model.inadmissibility(q_start)}")
    K0 = None
    if tangent:
        K0 = plant.add_springs(model._reduce_mat(ev0.K), ev0.J_l, T_start)
        K0 = 0.5 * (K0 + K0.T)
    Mz0 = model._reduce_mat(plant.mass_full(q_start)[0])
    coeffs = resolve_damping(model, damping, K0, Mz0)
    alpha_d, beta_d = coeffs["alpha"], coeffs["beta"]
    if "stiffness" in coeffs:                    # a fixed matrix for β (e.g. a plant's, across many runs)
        K0 = coeffs.pop("stiffness")
        K0 = 0.5 * (K0 + K0.T)
    if beta_d > 0:
        lam = np.linalg.eigvalsh(K0)[0]
        if lam < -1e-9 * max(np.abs(np.diag(K0)).max(), 1e-300):
            raise InputError("stiffness-proportional damping (beta) needs a stable start: the tangent at q0 "
                             f"has a negative eigenvalue ({lam:.3g}); start from an equilibrium or damp with "
                             "alpha / axial only")
    plant.C_R = (alpha_d * Mz0 + (beta_d * K0 if beta_d else 0.0)) if (alpha_d or beta_d) else None
    plant.Ct_const = np.zeros((model.nz, model.nz)) if plant.C_R is None else plant.C_R
    plant.c_ax = coeffs["axial"]
    # Newton tolerance [N]: 1e-7 of the force scale (EA(1)·1e-3 + the weight + |M z̈|); a residual r moves the
    # state by about β' J⁻¹ r — far below 1 nm at every step size
    plant.force_scale = abs(float(p.stiffness.EA(1.0))) * 1e-3 + abs(float(p.line_mass)) * 9.81 * p.length
    return plant, coeffs


def _damping_needs_tangent(params, damping) -> bool:
    """True when the run's damping needs the start tangent K0: a damping ratio (β = 2ζ/ω₁) or
    stiffness-proportional damping β > 0 without its own matrix (a short run of a plant whose damping is mass- or
    axial-proportional skips that assembly)."""
    if damping is None:
        return params.rayleigh_beta > 0
    if isinstance(damping, dict):
        return "stiffness" not in damping and bool(damping.get("beta", 0.0))
    return True


def _initial_acceleration(plant: _Plant, loads: _Loads, z: np.ndarray, vz: np.ndarray, p_init: float) -> StepState:
    """The integrator's start: z̈0 from M z̈0 = −g(z0, ż0, 0)."""
    sys0 = plant.system(0.0, loads.tensions(0.0), p_init, loads.F_sig(0.0), loads.lengths(0.0))
    try:
        r0, Mm = sys0(z, vz, np.zeros(plant.model.nz))[:2]
    except StepFailed as exc:
        raise InputError(f"q0: {exc.reason}") from None
    acc0 = -np.linalg.solve(Mm, r0)
    return StepState(z.copy(), vz.copy(), acc0, acc0.copy())


# ------------------------------------------------------------------------------------------------ energy
class _EnergyParts:
    """Π(q; T, p, F) = E0 + T·l − p V − F·p_end + ½ k Σ max(0, l − l0)² (module docstring), split so the
    q-dependent parts are computed once per output row (:meth:`parts`) and combined with any loads
    (:meth:`potential`)."""

    def __init__(self, model, loads: _Loads):
        self.model, self.loads = model, loads
        self.law = model.params.stiffness
        self.s1 = model._N[:, 1, :]                                   # slope shape values (nq, 4)
        self.eidx = np.arange(model.n)[:, None] * 6 + np.arange(12)[None, :]

    def parts(self, q: np.ndarray) -> tuple:
        """(E0 [J] the energy without tendon and pressure loads, tendon lengths (m,) [m], V [m³] the chamber
        volume ∫ A(λ) λ dx, p_end (3,) [m] the tool point, U_A, U_B [J] the axial and bending energies at p = 0
        of a pressure-dependent law, else 0)."""
        model = self.model
        e0 = model._evaluate(q, None, 0.0, (0.0, 0.0, 0.0), False, 1.0, "values")
        lam = np.linalg.norm(np.einsum("kj,ejc->ekc", self.s1, q[self.eidx].reshape(model.n, 4, 3)), axis=-1)
        V = float(np.sum(model._wq * sum(c * lam ** (j + 1) for j, c in enumerate(model._vc))))
        UA = UB = 0.0
        if self.law.pressure_dependent:
            z3, z1 = np.zeros(3), np.zeros(1)
            common = (model._E, model._d, model._co, model._so, np.zeros(model.m), 0.0, z3, False, 0)
            UA = assemble(q, model.n, model._N, model._wq, model._ea, z1, z1, z3, *common)[0]
            UB = assemble(q, model.n, model._N, model._wq, z1, model._ei, z1, z3, *common)[0]
        return e0.energy, e0.lengths, V, model._tip(q), UA, UB

    def potential(self, pt: tuple, T, pr: float, F, l0) -> float:
        """Π [J] of the state whose :meth:`parts` are ``pt`` under tensions T [N] (or lengths l0 [m]), pressure
        pr [Pa] and tip force F [N]."""
        E0, lq, V, pe, UA, UB = pt
        ld = self.loads
        Pi = E0 - pr * V - float(F @ pe)
        if self.law.pressure_dependent:
            fA, fI = self.law.pressure_factors(pr)
            Pi += (fA - 1.0) * UA + (fI - 1.0) * UB
        if ld.length_mode:
            st = np.maximum(lq - l0, 0.0)
            sc = np.minimum(st, ld.s_hold)
            Pi += float(np.sum(0.5 * ld.k_pen * sc ** 2 + ld.F_hold * (st - sc) if math.isfinite(ld.F_hold)
                               else 0.5 * ld.k_pen * sc ** 2))
        else:
            Pi += float(T @ lq)
        return Pi


# ------------------------------------------------------------------------------------------------ output rows
class _Recorder:
    """The output rows of a run (states, tip, tensions, pressure, energies, Newton iterations) and the energy
    bookkeeping between rows (work of the loads, dissipation: trapezoidal sums)."""

    def __init__(self, plant: _Plant, energy: _EnergyParts, n_rows: int):
        self.plant, self.energy = plant, energy
        model = plant.model
        self.q = np.empty((n_rows, model.ndof))
        self.v = np.empty((n_rows, model.ndof))
        self.tip = np.empty((n_rows, 3))
        self.T = np.empty((n_rows, model.m))
        self.p = np.empty(n_rows)
        self.kinetic = np.empty(n_rows)
        self.potential = np.empty(n_rows)
        self.work = np.zeros(n_rows)
        self.dissipated = np.zeros(n_rows)
        self.iterations = np.zeros(n_rows, dtype=int)
        fric = plant.friction
        self.Tseg = None if fric is None else np.empty((n_rows, model.m, model.n))
        self.friction_dissipated = None if fric is None else np.zeros(n_rows)
        self.prev: Optional[dict] = None          # the last row's parts, tensions, power and loads

    def point(self, st: StepState, t: float, pr: float, F, l0) -> dict:
        """The bookkeeping of the state st at time t [s] under pressure pr [Pa], tip force F [N], lengths l0 [m]:
        q, its velocities vq, tensions T, the energy parts, the dissipated power pw [W] and the loads."""
        plant = self.plant
        q = plant.model._to_full(st.z)
        vq = plant.full_v(st.v)
        T, _ = plant.tendons(q, t, l0)
        row = {"q": q, "vq": vq, "pt": self.energy.parts(q), "T": T, "pw": plant.dissipation_power(q, vq, st.v),
               "pr": pr, "F": F, "l0": l0, "t": t}
        if plant.friction is not None:
            row["Tseg"], row["lseg"] = plant.friction.at(q, T)
        return row

    def record(self, i: int, st: StepState, t: float, pr: float, F, l0, n_it: int = 0, mids=()) -> None:
        """Row i: the state st at time t [s] under pressure pr [Pa], tip force F [N], lengths l0 [m]; the work
        and dissipation since the previous row, summed over the substeps' ends ``mids`` (:meth:`point` dicts)
        when the row took more than one step."""
        row = self.point(st, t, pr, F, l0)
        q, vq, pt, T = row["q"], row["vq"], row["pt"], row["T"]
        self.q[i], self.v[i], self.tip[i], self.T[i], self.p[i] = q, vq, pt[3], T, pr
        Mf, _ = self.plant.mass_full(q)
        self.kinetic[i] = 0.5 * float(vq @ Mf @ vq)
        self.potential[i] = self.energy.potential(pt, T, pr, F, l0)
        self.iterations[i] = n_it
        if self.Tseg is not None:
            self.Tseg[i] = row["Tseg"]
        if self.prev is not None:
            dW = dD = dF = 0.0
            chain = [self.prev, *mids, row]
            for a, b in zip(chain[:-1], chain[1:]):
                w, d = self._increment(a, b)
                dW, dD = dW + w, dD + d
                if self.Tseg is not None:
                    dF += dissipation_increment(a, b)
            self.work[i] = self.work[i - 1] + dW
            self.dissipated[i] = self.dissipated[i - 1] + dD + dF
            if self.Tseg is not None:
                self.friction_dissipated[i] = self.friction_dissipated[i - 1] + dF
        self.prev = row

    def _increment(self, a: dict, b: dict) -> tuple[float, float]:
        """(work [J] of the time-varying loads: trapezoid of ∂Π/∂t; dissipation [J]: trapezoid of the power)
        from the point a to the point b (:meth:`point`)."""
        ld, pot = self.plant.loads, self.energy.potential
        dW = 0.0
        if ld.varying:
            Tn, Tn1 = ld.tensions(a["t"]), ld.tensions(b["t"])
            dW = 0.5 * ((pot(a["pt"], Tn1, b["pr"], b["F"], b["l0"]) - pot(a["pt"], Tn, a["pr"], a["F"], a["l0"]))
                        + (pot(b["pt"], Tn1, b["pr"], b["F"], b["l0"]) - pot(b["pt"], Tn, a["pr"], a["F"], a["l0"])))
        return dW, 0.5 * (b["pw"] + a["pw"]) * (b["t"] - a["t"])

    def tendon_events(self, T_prev: np.ndarray, T_now: np.ndarray, t: float) -> list:
        """Tendons gone slack / taut and motors overpowered / holding again between two rows (tendons held by
        length only)."""
        ld = self.plant.loads
        if not ld.length_mode:
            return []
        events, F_hold = [], ld.F_hold
        for j in range(len(T_now)):
            if (T_prev[j] > 0) != (T_now[j] > 0):
                kind = "taut" if T_now[j] > 0 else "slack"
                events.append({"t": float(t), "kind": kind, "tendon": j,
                               "text": f"tendon {j + 1} {kind} at t = {t:.6g} s"})
            if (T_prev[j] >= F_hold) != (T_now[j] >= F_hold):
                kind = "overpowered" if T_now[j] >= F_hold else "holding"
                what = "gives way at its holding force" if kind == "overpowered" else "holds again"
                events.append({"t": float(t), "kind": kind, "tendon": j,
                               "text": f"motor {j + 1} {what} ({F_hold:g} N) at t = {t:.6g} s"})
        return events


# ------------------------------------------------------------------------------------------------ time stepping
class _Stepper:
    """Advances the state from one output time to the next in substeps h / 2^(base + level): ``base`` is the
    run's refinement (the energy check's, :func:`simulate`), ``level`` the halvings of a failed step (up to
    ``max_halvings`` times; then ConvergenceError or CollapsedStateError naming the time) — four good steps in
    a row undo one.  ``events`` collects the subdivisions (and the recorder's tendon events)."""

    def __init__(self, h: float, coeff: AlphaCoefficients, max_halvings: int, max_iter: int, tol_abs: float,
                 base: int = 0):
        self.h, self.coeff, self.max_halvings, self.max_iter, self.tol_abs = h, coeff, max_halvings, max_iter, tol_abs
        self.base = base
        self.level = self.good = 0
        self.events: list = []

    def advance(self, plant: _Plant, st: StepState, tt: float, pr_s: float, t_target: float, point=None):
        """(state, pressure [Pa], Newton iterations, the ends of the substeps before t_target) at t_target from st
        at tt [s] with pressure pr_s [Pa]; ``point(st, t, pr, F, l0)`` makes those ends (a row of one step has
        none)."""
        loads, h, n_it, mids = plant.loads, self.h, 0, []
        while t_target - tt > 1e-12 * h:
            hh = min(h / 2 ** (self.base + self.level), t_target - tt)
            if t_target - tt - hh < 1e-9 * hh:
                hh = t_target - tt
            t1 = t_target if hh == t_target - tt else tt + hh
            pr1 = loads.pressure_at(t1, tt, pr_s)
            F1, l01, T1 = loads.F_sig(t1), loads.lengths(t1), loads.tensions(t1)
            loads.check(t1, T=T1, pr=pr1, l0=l01)
            try:
                st_new, k = alpha_step(st, hh, self.coeff, plant.system(t1, T1, pr1, F1, l01), rtol=1e-14,
                                       atol=0.0, vtol=1e-7, max_iter=self.max_iter)
            except StepFailed as exc:
                self._halve(exc, tt, t1, hh)
                continue
            n_it += k
            if plant.friction is not None:                  # the converged step's tensions: the next one's history
                plant.friction.commit(plant.model._to_full(st_new.z), T1)
            st, tt, pr_s = st_new, t1, pr1
            if point is not None and t1 != t_target:
                mids.append(point(st, t1, pr1, F1, l01))
            self.good += 1
            if self.level and self.good >= 4:
                self.level, self.good = self.level - 1, 0
        return st, pr_s, n_it, mids

    def _halve(self, exc: StepFailed, tt: float, t1: float, hh: float) -> None:
        """Halve the substep after a failed one (an event), or raise when it was halved often enough."""
        if self.level >= self.max_halvings:
            why = exc.reason
            if "domain" in why:
                raise CollapsedStateError(f"simulate: at t = {t1:.6g} s {why}, even with the step "
                                          f"halved {self.level} times", solver="simulate",
                                          stretch=float("nan")) from None
            raise ConvergenceError(f"at t = {t1:.6g} s the step did not converge even halved {self.level} "
                                   f"times (h = {hh:.3g} s): {why}", solver="simulate",
                                   iterations=exc.iterations, residual_norm=exc.residual,
                                   tolerance=self.tol_abs) from None
        self.level += 1
        self.good = 0
        self.events.append({"t": float(tt), "kind": "subdivided", "tendon": None,
                            "text": f"step halved to {self.h / 2 ** (self.base + self.level):.3g} s ({exc.reason})"})


# ------------------------------------------------------------------------------------------------ energy check
#: the integration error the energy balance allows: energy created (E + D growing) at most this fraction of
#: the energy of the motion (module docstring of :func:`simulate`)
ENERGY_RTOL = 1.0
#: most refinements of a run whose energy balance fails: substeps down to dt / 2^MAX_REFINE
MAX_REFINE = 6


class _EnergyWatch:
    """The run's integration error from its energy balance (docs/dynamics.md "Step size"): at row i the energy
    created, c_i = (E_i + D_i) − (E_0 + D_0) [J] (E = K + Π − W, D the dissipated energy; zero in exact time,
    negative with the scheme's numerical dissipation), against the energy of the motion
    B_i = max_{j≤i} K_j + max(D_i − c_i, 0) + max_{j≤i} |W_j| [J] (the kinetic energy reached, the energy truly
    dissipated, the work of the loads).  A row fails when c_i > ENERGY_RTOL · B_i + atol, atol = 1e-9 |Π_0| +
    1e-12 EA(1) L [J] the round-off of the energies (a state at rest stays at rest)."""

    def __init__(self, rec: _Recorder, model, rtol: float = ENERGY_RTOL):
        self.rec, self.rtol = rec, rtol
        self.start = rec.kinetic[0] + rec.potential[0] - rec.work[0] + rec.dissipated[0]
        pa = model.params
        self.atol = 1e-9 * abs(rec.potential[0]) + 1e-12 * abs(float(pa.stiffness.EA(1.0))) * pa.length
        self.k_max = rec.kinetic[0]
        self.w_max = 0.0

    def check_rows(self, i: int, j: int) -> Optional[dict]:
        """The check of rows i … j − 1 at once (the running maxima as arrays): the first failure {row, created
        [J], budget [J]}, or None when all pass."""
        r, sl = self.rec, slice(i, j)
        k_max = np.maximum.accumulate(np.concatenate(([self.k_max], r.kinetic[sl])))[1:]
        w_max = np.maximum.accumulate(np.concatenate(([self.w_max], np.abs(r.work[sl]))))[1:]
        created = r.kinetic[sl] + r.potential[sl] - r.work[sl] + r.dissipated[sl] - self.start
        budget = k_max + np.maximum(r.dissipated[sl] - created, 0.0) + w_max
        bad = np.flatnonzero(created > self.rtol * budget + self.atol)
        if len(bad):
            b = int(bad[0])
            return {"row": i + b, "created": float(created[b]), "budget": float(budget[b])}
        self.k_max, self.w_max = float(k_max[-1]), float(w_max[-1])
        return None


def _integrate(plant: _Plant, loads: _Loads, stepper: _Stepper, rec: _Recorder, state: StepState,
               times: np.ndarray, p_init: float, progress, stop) -> tuple[int, Optional[dict]]:
    """The time loop: row 0 at t = 0, then one row per output time — in chunks of compiled rows
    (:class:`_FastRows`, when the run can take them and no halving is in progress), else row by row in Python
    (:meth:`_Stepper.advance`, :meth:`_Recorder.record`).  The energy check, the tendon events and the progress
    report follow each row in order, whichever path made it (the energy check of a chunk at once:
    :meth:`_EnergyWatch.check_rows`).  Returns (the number of rows done — all of them,
    or those before a Ctrl-C: ``stop.requested`` read between chunks, or a KeyboardInterrupt from
    ``progress`` —, None or the energy check's failure {row, created [J], budget [J]} that ended the loop)."""
    rec.record(0, state, 0.0, p_init, loads.F_sig(0.0), loads.lengths(0.0))
    watch = _EnergyWatch(rec, plant.model)
    fast = _FastRows(plant, loads, stepper, rec, times) if _FastRows.eligible(plant, loads) else None
    t_prev, pr_prev, done, i = 0.0, p_init, 1, 1
    try:
        while i < len(times):
            if stop.requested:
                break
            j = i
            if fast is not None and stepper.level == 0:
                j, state, pr_prev = fast.run(i, state, t_prev, pr_prev)
            if j == i:                        # the Python path: no compiled rows, or this row's step failed there
                if fast is not None and fast.owns_prev:
                    rec.prev = rec.point(state, t_prev, pr_prev, loads.F_sig(t_prev), loads.lengths(t_prev))
                    fast.owns_prev = False
                state, pr_prev, n_it, mids = stepper.advance(plant, state, t_prev, pr_prev, times[i], rec.point)
                rec.record(i, state, times[i], pr_prev, loads.F_sig(times[i]), loads.lengths(times[i]), n_it, mids)
                j = i + 1
            bad = watch.check_rows(i, j)
            end = j if bad is None else bad["row"]
            if loads.length_mode or progress is not None:
                for k in range(i, end):
                    stepper.events.extend(rec.tendon_events(rec.T[k - 1], rec.T[k], times[k]))
                    if progress is not None:
                        progress(times[k], times[-1])
                    done = k + 1              # a row whose progress report was interrupted is not kept
            done = end
            if bad is not None:
                return end + 1, bad
            t_prev, i = times[j - 1], j
    except KeyboardInterrupt:
        pass
    return done, None


# ------------------------------------------------------------------------------------------------ compiled rows
#: compiled output rows (:mod:`.compiled_step`) for the runs that can take them (:meth:`_FastRows.eligible`)
COMPILED_ROWS = True
#: wall time [s] of one chunk of compiled rows: Ctrl-C and the progress report are read between chunks
CHUNK_SECONDS = 0.05


def _band(model, plant: _Plant, loads: _Loads) -> int:
    """The diagonals on each side of the iteration matrix M + γ' C_t + β' K_t outside which it is zero, or −1
    (solve it as a dense matrix): the elements couple coordinates at most 11 apart (12 with the base stretch),
    the tool point's blocks sit in the last node's, the mass and Rayleigh matrices are measured; taut length
    springs k ∇l ∇lᵀ fill the whole matrix."""
    if loads.length_mode:
        return -1
    band = 12 if model._P is not None else 11
    for A in (plant.Mz_const, plant.Ct_const):
        i, j = np.nonzero(A)
        band = max(band, int(np.abs(i - j).max()) if len(i) else 0)
    return band if 3 * band < model.nz else -1


class _FastRows:
    """Chunks of output rows made by :func:`.compiled_step.run_rows` — the same step, Newton iterations and
    recorder quantities as the Python path, to round-off.  Every run takes them (constant or time-varying
    signals, the pressure supply, pressure-dependent stiffness laws): the signals are sampled here on the
    substep grid of the chunk (:meth:`_table`, the same calls as the Python path); a row whose step fails there
    (a halving, an error), whose loads fail their checks and the rows until a halving is undone run in Python.
    ``owns_prev``: the last row was made here (the recorder's ``prev`` point is stale)."""

    @staticmethod
    def eligible(plant: _Plant, loads: _Loads) -> bool:
        return COMPILED_ROWS and plant.friction is None      # rows with tendon friction: the Python path

    def __init__(self, plant: _Plant, loads: _Loads, stepper: _Stepper, rec: _Recorder, times: np.ndarray):
        from . import compiled_step as cs
        self.cs, self.rec, self.times, self.stepper = cs, rec, np.ascontiguousarray(times, dtype=float), stepper
        model, p = plant.model, plant.model.params
        self.nz, self.owns_prev, self.per_row = model.nz, False, None
        F = loads.F_sig(0.0)
        self.arr = tuple(np.ascontiguousarray(a, dtype=float) for a in (
            model._q_fix, model._P_c, model._N, model._wq, model._ea, model._ei, model._vc, model._mg * 1.0,
            model._E, model._d, model._co, model._so, plant.M0, plant.Mz_const, plant.Ct_const,
            loads.tensions(0.0) if not loads.length_mode else np.zeros(model.m),
            loads.lengths(0.0) if loads.length_mode else np.ones(model.m),
            model.total_tip_load(F), model.total_tip_load((0.0, 0.0, 0.0)), F))
        c = stepper.coeff
        par = np.zeros(cs.N_PAR)
        for k, v in ((cs.P_N, model.n), (cs.P_USEP, model._P is not None), (cs.P_HTOOL, p.tool_offset),
                     (cs.P_CAX, plant.c_ax), (cs.P_HASCR, plant.C_R is not None), (cs.P_MTIP, p.tip_mass),
                     (cs.P_TIPMOVES, plant.tip_moves_mass), (cs.P_FSCALE, plant.force_scale),
                     (cs.P_LMODE, loads.length_mode), (cs.P_KPEN, loads.k_pen), (cs.P_FHOLD, loads.F_hold),
                     (cs.P_SHOLD, loads.s_hold), (cs.P_RHO, c.rho_inf), (cs.P_AM, c.alpha_m), (cs.P_AF, c.alpha_f),
                     (cs.P_GAMMA, c.gamma), (cs.P_BETA, c.beta), (cs.P_H, stepper.h),
                     (cs.P_HSUB, stepper.h / 2 ** stepper.base), (cs.P_MAXIT, stepper.max_iter),
                     (cs.P_VARYING, loads.varying),
                     (cs.P_BAND, _band(model, plant, loads)), (cs.P_PDEP, p.stiffness.pressure_dependent)):
            par[k] = float(v)
        self.par, self.loads, self.law, self.m = par, loads, p.stiffness, model.m
        self.F_w = model.total_tip_load((0.0, 0.0, 0.0))
        self.const = _constant_loads(loads, model.m)
        self.prev = np.zeros(cs.N_PREV + model.m)
        cs.check_inputs(self.arr, par, np.zeros((5, self.nz)), self.prev, self.nz, model.m)

    def _prev_from(self, row: dict) -> None:
        """The kernel's ``prev`` from the recorder's point dict (:meth:`_Recorder.point`)."""
        E0, lq, V, pe, UA, UB = row["pt"]
        self.prev[:self.cs.N_PREV] = (E0, V, *pe, row["pw"], row["pr"], row["t"], UA, UB)
        self.prev[self.cs.N_PREV:] = lq

    def run(self, i: int, st: StepState, t_prev: float, pr_prev: float) -> tuple[int, StepState, float]:
        """Rows i, i + 1, … in one kernel call of about :data:`CHUNK_SECONDS`: (the first row not done, the state
        and pressure [Pa] of the last row done)."""
        if not self.owns_prev:
            self._prev_from(self.rec.prev)
        n_rows = 8 if self.per_row is None else max(1, int(CHUNK_SECONDS / max(self.per_row, 1e-9)))
        stop = min(len(self.times), i + n_rows)
        has_prev = st.prev_acc is not None
        state = np.ascontiguousarray([st.z, st.v, st.acc, st.a, st.prev_acc if has_prev else np.zeros(self.nz)],
                                     dtype=float)
        sc = np.array([1.0 if has_prev else 0.0, t_prev, pr_prev])
        r = self.rec
        w0 = _time.perf_counter()
        tab = self._table(i, stop, t_prev, pr_prev)
        _, j = self.cs.run_rows(i, stop, self.times, state, sc, self.prev, self.arr, self.par, tab, r.q, r.v, r.tip,
                                r.T, r.p, r.kinetic, r.potential, r.work, r.dissipated, r.iterations)
        if j > i:
            self.per_row = (_time.perf_counter() - w0) / (j - i)
            self.owns_prev = True
            st = StepState(state[0].copy(), state[1].copy(), state[2].copy(), state[3].copy(),
                           state[4].copy() if sc[0] > 0 else None)
        return j, st, float(sc[2]) if j > i else pr_prev

    def _table(self, i: int, stop: int, t_prev: float, pr_prev: float) -> np.ndarray:
        """The load table of rows i … stop − 1 (:mod:`.compiled_step`, ``L_*`` columns): row 0 the loads at t_prev
        [s] with pressure pr_prev [Pa], then one row per substep end, with the substep times, pressures (the
        signal's or the supply's, :meth:`_Loads.pressure_at`) and signal values the Python path
        (:meth:`_Stepper.advance`) computes.  A row whose loads fail :meth:`_Loads.check` or whose signal raised
        is marked unusable (it and every later row: the Python path then raises as before)."""
        cs, loads, stepper = self.cs, self.loads, self.stepper
        ts, prs = _substep_grid(self.times, i, stop, t_prev, pr_prev, stepper.h, stepper.h / 2 ** stepper.base,
                                loads)
        tab = np.empty((len(ts), cs.L_VAR + 2 * self.m))
        tab[:, cs.L_T], tab[:, cs.L_PR] = ts, prs
        tab[:, cs.L_OK] = 1.0
        tab[:, cs.L_VAR:] = self.const[0]
        tab[:, cs.L_F:cs.L_F + 3] = self.const[1]
        ok = len(ts)
        if self.const[2] is not None:
            ok = _sample_signals(tab, loads, self.m, self.const[2])
        tab[:, cs.L_FTOT:cs.L_FTOT + 3] = tab[:, cs.L_F:cs.L_F + 3] + self.F_w
        tab[:, cs.L_FA:cs.L_FI + 1] = 1.0
        if self.law.pressure_dependent:
            tab[:, cs.L_FA:cs.L_FI + 1] = [self.law.pressure_factors(p) for p in prs]
        tab[ok:, cs.L_OK] = 0.0
        tab[:, cs.L_OK] *= _loads_ok(loads, tab, self.m)
        return tab


def _constant_loads(loads: _Loads, m: int):
    """(tensions and motor lengths (2m,), tip force (3,), the signals that vary or None): the load table's
    constant columns (zeros for the tendon mode not in use)."""
    T = np.zeros(m) if loads.length_mode else loads.T_sig(0.0)
    l0 = loads.l0_sig(0.0) if loads.length_mode else np.zeros(m)
    sig = loads.l0_sig if loads.length_mode else loads.T_sig
    varying = tuple(name for name, s in (("tendons", sig), ("F", loads.F_sig)) if not s.constant)
    return np.concatenate([T, l0]), loads.F_sig(0.0), varying or None


def _substep_grid(times: np.ndarray, i: int, stop: int, t: float, pr: float, h: float, hsub: float, loads: _Loads):
    """(substep end times (k,) [s], pressures (k,) [Pa]) of rows i … stop − 1 from t [s] at pressure pr [Pa], entry
    0 the start: the times :meth:`_Stepper.advance` steps to at substeps hsub (no halving), the same arithmetic."""
    ts, prs = [t], [pr]
    p_held = float(loads.pc_sig(0.0)) if loads.tau is None and loads.pc_sig.constant else None
    for k in range(i, stop):
        t_target = float(times[k])
        while t_target - t > 1e-12 * h:
            hh = min(hsub, t_target - t)
            if t_target - t - hh < 1e-9 * hh:
                hh = t_target - t
            t1 = t_target if hh == t_target - t else t + hh
            pr = p_held if p_held is not None else loads.pressure_at(t1, t, pr)
            t = t1
            ts.append(t1)
            prs.append(pr)
    return np.array(ts), np.array(prs)


def _sample_signals(tab: np.ndarray, loads: _Loads, m: int, varying: tuple) -> int:
    """Fill the load table's time-varying columns (tendons, tip force) from their signals at its times; the
    number of rows filled (a signal that raised stops it there: that row and the later ones stay unusable)."""
    from . import compiled_step as cs
    col = cs.L_VAR + (m if loads.length_mode else 0)
    sig = loads.l0_sig if loads.length_mode else loads.T_sig
    for k, t in enumerate(tab[:, cs.L_T]):
        try:
            if "tendons" in varying:
                tab[k, col:col + m] = sig(t)
            if "F" in varying:
                tab[k, cs.L_F:cs.L_F + 3] = loads.F_sig(t)
        except Exception:  # noqa: BLE001 — the Python path calls the signal again there and raises as before
            return k
    return len(tab)


def _loads_ok(loads: _Loads, tab: np.ndarray, m: int) -> np.ndarray:
    """(k,) 1.0 where the load-table row passes :meth:`_Loads.check` (tensions ≥ 0 and within tension_max,
    pressure within the actuator's limits when checked, motor lengths > 0), else 0.0."""
    from . import compiled_step as cs
    p = loads.params
    ok = np.ones(len(tab), dtype=bool)
    if loads.length_mode:
        ok &= np.all(tab[:, cs.L_VAR + m:] > 0, axis=1)
    else:
        T = tab[:, cs.L_VAR:cs.L_VAR + m]
        ok &= ~np.any(T < -1e-12, axis=1)
        if loads.check_limits:
            ok &= ~np.any(T > p.tension_max + 1e-12, axis=1)
    if loads.check_limits:
        pr = tab[:, cs.L_PR]
        ok &= (p.pressure_min - 1e-9 <= pr) & (pr <= p.pressure_max + 1e-9)
    return ok.astype(float)
