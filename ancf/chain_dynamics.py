r"""Dynamics of a multi-segment actuator: mass matrix, modes and transient response (docs/multisegment.md,
"Dynamics"; the one-segment model's are in :mod:`ancf.dynamics`).

**Kinetic energy.**  Segment k is an ANCF cable with the constant consistent mass M_k (:func:`ancf.dynamics.
consistent_mass`), T_k = ½ q̇_kᵀ M_k q̇_k.  The full coordinates are q = Φ(z) (:mod:`ancf.chain_system`), so
q̇ = J ż with J = ∂Φ/∂z.  Cap k is a rigid body fixed to segment k's last node (r, a), t = a/|a|: its centre of
mass is p_c = r + c t (c = ``mass_offset``), and, the model having no torsion, its angular velocity is t × ṫ
plus a spin about t that the model does not carry; with its transverse moment of inertia I_k about the centre
of mass (``cap_inertia``, default 0: a point mass, as the one-segment tool-point mass),

    T_cap = ½ m |ṗ_c|² + ½ I |ṫ|²,   ṗ_c = J_c (ṙ, ȧ),   J_c = [I₃, c D],   ṫ = D ȧ,   D = (I₃ − t tᵀ)/|a|.

The distal tip mass is the one-segment model's point mass at the tool offset.  Hence, with M = diag(M_k),

    T = ½ żᵀ M_z(z) ż,   M_z = Jᵀ M J + Σ_caps Sᵀ (m J_cᵀ J_c + I Dᵀ D) S + (tip mass)      (mass_matrix)

S selecting segment k's last node from z (it is a free node: the cap's terms are plain blocks of M_z).

**Equations of motion.**  The map Φ is nonlinear (the cap turns with t), so M_z depends on z.  Lagrange's
equations of T − Π give, because M is constant,

    Jᵀ M q̈ + Σ_bodies (inertia forces) + ∇_z Π = 0,     q̈ = J z̈ + Φ''[ż, ż],

the velocity term being the second derivative of the map along ż (only segment k + 1's first node has one):

    r̈₀ = r̈ + h (D ä + ∇²t[ȧ, ȧ]),   ä₀ = μ̈ t + 2 μ̇ D ȧ + μ (D ä + ∇²t[ȧ, ȧ])  ("free"),   ä₀ = ä  ("continuous"),
    ∇²t[u, u] = −[2 (t·u)(u − t (t·u)) + t (|u|² − (t·u)²)] / |a|².

A cap's mass gives m J_cᵀ p̈_c with p̈_c = J_c ẍ + c ∇²t[ȧ, ȧ] (the kernel of the one-segment tool-point mass,
:func:`ancf.dynamics.mass.tool_point_inertia`), its rotary inertia I Dᵀ ẗ, ẗ = D ä + ∇²t[ȧ, ȧ].  Every term is
a force Jᵀ(M·acceleration) of a body whose accelerations are exact, so the equations conserve T + Π (tested: the
energy of an undamped run drifts at the integrator's O(h²) only).  The Newton matrix of a step is exact: the
mass M_z, and the derivatives of the velocity terms by the complex step (∂/∂z and ∂/∂ż of q̈₀; the part
(∂Jᵀ/∂z) M q̈ is the junction curvature of :func:`ancf.chain_junction.curvature` with g = (M q̈)₀).

**Modes** about an equilibrium z* (velocities and accelerations zero, so every velocity term and ∂(M_z z̈)/∂z
vanish): M_z(z*) δz̈ + H δz = 0, H = ∇²_z Π at the equilibrium's loads (tensions held; pressures, tip force and
gravity dead loads); the taut tendons of a locked equilibrium as the constraints J_A δz = 0 (rigid tendons:
the chain has no elastic ones), solved on null(J_A) as :func:`ancf.dynamics.modes`.
"""

from __future__ import annotations

import math
import time as _time
import warnings
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from . import chain_junction as junction
from .dynamics.damping import UndampedWarning
from .dynamics.integrator import AlphaCoefficients, StepFailed, StepState, alpha_step
from .dynamics.mass import consistent_mass, tool_point_inertia
from .dynamics.modes import EQ_RTOL, lowest_modes, strain_energy_split
from .errors import (
    CollapsedStateError,
    ConvergenceError,
    InputError,
    UnstableEquilibriumError,
    check_finite,
    check_scalar,
)

_I3 = np.eye(3)


# ------------------------------------------------------------------------------------------------ kinematics
def _frame(a):
    """(t (3,), |a|, D = (I − t tᵀ)/|a| (3, 3)) of a slope a (3,) (complex-safe)."""
    lam = np.sqrt(a @ a)
    t = a / lam
    return t, lam, (_I3 - t[:, None] * t[None, :]) / lam


def _t_second(a, u):
    """∇²t[u, u] (3,) of t = a/|a| along u (3,) (module docstring; complex-safe)."""
    t, lam, _ = _frame(a)
    tu = t @ u
    return -(2.0 * tu * (u - t * tu) + t * (u @ u - tu * tu)) / (lam * lam)


def _node_acceleration(a, mu, va, vmu, xr, xa, xmu, h: float, continuous: bool):
    """Segment k + 1's first-node acceleration q̈₀ (6,) from segment k's last node (slope a, velocities va,
    accelerations xr, xa), the base stretch μ, μ̇, μ̈ and the cap length h [m] (module docstring)."""
    t, _, D = _frame(a)
    tdd = D @ xa + _t_second(a, va)
    r0 = xr + h * tdd
    a0 = xa if continuous else xmu * t + 2.0 * vmu * (D @ va) + mu * tdd
    return np.concatenate([r0, a0])


def _node_acceleration_tangents(a, mu, va, vmu, xr, xa, xmu, h, continuous):
    """(∂q̈₀/∂(r, a, μ) (6, 7), ∂q̈₀/∂(ṙ, ȧ, μ̇) (6, 7)) by the complex step (exact to round-off; r and ṙ do
    not enter, the velocity columns of ṙ are zero)."""
    eps = 1e-30
    Dx, Dv = np.zeros((6, 7)), np.zeros((6, 7))
    base = [np.asarray(v, complex) for v in (a, [mu], va, [vmu])]
    cols = ((0, Dx, 3), (1, Dx, 6), (2, Dv, 3), (3, Dv, 6))
    for which, out, col0 in cols:
        for j in range(base[which].size):
            args = [b.copy() for b in base]
            args[which][j] += 1j * eps
            acc = _node_acceleration(args[0], args[1][0], args[2], args[3][0], xr, xa, xmu, h, continuous)
            out[:, col0 + j] = acc.imag / eps
    return Dx, Dv


def _rotary_force(a, va, xa, inertia: float):
    """I Dᵀ ẗ (3,) on the slope a of a body whose rotation follows t = a/|a| (module docstring; complex-safe)."""
    _, _, D = _frame(a)
    return inertia * (D.T @ (D @ xa + _t_second(a, va)))


def _rotary_tangents(a, va, xa, inertia: float):
    """(∂(I Dᵀẗ)/∂a (3, 3), ∂/∂ȧ (3, 3)) by the complex step."""
    eps = 1e-30
    Da, Dv = np.zeros((3, 3)), np.zeros((3, 3))
    for j in range(3):
        e = np.zeros(3, complex)
        e[j] = 1j * eps
        Da[:, j] = _rotary_force(a + e, va.astype(complex), xa, inertia).imag / eps
        Dv[:, j] = _rotary_force(a.astype(complex), va + e, xa, inertia).imag / eps
    return Da, Dv


# ------------------------------------------------------------------------------------------------ the bodies
@dataclass(frozen=True)
class _Body:
    """A rigid body on a free node of z: its slice start ``zi`` (the node's 6 coordinates z[zi:zi+6]), mass m
    [kg] at offset c [m] along t, transverse moment of inertia I [kg m²] about its centre of mass."""
    zi: int
    m: float
    c: float
    inertia: float


class ChainInertia:
    """The chain's constant mass data (module docstring): the segments' consistent masses M (ndof, ndof) [kg],
    the rigid bodies (caps, the distal tip mass) and the junctions."""

    def __init__(self, model, cap_inertia=None):
        sys = model.sys
        K = model.n_segments
        ci = np.zeros(K - 1) if cap_inertia is None else check_finite("cap_inertia", cap_inertia, (K - 1,))
        if np.any(ci < 0) or np.any(ci > 10.0):
            raise InputError("cap_inertia must be within 0 … 10 kg m² per cap (the transverse moment of inertia "
                             "about the cap's centre of mass)")
        self.model, self.sys, self.cap_inertia = model, sys, ci
        self.M = np.zeros((sys.ndof, sys.ndof))
        for s in sys.segments:
            self.M[s.qo:s.qo + s.ndof, s.qo:s.qo + s.ndof] = consistent_mass(s.params.n_elements, s.N, s.wq,
                                                                             s.params.line_mass)
        bodies = []
        for k, s in enumerate(sys.segments):
            zi = s.zo + s.nz - 6
            if k < K - 1:
                cap = model.chain.caps[k]
                if cap.mass > 0 or ci[k] > 0:
                    bodies.append(_Body(zi, cap.mass, cap.mass_offset, float(ci[k])))
            elif s.params.tip_mass > 0:
                bodies.append(_Body(zi, s.params.tip_mass, s.params.tool_offset, 0.0))
        self.bodies = tuple(bodies)

    def _body_block(self, b: _Body, z: np.ndarray) -> np.ndarray:
        """(6, 6) [kg, kg m] m J_cᵀ J_c + I Dᵀ D of body b at z."""
        _, _, D = _frame(z[b.zi + 3:b.zi + 6])
        Jc = np.hstack([_I3, b.c * D])
        B = b.m * Jc.T @ Jc
        B[3:, 3:] += b.inertia * D.T @ D
        return B

    def mass_matrix(self, z: np.ndarray) -> np.ndarray:
        """M_z (nz, nz) [kg, …] at z (module docstring)."""
        J = self.sys.jacobian(z)
        Mz = J.T @ self.M @ J
        for b in self.bodies:
            Mz[b.zi:b.zi + 6, b.zi:b.zi + 6] += self._body_block(b, z)
        return 0.5 * (Mz + Mz.T)

    def kinetic_energy(self, z: np.ndarray, v: np.ndarray) -> float:
        """½ żᵀ M_z ż [J] at (z, ż)."""
        return 0.5 * float(v @ self.mass_matrix(z) @ v)

    def _junction(self, k: int, z, v, acc):
        """(z columns of junction k (6 or 7), has μ, args of :func:`_node_acceleration`)."""
        sys = self.sys
        s = sys.segments[k]
        _, a, h, mu = sys._junction_args(z, k)
        _, va, _, vmu = sys._junction_args(v, k)
        xr, xa, _, xmu = sys._junction_args(acc, k)
        has_mu = sys._has_mu(k)
        if not has_mu:
            vmu = xmu = 0.0
        cols = np.arange(s.zo - 6, s.zo + (1 if has_mu else 0))
        return cols, has_mu, (a, mu, va, vmu, xr, xa, xmu, h, sys.continuous)

    def inertia_force(self, z: np.ndarray, v: np.ndarray, acc: np.ndarray):
        """The generalized inertia force f (nz,) [N, N m] at (z, ż, z̈) and its exact derivatives: (f,
        M_z = ∂f/∂z̈, K_i = ∂f/∂z, C_i = ∂f/∂ż) (module docstring)."""
        sys, nz = self.sys, self.sys.nz
        J = sys.jacobian(z)
        qdd = J @ acc
        Kt, Ct = np.zeros((nz, nz)), np.zeros((nz, nz))
        parts = []
        for k in range(1, len(sys.segments)):
            s = sys.segments[k]
            cols, has_mu, args = self._junction(k, z, v, acc)
            qdd[s.qo:s.qo + 6] = _node_acceleration(*args)
            parts.append((s, cols, has_mu, args))
        G = self.M @ qdd
        f = J.T @ G
        JM = J.T @ self.M
        for s, cols, has_mu, args in parts:
            Dx, Dv = _node_acceleration_tangents(*args)
            w = len(cols)
            Kt[:, cols] += JM[:, s.qo:s.qo + 6] @ Dx[:, :w]
            Ct[:, cols] += JM[:, s.qo:s.qo + 6] @ Dv[:, :w]
            a, mu, h = args[0], args[1], args[7]
            Kt[np.ix_(cols, cols)] += junction.curvature(G[s.qo:s.qo + 6], a, h, mu, sys.continuous)[:w, :w]
        Mz = J.T @ self.M @ J
        for b in self.bodies:
            self._add_body(b, z, v, acc, f, Mz, Kt, Ct)
        return f, 0.5 * (Mz + Mz.T), Kt, Ct

    def _add_body(self, b: _Body, z, v, acc, f, Mz, Kt, Ct) -> None:
        """Body b's inertia force and its derivatives added in place (module docstring)."""
        i = b.zi
        a, va, xr, xa = z[i + 3:i + 6], v[i + 3:i + 6], acc[i:i + 3], acc[i + 3:i + 6]
        sl = slice(i, i + 6)
        if b.m > 0:
            fi, Ds, Dv, B = tool_point_inertia(np.ascontiguousarray(a), np.ascontiguousarray(va),
                                               np.ascontiguousarray(xr), np.ascontiguousarray(xa), b.c, b.m)
            f[sl] += fi
            Mz[sl, sl] += B
            Kt[sl, i + 3:i + 6] += Ds
            Ct[sl, i + 3:i + 6] += Dv
        if b.inertia > 0:
            _, _, D = _frame(a)
            f[i + 3:i + 6] += _rotary_force(a, va, xa, b.inertia)
            Mz[i + 3:i + 6, i + 3:i + 6] += b.inertia * D.T @ D
            Da, Dva = _rotary_tangents(a, va, xa, b.inertia)
            Kt[i + 3:i + 6, i + 3:i + 6] += Da
            Ct[i + 3:i + 6, i + 3:i + 6] += Dva


def inertia(model, cap_inertia=None) -> ChainInertia:
    """The :class:`ChainInertia` of ``model`` (cached per cap_inertia)."""
    key = None if cap_inertia is None else tuple(np.asarray(cap_inertia, float).ravel().tolist())
    cache = model.__dict__.setdefault("_inertia_cache", {})
    if key not in cache:
        cache[key] = ChainInertia(model, cap_inertia)
    return cache[key]


def mass_matrix(model, z, cap_inertia=None) -> np.ndarray:
    """M_z (nz, nz) at free coordinates z (nz,): T = ½ żᵀ M_z ż [J] (module docstring).  ``cap_inertia``
    (K − 1,) [kg m²]: each cap's transverse moment of inertia about its centre of mass (default 0)."""
    z = check_finite("z", z, (model.nz,))
    if not model.sys._junctions_ok(z):
        raise InputError("z is outside the model's domain (a degenerate segment end slope or base stretch)")
    return inertia(model, cap_inertia).mass_matrix(z)


# ------------------------------------------------------------------------------------------------ modes
@dataclass
class ChainModalResult:
    """frequencies [Hz] (k,), ascending; omega2 [1/s²] (k,); shapes_z (k, nz) in the free coordinates,
    mass-normalised (φᵀ M_z φ = 1 [kg]); shapes (k, ndof) the same in full coordinates (δq = J δz); tip_shapes
    (k, 3) [m] the tool point's motion; locked: the tendons held as constraints; axial_share (k,) [-] the share
    of each mode's strain energy in axial stretch, summed over the segments (:func:`ancf.dynamics.modes.
    strain_energy_split`; the caps are rigid).  No damping ratios: the chain's damping is not modelled in
    ``modes``."""
    frequencies: np.ndarray
    omega2: np.ndarray
    shapes_z: np.ndarray
    shapes: np.ndarray
    tip_shapes: np.ndarray
    locked: tuple
    axial_share: np.ndarray

    @property
    def kinds(self) -> tuple:
        """Per mode "axial" (axial share > ½) or "bending"."""
        return tuple("axial" if s > 0.5 else "bending" for s in self.axial_share)

    @property
    def frequencies_hz(self) -> np.ndarray:
        return self.frequencies


def check_equilibrium(model, eq, what: str) -> None:
    """InputError unless ``eq`` is an equilibrium of this chain: a ChainEquilibrium of its size, q = Φ(z), and a
    free generalized-force residual under its own loads ‖∇_z Π‖ ≤ EQ_RTOL · max(‖∇Π_body‖, ‖∇Π_loads‖)
    + 10 · default_tol (as :func:`ancf.dynamics.modes.check_equilibrium`; body: elastic and gravity, loads:
    tendons, pressures, tip force)."""
    from .chain_model import ChainEquilibrium
    if not isinstance(eq, ChainEquilibrium):
        raise InputError(f"{what}: needs an equilibrium of this chain (ChainModel.fk / fk_locked), got "
                         f"{type(eq).__name__}")
    if np.shape(eq.z) != (model.nz,) or np.size(eq.tensions) != model.m or np.size(eq.pressures) != model.n_segments:
        raise InputError(f"{what}: the equilibrium has {np.size(eq.z)} free coordinates, {np.size(eq.tensions)} "
                         f"tensions and {np.size(eq.pressures)} pressures but this chain has {model.nz}, {model.m} "
                         f"and {model.n_segments}: it belongs to another actuator")
    z = check_finite(f"{what}: eq.z", eq.z, (model.nz,))
    sys = model.sys
    E, g, _, _, _ = sys.evaluate(z, eq.tensions, eq.pressures, eq.tip_force, hessian=False)
    if not np.isfinite(E) or np.shape(eq.q) != (sys.ndof,) or \
            not np.allclose(eq.q, sys.to_full(z), rtol=0, atol=1e-12 * max(1.0, float(np.abs(eq.q).max()))):
        raise InputError(f"{what}: the state is outside this chain's domain or its q is not the cap map of its z")
    gb = sys.evaluate(z, np.zeros(model.m), np.zeros(model.n_segments), np.zeros(3), hessian=False)[1]
    res = float(np.linalg.norm(g))
    scale = max(float(np.linalg.norm(gb)), float(np.linalg.norm(g - gb)))
    if not res <= EQ_RTOL * scale + 10.0 * model.default_tol:
        raise InputError(f"{what}: the state is not an equilibrium of this chain under its loads (force residual "
                         f"{res:.3g} N = {res / max(scale, 1e-300):.2g} of the forces at the state, allowed "
                         f"{EQ_RTOL:g}): pass an equilibrium this chain solved (fk, fk_locked)")


def modes(model, eq, count: int = 6, cap_inertia=None) -> ChainModalResult:
    """The ``count`` lowest vibration modes of the chain about its equilibrium ``eq`` (module docstring).
    InputError for a count out of range, a segment without line mass, or a state that is not an equilibrium
    of this chain; UnstableEquilibriumError about an unstable one."""
    if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or not 1 <= count <= model.nz:
        raise InputError(f"count must be an integer 1…{model.nz} (the free coordinates), got {count!r}")
    for k, s in enumerate(model.chain.segments):
        if not s.line_mass > 0:
            raise InputError(f"segment {k + 1}: modes need its line mass (line_mass > 0 kg/m): without it the "
                             "mass matrix is singular")
    check_equilibrium(model, eq, "modes")
    if not eq.stable:
        raise UnstableEquilibriumError("modes about an unstable equilibrium (a saddle has no vibration modes)",
                                       solver="modes", min_eigenvalue=float("nan"))
    sys, z = model.sys, np.asarray(eq.z, float)
    _, _, H, _, Jl = sys.evaluate(z, eq.tensions, eq.pressures, eq.tip_force, hessian=True, lengths=2)
    K, Mz = 0.5 * (H + H.T), inertia(model, cap_inertia).mass_matrix(z)
    A = tuple(int(i) for i in (eq.active or ()))
    Z = None
    if A:
        Z = np.linalg.qr(Jl[list(A)].T, mode="complete")[0][:, len(A):]
        K, Mz = Z.T @ K @ Z, Z.T @ Mz @ Z
    w2, phi = lowest_modes(K, Mz, count)
    dz = (phi if Z is None else Z @ phi).T                                         # (k, nz)
    shapes = dz @ sys.jacobian(z).T
    return ChainModalResult(np.sqrt(w2) / (2 * np.pi), w2, dz, shapes, dz @ sys.tip_jacobian(z).T, A,
                            _axial_share(model, eq, shapes))


def _axial_share(model, eq, shapes: np.ndarray) -> np.ndarray:
    """(k,) U_A / (U_A + U_B) of each full-coordinate shape, the strain energies summed over the segments."""
    from types import SimpleNamespace
    sys, U = model.sys, np.zeros((len(shapes), 2))
    for k, s in enumerate(sys.segments):
        seg = SimpleNamespace(params=s.params, n=s.params.n_elements, _N=s.N, _wq=s.wq)
        sl = slice(s.qo, s.qo + s.ndof)
        U += strain_energy_split(seg, eq.q[sl], shapes[:, sl], float(eq.pressures[k]))
    tot = U.sum(axis=1)
    return np.divide(U[:, 0], tot, out=np.zeros(len(U)), where=tot > 0)


# ------------------------------------------------------------------------------------------------ simulate
@dataclass
class ChainSimulation:
    """A transient run of a chain; rows are output times.  t (N,) [s]; z, v (N, nz) free coordinates and
    velocities; q (N, ndof) full coordinates; tip (N, 3) [m]; kinetic, potential, energy = kinetic + potential,
    dissipated (N,) [J] (energy + dissipated is conserved up to the integrator's error; dissipated is the
    trapezoidal sum of żᵀ C ż); newton_iterations (N,); tensions (m,) [N], pressures (K,) [Pa], tip_force (3,)
    [N] (constant loads); dt [s]; damping {alpha [1/s], beta [s]}; rho_inf; events (step halvings);
    wall_time [s]."""
    t: np.ndarray
    z: np.ndarray
    v: np.ndarray
    q: np.ndarray
    tip: np.ndarray
    kinetic: np.ndarray
    potential: np.ndarray
    energy: np.ndarray
    dissipated: np.ndarray
    newton_iterations: np.ndarray
    tensions: np.ndarray
    pressures: np.ndarray
    tip_force: np.ndarray
    dt: float
    damping: dict
    rho_inf: float
    events: list
    wall_time: float


#: most time steps of one chain run
MAX_STEPS = 1_000_000


def _damping(model, damping, K0, M0) -> dict:
    """{alpha, beta} of a run: None — the segments' Rayleigh coefficients (equal in every segment), a dict
    {alpha [1/s], beta [s]}, or a ratio ζ of the first mode about the start (β = 2ζ/ω₁)."""
    segs = model.chain.segments
    if damping is None:
        if any(s.axial_damping for s in segs):
            raise InputError("the chain's simulate has no axial (Kelvin–Voigt) damping yet: pass damping= "
                             "{'alpha': …, 'beta': …} or a ratio")
        coeffs = {(s.rayleigh_alpha, s.rayleigh_beta) for s in segs}
        if len(coeffs) > 1:
            raise InputError("the segments state different Rayleigh coefficients; the chain's simulate takes one "
                             "pair: pass damping={'alpha': …, 'beta': …}")
        alpha, beta = coeffs.pop()
        if not (alpha or beta):
            warnings.warn(UndampedWarning(f"the chain '{model.chain.name}' states no damping and none was given: "
                                          "the run is undamped apart from the integrator's numerical dissipation "
                                          "(rho_inf < 1)"), stacklevel=3)
        return {"alpha": float(alpha), "beta": float(beta)}
    if isinstance(damping, dict):
        unknown = set(damping) - {"alpha", "beta"}
        if unknown:
            raise InputError(f"damping: unknown keys {sorted(unknown)}; use alpha [1/s], beta [s]")
        return {k: check_scalar(f"damping[{k!r}]", damping.get(k, 0.0), low=0.0, high=1e6) for k in ("alpha", "beta")}
    zeta = check_scalar("damping", damping, low=0.0, high=1.0)
    if zeta == 0.0:
        return {"alpha": 0.0, "beta": 0.0}
    w2 = sla.eigh(K0, M0, eigvals_only=True, subset_by_index=[0, 0])[0]
    if not w2 > 0:
        raise InputError("damping given as a ratio needs a stable start state; give {'alpha', 'beta'}")
    return {"alpha": 0.0, "beta": 2.0 * zeta / math.sqrt(w2)}


def _start(model, z0, v0, T, pr, F, check_limits):
    """(z (nz,), ż (nz,)) at t = 0: an equilibrium of this chain (checked), an admissible z, or None (the
    equilibrium of the run's loads); v0 default 0."""
    from .chain_model import ChainEquilibrium
    if isinstance(z0, ChainEquilibrium):
        check_equilibrium(model, z0, "simulate: z0")
        z0 = z0.z
    if z0 is None:
        z0 = model.fk(T, pr, F, check_limits=check_limits).z
    z = model._z0(z0)
    v = np.zeros(model.nz) if v0 is None else check_finite("v0", v0, (model.nz,))
    return np.array(z, float), np.array(v, float)


def _system(model, inert: ChainInertia, T, pr, F, C, loads):
    """The integrator's system (:func:`ancf.dynamics.integrator.alpha_step`): (z, ż, z̈) → (residual, M, K_t,
    C_t, force scale)."""
    sys = model.sys
    scale = max(abs(float(s.stiffness.EA(1.0))) for s in model.chain.segments) * 1e-3 + \
        sum(abs(float(s.line_mass)) * 9.81 * s.length for s in model.chain.segments)

    def system(z, v, acc):
        E, g, H, _, _ = sys.evaluate(z, T, pr, F, hessian=True, loads=loads)
        if not np.isfinite(E):
            raise StepFailed("the state left the model's domain")
        f, Mz, Ki, Ci = inert.inertia_force(z, v, acc)
        return f + g + C @ v, Mz, H + Ki, Ci + C, scale + float(np.linalg.norm(Mz @ acc))
    return system


def simulate(model, t_end: float, dt: float, z0=None, v0=None, *, tensions=None, pressures=None,
             tip_force=(0.0, 0.0, 0.0), damping=None, rho_inf: float = 0.9, cap_inertia=None,
             check_limits: bool = True, max_halvings: int = 8, max_iter: int = 12) -> ChainSimulation:
    """Transient response of the chain under constant loads over [0, t_end] [s], output every ``dt`` [s]
    (generalized-α, :mod:`ancf.dynamics.integrator`, the same step and Newton tolerances as
    :meth:`ancf.Model.simulate`; a failed step is halved up to ``max_halvings`` times).  tensions (m,) [N],
    pressures (K,) [Pa], tip_force (3,) [N]; z0: a ChainEquilibrium of this chain, an admissible z (nz,), or None
    (the equilibrium of the loads); v0 (nz,) the start velocities (default 0)."""
    wall0 = _time.perf_counter()
    t_end = check_scalar("t_end", t_end, low=0.0, unit="s")
    dt = check_scalar("dt", dt, low=0.0, unit="s")
    rho_inf = check_scalar("rho_inf", rho_inf, low=0.0, high=1.0)
    if not (t_end > 0 and dt > 0) or t_end / dt > MAX_STEPS:
        raise InputError(f"t_end and dt must be > 0 with at most {MAX_STEPS} steps (t_end / dt)")
    if isinstance(max_halvings, bool) or not isinstance(max_halvings, int) or not 0 <= max_halvings <= 20:
        raise InputError(f"max_halvings must be an integer 0 … 20, got {max_halvings!r}")
    pressures = np.zeros(model.n_segments) if pressures is None else pressures
    T, pr, F = model._check_inputs(tensions, pressures, tip_force, check_limits)
    z, v = _start(model, z0, v0, T, pr, F, check_limits)
    inert = inertia(model, cap_inertia)
    loads = model.sys.loads(T, pr, F)
    E0, _, H0, _, _ = model.sys.evaluate(z, T, pr, F, hessian=True, loads=loads)
    if not np.isfinite(E0):
        raise InputError("z0 is outside the model's domain")
    M0 = inert.mass_matrix(z)
    coeffs = _damping(model, damping, 0.5 * (H0 + H0.T), M0)
    C = coeffs["alpha"] * M0 + coeffs["beta"] * 0.5 * (H0 + H0.T)
    system = _system(model, inert, T, pr, F, C, loads)
    r0, Mm, _, _, _ = system(z, v, np.zeros(model.nz))
    acc = -np.linalg.solve(Mm, r0)
    n = math.ceil(t_end / dt - 1e-9)
    h = t_end / n
    rows = _integrate(model, inert, system, StepState(z, v, acc, acc.copy()), h, n, rho_inf, max_halvings,
                      max_iter, C, (T, pr, F, loads))
    return ChainSimulation(**rows, tensions=T, pressures=pr, tip_force=F, dt=h, damping=coeffs, rho_inf=rho_inf,
                           wall_time=_time.perf_counter() - wall0)


def _integrate(model, inert, system, st: StepState, h, n, rho_inf, max_halvings, max_iter, C, loads) -> dict:
    """The time loop: n output steps of size h, each in substeps halved on failure (events; four good substeps
    undo one halving); rows as a dict of :class:`ChainSimulation`'s arrays."""
    sys, coeff = model.sys, AlphaCoefficients.from_rho(rho_inf)
    T, pr, F, ld = loads
    out = {k: [] for k in ("t", "z", "v", "kinetic", "potential", "newton_iterations")}
    events, level, good = [], 0, 0

    def record(t, st, it):
        out["t"].append(t)
        out["z"].append(st.z.copy())
        out["v"].append(st.v.copy())
        out["kinetic"].append(inert.kinetic_energy(st.z, st.v))
        out["potential"].append(sys.evaluate(st.z, T, pr, F, hessian=False, loads=ld)[0])
        out["newton_iterations"].append(it)
    record(0.0, st, 0)
    for i in range(n):
        tt, t_target, its = i * h, (i + 1) * h, 0
        while t_target - tt > 1e-12 * h:
            hh = min(h / 2 ** level, t_target - tt)
            try:
                st, k = alpha_step(st, hh, coeff, system, rtol=1e-14, atol=0.0, vtol=1e-7, max_iter=max_iter)
            except StepFailed as exc:
                if level >= max_halvings:
                    err = CollapsedStateError if "domain" in exc.reason else ConvergenceError
                    kw = {"stretch": float("nan")} if err is CollapsedStateError else \
                        {"iterations": exc.iterations, "residual_norm": exc.residual, "tolerance": 0.0}
                    raise err(f"simulate: at t = {tt + hh:.6g} s the step did not converge even halved {level} "
                              f"times: {exc.reason}", solver="simulate", **kw) from None
                level, good = level + 1, 0
                events.append({"t": tt, "kind": "subdivided", "text": f"step halved to {h / 2 ** level:.3g} s"})
                continue
            tt, its, good = tt + hh, its + k, good + 1
            if level and good >= 4:                      # four good substeps undo one halving
                level, good = level - 1, 0
        record(t_target, st, its)
    rows = {k: np.array(v) for k, v in out.items()}
    rows["q"] = np.array([sys.to_full(z) for z in rows["z"]])
    rows["tip"] = np.array([sys.tip(z) for z in rows["z"]])
    rows["energy"] = rows["kinetic"] + rows["potential"]
    pw = np.einsum("ni,ij,nj->n", rows["v"], C, rows["v"])
    rows["dissipated"] = np.concatenate([[0.0], np.cumsum(0.5 * (pw[1:] + pw[:-1]) * np.diff(rows["t"]))])
    rows["events"] = events
    return rows
