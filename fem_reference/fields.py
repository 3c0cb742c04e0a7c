r"""Stress and stretch fields of an FE state, per element, for ParaView (:meth:`BellowsResult.save_vtu`).

At each of an element's 27 Gauss points, from the deformation gradient ``F`` of the displacements and the
solver's own stress (:meth:`fem_reference.material.Material.stress`; for the mixed u–p element with the
pointwise volumetric term replaced by the element's pressure field, as in
:meth:`fem_reference.assembly.HexAssembler._mixed_terms`):

.. math::

    \sigma = J^{-1} P F^T, \qquad b = F F^T, \qquad J = \det F.

For the mixed element the volumetric stress is the pressure field :math:`p_h = \kappa\,\Pi(J - 1)`, linear
in each element (``docs/fem.md`` §3a): :math:`\sigma = \sigma_{iso} + p_h I`, with :math:`\sigma_{iso}`
traceless (decoupled energies), so :math:`p_h = \operatorname{tr}\sigma / 3`.

Per element the fields are averages over the **deformed** element volume, :math:`\bar\sigma = \int\sigma\,dv /
\int dv` with :math:`dv = J\,dV` (27-point Gauss), likewise :math:`\bar b` and :math:`\bar p`; then

- von Mises stress :math:`\sigma_{vM} = \sqrt{\tfrac32\, s : s}`, :math:`s = \bar\sigma -
  \tfrac13 \operatorname{tr}\bar\sigma\, I` (of the averaged tensor, so the three fields are consistent);
- hydrostatic pressure :math:`-\tfrac13\operatorname{tr}\bar\sigma` (positive in compression; for the mixed
  element :math:`-\bar p_h`, the u–p pressure field with the usual sign);
- principal stretches: the eigenvalues of :math:`\bar b^{1/2}` (the left stretch tensor ``V``), largest first.

In a homogeneous deformation every average is the pointwise value (tested against closed forms).
"""

from __future__ import annotations

import numpy as np

from .errors import InputError

from .material import _inv_det

__all__ = ["cauchy_stress", "cell_fields", "principal_stretches", "von_mises"]


def cauchy_stress(P: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Cauchy stress ``σ = P Fᵀ / det F`` [Pa] from the first Piola–Kirchhoff stress ``P`` [Pa] and ``F``, both
    ``(3, 3, ...)``; same shape."""
    _, J = _inv_det(F)
    return np.einsum("iJ...,kJ...->ik...", P, F) / J


def von_mises(sigma: np.ndarray) -> np.ndarray:
    """Von Mises equivalent stress ``√(3/2 s:s)`` [Pa] of Cauchy stresses ``sigma`` ``(3, 3, ...)`` [Pa] (``s`` the
    deviator), shape ``sigma.shape[2:]``."""
    tr = sigma[0, 0] + sigma[1, 1] + sigma[2, 2]
    s = sigma - np.einsum("ij,...->ij...", np.eye(3), tr / 3.0)
    return np.sqrt(1.5 * np.einsum("ij...,ij...->...", s, s))


def principal_stretches(b: np.ndarray) -> np.ndarray:
    """Principal stretches, largest first: square roots of the eigenvalues of the left Cauchy–Green tensors
    ``b = F Fᵀ`` given as ``(n, 3, 3)``; shape ``(n, 3)``."""
    lam2 = np.linalg.eigvalsh(0.5 * (b + np.swapaxes(b, 1, 2)))
    return np.sqrt(np.clip(lam2, 0.0, None))[:, ::-1]


def _volume_mean(X: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Per-element weighted mean ``Σ_q X w / Σ_q w`` of tensors ``X`` (3, 3, ne, nq) with weights ``w`` (ne, nq);
    shape (ne, 3, 3)."""
    return np.einsum("ijeq,eq->eij", X, w) / w.sum(axis=1)[:, None, None]


def cell_fields(asm, U: np.ndarray) -> dict[str, np.ndarray]:
    """Per-element stress and stretch fields of the displacements ``U`` (3, n_nodes) [m] on the mesh of the
    :class:`~fem_reference.assembly.HexAssembler` ``asm`` (its material, element and quadrature).

    Returns (``ne`` elements, in the mesh's element order; averages over the deformed element volume, see the
    module docstring):

    - ``cauchy_stress_Pa`` (ne, 3, 3): Cauchy stress [Pa];
    - ``von_mises_Pa`` (ne,): von Mises stress of that tensor [Pa];
    - ``pressure_Pa`` (ne,): hydrostatic pressure ``−tr σ / 3`` [Pa] (positive in compression; for the mixed
      element the u–p pressure field ``−p_h``);
    - ``principal_stretches`` (ne, 3): principal stretches, largest first [-];
    - ``volume_ratio`` (ne,): deformed / reference element volume ``∫J dV / ∫dV`` [-].

    Raises :class:`~ancf.errors.InputError` if an element is inverted (``det F ≤ 0`` at a Gauss point): no
    stress is defined there (a converged equilibrium never has one).
    """
    out = {k: [] for k in ("cauchy_stress_Pa", "b", "volume_ratio")}
    chunk = 4 * asm.chunk
    for s0 in range(0, asm.ne, chunk):
        sl = slice(s0, min(s0 + chunk, asm.ne))
        F = asm.deformation_gradient(U, sl)
        P, _, J = asm.material.stress(F, tangent=False)
        if not np.all(J > 0):
            raise InputError("the displacements invert an element (det F <= 0 at a Gauss point): its stress "
                             "is undefined")
        if asm.element == "mixed":
            P = asm._mixed_terms(F, J, P, None, sl)[0]
        w = J * asm.dx[sl]                                 # deformed volume per Gauss point (ne, nq)
        out["cauchy_stress_Pa"].append(_volume_mean(cauchy_stress(P, F), w))
        out["b"].append(_volume_mean(np.einsum("iJ...,kJ...->ik...", F, F), w))
        out["volume_ratio"].append(w.sum(axis=1) / asm.dx[sl].sum(axis=1))
    sig = np.concatenate(out["cauchy_stress_Pa"])
    sig_t = np.moveaxis(sig, 0, -1)
    return {"cauchy_stress_Pa": sig,
            "von_mises_Pa": von_mises(sig_t),
            "pressure_Pa": -(sig[:, 0, 0] + sig[:, 1, 1] + sig[:, 2, 2]) / 3.0,
            "principal_stretches": principal_stretches(np.concatenate(out["b"])),
            "volume_ratio": np.concatenate(out["volume_ratio"])}
