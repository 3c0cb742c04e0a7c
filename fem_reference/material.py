r"""Hyperelastic materials: first Piola–Kirchhoff stress ``P(F)`` and its tangent ``A = ∂P/∂F``.

Array convention: ``F`` has shape ``(3, 3, ...)`` (any trailing shape, typically ``(n_el, n_qp)``);
``P`` the same; ``A[i, J, k, L, ...] = ∂P_iJ/∂F_kL``.  Units: stresses in Pa.

**Decoupled neo-Hookean** (``formulation="decoupled"``, default; Abaqus ``C10 = μ/2``, ``D1 = 2/κ``)

.. math::

    \psi = \tfrac{\mu}{2}\,(J^{-2/3} I_1 - 3) + \tfrac{\kappa}{2}(J - 1)^2, \qquad
    P = \mu J^{-2/3}\big(F - \tfrac{I_1}{3} F^{-T}\big) + \kappa (J - 1) J\, F^{-T}.

With :math:`a = J^{-2/3}`, :math:`\partial a/\partial F = -\tfrac23 a F^{-T}`,
:math:`\partial F^{-T}_{iJ}/\partial F_{kL} = -F^{-T}_{iL} F^{-T}_{kJ}`:

.. math::

    A_{iJkL} = \mu a\Big[\delta_{ik}\delta_{JL} - \tfrac23 F^{-T}_{kL}F_{iJ} - \tfrac23 F_{kL}F^{-T}_{iJ}
        + \tfrac29 I_1 F^{-T}_{iJ}F^{-T}_{kL} + \tfrac{I_1}{3} F^{-T}_{iL}F^{-T}_{kJ}\Big]
        + \kappa(2J^2 - J)\,F^{-T}_{iJ}F^{-T}_{kL} - \kappa(J^2 - J)\,F^{-T}_{iL}F^{-T}_{kJ}.

**Compressible neo-Hookean of scikit-fem ex43** (``formulation="ex43"``), with Lamé
:math:`\lambda = \kappa - 2\mu/3`:

.. math::

    \psi = \tfrac{\mu}{2}(I_1 - 3) - \mu\ln J + \tfrac{\lambda}{2}\ln^2 J, \qquad
    P = \mu F + (\lambda\ln J - \mu) F^{-T},

    A_{iJkL} = \mu\,\delta_{ik}\delta_{JL} + \lambda F^{-T}_{iJ}F^{-T}_{kL} - (\lambda\ln J - \mu)F^{-T}_{iL}F^{-T}_{kJ}.

**Decoupled Mooney–Rivlin** (``Material.mooney_rivlin``; ``c01 > 0``): adds
:math:`C_{01}(J^{-4/3} I_2 - 3)` to the decoupled form with :math:`\mu = 2(C_{10} + C_{01})`,
:math:`I_2 = \tfrac12(I_1^2 - \operatorname{tr}C^2)`, :math:`G = \tfrac12\partial I_2/\partial F = I_1 F - F C`:

.. math::

    P_{01} = C_{01}\big(2 b\,G - \tfrac43 b I_2 F^{-T}\big), \quad b = J^{-4/3}, \qquad
    \frac{\partial G_{iJ}}{\partial F_{kL}} = 2F_{iJ}F_{kL} + I_1\delta_{ik}\delta_{JL}
        - \delta_{ik}C_{LJ} - F_{iL}F_{kJ} - B_{ik}\delta_{JL},

    A_{01} = C_{01}\Big[2b\,\partial G - \tfrac83 b\,G_{iJ}F^{-T}_{kL}
        + \tfrac{16}{9} b I_2 F^{-T}_{iJ}F^{-T}_{kL} - \tfrac83 b\,F^{-T}_{iJ} G_{kL}
        + \tfrac43 b I_2 F^{-T}_{iL}F^{-T}_{kJ}\Big].

Both reduce to linear elasticity with shear modulus μ and bulk modulus κ at small strain
(``E = 9κμ/(3κ + μ)``, ``ν = (3κ − 2μ)/(2(3κ + μ))``).  Near incompressibility (``κ/μ ≈ 50``, ν ≈ 0.49)
is handled by the mixed u–p wall element of :mod:`fem_reference.assembly`, which replaces the pointwise
volumetric term κ/2 (J − 1)² of the decoupled forms by its element-wise projection (so it needs a decoupled
form; the ex43 form runs with the displacement element only).  docs/fem.md §3a has the locking measurements.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from .errors import ConfigError

from ._checks import validated

__all__ = ["Material"]


def _inv_det(F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(F^{-T}, J)`` for a stack of 3×3 matrices ``F[(3, 3) + shape]`` (explicit cofactors)."""
    c00 = F[1, 1] * F[2, 2] - F[1, 2] * F[2, 1]
    c01 = F[1, 2] * F[2, 0] - F[1, 0] * F[2, 2]
    c02 = F[1, 0] * F[2, 1] - F[1, 1] * F[2, 0]
    c10 = F[0, 2] * F[2, 1] - F[0, 1] * F[2, 2]
    c11 = F[0, 0] * F[2, 2] - F[0, 2] * F[2, 0]
    c12 = F[0, 1] * F[2, 0] - F[0, 0] * F[2, 1]
    c20 = F[0, 1] * F[1, 2] - F[0, 2] * F[1, 1]
    c21 = F[0, 2] * F[1, 0] - F[0, 0] * F[1, 2]
    c22 = F[0, 0] * F[1, 1] - F[0, 1] * F[1, 0]
    J = F[0, 0] * c00 + F[0, 1] * c01 + F[0, 2] * c02
    cof = np.array([[c00, c01, c02], [c10, c11, c12], [c20, c21, c22]])
    with np.errstate(divide="ignore", invalid="ignore"):
        FiT = cof / J
    return FiT, J


@dataclass(frozen=True)
class Material:
    """Isotropic hyperelastic material (SI: Pa, kg/m³).

    Use the constructors :meth:`neo_hookean` (decoupled or ex43 form).
    """

    mu: float
    kappa: float
    density: float = 1100.0
    formulation: Literal["decoupled", "ex43"] = "decoupled"
    c01: float = 0.0

    def __post_init__(self):
        validated(self, "Material")

    def _validate(self):
        for k in ("mu", "kappa", "density"):
            v = getattr(self, k)
            if not np.isfinite(v) or v <= 0:
                raise ConfigError(f"Material.{k} must be positive (SI units), got {v!r}")
        if self.formulation not in ("decoupled", "ex43"):
            raise ConfigError(f"unknown formulation {self.formulation!r}")
        if self.kappa <= 2 * self.mu / 3:
            raise ConfigError("kappa must exceed 2 mu / 3 (Poisson ratio > 0)")
        if self.mu > 1e11:
            raise ConfigError("Material takes Pa; mu > 100 GPa looks wrong")
        if self.c01 < 0 or 2 * self.c01 >= self.mu or (self.c01 and self.formulation != "decoupled"):
            raise ConfigError("c01 must satisfy 0 <= 2 c01 < mu (decoupled Mooney–Rivlin only)")

    @classmethod
    def neo_hookean(cls, mu: float, kappa: float, density: float = 1100.0,
                    formulation: Literal["decoupled", "ex43"] = "decoupled") -> Material:
        """Neo-Hookean solid with shear modulus ``mu`` [Pa], bulk modulus ``kappa`` [Pa], ``density`` [kg/m³]."""
        if any(isinstance(v, (str, bytes, bool, np.bool_)) for v in (mu, kappa, density)):
            raise ConfigError(f"Material.neo_hookean needs numbers [Pa, Pa, kg/m³], got {mu!r}, {kappa!r}, "
                              f"{density!r}")
        try:
            mu, kappa, density = float(mu), float(kappa), float(density)
        except (TypeError, ValueError):
            raise ConfigError(f"Material.neo_hookean needs numbers [Pa, Pa, kg/m³], got {mu!r}, {kappa!r}, "
                              f"{density!r}") from None
        return cls(mu, kappa, density, formulation)

    @classmethod
    def mooney_rivlin(cls, c10: float, c01: float, kappa: float, density: float = 1100.0) -> "Material":
        """Decoupled Mooney–Rivlin ``C10 (Ī1−3) + C01 (Ī2−3) + κ/2 (J−1)²`` [Pa]; shear modulus 2(C10+C01)."""
        if c10 <= 0:
            raise ConfigError("c10 must be positive [Pa]")
        return cls(2.0 * (c10 + c01), float(kappa), float(density), "decoupled", float(c01))

    @classmethod
    def from_E_nu(cls, E: float, nu: float, **kw) -> Material:
        """Neo-Hookean from small-strain Young's modulus ``E`` [Pa] and Poisson ratio ``nu``."""
        mu = E / (2 * (1 + nu))
        kappa = E / (3 * (1 - 2 * nu))
        return cls.neo_hookean(mu, kappa, **kw)

    @property
    def E(self) -> float:
        """Small-strain Young's modulus [Pa]."""
        return 9 * self.kappa * self.mu / (3 * self.kappa + self.mu)

    @property
    def nu(self) -> float:
        """Small-strain Poisson ratio."""
        return (3 * self.kappa - 2 * self.mu) / (2 * (3 * self.kappa + self.mu))

    @property
    def lame_lambda(self) -> float:
        return self.kappa - 2 * self.mu / 3

    # ------------------------------------------------------------------ constitutive law
    def energy(self, F: np.ndarray) -> np.ndarray:
        """Strain energy density ψ(F) [J/m³], shape ``F.shape[2:]``."""
        _, J = _inv_det(F)
        I1 = np.einsum("ij...,ij...->...", F, F)
        if self.formulation == "decoupled":
            mu1 = self.mu - 2 * self.c01
            psi = 0.5 * mu1 * (J ** (-2 / 3) * I1 - 3) + 0.5 * self.kappa * (J - 1) ** 2
            if self.c01:
                C = np.einsum("kI...,kJ...->IJ...", F, F)
                I2 = 0.5 * (I1 ** 2 - np.einsum("IJ...,JI...->...", C, C))
                psi = psi + self.c01 * (J ** (-4 / 3) * I2 - 3)
            return psi
        lnJ = np.log(J)
        return 0.5 * self.mu * (I1 - 3) - self.mu * lnJ + 0.5 * self.lame_lambda * lnJ ** 2

    def stress(self, F: np.ndarray, tangent: bool = True):
        """First Piola–Kirchhoff stress and its tangent.

        Parameters
        ----------
        F : ndarray (3, 3, ...)
            Deformation gradient.
        tangent : bool
            Also return ``A = ∂P/∂F``.

        Returns
        -------
        P : ndarray (3, 3, ...) [Pa]
        A : ndarray (3, 3, 3, 3, ...) [Pa] or None
        J : ndarray (...)  — ``det F``; the caller must reject ``J <= 0`` (P is then meaningless).
        """
        FiT, J = _inv_det(F)
        mu = self.mu - 2 * self.c01 if self.formulation == "decoupled" else self.mu
        if self.formulation == "decoupled":
            I1 = np.einsum("ij...,ij...->...", F, F)
            with np.errstate(invalid="ignore"):
                a = np.abs(J) ** (-2.0 / 3.0)
            P = mu * a * (F - I1 / 3 * FiT) + self.kappa * (J - 1) * J * FiT
            if not tangent:
                if self.c01:
                    P = P + self._mr_i2(F, FiT, J, I1, None, None, tangent=False)[0]
                return P, None, J
            c1 = mu * a
            A = np.zeros((3, 3, 3, 3) + F.shape[2:])
            for i in range(3):
                for J_ in range(3):
                    A[i, J_, i, J_] += c1
            FF = np.einsum("iJ...,kL...->iJkL...", FiT, F)
            A -= (2.0 / 3.0) * c1 * (FF + FF.transpose(2, 3, 0, 1, *range(4, FF.ndim)))
            TT = np.einsum("iJ...,kL...->iJkL...", FiT, FiT)
            A += (2.0 / 9.0) * c1 * I1 * TT
            TTx = TT.transpose(0, 3, 2, 1, *range(4, TT.ndim))  # F^-T_iL F^-T_kJ
            A += (c1 * I1 / 3) * TTx
            A += self.kappa * (2 * J * J - J) * TT - self.kappa * (J * J - J) * TTx
            if self.c01:
                P2, A2 = self._mr_i2(F, FiT, J, I1, TT, TTx)
                P = P + P2
                A = A + A2
            return P, A, J
        lam = self.lame_lambda
        with np.errstate(invalid="ignore", divide="ignore"):
            lnJ = np.log(J)
        P = mu * F + (lam * lnJ - mu) * FiT
        if not tangent:
            return P, None, J
        A = np.zeros((3, 3, 3, 3) + F.shape[2:])
        for i in range(3):
            for J_ in range(3):
                A[i, J_, i, J_] += mu
        TT = np.einsum("iJ...,kL...->iJkL...", FiT, FiT)
        A += lam * TT - (lam * lnJ - mu) * TT.transpose(0, 3, 2, 1, *range(4, TT.ndim))
        return P, A, J

    def _mr_i2(self, F, FiT, J, I1, TT, TTx, tangent=True):
        """``C01 (J^{-4/3} I2 − 3)`` term: stress and tangent (derivation in the module docstring)."""
        c = self.c01
        b = np.abs(J) ** (-4.0 / 3.0)
        C = np.einsum("kI...,kJ...->IJ...", F, F)
        FC = np.einsum("iM...,MJ...->iJ...", F, C)
        I2 = 0.5 * (I1 ** 2 - np.einsum("IJ...,JI...->...", C, C))
        G = I1 * F - FC  # ½ ∂I2/∂F
        P = c * (2 * b * G - (4.0 / 3.0) * b * I2 * FiT)
        if not tangent:
            return P, None
        nd = F.ndim - 2
        outer = lambda X, Y: np.einsum("iJ...,kL...->iJkL...", X, Y)  # noqa: E731
        Bm = np.einsum("iM...,kM...->ik...", F, F)
        d = np.eye(3)
        dG = 2 * outer(F, F) + I1 * np.einsum("ik,JL->iJkL", d, d).reshape((3, 3, 3, 3) + (1,) * nd)
        dG = dG - np.einsum("ik,LJ...->iJkL...", d, C) - np.einsum("iL...,kJ...->iJkL...", F, F) \
            - np.einsum("ik...,JL->iJkL...", Bm, d)
        A = 2 * b * dG - (8.0 / 3.0) * b * outer(G, FiT)
        A = A - (4.0 / 3.0) * (-(4.0 / 3.0) * b * I2 * TT + b * (2 * outer(FiT, G) - I2 * TTx))
        return P, c * A

    # ------------------------------------------------------------------ closed forms
    def uniaxial_stress(self, stretch: float) -> tuple[float, float]:
        """Exact homogeneous uniaxial tension: returns ``(P11 [Pa], lateral stretch)``.

        Solves the lateral equilibrium ``P22(λ1, λ2) = 0`` by a scalar Newton/bisection.
        """
        from scipy.optimize import brentq

        l1 = float(stretch)

        def p(l2):
            F = np.diag([l1, l2, l2]).reshape(3, 3, 1)
            P, _, _ = self.stress(F, tangent=False)
            return P[:, :, 0]

        l2 = brentq(lambda x: p(x)[1, 1], 1e-3, 10.0, xtol=1e-15, rtol=1e-15)
        return float(p(l2)[0, 0]), float(l2)
