"""Pluggable stiffness laws: EA(λ) [N] and EI(λ) [N m²] as polynomials in the local stretch λ = |r_x|.

Paper Sec. II-B identifies an effective structural stiffness ``k(λ) = a λ + b`` (a = 1336 N, b = -568.8 N)
and writes ``k_t = k(λ) l_0``, ``k_b = D_a² l_0 λ k(λ) / 8``.  With the element energy written over the
normalised coordinate ξ ∈ [0, 1] this reads (docs/design.md §3, flagged interpretation)

    EA(λ) = k(λ) = a λ + b,                 EI(λ) = D_a² λ k(λ) / 8 = (D_a²/8)(a λ² + b λ).

Both are polynomials in λ, and so is the constant law (EA, EI fixed); a general polynomial law covers
identified refinements.  The kernels therefore only need coefficient vectors.

Axial energy per unit reference length.  With Green strain ε = ½(λ² − 1) and dW/dε = EA(λ) ε,

    W'(λ)  = dW/dλ = EA(λ) ε λ = ½ EA(λ) (λ³ − λ),
    W''(λ) = ½ EA'(λ) (λ³ − λ) + ½ EA(λ) (3λ² − 1),
    W(λ)   = Σ_k c_k/2 [ (λ^{k+4} − 1)/(k+4) − (λ^{k+2} − 1)/(k+2) ]     for EA = Σ_k c_k λ^k,

so that W(1) = W'(1) = 0 at the undeformed state (for the constant law W = EA ε² / 2).
"""

from __future__ import annotations

import math
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, ValidationError, field_validator

from .errors import ConfigError, check_finite


def _real(name: str, v) -> float:
    """A finite real number (not text, not a boolean) as float, else ConfigError."""
    if isinstance(v, (bool, np.bool_, str, bytes)) or not isinstance(v, (int, float, np.integer, np.floating)):
        raise ConfigError(f"stiffness law: {name} must be a number, got {v!r}")
    if not math.isfinite(float(v)):
        raise ConfigError(f"stiffness law: {name} must be finite, got {v!r}")
    return float(v)


def _stretch(lam):
    """Stretch argument(s) as float (scalar stays scalar); InputError for text, booleans, NaN."""
    arr = check_finite("stretch λ", lam)
    return float(arr) if arr.ndim == 0 else arr


class StiffnessLaw(BaseModel):
    """Axial and bending stiffness as polynomials in the stretch λ.

    Attributes
    ----------
    kind : {"linear", "constant", "polynomial"}
        How the law was built (for display and TOML round trips).
    EA_coeffs : tuple of float
        ``EA(λ) = Σ_k EA_coeffs[k] λ^k`` [N].
    EI_coeffs : tuple of float
        ``EI(λ) = Σ_k EI_coeffs[k] λ^k`` [N m²].
    source : dict
        The constructor's arguments in SI units (``a``, ``b``, ``D_a`` for the linear law, ...).
    """

    model_config = ConfigDict(frozen=True, extra="forbid")

    kind: Literal["linear", "constant", "polynomial"]
    EA_coeffs: tuple[float, ...]
    EI_coeffs: tuple[float, ...]
    source: dict[str, float] = {}

    def __init__(self, **data):
        try:
            super().__init__(**data)
        except ValidationError as exc:
            msgs = "; ".join(f"{'.'.join(str(p) for p in e['loc']) or 'value'}: "
                             f"{e['msg'].removeprefix('Value error, ')}" for e in exc.errors())
            raise ConfigError(f"invalid stiffness law: {msgs}") from None

    @field_validator("EA_coeffs", "EI_coeffs", mode="before")
    @classmethod
    def _numbers(cls, v):
        if isinstance(v, (str, bytes)) or not hasattr(v, "__len__"):
            raise ValueError(f"expected a list of numbers, got {v!r}")
        return tuple(_real("coefficient", c) for c in v)

    @field_validator("EA_coeffs", "EI_coeffs")
    @classmethod
    def _finite(cls, v):
        if len(v) == 0 or len(v) > 8:
            raise ValueError("needs 1 to 8 polynomial coefficients")
        if not all(np.isfinite(v)):
            raise ValueError("coefficients must be finite")
        return tuple(float(c) for c in v)

    # ---------------------------------------------------------------- constructors
    @classmethod
    def linear(cls, a: float, b: float, D_a: float) -> "StiffnessLaw":
        """The paper's law ``k(λ) = a λ + b`` [N] with equivalent diameter ``D_a`` [m]."""
        a, b, D_a = _real("a", a), _real("b", b), _real("D_a", D_a)
        if D_a <= 0 or D_a > 1.0:
            raise ConfigError(f"linear stiffness law: D_a = {D_a} m is not a plausible diameter "
                              "(expected metres, e.g. 0.02959)")
        if a + b <= 0:
            raise ConfigError(f"linear stiffness law: k(1) = a + b = {a + b} N must be positive")
        c = D_a ** 2 / 8.0
        return cls(kind="linear", EA_coeffs=(b, a), EI_coeffs=(0.0, c * b, c * a),
                   source={"a": float(a), "b": float(b), "D_a": float(D_a)})

    @classmethod
    def constant(cls, EA: float, EI: float) -> "StiffnessLaw":
        """Constant axial stiffness ``EA`` [N] and bending stiffness ``EI`` [N m²]."""
        EA, EI = _real("EA", EA), _real("EI", EI)
        if EA <= 0 or EI <= 0:
            raise ConfigError(f"constant stiffness law needs EA > 0 and EI > 0, got EA={EA}, EI={EI}")
        return cls(kind="constant", EA_coeffs=(float(EA),), EI_coeffs=(float(EI),),
                   source={"EA": float(EA), "EI": float(EI)})

    @classmethod
    def polynomial(cls, EA, EI) -> "StiffnessLaw":
        """General law from coefficient lists (lowest power first) for EA [N] and EI [N m²]."""
        law = cls(kind="polynomial", EA_coeffs=tuple(EA), EI_coeffs=tuple(EI))
        if law.EA(1.0) <= 0 or law.EI(1.0) <= 0:
            raise ConfigError("polynomial stiffness law must give EA(1) > 0 and EI(1) > 0")
        return law

    # ---------------------------------------------------------------- evaluation (numpy, scalar or array)
    @property
    def ea(self) -> np.ndarray:
        return np.asarray(self.EA_coeffs, float)

    @property
    def ei(self) -> np.ndarray:
        return np.asarray(self.EI_coeffs, float)

    @property
    def valid_stretch_range(self) -> tuple[float, float]:
        """Open interval (λ_lo, λ_hi) of stretches around λ = 1 where the law is valid: EA(λ) > 0 and
        EI(λ) > 0.  Outside it the section has collapsed (the paper's linear law EA = a λ + b reaches zero
        at λ = −b/a ≈ 0.43); a state with a stretch outside this interval is never returned as an
        equilibrium (:class:`~ancf.errors.CollapsedStateError`).  ``λ_hi`` may be ``inf``."""
        lo, hi = 0.0, math.inf
        for coeffs in (self.EA_coeffs, self.EI_coeffs):
            c = np.trim_zeros(np.asarray(coeffs, float), "b")
            if c.size < 2:
                continue
            roots = np.polynomial.polynomial.polyroots(c)
            real = roots[np.abs(roots.imag) <= 1e-12 * np.maximum(1.0, np.abs(roots.real))].real
            below, above = real[real < 1.0], real[real > 1.0]
            if below.size:
                lo = max(lo, float(below.max()))
            if above.size:
                hi = min(hi, float(above.min()))
        return lo, hi

    def EA(self, lam):
        """Axial stiffness EA(λ) [N]."""
        return np.polynomial.polynomial.polyval(_stretch(lam), self.ea)

    def EI(self, lam):
        """Bending stiffness EI(λ) [N m²]."""
        return np.polynomial.polynomial.polyval(_stretch(lam), self.ei)

    def axial_energy(self, lam):
        """W(λ) [J/m = N], with W(1) = 0 (see module docstring)."""
        lam = _stretch(lam)
        return sum(c / 2 * ((lam ** (k + 4) - 1) / (k + 4) - (lam ** (k + 2) - 1) / (k + 2))
                   for k, c in enumerate(self.EA_coeffs))

    def axial_force(self, lam):
        """W'(λ) = EA(λ) ε λ [N]: the axial force at stretch λ."""
        lam = _stretch(lam)
        return 0.5 * self.EA(lam) * (lam ** 3 - lam)

    def stretch_under_force(self, force: float, lam0: float = 1.0) -> float:
        """Uniform stretch λ with W'(λ) = ``force`` [N] (closed-form root of a polynomial)."""
        # W'(λ) = ½ Σ c_k (λ^{k+3} − λ^{k+1}) − force = 0
        force, lam0 = _real("force", force), _real("lam0", lam0)
        n = len(self.EA_coeffs) + 3
        poly = np.zeros(n + 1)
        for k, c in enumerate(self.EA_coeffs):
            poly[k + 3] += 0.5 * c
            poly[k + 1] -= 0.5 * c
        poly[0] -= force
        roots = np.polynomial.polynomial.polyroots(poly)
        real = roots[np.abs(roots.imag) < 1e-9].real
        real = real[real > 0]
        if real.size == 0:
            raise ConfigError(f"no positive stretch carries an axial force of {force} N")
        return float(real[np.argmin(np.abs(real - lam0))])

    def describe(self) -> str:
        if self.kind == "linear":
            s = self.source
            return f"linear k(λ) = {s['a']:g} λ + {s['b']:g} N, D_a = {s['D_a'] * 1e3:g} mm"
        if self.kind == "constant":
            return f"constant EA = {self.EA_coeffs[0]:g} N, EI = {self.EI_coeffs[0]:g} N m²"
        return f"polynomial EA {self.EA_coeffs}, EI {self.EI_coeffs}"
