"""The chain's coordinates and its potential, assembled segment by segment (docs/multisegment.md §2–3).

Full coordinates: one ANCF node chain per segment, q_k (6(n_k + 1),), concatenated to q (Σ 6(n_k + 1),).
Free coordinates z: segment 1 as :class:`ancf.Model` (its nodes 2 … n+1; with ``free_base_stretch`` the base
stretch first); segment k ≥ 2 its nodes 2 … n_k + 1, preceded by its base stretch μ_k when
``junction_stretch = "free"``.  Segment k's first node is the cap map of :mod:`ancf.chain_junction` of segment
k − 1's last node — a free node — so q = Φ(z) needs no recursion and ∂Φ/∂z (J) is an identity selection plus one
6 × 7 block per junction.

The potential is a sum over segments, Π = Σ_k Π_k(q_k), each Π_k one call of :func:`ancf.assembly.assemble` with
segment k's law at its chamber's pressure p_k, its line mass, and every tendon j anchored at segment s(j) ≥ k
(tension T_j, its own distance d_j and angle θ_j: a distal tendon loads the proximal segments' routing); the
"tip load" of an inner segment is its cap's weight m_c g at the cap's centre of mass (offset along t), of the
distal segment the tip force plus the tip mass weight at the tool offset.  Hence

    ∇_z Π = Jᵀ Q,   ∇²_z Π = Jᵀ K J + Σ_junctions curvature,   l_j = Σ_{k ≤ s(j)} l_{j,k}(q_k) + Σ_{k < s(j)} h_k

(a tendon runs straight through a rigid cap, parallel to its axis: length h_k, a constant).  With one segment,
J is the selection of :class:`ancf.Model`'s free coordinates and every number is Model's own assembly.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import chain_junction as junction
from . import kinematics as kin
from .assembly import assemble
from .chain import ChainParams


@dataclass(frozen=True)
class Segment:
    """Constant arrays of one segment: its slice of q (qo, ndof) and z (zo, nz), the shape table, the law, the
    tendons passing it (``tendons``: chain indices; d, co, so), the end load's offset h [m] and mass [kg]."""
    params: object
    qo: int
    ndof: int
    zo: int
    nz: int
    N: np.ndarray
    wq: np.ndarray
    tendons: np.ndarray
    d: np.ndarray
    co: np.ndarray
    so: np.ndarray
    vc: np.ndarray
    end_offset: float
    end_mass: float


class ChainSystem:
    """Coordinates and potential of a :class:`~ancf.chain.ChainParams` (module docstring)."""

    def __init__(self, chain: ChainParams):
        self.chain = chain
        self.continuous = chain.junction_stretch == "continuous"
        s0 = chain.segments[0]
        self.E = np.ascontiguousarray(s0.frame)
        self.e1 = self.E[:, 0].copy()
        self.g = np.asarray(s0.gravity, float)
        self.owner = np.array(chain.tendon_segment, dtype=np.int64)
        self.m = int(self.owner.size)
        d = np.concatenate([s.tendon_distances for s in chain.segments])
        ang = np.concatenate([s.tendon_angles for s in chain.segments])
        self.caps = tuple(c.length for c in chain.caps)
        self.cap_length_of_tendon = np.array([sum(self.caps[:k]) for k in self.owner], dtype=float)
        self.segments = self._segments(chain, d, np.cos(ang), np.sin(ang))
        self.ndof = sum(s.ndof for s in self.segments)
        self.nz = sum(s.nz for s in self.segments)
        self.z_ref = self._z_reference()
        self._J0 = self._constant_jacobian()

    def _segments(self, chain, d, co, so) -> tuple:
        out, qo, zo, K = [], 0, 0, chain.n_segments
        for k, p in enumerate(chain.segments):
            ndof = 6 * (p.n_elements + 1)
            nz = ndof - 6 + (1 if (k == 0 and p.free_base_stretch) or (k > 0 and not self.continuous) else 0)
            N, wq = kin.shape_table(p.quadrature_points, p.element_length)
            idx = np.nonzero(self.owner >= k)[0]
            last = k == K - 1
            out.append(Segment(p, qo, ndof, zo, nz, N, wq, idx, np.ascontiguousarray(d[idx]),
                               np.ascontiguousarray(co[idx]), np.ascontiguousarray(so[idx]),
                               np.ascontiguousarray(p.volume_coeffs),
                               p.tool_offset if last else chain.caps[k].mass_offset,
                               p.tip_mass if last else chain.caps[k].mass))
            qo, zo = qo + ndof, zo + nz
        return tuple(out)

    # ----------------------------------------------------------------------------- coordinates
    def _has_mu(self, k: int) -> bool:
        s = self.segments[k]
        return s.nz == s.ndof - 5

    def _z_reference(self) -> np.ndarray:
        """Free coordinates of the straight, unloaded chain (every stretch 1)."""
        z = np.empty(self.nz)
        x0 = 0.0
        for k, s in enumerate(self.segments):
            q = kin.reference_q(s.params.n_elements, s.params.length, s.params.base_axis)
            q[0::6] += x0 * self.e1[0]
            q[1::6] += x0 * self.e1[1]
            q[2::6] += x0 * self.e1[2]
            j = s.zo
            if self._has_mu(k):
                z[j] = 1.0
                j += 1
            z[j:s.zo + s.nz] = q[6:]
            x0 += s.params.length + (self.caps[k] if k < len(self.caps) else 0.0)
        return z

    def _junction_args(self, z: np.ndarray, k: int):
        """(r, a, h, μ) of junction k (between segment k − 1 and k) at z."""
        prev, s = self.segments[k - 1], self.segments[k]
        end = prev.zo + prev.nz
        mu = z[s.zo] if self._has_mu(k) else 1.0
        return z[end - 6:end - 3], z[end - 3:end], self.caps[k - 1], mu

    def to_full(self, z: np.ndarray) -> np.ndarray:
        """q (ndof,) of z (nz,): the segments' node chains, each first node from the cap map (k ≥ 2)."""
        q = np.zeros(self.ndof)
        for k, s in enumerate(self.segments):
            j = s.zo + (1 if self._has_mu(k) else 0)
            q[s.qo + 6:s.qo + s.ndof] = z[j:s.zo + s.nz]
            if k == 0:
                q[3:6] = self.e1 * (z[0] if self._has_mu(0) else 1.0)
            else:
                r, a, h, mu = self._junction_args(z, k)
                q[s.qo:s.qo + 6] = junction.node(r, a, h, mu, self.continuous)
        return q

    def segment_q(self, q: np.ndarray, k: int) -> np.ndarray:
        s = self.segments[k]
        return q[s.qo:s.qo + s.ndof]

    def _constant_jacobian(self) -> np.ndarray:
        """The part of J = ∂q/∂z that does not depend on z: the identity rows of every segment's free nodes and
        segment 1's base stretch column."""
        J = np.zeros((self.ndof, self.nz))
        for k, s in enumerate(self.segments):
            j = s.zo + (1 if self._has_mu(k) else 0)
            J[s.qo + 6:s.qo + s.ndof, j:s.zo + s.nz] = np.eye(s.ndof - 6)
        if self._has_mu(0):
            J[3:6, 0] = self.e1
        return J

    def jacobian(self, z: np.ndarray) -> np.ndarray:
        """J = ∂q/∂z (ndof, nz) (module docstring)."""
        J = self._J0.copy()
        for k in range(1, len(self.segments)):
            s = self.segments[k]
            _, a, h, mu = self._junction_args(z, k)
            Jj = junction.jacobian(a, h, mu, self.continuous)
            end = self.segments[k - 1].zo + self.segments[k - 1].nz
            J[s.qo:s.qo + 6, end - 6:end] = Jj[:, :6]
            if self._has_mu(k):
                J[s.qo:s.qo + 6, s.zo] = Jj[:, 6]
        return J

    def _add_curvature(self, z: np.ndarray, Q: np.ndarray, Hz: np.ndarray) -> None:
        """Add every junction's Σ g_i ∇²Φ_i into Hz (nz, nz) (in place)."""
        for k in range(1, len(self.segments)):
            s = self.segments[k]
            _, a, h, mu = self._junction_args(z, k)
            C = junction.curvature(Q[s.qo:s.qo + 6], a, h, mu, self.continuous)
            end = s.zo                   # segment k − 1's z ends where segment k's starts (with μ_k first)
            w = 7 if self._has_mu(k) else 6
            Hz[end - 6:end - 6 + w, end - 6:end - 6 + w] += C[:w, :w]

    # ----------------------------------------------------------------------------- potential
    def segment_loads(self, k: int, T: np.ndarray, pressures: np.ndarray, F: np.ndarray, load: float = 1.0):
        """Arguments of segment k's assembly at ``load`` × (T (m,) [N], its pressure [Pa], F (3,) [N], gravity):
        (ea, ei, pa, mg, T_k, end load (3,) [N])."""
        s = self.segments[k]
        p = s.params
        pr = float(pressures[k]) * load
        law = p.stiffness
        ea, ei = law.coefficients(pr) if law.pressure_dependent else (law.ea, law.ei)
        end = s.end_mass * self.g * load + (F * load if k == len(self.segments) - 1 else 0.0)
        return (np.ascontiguousarray(ea), np.ascontiguousarray(ei), pr * s.vc, p.line_mass * self.g * load,
                np.ascontiguousarray(T[s.tendons] * load), np.ascontiguousarray(end, dtype=float))

    def loads(self, T, pressures, F, load: float = 1.0) -> tuple:
        """Every segment's :meth:`segment_loads` (constant within a solve: computed once per Newton loop)."""
        return tuple(self.segment_loads(k, T, pressures, F, load) for k in range(len(self.segments)))

    def evaluate(self, z, T, pressures, F, *, hessian: bool = True, lengths: int = 0, load: float = 1.0,
                 loads: tuple | None = None):
        """(Π [J], ∇_z Π (nz,), ∇²_z Π (nz, nz) or None, l (m,) [m], ∂l/∂z (m, nz)) at z; Π = inf (the rest None)
        outside the model's domain.  ``lengths`` as the assembly's ``need_lengths`` (0: none, 1: values,
        2: values and gradients).  ``loads``: :meth:`loads` of (T, pressures, F, load), when already known."""
        if not np.all(np.isfinite(z)) or not self._junctions_ok(z):
            return np.inf, None, None, None, None
        loads = self.loads(T, pressures, F, load) if loads is None else loads
        q = self.to_full(z)
        energy, Q = 0.0, np.zeros(self.ndof)
        K = np.zeros((self.ndof, self.ndof)) if hessian else None
        lc, Jl = self.cap_length_of_tendon.copy(), np.zeros((self.m, self.ndof))
        for k, s in enumerate(self.segments):
            ea, ei, pa, mg, Tk, end = loads[k]
            E_k, Q_k, K_k, lc_k, Jl_k, _, _ = assemble(
                np.ascontiguousarray(self.segment_q(q, k)), s.params.n_elements, s.N, s.wq, ea, ei, pa, mg,
                self.E, s.d, s.co, s.so, Tk, s.end_offset, end, hessian, lengths)
            if not np.isfinite(E_k):
                return np.inf, None, None, None, None
            energy += E_k
            sl = slice(s.qo, s.qo + s.ndof)
            Q[sl] = Q_k
            if hessian:
                K[sl, sl] = K_k
            lc[s.tendons] += lc_k
            Jl[s.tendons, sl] = Jl_k
        J = self.jacobian(z)
        Hz = None
        if hessian:
            Hz = J.T @ K @ J
            self._add_curvature(z, Q, Hz)
        return energy, J.T @ Q, Hz, (lc if lengths else None), (Jl @ J if lengths == 2 else None)

    def _junctions_ok(self, z: np.ndarray) -> bool:
        """The cap map needs a segment end slope with |a| ≥ the assembly's stretch floor and a positive base
        stretch μ (the assembly then checks the rest)."""
        from .assembly import STRETCH_MIN
        for k in range(1, len(self.segments)):
            _, a, _, mu = self._junction_args(z, k)
            if not (float(np.sqrt(a @ a)) >= STRETCH_MIN and mu >= STRETCH_MIN):
                return False
        return True

    # ----------------------------------------------------------------------------- tip
    def tip(self, z: np.ndarray) -> np.ndarray:
        """Tool point p_end = r + h t of the distal segment (3,) [m] (its last node: the last 6 entries of z)."""
        return kin.tip_position(z[-6:], self.segments[-1].end_offset)

    def tip_jacobian(self, z: np.ndarray) -> np.ndarray:
        """∂p_end/∂z (3, nz)."""
        J = np.zeros((3, self.nz))
        J[:, -6:] = kin.tip_position_jacobian(z[-6:], self.segments[-1].end_offset)
        return J
