r"""Small vibrations of the 3-D bellows about an equilibrium: the FEM's own modes (a dynamic reference for
the reduced model's :meth:`ancf.Model.modes`, docs/dynamics.md).

**Mass.** The consistent mass of the 27-node hexahedra, M_ab = ∫ ρ N_a N_b dV (the same quadrature as the
stiffness), assembled on the interleaved (x, y, z) nodal unknowns; the rigid distal cap's mass
``cap_mass`` is a point mass at its centre of mass (its rotary inertia is not included).  Reduced like the
stiffness by the rigid-cap prolongation P (clamped base, 6 cap unknowns): M_q = Pᵀ M P + m J_cᵀ J_c.

**Modes.** About the equilibrium ``res`` with its loads held (tensions, pressure as a follower load — the
symmetric part of the tangent —, tip force, gravity): K_q φ = ω² M_q φ, the lowest ``count`` pairs by
shift-invert Lanczos at σ = 0 (:func:`scipy.sparse.linalg.eigsh`; K_q is factorised once).  Locked taut
tendons are the constraints gᵀ δq = 0 (g the tendon-length gradients): the inverse is then the bordered
solve x = K⁻¹v − K⁻¹g (gᵀK⁻¹g)⁻¹ gᵀK⁻¹v, which keeps every Lanczos vector on the constraint space — the same
algebra as the locked tip compliance.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .errors import InputError, UnstableEquilibriumError


def mass_matrix(asm, density: float) -> sp.csr_matrix:
    """Consistent mass (3 n_nodes, 3 n_nodes) [kg] of the hexahedral mesh of ``asm``
    (:class:`~fem_reference.assembly.HexAssembler`) at ``density`` [kg/m³]."""
    phi, dx, edofs = asm.phi, asm.dx, asm.edofs                 # (27, ne, nq), (ne, nq), (27, ne)
    me = density * np.einsum("aeq,beq,eq->eab", phi, phi, dx)  # (ne, 27, 27)
    rows = np.broadcast_to(edofs.T[:, :, None], me.shape)
    cols = np.broadcast_to(edofs.T[:, None, :], me.shape)
    n = asm.n_nodes
    Ms = sp.csr_matrix((me.ravel(), (rows.ravel(), cols.ravel())), shape=(n, n))
    # interleaved vector unknowns: dof 3 a + i
    return sp.kron(Ms, sp.identity(3), format="csr")


@dataclass
class FemModes:
    """frequencies_hz (k,) ascending; omega2 (k,) [1/s²]; shapes (k, n_q) mass-normalised reduced
    unknowns; cap_shapes (k, 6): the cap's (u_c [m], θ [rad]) in each shape; tendons: "held" or "locked";
    total_mass [kg] of the moving body (a check)."""
    frequencies_hz: np.ndarray
    omega2: np.ndarray
    shapes: np.ndarray
    cap_shapes: np.ndarray
    tendons: str
    total_mass: float


def reduced_mass(model, state) -> sp.csr_matrix:
    """M_q = Pᵀ M P + the cap's point mass (module docstring) at the cap rotation of ``state``."""
    from .loads.caps import point_jacobian

    c = model.caps
    M = getattr(model, "_mass_full", None)
    if M is None:
        M = model._mass_full = mass_matrix(model.asm, model.material.density)
    PT = c.prolongation(state.R, transpose=True)
    Mq = (PT @ (M @ c.prolongation(state.R))).tolil()
    m_cap = model.geometry.cap_mass
    if m_cap > 0:
        J = point_jacobian(state.R @ model.a_com)
        s = c.n_free
        Mq[s:s + 6, s:s + 6] = Mq[s:s + 6, s:s + 6].toarray() + m_cap * J.T @ J
    return Mq.tocsr()


def modes(model, res, count: int = 4, tendons: str = "held") -> FemModes:
    """The ``count`` lowest modes of the FEM about its equilibrium ``res`` (module docstring).
    ``tendons``: "held" (tensions constant) or "locked" (taut tendons at their lengths)."""
    import scipy.sparse.linalg as spla

    from .solver import factorize

    if tendons not in ("held", "locked"):
        raise InputError(f"tendons must be 'held' or 'locked', got {tendons!r}")
    if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or not 1 <= count <= 50:
        raise InputError(f"count must be an integer 1…50, got {count!r}")
    model._own(res)
    if not model.material.density > 0:
        raise InputError("modes need the material's density > 0")
    st = res.state
    ev = model.evaluate(st, res.loadcase, tangent=True)
    K = (0.5 * (ev["K"] + ev["K"].T)).tocsr()
    M = reduced_mass(model, st)
    fac = factorize(K, model.linear_solver)
    n = K.shape[0]
    g = None
    if tendons == "locked":
        act = st.T > 1e-12
        if act.any():
            g = np.asarray(ev["g"][:, act], float)
            Kg = fac.solve(g)
            S = g.T @ Kg

    def inverse(v):
        x = fac.solve(np.asarray(v, float).ravel())
        if g is not None:
            x = x - Kg @ np.linalg.solve(S, g.T @ x)
        return x

    op = spla.LinearOperator((n, n), matvec=inverse, dtype=float)
    k = min(int(count), n - 2)
    w2, phi = spla.eigsh(K, k=k, M=M, sigma=0.0, which="LM", OPinv=op, tol=1e-10)
    order = np.argsort(w2)
    w2, phi = w2[order], phi[:, order]
    if w2[0] < -1e-8 * abs(w2[-1]):
        raise UnstableEquilibriumError("the FEM equilibrium has a negative ω²: not stable", solver="fem modes",
                                       min_eigenvalue=float(w2[0]))
    w2 = np.maximum(w2, 0.0)
    # mass-normalise (eigsh returns M-orthonormal vectors already; normalise again against round-off)
    phi = phi / np.sqrt(np.einsum("ik,ik->k", phi, M @ phi))[None, :]
    total = float(np.ones(3 * model.asm.n_nodes) @ (model._mass_full @ np.ones(3 * model.asm.n_nodes)) / 3
                  + model.geometry.cap_mass)
    return FemModes(np.sqrt(w2) / (2 * np.pi), w2, phi.T, phi[model.caps.cap_slice, :].T, tendons, total)
