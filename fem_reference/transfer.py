r"""Transfer of a solved state from one mesh of the bellows to another (nested iteration).

A finer mesh's Newton solve need not climb the whole load path again: the equilibrium already solved on a
coarser mesh of the same bellows, interpolated onto the finer one, is within the discretisation error of the
finer equilibrium, so Newton at the full load converges from it in a few iterations (measured in
``docs/fem.md`` §4) instead of the 10–40 load-stepped iterations from rest.  The answer is still the finer
mesh's own equilibrium: the start changes the path, not the converged state (which is checked as every
solve is: full residual, stability).

Interpolation.  Every mesh of :func:`fem_reference.mesh.build_mesh` is the image of a box lattice
:math:`(\zeta, \tau, \theta)` (``BellowsMesh.lattice``), and its 27-node elements interpolate the
displacement quadratically in each lattice direction: element ``e`` along an axis spans the lattice points
``2e, 2e + 1, 2e + 2``.  So the coarse displacement field, as a function of the lattice coordinates, is the
tensor product of 1-D piecewise-quadratic Lagrange interpolants, and its value at a node of any other mesh of
the same geometry is

.. math::  U(\zeta, \tau, \theta) = \sum_{a,b,c} \ell_a(\zeta)\, \ell_b(\tau)\, \ell_c(\theta)\, U_{abc},

three 1-D interpolation matrices applied in turn (θ periodic; exact for piecewise quadratics, tested).  The
deformation is carried through the two meshes' reference geometry (:func:`interpolate`), so an affine
displacement is carried exactly (tested), and the nodes the finer mesh adds are relaxed with the others held
(:func:`relax_new_nodes`).  The cap nodes are then placed on the rigid cap motion
(``RigidCapReduction.place``) and the cap translation, rotation and tendon tensions are copied.

:func:`snapshot` keeps what the transfer needs (lattice coordinates, displacements on the lattice, cap
motion, tensions and the loads) as plain arrays, picklable and independent of the model that made it;
:func:`start_from` turns it into a start (:class:`~fem_reference.results.BellowsResult`) for
``BellowsModel.solve(initial=...)`` of another mesh.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import InputError

__all__ = ["StateSnapshot", "snapshot", "start_from", "interpolate", "new_nodes", "relax_new_nodes",
           "lattice_coordinates", "interpolation_matrix"]


@dataclass(frozen=True)
class StateSnapshot:
    """A solved state on the lattice of its mesh (SI units).

    zeta (n_z,), tau (n_t,), theta (n_h,) : lattice coordinates [m, m, rad] (θ periodic on [0, 2π));
    X, U (3, n_z, n_t, n_h) : reference node positions and nodal displacements on the lattice [m];
    uc (3,) [m], R (3, 3) : the distal cap's translation and rotation; T (m,) : tendon tensions [N];
    pressure [Pa], tip_force (3,) [N], gravity : the loads of the state;
    geometry : the bellows geometry (a transfer needs the same one).
    """
    zeta: np.ndarray
    tau: np.ndarray
    theta: np.ndarray
    X: np.ndarray
    U: np.ndarray
    uc: np.ndarray
    R: np.ndarray
    T: np.ndarray
    pressure: float
    tip_force: np.ndarray
    gravity: float
    geometry: object


def lattice_coordinates(bmesh) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(ζ, τ, θ) coordinates of the fine lattice of a :class:`~fem_reference.mesh.BellowsMesh` [m, m, rad]:
    shapes (2 n_s + 1,), (2 n_t + 1,), (2 n_θ,)."""
    _, n_t, n_th = bmesh.shape
    t = bmesh.geometry.wall_thickness
    return (np.asarray(bmesh.zeta, float), np.linspace(-t / 2, t / 2, 2 * n_t + 1),
            2 * np.pi * np.arange(2 * n_th) / (2 * n_th))


def interpolation_matrix(nodes: np.ndarray, x: np.ndarray, periodic: float | None = None,
                         derivative: bool = False) -> np.ndarray:
    """Piecewise-quadratic Lagrange interpolation from the lattice ``nodes`` (2 n + 1 increasing points,
    element ``e`` on ``nodes[2e : 2e + 3]``; with ``periodic`` = P, 2 n points and the last element closing on
    ``nodes[0] + P``) to the points ``x`` → dense matrix (len(x), len(nodes)); with ``derivative``, the matrix
    of the interpolant's derivative d/dx instead.  Points outside the lattice (beyond round-off) raise
    InputError."""
    nodes = np.asarray(nodes, float)
    x = np.asarray(x, float)
    N = nodes.size
    ext = np.append(nodes, nodes[0] + periodic) if periodic is not None else nodes
    n_el = (ext.size - 1) // 2
    if ext.size != 2 * n_el + 1 or n_el < 1:
        raise InputError(f"interpolation_matrix: {N} lattice points do not make whole quadratic elements")
    if periodic is not None:
        x = nodes[0] + np.mod(x - nodes[0], periodic)
    span = ext[-1] - ext[0]
    if np.any(x < ext[0] - 1e-9 * span) or np.any(x > ext[-1] + 1e-9 * span):
        raise InputError("interpolation_matrix: points outside the lattice (a different geometry?)")
    e = np.clip(np.searchsorted(ext[2::2], x, side="left"), 0, n_el - 1)
    P = np.zeros((x.size, N))
    x0, x1, x2 = ext[2 * e], ext[2 * e + 1], ext[2 * e + 2]
    if derivative:
        ell = ((2 * x - x1 - x2) / ((x0 - x1) * (x0 - x2)),
               (2 * x - x0 - x2) / ((x1 - x0) * (x1 - x2)),
               (2 * x - x0 - x1) / ((x2 - x0) * (x2 - x1)))
    else:
        ell = ((x - x1) * (x - x2) / ((x0 - x1) * (x0 - x2)),
               (x - x0) * (x - x2) / ((x1 - x0) * (x1 - x2)),
               (x - x0) * (x - x1) / ((x2 - x0) * (x2 - x1)))
    rows = np.arange(x.size)
    for a in range(3):
        np.add.at(P, (rows, (2 * e + a) % N), ell[a])
    return P


def snapshot(result) -> StateSnapshot:
    """The :class:`StateSnapshot` of a solved :class:`~fem_reference.results.BellowsResult`."""
    model, st = result.model, result.state
    bm = model.bmesh
    z, t, h = lattice_coordinates(bm)
    G = np.empty((2, 3, z.size, t.size, h.size))
    G[:, :, bm.lattice[0], bm.lattice[1], bm.lattice[2]] = bm.X, st.U
    lc = result.loadcase
    return StateSnapshot(z, t, h, G[0], G[1], st.uc.copy(), st.R.copy(), st.T.copy(), float(lc.pressure),
                         np.asarray(lc.tip_force, float).copy(), float(lc.gravity), model.geometry)


def _lattice_field(snap: StateSnapshot, bmesh, G: np.ndarray):
    """Fields given on the snapshot's lattice, ``G`` (k, 3, n_z, n_t, n_h), at the lattice points of ``bmesh``:
    their values (k, 3, n_z', n_t', n_h') and lattice derivatives (k, 3, 3, n_z', n_t', n_h') [per m, m, rad]."""
    z, t, h = lattice_coordinates(bmesh)
    P = [interpolation_matrix(snap.zeta, z), interpolation_matrix(snap.tau, t),
         interpolation_matrix(snap.theta, h, periodic=2 * np.pi)]
    D = [interpolation_matrix(snap.zeta, z, derivative=True), interpolation_matrix(snap.tau, t, derivative=True),
         interpolation_matrix(snap.theta, h, periodic=2 * np.pi, derivative=True)]
    val = np.einsum("zi,tj,hk,fdijk->fdzth", *P, G, optimize=True)
    der = np.stack([np.einsum("zi,tj,hk,fdijk->fdzth", *[D[a] if a == b else P[a] for a in range(3)], G,
                              optimize=True) for b in range(3)], axis=2)
    return val, der


def interpolate(snap: StateSnapshot, bmesh) -> np.ndarray:
    """The snapshot's displacements carried to the nodes of ``bmesh`` (same geometry) → (3, n_nodes) [m].

    A node of ``bmesh`` at lattice point ξ sits at the exact reference point X(ξ); the snapshot's mesh,
    quadratic in ξ, has its own reference point X_c(ξ) there, which differs between its nodes (by up to 5 % of
    the wall thickness on the default design's convolutions).  The coarse deformation φ_c is carried to the
    exact point, to first order: φ_c(X) ≈ x_c(ξ) + F_c (X − X_c(ξ)), F_c = (∂x_c/∂ξ)(∂X_c/∂ξ)⁻¹, so a rigid
    rotation is carried as a rigid rotation (interpolating the displacement alone would strain the finer wall
    by (R − I)(X − X_c) — measured: a residual of 2e3 N on a 5/5/0 N, 100 kPa bend)."""
    val, der = _lattice_field(snap, bmesh, np.stack([snap.X + snap.U, snap.X]))
    lat = bmesh.lattice
    xq, Xq = val[:, :, lat[0], lat[1], lat[2]]                # (3, n) each: deformed and reference x_c, X_c
    dx, dX = der[:, :, :, lat[0], lat[1], lat[2]]             # (3, 3, n) each: ∂x_i/∂ξ_b, ∂X_i/∂ξ_b
    X = bmesh.X
    # F_c (X − X_c) = (∂x/∂ξ) (∂X/∂ξ)⁻¹ (X − X_c): solve (∂X/∂ξ) w = X − X_c per node
    w = np.linalg.solve(np.moveaxis(dX, -1, 0), (X - Xq).T[:, :, None])[:, :, 0]   # (n, 3)
    return xq + np.einsum("ibn,nb->in", dx, w) - X


def new_nodes(snap: StateSnapshot, bmesh) -> np.ndarray:
    """Boolean mask (n_nodes,) of the nodes of ``bmesh`` that are not at a lattice point of the snapshot's mesh
    (the nodes a refinement added)."""
    out = np.zeros(bmesh.n_nodes, bool)
    for ax, (old, new) in enumerate(zip((snap.zeta, snap.tau, snap.theta), lattice_coordinates(bmesh))):
        tol = 1e-9 * (np.ptp(new) + 1e-300)
        kept = np.abs(new[:, None] - old[None, :]).min(axis=1) <= tol
        out |= ~kept[bmesh.lattice[ax]]
    return out


#: Newton iterations of the local relaxation of the added nodes (measured: 3–4 reach round-off; 2 leave the
#: solve that follows the same equilibrium — FEM error estimates equal to 7 digits — in 2 s less per refined case)
RELAX_ITERATIONS = 2


def relax_new_nodes(model, st, lc, mask: np.ndarray, iterations: int = RELAX_ITERATIONS) -> list[float]:
    """Newton on the free nodes in ``mask`` alone, every other node held (in place on ``st``).

    The interpolated field is exact at the kept nodes to the coarse discretisation, but between them it is
    the coarse element's polynomial, whose volume change the finer element's pressure space sees as an
    error (a residual of ≈ 1e3 N measured on the default design, 85 % of it on the added nodes, with a
    tangent of the full system nearly singular in its direction: a full Newton step from there moved
    nodes by 0.16 m).  With the kept nodes held, the added ones solve small, well-posed problems (each
    row of added nodes sits between held rows).  Returns the residual norms [N] of the added nodes: before each
    iteration, and after the last one when all ``iterations`` ran."""
    from .solver import factorize
    c = model.caps
    free = mask[c.free_nodes]
    dofs = np.flatnonzero(np.repeat(free, 3))
    hist: list[float] = []
    if dofs.size == 0:
        return hist
    ev = model.evaluate(st, lc, tangent=True)
    for _ in range(iterations):
        if ev["r"] is None:           # inverted elements: leave the start to the solve (which says so)
            break
        r = ev["r"]
        hist.append(float(np.linalg.norm(r[dofs])))
        K = ev["K"][dofs][:, dofs]
        dq = np.zeros_like(r)
        dq[dofs] = -factorize(K, model.linear_solver).solve(r[dofs])
        for alpha in (1.0, 0.5, 0.25, 0.125):
            trial = model._apply(st, dq, alpha, rings=False)   # the held nodes stay
            ev_t = model.evaluate(trial, lc, tangent=True)
            if ev_t["r"] is not None and np.linalg.norm(ev_t["r"][dofs]) < hist[-1]:
                break
        else:
            break                     # no decrease: the start is as good as it gets
        st.U[:], st.uc[:], st.R[:] = trial.U, trial.uc, trial.R
        ev = ev_t
    if ev["r"] is not None and len(hist) == iterations:     # the residual the last iteration left
        hist.append(float(np.linalg.norm(ev["r"][dofs])))
    return hist


def start_from(snap: StateSnapshot, model, relax: bool = True):
    """A start for ``model.solve(initial=...)``: the snapshot's state interpolated onto ``model``'s mesh,
    with the snapshot's loads, and (``relax``) the nodes the finer mesh adds relaxed with the others held
    (:func:`relax_new_nodes`).  Not an equilibrium of ``model`` (its residual is the discretisation
    difference); the solve converges it.  InputError for another geometry or tendon count."""
    from .model import LoadCase
    from .results import BellowsResult
    if snap.geometry != model.geometry:
        raise InputError("start_from: the snapshot was solved for another geometry")
    if snap.T.shape != (model.m,):
        raise InputError(f"start_from: the snapshot has {snap.T.size} tendons, the model {model.m}")
    st = model.zero_state()
    st.U[:] = interpolate(snap, model.bmesh)
    st.uc[:], st.R[:], st.T[:] = snap.uc, snap.R, snap.T
    model.caps.place(st.U, st.uc, st.R)
    lc = LoadCase(snap.T.copy(), snap.pressure, snap.tip_force.copy(), snap.gravity, np.full(model.m, np.nan))
    if relax:
        relax_new_nodes(model, st, lc, new_nodes(snap, model.bmesh))
    return BellowsResult(model=model, state=st, loadcase=lc, stats=None,
                         tendon_lengths=model.tendon_lengths(st))
