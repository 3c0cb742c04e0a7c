r"""Frictionless penalty contact between the facing outer flanks of adjacent convolutions.

The gap's geometry on a solved wall is :mod:`fem_reference.contact`; this module is the generalized force that
keeps the flanks from passing through each other (``BellowsModel(..., contact=True)``).  It is a pure function
of the deformed node positions ``x`` (3, n_nodes) [m]; the model adds its gradient and tangent to the reduced
residual and Newton matrix (the contact nodes are free nodes of the wall, never cap nodes).

**Pairs.**  At every outer groove (interior root, fine-lattice row ``r``, ``h`` fine rows to a crest) the outer
surface node ``a`` of flank A at row ``r − i`` and the node ``b`` of flank B at row ``r + i``, on the same
lattice angle ``j``, ``i = 1 … h − 1``, are mirror images about the root plane in the reference configuration
(the same levels as :func:`fem_reference.contact.flank_gaps`).  The flanks close like a hinge about the groove's
bottom, so ``a`` and ``b`` stay nearly facing: node-to-node pairs fixed once.

**Gap along the current normal.**  Each node's own surface normal direction is the cross product of the
central differences of its lattice neighbours on its flank, :math:`c_a = (x_{a↑} - x_{a↓}) \times (x_{a+} -
x_{a-})` (↑ towards the crest, ↓ towards the bottom, ± the neighbouring angles), likewise :math:`c_b`.  Mirror
images have equal axial and opposite radial components of ``c``, so :math:`c = c_a + c_b` is the groove's axis
in the reference configuration and the bisector of the two flanks when they turn about the bottom.  With
:math:`n = c/|c|`, ``s = ±1`` fixed so that the reference gap is positive and :math:`d = x_b - x_a`:

.. math::  g = s\, d \cdot n,

ten nodes per pair (``a``, ``b`` and four neighbours each; at level 1 the two flanks share their ↓ node).
On the unloaded wall ``g`` is the axial distance of the mirror nodes (as :func:`~fem_reference.contact.flank_gaps`;
tested), and it is invariant under rigid motions.

**Energy** (``k_c`` [N/m³], ``A_p`` the pair's tributary area [m²], fixed):

.. math::  \Pi_c = \sum_p \tfrac12\, k_c A_p \langle -g_p \rangle^2, \qquad
           \nabla\Pi_c = -\sum_p k_c A_p \langle -g_p\rangle \nabla g_p, \qquad
           \nabla^2\Pi_c = \sum_{p:\,g_p<0} k_c A_p (\nabla g_p \nabla g_p^T - \langle -g_p\rangle \nabla^2 g_p).

``A_p = |c_a(X)|/4`` (the central differences span two lattice spacings each: a quarter of the cross product is
the node's share of the surface).  A pair pressed together by a force ``F`` along ``n`` settles at the
penetration ``F/(k_c A_p)`` (tested).  The contact pressure of a pair is :math:`k_c \langle -g\rangle` [Pa];
its normal force :math:`N_p = k_c A_p\langle -g_p\rangle` [N] acts on ``b`` along ``s n`` and on ``a`` against
it, the ``c`` terms distributing the torque of the turning normal over the neighbours.

**Derivatives.**  With :math:`P = I - n n^T`: :math:`\partial g/\partial x_b = s n = -\partial g/\partial
x_a`; :math:`w = \partial g/\partial c = s P d/|c|`; for one flank's :math:`e_1 = x_↑ - x_↓`,
:math:`e_2 = x_+ - x_-`, :math:`\partial(w\cdot c)/\partial e_1 = e_2 \times w`, :math:`\partial(w\cdot
c)/\partial e_2 = w \times e_1`.  Second derivatives: :math:`\partial^2 g/\partial d\,\partial c = s P/|c|`,
:math:`\partial^2 g/\partial c^2 = -s\,[d n^T + n d^T + (d\cdot n)(I - 3 n n^T)]/|c|^2`, and the bilinear
``c``: :math:`\partial^2 (w\cdot c)/\partial e_1 \partial e_2 = -[w]_\times`.  All checked against finite
differences of the energy (``tests/test_fem/test_fem_self_contact.py``).

**Stiffness.**  :func:`default_stiffness`: ``k_c = β E / t`` with ``E = 3 μ`` (the wall's small-strain Young's
modulus, nearly incompressible) and ``t`` the wall thickness: β = 1 is a layer as stiff as the wall is through
its thickness in uniaxial stress; the default β = :data:`STIFFNESS_FACTOR`.  The penetration falls as 1/k_c
(``docs/fem.md`` §5a shows the tip converging as k_c grows).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..contact import _layer_grid, groove_rows
from ..errors import InputError

__all__ = ["STIFFNESS_FACTOR", "ContactTerms", "FlankPairs", "contact_terms", "default_stiffness", "flank_pairs",
           "global_terms", "pair_gaps"]

#: β of :func:`default_stiffness` (k_c = β · 3 μ / t)
STIFFNESS_FACTOR = 10.0

#: per pair, the node order: a, b, then ↑, ↓, +, − of a, then of b
N_PAIR_NODES = 10


@dataclass(frozen=True)
class FlankPairs:
    """Node-to-node contact pairs of the facing outer flanks (module doc).

    nodes : (P, 10) int — ``a, b, a↑, a↓, a+, a−, b↑, b↓, b+, b−``; sign : (P,) ±1; area : (P,) [m²];
    groove, level, angle : (P,) int — groove index (from the base), level ``1 … h − 1`` from the groove's bottom,
    lattice angle index (θ = π · angle / n_θ from tendon 1's reference direction).
    """

    nodes: np.ndarray
    sign: np.ndarray
    area: np.ndarray
    groove: np.ndarray
    level: np.ndarray
    angle: np.ndarray

    @property
    def n_pairs(self) -> int:
        return int(self.sign.size)


@dataclass(frozen=True)
class ContactTerms:
    """Penalty energy [J], every pair's gap ``g`` (P,) [m] and, for the pairs in contact (``active``, indices
    into the pairs), the energy's gradient over the pair's 10 nodes ``grad`` (n_active, 30) [N] (node-major,
    order of :attr:`FlankPairs.nodes`) and its Hessian ``hess`` (n_active, 30, 30) [N/m] (None unless asked);
    ``normal_force`` (n_active,) [N] the pairs' normal forces ``k_c A ⟨−g⟩``."""

    energy: float
    gaps: np.ndarray
    active: np.ndarray
    grad: np.ndarray
    hess: np.ndarray | None
    normal_force: np.ndarray


def default_stiffness(material, geometry, factor: float = STIFFNESS_FACTOR) -> float:
    """Penalty stiffness ``k_c = factor · 3 μ / t`` [N/m³] (module doc)."""
    return float(factor) * 3.0 * float(material.mu) / float(geometry.wall_thickness)


def _cross_terms(x: np.ndarray, nodes: np.ndarray) -> np.ndarray:
    """``c`` of the flank nodes whose (↑, ↓, +, −) neighbours are ``nodes`` (P, 4): shape (P, 3)."""
    e1 = x[:, nodes[:, 0]] - x[:, nodes[:, 1]]
    e2 = x[:, nodes[:, 2]] - x[:, nodes[:, 3]]
    return np.cross(e1.T, e2.T)


def flank_pairs(bmesh) -> FlankPairs:
    """The contact pairs of every outer groove of ``bmesh`` (a :class:`~fem_reference.mesh.BellowsMesh` with its
    geometry), signs and tributary areas from its reference configuration."""
    rows, h = groove_rows(bmesh, "outer")
    surf = _layer_grid(bmesh, 2 * bmesh.shape[1])
    n_ang = surf.shape[1]
    j = np.arange(n_ang)
    jp, jm = (j + 1) % n_ang, (j - 1) % n_ang
    out = []
    for k, r in enumerate(rows):
        for i in range(1, h):
            ra, rb = r - i, r + i
            cols = [surf[ra, j], surf[rb, j], surf[ra - 1, j], surf[ra + 1, j], surf[ra, jp], surf[ra, jm],
                    surf[rb + 1, j], surf[rb - 1, j], surf[rb, jp], surf[rb, jm]]
            out.append((np.stack(cols, axis=1), np.full(n_ang, k), np.full(n_ang, i), j))
    nodes = np.concatenate([o[0] for o in out])
    if np.any(nodes < 0):  # pragma: no cover - every fine-lattice point is a Hex27 node
        raise InputError("the outer surface lattice has holes: no contact pairs")
    X = bmesh.X
    c = _cross_terms(X, nodes[:, 2:6]) + _cross_terms(X, nodes[:, 6:10])
    sign = np.sign(np.einsum("pi,ip->p", c, X[:, nodes[:, 1]] - X[:, nodes[:, 0]]))
    if np.any(sign == 0):  # pragma: no cover
        raise InputError("a contact pair has no reference gap along its normal")
    area = 0.25 * np.linalg.norm(_cross_terms(X, nodes[:, 2:6]), axis=1)
    return FlankPairs(nodes, sign, area, *(np.concatenate([o[q] for o in out]) for q in (1, 2, 3)))


def pair_gaps(pairs: FlankPairs, x: np.ndarray) -> np.ndarray:
    """Gap ``g`` of every pair along the current normal (module doc) [m], shape (P,)."""
    x = np.asarray(x, float)
    nd = pairs.nodes
    c = _cross_terms(x, nd[:, 2:6]) + _cross_terms(x, nd[:, 6:10])
    n = c / np.linalg.norm(c, axis=1)[:, None]
    d = (x[:, nd[:, 1]] - x[:, nd[:, 0]]).T
    return pairs.sign * np.einsum("pi,pi->p", d, n)


def _skew(w: np.ndarray) -> np.ndarray:
    """[w]× of each row of w (P, 3): shape (P, 3, 3)."""
    S = np.zeros(w.shape[:1] + (3, 3))
    S[:, 0, 1], S[:, 0, 2], S[:, 1, 2] = -w[:, 2], w[:, 1], -w[:, 0]
    return S - S.transpose(0, 2, 1)


def _gap_derivatives(x: np.ndarray, nd: np.ndarray, s: np.ndarray, hessian: bool):
    """Gap (P,), its gradient (P, 30) and Hessian (P, 30, 30) or None over the 10 nodes of each pair."""
    P = nd.shape[0]
    e = [(x[:, nd[:, o]] - x[:, nd[:, o + 1]]).T for o in (2, 4, 6, 8)]     # e1_a, e2_a, e1_b, e2_b
    c = np.cross(e[0], e[1]) + np.cross(e[2], e[3])
    nc = np.linalg.norm(c, axis=1)
    n = c / nc[:, None]
    d = (x[:, nd[:, 1]] - x[:, nd[:, 0]]).T
    dn = np.einsum("pi,pi->p", d, n)
    g = s * dn
    Pn = np.eye(3)[None] - n[:, :, None] * n[:, None, :]
    w = s[:, None] * np.einsum("pij,pj->pi", Pn, d) / nc[:, None]
    grad = np.zeros((P, N_PAIR_NODES, 3))
    grad[:, 0], grad[:, 1] = -s[:, None] * n, s[:, None] * n
    for f in (0, 1):                                   # flank a (nodes 2..5), flank b (nodes 6..9)
        e1, e2, o = e[2 * f], e[2 * f + 1], 2 + 4 * f
        grad[:, o], grad[:, o + 1] = np.cross(e2, w), -np.cross(e2, w)
        grad[:, o + 2], grad[:, o + 3] = np.cross(w, e1), -np.cross(w, e1)
    if not hessian:
        return g, grad.reshape(P, -1), None
    # J_d (P, 3, 30) and J_c (P, 3, 30): derivatives of d and c by the 30 coordinates
    Jd = np.zeros((P, 3, N_PAIR_NODES, 3))
    Jd[:, :, 0], Jd[:, :, 1] = -np.eye(3), np.eye(3)
    Jc = np.zeros((P, 3, N_PAIR_NODES, 3))
    for f in (0, 1):
        e1, e2, o = e[2 * f], e[2 * f + 1], 2 + 4 * f
        dc1, dc2 = -_skew(e2), _skew(e1)            # ∂(e1 × e2)/∂e1, ∂/∂e2
        Jc[:, :, o], Jc[:, :, o + 1], Jc[:, :, o + 2], Jc[:, :, o + 3] = dc1, -dc1, dc2, -dc2
    Jd, Jc = Jd.reshape(P, 3, -1), Jc.reshape(P, 3, -1)
    gdc = s[:, None, None] * Pn / nc[:, None, None]
    gcc = -(s / nc ** 2)[:, None, None] * (d[:, :, None] * n[:, None, :] + n[:, :, None] * d[:, None, :]
                                           + dn[:, None, None] * (np.eye(3)[None] - 3 * n[:, :, None] * n[:, None, :]))
    A = np.einsum("pia,pij,pjb->pab", Jd, gdc, Jc)
    H = A + A.transpose(0, 2, 1) + np.einsum("pia,pij,pjb->pab", Jc, gcc, Jc)
    H = H.reshape(P, N_PAIR_NODES, 3, N_PAIR_NODES, 3)
    W = _skew(w)
    for f in (0, 1):                                  # bilinear c: ∂²(w·c)/∂e1∂e2 = −[w]×
        o = 2 + 4 * f
        for a_, sa in ((o, 1.0), (o + 1, -1.0)):          # e1 = x↑ − x↓
            for b_, sb in ((o + 2, 1.0), (o + 3, -1.0)):  # e2 = x+ − x−
                H[:, a_, :, b_, :] -= sa * sb * W
                H[:, b_, :, a_, :] += sa * sb * W
    return g, grad.reshape(P, -1), H.reshape(P, 3 * N_PAIR_NODES, 3 * N_PAIR_NODES)


def contact_terms(pairs: FlankPairs, x: np.ndarray, k_c: float, hessian: bool = True) -> ContactTerms:
    """Penalty energy, gaps, and the gradient / Hessian of the pairs in contact at positions ``x`` (3, n_nodes)
    [m] with stiffness ``k_c`` [N/m³] (module doc)."""
    x = np.asarray(x, float)
    g = pair_gaps(pairs, x)
    act = np.flatnonzero(g < 0)
    pen = -g[act]
    kA = k_c * pairs.area[act]
    energy = float(0.5 * np.sum(kA * pen ** 2))
    if act.size == 0:
        return ContactTerms(energy, g, act, np.zeros((0, 3 * N_PAIR_NODES)), None, np.zeros(0))
    _, dg, d2g = _gap_derivatives(x, pairs.nodes[act], pairs.sign[act].astype(float), hessian)
    grad = -(kA * pen)[:, None] * dg
    hess = None
    if hessian:
        hess = kA[:, None, None] * (dg[:, :, None] * dg[:, None, :]) - (kA * pen)[:, None, None] * d2g
    return ContactTerms(energy, g, act, grad, hess, kA * pen)


def global_terms(pairs: FlankPairs, x: np.ndarray, k_c: float):
    """Penalty energy [J], its gradient (3 n_nodes,) [N] (node-major: ``3 i + k``) and Hessian (3 n_nodes,
    3 n_nodes) [N/m] (scipy csr) over all nodes of the mesh, the pair blocks summed (for checks and inspection;
    the model scatters :func:`contact_terms` into its reduced unknowns itself)."""
    import scipy.sparse as sp

    x = np.asarray(x, float)
    n = 3 * x.shape[1]
    t = contact_terms(pairs, x, k_c, hessian=True)
    dofs = (3 * pairs.nodes[t.active][:, :, None] + np.arange(3)).reshape(t.active.size, -1)
    grad = np.bincount(dofs.ravel(), weights=t.grad.ravel(), minlength=n)
    rows = np.broadcast_to(dofs[:, :, None], t.hess.shape if t.hess is not None else (0, 0, 0))
    cols = np.broadcast_to(dofs[:, None, :], rows.shape)
    vals = t.hess.ravel() if t.hess is not None else np.zeros(0)
    H = sp.csr_matrix((vals, (rows.ravel(), cols.ravel())), shape=(n, n))
    return t.energy, grad, H
