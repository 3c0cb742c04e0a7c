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

Pressure-dependent stiffness.  A pressurised bellows can be stiffer in bending than its stretch alone
explains (measured on the FEM of the default bellows: docs/identification.md).  Either stiffness may carry a factor
polynomial in the normalised pressure p̂ = p / P_REF, P_REF = 100 kPa:

    EI(λ, p) = EI(λ) · f_I(p̂),   f_I = 1 + Σ_{j≥1} c_I,j p̂^j,      EA(λ, p) = EA(λ) · f_A(p̂)  (likewise),

with dimensionless coefficients ``EI_pressure`` = (c_I,1, c_I,2, …) and ``EA_pressure`` (empty: factor 1,
today's law).  The pressure is a load input of every solve, constant within it, so at a given p the law is
the stretch polynomial with coefficients ``ei · f_I(p̂)`` (:meth:`StiffnessLaw.coefficients`): the energy,
its gradient and Hessian in q are those of a stretch-only law, and the kernels are unchanged.  What changes
is every derivative with respect to p: ∂Q/∂p gains ∂Q_axial/∂p + ∂Q_bend/∂p, the same assemblies with the
coefficient vectors ``ea · f_A'(p)``, ``ei · f_I'(p)`` (:meth:`StiffnessLaw.coefficient_derivatives`,
:meth:`ancf.Model.dQ_dp`).  A factor must stay positive over the pressures used (checked over the
actuator's pressure range by :class:`ancf.ActuatorParams`, and at the pressure of every solve); then EA and
EI vanish at the same stretches at every pressure and :attr:`StiffnessLaw.valid_stretch_range` holds for
all of them.
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


#: Reference pressure of the pressure factor, p̂ = p / P_REF [Pa].
P_REF = 100e3
#: Most coefficients of a pressure factor (powers p̂ … p̂^4).
MAX_PRESSURE_COEFFS = 4


def _factor(coeffs: tuple, p: float) -> float:
    """f(p̂) = 1 + Σ_j c_j p̂^j at the pressure p [Pa]."""
    x = p / P_REF
    f, xp = 1.0, 1.0
    for c in coeffs:
        xp *= x
        f += c * xp
    return f


def _factor_derivative(coeffs: tuple, p: float) -> float:
    """df/dp [1/Pa] of f(p̂) = 1 + Σ_j c_j p̂^j."""
    x = p / P_REF
    d, xp = 0.0, 1.0
    for j, c in enumerate(coeffs, start=1):
        d += j * c * xp
        xp *= x
    return d / P_REF


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
    EA_pressure, EI_pressure : tuple of float
        Dimensionless coefficients (c_1, c_2, …) of the pressure factors f(p̂) = 1 + Σ_j c_j p̂^j,
        p̂ = p / 100 kPa, multiplying EA(λ) and EI(λ) (module docstring); empty (the default): no pressure
        dependence.
    """

    model_config = ConfigDict(frozen=True, extra="forbid")

    kind: Literal["linear", "constant", "polynomial"]
    EA_coeffs: tuple[float, ...]
    EI_coeffs: tuple[float, ...]
    source: dict[str, float] = {}
    EA_pressure: tuple[float, ...] = ()
    EI_pressure: tuple[float, ...] = ()

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

    @field_validator("EA_pressure", "EI_pressure", mode="before")
    @classmethod
    def _pressure_numbers(cls, v):
        if isinstance(v, (str, bytes)) or not hasattr(v, "__len__"):
            raise ValueError(f"expected a list of numbers (coefficients of p/100 kPa), got {v!r}")
        v = tuple(_real("pressure coefficient", c) for c in v)
        if len(v) > MAX_PRESSURE_COEFFS:
            raise ValueError(f"a pressure factor takes at most {MAX_PRESSURE_COEFFS} coefficients "
                             f"(powers of p/100 kPa from 1), got {len(v)}")
        while v and v[-1] == 0.0:          # trailing zeros change nothing: one representation per law
            v = v[:-1]
        return v

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

    def with_pressure(self, EA=(), EI=()) -> "StiffnessLaw":
        """The same law with the pressure factors f_A = 1 + Σ EA[j−1] p̂^j on EA and f_I = 1 + Σ EI[j−1] p̂^j
        on EI, p̂ = p / 100 kPa (dimensionless coefficients, lowest power first; module docstring)."""
        return StiffnessLaw(kind=self.kind, EA_coeffs=self.EA_coeffs, EI_coeffs=self.EI_coeffs,
                            source=dict(self.source), EA_pressure=tuple(EA), EI_pressure=tuple(EI))

    # ---------------------------------------------------------------- pressure dependence
    @property
    def pressure_dependent(self) -> bool:
        """True when EA or EI carries a pressure factor."""
        return bool(self.EA_pressure or self.EI_pressure)

    def pressure_factors(self, pressure: float) -> tuple[float, float]:
        """(f_A, f_I) [−] at ``pressure`` [Pa]: EA(λ, p) = EA(λ) f_A, EI(λ, p) = EI(λ) f_I."""
        p = _real("pressure [Pa]", pressure)
        return _factor(self.EA_pressure, p), _factor(self.EI_pressure, p)

    def coefficients(self, pressure: float) -> tuple[np.ndarray, np.ndarray]:
        """Stretch-polynomial coefficients (ea, ei) of EA(λ, p) [N] and EI(λ, p) [N m²] at ``pressure`` [Pa]
        (the arrays :attr:`ea`, :attr:`ei` themselves when the law does not depend on pressure)."""
        if not self.pressure_dependent:
            return self.ea, self.ei
        fA, fI = self.pressure_factors(pressure)
        return self.ea * fA, self.ei * fI

    def coefficient_derivatives(self, pressure: float) -> tuple[np.ndarray, np.ndarray]:
        """∂(ea, ei)/∂p at ``pressure`` [Pa]: coefficient vectors [N/Pa], [N m²/Pa] (zeros (1,) for a factor
        that does not depend on pressure)."""
        p = _real("pressure [Pa]", pressure)
        dA = _factor_derivative(self.EA_pressure, p)
        dI = _factor_derivative(self.EI_pressure, p)
        return (self.ea * dA if self.EA_pressure else np.zeros(1),
                self.ei * dI if self.EI_pressure else np.zeros(1))

    def pressure_factor_minimum(self, p_lo: float, p_hi: float) -> tuple[float, float, str]:
        """(smallest factor, the pressure [Pa] where it is reached, "EA" or "EI") over [p_lo, p_hi] [Pa]
        (exact: the factors are polynomials; 1.0 at p_lo for a law without pressure factors)."""
        p_lo, p_hi = _real("p_lo [Pa]", p_lo), _real("p_hi [Pa]", p_hi)
        best = (math.inf, p_lo, "EA")
        for which, coeffs in (("EA", self.EA_pressure), ("EI", self.EI_pressure)):
            cand = [p_lo, p_hi]
            if len(coeffs) > 1:          # interior extrema: roots of f'(p̂)
                d = np.array([j * c for j, c in enumerate(coeffs, start=1)])
                for r in np.polynomial.polynomial.polyroots(d) if np.any(d[1:]) else []:
                    if abs(r.imag) <= 1e-12 * max(1.0, abs(r.real)):
                        pr = float(r.real) * P_REF
                        if p_lo < pr < p_hi:
                            cand.append(pr)
            for pr in cand:
                f = _factor(coeffs, pr)
                if f < best[0]:
                    best = (f, pr, which)
        return best

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

    def EA(self, lam, pressure: float = 0.0):
        """Axial stiffness EA(λ, p) [N] (``pressure`` [Pa]; only a pressure-dependent law uses it)."""
        v = np.polynomial.polynomial.polyval(_stretch(lam), self.ea)
        return v * self.pressure_factors(pressure)[0] if self.EA_pressure else v

    def EI(self, lam, pressure: float = 0.0):
        """Bending stiffness EI(λ, p) [N m²] (``pressure`` [Pa]; only a pressure-dependent law uses it)."""
        v = np.polynomial.polynomial.polyval(_stretch(lam), self.ei)
        return v * self.pressure_factors(pressure)[1] if self.EI_pressure else v

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
            out = f"linear k(λ) = {s['a']:g} λ + {s['b']:g} N, D_a = {s['D_a'] * 1e3:g} mm"
        elif self.kind == "constant":
            out = f"constant EA = {self.EA_coeffs[0]:g} N, EI = {self.EI_coeffs[0]:g} N m²"
        else:
            out = f"polynomial EA {self.EA_coeffs}, EI {self.EI_coeffs}"
        for which, coeffs in (("EA", self.EA_pressure), ("EI", self.EI_pressure)):
            if coeffs:
                terms = " ".join(f"{'+' if c >= 0 else '−'} {abs(c):g} p̂{'' if j == 1 else f'^{j}'}"
                                 for j, c in enumerate(coeffs, start=1))
                out += f"; {which} × (1 {terms})"
        if self.pressure_dependent:
            out += ", p̂ = p/100 kPa"
        return out
