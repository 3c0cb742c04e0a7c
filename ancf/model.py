"""The reduced ANCF kinetostatic model (paper Sec. II–III-B): equilibrium, FK, IK, locked-tendon FK.

Unknowns: the full coordinate vector q (6(n+1),) = [r_1, r_x,1, …, r_{n+1}, r_x,{n+1}].  The base node is
clamped (r_1 = 0, r_x,1 = e1); with ``free_base_stretch`` the base slope keeps its direction but not its
length.  Free coordinates z map to q = q_fix + P z.

Equilibrium is the stationarity of the potential (docs/design.md §3)

    Π(q) = U_axial + U_bend + Σ_i T_i l_c,i(q) − p ∫ A(λ) λ dx − m' ∫ g·r dx − F · p_end(q),

Q(q, T, p, F) = ∂Π/∂q = 0 is paper eq. (1); its exact derivatives are

    ∂Q/∂q = ∇²Π (symmetric),  ∂Q/∂T_i = ∂l_c,i/∂q,  ∂Q/∂F = −(∂p_end/∂q)ᵀ,
    ∂Q/∂p = −∂(∫A(λ)λ dx)/∂q + ∂Q_axial/∂p + ∂Q_bend/∂p

(A(λ) = A_eff for the paper's constant pressure area; see :mod:`ancf.forces.pressure`).  The last two terms
are those of a pressure-dependent stiffness law EA(λ, p), EI(λ, p) (:mod:`ancf.stiffness`; zero without
pressure factors): the stiffness of every solve is the law at the solve's pressure.

Solvers:
* FK (T, p, F) → q: Newton on ∇Π with an energy line search, LM shift, load stepping fallback.
* IK (p_d, p, F) → (q, T): Newton on [Q; p_end − p_d] = 0 (square for 3 tendons), then a bounded
  reduced solve over T ∈ [T_min, T_max] that either confirms a feasible solution or returns the nearest
  reachable tip in an :class:`~ancf.errors.InfeasibleTargetError`.
* Locked FK (l⁰, p, F) → (q, T, β): paper eqs. (3)–(6).  ``method="active_set"`` (default, exact):
  Newton on the KKT system of min Π₀ s.t. l_i(q) ≤ l⁰_i with an active-set loop.  ``method="gamma"``:
  the paper's substitution T = γ², β = 0 (γ > 0), T = 0, β = γ² (γ ≤ 0), solved by Newton/LM.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Optional

import numpy as np
import scipy.optimize as so

from . import kinematics as kin
from . import assembly as _asm
from .assembly import assemble
from .errors import (
    CollapsedStateError,
    ConvergenceError,
    InfeasibleTargetError,
    InputError,
    LimitError,
    UnstableEquilibriumError,
    check_finite,
    check_scalar,
)
from .params import ActuatorParams
from . import compiled_bounded as _cb
from . import compiled_solvers as _cs
from . import shear as _shear
from .solvers import SolveInfo, kkt_accept, locked_active_set, solve_root
from .textfmt import number, vector


@dataclass
class Evaluation:
    """Everything the assembly gives at one state (full coordinates, SI units)."""
    energy: float                 # Π [J]
    Q: np.ndarray                 # ∂Π/∂q (ndof,)
    K: Optional[np.ndarray]       # ∂²Π/∂q² (ndof, ndof) or None
    lengths: np.ndarray           # l_c,i [m] (m,)
    J_l: np.ndarray               # ∂l_c/∂q (m, ndof)
    arc_length: float             # ∫|r_x| dx [m]
    J_arc: np.ndarray             # ∂(∫|r_x| dx)/∂q (ndof,)


@dataclass
class Equilibrium:
    """A converged equilibrium.  Arrays in SI units (m, N, Pa).

    q (ndof,), tip (3,) tool point [m]: p_end plus, with a shear compliance s(p), the rotation-free offset
    s P⊥ F (:meth:`Model.tool_point`, :mod:`ancf.shear`), tip_rotation (3, 3), tendon_lengths (m,) [m],
    tensions (m,) [N], slack (m,) [m] (locked FK only, else None), active (tuple of taut tendon indices,
    locked FK only), pressure [Pa], tip_force (3,) [N], converged (always True: failures raise),
    iterations, residual_norm, energy [J], solver, stable (True: the reduced Hessian is positive definite;
    False only when the solve was asked not to check, ``check_stability=False``), ``min_eigenvalue``,
    limit_violations (tuple of texts: result quantities outside the actuator's limits, locked FK).
    """
    q: np.ndarray
    tip: np.ndarray
    tip_rotation: np.ndarray
    tendon_lengths: np.ndarray
    tensions: np.ndarray
    pressure: float
    tip_force: np.ndarray
    iterations: int
    residual_norm: float
    energy: float
    solver: str
    slack: Optional[np.ndarray] = None
    active: Optional[tuple] = None
    converged: bool = True
    history: list = field(default_factory=list)
    stable: bool = True
    limit_violations: tuple = ()

    def require_within_limits(self) -> "Equilibrium":
        """Return self, or raise :class:`~ancf.errors.LimitError` if the state violates the actuator's
        operating limits (``limit_violations``, e.g. locked-tendon tensions above ``tension_max``)."""
        if self.limit_violations:
            raise LimitError(f"{self.solver}: the state is outside the actuator's limits "
                             f"({'; '.join(self.limit_violations)}); change the inputs or lower the load")
        return self

    @property
    def min_eigenvalue(self) -> float:
        """Smallest eigenvalue of the reduced Hessian ∇²Π in free coordinates (for rigid locked tendons: on
        the tangent space of the taut tendons' length constraints; for elastic ones, ``tendon_stiffness``
        k_s, of ∇²Π + k_s Σ ∇l ∇lᵀ, the Hessian including the tendons' own energy).  Positive at a stable equilibrium (a
        minimum of the potential).  Mixed units (N/m for positions, N m for slopes); computed on first
        access (an eigen-decomposition), while ``stable`` comes from the Cholesky factorisation done in
        every solve."""
        cached = self.__dict__.get("_min_eig")
        if cached is None:
            H = self.__dict__.get("_stability_matrix")
            cached = float("nan") if H is None else float(np.linalg.eigvalsh(H)[0])
            self.__dict__["_min_eig"] = cached
        return cached

    def to_dict(self) -> dict:
        """JSON-friendly dictionary (lists instead of arrays)."""
        out = {}
        for k, v in asdict(self).items():
            out[k] = v.tolist() if isinstance(v, np.ndarray) else v
        return out

    # ----------------------------------------------------------------------------- display
    def _display_rows(self) -> list[tuple[str, str]]:
        """(quantity, value with unit) of the state, in display units (mm, N, kPa)."""
        rows = [("tip", vector(self.tip, "mm", 1e3, 3)), ("tensions", vector(self.tensions, "N", 1.0, 3)),
                ("pressure", number(self.pressure, "kPa", 1e-3, 2)),
                ("tip force", vector(self.tip_force, "N", 1.0, 3)),
                ("tendon lengths", vector(self.tendon_lengths, "mm", 1e3, 3))]
        if self.slack is not None:
            rows.append(("slack", vector(self.slack, "mm", 1e3, 3)))
        if self.active is not None:
            rows.append(("taut tendons", ", ".join(str(int(i) + 1) for i in self.active) or "none"))
        rows += [("stable", str(bool(self.stable))), ("converged", str(bool(self.converged))),
                 ("solver", str(self.solver)), ("iterations", str(self.iterations)),
                 ("residual", f"{self.residual_norm:.3g} N")]
        if self.limit_violations:
            rows.append(("outside the limits", "; ".join(self.limit_violations)))
        return rows

    def __repr__(self) -> str:
        """One line: tip [mm], tensions [N], pressure [kPa], slack [mm] (locked FK), stable, converged, solver —
        never the coordinate vector q (``eq.q``)."""
        slack = "" if self.slack is None else f", slack={vector(self.slack, None, 1e3, 3)} mm"
        limits = f", outside the limits: {len(self.limit_violations)}" if self.limit_violations else ""
        return (f"Equilibrium(tip={vector(self.tip, 'mm', 1e3, 3)}, tensions={vector(self.tensions, 'N', 1.0, 3)}, "
                f"pressure={number(self.pressure, 'kPa', 1e-3, 2)}{slack}, stable={bool(self.stable)}, "
                f"converged={bool(self.converged)}, solver={self.solver!r}{limits})")

    def _repr_html_(self) -> str:
        from .htmlrepr import table
        return table("Equilibrium", self._display_rows(), header=("quantity", "value"))


class Model:
    """ANCF model of one actuator.  ``Model(params)``; all methods take and return SI units."""

    def __init__(self, params: ActuatorParams):
        if not isinstance(params, ActuatorParams):
            raise InputError(f"Model needs ActuatorParams, got {type(params).__name__}")
        self.params = params
        p = params
        self.n = p.n_elements
        self.ndof = 6 * (self.n + 1)
        self.m = p.n_tendons
        self._N, self._wq = kin.shape_table(p.quadrature_points, p.element_length)
        self._law = p.stiffness
        self._ea = p.stiffness.ea                             # EA, EI coefficients at p = 0 [N], [N m²]
        self._ei = p.stiffness.ei
        self._vc = np.ascontiguousarray(p.volume_coeffs)      # A(λ) λ = Σ c_k λ^{k+1} [m²]
        self._E = np.ascontiguousarray(p.frame)
        self._e1 = self._E[:, 0].copy()
        self._d = p.tendon_distances
        self._co = np.cos(p.tendon_angles)
        self._so = np.sin(p.tendon_angles)
        self._g = np.asarray(p.gravity, float)
        self._mg = p.line_mass * self._g
        self._tip_weight = p.tip_mass * self._g               # [N] (3,)
        self.q_ref = kin.reference_q(self.n, p.length, p.base_axis)
        # free-coordinate map q = q_fix + P z
        if p.free_base_stretch:
            self._q_fix = np.zeros(self.ndof)            # r_1 = 0; everything else comes from z
            P = np.zeros((self.ndof, self.ndof - 5))
            P[3:6, 0] = self._e1
            P[6:, 1:] = np.eye(self.ndof - 6)
            self._P = P
            self._free = None
        else:
            self._q_fix = self.q_ref.copy()
            self._q_fix[6:] = 0.0
            self._P = None
            self._free = np.arange(6, self.ndof)
        # the same map for the compiled loops (a placeholder matrix when P is not used)
        self._P_c = np.ascontiguousarray(self._P) if self._P is not None else np.zeros((1, 1))
        self.nz = self.ndof - 6 + (1 if p.free_base_stretch else 0)
        # scale for mixing force and position residuals (N/m): axial stiffness of the whole actuator
        self._kscale = float(p.stiffness.EA(1.0)) / p.length
        # default residual tolerance [N]: the round-off floor of the generalized forces grows with the
        # stiffness and the element count — axial terms like EA/h, bending terms like EI/h³ (h = L/n), summed
        # over ndof entries.  Measured floors (paper preset): 2e-12 N at n = 6, 1.5e-10 N at n = 50, 1.4e-9 N
        # at n = 120; the size term below stays 10–100× above them, and negligible (5e-11 N) at n = 6.
        inv_h = self.n / p.length
        self.default_tol = (1e-9 + 1e-13 * float(p.stiffness.EA(1.0))
                            + np.finfo(float).eps * np.sqrt(self.ndof)
                            * (abs(float(p.stiffness.EA(1.0))) * inv_h + abs(float(p.stiffness.EI(1.0))) * inv_h ** 3))
        self._droop: dict[float, Equilibrium] = {}
        # the IK's evaluations where its latest solves started and ended: (z, T), p, F → (Q, ∂R/∂x, Π, lengths)
        self._ik_evaluations: dict = {}
        # series compliance of each tendon path 1/k_s [m/N] (0: inextensible)
        self._cs = 0.0 if p.tendon_stiffness is None else 1.0 / p.tendon_stiffness
        self._lam_range = p.stiffness.valid_stretch_range
        # series rotation-free tip compliance s(p) [m/N] (ancf.shear); none: every output as without it
        self._shear = tuple(p.shear_compliance)
        self._has_shear = any(c != 0.0 for c in self._shear)

    def __repr__(self) -> str:
        """One line: the actuator's name, elements, length [mm], tendons, pressure range [kPa]."""
        p = self.params
        return (f"Model({p.name!r}, {self.n} elements, L={number(p.length, 'mm', 1e3, 1)}, {self.m} tendons, "
                f"tensions ≤ {number(p.tension_max, 'N', 1.0, 2)}, pressure ≤ {number(p.pressure_max, 'kPa', 1e-3, 1)})")

    # ----------------------------------------------------------------------------- coordinate maps
    def to_free(self, q: np.ndarray) -> np.ndarray:
        """Free coordinates z (nz,) of full coordinates q (ndof,)."""
        return self._to_free(self._q(q))

    def _to_free(self, q: np.ndarray) -> np.ndarray:
        if self._P is None:
            return q[6:].copy()
        z = np.empty(self.nz)
        z[0] = float(q[3:6] @ self._e1)
        z[1:] = q[6:]
        return z

    def to_full(self, z: np.ndarray) -> np.ndarray:
        """Full coordinates q (ndof,) of free coordinates z (nz,)."""
        return self._to_full(check_finite("z", z, (self.nz,)))

    def _to_full(self, z: np.ndarray) -> np.ndarray:
        if self._P is None:
            q = self._q_fix.copy()
            q[6:] = z
            return q
        return self._q_fix + self._P @ z

    def reduce_vec(self, v: np.ndarray) -> np.ndarray:
        """Pᵀ v for a vector (ndof,) or rows (k, ndof) → (k, nz)."""
        v = check_finite("v", v)
        if v.ndim not in (1, 2) or v.shape[-1] != self.ndof:
            raise InputError(f"reduce_vec needs shape ({self.ndof},) or (k, {self.ndof}), got {v.shape}")
        return self._reduce_vec(v)

    def _reduce_vec(self, v: np.ndarray) -> np.ndarray:
        if self._P is None:
            return v[..., 6:]
        return v @ self._P

    def reduce_mat(self, K: np.ndarray) -> np.ndarray:
        """Pᵀ K P (nz, nz)."""
        return self._reduce_mat(check_finite("K", K, (self.ndof, self.ndof)))

    def _reduce_mat(self, K: np.ndarray) -> np.ndarray:
        if self._P is None:
            return K[6:, 6:]
        return self._P.T @ K @ self._P

    @staticmethod
    def _per_element(k) -> int:
        if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or not 1 <= k <= 1000:
            raise InputError(f"per_element must be an integer in [1, 1000], got {k!r}")
        return int(k)

    # ----------------------------------------------------------------------------- evaluation
    def _check_inputs(self, tensions, pressure, tip_force, check_limits: bool):
        p = self.params
        T = check_finite("tensions", tensions, (self.m,)) if tensions is not None else np.zeros(self.m)
        # a plain finite float (the common case) needs no array round trip
        pr = (pressure if type(pressure) is float and math.isfinite(pressure)
              else float(check_finite("pressure", pressure, ())))
        F = check_finite("tip_force", tip_force, (3,))
        self._check_law_pressure(pr)
        self._check_shear_pressure(pr)
        if check_limits:
            for i, t in enumerate(T.tolist()):
                if t < p.tension_min - 1e-12 or t > p.tension_max + 1e-12:
                    raise LimitError(f"tension T{i + 1} = {t:g} N is outside the actuator's limits "
                                     f"[{p.tension_min:g}, {p.tension_max:g}] N (check_limits=False analyses "
                                     f"it anyway)")
            if pr < p.pressure_min - 1e-9 or pr > p.pressure_max + 1e-9:
                raise LimitError(f"pressure {pr / 1e3:g} kPa is outside the actuator's limits "
                                 f"[{p.pressure_min / 1e3:g}, {p.pressure_max / 1e3:g}] kPa (the Python API takes "
                                 f"pascals: 30 kPa = 30e3; check_limits=False analyses it anyway)")
        return np.ascontiguousarray(T, dtype=float), pr, np.ascontiguousarray(F, dtype=float)

    def _check_law_pressure(self, pr: float) -> None:
        """InputError when a pressure factor of the stiffness law is not positive between 0 and ``pr`` [Pa] (the
        pressures a solve at ``pr`` passes through when it steps its loads; only reachable with
        ``check_limits=False`` outside the actuator's pressure range, over which the parameters checked it)."""
        if self._law.pressure_dependent:
            f, at, which = self._law.pressure_factor_minimum(min(0.0, pr), max(0.0, pr))
            if not f > 0:
                raise InputError(f"the stiffness law's pressure factor of {which} is {f:.4g} ≤ 0 at p = "
                                 f"{at / 1e3:g} kPa ({which} would not be positive there): the law is not valid "
                                 f"for a solve at {pr / 1e3:g} kPa")

    def stiffness_coefficients(self, pressure: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """Stretch-polynomial coefficients (ea [N], ei [N m²]) of EA(λ, p), EI(λ, p) at ``pressure`` [Pa]: the
        stiffness every solve at that pressure uses (:meth:`ancf.StiffnessLaw.coefficients`)."""
        pr = float(check_finite("pressure", pressure, ()))
        self._check_law_pressure(pr)
        ea, ei = self._coeffs(pr)
        return ea.copy(), ei.copy()

    def _coeffs(self, pr: float) -> tuple[np.ndarray, np.ndarray]:
        """(ea, ei) at pressure ``pr`` [Pa], contiguous, unchecked (the p = 0 arrays themselves for a law
        without pressure factors: bit-for-bit the stretch-only law)."""
        if not self._law.pressure_dependent:
            return self._ea, self._ei
        ea, ei = self._law.coefficients(pr)
        return np.ascontiguousarray(ea), np.ascontiguousarray(ei)

    def total_tip_load(self, tip_force, gravity_scale: float = 1.0) -> np.ndarray:
        """External tip force plus the tip mass weight (scaled by ``gravity_scale``) [N], contiguous (3,)."""
        return np.ascontiguousarray(np.asarray(tip_force, float) + self.params.tip_mass * self._g * gravity_scale)

    def evaluate(self, q, tensions=None, pressure: float = 0.0, tip_force=(0.0, 0.0, 0.0),
                 hessian: bool = True, gravity_scale: float = 1.0, lengths=True) -> Evaluation:
        """Potential, generalized force Q = ∂Π/∂q and tangent at full coordinates ``q`` (ndof,).

        ``lengths``: True — tendon lengths, arc length and their gradients; ``"values"`` — the lengths
        without gradients (``J_l``, ``J_arc`` zero); False — none of them (``lengths`` zero too; faster
        inside Newton loops).  Every argument is checked (shape, real numbers, finite) before the compiled
        assembly runs; a state outside the model's domain (:mod:`ancf.assembly`: a collapsed section
        |r_x| < 0.2, a section turned back towards −e1, a folded tendon path) raises
        :class:`~ancf.errors.CollapsedStateError` naming the rule instead of returning an infinite energy."""
        q = self._q(q)
        T = np.zeros(self.m) if tensions is None else check_finite("tensions", tensions, (self.m,))
        pr = float(check_finite("pressure", pressure, ()))
        F = check_finite("tip_force", tip_force, (3,))
        gs = float(check_finite("gravity_scale", gravity_scale, ()))
        self._check_law_pressure(pr)
        if lengths not in (True, False, "values"):
            raise InputError(f"lengths must be True, False or 'values', got {lengths!r}")
        ev = self._evaluate(q, T, pr, F, bool(hessian), gs, lengths)
        if not np.isfinite(ev.energy):
            why = self.inadmissibility(q)
            lam = self._stretches(q)
            raise CollapsedStateError(
                f"state is outside the model's domain: {why or 'the potential is not finite at these loads'}; "
                "the model is not defined there", solver="evaluate", stretch=float(lam.min()))
        return ev

    def _evaluate(self, q, tensions=None, pressure: float = 0.0, tip_force=(0.0, 0.0, 0.0),
                  hessian: bool = True, gravity_scale: float = 1.0, lengths=True) -> Evaluation:
        """:meth:`evaluate` without argument checks (solver internals: arguments already checked)."""
        T = np.zeros(self.m) if tensions is None else np.ascontiguousarray(tensions, dtype=float)
        F = self.total_tip_load(tip_force, gravity_scale)
        ea, ei = self._coeffs(float(pressure))
        E, Q, K, lc, Jl, arc, Jarc = assemble(
            np.ascontiguousarray(q, dtype=float), self.n, self._N, self._wq, ea, ei,
            float(pressure) * self._vc, self._mg * gravity_scale, self._E, self._d, self._co,
            self._so, T, self.params.tool_offset, F, hessian,
            2 if lengths is True else (1 if lengths == "values" else 0))
        return Evaluation(E, Q, K if hessian else None, lc, Jl, arc, Jarc)

    # ----------------------------------------------------------------------------- argument checks
    def _q(self, q, name: str = "q") -> np.ndarray:
        """Full coordinates (ndof,) as a checked float64 array (the only way q reaches a kernel)."""
        q = check_finite(name, q, (self.ndof,))
        return q

    def _q_tip(self, q) -> np.ndarray:
        q = self._q(q)
        if not np.linalg.norm(q[-3:]) > 1e-12:
            raise InputError("q has a zero tip slope r_x at the last node: the tip frame is undefined")
        return q

    def stretches(self, q) -> np.ndarray:
        """Local stretch λ = |r_x| at every quadrature point, array (n_elements, quadrature_points)."""
        q = self._q(q)
        return self._stretches(q)

    def _stretches(self, q) -> np.ndarray:
        idx = 6 * np.arange(self.n)[:, None] + np.arange(12)[None, :]
        qe = q[idx].reshape(self.n, 4, 3)                       # element nodal vectors
        a = np.einsum("kj,ejc->ekc", self._N[:, 1, :], qe)      # r_x at quadrature points
        return np.sqrt(np.einsum("ekc,ekc->ek", a, a))

    # convenience accessors (full coordinates) ---------------------------------------------------
    def residual(self, q, tensions=None, pressure=0.0, tip_force=(0, 0, 0)) -> np.ndarray:
        """Q(q, T, p, F) = ∂Π/∂q (ndof,) — paper eq. (1)."""
        return self.evaluate(q, tensions, pressure, tip_force, hessian=False, lengths=False).Q

    def tangent(self, q, tensions=None, pressure=0.0, tip_force=(0, 0, 0)) -> np.ndarray:
        """∂Q/∂q (ndof, ndof), symmetric."""
        return self.evaluate(q, tensions, pressure, tip_force).K

    def dQ_dT(self, q) -> np.ndarray:
        """∂Q/∂T (ndof, m) = (∂l_c/∂q)ᵀ."""
        return self.evaluate(q, hessian=False).J_l.T

    def dQ_dp(self, q, pressure: float = 0.0) -> np.ndarray:
        """∂Q/∂p (ndof,) [m² = N/Pa] at full coordinates ``q`` and ``pressure`` [Pa]: −∂V/∂q, V = ∫ A(λ) λ dx the
        chamber volume, plus, for a pressure-dependent stiffness law, ∂Q_axial/∂p + ∂Q_bend/∂p (the same
        assembly with the coefficient vectors ∂ea/∂p, ∂ei/∂p: every stiffness term is linear in its
        coefficients).  Without pressure factors it does not depend on ``pressure``."""
        zero3 = np.zeros(3)
        q = self._q(q)
        pr = float(check_finite("pressure", pressure, ()))
        self._check_law_pressure(pr)
        dea, dei = (self._law.coefficient_derivatives(pr) if self._law.pressure_dependent
                    else (np.zeros(1), np.zeros(1)))
        E, Q, *_ = assemble(q, self.n, self._N, self._wq, np.ascontiguousarray(dea),
                            np.ascontiguousarray(dei), self._vc, zero3, self._E, self._d, self._co, self._so,
                            np.zeros(self.m), 0.0, zero3, False, 0)
        if not np.isfinite(E):           # the assembly stopped at an inadmissible point: Q is partial
            raise CollapsedStateError(f"state is outside the model's domain: {self.inadmissibility(q)}",
                                      solver="dQ_dp", stretch=float(self._stretches(q).min()))
        return Q

    def dQ_dF(self, q) -> np.ndarray:
        """∂Q/∂F_e (ndof, 3) = −(∂p_end/∂q)ᵀ."""
        return -self.tip_jacobian(q).T

    def tendon_lengths(self, q) -> np.ndarray:
        """l_c,i(q) [m] (paper eq. 5)."""
        return self.evaluate(q, hessian=False, lengths="values").lengths

    def tendon_jacobian(self, q) -> np.ndarray:
        """∂l_c/∂q (m, ndof)."""
        return self.evaluate(q, hessian=False).J_l

    def tip(self, q) -> np.ndarray:
        """Tool point of the rod p_end = r(L) + h t [m] (3,), without the series shear offset that
        ``Equilibrium.tip`` and :meth:`tool_point` include (:mod:`ancf.shear`)."""
        return kin.tip_position(self._q_tip(q), self.params.tool_offset)

    def _tip(self, q) -> np.ndarray:
        return kin.tip_position(q, self.params.tool_offset)

    def _tip_jacobian(self, q) -> np.ndarray:
        return kin.tip_position_jacobian(q, self.params.tool_offset)

    def tip_jacobian(self, q) -> np.ndarray:
        """∂p_end/∂q (3, ndof)."""
        return kin.tip_position_jacobian(self._q_tip(q), self.params.tool_offset)

    # series shear compliance (ancf.shear) -------------------------------------------------------
    def shear_compliance(self, pressure: float = 0.0) -> float:
        """s(p) [m/N] at ``pressure`` [Pa]: the series rotation-free tip compliance (0 without one)."""
        pr = float(check_finite("pressure", pressure, ()))
        self._check_shear_pressure(pr)
        return _shear.compliance(self._shear, pr)

    def _check_shear_pressure(self, pr: float) -> None:
        """InputError when s(p) < 0 at ``pr`` [Pa] (only reachable with check_limits=False outside the
        actuator's pressure range, over which the parameters checked it)."""
        if self._has_shear and not _shear.compliance(self._shear, pr) >= 0:
            raise InputError(f"the shear compliance s = {_shear.compliance(self._shear, pr):.4g} m/N < 0 at p = "
                             f"{pr / 1e3:g} kPa: the actuator's shear_compliance is not valid there")

    def _shear_parts(self, q, pr: float, F):
        """(u (3,), ∂u/∂q (3, ndof), ∂u/∂s = P⊥F_tot (3,), s, ds/dp) at full coordinates ``q``, pressure ``pr``
        [Pa] and external tip force ``F`` (3,) [N] (plus the tip mass's weight), or None without a shear
        compliance (:mod:`ancf.shear`)."""
        if not self._has_shear:
            return None
        a = q[-3:]
        Ft = self.total_tip_load(F)
        s = _shear.compliance(self._shear, pr)
        J = np.zeros((3, self.ndof))
        J[:, -3:] = _shear.offset_jacobian(a, s, Ft)
        return (_shear.offset(a, s, Ft), J, _shear.offset(a, 1.0, Ft), s,
                _shear.compliance_derivative(self._shear, pr))

    def shear_offset(self, q, pressure: float = 0.0, tip_force=(0.0, 0.0, 0.0)) -> np.ndarray:
        """u = s(p) (I − t tᵀ) F_tot [m] (3,): the tool point's rotation-free displacement at full coordinates
        ``q`` under the tip force ``tip_force`` [N] plus the tip mass's weight (zero without a shear compliance)."""
        q = self._q_tip(q)
        pr = float(check_finite("pressure", pressure, ()))
        F = check_finite("tip_force", tip_force, (3,))
        self._check_shear_pressure(pr)
        parts = self._shear_parts(q, pr, F)
        return np.zeros(3) if parts is None else parts[0]

    def tool_point(self, q, pressure: float = 0.0, tip_force=(0.0, 0.0, 0.0)) -> np.ndarray:
        """The tool point [m] (3,) at full coordinates ``q``: p_end(q) + :meth:`shear_offset` — what
        ``Equilibrium.tip`` holds (:meth:`tip` is p_end alone)."""
        return self.tip(q) + self.shear_offset(q, pressure, tip_force)

    def tool_jacobian(self, q, pressure: float = 0.0, tip_force=(0.0, 0.0, 0.0)) -> np.ndarray:
        """∂(tool point)/∂q (3, ndof) at fixed loads: ∂p_end/∂q + ∂u/∂q (:mod:`ancf.shear`)."""
        q = self._q_tip(q)
        pr = float(check_finite("pressure", pressure, ()))
        F = check_finite("tip_force", tip_force, (3,))
        self._check_shear_pressure(pr)
        parts = self._shear_parts(q, pr, F)
        J = self._tip_jacobian(q)
        return J if parts is None else J + parts[1]

    def _q_tip_frame(self, q) -> np.ndarray:
        """q with a tip slope on which the Rodrigues frame is defined (the assembly's slope rules)."""
        q = self._q_tip(q)
        code, v = _asm.slope_status(q[-3:], self._E)
        if code != _asm.OK:
            what = (f"stretch {v:.3g} < {_asm.STRETCH_MIN:g}" if code == _asm.COLLAPSED else
                    f"1 + t·e1 = {v:.3g} < {_asm.FRAME_MIN:g}: it points back along the base axis")
            raise InputError(f"q's tip slope is outside the model's domain ({what}); the tip frame is undefined")
        return q

    def tip_rotation(self, q) -> np.ndarray:
        """Tip orientation R (3, 3), Rodrigues rotation of the base axis onto the tip tangent."""
        return kin.tip_rotation(self._q_tip_frame(q), self._e1)

    def tip_angular_jacobian(self, q) -> np.ndarray:
        """J_ω (3, ndof): δR = [J_ω δq]× R."""
        return kin.tip_angular_jacobian(self._q_tip_frame(q), self._e1)

    def centreline(self, q, per_element: int = 10) -> np.ndarray:
        """Points along the centreline (m, 3) [m]."""
        return kin.interpolate(self._q(q), self.n, self.params.length, self._per_element(per_element))

    def tendon_paths(self, q, per_element: int = 10) -> np.ndarray:
        """Tendon routing points r + d R(t) o, array (m_tendons, points, 3) [m].  CollapsedStateError for a
        state outside the model's domain (:meth:`inadmissibility`)."""
        q, per_element = self._q(q), self._per_element(per_element)
        why = self.inadmissibility(q)
        if why is not None:
            raise CollapsedStateError(f"state is outside the model's domain: {why}", solver="tendon_paths",
                                      stretch=float(self._stretches(q).min()))
        r = kin.interpolate(q, self.n, self.params.length, per_element, 0)
        a = kin.interpolate(q, self.n, self.params.length, per_element, 1)
        out = np.empty((self.m, len(r), 3))
        for k in range(len(r)):
            R = kin.rodrigues(a[k] / np.linalg.norm(a[k]), self._e1)
            for i in range(self.m):
                o = self._co[i] * self._E[:, 1] + self._so[i] * self._E[:, 2]
                out[i, k] = r[k] + self._d[i] * (R @ o)
        return out

    # ----------------------------------------------------------------------------- results
    def _result(self, q, T, pr, F, info, ev: Evaluation, solver, slack=None, active=None, *, H=None, JA=None,
                check_stability: bool = True) -> Equilibrium:
        """Verify a converged state (stretch inside the law's validity range, stable) and package it."""
        Hr, stable = self._verify(q, H, JA, solver, check_stability,
                                  positive_definite=info.positive_definite if JA is None else None)
        # q is a converged, admissible state (finite energy: its tip slope passed the assembly's rules)
        tip, frame_ok, R = _cs.tip_pose(q, self.params.tool_offset, self._e1)
        if not frame_ok:
            R = kin.tip_rotation(q, self._e1)           # raises CollapsedStateError naming the fold
        if self._has_shear:                     # the tool point: p_end + s P⊥ F (ancf.shear)
            tip = tip + self._shear_parts(q, float(pr), F)[0]
        eq = Equilibrium(q=q, tip=tip, tip_rotation=R,
                         tendon_lengths=ev.lengths.copy(), tensions=np.array(T, float), pressure=pr,
                         tip_force=np.array(F, float), iterations=info.iterations,
                         residual_norm=info.residual_norm, energy=ev.energy, solver=solver, slack=slack,
                         active=active, history=info.history, stable=stable)
        eq.__dict__["_stability_matrix"] = Hr
        eq.__dict__["_params"] = self.params          # the actuator it was solved for (ancf.dynamics.modes)
        return eq

    def _verify(self, q, H, JA, solver: str, check_stability: bool, positive_definite: Optional[bool] = None):
        """CollapsedStateError outside the stiffness law's validity range; UnstableEquilibriumError when
        the reduced Hessian of the potential is not positive definite.  Returns (that Hessian, stable).

        ``H`` (nz, nz) is ∂Q/∂z at fixed tensions (it holds the tendon term T ∇²l); ``JA`` (k, nz) are the
        length gradients ∇l of the taut locked tendons.  Rigid tendons (``tendon_stiffness`` unset) are
        constraints l = l₀: the test matrix is H projected on null(JA).  Elastic tendons of stiffness k_s
        add the energy ½ k_s (l − l₀)² each, whose Hessian is k_s ∇l ∇lᵀ + T ∇²l; no constraint is left,
        so the test matrix is H + k_s JAᵀ JA on all of z (a projection would ignore the tendons' own
        stiffness and test the wrong matrix: it can pass a saddle or refuse a minimum).
        ``positive_definite=True``: the solver's compiled loop already factorised this very H (no JA)."""
        lo, hi = self._lam_range
        lmin, lmax = _cs.stretch_range(q, self.n, self._N)
        if lmin <= lo or lmax >= hi:
            bad = lmin if lmin <= lo else lmax
            raise CollapsedStateError(
                f"{solver}: the solution has a local stretch λ = {bad:.3f} outside the stiffness law's valid "
                f"range ({lo:.3f}, {hi:.3g}) where EA(λ) and EI(λ) are positive: the section has collapsed "
                "and the state is not an equilibrium of the model (lower the load or the tendon tensions)",
                solver=solver, stretch=bad)
        if H is None:
            return None, True
        if positive_definite and (JA is None or not len(JA)):
            return H, True           # the compiled loop factorised this very (assembled, symmetric) H
        Hr = H
        if JA is not None and len(JA):
            JA = np.asarray(JA, float)
            if self._cs > 0.0:
                Hr = H + (JA.T @ JA) / self._cs
            else:
                Qf, _ = np.linalg.qr(JA.T, mode="complete")
                Z = Qf[:, len(JA):]
                Hr = Z.T @ H @ Z
        Hr = 0.5 * (Hr + Hr.T)
        try:
            np.linalg.cholesky(Hr)
            return Hr, True
        except np.linalg.LinAlgError:
            pass
        lam_min = float(np.linalg.eigvalsh(Hr)[0])
        if lam_min >= -1e-10 * max(float(np.max(np.abs(np.diag(Hr)))), 1e-300):
            return Hr, True                      # positive semi-definite within round-off
        if not check_stability:
            return Hr, False
        what = ("on the tangent space of the locked tendons " if JA is not None and len(JA) and self._cs == 0
                else "with the locked tendons' stiffness " if JA is not None and len(JA) else "")
        raise UnstableEquilibriumError(
            f"the solve converged to an unstable equilibrium (a saddle of the potential: the reduced "
            f"Hessian {what}has a negative eigenvalue), not a usable state; perturb the start (q0), apply the "
            f"load in steps from a stable state, or lower the load", solver=solver, min_eigenvalue=lam_min)

    def modes(self, eq: "Equilibrium", count: int = 6, damping=None):
        """The ``count`` lowest vibration modes about the equilibrium ``eq`` — frequencies [Hz] (undamped,
        ``.frequencies_hz``), damping ratios (``.damping_ratios``, from ``damping``: None — the actuator's
        coefficients, a dict {alpha, beta, axial} or a ratio ζ of the first mode) and mass-normalised shapes
        (:func:`ancf.dynamics.modes`; locked tendons as constraints when ``eq`` comes from :meth:`fk_locked`).
        InputError for a state that is not an equilibrium of this model: solved for another actuator, or with a
        force residual under its loads above 1e-6 of the forces at the state
        (:func:`ancf.dynamics.modes.check_equilibrium`)."""
        from .dynamics import modes
        return modes(self, eq, count, damping)

    def simulate(self, t_end: float, dt: float, q0=None, v0=None, *, tensions=None, lengths=None,
                 pressure=0.0, pressure_tau: Optional[float] = None, pressure0: Optional[float] = None,
                 tip_force=(0.0, 0.0, 0.0), damping=None, rho_inf: float = 0.9,
                 tendon_penalty: Optional[float] = None, holding_force: Optional[float] = None,
                 check_limits: bool = True, max_halvings: int = 8, max_iter: int = 12, progress=None,
                 segment_tensions=None):
        """Transient response over [0, ``t_end``] [s] with steps ≤ ``dt`` [s] (:mod:`ancf.dynamics.transient`,
        docs/dynamics.md) → :class:`~ancf.dynamics.Simulation` (``.t``, ``.q``, ``.tip`` [m], ``.energy`` [J], …).

        Loads — each a constant, a function of t [s], or a table ``(times, values)``: ``tensions`` [N] (m,)
        *or* ``lengths`` [m] (m,) (tendons held by motors: a one-sided spring of the actuator's
        ``tendon_stiffness``, or of ``tendon_penalty`` [N/m] (default 1e5) for inextensible tendons; slack
        allowed; ``holding_force`` [N]: the motors' force limit — beyond it a motor gives way and the tension
        stays at the limit); ``pressure`` [Pa] (the supply's command when ``pressure_tau`` [s] is given: p' = (p_cmd − p)/τ
        from ``pressure0``, default the command at t = 0); ``tip_force`` [N] (3,).  ``q0`` (ndof,): the start
        (default: the static equilibrium under the loads at t = 0; required with ``lengths``; an
        :class:`Equilibrium` is checked to be one of this model, an array may be any admissible state), ``v0`` (ndof,)
        [m/s] its velocity (default 0).  ``damping``: None — the actuator's (``rayleigh_alpha`` [1/s],
        ``rayleigh_beta`` [s], ``axial_damping`` [N s]); a dict with those keys (alpha, beta, axial; optionally
        ``stiffness``, the (nz, nz) matrix β multiplies, default the tangent at q0); a number ζ ∈ [0, 1] —
        stiffness-proportional Rayleigh damping with ratio ζ at the first mode about q0 (0: none; about another
        equilibrium: :func:`ancf.dynamics.rayleigh_about`).
        ``rho_inf`` ∈ [0, 1]: the integrator's high-frequency spectral radius (1: no numerical dissipation).
        Fails fast (InputError/LimitError) on a load outside the limits anywhere on the time grid; raises
        ConvergenceError / CollapsedStateError at the time a step fails after ``max_halvings`` halvings.
        A step too coarse for the motion (its energy balance creating more energy than the motion has) is
        repeated in halved substeps, output rows still every ``dt`` (events ``refined``); ConvergenceError naming
        a step that would do when 64 substeps are not enough.  Ctrl-C (SIGINT, read between steps) returns the
        rows done so far with ``interrupted=True``.  With ``tendon_friction`` μ > 0 the guides' stick/slip history
        runs along (:mod:`ancf.dynamics.friction_step`): ``segment_tensions`` (m, n) [N] its start (default:
        every segment at the start's motor tension), e.g. a FrictionState's or a previous run's last row."""
        from .dynamics.transient import simulate
        return simulate(self, t_end, dt, q0, v0, tensions=tensions, lengths=lengths, pressure=pressure,
                        pressure_tau=pressure_tau, pressure0=pressure0, tip_force=tip_force, damping=damping,
                        rho_inf=rho_inf, tendon_penalty=tendon_penalty, holding_force=holding_force,
                        check_limits=check_limits,
                        max_halvings=max_halvings, max_iter=max_iter, progress=progress,
                        segment_tensions=segment_tensions)

    def inadmissibility(self, q) -> Optional[str]:
        """None when the full coordinates ``q`` (ndof,) are in the model's domain, else a text naming the
        first admissibility rule they violate and where (rules: :mod:`ancf.assembly`)."""
        q = self._q(q)
        code, e, k, i, v = _asm.state_status(q, self.n, self._N, self._E, self._d, self._co, self._so)
        if code == _asm.OK:
            return None
        where = "the tip slope" if e == self.n else f"element {e + 1}, quadrature point {k + 1}"
        if code == _asm.NONFINITE:
            return f"a coordinate of node {e + 1} is {v}"
        if code == _asm.COLLAPSED:
            return (f"collapsed section at {where}: stretch |r_x| = {v:.3g} < {_asm.STRETCH_MIN:g} "
                    "(zero or degenerate slope)")
        if code == _asm.REVERSED:
            return (f"section at {where} points back along the base axis: 1 + t·e1 = {v:.3g} < "
                    f"{_asm.FRAME_MIN:g} (turned more than {np.degrees(np.arccos(_asm.FRAME_MIN - 1)):.0f}°; "
                    "the section frame is singular there)")
        return (f"tendon {i + 1}'s path folds at {where}: length density |r_c,x| = {v:.3g} < "
                f"{_asm.TENDON_MIN:g} (local curvature radius close to the tendon distance)")

    def _initial_z(self, q0) -> np.ndarray:
        """Free coordinates of a user-given start q0, or of the straight reference for None.

        q0 must be a finite (ndof,) vector whose state — with the base node clamped as the solvers use
        it — is admissible (:mod:`ancf.assembly`); otherwise :class:`~ancf.errors.InputError` names the
        problem before any solver runs.  An inadmissible start is refused, not repaired: a silent
        fall-back to the reference would hide a wrong warm start (another model's vector, a zeroed buffer)."""
        if q0 is None:
            return self._to_free(self.q_ref)
        q0 = check_finite("q0", q0)
        if q0.ndim == 1 and q0.size != self.ndof:
            raise InputError(f"q0 has {q0.size} coordinates; this model ({self.n} elements) has "
                             f"{self.ndof}: pass an equilibrium of this model (eq.q) or None")
        q0 = check_finite("q0", q0, (self.ndof,))
        z0 = self._to_free(q0)
        why = self.inadmissibility(self._to_full(z0))
        if why is not None:
            raise InputError(f"q0 is not an admissible starting state: {why}; pass an equilibrium of this "
                             "model (eq.q) or None for the straight reference")
        return z0

    # ----------------------------------------------------------------------------- FK
    def fk(self, tensions=(0.0, 0.0, 0.0), pressure: float = 0.0, tip_force=(0.0, 0.0, 0.0),
           q0=None, *, tol: Optional[float] = None, max_iter: int = 60, check_limits: bool = True,
           check_stability: bool = True) -> Equilibrium:
        """Forward kinetostatics (T [N], p [Pa], F_e [N]) → equilibrium (paper Sec. III-A).

        ``q0`` (ndof,) warm-starts; default: the straight reference.  An inadmissible q0 (wrong size,
        NaN/inf, a zero or reversed slope, a folded tendon path; :meth:`inadmissibility`) raises
        InputError before any solve.  Converged when the free
        generalized-force residual ‖Q‖₂ < ``tol`` [N, N m] (default ``model.default_tol``: 1e-9 N + 1e-13 EA
        plus a round-off term that grows with the element count, see ``Model.__init__``).  Raises ConvergenceError otherwise, UnstableEquilibriumError if the state
        found is a saddle (``check_stability=False`` returns it with ``stable=False`` instead),
        CollapsedStateError if it leaves the stiffness law's validity range, InputError for bad arguments
        or loads outside the actuator's limits (``check_limits=False`` to analyse them anyway).
        """
        tol, max_iter = self._check_solver_options(tol, max_iter)
        if tensions is not None:
            tensions = check_finite("tensions", tensions)
            if tensions.ndim == 1 and tensions.size != self.m:
                raise InputError(f"tensions needs {self.m} values (one per tendon), got {tensions.size}")
        T, pr, F = self._check_inputs(tensions, pressure, tip_force, check_limits)
        z0 = self._initial_z(q0)
        z, info = self._fk_z(z0, T, pr, F, tol, max_iter)
        q = self._to_full(z)
        ev = self._values(q, T, pr, F, info)
        return self._result(q, T, pr, F, info, ev, "fk", H=info.matrix, check_stability=check_stability)

    def fk_history(self, tensions, pressure: float = 0.0, tip_force=(0.0, 0.0, 0.0), state=None, *,
                   tol: Optional[float] = None, max_iter: int = 60, check_limits: bool = True,
                   check_stability: bool = True):
        """FK with tendon friction (``params.tendon_friction`` μ; docs/friction.md): the next equilibrium of the
        friction history from ``state`` (a previous result; None: the unloaded actuator) at the motor tensions
        ``tensions`` (m,) [N], ``pressure`` [Pa], ``tip_force`` (3,) [N] → :class:`ancf.friction.FrictionState`
        (``.equilibrium``, ``.segment_tensions`` (m, n) [N], ``.sliding``).  μ = 0: :meth:`fk` itself (warm-started
        from ``state``).  :meth:`fk` ignores friction: its state is one the guides can hold (every guide stuck)."""
        from .friction import fk_history
        return fk_history(self, tensions, pressure, tip_force, state, tol=tol, max_iter=max_iter,
                          check_limits=check_limits, check_stability=check_stability)

    def tension_cycle(self, peak_tensions, pressure: float = 0.0, tip_force=(0.0, 0.0, 0.0), steps: int = 10, *,
                      check_limits: bool = True):
        """Quasi-static cycle of the motor tensions 0 → ``peak_tensions`` (m,) [N] → 0 in ``steps`` steps per branch
        with tendon friction → :class:`ancf.friction.TensionCycle` (both branches, the frictionless curve, the
        loop area [N m] and the dissipated energy [J]; :func:`ancf.friction.tension_cycle`)."""
        from .friction import tension_cycle
        return tension_cycle(self, peak_tensions, pressure, tip_force, steps, check_limits=check_limits)

    def _tangent_key(self, eq: Equilibrium) -> tuple:
        return (id(self), eq.q.tobytes(), eq.tensions.tobytes(), float(eq.pressure), eq.tip_force.tobytes())

    def _keep_tangent_parts(self, eq: Equilibrium, parts: tuple) -> None:
        """Keep (H (nz, nz), J_p (3, nz), J_l (m, nz)) — the free-coordinate tangent, tip Jacobian and tendon
        length Jacobian at ``eq`` — on the equilibrium, keyed by its state, for :mod:`ancf.compliance`."""
        object.__setattr__(eq, "_compliance_parts", (self._tangent_key(eq), parts))

    def _tangent_parts(self, eq: Equilibrium) -> Optional[tuple]:
        """The kept parts if they belong to ``eq``'s current state (q, T, p, F) and this model, else None."""
        cached = getattr(eq, "_compliance_parts", None)
        return cached[1] if cached is not None and cached[0] == self._tangent_key(eq) else None

    def _values(self, q, T, pr, F, info: SolveInfo) -> "Evaluation":
        """Energy and tendon lengths at a solution: from the solver's last evaluation when it kept them
        (the compiled loops), else assembled again."""
        if info.values is None:
            return self._evaluate(q, T, pr, F, hessian=False, lengths="values")
        return Evaluation(info.values[0], None, None, info.values[1], None, float("nan"), None)

    def _check_solver_options(self, tol, max_iter):
        tol = self.default_tol if tol is None else check_scalar("tol", tol, low=0.0)
        if not tol > 0:
            raise InputError("tol must be > 0 (a residual of exactly zero is never reached in floating point)")
        if isinstance(max_iter, bool) or not isinstance(max_iter, (int, np.integer)) or not 1 <= max_iter <= 10_000:
            raise InputError(f"max_iter must be an integer in [1, 10000], got {max_iter!r}")
        return float(tol), int(max_iter)

    def _fk_fun(self, T, pr, F, load=1.0):
        """Potential, free gradient and free Hessian at free coordinates z (lean path for Newton)."""
        Ts = np.ascontiguousarray(T * load, dtype=float)
        Ftot = self.total_tip_load(F * load, gravity_scale=load)
        pa = float(pr * load) * self._vc
        mg = self._mg * load
        p = self.params
        ea, ei = self._coeffs(float(pr * load))

        def fun(z, hessian):
            q = self._to_full(z)
            E, Q, K, *_ = assemble(q, self.n, self._N, self._wq, ea, ei, pa, mg, self._E, self._d,
                                   self._co, self._so, Ts, p.tool_offset, Ftot, hessian, 0)
            if not np.isfinite(E):
                return np.inf, None, None
            return E, self._reduce_vec(Q), (self._reduce_mat(K) if hessian else None)
        return fun

    def _fk_newton(self, z0, T, pr, F, tol, max_iter, load=1.0):
        """:func:`~ancf.solvers.minimize_newton` on Π(z) at ``load`` × (T, p, F, gravity), run by the compiled
        loop :func:`ancf.compiled_solvers.fk_newton` (same algorithm; ``_fk_fun`` is the Python form of the
        same potential).  Returns (z, SolveInfo) or raises ConvergenceError like ``minimize_newton``."""
        if load == 1.0:               # the common case: the checked arrays as they are
            Ts, Ftot, mg = np.ascontiguousarray(T, dtype=float), self._tip_weight + F, self._mg
        else:
            Ts = np.ascontiguousarray(T * load, dtype=float)
            Ftot, mg = self.total_tip_load(F * load, gravity_scale=load), self._mg * load
        ea, ei = self._coeffs(float(pr * load))      # the law at the pressure of this load step
        status, z, it, hist, H, pd, energy, lengths = _cs.fk_newton(
            np.ascontiguousarray(z0, dtype=float), self._q_fix, self._P_c, self._P is not None, self.n, self._N,
            self._wq, ea, ei, float(pr * load) * self._vc, mg, self._E, self._d,
            self._co, self._so, Ts, self.params.tool_offset, Ftot, float(tol), int(max_iter))
        history = hist.tolist()
        if status == _cs.CONVERGED:
            return z, SolveInfo(int(it), history[-1], history, H, bool(pd), (float(energy), lengths))
        if status == _cs.BAD_START:
            raise ConvergenceError("the starting state is inadmissible (potential or its derivatives not finite)",
                                   solver="fk", iterations=0, residual_norm=float("inf"), tolerance=tol,
                                   history=[float("inf")])
        raise ConvergenceError("Newton on the equilibrium did not converge", solver="fk",
                               iterations=len(history) - 1, residual_norm=history[-1], tolerance=tol,
                               history=history)

    @staticmethod
    def _admissible(ev: "Evaluation") -> bool:
        """False for states the assembly rejected (|r_x| < 0.2 somewhere: a collapsed section)."""
        return bool(np.isfinite(ev.energy))

    def _fk_z(self, z0, T, pr, F, tol, max_iter):
        """Newton from ``z0``; if that fails within a short budget, adaptive load stepping from the
        unloaded reference with a secant predictor (robust cold start over the whole operating range)."""
        try:
            return self._fk_newton(z0, T, pr, F, tol, min(max_iter, 25))
        except ConvergenceError as exc:
            first = exc
        z_prev = z = self._to_free(self.q_ref)
        s_prev, s, ds, total_it, hist = 0.0, 0.0, 0.25, first.iterations, list(first.history)
        while s < 1.0:
            s_try = min(1.0, s + ds)
            z_pred = z if s == 0.0 else z + (z - z_prev) * (s_try - s) / (s - s_prev)
            try:
                z_try, info = self._fk_newton(z_pred, T, pr, F, tol, max_iter if s_try == 1.0 else 15, s_try)
            except ConvergenceError as exc:
                total_it += exc.iterations
                ds /= 3
                if ds < 1e-5:
                    raise ConvergenceError(
                        self._stall_message(z, s, T, pr, F, math.isinf(exc.residual_norm), first.residual_norm),
                        solver="fk", iterations=total_it, residual_norm=exc.residual_norm, tolerance=tol,
                        history=hist + exc.history) from None
                continue
            z_prev, s_prev, z, s = z, s, z_try, s_try
            total_it += info.iterations
            hist += info.history
            ds = min(ds * (2.0 if info.iterations <= 6 else 1.2), 1.0)
        return z, SolveInfo(total_it, hist[-1], hist, info.matrix)

    def _stall_message(self, z, s: float, T, pr: float, F, collapsed: bool, direct_residual: float) -> str:
        """What a stalled load stepping means: the equilibrium path of ``s`` × (T [N], p [Pa], F [N], weight)
        ends at the load factor ``s`` of the last converged state ``z`` (a limit point, past which no nearby
        equilibrium exists, or the edge of the model's admissible states when ``collapsed``), i.e. the load asked is
        beyond what the actuator carries in this configuration.  States the load factor, the loads reached and that state's tip [mm]."""
        tip = self.tip(self._to_full(z))
        step = ("the next load step leaves the model's admissible states: a section collapses, turns back "
                "past ≈172° or a tendon path folds" if collapsed else
                "no equilibrium a load step further: a limit point, where the equilibrium loses stability")
        return (f"the load is beyond what the actuator can carry in this configuration: the equilibrium path ends "
                f"at {100 * s:.2f} % of the asked load ({step}). "
                f"Asked: T = {vector(T, 'N', 1.0, 4)}, p = {pr / 1e3:g} kPa, F = {vector(F, 'N', 1.0, 4)}; "
                f"last converged state at load factor {s:.4f}: T = {vector(s * np.asarray(T), 'N', 1.0, 4)}, "
                f"p = {s * pr / 1e3:g} kPa, F = {vector(s * np.asarray(F), 'N', 1.0, 4)}, weight × {s:.4f}, "
                f"tip at {vector(tip, 'mm', 1e3, 2)}; the direct Newton solve ended at residual {direct_residual:.3e}")

    def droop(self, pressure: float = 0.0) -> Equilibrium:
        """Gravity-only equilibrium (T = 0, no tip force) at ``pressure`` [Pa] — the stored warm start of
        the paper's LACC (computed once per pressure and kept)."""
        key = check_scalar("pressure", pressure, unit="Pa")
        if key not in self._droop:
            self._droop[key] = self.fk(np.zeros(self.m), key, (0, 0, 0))
        return self._droop[key]

    # ----------------------------------------------------------------------------- IK
    def ik(self, target, pressure: float = 0.0, tip_force=(0.0, 0.0, 0.0), q0=None, tensions0=None, *,
           tol: Optional[float] = None, tol_position: float = 1e-9, max_iter: int = 60,
           check_limits: bool = True, check_stability: bool = True) -> Equilibrium:
        """Inverse kinetostatics (p_d [m], p [Pa], F_e [N]) → (q, T) with T_min ≤ T ≤ T_max
        (paper Sec. III-A, eq. 2); ``target`` is the tool point (``Equilibrium.tip``).

        Raises InfeasibleTargetError (naming the violated bound and giving the nearest reachable tool point)
        when no tensions inside the bounds reach the target, ConvergenceError if a solve fails.
        With more than 3 tendons the solution is not unique: the one with the least Σ T² is returned.
        The state returned is a stable equilibrium at the tensions found (UnstableEquilibriumError
        otherwise, unless ``check_stability=False``).  The pressure is checked against the actuator's
        limits (``check_limits=False`` skips that; the tensions always stay inside their bounds).

        With a shear compliance s(p) (:mod:`ancf.shear`) the tool point is p_end(q) + u(q), u = s P⊥ F: the
        rod's IK is solved for the corrected target p_d − u, u taken at the previous solution, until the tool
        point is within ``tol_position`` of p_d (a fixed point; u turns with the tip tangent only, so each
        pass shrinks the error by about s |F| / L).  Without one this is the rod's IK itself."""
        if not self._has_shear:
            return self._ik_rod(target, pressure, tip_force, q0, tensions0, tol=tol, tol_position=tol_position,
                                max_iter=max_iter, check_limits=check_limits, check_stability=check_stability)
        tol_position = check_scalar("tol_position", tol_position, low=1e-15, high=1e-2, unit="m")
        pd = check_finite("target", target, (3,))
        _, pr, F = self._check_inputs(None, pressure, tip_force, check_limits)
        T0 = np.zeros(self.m) if tensions0 is None else check_finite("tensions0", tensions0, (self.m,))
        if q0 is None:                          # the rod IK's own default start, shared
            p = self.params
            q0 = self.fk(np.clip(T0, p.tension_min, p.tension_max), pr, F, check_limits=check_limits).q
        u = self._shear_parts(self._q_tip_frame(q0), pr, F)[0]
        err_hist = []
        for _ in range(50):
            try:
                eq = self._ik_rod(pd - u, pr, F, q0, T0, tol=tol, tol_position=max(0.5 * tol_position, 1e-15),
                                  max_iter=max_iter, check_limits=check_limits, check_stability=check_stability)
            except InfeasibleTargetError as exc:
                # the corrected target of a pass may lie just outside the reachable set while the tool point
                # target does not: go on from the nearest state until u stops changing
                if exc.tensions is None:
                    raise
                try:
                    near = self.fk(exc.tensions, pr, F, q0=q0, check_limits=False, check_stability=False)
                except (ConvergenceError, CollapsedStateError):
                    raise exc from None
                u_near = near.tip - self._tip(near.q)
                if np.linalg.norm(u_near - u) > 0.5 * tol_position:
                    u, q0, T0 = u_near, near.q, np.asarray(exc.tensions, float)
                    err_hist.append(float(np.linalg.norm(near.tip - pd)))
                    continue
                raise InfeasibleTargetError(
                    f"IK target {vector(pd, 'mm', 1e3, 3)} (tool point, shear offset {vector(u, 'mm', 1e3, 3)}): "
                    f"{exc}; nearest reachable tool point {vector(near.tip, 'mm', 1e3, 3)}", target=pd,
                    nearest=near.tip, tensions=exc.tensions, violated=exc.violated) from None
            err = float(np.linalg.norm(eq.tip - pd))
            err_hist.append(err)
            if err <= tol_position:
                return eq
            u = eq.tip - self._tip(eq.q)
            q0, T0 = eq.q, eq.tensions
        raise ConvergenceError("the IK's shear correction of the target did not converge (tool point errors "
                               f"{', '.join(f'{e:.3g}' for e in err_hist[-4:])} m)", solver="ik",
                               iterations=len(err_hist), residual_norm=err_hist[-1], tolerance=tol_position,
                               history=err_hist)

    def _ik_rod(self, target, pressure: float = 0.0, tip_force=(0.0, 0.0, 0.0), q0=None, tensions0=None, *,
                tol: Optional[float] = None, tol_position: float = 1e-9, max_iter: int = 60,
                check_limits: bool = True, check_stability: bool = True) -> Equilibrium:
        """The rod's IK (:meth:`ik` without the shear correction: ``target`` is p_end).  Inverse kinetostatics
        (p_d [m], p [Pa], F_e [N]) → (q, T) with T_min ≤ T ≤ T_max (paper Sec. III-A, eq. 2).

        Raises InfeasibleTargetError (naming the violated bound and giving the nearest reachable tip)
        when no tensions inside the bounds reach the target, ConvergenceError if a solve fails.
        With more than 3 tendons the solution is not unique: the one with the least Σ T² is returned.
        The state returned is a stable equilibrium at the tensions found (UnstableEquilibriumError
        otherwise, unless ``check_stability=False``).  The pressure is checked against the actuator's
        limits (``check_limits=False`` skips that; the tensions always stay inside their bounds).
        """
        tol, max_iter = self._check_solver_options(tol, max_iter)
        tol_position = check_scalar("tol_position", tol_position, low=1e-15, high=1e-2, unit="m")
        pd = check_finite("target", target, (3,))
        _, pr, F = self._check_inputs(None, pressure, tip_force, check_limits)
        p = self.params
        T0 = np.zeros(self.m) if tensions0 is None else check_finite("tensions0", tensions0, (self.m,))
        if q0 is None:
            q0 = self.fk(np.clip(T0, p.tension_min, p.tension_max), pr, F, check_limits=check_limits).q
        z0 = self._initial_z(q0)
        sol = None
        if self.m == 3:
            try:
                sol = self._ik_newton(z0, T0, pd, pr, F, tol, tol_position, max_iter)
            except ConvergenceError:
                sol = None
        if sol is not None:
            z, T, info = sol
            if np.all(T >= p.tension_min - 1e-9) and np.all(T <= p.tension_max + 1e-9):
                Tc = np.clip(T, p.tension_min, p.tension_max)
                clipped = not np.array_equal(Tc, T)
                if clipped and info.values is not None:
                    # clipped by round-off: Π is linear in T (Σ T_i l_i) and the lengths do not depend on T
                    energy, lengths = info.values
                    info.values = (float(energy + (Tc - T) @ lengths), lengths)
                T = Tc
                q = self._to_full(z)
                ev = self._values(q, T, pr, F, info)
                nz = self.nz
                eq = self._result(q, T, pr, F, info, ev, "ik", H=info.matrix[:nz, :nz],
                                  check_stability=check_stability)
                if info.values is not None and not clipped:    # the compiled loop's last Jacobian: the tangent at eq
                    J = info.matrix
                    self._keep_tangent_parts(eq, (J[:nz, :nz], J[nz:, :nz], J[:nz, nz:].T))
                return eq
        # bounded reduced solve over the tensions: feasible solution or nearest reachable point
        unconstrained = None if sol is None else sol[1]
        return self._ik_bounded(z0, T0, pd, pr, F, tol, tol_position, unconstrained, check_stability,
                                warm=tensions0 is not None)

    def _ik_newton(self, z0, T0, pd, pr, F, tol, tol_position, max_iter):
        nz, m = self.nz, self.m

        def fun(x):
            z, T = x[:nz], x[nz:]
            q = self._to_full(z)
            ev = self._evaluate(q, T, pr, F)
            if not self._admissible(ev):
                return np.full(nz + 3, np.nan), None
            R = np.concatenate([self._reduce_vec(ev.Q), self._tip(q) - pd])
            J = np.zeros((nz + 3, nz + m))
            J[:nz, :nz] = self._reduce_mat(ev.K)
            J[:nz, nz:] = self._reduce_vec(ev.J_l).T
            J[nz:, :nz] = self._reduce_vec(self._tip_jacobian(q))
            return R, J

        w = np.concatenate([np.ones(nz), np.full(3, self._kscale)])
        tol_w = min(tol, self._kscale * tol_position)
        x0 = np.concatenate([z0, T0])
        ea, ei = self._coeffs(float(pr))
        # the Newton phase of solve_root, compiled; a solve that needs its LM phase runs solve_root itself.  A start
        # where the last solve started or ended (same pressure and tip force) reuses its evaluation there
        Fc = self.total_tip_load(F)
        key0 = (x0.tobytes(), float(pr), Fc.tobytes())
        kept = self._ik_evaluations.get(key0)
        reuse = kept if kept is not None else (np.zeros(nz), np.zeros((nz + 3, nz + m)), 0.0, np.zeros(m))
        # (the flag is not named pd: ``fun`` above reads the target pd when the Python solver runs)
        (status, x, it, hist, J, posdef, energy, lengths, Q_end, *first) = _cs.ik_newton_reuse(
            x0, nz, np.ascontiguousarray(pd, dtype=float), w, self._q_fix, self._P_c, self._P is not None, self.n,
            self._N, self._wq, ea, ei, float(pr) * self._vc, self._mg, self._E, self._d, self._co,
            self._so, self.params.tool_offset, Fc, float(tol_w), int(max_iter), *reuse, kept is not None)
        kept_all = self._ik_evaluations
        kept_all.pop(key0, None)
        if first[4]:
            kept_all[key0] = tuple(first[:4])
        if status == _cs.CONVERGED:
            # copies: J and the lengths also go out with the result, whose user may change them
            kept_all[(x.tobytes(), float(pr), Fc.tobytes())] = (Q_end, J.copy(), float(energy), lengths.copy())
        keys = list(kept_all)                                            # a snapshot, oldest first
        for old in keys[:max(0, len(keys) - self.IK_KEPT_EVALUATIONS)]:
            kept_all.pop(old, None)
        if status == _cs.CONVERGED:
            history = hist.tolist()
            return x[:nz], x[nz:], SolveInfo(int(it), history[-1], history, J, bool(posdef),
                                             (float(energy), lengths))
        x, info = solve_root(fun, x0, tol=tol_w, max_iter=max_iter, name="ik", weights=w)
        return x[:nz], x[nz:], info

    #: The IK keeps its evaluations (Q, ∂R/∂x, Π, lengths) where its latest solves started and ended, this many
    #: (the oldest dropped first): a solve that starts at one of them (same pressure and tip force: a control
    #: loop warm-starting from its last state or from a stored one) reuses it, to the bit (``_ik_newton``).
    IK_KEPT_EVALUATIONS = 8

    #: Solve the bounded IK (nearest reachable tip) by the compiled projected Gauss–Newton
    #: (:mod:`ancf.compiled_bounded`) before falling back to ``scipy.optimize.least_squares``; False: scipy only
    #: (the reference the compiled loop is tested against).
    fast_bounded_ik = True

    def _ik_bounded_fast(self, z0, x0, lo, hi, pd, pr, F, tol):
        """(T (m,) [N], z (nz,), SolveInfo of the FK at T, FK evaluations, tangent parts (H, J_p, J_l) at z) from
        the compiled projected Gauss–Newton of :mod:`ancf.compiled_bounded`, or None when it did not converge (or
        its last state is not an equilibrium to ``tol``)."""
        ea, ei = self._coeffs(float(pr))
        status, T, z, _, _, _, it, nfev, _ = _cb.ik_bounded(
            np.ascontiguousarray(x0, dtype=float), np.ascontiguousarray(z0, dtype=float), lo, hi,
            np.ascontiguousarray(pd, dtype=float), self._q_fix, self._P_c, self._P is not None, self.n, self._N,
            self._wq, ea, ei, float(pr) * self._vc, self._mg, self._E, self._d, self._co, self._so,
            self.params.tool_offset, self._tip_weight + F, float(tol), 25, 100, 1e-12)
        if status != _cs.CONVERGED:
            return None
        # the loop's last FK was corrected by one Newton step after its last assembly: assemble again at z, verify
        # the equilibrium there (‖Q‖ < tol; the stability of this very H is checked by _result) and keep the
        # tangent parts (H, J_p, J_l) for the compliances at the state the controller will command
        q = self._to_full(z)
        ev = self._evaluate(q, T, pr, F)
        res = float(np.linalg.norm(self._reduce_vec(ev.Q)))
        if not res < tol:
            return None
        H = self._reduce_mat(ev.K)
        parts = (H, self._reduce_vec(self._tip_jacobian(q)), self._reduce_vec(ev.J_l))
        return T, z, SolveInfo(int(it), res, [res], H, None, (ev.energy, ev.lengths)), int(nfev), parts

    def _ik_bounded(self, z0, T0, pd, pr, F, tol, tol_position, unconstrained, check_stability=True, warm=False):
        """Bounded solve over T ∈ [T_min, T_max]: the feasible solution (least Σ T² for more than 3 tendons) or
        InfeasibleTargetError with the nearest reachable tip.  The compiled projected Gauss–Newton starts from
        the caller's tensions0 ``T0`` when ``warm`` (with ``z0`` its state: the previous state of a control loop,
        next to the answer), else from scipy's start, the clipped unconstrained solution; scipy's
        ``least_squares`` from its own start when the compiled loop does not converge."""
        p = self.params
        state = {"z": z0, "info": None}
        lo, hi = np.full(self.m, p.tension_min), np.full(self.m, p.tension_max)

        def solve_fk(T):
            z, info = self._fk_z(state["z"], T, pr, F, tol, 60)
            state["z"], state["info"] = z, info
            return z

        def fun(T):
            z = solve_fk(T)
            return self._tip(self._to_full(z)) - pd

        def jac(T):
            z = solve_fk(T)
            q = self._to_full(z)
            ev = self._evaluate(q, T, pr, F)
            H = self._reduce_mat(ev.K)
            dz = -np.linalg.solve(H, self._reduce_vec(ev.J_l).T)
            return self._reduce_vec(self._tip_jacobian(q)) @ dz

        x0 = np.clip(T0 if unconstrained is None else unconstrained, lo, hi)
        start = np.clip(T0, lo, hi) if warm else x0
        fast = self._ik_bounded_fast(z0, start, lo, hi, pd, pr, F, tol) if self.fast_bounded_ik else None
        parts = fast_info = None
        if fast is not None:
            T, z, fast_info, nfev, parts = fast
            state["z"], state["info"] = z, fast_info
        else:           # the compiled loop did not converge: scipy's trust-region reflective on the same problem
            res = so.least_squares(fun, x0, jac=jac, bounds=(lo, hi), method="trf", xtol=1e-14, ftol=1e-15,
                                   gtol=1e-15, max_nfev=200)
            T = res.x
            nfev = int(res.nfev)
            z = solve_fk(T)
        q = self._to_full(z)
        err = float(np.linalg.norm(self._tip(q) - pd))
        feasible = err <= max(tol_position * 10, 1e-8)
        if feasible and self.m > 3:
            # redundant tendons: least total tension Σ T² on the solution manifold, inside the bounds
            cons = {"type": "eq", "fun": fun, "jac": jac}
            opt = so.minimize(lambda t: 0.5 * t @ t, T, jac=lambda t: t, bounds=list(zip(lo, hi, strict=True)),
                              constraints=[cons], method="SLSQP", options={"ftol": 1e-12, "maxiter": 100})
            nfev += int(opt.nfev)
            # judge the candidate ourselves (SLSQP's own flag trips on the FK's round-off): on target,
            # inside the bounds, and less total tension than the least-squares point
            if (np.linalg.norm(fun(np.clip(opt.x, lo, hi))) <= max(tol_position * 10, 1e-8)
                    and opt.x @ opt.x < T @ T):
                T = np.clip(opt.x, lo, hi)
                z = solve_fk(T)
                q = self._to_full(z)
                err = float(np.linalg.norm(self._tip(q) - pd))
        if feasible:
            ev = self._evaluate(q, T, pr, F, hessian=False, lengths="values")
            info = SolveInfo(nfev, float(np.linalg.norm(self._reduce_vec(ev.Q))), [])
            return self._result(q, T, pr, F, info, ev, "ik", H=state["info"].matrix,
                                check_stability=check_stability)
        violated = []
        for i in range(self.m):
            need = None if unconstrained is None else unconstrained[i]
            note = "" if need is None else f" (unconstrained solution needs {need:.3g} N)"
            if T[i] <= lo[i] + 1e-9 and (need is None or need < lo[i]):
                violated.append(f"T{i + 1} >= {lo[i]:g} N{note}")
            elif T[i] >= hi[i] - 1e-9 and (need is None or need > hi[i]):
                violated.append(f"T{i + 1} <= {hi[i]:g} N{note}")
        if not violated:
            violated = [f"T{i + 1} at {'lower' if T[i] <= lo[i] + 1e-9 else 'upper'} bound"
                        for i in range(self.m) if T[i] <= lo[i] + 1e-9 or T[i] >= hi[i] - 1e-9]
        near = self._tip(q)
        try:            # the FK state at the nearest tensions, verified (the compiled path's tangent kept on it)
            info = state["info"]
            nearest_state = self._result(q, np.array(T, float), pr, F, info, self._values(q, T, pr, F, info), "fk",
                                         H=info.matrix)
            if parts is not None and info is fast_info:          # the parts belong to this state
                self._keep_tangent_parts(nearest_state, parts)
        except (CollapsedStateError, UnstableEquilibriumError):
            nearest_state = None
        raise InfeasibleTargetError(
            f"IK target {vector(pd, 'mm', 1e3, 3)} is not reachable with tensions in "
            f"[{p.tension_min:g}, {p.tension_max:g}] N at p = {pr / 1e3:g} kPa: violated "
            f"{'; '.join(violated) or 'no bound (solver stalled)'}; nearest reachable tip "
            f"{vector(near, 'mm', 1e3, 3)} ({err * 1e3:.3f} mm away) with tensions "
            f"{vector(T, 'N', 1.0, 4)}", target=pd, nearest=near, tensions=T, violated=violated, state=nearest_state)

    # ----------------------------------------------------------------------------- locked FK
    def rest_lengths(self, eq: Equilibrium) -> np.ndarray:
        """Tendon lengths to lock at ``eq`` [m]: l(q) − T/k_s (the path lengths for inextensible tendons)."""
        return eq.tendon_lengths - self._cs * eq.tensions

    def fk_locked(self, tendon_lengths, pressure: float = 0.0, tip_force=(0.0, 0.0, 0.0), q0=None,
                  tensions0=None, *, method: str = "active_set", tol: Optional[float] = None, tol_length: float = 1e-10,
                  max_iter: int = 60, check_limits: bool = True, check_stability: bool = True) -> Equilibrium:
        """FK with locked tendon lengths l⁰ [m] (paper eqs. 3–6): returns q, tensions T ≥ 0 and slack
        β = l⁰ − l(q) ≥ 0 with T_i β_i = 0.  ``method``: ``"active_set"`` (exact) or ``"gamma"`` (paper).
        With elastic tendons (``tendon_stiffness`` k_s) a taut tendon obeys l(q) − T/k_s = l⁰, the rest
        length (lock at :meth:`rest_lengths` of an equilibrium).

        The pressure is checked against the actuator's limits up front (``check_limits=False`` skips
        it).  The tensions are a result here: tensions above ``tension_max`` are listed in
        ``eq.limit_violations`` (and :meth:`Equilibrium.require_within_limits` raises
        :class:`~ancf.errors.LimitError` for them; the CLI does so unless ``--no-limits``).  The state must be a minimum of the potential: on the
        tangent space of the taut tendons' constraints for rigid tendons, of the potential including the
        tendons' energy ½ k_s (l − l₀)² for elastic ones (UnstableEquilibriumError otherwise, unless
        ``check_stability=False``)."""
        tol, max_iter = self._check_solver_options(tol, max_iter)
        tol_length = check_scalar("tol_length", tol_length, low=1e-15, high=1e-3, unit="m")
        l0 = check_finite("tendon_lengths", tendon_lengths, (self.m,))
        if np.any(l0 <= 0) or np.any(l0 > 3 * self.params.length):
            raise InputError(f"tendon_lengths {vector(l0, 'mm', 1e3, 3)} must be positive and below "
                             f"3 × the actuator length ({3e3 * self.params.length:g} mm)")
        if method not in ("active_set", "gamma"):
            raise InputError(f"fk_locked method must be 'active_set' or 'gamma', got {method!r}")
        _, pr, F = self._check_inputs(None, pressure, tip_force, check_limits)
        q0_given = q0 is not None
        if q0 is None:
            # only a start: an unstable free state may well be held stable by the locked tendons
            q0 = self.fk(np.zeros(self.m), pr, F, check_limits=check_limits, check_stability=False).q
        z0 = self._initial_z(q0)
        if tensions0 is None:
            T0 = np.zeros(self.m)
        else:
            T0 = check_finite("tensions0", tensions0, (self.m,))
        solve = self._locked_active_set if method == "active_set" else self._locked_gamma
        # Start from the given state and tensions; if that fails (e.g. four tendons all taut at lock time
        # make the KKT system nearly singular while the answer has one slack), restart from the same state
        # with the active set taken from the lengths, then from a cold start.
        starts = [lambda: (z0, T0)]
        if np.any(T0 != 0):
            starts.append(lambda: (z0, np.zeros(self.m)))
        if q0_given:
            starts.append(lambda: (self._to_free(self.fk(np.zeros(self.m), pr, F, check_limits=check_limits).q),
                                   np.zeros(self.m)))
        first = None
        for start in starts:
            try:
                z_s, T_s = start()
                eq = solve(z_s, T_s, l0, pr, F, tol, tol_length, max_iter, check_stability)
                break
            except (ConvergenceError, UnstableEquilibriumError, CollapsedStateError) as exc:
                first = first or exc
        else:
            raise first
        p = self.params
        eq.limit_violations = tuple(
            f"T{i + 1} = {eq.tensions[i]:.3g} N > tension_max = {p.tension_max:g} N" for i in range(self.m)
            if eq.tensions[i] > p.tension_max * (1 + 1e-9) + 1e-12)
        return eq

    def _locked_accept(self, tol, tol_length):
        """Convergence of a locked solve in the rows' own units: ‖Q‖ < tol [N] and every length residual
        below tol_length [m] (the weighted norm alone would ask lengths EA/L × L times more than stated)."""
        return kkt_accept(self.nz, tol, tol_length)

    def _locked_system(self, A, l0, pr, F):
        nz = self.nz
        A = list(A)

        def fun(x):
            z, TA = x[:nz], x[nz:]
            T = np.zeros(self.m)
            T[A] = TA
            q = self._to_full(z)
            ev = self._evaluate(q, T, pr, F)
            if not self._admissible(ev):
                return np.full(nz + len(A), np.nan), None
            JlA = self._reduce_vec(ev.J_l[A])
            R = np.concatenate([self._reduce_vec(ev.Q), ev.lengths[A] - self._cs * TA - l0[A]])
            J = np.zeros((nz + len(A), nz + len(A)))
            J[:nz, :nz] = self._reduce_mat(ev.K)
            J[:nz, nz:] = JlA.T
            J[nz:, :nz] = JlA
            J[nz:, nz:] = -self._cs * np.eye(len(A))
            return R, J
        return fun

    def _locked_active_set(self, z0, T0, l0, pr, F, tol, tol_length, max_iter, check_stability=True):
        # the loop (ancf.solvers.locked_active_set) starts with the tendons carrying tension at lock time and
        # those the start state stretches
        def lengths(z, T):
            return self._evaluate(self._to_full(z), hessian=False, lengths="values").lengths

        z, T, A, _, info = locked_active_set(lambda A: self._locked_system(A, l0, pr, F), lengths, z0, T0, l0,
                                             tol=tol, tol_length=tol_length, max_iter=max_iter,
                                             length_scale=self._kscale * self.params.length)
        q = self._to_full(z)
        T = np.maximum(T, 0.0)
        ev = self._evaluate(q, T, pr, F, hessian=False, lengths="values")
        slack = np.maximum(l0 - ev.lengths, 0.0)
        slack[list(A)] = 0.0
        return self._result(q, T, pr, F, info, ev, "fk_locked", slack=slack, active=A,
                            H=info.matrix[:self.nz, :self.nz], JA=info.matrix[self.nz:, :self.nz],
                            check_stability=check_stability)

    def _locked_gamma(self, z0, T0, l0, pr, F, tol, tol_length, max_iter, check_stability=True):
        """Paper eq. (6): T = γ², β = 0 for γ > 0; T = 0, β = γ² for γ ≤ 0, Newton/LM on (z, γ).

        The γ column of the Jacobian vanishes at γ = 0, so a tendon that has to change from taut to
        slack (or back) can stall there; the solve is then restarted with the initial sign of γ flipped
        for the tendons that started at zero tension (at most 2^m starts)."""
        nz, m = self.nz, self.m
        l_start = self._evaluate(self._to_full(z0), hessian=False, lengths="values").lengths
        g_base = np.where(T0 > 0, np.sqrt(np.maximum(T0, 0)), -np.sqrt(np.maximum(l0 - l_start, 0)))
        undecided = [i for i in range(m) if g_base[i] == 0.0]
        g_base = np.where(g_base == 0, 1e-3, g_base)

        def fun(x):
            z, gam = x[:nz], x[nz:]
            T = np.where(gam > 0, gam ** 2, 0.0)
            beta = np.where(gam > 0, 0.0, gam ** 2)
            q = self._to_full(z)
            ev = self._evaluate(q, T, pr, F)
            if not self._admissible(ev):
                return np.full(nz + m, np.nan), None
            Jl = self._reduce_vec(ev.J_l)
            R = np.concatenate([self._reduce_vec(ev.Q), ev.lengths - self._cs * T + beta - l0])
            J = np.zeros((nz + m, nz + m))
            J[:nz, :nz] = self._reduce_mat(ev.K)
            J[:nz, nz:] = Jl.T * np.where(gam > 0, 2 * gam, 0.0)
            J[nz:, :nz] = Jl
            J[nz:, nz:] = np.diag(np.where(gam > 0, -2 * self._cs * gam, 2 * gam))
            return R, J

        w = np.concatenate([np.ones(nz), np.full(m, self._kscale * self.params.length)])
        tol_w = min(tol, self._kscale * self.params.length * tol_length)
        first = None
        for flips in range(2 ** len(undecided)):
            g0 = g_base.copy()
            for k, i in enumerate(undecided):
                if flips >> k & 1:
                    g0[i] = -1e-2
            try:
                x, info = solve_root(fun, np.concatenate([z0, g0]), tol=tol_w, max_iter=max_iter * 3,
                                     accept=self._locked_accept(tol, tol_length),
                                     name="fk_locked(gamma)", weights=w)
                break
            except ConvergenceError as exc:
                first = first or exc
        else:
            raise first
        z, gam = x[:nz], x[nz:]
        T = np.where(gam > 0, gam ** 2, 0.0)
        slack = np.where(gam > 0, 0.0, gam ** 2)
        q = self._to_full(z)
        ev = self._evaluate(q, T, pr, F, hessian=False, lengths="values")
        return self._result(q, T, pr, F, info, ev, "fk_locked(gamma)", slack=slack,
                            active=tuple(int(i) for i in np.flatnonzero(gam > 0)),
                            H=info.matrix[:nz, :nz], JA=info.matrix[nz:, :nz][gam > 0],
                            check_stability=check_stability)
