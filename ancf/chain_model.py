"""Statics of a multi-segment actuator: FK with frictionless tendons, locked-length FK, compliances
(docs/multisegment.md §4).

The potential and its derivatives are :class:`ancf.chain_system.ChainSystem`'s (the existing per-element kernels,
one assembly per segment, joined by the cap map).  The solvers are those of :mod:`ancf.solvers`:

* FK (T (m,), p (K,), F (3,)) → z: :func:`~ancf.solvers.minimize_newton` on Π(z), with load stepping from the
  straight chain as the fallback;
* locked FK (l⁰ (m,), p, F) → (z, T, β): the active-set KKT Newton of :meth:`ancf.Model.fk_locked` on
  [∇Π₀ + J_Aᵀ T_A; l_A − l⁰_A] = 0 (:func:`~ancf.solvers.solve_root`), T ≥ 0, β = l⁰ − l ≥ 0, T β = 0;
* compliances at an equilibrium: tensions held C = J_p H⁻¹ J_pᵀ; lengths held (exact KKT)
  C' = J_p [H⁻¹ − H⁻¹J_Aᵀ(J_A H⁻¹ J_Aᵀ)⁻¹J_A H⁻¹] J_pᵀ, H = ∇²_z Π at the state's tensions.

A result is a minimum: Cholesky of H (on null(J_A) for locked tendons), else UnstableEquilibriumError unless
``check_stability=False``; every local stretch inside each segment's law's valid range (CollapsedStateError).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np

from . import compiled_solvers as _cs
from . import kinematics as kin
from .chain import ChainParams
from .chain_system import ChainSystem
from .errors import (
    CollapsedStateError,
    ConvergenceError,
    InputError,
    LimitError,
    UnstableEquilibriumError,
    check_finite,
    check_scalar,
)
from .params import ActuatorParams
from .solvers import SolveInfo, minimize_newton
from .textfmt import vector


@dataclass
class ChainEquilibrium:
    """A converged state of a chain (SI units).  z (nz,) free and q (ndof,) full coordinates (the segments'
    node chains concatenated), tip (3,) tool point [m], tip_rotation (3, 3), segment_ends (K, 3) [m] (each
    segment's last node), tendon_lengths (m,) [m], tensions (m,) [N], pressures (K,) [Pa], tip_force (3,) [N],
    slack (m,) [m] and active (taut tendons) for the locked FK, stable, limit_violations (texts)."""
    z: np.ndarray
    q: np.ndarray
    tip: np.ndarray
    tip_rotation: np.ndarray
    segment_ends: np.ndarray
    tendon_lengths: np.ndarray
    tensions: np.ndarray
    pressures: np.ndarray
    tip_force: np.ndarray
    iterations: int
    residual_norm: float
    energy: float
    solver: str
    slack: np.ndarray | None = None
    active: tuple | None = None
    stable: bool = True
    limit_violations: tuple = ()
    history: list = field(default_factory=list)

    def to_dict(self) -> dict:
        """JSON-friendly dictionary (lists instead of arrays; SI units)."""
        return {k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in asdict(self).items()}

    def __repr__(self) -> str:
        """One line: tip [mm], tensions [N], pressures [kPa], stable, solver — never the coordinates."""
        return (f"ChainEquilibrium(tip={vector(self.tip, 'mm', 1e3, 3)}, tensions={vector(self.tensions, 'N', 1.0, 3)}, "
                f"pressures={vector(self.pressures, 'kPa', 1e-3, 2)}, stable={self.stable}, solver={self.solver!r})")


class ChainModel:
    """Reduced ANCF model of a chain of segments.  ``ChainModel(chain)`` (a :class:`~ancf.chain.ChainParams`, or
    one :class:`~ancf.params.ActuatorParams`: a chain of one segment, the same numbers as :class:`ancf.Model`)."""

    def __init__(self, chain):
        if isinstance(chain, ActuatorParams):
            chain = ChainParams(name=chain.name, segments=(chain,))
        if not isinstance(chain, ChainParams):
            raise InputError(f"ChainModel needs ChainParams or ActuatorParams, got {type(chain).__name__}")
        if any(chain.segments[-1].shear_compliance):
            raise InputError("the chain model has no series shear compliance yet: remove shear_compliance from the "
                             "distal segment (ancf.Model has it for one segment)")
        self.chain = chain
        self.sys = ChainSystem(chain)
        self.m, self.n_segments, self.nz = self.sys.m, chain.n_segments, self.sys.nz
        ea1 = min(float(s.stiffness.EA(1.0)) for s in chain.segments)
        n_max = max(s.n_elements / s.length for s in chain.segments)
        ei1 = max(float(s.stiffness.EI(1.0)) for s in chain.segments)
        # the residual tolerance of ancf.Model, with the stiffest and finest segment's terms
        self.default_tol = (1e-9 + 1e-13 * max(float(s.stiffness.EA(1.0)) for s in chain.segments)
                            + np.finfo(float).eps * np.sqrt(self.sys.ndof)
                            * (max(float(s.stiffness.EA(1.0)) for s in chain.segments) * n_max + ei1 * n_max ** 3))
        self._kscale = ea1 / chain.length

    def __repr__(self) -> str:
        return (f"ChainModel({self.chain.name!r}, {self.n_segments} segments, {self.m} tendons, "
                f"L={self.chain.length * 1e3:.1f} mm)")

    # ----------------------------------------------------------------------------- inputs
    def _pressures(self, pressures) -> np.ndarray:
        if np.ndim(pressures) == 0 and self.n_segments == 1:
            pressures = [pressures]
        p = check_finite("pressures", pressures)
        if p.shape != (self.n_segments,):
            raise InputError(f"pressures needs {self.n_segments} values [Pa] (one per chamber, segment 1 first), "
                             f"got shape {p.shape}")
        return p

    def _check_inputs(self, tensions, pressures, tip_force, check_limits: bool):
        """(T (m,), p (K,), F (3,)) checked: finite, the right sizes, every stiffness law valid at its chamber's
        pressure, and — with ``check_limits`` — each tendon within its segment's tension limits, each chamber
        within its pressure limits (LimitError naming the tendon or chamber)."""
        T = np.zeros(self.m) if tensions is None else check_finite("tensions", tensions)
        if T.shape != (self.m,):
            raise InputError(f"tensions needs {self.m} values [N] (one per tendon, segment 1's first), got shape "
                             f"{T.shape}")
        pr = self._pressures(pressures)
        F = check_finite("tip_force", tip_force, (3,))
        for k, s in enumerate(self.chain.segments):
            law = s.stiffness
            if law.pressure_dependent:
                f, at, which = law.pressure_factor_minimum(min(0.0, pr[k]), max(0.0, pr[k]))
                if not f > 0:
                    raise InputError(f"segment {k + 1}: the stiffness law's pressure factor of {which} is {f:.4g} "
                                     f"≤ 0 at p = {at / 1e3:g} kPa: the law is not valid at {pr[k] / 1e3:g} kPa")
            if check_limits:
                self._check_limits(k, s, T, pr[k])
        return np.ascontiguousarray(T), pr, np.ascontiguousarray(F)

    def _check_limits(self, k: int, s: ActuatorParams, T: np.ndarray, pr: float) -> None:
        for j in np.nonzero(self.sys.owner == k)[0]:
            if T[j] < s.tension_min - 1e-12 or T[j] > s.tension_max + 1e-12:
                raise LimitError(f"tension T{j + 1} = {T[j]:g} N (segment {k + 1}) is outside its limits "
                                 f"[{s.tension_min:g}, {s.tension_max:g}] N (check_limits=False analyses it anyway)")
        if pr < s.pressure_min - 1e-9 or pr > s.pressure_max + 1e-9:
            raise LimitError(f"pressure of chamber {k + 1} = {pr / 1e3:g} kPa is outside its limits "
                             f"[{s.pressure_min / 1e3:g}, {s.pressure_max / 1e3:g}] kPa (pascals in the Python API; "
                             "check_limits=False analyses it anyway)")

    def _options(self, tol, max_iter):
        tol = self.default_tol if tol is None else check_scalar("tol", tol, low=0.0)
        if not tol > 0:
            raise InputError("tol must be > 0")
        if isinstance(max_iter, bool) or not isinstance(max_iter, (int, np.integer)) or not 1 <= max_iter <= 10_000:
            raise InputError(f"max_iter must be an integer in [1, 10000], got {max_iter!r}")
        return float(tol), int(max_iter)

    def _z0(self, z0) -> np.ndarray:
        if z0 is None:
            return self.sys.z_ref.copy()
        z0 = check_finite("z0", z0, (self.nz,))
        if not np.isfinite(self.sys.evaluate(z0, np.zeros(self.m), np.zeros(self.n_segments), np.zeros(3),
                                             hessian=False)[0]):
            raise InputError("z0 is not an admissible starting state (a collapsed or reversed section, a folded "
                             "tendon path or a degenerate cap); pass an equilibrium's z or None")
        return z0

    # ----------------------------------------------------------------------------- FK
    def fk(self, tensions=None, pressures=None, tip_force=(0.0, 0.0, 0.0), z0=None, *, tol: float | None = None,
           max_iter: int = 60, check_limits: bool = True, check_stability: bool = True) -> ChainEquilibrium:
        """Forward kinetostatics: tensions (m,) [N] (segment 1's tendons first), pressures (K,) [Pa] (one per
        chamber; a number for one segment), tip_force (3,) [N] → :class:`ChainEquilibrium`.  Frictionless tendons
        (constant tension along each path).  Errors as :meth:`ancf.Model.fk`."""
        tol, max_iter = self._options(tol, max_iter)
        pressures = np.zeros(self.n_segments) if pressures is None else pressures
        T, pr, F = self._check_inputs(tensions, pressures, tip_force, check_limits)
        z, info = self._fk_z(self._z0(z0), T, pr, F, tol, max_iter)
        return self._result(z, T, pr, F, info, "fk", check_stability=check_stability)

    def _fk_fun(self, T, pr, F, load=1.0):
        loads = self.sys.loads(T, pr, F, load)

        def fun(z, hessian):
            E, g, H, _, _ = self.sys.evaluate(z, T, pr, F, hessian=hessian, load=load, loads=loads)
            return E, g, H
        return fun

    def _fk_z(self, z0, T, pr, F, tol, max_iter):
        """Newton from z0; on failure, load stepping from the straight chain (as :meth:`ancf.Model.fk`)."""
        try:
            return minimize_newton(self._fk_fun(T, pr, F), z0, tol=tol, max_iter=min(max_iter, 25), name="fk")
        except ConvergenceError as exc:
            first = exc
        z_prev = z = self.sys.z_ref.copy()
        s_prev, s, ds, total = 0.0, 0.0, 0.25, first.iterations
        while s < 1.0:
            s_try = min(1.0, s + ds)
            z_pred = z if s == 0.0 else z + (z - z_prev) * (s_try - s) / (s - s_prev)     # secant predictor
            try:
                z_try, info = minimize_newton(self._fk_fun(T, pr, F, s_try), z_pred, tol=tol,
                                              max_iter=max_iter if s_try == 1.0 else 15, name="fk")
            except ConvergenceError as exc:
                total += exc.iterations
                ds /= 3
                if ds < 1e-5:
                    raise ConvergenceError(f"the load is beyond what the chain carries: the equilibrium path ends "
                                           f"at {s:.3g} × the load (a limit point or the edge of the admissible "
                                           "states)", solver="fk", iterations=total,
                                           residual_norm=exc.residual_norm, tolerance=tol, history=exc.history) from None
                continue
            z_prev, s_prev, z, s, total = z, s, z_try, s_try, total + info.iterations
            ds = min(ds * (2.0 if info.iterations <= 6 else 1.2), 1.0)
        return z, SolveInfo(total, info.residual_norm, info.history, info.matrix)

    # ----------------------------------------------------------------------------- results
    def _verify(self, z, H, JA, solver: str, check_stability: bool) -> bool:
        """CollapsedStateError outside a segment law's valid stretch range; UnstableEquilibriumError when H (on
        null(JA) for taut locked tendons) is not positive definite.  Returns stable."""
        q = self.sys.to_full(z)
        for k, s in enumerate(self.sys.segments):
            lo, hi = s.params.stiffness.valid_stretch_range
            lmin, lmax = _cs.stretch_range(self.sys.segment_q(q, k), s.params.n_elements, s.N)
            if lmin <= lo or lmax >= hi:
                bad = lmin if lmin <= lo else lmax
                raise CollapsedStateError(f"{solver}: segment {k + 1} has a local stretch λ = {bad:.3f} outside its "
                                          f"law's valid range ({lo:.3f}, {hi:.3g}); lower the load",
                                          solver=solver, stretch=bad)
        Hr = H
        if JA is not None and len(JA):
            Qf, _ = np.linalg.qr(np.asarray(JA).T, mode="complete")
            Z = Qf[:, len(JA):]
            Hr = Z.T @ H @ Z
        Hr = 0.5 * (Hr + Hr.T)
        try:
            np.linalg.cholesky(Hr)
            return True
        except np.linalg.LinAlgError:
            pass
        lam = float(np.linalg.eigvalsh(Hr)[0])
        if lam >= -1e-10 * max(float(np.max(np.abs(np.diag(Hr)))), 1e-300):
            return True
        if not check_stability:
            return False
        raise UnstableEquilibriumError("the solve converged to an unstable equilibrium of the chain (a saddle of "
                                       "the potential); perturb the start (z0) or lower the load", solver=solver,
                                       min_eigenvalue=lam)

    def _result(self, z, T, pr, F, info, solver, *, JA=None, slack=None, active=None,
                check_stability=True) -> ChainEquilibrium:
        E, _, H, lc, _ = self.sys.evaluate(z, T, pr, F, hessian=True, lengths=1)
        stable = self._verify(z, H, JA, solver, check_stability)
        q = self.sys.to_full(z)
        ends = np.array([self.sys.segment_q(q, k)[-6:-3] for k in range(self.n_segments)])
        return ChainEquilibrium(z=z, q=q, tip=self.sys.tip(z), tip_rotation=kin.tip_rotation(z[-6:], self.sys.e1),
                                segment_ends=ends, tendon_lengths=lc, tensions=np.array(T, float),
                                pressures=np.array(pr, float), tip_force=np.array(F, float),
                                iterations=info.iterations, residual_norm=info.residual_norm, energy=E, solver=solver,
                                slack=slack, active=active, stable=stable, history=list(info.history))

    # ----------------------------------------------------------------------------- queries
    def tendon_lengths(self, z) -> np.ndarray:
        """Tendon lengths l (m,) [m] at free coordinates z (nz,) (through every segment and cap each passes)."""
        z = check_finite("z", z, (self.nz,))
        lc = self.sys.evaluate(z, np.zeros(self.m), np.zeros(self.n_segments), np.zeros(3), hessian=False,
                               lengths=1)[3]
        if lc is None:
            raise InputError("z is outside the model's domain (a collapsed or reversed section, a folded tendon path)")
        return lc

    def tip(self, z) -> np.ndarray:
        """Tool point (3,) [m] at z (nz,)."""
        return self.sys.tip(check_finite("z", z, (self.nz,)))

    def to_full(self, z) -> np.ndarray:
        """Full coordinates q (ndof,) (the segments' node chains concatenated) of z (nz,)."""
        return self.sys.to_full(check_finite("z", z, (self.nz,)))

    # ----------------------------------------------------------------------------- locked FK, compliances
    def fk_locked(self, tendon_lengths, pressures=None, tip_force=(0.0, 0.0, 0.0), z0=None, *,
                  tol: float | None = None, tol_length: float = 1e-10, max_iter: int = 60,
                  check_limits: bool = True, check_stability: bool = True) -> ChainEquilibrium:
        """FK with locked tendon lengths l⁰ (m,) [m]: tensions T ≥ 0 and slack β ≥ 0 per tendon
        (:func:`ancf.chain_locked.fk_locked`)."""
        from .chain_locked import fk_locked
        return fk_locked(self, tendon_lengths, pressures, tip_force, z0, tol=tol, tol_length=tol_length,
                         max_iter=max_iter, check_limits=check_limits, check_stability=check_stability)

    def compliance(self, eq: ChainEquilibrium) -> np.ndarray:
        """Tip compliance dp_end/dF with the tensions held (3, 3) [m/N] at ``eq``."""
        from .chain_locked import compliance
        return compliance(self, self._own(eq))

    def locked_compliance(self, eq: ChainEquilibrium, active=None) -> np.ndarray:
        """Tip compliance with the lengths of the tendons ``active`` held (default: eq.active, else the tendons
        under tension), exact KKT form (3, 3) [m/N]."""
        from .chain_locked import locked_compliance
        return locked_compliance(self, self._own(eq), active)

    # ----------------------------------------------------------------------------- IK
    def ik(self, target, pressures=None, tip_force=(0.0, 0.0, 0.0), **options):
        """Inverse kinetostatics with redundant tendons: tool point ``target`` (3,) [m] (and ``tip_direction`` for
        a pose), pressures (K,) [Pa] as inputs, tip_force (3,) [N] → :class:`ancf.chain_ik.ChainIKEquilibrium`,
        the tensions inside their bounds chosen by ``objective`` ("least_tension": min ½ Σ T²; "compliance": min
        uᵀ C u along ``compliance_direction``) (:func:`ancf.chain_ik.ik`, its options and errors)."""
        from .chain_ik import ik
        return ik(self, target, pressures, tip_force, **options)

    # ----------------------------------------------------------------------------- dynamics
    def mass_matrix(self, z, cap_inertia=None) -> np.ndarray:
        """Mass matrix M_z (nz, nz) at free coordinates z (nz,): kinetic energy ½ żᵀ M_z ż [J]; the segments'
        consistent masses through the cap map, each cap's mass at its centre of mass and ``cap_inertia`` (K − 1,)
        [kg m²] its transverse moment of inertia (default 0), the distal tip mass (:mod:`ancf.chain_dynamics`)."""
        from .chain_dynamics import mass_matrix
        return mass_matrix(self, z, cap_inertia)

    def modes(self, eq: ChainEquilibrium, count: int = 6, cap_inertia=None):
        """The ``count`` lowest vibration modes about the equilibrium ``eq`` (tensions held, or the taut tendons
        of a locked equilibrium as constraints) → :class:`ancf.chain_dynamics.ChainModalResult`.  InputError for
        a state that is not an equilibrium of this chain (:func:`ancf.chain_dynamics.check_equilibrium`)."""
        from .chain_dynamics import modes
        return modes(self, eq, count, cap_inertia)

    def simulate(self, t_end: float, dt: float, z0=None, v0=None, **options):
        """Transient response under constant loads (tensions (m,) [N], pressures (K,) [Pa], tip_force (3,) [N],
        damping, rho_inf, cap_inertia, …) → :class:`ancf.chain_dynamics.ChainSimulation`
        (:func:`ancf.chain_dynamics.simulate`)."""
        from .chain_dynamics import simulate
        return simulate(self, t_end, dt, z0, v0, **options)

    def _own(self, eq) -> ChainEquilibrium:
        if not isinstance(eq, ChainEquilibrium) or eq.z.shape != (self.nz,):
            raise InputError("pass an equilibrium of this chain model (ChainModel.fk / fk_locked)")
        return eq
