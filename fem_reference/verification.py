"""Small verification problems with closed-form answers (used by the tests and the benchmark).

- :func:`uniaxial_block` — homogeneous uniaxial tension of a unit cube (symmetry BCs, prescribed
  face displacement, free lateral faces) with the same assembler as the bellows; exact answer from
  :meth:`Material.uniaxial_stress` (docs/fem.md §6.1).
- :func:`tube_beam_theory` — axial, bending (Timoshenko), torsion compliances of a clamped tube.
- :func:`rivlin_ring` / :func:`rivlin_ring_exact` — large-strain inflation of a plane-strain thick
  ring by a follower pressure vs Rivlin's incompressible solution: checks the follower load at
  large strain *and* the absence of volumetric locking of full-integration Hex2 at κ/μ = 1000.
- :func:`curved_wall_bending` — a thin curved wall (quarter ring, R/t = 20, plane strain) bent by a tip
  load with ONE element through the wall, vs the curved-beam closed form: the bending of a thin, nearly
  incompressible curved wall that the bellows' convolutions do, where the displacement element locks.
"""

from __future__ import annotations

import numpy as np

from .errors import InputError

from .assembly import HexAssembler
from .material import Material
from .solver import factorize

__all__ = ["curved_wall_bending", "rivlin_ring", "rivlin_ring_exact", "tube_beam_theory", "uniaxial_block"]


def uniaxial_block(material: Material, stretch: float, n: int = 2, side: float = 0.01,
                   tol: float = 1e-10, max_iter: int = 20, element: str = "mixed") -> dict:
    """FE uniaxial tension of a cube of edge ``side`` [m] on an ``n³`` Hex2 mesh (wall ``element`` of
    :class:`~fem_reference.assembly.HexAssembler`).

    Returns ``{"P11": nominal stress [Pa] from the reaction, "lateral_stretch", "history"}``.
    """
    from skfem import MeshHex1, MeshHex2

    x = np.linspace(0, side, n + 1)
    m = MeshHex2.from_mesh(MeshHex1.init_tensor(x, x, x))
    asm = HexAssembler(m, material, element=element)
    X = m.doflocs
    nn = X.shape[1]
    fixed = []
    for i in range(3):
        fixed.append(3 * np.flatnonzero(np.isclose(X[i], 0.0)) + i)
    top = np.flatnonzero(np.isclose(X[0], side))
    fixed.append(3 * top)
    fixed = np.unique(np.concatenate(fixed))
    free = np.setdiff1d(np.arange(3 * nn), fixed)
    # homogeneous predictor (uniaxial, volume-preserving guess) avoids J <= 0 on the first iterate
    U = np.zeros((3, nn))
    U[0] = (stretch - 1) * X[0]
    l2 = stretch ** -0.5
    U[1] = (l2 - 1) * X[1]
    U[2] = (l2 - 1) * X[2]
    hist = []
    for _ in range(max_iter):
        f, K, jmin = asm.assemble(U)
        r = f[free]
        hist.append(float(np.linalg.norm(r)))
        if hist[-1] < tol * material.mu * side ** 2:
            break
        du = factorize(K[free][:, free], "splu").solve(-r)
        u = U.T.ravel().copy()
        u[free] += du
        U = u.reshape(-1, 3).T.copy()
    f, _, _ = asm.assemble(U, tangent=False)
    reaction = f[3 * top].sum()
    corner = np.flatnonzero(np.isclose(X[0], side) & np.isclose(X[1], side) & np.isclose(X[2], side))[0]
    return dict(P11=reaction / side ** 2, lateral_stretch=1 + U[1, corner] / side, history=hist)


def curved_wall_bending(material: Material, n_along: int = 16, n_thick: int = 1, element: str = "mixed",
                        radius: float = 0.05, thickness: float = 0.0025) -> float:
    r"""Tip deflection of a clamped quarter ring under a radial tip load, over the curved-beam closed form.

    The wall (mid-radius ``radius``, ``thickness`` [m], width = thickness) spans θ ∈ [0, π/2] with
    ``n_along × n_thick`` exactly curved Hex2 elements; it is clamped at θ = 0, held in plane strain
    (u_z = 0), and loaded at θ = π/2 by a small force P along the radius there (y).  Castigliano on
    M(θ) = P R cos θ gives δ = π P R³ / (4 E' I), E' = E / (1 − ν²), I = b t³/12 (membrane and shear add
    O((t/R)²), ≈ 0.25 % here).  Linear: one solve with the tangent at the reference state.  Returns the
    mean tip deflection over δ (1 for a converged, locking-free element).
    """
    import scipy.sparse.linalg as spla
    from skfem import MeshHex1, MeshHex2

    if n_along < 1 or n_thick < 1 or not (0 < thickness < radius):
        raise InputError(f"curved_wall_bending needs n_along, n_thick >= 1 and 0 < thickness < radius, got "
                         f"{n_along}, {n_thick}, {thickness}, {radius}")
    R, t = float(radius), float(thickness)
    m = MeshHex2.from_mesh(MeshHex1.init_tensor(np.linspace(0.0, np.pi / 2, n_along + 1),
                                                np.linspace(R - t / 2, R + t / 2, n_thick + 1),
                                                np.linspace(0.0, t, 2)))
    th, r, z = m.doflocs
    m.doflocs[:] = np.array([r * np.cos(th), r * np.sin(th), z])      # exact curved nodes
    asm = HexAssembler(m, material, element=element)
    X = m.doflocs
    nn = X.shape[1]
    _, K, _ = asm.assemble(np.zeros((3, nn)))
    clamp = np.flatnonzero(np.abs(X[1]) < 1e-12 * R)
    tip = np.flatnonzero(np.abs(X[0]) < 1e-12 * R)
    fixed = np.unique(np.concatenate([3 * clamp, 3 * clamp + 1, 3 * np.arange(nn) + 2]))
    free = np.setdiff1d(np.arange(3 * nn), fixed)
    f = np.zeros(3 * nn)
    f[3 * tip + 1] = 1.0 / tip.size                                       # P = 1 N
    u = np.zeros(3 * nn)
    u[free] = spla.splu(K[free][:, free].tocsc()).solve(f[free])
    E_plane = material.E / (1 - material.nu ** 2)
    return float(u[3 * tip + 1].mean() / (np.pi * R ** 3 / (4 * E_plane * t * t ** 3 / 12)))


def tube_beam_theory(length: float, r_mid: float, thickness: float, material: Material) -> dict:
    """Closed-form compliances of a clamped tube (small strain, E and ν of ``material``).

    Returns ``axial`` L/EA [m/N], ``bending`` FL³/3EI + FL/(k G A) [m/N] (Timoshenko, k = 2(1+ν)/(4+3ν)),
    ``bending_eb`` (no shear), ``rotation_moment`` L/EI, ``torsion`` L/(G J) with J = 2I.
    """
    E, nu, G = material.E, material.nu, material.mu
    Ro, Ri = r_mid + thickness / 2, r_mid - thickness / 2
    A = np.pi * (Ro ** 2 - Ri ** 2)
    I = np.pi * (Ro ** 4 - Ri ** 4) / 4
    k = 2 * (1 + nu) / (4 + 3 * nu)
    L = length
    return dict(axial=L / (E * A), bending=L ** 3 / (3 * E * I) + L / (k * G * A),
                bending_eb=L ** 3 / (3 * E * I), rotation_moment=L / (E * I), torsion=L / (G * 2 * I))


def rivlin_ring_exact(p_over_mu: float, A: float, B: float) -> float:
    """Deformed inner radius ``a`` of an incompressible neo-Hookean thick ring in plane strain under
    internal pressure ``p = p_over_mu · μ`` (Rivlin; docs/fem.md §6.2):
    ``p/μ = ln(B/A) − ln(b/a) + (c/2)(1/a² − 1/b²)``, ``c = a² − A²``, ``b² = B² + c``.
    There is a limit pressure ``μ ln(B/A)``."""
    from scipy.optimize import brentq

    def g(a):
        c = a * a - A * A
        b = np.sqrt(B * B + c)
        return np.log(B / A) - np.log(b / a) + 0.5 * c * (1 / a ** 2 - 1 / b ** 2) - p_over_mu

    if p_over_mu >= np.log(B / A):
        raise InputError("above the limit pressure μ ln(B/A) of the thick-walled tube")
    hi = A * 1.01
    while g(hi) < 0:
        hi *= 1.5
    return brentq(g, A, hi, xtol=1e-15 * A)


def rivlin_ring(material: Material, p_over_mu: float, A: float = 0.01, B: float = 0.02,
                n_thick: int = 4, n_theta: int = 24, n_steps: int = 5, tol: float = 1e-10,
                element: str = "mixed") -> dict:
    """FE plane-strain thick ring (full ring, exact curved Hex2, one element axially) inflated by a
    follower pressure on its inner surface; returns the mean deformed inner radius and Newton data.

    Plane strain: axial displacement fixed everywhere; rigid in-plane motions removed by symmetry
    (``u_y = 0`` on ``y = 0``, ``u_z = 0`` on ``z = 0``).
    """
    from .assembly import PressureAssembler
    from .geometry import BellowsGeometry
    from .mesh import MeshLevel, build_mesh

    h = 0.2 * (B - A)
    geo = BellowsGeometry.straight_tube(h, 0.5 * (A + B), B - A, n_segments=1)
    bm = build_mesh(geo, MeshLevel(1, n_thick, n_theta, 0))
    asm = HexAssembler(bm.mesh, material, element=element)
    pa = PressureAssembler(bm.mesh, bm.inner_facets(), asm.pattern)
    X = bm.X
    nn = X.shape[1]
    scale = B
    fixed = [3 * np.arange(nn)]  # u_x = 0 (plane strain along the tube axis)
    fixed.append(3 * np.flatnonzero(np.abs(X[1]) < 1e-12 * scale) + 1)
    fixed.append(3 * np.flatnonzero(np.abs(X[2]) < 1e-12 * scale) + 2)
    free = np.setdiff1d(np.arange(3 * nn), np.concatenate(fixed))
    U = np.zeros((3, nn))
    hist_all = []
    p_fin = p_over_mu * material.mu
    for k in range(1, n_steps + 1):
        p = p_fin * k / n_steps
        hist = []
        for _ in range(30):
            f, K, jmin = asm.assemble(U)
            fp, Kp = pa.assemble(U, p)
            r = (f - fp)[free]
            hist.append(float(np.linalg.norm(r)))
            if hist[-1] < tol * max(1.0, float(np.linalg.norm(fp))):
                break
            du = factorize((K - Kp)[free][:, free], "splu").solve(-r)
            u = U.T.ravel().copy()
            alpha = 1.0
            while True:
                u2 = u.copy()
                u2[free] += alpha * du
                U2 = u2.reshape(-1, 3).T.copy()
                if asm.min_jacobian(U2) > 0:
                    break
                alpha *= 0.5
            U = U2
        hist_all.append(hist)
    inner = bm.nodes_where(i_t=0)
    x = X[:, inner] + U[:, inner]
    return dict(a=float(np.mean(np.hypot(x[1], x[2]))), a_spread=float(np.ptp(np.hypot(x[1], x[2]))),
                history=hist_all)
