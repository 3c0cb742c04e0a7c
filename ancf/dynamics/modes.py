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
from .damping import axial_damping
from .mass import consistent_mass, tip_mass_matrix


@dataclass
class ModalResult:
    """frequencies [Hz] (k,), ascending (undamped); omega2 [1/s²] (k,) the eigenvalues ω²; shapes (k, ndof):
    mode shapes in full coordinates (δq; mass-normalised: φᵀ M φ = 1 [kg]); tip_shapes (k, 3) [m]: the tool
    point's motion in each shape; locked: indices of the tendons held as constraints (empty: tensions held);
    damping_ratios (k,) [-]: ζ_k = φ_kᵀ C φ_k / (2 ω_k) with the damping C of :mod:`.damping` (exact for
    Rayleigh damping, first order in the damping for the axial Kelvin–Voigt part); damping: the coefficients
    used {alpha [1/s], beta [s], axial [N s]}."""
    frequencies: np.ndarray
    omega2: np.ndarray
    shapes: np.ndarray
    tip_shapes: np.ndarray
    locked: tuple = ()
    damping_ratios: np.ndarray = None
    damping: dict = None

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
    if np.shape(eq.q) != (model.ndof,):
        raise InputError(f"the equilibrium has {np.size(eq.q)} coordinates but the model has {model.ndof}")
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
    count = min(int(count), K.shape[0])
    w2, phi = sla.eigh(0.5 * (K + K.T), 0.5 * (Mz + Mz.T), subset_by_index=[0, count - 1])
    if w2[0] < -1e-9 * max(abs(w2[-1]), 1.0):
        raise UnstableEquilibriumError("the linearisation has a negative ω²: the equilibrium is not stable",
                                       solver="modes", min_eigenvalue=float(w2[0]))
    w2 = np.maximum(w2, 0.0)
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
                       zeta, coeffs)
