r"""Rigid caps as a nonlinear 6-DOF reduction (``docs/fem.md`` §5).

The base cap is clamped: every node of the base face is fixed.  The distal cap is rigid: every node
of the distal face (vertices and Hex2 edge/face nodes) is placed exactly

.. math::  x_i = X_c + u_c + R\,(X_i - X_c), \qquad r_i := R\,(X_i - X_c),

with the cap centre ``X_c = (L, 0, 0)``.  The reduced unknowns are ``q = [free nodal displacements,
u_c (3), θ (3)]``; a Newton increment moves a cap node by :math:`\delta x_i = \delta u_c - [r_i]_\times
\delta\theta` (spatial rotation vector), so the prolongation ``P(q)`` is the identity on free DOFs and
``[I, -[r_i]_×]`` on cap rows, and the rotation is updated exactly, :math:`R \leftarrow \exp([\Delta\theta]_\times) R`.

Reduced residual and tangent (Galerkin, not ``skfem.mpc``):

.. math::

    r_q = P^T r, \qquad K_q = P^T K P + \sum_i \big(r_i\,\rho_i^T - (\rho_i \cdot r_i)\,I\big)_{\theta\theta},

where :math:`\rho_i` is the nodal residual force on cap node ``i``.  The last term is the geometric
stiffness of the rigid link: :math:`\partial(r_i \times \rho_i)/\partial\theta = r_i\rho_i^T - (\rho_i\cdot r_i)I`
because :math:`\delta r_i = \delta\theta \times r_i`.  The same rule holds for any force acting at a
cap point ``X_c + R a`` (tip force, cap weight, tendon anchor) with :math:`r = R a`.

The condensed cap stiffness (Schur complement of ``K_q`` on the 6 cap DOFs) is the consistent tip
stiffness of the loaded state; its inverse is the tip compliance.

**Cost.**  ``P`` is the identity on the free DOFs, so ``Pᵀ K P`` needs no sparse triple product: with the
DOFs split into free (f), cap (c) and base (dropped), ``K_q = [[K_ff, K_fc P_c], [P_cᵀ K_cf, P_cᵀ K_cc P_c]]``
with ``P_c`` the (3 n_cap × 6) rows of ``P`` on the cap DOFs.  :class:`_ReductionMap` finds once, for the
fixed pattern of ``K``, where each entry of ``K`` goes in ``K_q``; every reduction is then a gather of
``K_ff``, six weighted sums for ``K_fc P_c`` and ``P_cᵀ K_cf``, and a small dense product
(:meth:`RigidCapReduction.reduce`; ``reduce_reference`` keeps the sparse triple product it is tested
against).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..errors import InputError

from ..sparse_keys import csr_index, unique_keys

__all__ = ["RigidCapReduction", "expm_so3", "log_so3", "point_geometric", "point_jacobian", "skew"]


def skew(v) -> np.ndarray:
    """Cross-product matrix ``[v]_×`` of a 3-vector (``skew(a) @ b == a × b``)."""
    x, y, z = np.asarray(v, float)
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def expm_so3(w) -> np.ndarray:
    """Rotation matrix ``exp([w]_×)`` (Rodrigues; exact, series near 0)."""
    w = np.asarray(w, float)
    th = float(np.linalg.norm(w))
    W = skew(w)
    if th < 1e-6:
        return np.eye(3) + W + 0.5 * W @ W
    return np.eye(3) + np.sin(th) / th * W + (1 - np.cos(th)) / th ** 2 * W @ W


def log_so3(R: np.ndarray) -> np.ndarray:
    """Rotation vector ``w`` with ``expm_so3(w) == R`` (|w| < π)."""
    c = np.clip((np.trace(R) - 1) / 2, -1.0, 1.0)
    th = np.arccos(c)
    v = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    if th < 1e-8:
        return 0.5 * v
    if np.pi - th < 1e-6:  # pragma: no cover - near half turn
        w, V = np.linalg.eigh(0.5 * (R + R.T))
        axis = V[:, np.argmax(w)]
        return th * axis * np.sign(axis @ v if abs(axis @ v) > 0 else 1.0)
    return th / (2 * np.sin(th)) * v


def point_jacobian(r: np.ndarray) -> np.ndarray:
    """``∂x/∂[u_c, θ]`` of a cap point at spatial offset ``r = R a``: the 3×6 block ``[I, -[r]_×]``."""
    return np.hstack([np.eye(3), -skew(r)])


def point_geometric(r: np.ndarray, rho: np.ndarray) -> np.ndarray:
    """θθ geometric stiffness ``r ρᵀ − (ρ·r) I`` of a residual force ``ρ`` acting at offset ``r``."""
    return np.outer(r, rho) - float(rho @ r) * np.eye(3)


class RigidCapReduction:
    """Index bookkeeping and the prolongation ``P`` of the clamped-base / rigid-distal-cap model.

    Parameters
    ----------
    X : ndarray (3, n_nodes)
        Reference node positions [m].
    base_nodes, cap_nodes : ndarray of int
        Nodes of the clamped base face and of the rigid distal face.
    X_c : ndarray (3,)
        Reference cap centre [m].
    """

    def __init__(self, X: np.ndarray, base_nodes: np.ndarray, cap_nodes: np.ndarray, X_c):
        n = X.shape[1]
        self.n_nodes = n
        self.X = X
        self.X_c = np.asarray(X_c, float)
        self.base_nodes = np.asarray(base_nodes)
        self.cap_nodes = np.asarray(cap_nodes)
        kind = np.zeros(n, int)
        kind[self.base_nodes] = 1
        kind[self.cap_nodes] = 2
        self.free_nodes = np.flatnonzero(kind == 0)
        self.n_free = 3 * self.free_nodes.size
        self.n_q = self.n_free + 6
        self.free_dofs = (3 * self.free_nodes[:, None] + np.arange(3)).ravel()
        self.cap_dofs = (3 * self.cap_nodes[:, None] + np.arange(3)).ravel()
        self.A_cap = X[:, self.cap_nodes] - self.X_c[:, None]  # reference offsets (3, nc)
        # q index of the translational DOFs of each node (-1 if not free)
        self.q_of_node = -np.ones(n, np.int64)
        self.q_of_node[self.free_nodes] = 3 * np.arange(self.free_nodes.size)

    @property
    def cap_slice(self) -> slice:
        return slice(self.n_free, self.n_free + 6)

    def place(self, U: np.ndarray, uc: np.ndarray, R: np.ndarray) -> None:
        """Set the displacements of base (zero) and cap nodes (rigid motion) in ``U`` in place."""
        U[:, self.base_nodes] = 0.0
        U[:, self.cap_nodes] = uc[:, None] + (R - np.eye(3)) @ self.A_cap

    def prolongation(self, R: np.ndarray, transpose: bool = False) -> sp.csr_matrix:
        """``P = ∂u/∂q`` at cap rotation ``R``; shape ``(3 n_nodes, n_q)`` (``Pᵀ`` if ``transpose``)."""
        nf = self.n_free
        rows = [self.free_dofs]
        cols = [np.arange(nf)]
        vals = [np.ones(nf)]
        r = R @ self.A_cap  # (3, nc)
        nc = r.shape[1]
        # translational part: identity
        for i in range(3):
            rows.append(3 * self.cap_nodes + i)
            cols.append(np.full(nc, nf + i))
            vals.append(np.ones(nc))
        # rotational part: -skew(r) ; -skew(r)[i, j] = -eps_ikj r_k = eps_ijk r_k
        eps = np.zeros((3, 3, 3))
        eps[0, 1, 2] = eps[1, 2, 0] = eps[2, 0, 1] = 1
        eps[0, 2, 1] = eps[2, 1, 0] = eps[1, 0, 2] = -1
        for i in range(3):
            for j in range(3):
                v = np.einsum("k,kn->n", eps[i, j], r)
                rows.append(3 * self.cap_nodes + i)
                cols.append(np.full(nc, nf + 3 + j))
                vals.append(v)
        r_, c_, v_ = np.concatenate(rows), np.concatenate(cols), np.concatenate(vals)
        if transpose:  # build Pᵀ directly in CSR (scipy's P.T is CSC: a conversion per product)
            return sp.csr_matrix((v_, (c_, r_)), shape=(self.n_q, 3 * self.n_nodes))
        return sp.csr_matrix((v_, (r_, c_)), shape=(3 * self.n_nodes, self.n_q))

    def cap_rows(self, R: np.ndarray) -> np.ndarray:
        """``P_c``: the rows of ``P`` on the cap DOFs, dense ``(3 n_cap, 6)`` in ``cap_dofs`` order."""
        r = R @ self.A_cap  # (3, nc)
        nc = r.shape[1]
        Pc = np.zeros((nc, 3, 6))
        Pc[:, 0, 0] = Pc[:, 1, 1] = Pc[:, 2, 2] = 1.0
        # -skew(r) = [[0, z, -y], [-z, 0, x], [y, -x, 0]]
        x, y, z = r
        Pc[:, 0, 4], Pc[:, 0, 5] = z, -y
        Pc[:, 1, 3], Pc[:, 1, 5] = -z, x
        Pc[:, 2, 3], Pc[:, 2, 4] = y, -x
        return Pc.reshape(3 * nc, 6)

    def restrict(self, v: np.ndarray, R: np.ndarray, Pc: np.ndarray | None = None) -> np.ndarray:
        """``Pᵀ v`` of a full nodal vector ``v`` (3n,) → (n_q,); ``Pc``: :meth:`cap_rows` of ``R`` if known."""
        Pc = self.cap_rows(R) if Pc is None else Pc
        out = np.empty(self.n_q)
        out[: self.n_free] = v[self.free_dofs]
        out[self.n_free:] = Pc.T @ v[self.cap_dofs]
        return out

    def reduce(self, K: sp.spmatrix | None, r: np.ndarray, R: np.ndarray, extra_cc: np.ndarray | None = None):
        """Reduced residual ``Pᵀ r`` and tangent ``Pᵀ K P`` + rigid-link geometric stiffness (see the module
        docstring, "Cost"; the same as :meth:`reduce_reference` to round-off), plus ``extra_cc`` (6, 6) on the
        cap block if given (point loads' terms).

        Parameters
        ----------
        K : csr (3n, 3n) or None
        r : ndarray (3n,)  — full residual (internal − external) [N]
        R : ndarray (3, 3) — current cap rotation

        Returns
        -------
        r_q : ndarray (n_q,)
        K_q : csr_matrix (n_q, n_q) or None
        """
        Pc = self.cap_rows(R)
        rq = self.restrict(r, R, Pc)
        if K is None:
            return rq, None
        K = K.tocsr()
        m = getattr(self, "_map", None)
        if m is None or not m.matches(K):
            m = self._map = _ReductionMap(self, K)
        data = m.reduce(K.data, Pc)
        data[m.pos_cc[3:, 3:].ravel()] += self._rigid_link(r, R).ravel()
        if extra_cc is not None:
            data[m.pos_cc.ravel()] += np.asarray(extra_cc, float).ravel()
        Kq = sp.csr_matrix((data, m.indices, m.indptr), shape=(self.n_q, self.n_q))
        Kq._reduction_map, Kq._written_on = m, m.target     # for BellowsModel._canonical: no compare, no copy
        return rq, Kq

    def _rigid_link(self, r: np.ndarray, R: np.ndarray) -> np.ndarray:
        """θθ geometric stiffness Σ_i r_i ρ_iᵀ − (ρ_i · r_i) I of the cap nodes' residual forces (3, 3)."""
        rho = r.reshape(-1, 3)[self.cap_nodes].T  # (3, nc)
        rr = R @ self.A_cap
        return rr @ rho.T - np.sum(rho * rr) * np.eye(3)

    def reduce_reference(self, K: sp.spmatrix | None, r: np.ndarray, R: np.ndarray):
        """:meth:`reduce` by sparse products with the prolongation (the reference it is tested against)."""
        PT = self.prolongation(R, transpose=True)
        rq = PT @ r
        if K is None:
            return rq, None
        P = self.prolongation(R)
        Kq = PT @ (K.tocsr() @ P)
        G = self._rigid_link(r, R)
        s = self.n_free + 3
        Kq = Kq + sp.csr_matrix((G.ravel(), (np.repeat(np.arange(s, s + 3), 3), np.tile(np.arange(s, s + 3), 3))),
                                shape=Kq.shape)
        return rq, Kq.tocsr()

    def cap_point_rows(self, R: np.ndarray, a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Spatial offset ``r = R a`` and 3×6 Jacobian block (columns ``cap_slice``) of a cap point."""
        r = R @ np.asarray(a, float)
        return r, point_jacobian(r)


class _ReductionMap:
    """Where every entry of a fixed-pattern ``K`` (3n × 3n CSR) goes in ``K_q = Pᵀ K P`` (module docstring).

    Built once per pattern.  ``K_q``'s pattern: the free–free entries of ``K``, the 6 cap columns on every free
    row coupled to a cap DOF, the 6 cap rows on every free column coupled to a cap DOF, and the full 6 × 6 cap
    block (always present, so the rigid-link and point-load terms have their places).
    """

    def __init__(self, red: RigidCapReduction, K: sp.csr_matrix):
        n = K.shape[0]
        self.indptr_k, self.indices_k = K.indptr, K.indices
        nf, nq = red.n_free, red.n_q
        qd = -np.ones(n, np.int64)
        qd[red.free_dofs] = np.arange(nf)
        cd = -np.ones(n, np.int64)
        cd[red.cap_dofs] = np.arange(red.cap_dofs.size)
        rows = np.repeat(np.arange(n), np.diff(K.indptr))
        cols = K.indices.astype(np.int64)
        ff = (qd[rows] >= 0) & (qd[cols] >= 0)
        fc = (qd[rows] >= 0) & (cd[cols] >= 0)
        cf = (cd[rows] >= 0) & (qd[cols] >= 0)
        cc = (cd[rows] >= 0) & (cd[cols] >= 0)
        self.src_ff = np.flatnonzero(ff)
        self.src_fc, self.src_cf, self.src_cc = np.flatnonzero(fc), np.flatnonzero(cf), np.flatnonzero(cc)
        # K_fc P_c: free row q, summed over the cap columns; rows_fc = the distinct free rows, slot_fc per entry
        self.rows_fc, self.slot_fc = np.unique(qd[rows[fc]], return_inverse=True)
        self.cap_fc = cd[cols[fc]]
        self.cols_cf, self.slot_cf = np.unique(qd[cols[cf]], return_inverse=True)
        self.cap_cf = cd[rows[cf]]
        self.cc_r, self.cc_c = cd[rows[cc]], cd[cols[cc]]
        self.n_cap = red.cap_dofs.size
        six = np.arange(6)
        keys = np.concatenate([
            qd[rows[ff]] * nq + qd[cols[ff]],
            (self.rows_fc[:, None] * nq + nf + six[None, :]).ravel(),
            ((nf + six[:, None]) * nq + self.cols_cf[None, :]).ravel(),
            ((nf + six[:, None]) * nq + nf + six[None, :]).ravel()])
        ukeys = unique_keys(keys)
        self.indptr, self.indices = csr_index(ukeys, nq)
        self.keys = ukeys                                  # row * n_q + column of each entry of K_q, sorted
        self.target = None                                 # the pattern token of :meth:`retarget`
        pos = np.searchsorted(ukeys, keys)
        a, b, c = self.src_ff.size, self.rows_fc.size * 6, self.cols_cf.size * 6
        self.pos_ff = pos[:a]
        self.pos_fc = pos[a:a + b]                         # (rows_fc, 6) in C order
        self.pos_cf = pos[a + b:a + b + c]                 # (6, cols_cf)
        self.pos_cc = pos[a + b + c:].reshape(6, 6)
        self.nnz = ukeys.size

    def retarget(self, keys: np.ndarray, indptr: np.ndarray, indices: np.ndarray, target=None) -> None:
        """Write ``K_q`` on a larger pattern from now on: ``keys`` (sorted row * n_q + column, a superset of
        this map's) with its CSR ``indptr``/``indices`` (the model-wide pattern that also holds the tendons'
        Hessian blocks, :meth:`fem_reference.BellowsModel._canonical`): the positions are composed once, so
        that no copy into that pattern is made per evaluation.  ``target``: the caller's token of that pattern,
        given to every ``K_q`` written on it (its attribute ``_written_on``)."""
        where = np.searchsorted(keys, self.keys)
        if where.size and (where[-1] >= keys.size or not np.array_equal(keys[where], self.keys)):
            raise InputError("retarget: the pattern does not contain this reduction's entries")
        self.pos_ff, self.pos_fc, self.pos_cf, self.pos_cc = (where[self.pos_ff], where[self.pos_fc],
                                                              where[self.pos_cf], where[self.pos_cc])
        self.keys, self.indptr, self.indices, self.nnz = keys, indptr, indices, keys.size
        self.target = target

    def matches(self, K: sp.csr_matrix) -> bool:
        """True when ``K`` has the pattern this map was built for."""
        return ((K.indptr is self.indptr_k or np.array_equal(K.indptr, self.indptr_k))
                and (K.indices is self.indices_k or np.array_equal(K.indices, self.indices_k)))

    def reduce(self, kdata: np.ndarray, Pc: np.ndarray) -> np.ndarray:
        """``K_q``'s data from ``K``'s data and ``P_c`` (3 n_cap, 6)."""
        data = np.zeros(self.nnz)
        data[self.pos_ff] = kdata[self.src_ff]
        v = kdata[self.src_fc]
        fc = np.empty((self.rows_fc.size, 6))
        for j in range(6):
            fc[:, j] = np.bincount(self.slot_fc, weights=v * Pc[self.cap_fc, j], minlength=self.rows_fc.size)
        data[self.pos_fc] = fc.ravel()
        v = kdata[self.src_cf]
        cf = np.empty((6, self.cols_cf.size))
        for j in range(6):
            cf[j] = np.bincount(self.slot_cf, weights=v * Pc[self.cap_cf, j], minlength=self.cols_cf.size)
        data[self.pos_cf] = cf.ravel()
        Kcc = np.zeros((self.n_cap, self.n_cap))
        Kcc[self.cc_r, self.cc_c] = kdata[self.src_cc]
        data[self.pos_cc.ravel()] += (Pc.T @ Kcc @ Pc).ravel()
        return data
