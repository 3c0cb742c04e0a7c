r"""Compiled (numba) element kernels of the hyperelastic assembly (``docs/fem.md`` "Where the time goes").

:class:`HexKernel` computes, element by element, the internal force and the element tangent of
:class:`fem_reference.assembly.HexAssembler` with the material law of :class:`fem_reference.material.Material`
evaluated inline at each of the 27 Gauss points, and adds both straight into the global force vector and
the CSR data array through the precomputed scatter map.  Same formulation and quadrature as the numpy
reference path (``HexAssembler(kernel="numpy")``), which is kept and against which this kernel is tested
(``tests/test_fem/test_fem_kernels.py``):

.. math::

    f^{int}_{a i} = \sum_q P_{iJ}\,\partial_J N_a\, dx_q, \qquad
    K_{a i, b k} = \sum_q \partial_J N_a\, A_{iJkL}\, \partial_L N_b\, dx_q .

Per Gauss point: ``H[i, J, k, b] = Σ_L A_iJkL ∂_L N_b dx`` (729 × 3 multiply-adds), then
``K[a, i, k, b] += Σ_J ∂_J N_a H[i, J, k, b]`` for ``b >= a`` only; the element matrix is symmetric
(``A_iJkL = A_kLiJ``: hyperelastic), so the lower triangle is filled by mirroring before the scatter.  No temporary of size
``A × points × elements`` is formed (the numpy path builds ``(chunk, 81, 243)`` arrays), and the
kernel uses no BLAS, so it does not start OpenBLAS threads that compete with PARDISO's threads and
other jobs on a small machine (that contention made the numpy path up to ~25× slower inside a solve;
measured, ``docs/fem.md``).

The kernels never see an unchecked array: :class:`HexKernel` converts and checks the per-mesh arrays
(dtype, contiguity, shapes, index ranges, finiteness) once at construction and ``U`` on every call.

Material codes: ``0`` decoupled neo-Hookean (plus the decoupled Mooney–Rivlin ``C01`` term when
``c01 > 0``), ``1`` the compressible neo-Hookean of scikit-fem ex43 (formulas in
:mod:`fem_reference.material`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["MATERIAL_CODES", "HexKernel", "PressureKernel"]

MATERIAL_CODES = {"decoupled": 0, "ex43": 1}


@njit(cache=True)
def _material_point(F, mode, mu, kappa, c01, tangent, P, A):
    """First Piola–Kirchhoff stress ``P`` (3, 3) and, if ``tangent``, ``A = ∂P/∂F`` (3, 3, 3, 3) at one
    point (written in place); returns ``J = det F``.  Nothing is written when ``J <= 0`` or NaN."""
    c00 = F[1, 1] * F[2, 2] - F[1, 2] * F[2, 1]
    c01_ = F[1, 2] * F[2, 0] - F[1, 0] * F[2, 2]
    c02 = F[1, 0] * F[2, 1] - F[1, 1] * F[2, 0]
    c10 = F[0, 2] * F[2, 1] - F[0, 1] * F[2, 2]
    c11 = F[0, 0] * F[2, 2] - F[0, 2] * F[2, 0]
    c12 = F[0, 1] * F[2, 0] - F[0, 0] * F[2, 1]
    c20 = F[0, 1] * F[1, 2] - F[0, 2] * F[1, 1]
    c21 = F[0, 2] * F[1, 0] - F[0, 0] * F[1, 2]
    c22 = F[0, 0] * F[1, 1] - F[0, 1] * F[1, 0]
    J = F[0, 0] * c00 + F[0, 1] * c01_ + F[0, 2] * c02
    if not J > 0.0:
        return J
    T = np.empty((3, 3))  # F^{-T}
    T[0, 0] = c00 / J
    T[0, 1] = c01_ / J
    T[0, 2] = c02 / J
    T[1, 0] = c10 / J
    T[1, 1] = c11 / J
    T[1, 2] = c12 / J
    T[2, 0] = c20 / J
    T[2, 1] = c21 / J
    T[2, 2] = c22 / J
    if mode == 1:  # ex43: P = mu F + (lam lnJ - mu) F^-T
        lam = kappa - 2.0 * mu / 3.0
        lnJ = math.log(J)
        s = lam * lnJ - mu
        for i in range(3):
            for j in range(3):
                P[i, j] = mu * F[i, j] + s * T[i, j]
        if tangent:
            for i in range(3):
                for j in range(3):
                    for k in range(3):
                        for l in range(3):
                            v = lam * T[i, j] * T[k, l] - s * T[i, l] * T[k, j]
                            if i == k and j == l:
                                v += mu
                            A[i, j, k, l] = v
        return J
    # decoupled neo-Hookean, shear modulus mu1 = mu - 2 c01 on the I1 term
    mu1 = mu - 2.0 * c01
    I1 = 0.0
    for i in range(3):
        for j in range(3):
            I1 += F[i, j] * F[i, j]
    a = J ** (-2.0 / 3.0)
    c1 = mu1 * a
    vol = kappa * (J - 1.0) * J
    for i in range(3):
        for j in range(3):
            P[i, j] = c1 * (F[i, j] - I1 / 3.0 * T[i, j]) + vol * T[i, j]
    if tangent:
        cTT = (2.0 / 9.0) * c1 * I1 + kappa * (2.0 * J * J - J)
        cTx = c1 * I1 / 3.0 - kappa * (J * J - J)
        cFF = (2.0 / 3.0) * c1
        for i in range(3):
            for j in range(3):
                for k in range(3):
                    for l in range(3):
                        v = (-cFF * (T[i, j] * F[k, l] + F[i, j] * T[k, l]) + cTT * T[i, j] * T[k, l]
                             + cTx * T[i, l] * T[k, j])
                        if i == k and j == l:
                            v += c1
                        A[i, j, k, l] = v
    if c01 > 0.0:  # C01 (J^{-4/3} I2 - 3)
        b = J ** (-4.0 / 3.0)
        C = np.zeros((3, 3))  # F^T F
        B = np.zeros((3, 3))  # F F^T
        for i in range(3):
            for j in range(3):
                for m in range(3):
                    C[i, j] += F[m, i] * F[m, j]
                    B[i, j] += F[i, m] * F[j, m]
        CC = 0.0
        for i in range(3):
            for j in range(3):
                CC += C[i, j] * C[j, i]
        I2 = 0.5 * (I1 * I1 - CC)
        G = np.empty((3, 3))  # I1 F - F C
        for i in range(3):
            for j in range(3):
                fc = 0.0
                for m in range(3):
                    fc += F[i, m] * C[m, j]
                G[i, j] = I1 * F[i, j] - fc
        for i in range(3):
            for j in range(3):
                P[i, j] += c01 * (2.0 * b * G[i, j] - (4.0 / 3.0) * b * I2 * T[i, j])
        if tangent:
            for i in range(3):
                for j in range(3):
                    for k in range(3):
                        for l in range(3):
                            dG = 2.0 * F[i, j] * F[k, l] - F[i, l] * F[k, j]
                            if i == k:
                                dG -= C[l, j]
                            if j == l:
                                dG -= B[i, k]
                                if i == k:
                                    dG += I1
                            v = (2.0 * b * dG - (8.0 / 3.0) * b * G[i, j] * T[k, l]
                                 + (16.0 / 9.0) * b * I2 * T[i, j] * T[k, l]
                                 - (8.0 / 3.0) * b * T[i, j] * G[k, l]
                                 + (4.0 / 3.0) * b * I2 * T[i, l] * T[k, j])
                            A[i, j, k, l] += c01 * v
    return J


@njit(cache=True)
def _gather(U, edofs, e, ue):
    """The 27 nodal displacements of element ``e``: ``ue[i, a] = U[i, edofs[a, e]]`` (in place)."""
    for a in range(27):
        n = edofs[a, e]
        for i in range(3):
            ue[i, a] = U[i, n]


@njit(cache=True)
def _deformation_gradient(ue, D, F):
    """F = I + Σ_a u_a ⊗ ∇N_a at one point (in place); ``D[J, a] = ∂N_a/∂X_J`` (3, 27)."""
    for i in range(3):
        for j in range(3):
            s = 1.0 if i == j else 0.0
            for a in range(27):
                s += ue[i, a] * D[j, a]
            F[i, j] = s


@njit(cache=True)
def _cofactor(F, C):
    """Cofactor ``C = J F^{-T}`` of one 3×3 ``F`` (in place); returns ``J = det F``."""
    C[0, 0] = F[1, 1] * F[2, 2] - F[1, 2] * F[2, 1]
    C[0, 1] = F[1, 2] * F[2, 0] - F[1, 0] * F[2, 2]
    C[0, 2] = F[1, 0] * F[2, 1] - F[1, 1] * F[2, 0]
    C[1, 0] = F[0, 2] * F[2, 1] - F[0, 1] * F[2, 2]
    C[1, 1] = F[0, 0] * F[2, 2] - F[0, 2] * F[2, 0]
    C[1, 2] = F[0, 1] * F[2, 0] - F[0, 0] * F[2, 1]
    C[2, 0] = F[0, 1] * F[1, 2] - F[0, 2] * F[1, 1]
    C[2, 1] = F[0, 2] * F[1, 0] - F[0, 0] * F[1, 2]
    C[2, 2] = F[0, 0] * F[1, 1] - F[0, 1] * F[1, 0]
    return F[0, 0] * C[0, 0] + F[0, 1] * C[0, 1] + F[0, 2] * C[0, 2]


@njit(cache=True)
def _hex_kernel(U, edofs, dphi, dx, mode, mu, kappa, c01, tangent, emap, f, data, pb, Mi):
    """Element loop of :class:`HexKernel` (arrays already checked there).  Returns ``(ok, jmin)``.

    ``pb`` (ne, nq, 4) and ``Mi`` (ne, 4, 4): the element pressure basis at the Gauss points and the inverse
    of its mass matrix — the mixed (u–p, P1-disc) volumetric term; empty (0, …) for the displacement element.
    """
    ne = dx.shape[0]
    nq = dx.shape[1]
    mixed = pb.shape[0] > 0
    kpt = 0.0 if mixed else kappa  # the pointwise volumetric term is replaced by the projected one
    ue = np.empty((3, 27))
    F = np.empty((3, 3))
    P = np.empty((3, 3))
    A = np.empty((3, 3, 3, 3))
    Dw = np.empty((3, 27))
    H = np.empty((3, 3, 3, 27))  # [i, J, k, b]
    Ke = np.empty((27, 3, 3, 27))  # [a, i, k, b]
    fe = np.empty((27, 3))
    Fq = np.empty((nq, 3, 3))
    Cq = np.empty((nq, 3, 3))  # cofactors J F^{-T}
    Jq = np.empty(nq)
    pq = np.empty(nq)  # projected pressure p_h = κ(ΠJ − 1) at the Gauss points
    G = np.empty((4, 27, 3))  # ∂(∫ N_m J dV)/∂u_{a i}
    Gt = np.empty((4, 27, 3))  # Mi G
    bm = np.empty(4)
    cm = np.empty(4)
    jmin = np.inf
    for e in range(ne):
        _gather(U, edofs, e, ue)
        fe[:] = 0.0
        if tangent:
            Ke[:] = 0.0
        if mixed:
            # first pass: J at every point, its projection ΠJ on {1, X, Y, Z} and the pressure p_h
            bm[:] = 0.0
            if tangent:
                G[:] = 0.0
            for q in range(nq):
                D = dphi[e, q]
                _deformation_gradient(ue, D, Fq[q])
                Jq[q] = _cofactor(Fq[q], Cq[q])
                if not Jq[q] > 0.0:
                    return False, Jq[q]
                w = dx[e, q]
                for m in range(4):
                    bm[m] += pb[e, q, m] * (Jq[q] - 1.0) * w  # Π(J − 1): exactly 0 at J = 1
                if tangent:
                    for a in range(27):
                        for i in range(3):
                            g = (Cq[q, i, 0] * D[0, a] + Cq[q, i, 1] * D[1, a] + Cq[q, i, 2] * D[2, a]) * w
                            for m in range(4):
                                G[m, a, i] += pb[e, q, m] * g
            for m in range(4):
                s = 0.0
                for n in range(4):
                    s += Mi[e, m, n] * bm[n]
                cm[m] = s
            for q in range(nq):
                s = 0.0
                for m in range(4):
                    s += pb[e, q, m] * cm[m]
                pq[q] = kappa * s
        for q in range(nq):
            D = dphi[e, q]  # (3, 27): D[J, a] = dN_a/dX_J
            if mixed:
                for i in range(3):
                    for j in range(3):
                        F[i, j] = Fq[q, i, j]
            else:
                _deformation_gradient(ue, D, F)
            J = _material_point(F, mode, mu, kpt, c01, tangent, P, A)
            if not J > 0.0:
                return False, J
            if J < jmin:
                jmin = J
            if mixed:
                # P += p_h J F^{-T};  A += p_h J (F^{-T}_iJ F^{-T}_kL − F^{-T}_iL F^{-T}_kJ)
                ph = pq[q]
                for i in range(3):
                    for j in range(3):
                        P[i, j] += ph * Cq[q, i, j]
                if tangent:
                    sJ = ph / J
                    for i in range(3):
                        for j in range(3):
                            for k in range(3):
                                for l in range(3):
                                    A[i, j, k, l] += sJ * (Cq[q, i, j] * Cq[q, k, l] - Cq[q, i, l] * Cq[q, k, j])
            w = dx[e, q]
            for a in range(27):
                d0 = D[0, a] * w
                d1 = D[1, a] * w
                d2 = D[2, a] * w
                for i in range(3):
                    fe[a, i] += P[i, 0] * d0 + P[i, 1] * d1 + P[i, 2] * d2
            if not tangent:
                continue
            for L in range(3):
                for b in range(27):
                    Dw[L, b] = D[L, b] * w
            for i in range(3):
                for j in range(3):
                    for k in range(3):
                        a0 = A[i, j, k, 0]
                        a1 = A[i, j, k, 1]
                        a2 = A[i, j, k, 2]
                        for b in range(27):
                            H[i, j, k, b] = a0 * Dw[0, b] + a1 * Dw[1, b] + a2 * Dw[2, b]
            for a in range(27):
                d0 = D[0, a]
                d1 = D[1, a]
                d2 = D[2, a]
                for i in range(3):
                    for k in range(3):
                        for b in range(a, 27):
                            Ke[a, i, k, b] += d0 * H[i, 0, k, b] + d1 * H[i, 1, k, b] + d2 * H[i, 2, k, b]
        if mixed and tangent:
            # the projected pressure's own variation: κ Gᵀ M⁻¹ G (rank 4), upper triangle
            for m in range(4):
                for a in range(27):
                    for i in range(3):
                        s = 0.0
                        for n in range(4):
                            s += Mi[e, m, n] * G[n, a, i]
                        Gt[m, a, i] = s
            for a in range(27):
                for i in range(3):
                    for k in range(3):
                        for b in range(a, 27):
                            s = 0.0
                            for m in range(4):
                                s += Gt[m, a, i] * G[m, b, k]
                            Ke[a, i, k, b] += kappa * s
        for a in range(27):
            n3 = 3 * edofs[a, e]
            for i in range(3):
                f[n3 + i] += fe[a, i]
        if tangent:
            # lower triangle by symmetry, then one pass in the scatter map's row-major order: the writes of
            # a row stay in one CSR row (1.5x faster than mirroring each entry into another row; measured)
            for a in range(1, 27):
                for i in range(3):
                    for k in range(3):
                        for b in range(a):
                            Ke[a, i, k, b] = Ke[b, k, i, a]
            # emap[e, 3 a + i, 27 k + b]: position of K[(a, i), (b, k)] in the CSR data
            for a in range(27):
                for i in range(3):
                    r = 3 * a + i
                    for k in range(3):
                        for b in range(27):
                            data[emap[e, r, 27 * k + b]] += Ke[a, i, k, b]
    return True, jmin


class HexKernel:
    """The compiled assembly of one mesh: element arrays checked once, ``U`` checked on every call.

    Parameters
    ----------
    edofs : (27, ne) int — element nodes
    dphi : (ne, nq, 3, 27) float64 — ``∂N_a/∂X_J`` at the Gauss points [1/m]
    dx : (ne, nq) float64 — quadrature weight × |det DF| [m³]
    emap : (ne, 81, 81) int32 or int64 — position in the CSR data of ``K[(a, i), (b, k)]``, stored at
        ``[e, 3a+i, 27k+b]``
    nnz : int — length of the CSR data array
    n_nodes : int
    material : fem_reference.material.Material
    pressure_basis : (ne, nq, 4) float64 or None — the mixed element's pressure basis at the Gauss points
        (:func:`fem_reference.assembly.pressure_basis`); None: the displacement element (pointwise ``J``)
    pressure_mass_inv : (ne, 4, 4) float64 or None — inverse of ``Σ_q N N^T dx`` per element [1/m³]
    """

    def __init__(self, edofs, dphi, dx, emap, nnz: int, n_nodes: int, material, pressure_basis=None,
                 pressure_mass_inv=None):
        self.n_nodes = int(n_nodes)
        self.nnz = int(nnz)
        self.edofs = np.ascontiguousarray(edofs, dtype=np.int64)
        self.dphi = np.ascontiguousarray(dphi, dtype=np.float64)
        self.dx = np.ascontiguousarray(dx, dtype=np.float64)
        # the scatter map is the largest array (ne × 6561 entries): keep CsrPattern's int32 map, do not copy it
        emap = np.asarray(emap)
        self.emap = np.ascontiguousarray(emap, dtype=emap.dtype if emap.dtype in (np.int32, np.int64) else np.int64)
        if material.formulation not in MATERIAL_CODES:
            raise ValueError(f"no compiled kernel for the formulation {material.formulation!r}")
        self.mode = MATERIAL_CODES[material.formulation]
        self.params = (float(material.mu), float(material.kappa), float(material.c01))
        if not all(np.isfinite(self.params)) or self.params[0] <= 0 or self.params[1] <= 0 or self.params[2] < 0:
            raise ValueError(f"material constants {self.params} are not usable")
        ne, nq = self.dx.shape
        if (self.edofs.shape != (27, ne) or self.dphi.shape != (ne, nq, 3, 27)
                or self.emap.shape != (ne, 81, 81)):
            raise ValueError(f"kernel shapes: edofs {self.edofs.shape} (want (27, {ne})), dphi {self.dphi.shape} "
                             f"(want ({ne}, {nq}, 3, 27)), emap {self.emap.shape} (want ({ne}, 81, 81))")
        if ne and (self.edofs.min() < 0 or self.edofs.max() >= self.n_nodes):
            raise ValueError("element nodes outside the node range")
        if ne and (self.emap.min() < 0 or self.emap.max() >= self.nnz):
            raise ValueError("scatter map outside the CSR data array")
        if not (np.all(np.isfinite(self.dphi)) and np.all(np.isfinite(self.dx))):
            raise ValueError("shape-function gradients or weights are not finite")
        if (pressure_basis is None) != (pressure_mass_inv is None):
            raise ValueError("the mixed element needs both pressure_basis and pressure_mass_inv")
        if pressure_basis is None:
            self.pb, self.Mi = np.zeros((0, nq, 4)), np.zeros((0, 4, 4))
        else:
            if self.mode != 0:
                raise ValueError("the mixed element needs the decoupled volumetric energy κ/2 (J − 1)²")
            self.pb = np.ascontiguousarray(pressure_basis, dtype=np.float64)
            self.Mi = np.ascontiguousarray(pressure_mass_inv, dtype=np.float64)
            if self.pb.shape != (ne, nq, 4) or self.Mi.shape != (ne, 4, 4):
                raise ValueError(f"pressure basis {self.pb.shape} (want ({ne}, {nq}, 4)) or mass inverse "
                                 f"{self.Mi.shape} (want ({ne}, 4, 4))")
            if not (np.all(np.isfinite(self.pb)) and np.all(np.isfinite(self.Mi))):
                raise ValueError("the pressure basis or its mass inverse is not finite")

    @property
    def mixed(self) -> bool:
        """True for the mixed u–p element (projected volumetric term)."""
        return self.pb.shape[0] > 0

    def __call__(self, U: np.ndarray, tangent: bool = True):
        """Internal force and CSR tangent data at nodal displacements ``U`` (3, n_nodes) [m].

        Returns ``(ok, jmin, f, data)``: ``ok`` False when some ``det F <= 0`` or is NaN (``f``/``data``
        are then incomplete and ``jmin`` is the offending value); ``f`` (3 n_nodes,) [N];
        ``data`` (nnz,) [N/m] or None.
        """
        U = np.asarray(U)
        if U.dtype.kind not in "fiu" or U.shape != (3, self.n_nodes):
            raise ValueError(f"U must be a real (3, {self.n_nodes}) array, got {U.dtype} {U.shape}")
        U = np.ascontiguousarray(U, dtype=np.float64)
        f = np.zeros(3 * self.n_nodes)
        data = np.zeros(self.nnz if tangent else 1)
        ok, jmin = _hex_kernel(U, self.edofs, self.dphi, self.dx, self.mode, *self.params, bool(tangent),
                               self.emap, f, data, self.pb, self.Mi)
        return bool(ok), float(jmin), f, (data if tangent else None)


@njit(cache=True, error_model="numpy")
def _pressure_kernel(U, edofs, phi, dphi, nrm, dA, p, tangent, emap, f, data):
    """Follower pressure force and load stiffness (formulas in :mod:`fem_reference.assembly`), facet by facet.

    ``phi[e, q, a]``, ``dphi[e, q, J, a]``, ``nrm[e, q, J]`` (reference outward normal), ``dA[e, q]``;
    ``emap[e, 3a+i, 3b+k]``: position of ``∂f_{ai}/∂u_{bk}`` in ``data``.  Like the numpy path, no
    ``det F`` check here (the volume assembly rejects inadmissible states).
    """
    ne = dA.shape[0]
    nq = dA.shape[1]
    ue = np.empty((3, 27))
    F = np.empty((3, 3))
    T = np.empty((3, 3))
    m = np.empty(3)
    h = np.empty((27, 3))
    fe = np.empty((27, 3))
    Ke = np.empty((27, 3, 27, 3))
    for e in range(ne):
        _gather(U, edofs, e, ue)
        fe[:] = 0.0
        if tangent:
            Ke[:] = 0.0
        for q in range(nq):
            D = dphi[e, q]
            _deformation_gradient(ue, D, F)
            c00 = F[1, 1] * F[2, 2] - F[1, 2] * F[2, 1]
            c01 = F[1, 2] * F[2, 0] - F[1, 0] * F[2, 2]
            c02 = F[1, 0] * F[2, 1] - F[1, 1] * F[2, 0]
            J = F[0, 0] * c00 + F[0, 1] * c01 + F[0, 2] * c02
            T[0, 0] = c00 / J
            T[0, 1] = c01 / J
            T[0, 2] = c02 / J
            T[1, 0] = (F[0, 2] * F[2, 1] - F[0, 1] * F[2, 2]) / J
            T[1, 1] = (F[0, 0] * F[2, 2] - F[0, 2] * F[2, 0]) / J
            T[1, 2] = (F[0, 1] * F[2, 0] - F[0, 0] * F[2, 1]) / J
            T[2, 0] = (F[0, 1] * F[1, 2] - F[0, 2] * F[1, 1]) / J
            T[2, 1] = (F[0, 2] * F[1, 0] - F[0, 0] * F[1, 2]) / J
            T[2, 2] = (F[0, 0] * F[1, 1] - F[0, 1] * F[1, 0]) / J
            for i in range(3):
                m[i] = T[i, 0] * nrm[e, q, 0] + T[i, 1] * nrm[e, q, 1] + T[i, 2] * nrm[e, q, 2]
            w = -p * J * dA[e, q]
            for a in range(27):
                pw = phi[e, q, a] * w
                for i in range(3):
                    fe[a, i] += pw * m[i]
            if not tangent:
                continue
            for b in range(27):
                for k in range(3):
                    h[b, k] = T[k, 0] * D[0, b] + T[k, 1] * D[1, b] + T[k, 2] * D[2, b]
            for a in range(27):
                pw = phi[e, q, a] * w
                for i in range(3):
                    pm = pw * m[i]
                    for b in range(27):
                        for k in range(3):
                            Ke[a, i, b, k] += pm * h[b, k] - pw * h[b, i] * m[k]
        for a in range(27):
            n3 = 3 * edofs[a, e]
            for i in range(3):
                f[n3 + i] += fe[a, i]
        if tangent:
            for a in range(27):
                for i in range(3):
                    for b in range(27):
                        for k in range(3):
                            data[emap[e, 3 * a + i, 3 * b + k]] += Ke[a, i, b, k]


class PressureKernel:
    """The compiled follower-pressure assembly of one facet set: arrays checked once, ``U`` and ``p`` per call.

    Parameters
    ----------
    edofs : (27, nf) int; phi : (nf, nq, 27); dphi : (nf, nq, 3, 27) [1/m]; normals : (nf, nq, 3);
    dA : (nf, nq) [m²]; emap : (nf, 81, 81) int or None (positions in the CSR data, ``[e, 3a+i, 3b+k]``);
    nnz : int (length of the CSR data); n_nodes : int
    """

    def __init__(self, edofs, phi, dphi, normals, dA, emap, nnz: int, n_nodes: int):
        self.n_nodes = int(n_nodes)
        self.nnz = int(nnz)
        self.edofs = np.ascontiguousarray(edofs, dtype=np.int64)
        self.phi = np.ascontiguousarray(phi, dtype=np.float64)
        self.dphi = np.ascontiguousarray(dphi, dtype=np.float64)
        self.normals = np.ascontiguousarray(normals, dtype=np.float64)
        self.dA = np.ascontiguousarray(dA, dtype=np.float64)
        ne, nq = self.dA.shape
        self.emap = None if emap is None else np.ascontiguousarray(emap, dtype=np.int64)
        if (self.edofs.shape != (27, ne) or self.phi.shape != (ne, nq, 27) or self.dphi.shape != (ne, nq, 3, 27)
                or self.normals.shape != (ne, nq, 3)
                or (self.emap is not None and self.emap.shape != (ne, 81, 81))):
            raise ValueError(f"pressure kernel shapes: edofs {self.edofs.shape}, phi {self.phi.shape}, dphi "
                             f"{self.dphi.shape}, normals {self.normals.shape}, dA {self.dA.shape}")
        if ne and (self.edofs.min() < 0 or self.edofs.max() >= self.n_nodes):
            raise ValueError("facet nodes outside the node range")
        if ne and self.emap is not None and (self.emap.min() < 0 or self.emap.max() >= self.nnz):
            raise ValueError("scatter map outside the CSR data array")
        if not all(np.all(np.isfinite(x)) for x in (self.phi, self.dphi, self.normals, self.dA)):
            raise ValueError("facet basis arrays are not finite")
        self._dummy_map = np.zeros((1, 81, 81), np.int64)

    def __call__(self, U: np.ndarray, p: float, tangent: bool = True):
        """``(f_p (3 n_nodes,), data (nnz,) or None)`` at displacements ``U`` (3, n_nodes) [m], pressure ``p`` [Pa]."""
        U = np.asarray(U)
        if U.dtype.kind not in "fiu" or U.shape != (3, self.n_nodes):
            raise ValueError(f"U must be a real (3, {self.n_nodes}) array, got {U.dtype} {U.shape}")
        U = np.ascontiguousarray(U, dtype=np.float64)
        p = float(p)
        if tangent and self.emap is None:
            raise ValueError("a pressure tangent needs the scatter map (pattern)")
        f = np.zeros(3 * self.n_nodes)
        data = np.zeros(self.nnz if tangent else 1)
        _pressure_kernel(U, self.edofs, self.phi, self.dphi, self.normals, self.dA, p, bool(tangent),
                         self.emap if tangent else self._dummy_map, f, data)
        return f, (data if tangent else None)
