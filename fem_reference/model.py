r"""The bellows model: mesh + material + loads + rigid caps + Newton with load stepping.

Reduced unknowns ``q = [free nodal displacements (3 n_free), u_c (3), θ (3)]`` (see
:mod:`fem_reference.loads.caps`).  With ``λ ∈ [0, 1]`` the load parameter of a solve, every load is
ramped linearly from its starting value (zero, or the loads of ``initial``) to its target:

.. math::

    r_q(q) = P^T\big(f^{int}(u) - f^{p}(u; p) - s_g f^g\big)
             - J_{tip}^T F_{tip} - J_{com}^T m_{cap} g - J_c^T\,p A_{cap} R e_x
             + \sum_i T_i\,\partial L_i/\partial q = 0,

with ``s_g`` = 1 when gravity is on, and for a locked tendon the extra equation ``L_i(q) = L_{0,i}``
with ``T_i`` unknown (``T_i ≥ 0``; a cable whose multiplier would become negative goes slack).
With tendon friction (``solve(friction=μ)``) the tendon term is ``Σ_s T_is ∂ℓ_is/∂q`` over the segments
between the guides, the tensions from the capstan law with history (:mod:`fem_reference.loads.tendon_friction`).
The Newton matrix is the exact derivative of ``r_q`` (internal tangent, follower-pressure load
stiffness, cap pressure follower term, tendon Hessians and every rigid-link geometric term), so
Newton converges quadratically (tested).

Tip compliance (3×3, ``δp_tip = C δF_tip``) from the same tangent:

- ``mode="tension"`` (tensions held): :math:`C = J_p K_q^{-1} J_p^T`;
- ``mode="locked"`` (taut tendons at fixed length; multipliers change):
  :math:`C' = J_p\,[K^{-1} - K^{-1} g (g^T K^{-1} g)^{-1} g^T K^{-1}]\,J_p^T`
  over the taut tendons (``T > 0``).  Direction-dependent slackening under the perturbation is not
  modelled (it is a linearisation about the loaded state).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp

from .errors import (
    ConfigError,
    ConvergenceError,
    InputError,
    LimitError,
    UnstableEquilibriumError,
    check_finite,
)

from .assembly import KERNELS, HexAssembler, check_element, PressureAssembler, gravity_load
from .corotation import ring_rotation_correction
from .geometry import BellowsGeometry, e_radial
from .loads.caps import (
    RigidCapReduction,
    expm_so3,
    point_geometric,
    point_jacobian,
)
from .loads.contact import ContactTerms, contact_terms, default_stiffness, flank_pairs
from .loads.gravity import cap_weight
from .loads.pressure import cap_pressure_force
from .loads.tendon_friction import (
    FemTensionCycle,
    FrictionLaw,
    FrictionProfile,
    friction_block,
    loop_area,
    tension_profile,
    weighted_gradient,
    wrap_angles,
)
from .loads.tendons import (
    TendonPath,
    guide_hessian,
    guide_point,
    polyline_gradient,
    polyline_hessian_blocks,
    polyline_length,
)
from .material import Material
from .mesh import BellowsMesh, build_mesh
from .sparse_keys import csr_index, unique_keys
from .solver import NewtonStats, StepFailed, available_solvers, bordered_step, factorize, symmetric_inertia
from .symmetry import check_symmetry_flag, subspace_for

if TYPE_CHECKING:  # pragma: no cover
    from .results import BellowsResult

__all__ = ["BellowsModel", "LoadCase", "OperatingLimits", "State"]

G_DEFAULT = (0.0, 0.0, -9.81)


@dataclass(frozen=True)
class OperatingLimits:
    """The loads a solve accepts without being told otherwise (``solve(check_limits=False)``, CLI
    ``--no-limits``).  Defaults: the paper actuator's operating range (0–120 kPa, tendon tensions up to
    5 N) with margin, so that a unit slip (a pressure in Pa written as kPa, 30 000 kPa) is rejected in a
    millisecond instead of failing after minutes of load steps.

    pressure_min, pressure_max [Pa]; tension_max [N] per tendon; tip_force_max [N] (magnitude);
    locked_stretch (lo, hi): locked cable lengths as a fraction of the undeformed cable length.
    """
    pressure_min: float = -50e3
    pressure_max: float = 200e3
    tension_max: float = 20.0
    tip_force_max: float = 10.0
    locked_stretch: tuple[float, float] = (0.6, 1.5)

    def check_loads(self, tensions, pressure: float, tip_force, locked=None) -> None:
        """Raise :class:`~ancf.errors.LimitError` naming the first of tension [N] (m,), pressure [Pa] and tip
        force [N] (3,) outside the limits (``locked``: boolean mask of locked tendons, whose tension is
        not an input)."""
        how = "check_limits=False analyses it anyway"
        if not self.pressure_min <= pressure <= self.pressure_max:
            raise LimitError(f"pressure {pressure / 1e3:g} kPa is outside the FEM model's operating limits "
                             f"[{self.pressure_min / 1e3:g}, {self.pressure_max / 1e3:g}] kPa ({how})")
        T = np.asarray(tensions, float)
        free = np.ones(T.size, bool) if locked is None else ~np.asarray(locked, bool)
        over = np.flatnonzero(free & (T > self.tension_max))
        if over.size:
            k = int(over[0])
            raise LimitError(f"tension T{k + 1} = {T[k]:g} N is above the FEM model's operating limit "
                             f"{self.tension_max:g} N ({how})")
        fn = float(np.linalg.norm(tip_force))
        if fn > self.tip_force_max:
            raise LimitError(f"tip force |F| = {fn:g} N is above the FEM model's operating limit "
                             f"{self.tip_force_max:g} N ({how})")

    def check(self, lc: "LoadCase", cable_lengths: np.ndarray) -> None:
        """:meth:`check_loads` for a load case, plus locked cable lengths against ``locked_stretch``."""
        how = "check_limits=False analyses it anyway"
        locked = ~np.isnan(lc.locked_lengths)
        self.check_loads(lc.tensions, lc.pressure, lc.tip_force, locked)
        lo, hi = self.locked_stretch
        for k in np.flatnonzero(locked):
            ratio = lc.locked_lengths[k] / cable_lengths[k]
            if not lo <= ratio <= hi:
                raise LimitError(f"locked length {lc.locked_lengths[k] * 1e3:g} mm of tendon {k + 1} is "
                                 f"{ratio:.2f} × its undeformed length {cable_lengths[k] * 1e3:g} mm, outside "
                                 f"the operating range [{lo:g}, {hi:g}] ({how})")


@dataclass
class LoadCase:
    """Loads of one equilibrium (SI).

    tensions : (m,) [N]; pressure [Pa]; tip_force (3,) [N]; gravity : 0..1 scale of the dead weight;
    locked_lengths : (m,) [m] with NaN for tendons at prescribed tension; friction : the tendons' capstan law
    and history (:class:`~fem_reference.loads.tendon_friction.FrictionLaw`), None: frictionless.
    """

    tensions: np.ndarray
    pressure: float
    tip_force: np.ndarray
    gravity: float
    locked_lengths: np.ndarray
    friction: FrictionLaw | None = None

    def lerp(self, other: LoadCase, lam: float) -> LoadCase:
        a = lambda x, y: x + lam * (y - x)
        ll = np.where(np.isnan(other.locked_lengths), np.nan,
                      a(np.nan_to_num(self.locked_lengths, nan=0.0), other.locked_lengths))
        return LoadCase(a(self.tensions, other.tensions), a(self.pressure, other.pressure),
                        a(self.tip_force, other.tip_force), a(self.gravity, other.gravity), ll, other.friction)


#: Newton iterations after which a load step whose residual is still above its starting value is cut back
#: (measured on the default design: converging steps are below their start after two iterations; failing ones
#: crawled for all of max_iter = 25 iterations, half the factorisations of a solve)
STALL_ITERATIONS = 4
#: a load step whose residual after two Newton iterations is above this multiple of its start is cut at once
#: (measured on the default design's sweep: in a converging step the full first iterate overshoots ×100–400 —
#: rotation-induced stretch of the thin wall — and the second is back at 0.3–1.5× the start; the steps that went
#: on to fail were at ×350–1900 after two iterations and took two more factorisations to be cut)
EARLY_CUT_RATIO = 30.0
#: initial load increments: one more per this tension difference between tendons [N] (bending is what makes the
#: steps fail: measured on four cold bends of the default design, 163 factorisations against 194 with the former
#: rule — pressure and total tension only — 186 with 1 N, 169 with 0.25 N)
ASYMMETRY_STEP = 0.5
#: Newton updates turn each ring of nodes by a finite rotation (:mod:`fem_reference.corotation`; measured there)
RING_UPDATE = True
#: relative residual to which intermediate load steps are converged (the last step: the solve's rtol)
STEP_RTOL = 1e-2


def _check_progress(history: list[float], it: int) -> None:
    """StepFailed when the residual norms ``history`` [N] of a load step's Newton iterations ``0 … it`` show that
    it will not converge: diverging (×1e6 its smallest), still above :data:`EARLY_CUT_RATIO` × its start after two
    iterations, or above its start after :data:`STALL_ITERATIONS`.  The load step is then cut back."""
    rn = history[-1]
    if len(history) > 3 and rn > 1e6 * min(history):
        raise StepFailed("diverging", history, it)
    if it == 2 and rn > EARLY_CUT_RATIO * history[0]:
        raise StepFailed(f"not converging (residual ×{rn / history[0]:.0f} its start after 2 iterations)",
                         history, it)
    if it >= STALL_ITERATIONS and rn > history[0]:
        # a converging step is below its starting residual after two or three iterations (measured);
        # one that is not is crawling (halved steps, residual falling by a few % per iteration): cut
        # the load step now instead of spending max_iter factorisations on it
        raise StepFailed(f"not converging (residual above its start after {it} iterations)", history, it)


def _check_solve_options(*, max_iter, max_cuts, max_steps, rtol, atol, ltol, time_limit_s) -> None:
    """InputError naming the first of :meth:`BellowsModel.solve`'s iteration bounds (integers ≥ 1, cuts ≥ 0),
    tolerances (> 0) and time limit [s] (> 0 or None) that is out of range."""
    for name, v, lo in (("max_iter", max_iter, 1), ("max_cuts", max_cuts, 0), ("max_steps", max_steps, 1)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < lo:
            raise InputError(f"{name} must be an integer >= {lo}, got {v!r}")
    for name, v in (("rtol", rtol), ("atol", atol), ("ltol", ltol)):
        if not float(check_finite(name, v, ())) > 0:
            raise InputError(f"{name} must be > 0, got {v!r}")
    if time_limit_s is not None and not float(check_finite("time_limit_s", time_limit_s, ())) > 0:
        raise InputError(f"time_limit_s must be > 0 s, got {time_limit_s!r}")


@dataclass
class _LoadPath:
    """Progress of a solve's load parameter λ ∈ [0, 1]: adaptive increments (halved on a failed step, ×1.5 after
    a step of at most five iterations), and the bounds on increments tried and on time."""

    dlam: float
    t_start: float       # perf_counter() at the start of the solve [s]
    tolerance: float     # residual tolerance reported with a ConvergenceError [N]
    lam: float = 0.0
    cuts: int = 0        # increments cut back
    step: int = 0        # increments converged
    tried: int = 0       # increments tried (converged and cut back)

    def next_increment(self, stats: NewtonStats, max_steps: int, time_limit_s: float | None) -> float:
        """λ at the end of the next increment; ConvergenceError when more than ``max_steps`` increments were
        tried or ``time_limit_s`` [s] is exceeded."""
        self.tried += 1
        elapsed = time.perf_counter() - self.t_start
        if self.tried > max_steps or (time_limit_s is not None and elapsed > time_limit_s):
            why = (f"more than max_steps = {max_steps} load increments" if self.tried > max_steps
                   else f"more than time_limit_s = {time_limit_s:g} s")
            last = stats.steps[-1]["residuals"] if stats.steps else []
            raise ConvergenceError(
                f"load stepping stopped at λ = {self.lam:.4g} after {why} ({self.step} converged, {self.cuts} cut "
                f"back, {elapsed:.1f} s): the load is likely beyond what the structure carries; lower it or "
                f"raise the bound", solver="fem_newton", iterations=stats.n_iterations,
                residual_norm=last[-1] if last else np.nan, tolerance=self.tolerance, history=last)
        return min(1.0, self.lam + self.dlam)

    def cut_back(self, e: StepFailed, stats: NewtonStats, lam_t: float, max_cuts: int) -> None:
        """Record the failed increment to ``lam_t`` and halve the increment; ConvergenceError after more than
        ``max_cuts`` cut-backs."""
        stats.failed_steps.append(dict(lam=lam_t, reason=e.reason, residuals=list(e.history)))
        self.cuts += 1
        if self.cuts > max_cuts:
            raise ConvergenceError(
                f"load step λ {self.lam:.4g} → {lam_t:.4g} failed: {e.reason}; residual [N] per "
                f"iteration in .history", solver="fem_newton", iterations=e.iterations,
                residual_norm=e.history[-1] if e.history else np.nan,
                tolerance=self.tolerance, history=e.history) from None
        self.dlam *= 0.5

    def advance(self, lam_t: float, iterations: int) -> None:
        """Accept the converged increment to ``lam_t``; grow the next one if it took ≤ 5 iterations."""
        self.step += 1
        self.lam = lam_t
        if iterations <= 5:
            self.dlam = min(1.0, self.dlam * 1.5)


@dataclass
class State:
    """Configuration: full nodal displacements, cap translation and rotation, tendon tensions."""

    U: np.ndarray  # (3, n_nodes) [m]
    uc: np.ndarray  # (3,) [m]
    R: np.ndarray  # (3, 3)
    T: np.ndarray  # (m,) [N]  (multipliers for locked tendons)
    slack: np.ndarray  # (m,) bool — locked tendon currently slack

    def copy(self) -> State:
        return State(self.U.copy(), self.uc.copy(), self.R.copy(), self.T.copy(), self.slack.copy())


#: Accepted ``linear_solver`` names (a library's solver only where it is installed: :func:`available_solvers`).
LINEAR_SOLVERS = ("auto", "pardiso", "pardiso_no_reuse", "splu", "splu_partial_pivoting", "umfpack")


class BellowsModel:
    """3-D hyperelastic FE model of the bellows with rigid caps, pressure, tendons, gravity, tip load.

    Parameters
    ----------
    geometry : BellowsGeometry
    material : Material
    mesh : {"coarse", "medium", "reference"}, MeshLevel or BellowsMesh
    linear_solver : one of :data:`LINEAR_SOLVERS` ("auto": pardiso if installed, else splu)
    gravity_vector : (3,) [m/s²]
    limits : OperatingLimits
        Loads accepted by :meth:`solve` unless ``check_limits=False``.
    assembly_kernel : {"numba", "numpy"}
        Implementation of the hyperelastic assembly (:class:`~fem_reference.assembly.HexAssembler`): the
        compiled kernel (default) or the numpy reference; same results to round-off.
    element : {"mixed", "displacement"}
        The wall element (:data:`fem_reference.assembly.ELEMENTS`): ``"mixed"`` (default) — Hex27 with a
        discontinuous linear pressure per element, condensed (u–p, Q2/P1-disc; locking-free for the nearly
        incompressible wall); ``"displacement"`` — Hex27 alone, which over-stiffens bending of a thin wall at
        κ/μ ≫ 1 (``docs/fem.md`` §3).
    contact : bool
        Frictionless penalty contact between the facing outer flanks of adjacent convolutions
        (:mod:`fem_reference.loads.contact`); off by default (the flanks may then pass through each other:
        check :func:`fem_reference.contact.flank_gaps`).  While every gap is open the results are the same
        bit for bit either way.
    contact_stiffness : float, optional
        Penalty stiffness ``k_c`` [N/m³] (contact pressure per unit penetration); default
        :func:`~fem_reference.loads.contact.default_stiffness` (10 · 3 μ / wall thickness).
    """

    def __init__(self, geometry: BellowsGeometry, material: Material, mesh="coarse",
                 linear_solver: str = "auto", gravity_vector=G_DEFAULT, limits: OperatingLimits | None = None,
                 assembly_kernel: str = "numba", element: str = "mixed", *, contact: bool = False,
                 contact_stiffness: float | None = None):
        if not isinstance(geometry, BellowsGeometry) or not isinstance(material, Material):
            raise InputError(f"BellowsModel needs (BellowsGeometry, Material), got "
                             f"({type(geometry).__name__}, {type(material).__name__})")
        known = LINEAR_SOLVERS
        base = str(linear_solver).split("_")[0] if linear_solver != "splu_partial_pivoting" else "splu"
        if linear_solver not in known or (linear_solver != "auto" and base not in available_solvers()):
            raise ConfigError(f"linear solver {linear_solver!r} is not available here; choose one of "
                              f"{['auto'] + available_solvers()}")       # before minutes of meshing
        if assembly_kernel not in KERNELS:
            raise ConfigError(f"unknown assembly kernel {assembly_kernel!r}; choose one of {KERNELS}")
        check_element(element, material)
        self.element = element
        self.geometry = geometry
        self.material = material
        self.linear_solver = linear_solver
        self.g = check_finite("gravity_vector", gravity_vector, (3,))
        self.limits = OperatingLimits() if limits is None else limits
        t0 = time.perf_counter()
        self.bmesh = mesh if isinstance(mesh, BellowsMesh) else build_mesh(geometry, mesh)
        bm = self.bmesh
        self.asm = HexAssembler(bm.mesh, material, kernel=assembly_kernel, element=element)
        self.press = PressureAssembler(bm.mesh, bm.inner_facets(), self.asm.pattern, kernel=assembly_kernel)
        self.f_gravity = gravity_load(self.asm, material.density, self.g)
        n_s, n_t, n_th = bm.shape
        X = bm.X
        L = geometry.length
        self.X_c = np.array([L, 0.0, 0.0])
        self.caps = RigidCapReduction(X, bm.nodes_where(i_s=0), bm.nodes_where(i_s=2 * n_s), self.X_c)
        self.a_tip = np.array([geometry.tip_offset, 0.0, 0.0])
        self.a_com = np.array([geometry.cap_com_offset, 0.0, 0.0])
        self.A_cap = np.pi * geometry.cap_inner_radius ** 2
        self.tendons = [self._route(th) for th in geometry.tendon_angles]
        self.m = len(self.tendons)
        self._setup_contact(contact, contact_stiffness)
        self.setup_time = time.perf_counter() - t0

    # ------------------------------------------------------------------ setup helpers
    def _setup_contact(self, contact, stiffness) -> None:
        """``contact_pairs`` (FlankPairs or None), ``contact_stiffness`` [N/m³] and the pairs' reduced DOFs."""
        if not isinstance(contact, (bool, np.bool_)):
            raise InputError(f"contact must be True or False, got {contact!r}")
        if stiffness is not None:
            stiffness = float(check_finite("contact_stiffness [N/m^3]", stiffness, ()))
            if stiffness <= 0:
                raise InputError(f"contact_stiffness must be > 0 N/m^3, got {stiffness}")
        self.contact_stiffness = (default_stiffness(self.material, self.geometry) if stiffness is None
                                  else stiffness) if contact else None
        self.contact_pairs = flank_pairs(self.bmesh) if contact else None
        if contact:
            q0 = self.caps.q_of_node[self.contact_pairs.nodes]
            if np.any(q0 < 0):
                raise ConfigError("a flank contact node is a cap node: the mesh has no free flank between the caps")
            self._contact_dofs = (q0[:, :, None] + np.arange(3)).reshape(q0.shape[0], -1)

    def _route(self, theta: float) -> TendonPath:
        geo, bm = self.geometry, self.bmesh
        n_s, n_t, n_th = bm.shape
        d = geo.tendon_radius
        er = e_radial(theta)
        roots = geo.root_positions()[1:-1]
        nodes_l, w_l = [], []
        nth2 = 2 * n_th
        for z in roots:
            i_s = int(np.argmin(np.abs(bm.zeta - z)))
            if abs(bm.zeta[i_s] - z) > 1e-9 * geo.length:  # pragma: no cover
                raise ConfigError("root not on a mesh row")
            ring = np.array([bm.nodes_where(i_s=i_s, i_t=n_t, i_theta=k)[0] for k in range(nth2)])
            pos = (theta % (2 * np.pi)) / (2 * np.pi) * nth2
            k0 = int(np.floor(pos)) % nth2
            s = pos - np.floor(pos)
            k1 = (k0 + 1) % nth2
            wc = np.full(nth2, 1.0 / nth2)
            a = -wc.copy()
            a[k0] += 1 - s
            a[k1] += s
            nodes_l.append(ring)
            w_l.append((wc, a))
        return TendonPath(theta=float(theta), radius=d, exit_point=d * er, guide_nodes=nodes_l,
                          guide_wc=[w[0] for w in w_l], guide_a=[w[1] for w in w_l], anchor=d * er)

    @property
    def n_dofs(self) -> int:
        """Number of reduced unknowns (free nodal DOFs + 6 cap DOFs)."""
        return self.caps.n_q

    def zero_state(self) -> State:
        m = self.m
        return State(np.zeros((3, self.bmesh.n_nodes)), np.zeros(3), np.eye(3), np.zeros(m), np.zeros(m, bool))

    def _apply(self, st: State, dq: np.ndarray, alpha: float = 1.0, rings: bool = True) -> State:
        """``st`` moved by ``alpha dq`` (reduced coordinates); with ``rings`` (and :data:`RING_UPDATE`) each ring
        of free nodes turns by the finite rotation of its rigid part (:mod:`fem_reference.corotation`)."""
        new = st.copy()
        c = self.caps
        du = alpha * dq[: c.n_free].reshape(-1, 3).T
        if RING_UPDATE and rings:   # each ring turns by a finite rotation (fem_reference.corotation)
            x = (self.bmesh.X + st.U)[:, c.free_nodes]
            du = du + ring_rotation_correction(x, du, self._rings())
        new.U[:, c.free_nodes] += du
        new.uc = st.uc + alpha * dq[c.n_free: c.n_free + 3]
        new.R = expm_so3(alpha * dq[c.n_free + 3: c.n_free + 6]) @ st.R
        c.place(new.U, new.uc, new.R)
        return new

    def _rings(self) -> np.ndarray:
        """Ring index of each free node (its lattice row along the axis; :mod:`fem_reference.corotation`)."""
        rows = self.__dict__.get("_ring_rows")
        if rows is None:
            _, rows = np.unique(self.bmesh.lattice[0, self.caps.free_nodes], return_inverse=True)
            rows = self._ring_rows = np.asarray(rows).ravel()
        return rows

    # ------------------------------------------------------------------ kinematics of points
    def tip_position(self, st: State) -> np.ndarray:
        return self.X_c + st.uc + st.R @ self.a_tip

    def tip_jacobian(self, st: State) -> sp.csr_matrix:
        """``∂p_tip/∂q``, shape ``(3, n_q)``."""
        Jb = point_jacobian(st.R @ self.a_tip)
        s = self.caps.n_free
        rows, cols = np.nonzero(np.ones((3, 6)))
        return sp.csr_matrix((Jb[rows, cols], (rows, cols + s)), shape=(3, self.n_dofs))

    def _tendon_dofs(self, k: int) -> list[np.ndarray]:
        """Reduced DOF indices ``D_p`` of the points ``p = 1 … n`` of tendon ``k``'s polyline (the exit point 0
        is fixed): the 3 × N ring DOFs of each guide (node-major), the 6 cap DOFs for the anchor."""
        tp, c = self.tendons[k], self.caps
        out = []
        for nodes in tp.guide_nodes:
            q0 = c.q_of_node[nodes]
            if np.any(q0 < 0):  # pragma: no cover
                raise ConfigError("tendon guide on a constrained node")
            out.append((q0[:, None] + np.arange(3)[None, :]).ravel())
        out.append(c.n_free + np.arange(6))
        return out

    def _tendon_blocks(self, k: int) -> list[tuple[int, int]]:
        """The (row point, column point) pairs of tendon ``k``'s Hessian blocks, in the order of the values of
        :meth:`_tendon_terms`: each diagonal block, then each pair of neighbours and its transpose."""
        n = len(self.tendons[k].guide_nodes) + 1
        return [(p, p) for p in range(n)] + [pq for p in range(n - 1) for pq in ((p, p + 1), (p + 1, p))]

    def _tendon_keys(self, k: int) -> np.ndarray:
        """Flat keys ``row · n_q + col`` of every entry of tendon ``k``'s Hessian blocks (static: the blocks are
        dense and their DOFs do not change with the state)."""
        cache = self.__dict__.setdefault("_tkeys", {})
        if k not in cache:
            D, n = self._tendon_dofs(k), self.n_dofs
            cache[k] = np.concatenate([(D[p][:, None].astype(np.int64) * n + D[q][None, :]).ravel()
                                       for p, q in self._tendon_blocks(k)])
        return cache[k]

    def _tendon_terms(self, st: State, k: int, want_hessian: bool, weights: np.ndarray | None = None,
                      jacobians: list | None = None):
        """Length ``L`` [m], gradient ``∂L/∂q`` (n_q,) and, if asked, the values of the Hessian ``∂²L/∂q²`` on
        the dense blocks of :meth:`_tendon_keys` (same order), of tendon ``k``.  With segment ``weights`` (n,)
        the gradient and Hessian are those of ``Σ_s w_s ℓ_s`` at constant weights (``L`` stays the length);
        ``jacobians``, a list, receives the points' ``G_p``.

        With ``G_p = ∂x_p/∂q_{D_p}`` (3 × |D_p|) of each polyline point and the segment blocks ``H_s``
        (:func:`~fem_reference.loads.tendons.polyline_hessian_blocks`): the block of points (p, p) is
        ``G_pᵀ (H_{p-1} + H_p) G_p`` plus the guide's curvature term ``a aᵀ ⊗ B`` (or, for the anchor, the
        rigid-link geometric term), the block (p, p+1) is ``−G_pᵀ H_p G_{p+1}``."""
        tp = self.tendons[k]
        x = self.bmesh.X + st.U
        centre = self.X_c + st.uc
        pts = tp.points(x, centre, st.R)
        L = polyline_length(pts)
        gL = polyline_gradient(pts) if weights is None else weighted_gradient(pts, weights)
        D = self._tendon_dofs(k)
        Gs, extra = [], []
        for gi, (nodes, wc, a) in enumerate(zip(tp.guide_nodes, tp.guide_wc, tp.guide_a)):
            _, blocks, geo_ = guide_point(x[:, nodes], wc, a, tp.radius)
            Gs.append(blocks.transpose(1, 0, 2).reshape(3, -1))          # G[i, 3j + k] = ∂x_g,i/∂x_j,k
            extra.append((a, geo_))
        ra = st.R @ tp.anchor
        Gs.append(point_jacobian(ra))                                     # anchor: (3, 6)
        g = np.zeros(self.n_dofs)
        for p, G in enumerate(Gs):
            g[D[p]] += G.T @ gL[p + 1]
        if jacobians is not None:
            jacobians.extend(Gs)
        if not want_hessian:
            return L, g, None
        Hb = polyline_hessian_blocks(pts)                                 # segment s joins points s, s + 1
        if weights is not None:
            Hb = Hb * np.asarray(weights, float)[:, None, None]
        n = len(Gs)
        vals = []
        for p in range(n):                                                # point p + 1 of the polyline
            Hs = Hb[p] + (Hb[p + 1] if p + 1 < Hb.shape[0] else 0.0)
            blk = Gs[p].T @ Hs @ Gs[p]
            if p < n - 1:
                a, (n_, P_, rho_) = extra[p]
                blk = blk + np.kron(np.outer(a, a), guide_hessian(gL[p + 1], n_, P_, rho_, tp.radius))
            else:
                blk[3:, 3:] += point_geometric(ra, gL[-1])
            vals.append(blk.ravel())
        for p in range(n - 1):
            off = -(Gs[p].T @ Hb[p + 1] @ Gs[p + 1])
            vals.append(off.ravel())
            vals.append(off.T.ravel())
        return L, g, np.concatenate(vals)

    def _tendon_hessian(self, st: State, k: int) -> sp.csr_matrix:
        """``∂²L/∂q²`` of tendon ``k`` as a sparse (n_q, n_q) matrix (for tests and inspection)."""
        _, _, vals = self._tendon_terms(st, k, True)
        keys, n = self._tendon_keys(k), self.n_dofs
        return sp.csr_matrix((vals, (keys // n, keys % n)), shape=(n, n))

    # ------------------------------------------------------------------ tendon friction
    def _friction_keys(self, k: int) -> np.ndarray:
        """Flat keys of the dense block over all DOFs of tendon ``k``'s points (row-major): the friction tangent
        ``Σ_s ∂ℓ_s/∂q (∂T_s/∂q)ᵀ`` couples every guide with the guides before it."""
        cache = self.__dict__.setdefault("_fkeys", {})
        if k not in cache:
            D = np.concatenate(self._tendon_dofs(k)).astype(np.int64)
            cache[k] = (D[:, None] * self.n_dofs + D[None, :]).ravel()
        return cache[k]

    def _ensure_friction_pattern(self) -> None:
        """Extend the model-wide sparsity pattern (:meth:`_canonical`) by the friction blocks of every tendon."""
        self._ensure_keys(np.concatenate([self._friction_keys(k) for k in range(self.m)]))

    def _ensure_keys(self, keys: np.ndarray) -> None:
        """Extend the model-wide sparsity pattern (:meth:`_canonical`) by the flat keys ``row · n_q + col``."""
        pat = getattr(self, "_pattern", None)
        if pat is not None and pat[0] is not None:
            pos = np.minimum(np.searchsorted(pat[2], keys), pat[2].size - 1)
            if np.all(pat[2][pos] == keys):
                return
        n = self.n_dofs
        self._canonical(sp.csr_matrix((np.zeros(keys.size), (keys // n, keys % n)), shape=(n, n)))

    def _friction_positions(self, k: int) -> np.ndarray:
        """Positions of :meth:`_friction_keys` in the data of the model-wide pattern."""
        pat = self._pattern
        cache = self.__dict__.setdefault("_fpos", {})
        if cache.get(k, (None,))[0] is not pat:
            cache[k] = (pat, np.searchsorted(pat[2], self._friction_keys(k)))
        return cache[k][1]

    def _friction_terms(self, st: State, k: int, fr: FrictionLaw, tangent: bool):
        """Tendon ``k`` under the capstan law ``fr`` (:mod:`fem_reference.loads.tendon_friction`): its length
        ``L`` [m], ``∂L/∂q`` (n_q,), the residual ``Σ_s T_s ∂ℓ_s/∂q`` (n_q,) [N] and, with ``tangent``, the values
        of ``Σ_s T_s ∂²ℓ_s/∂q² + Σ_s ∂ℓ_s/∂q (∂T_s/∂q)ᵀ`` on :meth:`_friction_keys` (else None)."""
        tp = self.tendons[k]
        pts = tp.points(self.bmesh.X + st.U, self.X_c + st.uc, st.R)
        alpha, dalpha = wrap_angles(pts, fr.e_in)
        T, _, dT = tension_profile(st.T[k], fr.held[k], alpha, fr.mu, dalpha if tangent else None)
        Gs: list = []
        L, rk, Hw = self._tendon_terms(st, k, tangent, weights=T, jacobians=Gs)
        D = self._tendon_dofs(k)
        gL = polyline_gradient(pts)
        g = np.zeros(self.n_dofs)
        for p, G in enumerate(Gs):
            g[D[p]] += G.T @ gL[p + 1]
        if not tangent:
            return L, g, rk, None
        sizes = [d.size for d in D]
        off = np.concatenate([[0], np.cumsum(sizes)])
        M = np.zeros((off[-1], off[-1]))
        pos = 0
        for p, q in self._tendon_blocks(k):                     # Σ_s T_s ∂²ℓ_s/∂q², block by block
            size = sizes[p] * sizes[q]
            M[off[p]:off[p + 1], off[q]:off[q + 1]] += Hw[pos:pos + size].reshape(sizes[p], sizes[q])
            pos += size
        Gfull = np.zeros((3 * len(Gs), off[-1]))
        for p, G in enumerate(Gs):
            Gfull[3 * p:3 * p + 3, off[p]:off[p + 1]] = G
        Kf = friction_block(pts, dT)[1:, :, 1:, :].reshape(3 * len(Gs), 3 * len(Gs))   # the exit is fixed
        M += Gfull.T @ Kf @ Gfull
        return L, g, rk, M.ravel()

    def friction_profile(self, res: BellowsResult) -> FrictionProfile:
        """Segment tensions, sliding codes and wrap angles of the equilibrium ``res``
        (:class:`~fem_reference.loads.tendon_friction.FrictionProfile`; frictionless: every segment at its
        tendon's tension, μ = 0) — the history of the next friction step (``solve(friction_state=…)``)."""
        self._own(res)
        st, fr = res.state, res.loadcase.friction
        x = self.bmesh.X + st.U
        Ts, codes, alphas = [], [], []
        for k, tp in enumerate(self.tendons):
            pts = tp.points(x, self.X_c + st.uc, st.R)
            alpha = wrap_angles(pts, np.array([1.0, 0.0, 0.0]))[0]
            if fr is None:
                T, code = np.full(alpha.size, float(st.T[k])), np.zeros(alpha.size, np.int8)
            else:
                T, code, _ = tension_profile(st.T[k], fr.held[k], alpha, fr.mu)
            Ts.append(T)
            codes.append(code)
            alphas.append(alpha)
        return FrictionProfile(0.0 if fr is None else fr.mu, np.array(Ts), np.array(codes), np.array(alphas))

    def _friction_law(self, friction, friction_state, target: LoadCase) -> FrictionLaw | None:
        """The :class:`FrictionLaw` of a solve (None for μ = 0); InputError for μ outside [0, 1], a history of
        another μ or model, or locked tendons with friction (not modelled)."""
        mu = float(check_finite("friction (coefficient μ)", friction, ()))
        if not 0.0 <= mu <= 1.0:
            raise InputError(f"friction must be a coefficient μ in [0, 1], got {mu:g}")
        if mu == 0.0:
            if friction_state is not None:
                raise InputError("friction_state needs friction > 0 (the frictionless solve has no history)")
            return None
        if np.any(~np.isnan(target.locked_lengths)):
            raise InputError("locked tendons with friction are not modelled by the FEM; prescribe tensions")
        n_seg = len(self.tendons[0].guide_nodes) + 1
        if friction_state is None:
            held = np.zeros((self.m, n_seg))
        else:
            prof = friction_state
            if not isinstance(prof, FrictionProfile):
                if getattr(prof, "model", None) is not self:
                    raise InputError("friction_state must be a FrictionProfile or a result of this model, got "
                                     f"{type(prof).__name__}")
                prof = self.friction_profile(prof)
            if prof.mu != mu or prof.segment_tensions.shape != (self.m, n_seg):
                raise InputError(f"friction_state was solved with μ = {prof.mu:g} and segment tensions of shape "
                                 f"{prof.segment_tensions.shape}; this solve has μ = {mu:g}, ({self.m}, {n_seg})")
            held = np.array(prof.segment_tensions, float)
        return FrictionLaw(mu, held, np.array([1.0, 0.0, 0.0]))

    def tension_cycle(self, peak_tensions, pressure: float = 0.0, steps: int = 6, friction: float = 0.0,
                      **solve_options) -> FemTensionCycle:
        """A quasi-static cycle of the tendon tensions 0 → ``peak_tensions`` (m,) [N] → 0 in ``steps`` equal steps
        per branch (2 … 1000) at ``pressure`` [Pa], each state the friction step (``friction`` μ) from the one
        before; the start is the equilibrium under the pressure alone.  ``solve_options`` go to :meth:`solve`.
        Returns :class:`~fem_reference.loads.tendon_friction.FemTensionCycle` (tips, results, profiles, loop
        area as ``ancf``'s ``Model.tension_cycle``)."""
        if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or not 2 <= steps <= 1000:
            raise InputError(f"steps must be an integer in [2, 1000], got {steps!r}")
        Tp = check_finite("peak_tensions [N]", peak_tensions, (self.m,))
        if not np.all(Tp >= 0) or not np.any(Tp > 0):
            raise InputError(f"peak_tensions must be ≥ 0 N with at least one > 0, got {Tp.tolist()}")
        s = int(steps)
        scale = np.concatenate([np.linspace(0.0, 1.0, s + 1), np.linspace(1.0, 0.0, s + 1)[1:]])
        res = self.solve(np.zeros(self.m), pressure, **solve_options)
        results, profiles = [res], [self.friction_profile(res)]
        for c in scale[1:]:
            state = results[-1] if (friction > 0 and len(results) > 1) else None
            res = self.solve(c * Tp, pressure, initial=res, friction=friction, friction_state=state,
                             **solve_options)
            results.append(res)
            profiles.append(self.friction_profile(res))
        tip = np.array([r.tip_position for r in results])
        d = tip[s] - tip[0]
        u = (tip - tip[0]) @ (d / np.linalg.norm(d) if np.linalg.norm(d) > 0 else d)
        return FemTensionCycle(scale, tip, results, profiles, loop_area(scale * float(Tp.max()), u), Tp.copy())

    def tendon_lengths(self, st: State) -> np.ndarray:
        """Current cable path lengths [m], shape ``(m,)``."""
        x = self.bmesh.X + st.U
        return np.array([polyline_length(tp.points(x, self.X_c + st.uc, st.R)) for tp in self.tendons])

    # ------------------------------------------------------------------ residual and tangent
    def evaluate(self, st: State, lc: LoadCase, tangent: bool = True, stats: NewtonStats | None = None):
        """Reduced residual, tangent and tendon data at state ``st`` under loads ``lc``.

        Returns
        -------
        dict with ``r`` (n_q,) [N | N m], ``K`` (csr or None), ``jmin``, ``L`` (m,) [m],
        ``g`` (n_q, m) tendon length gradients, ``f_ref`` (norm of the external generalised load).
        """
        t0 = time.perf_counter()
        c = self.caps
        f_int, K, jmin = self.asm.assemble(st.U, tangent=tangent)
        out = dict(jmin=jmin)
        if jmin <= 0:
            out["r"] = None
            return out
        f_ext = lc.gravity * self.f_gravity
        Kp = None
        if lc.pressure != 0.0:
            fp, Kp = self.press.assemble(st.U, lc.pressure, tangent=tangent)
            f_ext = f_ext + fp
        r_full = f_int - f_ext
        if tangent and Kp is not None:
            if K.indptr is Kp.indptr and (K.indices is Kp.indices or np.array_equal(K.indices, Kp.indices)):
                # both on the volume pattern (CsrPattern.csr)
                K.data -= Kp.data  # the same differences as K - Kp, without scipy's merge of two patterns
            else:  # pragma: no cover - a pressure assembler without the volume pattern
                K = K - Kp
        s = c.n_free
        extra_K = np.zeros((6, 6))
        # point loads on the cap: (spatial offset, external force)
        loads = [(st.R @ self.a_tip, lc.tip_force)]
        if lc.gravity and self.geometry.cap_mass > 0:
            loads.append((st.R @ self.a_com, cap_weight(self.geometry.cap_mass, self.g, lc.gravity)))
        pvec, dpvec = cap_pressure_force(lc.pressure, self.A_cap, st.R)
        loads.append((np.zeros(3), pvec))
        for rr, F in loads:
            extra_K[3:, 3:] += point_geometric(rr, -F)
        # follower cap pressure: residual -f, so K[u_c, θ] += -∂f/∂θ = p A [R e_x]_×
        extra_K[0:3, 3:6] -= dpvec
        r, Kq = c.reduce(K, r_full, st.R, extra_cc=extra_K)
        fext_q = c.restrict(f_ext, st.R)
        for rr, F in loads:
            Jb = point_jacobian(rr)
            r[s: s + 6] -= Jb.T @ F
            fext_q[s: s + 6] += Jb.T @ F
        m = self.m
        Ls = np.zeros(m)
        g = np.zeros((self.n_dofs, m))
        fr = lc.friction
        ct = self.contact_forces(st, tangent) if self.contact_pairs is not None else None
        if tangent:
            if fr is not None:
                self._ensure_friction_pattern()
            if ct is not None and ct.active.size:
                self._ensure_contact_pattern()
            Kq = self._canonical(Kq)
        for k in range(m):
            if fr is not None and st.T[k] != 0.0:       # segment tensions of the capstan law
                Ls[k], g[:, k], rk, Hk = self._friction_terms(st, k, fr, tangent)
                r += rk
                fext_q -= rk
                if tangent:
                    Kq.data[self._friction_positions(k)] += Hk
                continue
            Lk, gk, Hk = self._tendon_terms(st, k, tangent and st.T[k] != 0.0)
            Ls[k], g[:, k] = Lk, gk
            if st.T[k] != 0.0:
                r += st.T[k] * gk
                fext_q -= st.T[k] * gk
                if tangent:
                    Kq.data[self._tendon_positions(k)] += st.T[k] * Hk  # distinct positions: no np.add.at
        if ct is not None and ct.active.size:
            self._add_contact(ct, r, Kq if tangent else None)
        out.update(r=r, K=Kq, L=Ls, g=g, f_ref=float(np.linalg.norm(fext_q)), contact=ct)
        if stats is not None:
            stats.t_assembly += time.perf_counter() - t0
        return out

    def _canonical(self, K: sp.csr_matrix) -> sp.csr_matrix:
        """Embed ``K`` in a model-wide sparsity pattern (the union of all patterns seen so far).

        scipy drops entries that cancel exactly in sparse sums, and tendon Hessians appear only when
        a tension is non-zero, so the raw pattern flickers between iterations; a stable pattern lets
        PARDISO reuse its symbolic analysis (see :mod:`fem_reference.solver`).
        """
        pat = getattr(self, "_pattern", None)
        if pat is not None and getattr(K, "_written_on", None) is pat:
            return K                 # written on this pattern by the caps' reduction (retargeted below)
        K.sum_duplicates()
        if pat is not None and np.array_equal(pat[0], K.indptr) and np.array_equal(pat[1], K.indices):
            return K
        cache = getattr(self, "_pattern_cache", None)  # last raw pattern -> positions in `pat`
        if (cache is not None and cache[3] is pat and np.array_equal(cache[0], K.indptr)
                and np.array_equal(cache[1], K.indices)):
            data = np.zeros(pat[2].size)
            data[cache[2]] = K.data
            return sp.csr_matrix((data, pat[1], pat[0]), shape=K.shape)
        n = K.shape[0]
        keys = np.repeat(np.arange(n, dtype=np.int64), np.diff(K.indptr)) * n + K.indices
        if pat is None:  # start from the tendons' Hessian blocks too: added in place by evaluate
            tk = np.concatenate([self._tendon_keys(k) for k in range(self.m)] + [keys[:0]])
            pat = (None, None, unique_keys(tk))
        pkeys = pat[2]
        pos = np.searchsorted(pkeys, keys)
        if not np.all(pkeys[np.minimum(pos, pkeys.size - 1)] == keys):
            pkeys = unique_keys(np.concatenate([pkeys, keys]))
            indptr, indices = csr_index(pkeys, n, K.indptr.dtype)
            pat = (indptr, indices.astype(K.indices.dtype), pkeys)
            self._pattern = pat
            pos = np.searchsorted(pkeys, keys)
        self._pattern_cache = (K.indptr.copy(), K.indices.copy(), pos, pat)
        m = getattr(K, "_reduction_map", None)
        if m is not None:
            # the caps' reduction made K: from now on it writes on the model-wide pattern itself (the test
            # at the top), without this copy of ≈ 4 M entries and the pattern compares per evaluation
            m.retarget(pkeys, pat[0], pat[1], target=pat)
        data = np.zeros(pkeys.size)
        data[pos] = K.data
        return sp.csr_matrix((data, pat[1], pat[0]), shape=K.shape)

    def _tendon_positions(self, k: int) -> np.ndarray:
        """Positions of tendon ``k``'s Hessian block entries in the data of the model-wide pattern."""
        pat = self._pattern
        cache = self.__dict__.setdefault("_tpos", {})
        if cache.get(k, (None,))[0] is not pat:
            cache[k] = (pat, np.searchsorted(pat[2], self._tendon_keys(k)))
        return cache[k][1]

    # ------------------------------------------------------------------ flank contact
    def contact_forces(self, st: State, hessian: bool = False) -> ContactTerms | None:
        """The flank contact's gaps, energy and (pairs in contact) gradient / normal forces at ``st``
        (:func:`fem_reference.loads.contact.contact_terms`); None when the model has no contact."""
        if self.contact_pairs is None:
            return None
        return contact_terms(self.contact_pairs, self.bmesh.X + st.U, self.contact_stiffness, hessian=hessian)

    def _contact_keys(self) -> np.ndarray:
        """Flat keys ``row · n_q + col`` of every contact pair's dense 30 × 30 block, shape (P, 900)."""
        if "_ckeys" not in self.__dict__:
            D = self._contact_dofs.astype(np.int64)
            self._ckeys = (D[:, :, None] * self.n_dofs + D[:, None, :]).reshape(D.shape[0], -1)
        return self._ckeys

    def _ensure_contact_pattern(self) -> None:
        """Put every contact pair's block into the model-wide pattern, once (a pattern only grows)."""
        pat = getattr(self, "_pattern", None)
        if pat is None or self.__dict__.get("_contact_pattern") is not pat:
            self._ensure_keys(unique_keys(self._contact_keys()))
            self._contact_pattern = self._pattern

    def _add_contact(self, ct: ContactTerms, r: np.ndarray, Kq: sp.csr_matrix | None) -> None:
        """Add the contact's gradient to the reduced residual ``r`` and its Hessian to ``Kq`` (in place)."""
        D = self._contact_dofs[ct.active]
        r += np.bincount(D.ravel(), weights=ct.grad.ravel(), minlength=r.size)
        if Kq is not None:
            pat = self._pattern
            pos = np.searchsorted(pat[2], self._contact_keys()[ct.active].ravel())
            u, inv = np.unique(pos, return_inverse=True)
            Kq.data[u] += np.bincount(inv.ravel(), weights=ct.hess.ravel(), minlength=u.size)

    # ------------------------------------------------------------------ Newton at fixed load
    def _newton(self, st: State, lc: LoadCase, stats: NewtonStats, *, rtol: float, atol: float,
                ltol: float, max_iter: int, growth: float, callback=None, lc_prev: LoadCase | None = None,
                sym=None):
        """Equilibrium under the fixed loads ``lc`` from ``st``: Newton on the reduced system (in the symmetric
        subspace ``sym`` where it applies; bordered by the active locked tendons' length constraints), with the
        backtracking line search of :meth:`_line_search` and the early cut-back tests of :func:`_check_progress`.
        The tangent is assembled only where a Newton step is taken (the line search's trial states and the new
        loads' start state need residuals only: two tangent assemblies fewer per load step).
        Returns ``(state, evaluation, residual norms [N], iterations)``; raises StepFailed."""
        locked = ~np.isnan(lc.locked_lengths)
        history: list[float] = []
        step_norms: list[float] = []
        st = st.copy()
        # prescribed tensions
        st.T[~locked] = lc.tensions[~locked]
        st.T[locked & st.slack] = 0.0
        ev = self.evaluate(st, lc, tangent=lc_prev is None, stats=stats)
        if lc_prev is not None and ev["r"] is not None:
            # Euler predictor: the first matrix is the tangent of the converged start state under its
            # own loads (prestress and load stiffness consistent), not under the new loads.  From an
            # unstressed state with a pressure increment, the latter contains the follower-load
            # stiffness without the matching wall prestress and can be near-singular (measured).
            ev["K"] = self.evaluate(st, lc_prev, tangent=True, stats=stats).get("K")
        for it in range(max_iter + 1):
            r = ev["r"]
            active = locked & ~st.slack
            cres = (ev["L"] - lc.locked_lengths)[active]
            rn = float(np.linalg.norm(r))
            history.append(rn)
            if callback is not None:
                callback(dict(iteration=it, residual=rn, constraint=float(np.abs(cres).max(initial=0.0))))
            tol = max(atol, rtol * ev["f_ref"])
            if not np.isfinite(rn):
                raise StepFailed("residual not finite", history, it)
            if rn <= tol and np.all(np.abs(cres) <= ltol):
                stats.n_iterations += it
                self._last_step_norms = step_norms
                return st, ev, history, it
            if it == max_iter:
                break
            _check_progress(history, it)
            if ev.get("K") is None:          # the line search evaluates residuals only: the tangent now
                ev = self.evaluate(st, lc, tangent=True, stats=stats)
            t0 = time.perf_counter()
            stats.n_factorizations += 1
            if sym is not None and sym.applies(r, tol):  # the step in the invariant subspace (fem_reference.symmetry)
                dq, dT = sym.newton_step(ev["K"], r, ev["g"], active, cres, self.linear_solver)
                stats.n_symmetric_steps += 1
            else:  # a Newton step: see factorize
                # friction makes K non-symmetric: the exact factorisation (LU), not the symmetric part alone
                fac = factorize(ev["K"], self.linear_solver, exact=lc.friction is not None)
                dq, dT = bordered_step(fac, r, ev["g"][:, active], cres)
            stats.t_linear += time.perf_counter() - t0
            step_norms.append(float(np.linalg.norm(dq)))
            st, ev = self._line_search(st, dq, dT, active, lc, stats, bound=growth * max(rn, tol))
            if st is None:
                raise StepFailed("line search failed (inverted elements or residual growth)", history, it)
        raise StepFailed(f"no convergence in {max_iter} iterations", history, max_iter)

    def _line_search(self, st: State, dq: np.ndarray, dT: np.ndarray, active: np.ndarray, lc: LoadCase,
                     stats: NewtonStats, bound: float):
        """``(state, evaluation)`` after the Newton step ``α (dq, dT)`` with the largest ``α ∈ {1, ½, …, 2⁻¹¹}``
        that keeps every element uninverted and the residual norm at most ``bound`` [N]; ``(None, None)`` if none
        does.  ``dT`` (n_active,) [N] are the increments of the active locked tendons'
        multipliers.  The evaluation has no tangent (the converged state of a load step needs none)."""
        alpha = 1.0
        for _ls in range(12):
            trial = self._apply(st, dq, alpha)
            if active.any():
                trial.T[active] = st.T[active] + alpha * dT
            ev_t = self.evaluate(trial, lc, tangent=False, stats=stats)
            ok = ev_t["jmin"] > 0 and bool(np.all(np.isfinite(ev_t["r"])))
            if ok and np.linalg.norm(ev_t["r"]) <= bound:
                return trial, ev_t
            alpha *= 0.5
        return None, None

    # ------------------------------------------------------------------ public solve
    def _loadcase(self, tensions, pressure, tip_force, gravity, locked_lengths) -> LoadCase:
        m = self.m
        T = np.zeros(m) if tensions is None else check_finite("tensions [N]", tensions, (m,))
        if np.any(T < 0):
            raise InputError(f"tensions must be finite and >= 0 N (a cable cannot push), got {T}")
        p = float(check_finite("pressure [Pa]", pressure, ()))
        F = check_finite("tip_force [N]", tip_force, (3,))
        gs = (1.0 if gravity else 0.0) if isinstance(gravity, (bool, np.bool_)) else \
            float(check_finite("gravity (scale)", gravity, ()))
        ll = np.full(m, np.nan)
        if locked_lengths is not None:
            if isinstance(locked_lengths, (str, bytes)) or not hasattr(locked_lengths, "__len__"):
                raise InputError(f"locked_lengths must be a sequence of {m} lengths [m] or None, got "
                                 f"{locked_lengths!r}")
            vals = list(locked_lengths)
            if len(vals) != m:
                raise InputError(f"locked_lengths must have {m} entries (None = tension mode)")
            for k, v in enumerate(vals):
                if v is not None and not (isinstance(v, float) and np.isnan(v)):
                    v = float(check_finite(f"locked length {k} [m]", v, ()))
                    if v <= 0:
                        raise InputError(f"locked length {k} must be a positive length [m], got {v}")
                    ll[k] = float(v)
        return LoadCase(T, p, F, gs, ll)

    def solve(self, tensions=None, pressure: float = 0.0, tip_force=(0.0, 0.0, 0.0), gravity=False,
              locked_lengths: Sequence[float | None] | None = None, initial: BellowsResult | None = None,
              n_steps: int | None = None, rtol: float = 1e-9, atol: float = 1e-9, ltol: float = 1e-11,
              max_iter: int = 25, max_cuts: int = 8, growth: float = 1e4,
              progress: Callable[[dict], None] | None = None, *, check_limits: bool = True,
              max_steps: int = 60, time_limit_s: float | None = None,
              check_stability: bool = True, symmetry: bool = True, friction: float = 0.0,
              friction_state: FrictionProfile | BellowsResult | None = None) -> BellowsResult:
        """Static equilibrium under the given loads (SI units).

        Parameters
        ----------
        tensions : (m,) [N]
            Tendon tensions (≥ 0).  For locked tendons this is ignored (the tension is an unknown).
        pressure : float [Pa]
            Cavity gauge pressure (follower load on the inner wall and the distal cap).
        tip_force : (3,) [N]
            Dead force on the tip point of the distal cap (world frame).
        gravity : bool or float
            Dead weight of wall and cap (float: scale factor).
        locked_lengths : (m,) of float or None, optional
            Locked cable lengths [m]; ``None`` entries stay at prescribed tension.
        initial : BellowsResult, optional
            Start from this equilibrium and ramp the loads from its loads (warm start).
        n_steps : int, optional
            Initial number of load increments (adaptive cut-back/growth afterwards); default: one, plus one per
            20 kPa of pressure, per 3 N of total tension and per :data:`ASYMMETRY_STEP` of tension difference
            between the tendons, of the change from the start.
        rtol, atol : float
            Residual tolerance ``‖r‖ <= max(atol [N], rtol ‖f_ext‖)``.
        ltol : float
            Locked length tolerance [m].
        progress : callable(dict), optional
            Called after each converged load step with ``{"lam", "step", "iterations", "residuals"}``.
        check_limits : bool
            Reject loads outside ``self.limits`` up front (:class:`~ancf.errors.LimitError`) — the default;
            ``False`` analyses them anyway.
        max_steps : int
            Bound on the load increments tried (converged and cut back): a failing solve reports within it.
        time_limit_s : float, optional
            Wall-clock bound [s]; the solve raises ConvergenceError when it is exceeded.
        check_stability : bool
            Check that the equilibrium is a minimum (inertia of the reduced tangent, see
            :meth:`stability`; one extra factorisation) and raise UnstableEquilibriumError if it is not;
            ``False`` skips the check (``res.stable`` is then None).
        symmetry : bool
            Solve the Newton steps of each load step in the subspace invariant under the symmetries of the
            mesh that leave its loads and start state invariant (:mod:`fem_reference.symmetry`; same discrete
            equilibrium, smaller factorisations; the order used is ``res.stats.symmetry_order``) — the
            default; ``False`` always solves the full system.
        friction : float
            Tendon friction coefficient μ ∈ [0, 1] of the capstan law at the guides
            (:mod:`fem_reference.loads.tendon_friction`; 0: frictionless, the solve as without it).  With μ > 0
            the Newton matrix is not symmetric (LU) and the symmetric subspace is not used.
        friction_state : FrictionProfile or BellowsResult, optional
            The history: the previous state's segment tensions (:meth:`friction_profile`, or a friction result of
            this model, same μ); None: every segment slack.  The law is applied once with it (the load ramp is a
            continuation path to this step's equilibrium).

        Returns
        -------
        BellowsResult

        Raises
        ------
        ancf.errors.ConvergenceError
            When a load increment fails after ``max_cuts`` cut-backs, more than ``max_steps`` increments are
            needed, or ``time_limit_s`` is exceeded (carries the residual history).
        ancf.errors.LimitError
            A load outside the operating limits (unless ``check_limits=False``).
        """
        _check_solve_options(max_iter=max_iter, max_cuts=max_cuts, max_steps=max_steps, rtol=rtol, atol=atol,
                             ltol=ltol, time_limit_s=time_limit_s)
        symmetry = check_symmetry_flag(symmetry)
        target = self._loadcase(tensions, pressure, tip_force, gravity, locked_lengths)
        target.friction = self._friction_law(friction, friction_state, target)
        symmetry = symmetry and target.friction is None
        if check_limits:
            self.limits.check(target, self.tendon_lengths(self.zero_state()))
        t_start = time.perf_counter()
        stats = NewtonStats()
        st, start = self._start(initial, target)
        start.friction = target.friction
        locked = ~np.isnan(target.locked_lengths)
        if n_steps is None:
            n_steps = self._initial_steps(start, target)
        path = _LoadPath(dlam=1.0 / max(1, int(n_steps)), t_start=t_start, tolerance=max(atol, rtol))
        while path.lam < 1.0 - 1e-14:
            lam_t = path.next_increment(stats, max_steps, time_limit_s)
            lc, lc_prev = start.lerp(target, lam_t), start.lerp(target, path.lam)
            # intermediate load steps are only a path to the last one: converged to STEP_RTOL (the next step's
            # Newton starts from them and corrects what is left), the last one to rtol.  Not with locked tendons:
            # their slack/taut decisions are taken on each step's state (a loose one made the slack transition
            # of a locked tendon fail, measured)
            rt = rtol if (lam_t >= 1.0 - 1e-14 or locked.any()) else max(rtol, STEP_RTOL)
            try:
                st, hist, its = self._load_step(st, lc_prev, lc, stats, symmetry, {
                    "rtol": rt, "atol": atol, "ltol": ltol, "max_iter": max_iter, "growth": growth})
            except StepFailed as e:
                path.cut_back(e, stats, lam_t, max_cuts)    # from the same converged st, half the increment
                continue
            path.advance(lam_t, its)
            stats.steps.append(dict(lam=lam_t, iterations=its, residuals=hist,
                                    step_norms=list(self._last_step_norms)))
            if progress is not None:
                progress(dict(lam=lam_t, step=path.step, iterations=its, residuals=hist))
        return self._finish(st, target, stats, t_start, check_stability)

    def _start(self, initial: BellowsResult | None, target: LoadCase) -> tuple[State, LoadCase]:
        """Start state and start loads of a solve towards ``target``: the unloaded state, or ``initial``'s
        equilibrium and loads (warm start).  Locked tendons start at their current length and tension (their
        target tension is set to it: it is an unknown, ``target`` is updated in place); a locked tendon that is
        slack and shorter than its target length starts slack."""
        if initial is not None:
            self._own(initial)
            st = initial.state.copy()
            start = initial.loadcase
            start = LoadCase(st.T.copy(), start.pressure, start.tip_force.copy(), start.gravity,
                             np.full(self.m, np.nan))
        else:
            st = self.zero_state()
            start = LoadCase(np.zeros(self.m), 0.0, np.zeros(3), 0.0, np.full(self.m, np.nan))
        locked = ~np.isnan(target.locked_lengths)
        L_now = self.tendon_lengths(st)
        start.locked_lengths = np.where(locked, L_now, np.nan)
        start.tensions = np.where(locked, st.T, start.tensions)
        target.tensions = np.where(locked, st.T, target.tensions)  # unused for locked tendons
        st.slack = locked & (st.T <= 0) & (target.locked_lengths >= L_now)
        return st, start

    def _initial_steps(self, start: LoadCase, target: LoadCase) -> int:
        """Initial number of load increments from ``start`` to ``target``: one, plus one per 20 kPa of pressure,
        per 3 N of total tension and per :data:`ASYMMETRY_STEP` of tension difference between the tendons."""
        dp = abs(target.pressure - start.pressure)
        dT = float(np.abs(target.tensions - start.tensions).sum())
        asym = float(np.ptp(target.tensions - start.tensions)) if self.m else 0.0
        return 1 + int(dp / 20e3) + int(dT / 3.0) + int(asym / ASYMMETRY_STEP)

    def _load_step(self, st: State, lc_prev: LoadCase, lc: LoadCase, stats: NewtonStats, symmetry: bool,
                   newton: dict) -> tuple[State, list[float], int]:
        """Equilibrium under ``lc`` from the equilibrium ``st`` under ``lc_prev``: ``(state, residuals [N],
        iterations)`` of :meth:`_newton` (options ``newton``), repeated while the locked tendons' active set
        changes (a taut cable whose multiplier turns negative goes slack; a slack one stretched beyond its
        locked length is taut again).  Raises StepFailed."""
        locked = ~np.isnan(lc.locked_lengths)
        for _pass in range(6):  # active-set passes for locked tendons
            sym = subspace_for(self, (lc_prev, lc), (st,)) if symmetry else None
            stats.symmetry_order = 1 if sym is None else sym.order
            st_new, ev, hist, its = self._newton(st, lc, stats, **newton, lc_prev=lc_prev if _pass == 0 else None,
                                                 sym=sym)
            changed = False
            for k in np.flatnonzero(locked):
                if not st_new.slack[k] and st_new.T[k] < 0:
                    st_new.slack[k], st_new.T[k], changed = True, 0.0, True
                elif st_new.slack[k] and ev["L"][k] > lc.locked_lengths[k] + newton["ltol"]:
                    st_new.slack[k], changed = False, True
            if not changed:
                return st_new, hist, its
            st = st_new
        raise StepFailed("tendon active set did not settle", hist, its)  # pragma: no cover

    def _finish(self, st: State, target: LoadCase, stats: NewtonStats, t_start: float,
                check_stability: bool) -> BellowsResult:
        """The result at the converged state ``st`` (tensions: the final ones, multipliers of locked tendons);
        with ``check_stability``, UnstableEquilibriumError unless it is a minimum (:meth:`stability`)."""
        from .results import BellowsResult

        stats.t_total = time.perf_counter() - t_start
        target.tensions = st.T.copy()
        res = BellowsResult(model=self, state=st, loadcase=target, stats=stats,
                            tendon_lengths=self.tendon_lengths(st))
        if check_stability:
            n_neg = self.stability(res)
            if n_neg:
                raise UnstableEquilibriumError(
                    f"the solve converged to an unstable equilibrium ({n_neg} negative direction(s) of the "
                    "reduced tangent: a saddle, e.g. beyond a buckling load), not a usable state; perturb the "
                    "start (initial=...), apply the load in steps from a stable state, or lower the load",
                    solver="fem_newton", min_eigenvalue=float("nan"))
        return res

    # ------------------------------------------------------------------ compliance
    def stability(self, res: BellowsResult) -> int | None:
        """Number of negative eigenvalues of the reduced tangent at ``res`` (0: a stable minimum), from its
        inertia; sets ``res.stable`` and ``res.negative_directions``.

        The symmetric part of K is factorised by PARDISO's LDLᵀ (Bunch–Kaufman pivots; its count of negative
        pivots is the count of negative eigenvalues by Sylvester's law, :func:`fem_reference.solver.symmetric_inertia`;
        4× faster than SuperLU here), or — without PARDISO, or when it perturbed pivots — by SuperLU with
        diagonal pivots only (symmetric mode), whose U diagonal has the signs of the eigenvalues.  With taut locked
        tendons (constraint gradients g, n × k) the count is taken on the constraint tangent space by
        Haynsworth's inertia additivity for the bordered matrix [[K, g], [gᵀ, 0]]:
        n₋(reduced) = n₋(K) + n₊(gᵀ K⁻¹ g) − k.  Returns None (inconclusive) if the factorisation had to
        pivot off the diagonal or K is singular.
        """
        import scipy.sparse.linalg as spla

        self._own(res)
        st = res.state
        ev = self.evaluate(st, res.loadcase, tangent=True)
        K = ev["K"]
        sym = symmetric_inertia(K) if self.linear_solver in ("auto", "pardiso") else None
        if sym is not None:
            n_neg, solve = sym
        else:
            Ks = (0.5 * (K + K.T)).tocsc()
            try:
                lu = spla.splu(Ks, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                               options=dict(SymmetricMode=True))
            except RuntimeError:        # exactly singular
                res.stable, res.negative_directions = None, None
                return None
            d = lu.U.diagonal()
            if not np.array_equal(lu.perm_r, lu.perm_c) or np.any(d == 0):
                res.stable, res.negative_directions = None, None
                return None
            n_neg, solve = int(np.sum(d < 0)), lu.solve
        active = ~np.isnan(res.loadcase.locked_lengths) & ~st.slack
        if active.any():
            g = np.asarray(ev["g"][:, active], float)
            S = g.T @ solve(g)
            n_neg += int(np.sum(np.linalg.eigvalsh(0.5 * (S + S.T)) > 0)) - int(active.sum())
        res.stable, res.negative_directions = n_neg == 0, n_neg
        return n_neg

    def _own(self, res) -> None:
        """InputError unless ``res`` is a result of this model (another mesh has other unknowns)."""
        if getattr(res, "model", None) is not self:
            raise InputError("the result must come from this same BellowsModel (a result of another model or "
                             f"mesh has other unknowns), got {type(res).__name__}")

    def cap_compliance(self, res: BellowsResult) -> np.ndarray:
        """6×6 compliance of the cap centre: ``[δu_c; δθ] = C [δF; δM]`` (tension mode) [m/N, 1/N ...]."""
        self._own(res)
        ev = self.evaluate(res.state, res.loadcase, tangent=True)
        fac = factorize(ev["K"], self.linear_solver)
        E = np.zeros((self.n_dofs, 6))
        E[self.caps.cap_slice, :] = np.eye(6)
        return E.T @ fac.solve(E)

    def tip_compliance(self, res: BellowsResult, mode: str = "tension") -> np.ndarray:
        """3×3 tip compliance ``δp_tip = C δF_tip`` [m/N] about the equilibrium ``res``.

        ``mode="tension"``: tensions held constant.  ``mode="locked"``: tendons with ``T > 0`` held at
        their current length (tensions are multipliers); slack tendons stay slack.
        """
        if mode not in ("tension", "locked"):
            raise InputError("mode must be 'tension' or 'locked'")
        self._own(res)
        st = res.state
        ev = self.evaluate(st, res.loadcase, tangent=True)
        fac = factorize(ev["K"], self.linear_solver)
        Jp = self.tip_jacobian(st).toarray()
        Y = fac.solve(Jp.T)
        C = Jp @ Y
        if mode == "locked":
            act = st.T > 1e-12
            if act.any():
                g = ev["g"][:, act]
                Z = fac.solve(g)
                C = C - (Jp @ Z) @ np.linalg.solve(g.T @ Z, g.T @ Y)
        return C

    def modes(self, res: BellowsResult | None = None, count: int = 4, tendons: str = "held"):
        """The ``count`` lowest vibration modes about ``res`` (default: unloaded) — frequencies [Hz], reduced
        and cap shapes; tendons "held" or "locked" (:mod:`fem_reference.dynamics`)."""
        from .dynamics import modes
        return modes(self, self.solve() if res is None else res, count, tendons)

    def equivalent_rod(self, res: BellowsResult | None = None) -> dict:
        """Equivalent-rod parameters from the condensed cap tangent about ``res`` (default: unloaded).

        Returns (SI): ``EA`` = L / C_{u_x F_x} [N]; ``EI`` = L / C_{θ_y M_y} [N m²] (pure moment, no
        shear); ``EI_tip_force`` = L³ / (3 C_{u_z F_z}) [N m²] (cantilever with shear, i.e. what a
        tip-load experiment identifies); ``D_a`` = sqrt(8 EI / EA) [m] (the ANCF thin-tube relation);
        ``A_eff`` = (∂u_x/∂p) / C_{u_x F_x} [m²] — the blocked-force pressure area — and
        ``D_eff`` = sqrt(4 A_eff / π) [m].  ``∂u/∂p = −K_q⁻¹ ∂r_q/∂p`` is exact because the residual
        is affine in ``p`` at a fixed configuration.

        Straight-tube closed form (Lamé, closed ends, long tube): ``A_eff = π a² (1 − 2ν)``.
        """
        if res is None:
            res = self.solve()
        self._own(res)
        L = self.geometry.length
        st, lc = res.state, res.loadcase
        ev = self.evaluate(st, lc, tangent=True)
        fac = factorize(ev["K"], self.linear_solver)
        E = np.zeros((self.n_dofs, 6))
        E[self.caps.cap_slice, :] = np.eye(6)
        C6 = E.T @ fac.solve(E)
        lc1 = LoadCase(lc.tensions.copy(), lc.pressure + 1.0, lc.tip_force.copy(), lc.gravity,
                       lc.locked_lengths.copy())
        drdp = self.evaluate(st, lc1, tangent=False)["r"] - self.evaluate(st, lc, tangent=False)["r"]
        dudp = -fac.solve(drdp)[self.caps.cap_slice]
        EA = L / C6[0, 0]
        EI = L / C6[4, 4]
        A_eff = dudp[0] / C6[0, 0]
        return dict(EA=EA, EI=EI, EI_tip_force=L ** 3 / (3 * C6[2, 2]), D_a=float(np.sqrt(8 * EI / EA)),
                    A_eff=A_eff, D_eff=float(np.sqrt(4 * max(A_eff, 0.0) / np.pi)), cap_compliance=C6)

