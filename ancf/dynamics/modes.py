r"""Small vibrations about an equilibrium: natural frequencies and mode shapes.

Linearising M q̈ + Q(q) = 0 about an equilibrium q* in the free coordinates z (q = q_fix + P z):

    M_z δz̈ + K_z δz = 0,    M_z = Pᵀ (M + m J_pᵀ J_p) P,    K_z = ∂Q_z/∂z,

with the loads of the equilibrium held: tensions as they are (tendons driven at constant tension), pressure,
tip force and gravity as dead loads.  Locked tendons (an equilibrium of :meth:`ancf.Model.fk_locked`): rigid
tendons are the constraints J_A δz = 0, so the problem is solved on their null space Z (K_z → Zᵀ K_z Z,
M_z → Zᵀ M_z Z, shapes Z φ); elastic ones (``tendon_stiffness`` k_s) add k_s J_Aᵀ J_A to K_z.  These are the
stiffness matrices of the stability check (:meth:`ancf.Model.fk`, docs/errors.md), so a stable equilibrium
has real, positive frequencies.  The generalized symmetric eigenproblem K φ = ω² M φ is solved densely
(:func:`scipy.linalg.eigh`); f = ω / 2π.

**Axial or bending** (:func:`strain_energy_split`).  A mode is classified by where its elastic strain energy
goes, along the body, not by the direction its tip moves in a fixed frame (a bent actuator's axial mode moves
the tip along its own bent axis).  The first variation of the model's strains along a shape φ, at each
quadrature point (a = r_x, b = r_xx, λ = |a|, t = a/λ, κ = a × b / λ³ the curvature vector whose square
the bending energy ½ EI κ² uses — :mod:`ancf.forces.bending`):

    δλ = t · δa,      δκ = (δa × b + a × δb) / λ³ − 3 (a · δa) (a × b) / λ⁵,

gives the mode's axial and bending strain energies

    U_A = ½ ∫ W''(λ) δλ² dx,      U_B = ½ ∫ EI(λ, p) |δκ|² dx,

W''(λ) = ½ EA'(λ)(λ³ − λ) + ½ EA(λ)(3λ² − 1) the axial energy's stretch stiffness (:mod:`ancf.stiffness`,
with the pressure factors of a pressure-dependent law).  These are the *material* parts of the second
variation of U_axial and U_bend (the prestress terms — W'(λ)/λ (I − t tᵀ), κ · δ²κ — and the load potentials
are left out: they are not strain of the body).  The axial share U_A / (U_A + U_B) ∈ [0, 1] labels a mode
``axial`` above ½, else ``bending``; on a straight, unstressed rod it is exactly 1 for the axial modes and 0
for the bending ones (no coupling at first order), and for mass-normalised shapes U_A + U_B ≈ ω²/2.

Verified against closed forms (tests/test_dynamics_modes.py): the clamped-free Euler–Bernoulli beam
(f_k = β_k² / 2π · √(EI / (m' L⁴)), β₁ L = 1.8751, β₂ L = 4.6941), the fixed-free axial rod
(f = √(EA/m') / 4L), a tip mass on a light beam (f = √(3 EI / (m L³)) / 2π), and the interlacing of
constrained (locked) and unconstrained eigenvalues.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from ..errors import InputError, UnstableEquilibriumError
from .damping import axial_damping, damping_source
from .mass import consistent_mass, tip_mass_matrix


@dataclass
class ModalResult:
    """frequencies [Hz] (k,), ascending (undamped); omega2 [1/s²] (k,) the eigenvalues ω²; shapes (k, ndof):
    mode shapes in full coordinates (δq; mass-normalised: φᵀ M φ = 1 [kg]); tip_shapes (k, 3) [m]: the tool
    point's motion in each shape; locked: indices of the tendons held as constraints (empty: tensions held);
    damping_ratios (k,) [-]: ζ_k = φ_kᵀ C φ_k / (2 ω_k) with the damping C of :mod:`.damping` (exact for
    Rayleigh damping, first order in the damping for the axial Kelvin–Voigt part); damping: the coefficients
    used {alpha [1/s], beta [s], axial [N s]}; damping_source: "given" (the call's ``damping=``), "actuator"
    (the actuator's coefficients) or "none" (the actuator states no damping: the ratios are 0 because nothing
    is known, not because the actuator is undamped); axial_share (k,) [-]: the share of each mode's elastic
    strain energy in axial stretch (module docstring; the rest is bending), ``kinds`` the labels from it."""
    frequencies: np.ndarray
    omega2: np.ndarray
    shapes: np.ndarray
    tip_shapes: np.ndarray
    locked: tuple = ()
    damping_ratios: np.ndarray = None
    damping: dict = None
    damping_source: str = "given"
    axial_share: np.ndarray = None

    @property
    def kinds(self) -> tuple:
        """Per mode "axial" (axial share of its strain energy > ½) or "bending"."""
        return tuple("axial" if s > 0.5 else "bending" for s in self.axial_share)

    @property
    def tip_directions(self) -> np.ndarray:
        """(k, 3) [-] the unit vector along which the tool point moves in each mode (world frame; zero for a
        mode that does not move it)."""
        n = np.linalg.norm(self.tip_shapes, axis=1, keepdims=True)
        return np.divide(self.tip_shapes, n, out=np.zeros_like(self.tip_shapes), where=n > 0)

    @property
    def frequencies_hz(self) -> np.ndarray:
        """The natural frequencies [Hz] (k,), ascending (same as ``frequencies``)."""
        return self.frequencies


def modes(model, eq, count: int = 6, damping=None) -> ModalResult:
    """The ``count`` lowest modes of ``model`` about its equilibrium ``eq`` (module docstring).  ``damping``:
    None — the actuator's coefficients; a dict {alpha [1/s], beta [s], axial [N s]}; a number ζ — the ratio
    of the first mode (stiffness-proportional), as in :meth:`ancf.Model.simulate`.  InputError
    when the actuator has no mass to vibrate or ``count`` is out of range; UnstableEquilibriumError about an
    unstable equilibrium (it has no vibration modes: a negative ω²)."""
    p = model.params
    if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or not 1 <= count <= model.nz:
        raise InputError(f"count must be an integer 1…{model.nz} (the free coordinates), got {count!r}")
    if not p.line_mass > 0:
        raise InputError("modes need the actuator's line mass (line_mass > 0 kg/m): without it the mass "
                         "matrix is singular")
    check_equilibrium(model, eq, "modes")
    if not eq.stable:
        raise UnstableEquilibriumError("modes about an unstable equilibrium (a saddle has no vibration modes)",
                                       solver="modes", min_eigenvalue=eq.min_eigenvalue)
    q = np.asarray(eq.q, float)
    M = consistent_mass(model.n, model._N, model._wq, p.line_mass)
    if p.tip_mass > 0:
        M = M + tip_mass_matrix(q, p.tool_offset, p.tip_mass)
    ev = model.evaluate(q, eq.tensions, eq.pressure, eq.tip_force)
    K = model.reduce_mat(ev.K)
    Mz = model.reduce_mat(M)
    A = tuple(int(i) for i in (eq.active or ()))
    Z = None
    if A:
        JA = model.reduce_vec(ev.J_l)[list(A)]
        if p.tendon_stiffness:
            K = K + p.tendon_stiffness * JA.T @ JA
        else:
            Z = np.linalg.qr(JA.T, mode="complete")[0][:, len(A):]
            K, Mz = Z.T @ K @ Z, Z.T @ Mz @ Z
    w2, phi = lowest_modes(K, Mz, count)
    dz = phi if Z is None else Z @ phi                                # (nz, k)
    if model._P is None:
        shapes = np.zeros((count, model.ndof))
        shapes[:, 6:] = dz.T
    else:
        shapes = (model._P @ dz).T
    Jp = model.tip_jacobian(q)
    Ks = 0.5 * (K + K.T)
    Ms = 0.5 * (Mz + Mz.T)
    from .transient import resolve_damping
    coeffs = resolve_damping(model, damping, Ks, Ms)
    C = coeffs["alpha"] * Ms + coeffs["beta"] * Ks
    if coeffs["axial"] > 0:
        Cax = model.reduce_mat(axial_damping(q, np.zeros(model.ndof), model.n, model._N, model._wq,
                                             coeffs["axial"])[2])
        C = C + (Cax if Z is None else Z.T @ Cax @ Z)
    omega = np.sqrt(w2)
    with np.errstate(divide="ignore", invalid="ignore"):
        zeta = np.where(omega > 0, np.einsum("ik,ij,jk->k", phi, C, phi) / (2 * omega), np.inf)
    if not np.any(C):
        zeta = np.zeros(count)
    return ModalResult(omega / (2 * np.pi), w2, shapes, shapes @ Jp.T, A if Z is not None or A else (),
                       zeta, coeffs, damping_source(p, damping), axial_share(model, eq, shapes))


#: relative residual an equilibrium may have under the model's loads (:func:`check_equilibrium`)
EQ_RTOL = 1e-6


def lowest_modes(K: np.ndarray, M: np.ndarray, count: int) -> tuple[np.ndarray, np.ndarray]:
    """The ``count`` lowest modes of K φ = ω² M φ (K, M (n, n), their symmetric parts used) → (ω² (k,) [1/s²],
    φ (n, k)), k = min(count, n); UnstableEquilibriumError when the lowest ω² is negative beyond round-off (an
    equilibrium that is not stable has no vibration modes), round-off negatives clipped to 0."""
    count = min(int(count), K.shape[0])
    w2, phi = sla.eigh(0.5 * (K + K.T), 0.5 * (M + M.T), subset_by_index=[0, count - 1])
    if w2[0] < -1e-9 * max(abs(w2[-1]), 1.0):
        raise UnstableEquilibriumError("the linearisation has a negative ω²: the equilibrium is not stable",
                                       solver="modes", min_eigenvalue=float(w2[0]))
    return np.maximum(w2, 0.0), phi


def check_equilibrium(model, eq, what: str) -> None:
    """InputError unless ``eq`` is an equilibrium of ``model``: its size is the model's (ndof,), it was not
    solved by a model of other parameters (the actuator it carries, set by every solve of :class:`ancf.Model`,
    compared with ``model.params``; an equilibrium built by hand carries none and is judged by its residual
    alone), and its free generalized-force residual under its own loads (tensions, pressure, tip force) in this
    model is ~0: ‖Q_z‖ ≤ EQ_RTOL · max(‖Q_z,body‖, ‖Q_z,loads‖) + 10 · model.default_tol [N, N m], with
    Q_body the elastic and gravity forces at eq.q, Q_loads the tendon, pressure and tip-force ones (they
    balance at an equilibrium; EQ_RTOL = 1e-6, the solvers converge to about 1e-12 of them).  ``what`` names
    the caller in the message."""
    q = getattr(eq, "q", None)
    if q is None or not hasattr(eq, "tensions"):
        raise InputError(f"{what}: needs an equilibrium of this model (from fk, fk_locked or ik), got "
                         f"{type(eq).__name__}")
    if np.shape(q) != (model.ndof,) or np.size(eq.tensions) != model.m:
        raise InputError(f"{what}: the equilibrium has {np.size(q)} coordinates and {np.size(eq.tensions)} "
                         f"tensions but this model has {model.ndof} and {model.m}: it belongs to another actuator")
    solved_by = getattr(eq, "__dict__", {}).get("_params")
    if solved_by is not None and solved_by is not model.params and solved_by != model.params:
        raise InputError(f"{what}: the equilibrium was solved for the actuator '{solved_by.name}', not for this "
                         f"model's '{model.params.name}' (their parameters differ): solve it with this model")
    ev = model.evaluate(q, eq.tensions, eq.pressure, eq.tip_force)
    body = model.evaluate(q, np.zeros(model.m), 0.0, np.zeros(3))
    Qz, Qb = model.reduce_vec(ev.Q), model.reduce_vec(body.Q)
    res = float(np.linalg.norm(Qz))
    scale = max(float(np.linalg.norm(Qb)), float(np.linalg.norm(Qz - Qb)))
    if not res <= EQ_RTOL * scale + 10.0 * model.default_tol:
        raise InputError(f"{what}: the state is not an equilibrium of this model under its loads (force "
                         f"residual {res:.3g} N = {res / max(scale, 1e-300):.2g} of the forces at the state, "
                         f"allowed {EQ_RTOL:g}): pass an equilibrium this model solved (fk, fk_locked, ik)")


def strain_energy_split(model, q: np.ndarray, shapes: np.ndarray, pressure: float = 0.0) -> np.ndarray:
    """(k, 2) [J]: the axial and bending strain energies (U_A, U_B) of each shape (k, ndof) (a δq about the
    state q (ndof,)) at the pressure [Pa] (module docstring: the material parts of the second variation)."""
    shapes = np.atleast_2d(np.asarray(shapes, float))
    ea, ei = model.params.stiffness.coefficients(float(pressure))
    n, N, wq = model.n, model._N, model._wq
    idx = 6 * np.arange(n)[:, None] + np.arange(12)[None, :]

    def slopes(v):                                                      # (r_x, r_xx) at every point (n, nq, 3)
        ve = v[idx].reshape(n, 4, 3)
        return np.einsum("kj,ejc->ekc", N[:, 1, :], ve), np.einsum("kj,ejc->ekc", N[:, 2, :], ve)

    a, b = slopes(np.asarray(q, float))
    lam = np.linalg.norm(a, axis=-1)
    t = a / lam[..., None]
    P = np.polynomial.polynomial
    W2 = 0.5 * P.polyval(lam, P.polyder(ea)) * (lam ** 3 - lam) + 0.5 * P.polyval(lam, ea) * (3 * lam ** 2 - 1)
    EI = P.polyval(lam, ei)
    axb = np.cross(a, b)
    out = np.empty((len(shapes), 2))
    for k, phi in enumerate(shapes):
        da, db = slopes(phi)
        dlam = np.einsum("ekc,ekc->ek", t, da)
        dkap = ((np.cross(da, b) + np.cross(a, db)) / lam[..., None] ** 3
                - 3.0 * (np.einsum("ekc,ekc->ek", a, da) / lam ** 5)[..., None] * axb)
        out[k] = 0.5 * np.sum(wq * W2 * dlam ** 2), 0.5 * np.sum(wq * EI * np.sum(dkap ** 2, axis=-1))
    return out


def axial_share(model, eq, shapes: np.ndarray) -> np.ndarray:
    """(k,) [-]: U_A / (U_A + U_B) of each shape about the equilibrium ``eq`` (:func:`strain_energy_split`;
    0 for a shape without strain)."""
    U = strain_energy_split(model, eq.q, shapes, eq.pressure)
    tot = U.sum(axis=1)
    return np.divide(U[:, 0], tot, out=np.zeros(len(U)), where=tot > 0)
