r"""Stacked bellows: N hyperelastic segments joined by rigid intermediate caps (``docs/fem.md``, "Stacked bellows").

**Layout.**  Segment k (k = 1 … N, proximal first) is a bellows of its own (:class:`BellowsGeometry`, material,
mesh), meshed in its own frame (base face at x = 0) and placed along the undeformed axis ``+x`` at
``s_k = Σ_{j<k} (L_j + h_j)``.  Cap k is the rigid body at the distal face of segment k: its reference point
``X_k = (s_k + L_k, 0, 0)`` is on its proximal face, its distal face (where segment k + 1 starts) is ``h_k``
further along its axis (``cap_lengths``; the last cap is the tip cap, of no length).  Each cap has six unknowns
``(u_k, θ_k)`` (translation, spatial rotation vector), updated exactly as the single model's cap
(:mod:`fem_reference.loads.caps`).  The distal ring of segment k and the proximal ring of segment k + 1 are
both placed rigidly by cap k, ``x_i = X_k + u_k + R_k (X_i − X_k)``; the base ring of segment 1 is clamped.

**Unknowns and reduction.**  ``z = [free DOFs of segment 1, …, of segment N, cap 1 (6), …, cap N (6)]``.  With
``P_k = ∂u_k/∂z`` (identity on segment k's free DOFs, ``[I, −[r_i]_×]`` on each tied ring node into its cap's
columns) the reduced residual and tangent are the single model's Galerkin reduction summed over the segments,

.. math::

    r_z = \sum_k P_k^T \big(f^{int}_k - f^{p}_k(p_k) - s_g f^g_k\big) + \text{cap loads} + \sum_j T_j\,\partial L_j/\partial z,
    \qquad
    K_z = \sum_k P_k^T K_k P_k + \sum_{\text{ties}} \sum_i \big(r_i \rho_i^T - (\rho_i\cdot r_i) I\big)_{\theta\theta}
          + \text{cap load terms} + \sum_j T_j\,\partial^2 L_j/\partial z^2,

with ``ρ_i`` the nodal residual on tied node ``i`` (the rigid-link geometric stiffness of each tie, per cap).
Every segment's internal force, wall pressure and gravity are the single model's own assemblers
(``BellowsModel.asm``, ``.press``, ``.f_gravity``): they depend on displacement gradients (and a dead load),
so the segment's placement along the axis does not enter them.

**Chambers.**  Chamber k is closed by cap k − 1 (or the base) and cap k.  Its pressure ``p_k`` loads segment
k's inner wall (follower, Nanson) and pushes cap k along its axis by ``p_k A_k`` (``A_k = π r_i²`` at segment
k's distal end) and cap k − 1 back by ``p_k A'_k`` (``A'_k`` at segment k's base end).  An intermediate cap
thus carries ``(p_k A_k − p_{k+1} A'_{k+1}) R_k e_x``; both forces act along the cap axis, so their moment
about the cap's reference point vanishes at every rotation and they are applied there
(:func:`fem_reference.loads.pressure.cap_pressure_force`, its follower tangent).

**Series law** (checked by the tests).  Under axisymmetric pressures alone, cap k is pushed up by ``p_k A_k``,
down by ``p_{k+1} A'_{k+1}``, and segment k + 1's wall — whose own cavity is closed, so the wall's net pressure
force is zero — pulls it up by exactly ``p_{k+1} A'_{k+1}`` (the force with which it holds cap k + 1).  So
segment k's wall carries only its own chamber's end load ``p_k A_k``, as a single bellows does; its deformation
is the single bellows' one displaced rigidly, and the stack's elongation is the sum of the segments' own.

**Tendons.**  A tendon of segment s (its angle θ and routing distance d from segment s's geometry) is the
polyline: the fixed exit ``d e_r(θ)`` on the base, then for every segment k ≤ s the guides of segment k's
interior roots at θ and d (:func:`fem_reference.loads.tendons.guide_point`, the routes of
``BellowsModel``), for every cap k < s its channel — the entry point ``d e_r`` on the proximal face and, for a
cap of length ``h_k > 0``, the exit point ``h_k e_x + d e_r`` on its distal face (a straight channel of constant
length ``h_k``: it adds nothing to the cap's generalised force) — and the anchor ``d e_r`` on cap s's proximal
face.  Its length, gradient and Hessian are those of :mod:`fem_reference.loads.tendons`: ``G_pᵀ H G_q`` blocks
of the polyline segments, the guides' curvature term and, for cap points, the rigid-link geometric term.
A distal tendon therefore loads every proximal segment through its guides and every cap it passes.

**Solver.**  The Newton iteration, line search and load stepping are ``BellowsModel``'s own (``_newton``,
``_line_search``, ``_load_step`` and ``_LoadPath``): they call this model's :meth:`StackModel.evaluate` and
:meth:`StackModel._apply`.  Tendon tensions are prescribed (locked lengths, friction and the symmetric subspace
are not offered for a stack yet).  With one segment the unknowns, residual and tangent are ``BellowsModel``'s
(tested to round-off).
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from . import model as _model
from .corotation import ring_rotation_correction
from .errors import (
    ConfigError,
    InputError,
    LimitError,
    UnstableEquilibriumError,
    check_finite,
)
from .geometry import BellowsGeometry, e_radial
from .loads.caps import (
    RigidCapReduction,
    expm_so3,
    log_so3,
    point_geometric,
    point_jacobian,
)
from .loads.gravity import cap_weight
from .loads.pressure import cap_pressure_force
from .loads.tendons import (
    guide_hessian,
    guide_point,
    polyline_gradient,
    polyline_hessian_blocks,
    polyline_length,
)
from .material import Material
from .model import (
    G_DEFAULT,
    STEP_RTOL,
    BellowsModel,
    OperatingLimits,
    _check_solve_options,
    _LoadPath,
)
from .solver import NewtonStats, StepFailed

__all__ = ["MAX_SEGMENTS", "StackLoadCase", "StackModel", "StackResult", "StackState"]

#: most segments a stack may have (each is a full FEM bellows)
MAX_SEGMENTS = 8
#: smallest angular distance between two tendons of the stack [rad] (every tendon runs through segment 1)
MIN_TENDON_GAP = 1e-3


@dataclass
class StackState:
    """Configuration: each segment's nodal displacements, each cap's translation and rotation, the tensions."""

    U: list            # N arrays (3, n_nodes_k) [m]
    uc: np.ndarray     # (N, 3) [m]
    R: np.ndarray      # (N, 3, 3)
    T: np.ndarray      # (m,) [N]
    slack: np.ndarray  # (m,) bool (no locked tendons: always False)

    def copy(self) -> StackState:
        return StackState([u.copy() for u in self.U], self.uc.copy(), self.R.copy(), self.T.copy(),
                          self.slack.copy())


@dataclass
class StackLoadCase:
    """Loads of one equilibrium (SI): tensions (m,) [N], one pressure per chamber (N,) [Pa], tip force (3,) [N],
    gravity scale 0..1.  ``locked_lengths`` (all NaN) and ``friction`` (None) are what the Newton loop reads."""

    tensions: np.ndarray
    pressures: np.ndarray
    tip_force: np.ndarray
    gravity: float
    locked_lengths: np.ndarray
    friction: None = None

    def lerp(self, other: StackLoadCase, lam: float) -> StackLoadCase:
        a = lambda x, y: x + lam * (y - x)
        return StackLoadCase(a(self.tensions, other.tensions), a(self.pressures, other.pressures),
                             a(self.tip_force, other.tip_force), a(self.gravity, other.gravity),
                             other.locked_lengths.copy())


def _per_segment(value, n: int, name: str) -> list:
    """``value`` repeated for ``n`` segments, or its ``n`` entries if it is a list/tuple (InputError otherwise)."""
    if isinstance(value, (list, tuple)):
        if len(value) != n:
            raise InputError(f"{name}: one entry per segment ({n}) or one for all, got {len(value)}")
        return list(value)
    return [value] * n


class StackModel:
    """N bellows in series joined by rigid caps: one chamber and pressure per segment, tendons per segment
    anchored at its distal cap and routed through every segment below (module docstring).

    Parameters
    ----------
    geometries : sequence of BellowsGeometry, proximal first
        Segment k's bellows; its ``tendon_angles``/``tendon_radius`` are its own tendons, its ``cap_mass`` and
        ``cap_com_offset`` those of cap k (its distal cap), the last one's ``tip_offset`` the tip point.
    material : Material or a sequence of one per segment
    mesh : mesh level ("coarse", …, a MeshLevel) or a sequence of one per segment
    cap_lengths : (N − 1,) [m], optional
        Length ``h_k`` of each intermediate cap along its axis (default 0).
    linear_solver, gravity_vector, limits, assembly_kernel, element
        As :class:`~fem_reference.BellowsModel` (the limits apply to every chamber and tendon).
    """

    # the Newton machinery of the single model, run on this model's evaluate/_apply (module docstring)
    _newton = BellowsModel._newton
    _line_search = BellowsModel._line_search
    _load_step = BellowsModel._load_step
    stability = BellowsModel.stability

    def __init__(self, geometries: Sequence[BellowsGeometry], material, mesh="coarse", cap_lengths=None,
                 linear_solver: str = "auto", gravity_vector=G_DEFAULT, limits: OperatingLimits | None = None,
                 assembly_kernel: str = "numba", element: str = "mixed"):
        geos = list(geometries) if isinstance(geometries, (list, tuple)) else [geometries]
        N = len(geos)
        if not 1 <= N <= MAX_SEGMENTS or not all(isinstance(g, BellowsGeometry) for g in geos):
            raise InputError(f"StackModel needs 1 … {MAX_SEGMENTS} BellowsGeometry segments, got {geometries!r}")
        mats = _per_segment(material, N, "material")
        if not all(isinstance(m, Material) for m in mats):
            raise InputError("material must be a Material or one Material per segment")
        meshes = _per_segment(mesh, N, "mesh")
        h = np.zeros(max(N - 1, 0)) if cap_lengths is None else check_finite("cap_lengths [m]", cap_lengths, (N - 1,))
        if np.any(h < 0) or np.any(h > 1.0):
            raise ConfigError(f"cap_lengths must be in [0, 1] m (metres), got {h.tolist()}")
        self.cap_lengths = h
        self.limits = OperatingLimits() if limits is None else limits
        t0 = time.perf_counter()
        self.segments = [BellowsModel(g, m, me, linear_solver, gravity_vector, self.limits, assembly_kernel, element)
                         for g, m, me in zip(geos, mats, meshes)]
        self.linear_solver, self.g, self.N = linear_solver, self.segments[0].g, N
        L = np.array([g.length for g in geos])
        self.offsets = np.concatenate([[0.0], np.cumsum(L[:-1] + h)])          # s_k: base face of segment k [m]
        self.X_c = np.stack([[s + l, 0.0, 0.0] for s, l in zip(self.offsets, L)])  # (N, 3) cap reference points
        nf = [s.caps.n_free for s in self.segments]
        self.free_offsets = np.concatenate([[0], np.cumsum(nf)]).astype(np.int64)
        self.n_free = int(self.free_offsets[-1])
        self.n_dofs = self.n_free + 6 * N
        self.A_distal = np.array([np.pi * g.cap_inner_radius ** 2 for g in geos])
        self.A_base = np.array([np.pi * (g.profile.r_inner[0] if g.is_table else g.root_radius) ** 2 for g in geos])
        self._ties = [self._segment_ties(k) for k in range(N)]
        self.tendon_segment = np.concatenate([np.full(len(g.tendon_angles), k) for k, g in enumerate(geos)]).astype(int)
        self.m = self.tendon_segment.size
        self._check_tendon_gaps(geos)
        self.tendons = [self._tendon_points(j) for j in range(self.m)]
        self.setup_time = time.perf_counter() - t0

    # ------------------------------------------------------------------ setup
    def _segment_ties(self, k: int) -> list[tuple[RigidCapReduction, int]]:
        """The rings of segment k tied to caps: ``(reduction over that ring, cap index)`` — its distal ring to cap k
        (the single model's own cap reduction), its base ring to cap k − 1 (k ≥ 1; offsets from that cap's
        reference point, ``X_local + h_{k−1} e_x``)."""
        seg = self.segments[k]
        ties = [(seg.caps, k)]
        if k > 0:
            X_c = np.array([-self.cap_lengths[k - 1], 0.0, 0.0])
            ties.append((RigidCapReduction(seg.bmesh.X, np.zeros(0, np.int64), seg.caps.base_nodes, X_c), k - 1))
        return ties

    def _check_tendon_gaps(self, geos) -> None:
        """ConfigError when two tendons of the stack share an angle (all run through segment 1's guides)."""
        a = np.concatenate([np.asarray(g.tendon_angles, float) for g in geos])
        for i in range(a.size):
            for j in range(i):
                if abs((a[i] - a[j] + np.pi) % (2 * np.pi) - np.pi) < MIN_TENDON_GAP:
                    raise ConfigError(f"tendons {j + 1} and {i + 1} of the stack (numbered segment by segment) "
                                      f"coincide at {np.degrees(a[i]):g}°: every tendon runs through segment 1")

    def _tendon_points(self, j: int) -> list[tuple]:
        """Polyline points after the fixed exit of tendon ``j``: ``("guide", k, nodes, wc, a)`` on segment k's root
        rings, ``("cap", c, offset (3,))`` on cap c (channel entry/exit, anchor)."""
        s = int(self.tendon_segment[j])
        geo = self.segments[s].geometry
        theta = geo.tendon_angles[j - int(np.flatnonzero(self.tendon_segment == s)[0])]
        er = geo.tendon_radius * e_radial(theta)
        pts: list[tuple] = []
        for k in range(s + 1):
            tp = self.segments[k]._route(theta)
            pts += [("guide", k, n, wc, a) for n, wc, a in zip(tp.guide_nodes, tp.guide_wc, tp.guide_a)]
            pts.append(("cap", k, er.copy()))
            if k < s and self.cap_lengths[k] > 0:
                pts.append(("cap", k, er + np.array([self.cap_lengths[k], 0.0, 0.0])))
        return pts

    def tendon_geometry(self, j: int) -> tuple[float, float, np.ndarray]:
        """Angle θ [rad], routing distance d [m] and fixed base exit point (3,) [m] of tendon ``j``."""
        s = int(self.tendon_segment[j])
        geo = self.segments[s].geometry
        theta = geo.tendon_angles[j - int(np.flatnonzero(self.tendon_segment == s)[0])]
        return theta, geo.tendon_radius, geo.tendon_radius * e_radial(theta)

    # ------------------------------------------------------------------ states and kinematics
    def zero_state(self) -> StackState:
        N, m = self.N, self.m
        return StackState([np.zeros((3, s.bmesh.n_nodes)) for s in self.segments], np.zeros((N, 3)),
                          np.repeat(np.eye(3)[None], N, 0), np.zeros(m), np.zeros(m, bool))

    def cap_slice(self, c: int) -> slice:
        """Unknowns of cap ``c`` (0-based): ``[u (3), θ (3)]``."""
        return slice(self.n_free + 6 * c, self.n_free + 6 * c + 6)

    def _place(self, st: StackState) -> None:
        """Set the tied rings' displacements (rigid motion of their caps) and the clamped base in place."""
        st.U[0][:, self.segments[0].caps.base_nodes] = 0.0
        for k in range(self.N):
            for tie, c in self._ties[k]:
                st.U[k][:, tie.cap_nodes] = st.uc[c][:, None] + (st.R[c] - np.eye(3)) @ tie.A_cap

    def _apply(self, st: StackState, dq: np.ndarray, alpha: float = 1.0, rings: bool = True) -> StackState:
        """``st`` moved by ``alpha dq``; each segment's rings of free nodes turn finitely as in the single model."""
        new = st.copy()
        for k, seg in enumerate(self.segments):
            c, o = seg.caps, self.free_offsets[k]
            du = alpha * dq[o: o + c.n_free].reshape(-1, 3).T
            if _model.RING_UPDATE and rings:
                du = du + ring_rotation_correction((seg.bmesh.X + st.U[k])[:, c.free_nodes], du, seg._rings())
            new.U[k][:, c.free_nodes] += du
        for c in range(self.N):
            s = self.n_free + 6 * c
            new.uc[c] = st.uc[c] + alpha * dq[s: s + 3]
            new.R[c] = expm_so3(alpha * dq[s + 3: s + 6]) @ st.R[c]
        self._place(new)
        return new

    def nodes(self, st: StackState, k: int) -> np.ndarray:
        """Current positions of segment ``k``'s nodes in the stack's frame, (3, n_nodes_k) [m]."""
        return self.segments[k].bmesh.X + st.U[k] + np.array([self.offsets[k], 0.0, 0.0])[:, None]

    def tip_position(self, st: StackState) -> np.ndarray:
        a = np.array([self.segments[-1].geometry.tip_offset, 0.0, 0.0])
        return self.X_c[-1] + st.uc[-1] + st.R[-1] @ a

    def _points(self, st: StackState, j: int, xs: list | None = None):
        """Polyline points (n+1, 3) [m] of tendon ``j``, and per point after the exit ``(G (3, |D|), D, extra)``:
        its Jacobian, its unknowns and what its curvature term needs."""
        xs = [self.nodes(st, k) for k in range(self.N)] if xs is None else xs
        pts, jac = [self.tendon_geometry(j)[2]], []
        d = self.tendon_geometry(j)[1]
        for p in self.tendons[j]:
            if p[0] == "guide":
                _, k, nodes, wc, a = p
                xg, blocks, curv = guide_point(xs[k][:, nodes], wc, a, d)
                q0 = self.free_offsets[k] + self.segments[k].caps.q_of_node[nodes]
                jac.append((blocks.transpose(1, 0, 2).reshape(3, -1), (q0[:, None] + np.arange(3)).ravel(),
                            ("guide", a, curv)))
                pts.append(xg)
            else:
                _, c, off = p
                ra = st.R[c] @ off
                jac.append((point_jacobian(ra), np.arange(self.cap_slice(c).start, self.cap_slice(c).stop),
                            ("cap", ra)))
                pts.append(self.X_c[c] + st.uc[c] + ra)
        return np.array(pts), jac

    def tendon_lengths(self, st: StackState) -> np.ndarray:
        """Cable path lengths [m], (m,)."""
        xs = [self.nodes(st, k) for k in range(self.N)]
        return np.array([polyline_length(self._points(st, j, xs)[0]) for j in range(self.m)])

    def _tendon_terms(self, st: StackState, j: int, want_hessian: bool, xs=None):
        """Length ``L`` [m], ``∂L/∂z`` (n_z,) and, if asked, ``∂²L/∂z²`` as COO ``(rows, cols, values)`` of tendon
        ``j`` (module docstring of :mod:`fem_reference.loads.tendons`; point ``i`` of the polyline gets the
        block ``G_iᵀ (H_{i−1} + H_i) G_i`` plus its curvature term, neighbours ``−G_iᵀ H_i G_{i+1}``)."""
        pts, jac = self._points(st, j, xs)
        gL = polyline_gradient(pts)
        g = np.zeros(self.n_dofs)
        for i, (G, D, _) in enumerate(jac):
            np.add.at(g, D, G.T @ gL[i + 1])
        if not want_hessian:
            return polyline_length(pts), g, None
        Hb = polyline_hessian_blocks(pts)
        d, n = self.tendon_geometry(j)[1], len(jac)
        rows, cols, vals = [], [], []

        def put(Dp, Dq, blk):
            rows.append(np.repeat(Dp, Dq.size))
            cols.append(np.tile(Dq, Dp.size))
            vals.append(blk.ravel())

        for i, (G, D, extra) in enumerate(jac):
            blk = G.T @ (Hb[i] + (Hb[i + 1] if i + 1 < n else 0.0)) @ G
            if extra[0] == "guide":
                blk = blk + np.kron(np.outer(extra[1], extra[1]), guide_hessian(gL[i + 1], *extra[2], d))
            else:
                blk[3:, 3:] += point_geometric(extra[1], gL[i + 1])
            put(D, D, blk)
            if i + 1 < n:
                off = -(G.T @ Hb[i + 1] @ jac[i + 1][0])
                put(D, jac[i + 1][1], off)
                put(jac[i + 1][1], D, off.T)
        return polyline_length(pts), g, (np.concatenate(rows), np.concatenate(cols), np.concatenate(vals))

    # ------------------------------------------------------------------ residual and tangent
    def _prolongation(self, k: int, st: StackState) -> sp.csr_matrix:
        """``P_k = ∂u_k/∂z``, shape (3 n_nodes_k, n_z): identity on the free DOFs, ``[I, −[r_i]_×]`` on tied rings."""
        c = self.segments[k].caps
        rows, cols, vals = [c.free_dofs], [self.free_offsets[k] + np.arange(c.n_free)], [np.ones(c.n_free)]
        for tie, cap in self._ties[k]:
            Pc = tie.cap_rows(st.R[cap])
            rows.append(np.repeat(tie.cap_dofs, 6))
            cols.append(np.tile(np.arange(self.cap_slice(cap).start, self.cap_slice(cap).stop), tie.cap_dofs.size))
            vals.append(Pc.ravel())
        n = self.segments[k].bmesh.n_nodes
        return sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                             shape=(3 * n, self.n_dofs))

    def _segment_terms(self, st: StackState, lc: StackLoadCase, tangent: bool, out: dict) -> bool:
        """Add each segment's reduced wall terms (internal, wall pressure, gravity; the ties' geometric terms) to
        ``out`` (``r``, ``fext``, ``K`` list, ``cc`` (N, 6, 6)); False if an element inverted (``jmin`` ≤ 0)."""
        for k, seg in enumerate(self.segments):
            f_int, K, jmin = seg.asm.assemble(st.U[k], tangent=tangent)
            out["jmin"] = min(out["jmin"], jmin)
            if jmin <= 0:
                return False
            f_ext = lc.gravity * seg.f_gravity
            if lc.pressures[k] != 0.0:
                fp, Kp = seg.press.assemble(st.U[k], float(lc.pressures[k]), tangent=tangent)
                f_ext = f_ext + fp
                K = K - Kp if tangent else K
            rk = f_int - f_ext
            P = self._prolongation(k, st)
            PT = P.T.tocsr()
            out["r"] += PT @ rk
            out["fext"] += PT @ f_ext
            for tie, c in self._ties[k]:
                out["cc"][c, 3:, 3:] += tie._rigid_link(rk, st.R[c])
            if tangent:
                out["K"].append(PT @ (K.tocsr() @ P))
        return True

    def _cap_terms(self, st: StackState, lc: StackLoadCase, out: dict) -> None:
        """Point loads on every cap: tip force (last cap), cap weight, chamber pressures on both faces."""
        for c in range(self.N):
            R, geo, s = st.R[c], self.segments[c].geometry, self.cap_slice(c)
            loads = []
            if c == self.N - 1:
                loads.append((R @ np.array([geo.tip_offset, 0.0, 0.0]), lc.tip_force))
            if lc.gravity and geo.cap_mass > 0:
                loads.append((R @ np.array([geo.cap_com_offset, 0.0, 0.0]), cap_weight(geo.cap_mass, self.g, lc.gravity)))
            pvec, dpvec = cap_pressure_force(float(lc.pressures[c]), self.A_distal[c], R)
            if c + 1 < self.N:                       # the chamber above pushes the cap back (same line of action)
                pv2, dp2 = cap_pressure_force(-float(lc.pressures[c + 1]), self.A_base[c + 1], R)
                pvec, dpvec = pvec + pv2, dpvec + dp2
            loads.append((np.zeros(3), pvec))
            for rr, F in loads:
                out["cc"][c, 3:, 3:] += point_geometric(rr, -F)
                Jb = point_jacobian(rr)
                out["r"][s] -= Jb.T @ F
                out["fext"][s] += Jb.T @ F
            out["cc"][c, 0:3, 3:6] -= dpvec

    def evaluate(self, st: StackState, lc: StackLoadCase, tangent: bool = True, stats: NewtonStats | None = None):
        """Reduced residual, tangent and tendon data at ``st`` under ``lc`` (as ``BellowsModel.evaluate``): dict with
        ``r`` (n_z,) [N | N m] (None if an element inverted), ``K`` (csr or None), ``jmin``, ``L`` (m,) [m],
        ``g`` (n_z, m) tendon length gradients, ``f_ref`` [N] (norm of the external generalised load)."""
        t0 = time.perf_counter()
        n = self.n_dofs
        out = dict(r=np.zeros(n), fext=np.zeros(n), K=[], cc=np.zeros((self.N, 6, 6)), jmin=np.inf)
        if not self._segment_terms(st, lc, tangent, out):
            return dict(jmin=out["jmin"], r=None)
        self._cap_terms(st, lc, out)
        r, fext = out["r"], out["fext"]
        Ls, g = np.zeros(self.m), np.zeros((n, self.m))
        xs = [self.nodes(st, k) for k in range(self.N)]
        blocks = [sp.csr_matrix((out["cc"][c].ravel(), (np.repeat(np.arange(6), 6) + self.cap_slice(c).start,
                                                        np.tile(np.arange(6), 6) + self.cap_slice(c).start)),
                                shape=(n, n)) for c in range(self.N)]
        for j in range(self.m):
            T = float(st.T[j])
            Ls[j], g[:, j], H = self._tendon_terms(st, j, tangent and T != 0.0, xs)
            if T != 0.0:
                r += T * g[:, j]
                fext -= T * g[:, j]
                if tangent:
                    blocks.append(sp.csr_matrix((T * H[2], (H[0], H[1])), shape=(n, n)))
        K = None
        if tangent:
            K = out["K"][0]
            for b in out["K"][1:] + blocks:
                K = K + b
            K = K.tocsr()
            K.sum_duplicates()
            K.sort_indices()
        if stats is not None:
            stats.t_assembly += time.perf_counter() - t0
        return dict(r=r, K=K, jmin=out["jmin"], L=Ls, g=g, f_ref=float(np.linalg.norm(fext)))

    # ------------------------------------------------------------------ solve
    def _loadcase(self, tensions, pressures, tip_force, gravity) -> StackLoadCase:
        T = np.zeros(self.m) if tensions is None else check_finite("tensions [N]", tensions, (self.m,))
        if np.any(T < 0):
            raise InputError(f"tensions must be >= 0 N (a cable cannot push), got {T.tolist()}")
        p = np.zeros(self.N) if pressures is None else check_finite("pressures [Pa]", pressures, (self.N,))
        F = check_finite("tip_force [N]", tip_force, (3,))
        gs = (1.0 if gravity else 0.0) if isinstance(gravity, (bool, np.bool_)) else \
            float(check_finite("gravity (scale)", gravity, ()))
        return StackLoadCase(T, p, F, gs, np.full(self.m, np.nan))

    def check_limits(self, lc: StackLoadCase) -> None:
        """LimitError naming the first chamber pressure, tendon tension or tip force outside ``self.limits``."""
        lim, how = self.limits, "check_limits=False analyses it anyway"
        for k, p in enumerate(lc.pressures):
            if not lim.pressure_min <= p <= lim.pressure_max:
                raise LimitError(f"pressure of chamber {k + 1}, {p / 1e3:g} kPa, is outside the FEM model's operating "
                                 f"limits [{lim.pressure_min / 1e3:g}, {lim.pressure_max / 1e3:g}] kPa ({how})")
        for j, T in enumerate(lc.tensions):
            if T > lim.tension_max:
                raise LimitError(f"tension T{j + 1} (segment {self.tendon_segment[j] + 1}) = {T:g} N is above the "
                                 f"FEM model's operating limit {lim.tension_max:g} N ({how})")
        lim.check_loads(np.zeros(0), 0.0, lc.tip_force)

    def solve(self, tensions=None, pressures=None, tip_force=(0.0, 0.0, 0.0), gravity=False,
              initial: StackResult | None = None, n_steps: int | None = None, rtol: float = 1e-9,
              atol: float = 1e-9, max_iter: int = 25, max_cuts: int = 8, growth: float = 1e4, *,
              check_limits: bool = True, max_steps: int = 60, time_limit_s: float | None = None,
              check_stability: bool = True) -> StackResult:
        """Static equilibrium (SI): ``tensions`` (m,) [N], numbered segment by segment (segment 1's first, each
        segment's in its geometry's order); ``pressures`` (N,) [Pa], one per chamber, segment 1 first;
        ``tip_force`` (3,) [N] dead force on the tip point; ``gravity`` (bool or scale).  The other options are
        :meth:`BellowsModel.solve`'s.  Raises ConvergenceError, LimitError, InputError, UnstableEquilibriumError
        as it does."""
        _check_solve_options(max_iter=max_iter, max_cuts=max_cuts, max_steps=max_steps, rtol=rtol, atol=atol,
                             ltol=1.0, time_limit_s=time_limit_s)
        target = self._loadcase(tensions, pressures, tip_force, gravity)
        if check_limits:
            self.check_limits(target)
        t_start, stats = time.perf_counter(), NewtonStats()
        if initial is not None:
            self._own(initial)
            st, s0 = initial.state.copy(), initial.loadcase
            start = StackLoadCase(s0.tensions.copy(), s0.pressures.copy(), s0.tip_force.copy(), s0.gravity,
                                  np.full(self.m, np.nan))
        else:
            st = self.zero_state()
            start = StackLoadCase(np.zeros(self.m), np.zeros(self.N), np.zeros(3), 0.0, np.full(self.m, np.nan))
        if n_steps is None:
            dT = target.tensions - start.tensions
            n_steps = (1 + int(np.abs(target.pressures - start.pressures).max() / 20e3) + int(np.abs(dT).sum() / 3.0)
                       + int((np.ptp(dT) if self.m else 0.0) / _model.ASYMMETRY_STEP))
        path = _LoadPath(dlam=1.0 / max(1, int(n_steps)), t_start=t_start, tolerance=max(atol, rtol))
        while path.lam < 1.0 - 1e-14:
            lam_t = path.next_increment(stats, max_steps, time_limit_s)
            lc, lc_prev = start.lerp(target, lam_t), start.lerp(target, path.lam)
            rt = rtol if lam_t >= 1.0 - 1e-14 else max(rtol, STEP_RTOL)
            try:
                st, hist, its = self._load_step(st, lc_prev, lc, stats, False, {
                    "rtol": rt, "atol": atol, "ltol": 1.0, "max_iter": max_iter, "growth": growth})
            except StepFailed as e:
                path.cut_back(e, stats, lam_t, max_cuts)
                continue
            path.advance(lam_t, its)
            stats.steps.append(dict(lam=lam_t, iterations=its, residuals=hist, step_norms=list(self._last_step_norms)))
        stats.t_total = time.perf_counter() - t_start
        res = StackResult(self, st, target, stats, self.tendon_lengths(st))
        if check_stability and self.stability(res):
            raise UnstableEquilibriumError(
                f"the stack's solve converged to an unstable equilibrium ({res.negative_directions} negative "
                "direction(s) of the reduced tangent), not a usable state; lower the load or apply it in steps",
                solver="fem_newton", min_eigenvalue=float("nan"))
        return res

    def _own(self, res) -> None:
        """InputError unless ``res`` is a result of this model."""
        if getattr(res, "model", None) is not self:
            raise InputError(f"the result must come from this same StackModel, got {type(res).__name__}")

    # ------------------------------------------------------------------ forces on the caps (checks)
    def wall_forces_on_caps(self, res: StackResult) -> np.ndarray:
        """Force [N] and moment about each cap's reference point [N m] that the walls (internal forces, wall
        pressure and weight of the tied ring nodes) exert on each cap: (N, 6) ``[F, M]``, from the full nodal
        residual of each segment — the reaction that the cap's point loads and tendons balance."""
        self._own(res)
        st, lc = res.state, res.loadcase
        out = np.zeros((self.N, 6))
        for k, seg in enumerate(self.segments):
            f_int, _, _ = seg.asm.assemble(st.U[k], tangent=False)
            f_ext = lc.gravity * seg.f_gravity
            if lc.pressures[k] != 0.0:
                f_ext = f_ext + seg.press.assemble(st.U[k], float(lc.pressures[k]), tangent=False)[0]
            rho = -(f_int - f_ext).reshape(-1, 3)
            for tie, c in self._ties[k]:
                r = st.R[c] @ tie.A_cap
                out[c, :3] += rho[tie.cap_nodes].sum(0)
                out[c, 3:] += np.cross(r.T, rho[tie.cap_nodes]).sum(0)
        return out


@dataclass
class StackResult:
    """One converged equilibrium of a :class:`StackModel` (SI units): ``model``, ``state`` (:class:`StackState`),
    ``loadcase`` (:class:`StackLoadCase`), ``stats`` (NewtonStats), ``tendon_lengths`` (m,) [m], ``stable`` and
    ``negative_directions`` (as :class:`~fem_reference.BellowsResult`)."""

    model: StackModel
    state: StackState
    loadcase: StackLoadCase
    stats: NewtonStats
    tendon_lengths: np.ndarray
    stable: bool | None = None
    negative_directions: int | None = None

    @property
    def tip_position(self) -> np.ndarray:
        """Tip point of the last cap [m], (3,)."""
        return self.model.tip_position(self.state)

    @property
    def cap_centres(self) -> np.ndarray:
        """Each cap's reference point (centre of its proximal face) [m], (N, 3)."""
        return self.model.X_c + self.state.uc

    @property
    def cap_rotations(self) -> np.ndarray:
        """Each cap's rotation matrix, (N, 3, 3); column 0 is its deformed axis."""
        return self.state.R.copy()

    @property
    def cap_rotation_vectors(self) -> np.ndarray:
        """Each cap's rotation vector [rad], (N, 3)."""
        return np.array([log_so3(R) for R in self.state.R])

    @property
    def tensions(self) -> np.ndarray:
        return self.state.T.copy()

    @property
    def iterations(self) -> int:
        return int(self.stats.n_iterations)

    def segment_centreline(self, k: int) -> np.ndarray:
        """Deformed centreline of segment ``k`` [m], (2 n_s + 1, 3): the mean of each ring of mid-wall nodes."""
        bm = self.model.segments[k].bmesh
        n_s, n_t, _ = bm.shape
        x = self.model.nodes(self.state, k)
        sel = bm.lattice[1] == n_t
        i_s = bm.lattice[0, sel]
        cnt = np.bincount(i_s, minlength=2 * n_s + 1)
        return np.stack([np.bincount(i_s, weights=x[i, sel], minlength=2 * n_s + 1) / cnt for i in range(3)], 1)

    @property
    def centreline(self) -> np.ndarray:
        """The segments' centrelines one after the other, proximal first [m], (Σ (2 n_s,k + 1), 3)."""
        return np.concatenate([self.segment_centreline(k) for k in range(self.model.N)])

    def tendon_points(self, j: int) -> np.ndarray:
        """Current polyline of tendon ``j`` [m], (n + 1, 3): base exit, guides, cap channels, anchor."""
        return self.model._points(self.state, j)[0]

    def summary(self) -> dict:
        """JSON-friendly summary (SI units)."""
        lc = self.loadcase
        return dict(tip_position_m=self.tip_position.tolist(), cap_centres_m=self.cap_centres.tolist(),
                    cap_rotation_vectors_rad=self.cap_rotation_vectors.tolist(), tensions_N=self.tensions.tolist(),
                    tendon_lengths_m=np.asarray(self.tendon_lengths).tolist(), pressures_Pa=lc.pressures.tolist(),
                    tip_force_N=np.asarray(lc.tip_force).tolist(), gravity=float(lc.gravity),
                    iterations=self.iterations, load_steps=len(self.stats.steps), n_dofs=int(self.model.n_dofs),
                    stable=self.stable)

    def save_vtu(self, path: str | Path) -> Path:
        """Write every segment's reference mesh (hex27, stack frame) with point data ``displacement`` [m],
        ``chamber_pressure_Pa`` and ``segment`` (1-based), and the cell data of ``BellowsResult.save_vtu``."""
        import meshio
        from skfem.io.meshio import to_meshio

        from .fields import cell_fields

        pts, cells, pdata, cdata, base = [], [], {"displacement": [], "chamber_pressure_Pa": [], "segment": []}, {}, 0
        kind = "hexahedron27"
        for k, seg in enumerate(self.model.segments):
            mm = to_meshio(seg.bmesh.mesh)
            pts.append(mm.points + np.array([self.model.offsets[k], 0.0, 0.0]))
            cells.append(mm.cells[0].data + base)
            kind = mm.cells[0].type
            base += mm.points.shape[0]
            pdata["displacement"].append(self.state.U[k].T)
            on = seg.asm.basis.get_dofs(facets=seg.bmesh.inner_facets()).flatten()
            pc = np.zeros(seg.bmesh.n_nodes)
            pc[on] = float(self.loadcase.pressures[k])
            pdata["chamber_pressure_Pa"].append(pc)
            pdata["segment"].append(np.full(seg.bmesh.n_nodes, k + 1, np.int64))
            f = cell_fields(seg.asm, self.state.U[k])
            f["cauchy_stress_Pa"] = f["cauchy_stress_Pa"].reshape(-1, 9)
            for name, v in f.items():
                cdata.setdefault(name, []).append(np.ascontiguousarray(v))
        out = meshio.Mesh(np.concatenate(pts), [(kind, np.concatenate(cells))],
                          point_data={k: np.concatenate(v) for k, v in pdata.items()},
                          cell_data={k: [np.concatenate(v)] for k, v in cdata.items()})
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        meshio.write(path, out)
        return path
