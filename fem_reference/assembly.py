r"""Vectorised assembly of the hyperelastic internal force, tangent and surface/body loads.

Unknowns are nodal displacements ``U`` of shape ``(3, n_nodes)``; the global vector index of
``U[i, a]`` is ``3 a + i`` (interleaved, as skfem's ``ElementVector``).

Volume terms (27-point Gauss on each Hex2, ``dphi[a, J, e, q] = ∂N_a/∂X_J``, ``dx = |detDF| w``):

.. math::

    F = I + \sum_a u_a \otimes \nabla N_a, \qquad
    f^{int}_{a i} = \sum_q P_{iJ}\,\partial_J N_a\, dx, \qquad
    K_{a i, b k} = \sum_q \partial_J N_a\, A_{iJkL}\, \partial_L N_b\, dx.

**Mixed u–p element** (``element="mixed"``, default).  With the decoupled energy
:math:`\psi = \psi_{iso}(F) + \tfrac{\kappa}{2}(J - 1)^2` a full-integration Hex27 locks: 27 pointwise
constraints :math:`J \approx 1` per element are too many for its displacements when the wall bends.  The
two-field functional :math:`\int \psi_{iso} + p_h (J - 1) - p_h^2/(2\kappa)` with a pressure
:math:`p_h \in \mathrm{span}\{1, \xi, \eta, \zeta\}` per element (discontinuous, the Q2/P1-disc pair; linear in
the element's reference coordinates, which follow a curved wall's thickness direction, or in (X, Y, Z) with
``HexAssembler.PRESSURE_COORDINATES = "physical"``; :func:`pressure_basis`) is condensed exactly: the
pressure equation gives :math:`p_h = \kappa\,\Pi(J - 1)` with :math:`\Pi` the element's L² projection on
that space, and the functional becomes the displacement energy

.. math::

    \Pi(u) = \int \psi_{iso}(F)\,dV + \frac{\kappa}{2}\int (\Pi J - 1)^2\,dV, \qquad
    \Pi J = N^T M^{-1} b, \quad M = \int N N^T dV, \quad b = \int N J\, dV,

so the global system keeps its size.  Its force replaces :math:`\kappa(J-1)` by :math:`p_h` at each point,
:math:`f_{ai} = \sum_q (P^{iso} + p_h J F^{-T})_{iJ} \partial_J N_a dx`, and its exact tangent is the
pointwise part with the same replacement, :math:`A \mathrel{+}= p_h J (F^{-T}_{iJ}F^{-T}_{kL} -
F^{-T}_{iL}F^{-T}_{kJ})`, plus the rank-4 element matrix :math:`\kappa\, G^T M^{-1} G`,
:math:`G_{m,ai} = \sum_q N_m J F^{-T}_{iJ}\partial_J N_a\, dx`.  At κ → ∞ the element enforces
:math:`\Pi J = 1` (4 constraints per element), not :math:`J = 1` at 27 points.

Two implementations with the same formulation and quadrature (``kernel=``):

- ``"numba"`` (default): a compiled element loop (:mod:`fem_reference._kernels`) with the material law
  inline at each Gauss point and the symmetric element matrix added straight into the CSR data array
  through the precomputed scatter map; no BLAS, no large temporaries.
- ``"numpy"`` (reference): the element matrices are formed with one batched matrix product per chunk
  of elements (``(27 × 81) @ (81 × 243)`` per element) and summed into the fixed CSR pattern through the
  scatter map (``np.bincount``).  This is the kernel of ``docs/fem.md`` §1 (≈50× faster than
  ``BilinearForm`` for Hex2 vectors); its threaded BLAS product is slowed badly by thread contention
  on a small shared machine (``docs/fem.md`` "Where the time goes").

Either way the pattern is fixed, so repeated assemblies never sort indices again.

Follower pressure on the deformed inner surface (Nanson, :math:`n\,da = J F^{-T} N\,dA`); the
solid's outward normal ``N`` on the inner surface points into the cavity, the pressure pushes along
``-n``:

.. math::

    f^{p}_{a i} = -p \sum_q N_a\, J\, m_i\, dA, \quad m = F^{-T} N, \qquad
    \frac{\partial f^p_{a i}}{\partial u_{b k}} = -p \sum_q N_a\, J\,(m_i h^b_k - h^b_i m_k)\, dA,
    \quad h^b = F^{-T}\nabla N_b,

from :math:`d(\operatorname{cof}F)[\Delta F] = J[(F^{-T}\!:\!\Delta F)F^{-T} - F^{-T}\Delta F^T F^{-T}]`
with :math:`\Delta F = e_k \otimes \nabla N_b`.  The load stiffness is non-symmetric on an open
surface (the Newton matrix is ``K_int - K_p``).

Gravity is a dead body load :math:`f^g_{a i} = \rho\, g_i \sum_q N_a\, dx` (no tangent).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from .errors import ConfigError

from .material import Material, _inv_det
from .sparse_keys import csr_index, unique_keys

__all__ = ["ELEMENTS", "KERNELS", "CsrPattern", "HexAssembler", "PressureAssembler", "gravity_load",
           "pressure_basis"]

#: Wall elements (``element=``): ``"mixed"`` — Hex27 displacements with a discontinuous linear pressure per
#: element (Q2/P1-disc, u–p; the pressure condensed element by element; locking-free, the default) and
#: ``"displacement"`` — Hex27 displacements alone with the pointwise volumetric term (locks in bending of a
#: thin nearly incompressible wall; ``docs/fem.md`` §3).
ELEMENTS = ("mixed", "displacement")

#: Implementations of :meth:`HexAssembler.assemble`: ``"numba"`` (compiled element loop of
#: :mod:`fem_reference._kernels`, the default) and ``"numpy"`` (the vectorised reference it is tested against).
KERNELS = ("numba", "numpy")


class CsrPattern:
    """Fixed CSR sparsity pattern of a set of element blocks with a scatter map.

    Parameters
    ----------
    ldofs : ndarray (n_loc, n_el) of int
        Global vector DOFs of each element (local order = order of the element matrices' rows).
    n : int
        Global size.
    col_ldofs : ndarray (n_loc, n_el) of int, optional
        Column DOFs if the element matrices order their columns differently (same set per element).
    """

    def __init__(self, ldofs: np.ndarray, n: int, col_ldofs: np.ndarray | None = None):
        nloc, ne = ldofs.shape
        cl = ldofs if col_ldofs is None else col_ldofs
        rows = np.broadcast_to(ldofs.T[:, :, None], (ne, nloc, nloc)).ravel()
        cols = np.broadcast_to(cl.T[:, None, :], (ne, nloc, nloc)).ravel()
        keys = rows.astype(np.int64) * n + cols
        self.keys, inv = unique_keys(keys, return_inverse=True)
        self.scatter = inv.astype(np.int64 if self.keys.size > 2**31 - 1 else np.int32)
        self.n = n
        self.indptr, self.indices = csr_index(self.keys, n, np.int64)

    @property
    def nnz(self) -> int:
        return self.keys.size

    def matrix(self, element_values: np.ndarray) -> sp.csr_matrix:
        """CSR matrix from element matrices ``(n_el, n_loc, n_loc)`` (same order as ``ldofs``)."""
        data = np.bincount(self.scatter, weights=element_values.ravel(), minlength=self.nnz)
        return self.csr(data)

    def csr(self, data: np.ndarray) -> sp.csr_matrix:
        """CSR matrix with this pattern and the values ``data`` (nnz,).  Every matrix made here shares the
        same index arrays (already in scipy's index dtype, so not copied): same-pattern sums can work on
        ``.data`` directly."""
        idx = getattr(self, "_scipy_index", None)
        if idx is None:
            K = sp.csr_matrix((np.zeros(self.nnz), self.indices, self.indptr), shape=(self.n, self.n))
            idx = self._scipy_index = (K.indices, K.indptr)
        return sp.csr_matrix((data, idx[0], idx[1]), shape=(self.n, self.n))

    def submap(self, ldofs: np.ndarray) -> np.ndarray:
        """Scatter map of another set of element blocks whose entries lie inside this pattern."""
        nloc, ne = ldofs.shape
        rows = np.broadcast_to(ldofs.T[:, :, None], (ne, nloc, nloc)).ravel()
        cols = np.broadcast_to(ldofs.T[:, None, :], (ne, nloc, nloc)).ravel()
        keys = rows.astype(np.int64) * self.n + cols
        pos = np.searchsorted(self.keys, keys)
        if np.any(self.keys[np.minimum(pos, self.nnz - 1)] != keys):  # pragma: no cover
            raise RuntimeError("sub-pattern not contained in the volume pattern")
        return pos


def _vector_ldofs(edofs: np.ndarray) -> np.ndarray:
    """Scalar element DOFs ``(27, n_el)`` → interleaved vector DOFs ``(81, n_el)`` in (a, i) order."""
    return (3 * edofs[:, None, :] + np.arange(3)[None, :, None]).reshape(-1, edofs.shape[1])


class HexAssembler:
    """Internal force and tangent of a hyperelastic ``MeshHex2`` body (vectorised).

    Parameters
    ----------
    mesh : skfem.MeshHex2
    material : Material
    chunk : int
        Elements per vectorised batch of the numpy path (memory ≈ chunk × 1.2 MB).
    kernel : {"numba", "numpy"}
        ``"numba"``: compiled per-element force and symmetric tangent written straight into the CSR data
        (:mod:`fem_reference._kernels`); ``"numpy"``: the vectorised reference (batched BLAS products).
        Same formulation and quadrature; results agree to round-off (tested).
    element : {"mixed", "displacement"}
        The wall element (:data:`ELEMENTS`): mixed u–p Q2/P1-disc (locking-free, default; needs the
        decoupled volumetric energy) or displacement-only Hex27.
    """

    def __init__(self, mesh, material: Material, chunk: int = 128, kernel: str = "numba",
                 element: str = "mixed"):
        from skfem import CellBasis, ElementHex2

        if kernel not in KERNELS:
            raise ConfigError(f"unknown assembly kernel {kernel!r}; choose one of {KERNELS}")
        check_element(element, material)
        self.material = material
        self.element = element
        self.basis = CellBasis(mesh, ElementHex2(), intorder=4)
        b = self.basis
        self.edofs = b.element_dofs  # (27, ne) scalar dofs == node ids
        self.n_nodes = b.N
        self.dphi = np.ascontiguousarray(np.array([b.basis[a][0].grad for a in range(27)]))  # (27,3,ne,nq)
        self.phi = np.array([np.asarray(b.basis[a][0]) for a in range(27)])  # (27, ne, nq)
        self.dx = b.dx  # (ne, nq) [m^3]
        self.ne, self.nq = self.dx.shape
        self.ldofs = _vector_ldofs(self.edofs)
        # element matrices come out of the batched product as [e, (a, i), (k, b)]: scatter them in that
        # order (columns k-major) so that no transposed copy is needed
        cols = (3 * self.edofs[None, :, :] + np.arange(3)[:, None, None]).reshape(81, -1)
        self.pattern = CsrPattern(self.ldofs, 3 * self.n_nodes, col_ldofs=cols)
        self.chunk = int(chunk)
        self.kernel = kernel
        self.pb = self.Mi = None
        if element == "mixed":
            self.pb, self.Mi = pressure_basis(self._pressure_points(), self.dx)
        self._compiled = None
        if kernel == "numba":
            from ._kernels import HexKernel

            # the compiled kernel's layouts: dphi[e, q, J, a]; scatter map [e, (a, i), (k, b)] (same order)
            self._compiled = HexKernel(self.edofs, self.dphi.transpose(2, 3, 1, 0), self.dx,
                                       self.pattern.scatter.reshape(self.ne, 81, 81), self.pattern.nnz,
                                       self.n_nodes, material, self.pb, self.Mi)

    #: coordinates of the mixed element's linear pressure: "reference" (ξ, η, ζ of the element; they follow a
    #: curved wall's thickness direction) or "physical" (X, Y, Z)
    PRESSURE_COORDINATES = "reference"

    def _pressure_points(self) -> np.ndarray:
        """Gauss points in the pressure basis' coordinates, (3, ne, nq)."""
        if self.PRESSURE_COORDINATES == "physical":
            return np.asarray(self.basis.global_coordinates())
        return np.ascontiguousarray(np.broadcast_to(self.basis.X[:, None, :], (3, self.ne, self.nq)))

    def deformation_gradient(self, U: np.ndarray, sl=slice(None)) -> np.ndarray:
        """``F`` at the Gauss points of elements ``sl``, shape ``(3, 3, ne, nq)``."""
        ue = U[:, self.edofs[:, sl]]  # (3, 27, ne)
        F = np.einsum("iae,aJeq->iJeq", ue, self.dphi[:, :, sl])
        F[0, 0] += 1.0
        F[1, 1] += 1.0
        F[2, 2] += 1.0
        return F

    def min_jacobian(self, U: np.ndarray) -> float:
        """Smallest ``det F`` over all Gauss points."""
        jmin = np.inf
        for s in range(0, self.ne, 4 * self.chunk):
            sl = slice(s, min(s + 4 * self.chunk, self.ne))
            _, J = _inv_det(self.deformation_gradient(U, sl))
            jmin = min(jmin, float(J.min()))
        return jmin

    def energy(self, U: np.ndarray) -> float:
        """Stored strain energy [J] (of the mixed element: with the projected volumetric term)."""
        F = self.deformation_gradient(U)
        psi = self.material.energy(F)
        if self.element == "mixed":
            _, J = _inv_det(F)
            kap = self.material.kappa
            psi = psi - 0.5 * kap * (J - 1) ** 2 + 0.5 * kap * self._projected(J - 1) ** 2
        return float((psi * self.dx).sum())

    def _projected(self, g: np.ndarray, sl=slice(None)) -> np.ndarray:
        """``Πg`` at the Gauss points of elements ``sl`` from ``g`` there (``g = J − 1``: exactly 0 at the
        reference state, which ``ΠJ − 1`` is only to round-off), shape ``(ne, nq)``."""
        pb = self.pb[sl]
        b = np.einsum("eqm,eq,eq->em", pb, g, self.dx[sl])
        return np.einsum("eqm,emn,en->eq", pb, self.Mi[sl], b)

    def assemble(self, U: np.ndarray, tangent: bool = True):
        """Internal force and tangent.

        Parameters
        ----------
        U : ndarray (3, n_nodes)
            Nodal displacements [m].
        tangent : bool

        Returns
        -------
        f_int : ndarray (3 n_nodes,) [N]  (interleaved)
        K : scipy.sparse.csr_matrix (3 n_nodes, 3 n_nodes) [N/m] or None
        jmin : float — smallest det F; if ``<= 0`` the outputs are not meaningful.
        """
        if self._compiled is not None:
            ok, jmin, f, data = self._compiled(U, tangent)
            if not ok:
                return f, None, -1.0 if not np.isfinite(jmin) else min(jmin, 0.0)
            K = None
            if tangent:
                K = self.pattern.csr(data)
            return f, K, jmin
        return self._assemble_numpy(U, tangent)

    def _assemble_numpy(self, U: np.ndarray, tangent: bool = True):
        """The numpy reference implementation of :meth:`assemble` (``kernel="numpy"``)."""
        ne, nq = self.ne, self.nq
        f = np.zeros(3 * self.n_nodes)
        Kvals = np.empty((ne, 81, 81)) if tangent else None
        jmin = np.inf
        for s in range(0, ne, self.chunk):
            sl = slice(s, min(s + self.chunk, ne))
            nc = sl.stop - sl.start
            dphi = self.dphi[:, :, sl]
            dx = self.dx[sl]
            F = self.deformation_gradient(U, sl)
            P, A, J = self.material.stress(F, tangent=tangent)
            jmin = min(jmin, float(np.nanmin(J)))
            if not np.all(J > 0):
                return f, None, -1.0 if not np.isfinite(jmin) else min(jmin, 0.0)
            if self.element == "mixed":
                P, A, G = self._mixed_terms(F, J, P, A, sl)
            Re = np.einsum("aJeq,iJeq,eq->eai", dphi, P, dx).reshape(nc, 81)
            f += np.bincount(self.ldofs[:, sl].T.ravel(), weights=Re.ravel(), minlength=f.size)
            if tangent:
                # Y[e, (J,q), (i,k,b)] = sum_L A[i,J,k,L,e,q] dphi[b,L,e,q] dx[e,q]
                Y = np.einsum("iJkLeq,bLeq,eq->eJqikb", A, dphi, dx, optimize=True).reshape(nc, 3 * nq, 243)
                D = dphi.transpose(2, 0, 1, 3).reshape(nc, 27, 3 * nq)  # [e, a, (J,q)]
                np.matmul(D, Y, out=Kvals[sl].reshape(nc, 27, 243))  # [e, a, (i, k, b)]
                if self.element == "mixed":
                    Kvals[sl] += self.material.kappa * np.einsum(
                        "emai,emn,enbk->eaikb", G, self.Mi[sl], G).reshape(nc, 81, 81)
        K = self.pattern.matrix(Kvals) if tangent else None
        return f, K, jmin

    def _mixed_terms(self, F, J, P, A, sl):
        """The mixed element's stress and pointwise tangent at the points of elements ``sl`` (the pointwise
        volumetric term κ(J − 1) replaced by the projected pressure p_h), and ``G[e, m, a, i]``."""
        kap = self.material.kappa
        FiT, _ = _inv_det(F)
        ph = kap * self._projected(J - 1.0, sl)
        P = P + (ph - kap * (J - 1)) * J * FiT
        G = None
        if A is not None:
            TT = np.einsum("iJ...,kL...->iJkL...", FiT, FiT)
            TTx = TT.transpose(0, 3, 2, 1, 4, 5)
            A = A - kap * (2 * J * J - J) * TT + kap * (J * J - J) * TTx + ph * J * (TT - TTx)
            G = np.einsum("eqm,eq,iJeq,aJeq->emai", self.pb[sl], self.dx[sl], J * FiT, self.dphi[:, :, sl])
        return P, A, G

    def body_load(self, b: np.ndarray) -> np.ndarray:
        """Consistent nodal load of a constant body force density ``b`` [N/m³], shape ``(3 n_nodes,)``."""
        w = (self.phi * self.dx[None]).sum(axis=2)  # (27, ne)  ∫ N_a dx
        mass = np.bincount(self.edofs.ravel(), weights=w.ravel(), minlength=self.n_nodes)
        return (np.asarray(b, float)[:, None] * mass[None, :]).T.ravel()


def check_element(element: str, material: Material) -> None:
    """ConfigError unless ``element`` is one of :data:`ELEMENTS` and fits the material's volumetric law."""
    if element not in ELEMENTS:
        raise ConfigError(f"unknown wall element {element!r}; choose one of {ELEMENTS}")
    if element == "mixed" and material.formulation != "decoupled":
        raise ConfigError(f"the mixed wall element needs the decoupled volumetric energy κ/2 (J − 1)²; the "
                          f"material's formulation is {material.formulation!r}: use element='displacement'")


def pressure_basis(X: np.ndarray, dx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The mixed element's pressure basis ``N = [1, X̂, Ŷ, Ẑ]`` at the Gauss points and ``M⁻¹``.

    ``X`` (3, ne, nq) Gauss-point coordinates (reference ξ, η, ζ or physical [m]), ``dx`` (ne, nq) weights [m³].
    ``X̂_j = (X_j − X_c,j)/s_j`` about the element's centroid ``X_c`` with ``s_j`` the RMS spread of ``X_j`` over
    the element (a well-conditioned 4×4 ``M`` for either kind of coordinate; the span is the same).  Returns
    ``pb`` (ne, nq, 4) and ``Mi`` (ne, 4, 4) = ``(Σ_q N Nᵀ dx)⁻¹`` [1/m³].
    """
    V = dx.sum(axis=1)
    Xc = np.einsum("ieq,eq->ie", X, dx) / V
    d = X - Xc[:, :, None]
    spread = np.sqrt(np.einsum("ieq,eq->ie", d * d, dx) / V)
    pb = np.empty(dx.shape + (4,))
    pb[..., 0] = 1.0
    pb[..., 1:] = (d / spread[:, :, None]).transpose(1, 2, 0)
    M = np.einsum("eqm,eqn,eq->emn", pb, pb, dx)
    return pb, np.linalg.inv(M)


def gravity_load(assembler: HexAssembler, density: float, g=(0.0, 0.0, -9.81)) -> np.ndarray:
    """Dead gravity load of the meshed body [N], interleaved ``(3 n_nodes,)``."""
    return assembler.body_load(density * np.asarray(g, float))


class PressureAssembler:
    """Follower pressure on a set of boundary facets (Nanson) with its load stiffness.

    Parameters
    ----------
    mesh : skfem.MeshHex2
    facets : ndarray of int
        Boundary facets loaded by the pressure; their skfem outward normal must point into the cavity.
    pattern : CsrPattern
        Volume pattern (the facet blocks are a subset of it).
    kernel : {"numba", "numpy"}
        Compiled facet loop (:mod:`fem_reference._kernels`; needs ``pattern`` for the tangent) or the
        vectorised numpy reference; same results to round-off (tested).
    """

    def __init__(self, mesh, facets: np.ndarray, pattern: CsrPattern | None = None, kernel: str = "numba"):
        from skfem import ElementHex2, FacetBasis

        # skfem maps the facet quadrature points back to the element by a Newton iteration with an
        # absolute tolerance of 1e-12 on the reference coordinates; on fine meshes in SI units the
        # round-off floor (eps |x| / h) gets close to it and the iteration "fails" (measured on the
        # reference mesh).  1e-10 on reference coordinates is still exact to plotting/quadrature accuracy.
        mapping = mesh._mapping()
        _inv = type(mapping).invF
        mapping.invF = lambda x, tind=None, _m=mapping: _inv(_m, x, tind=tind, newton_tol=1e-10)
        fb = FacetBasis(mesh, ElementHex2(), mapping=mapping, facets=facets, intorder=4)
        self.basis = fb
        self.edofs = fb.element_dofs  # (27, nf)
        self.phi = np.array([np.asarray(fb.basis[a][0]) for a in range(27)])  # (27, nf, nq)
        self.dphi = np.array([fb.basis[a][0].grad for a in range(27)])  # (27, 3, nf, nq)
        self.N = fb.normals  # (3, nf, nq)
        self.dA = fb.dx  # (nf, nq)
        self.n_nodes = fb.N
        self.ldofs = _vector_ldofs(self.edofs)
        self.pattern = pattern
        self.submap = pattern.submap(self.ldofs) if pattern is not None else None
        if kernel not in KERNELS:
            raise ConfigError(f"unknown assembly kernel {kernel!r}; choose one of {KERNELS}")
        self.kernel = kernel
        self._compiled = None
        if kernel == "numba" and pattern is not None:
            from ._kernels import PressureKernel

            nf = self.edofs.shape[1]
            self._compiled = PressureKernel(self.edofs, self.phi.transpose(1, 2, 0), self.dphi.transpose(2, 3, 1, 0),
                                            self.N.transpose(1, 2, 0), self.dA, self.submap.reshape(nf, 81, 81),
                                            pattern.nnz, self.n_nodes)

    def assemble(self, U: np.ndarray, p: float, tangent: bool = True):
        """External pressure force and its derivative.

        Parameters
        ----------
        U : ndarray (3, n_nodes)  [m]
        p : float  — gauge pressure [Pa] (positive inflates)

        Returns
        -------
        f_p : ndarray (3 n_nodes,) [N] — external nodal force (add to f_ext)
        K_p : csr_matrix or None [N/m] — ``∂f_p/∂u`` (subtract from the Newton matrix)
        """
        if self._compiled is not None:
            f, data = self._compiled(U, p, tangent)
            if not tangent:
                return f, None
            return f, self.pattern.csr(data)
        ue = U[:, self.edofs]
        F = np.einsum("iae,aJeq->iJeq", ue, self.dphi)
        F[0, 0] += 1.0
        F[1, 1] += 1.0
        F[2, 2] += 1.0
        FiT, J = _inv_det(F)
        m = np.einsum("iJeq,Jeq->ieq", FiT, self.N)
        w = -p * J * self.dA  # (nf, nq)
        fe = np.einsum("aeq,ieq,eq->eai", self.phi, m, w).reshape(-1, 81)
        f = np.bincount(self.ldofs.T.ravel(), weights=fe.ravel(), minlength=3 * self.n_nodes)
        if not tangent:
            return f, None
        h = np.einsum("iJeq,bJeq->bieq", FiT, self.dphi)  # (27, 3, nf, nq)
        t1 = np.einsum("aeq,ieq,bkeq,eq->eaibk", self.phi, m, h, w, optimize=True)
        Ke = t1 - t1.transpose(0, 1, 4, 3, 2)  # m_i h_k - h_i m_k
        Ke = Ke.reshape(-1, 81, 81)
        if self.pattern is None:
            nf = Ke.shape[0]
            rows = np.broadcast_to(self.ldofs.T[:, :, None], (nf, 81, 81)).ravel()
            cols = np.broadcast_to(self.ldofs.T[:, None, :], (nf, 81, 81)).ravel()
            K = sp.coo_matrix((Ke.ravel(), (rows, cols)), shape=(f.size, f.size)).tocsr()
        else:
            data = np.bincount(self.submap, weights=Ke.ravel(), minlength=self.pattern.nnz)
            K = self.pattern.csr(data)
        return f, K
