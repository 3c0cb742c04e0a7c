r"""Model forms: which parameters of the reduced model an identification fits, and their exact sensitivities.

A *form* maps a parameter vector θ to :class:`ancf.ActuatorParams` (a stiffness law EA(λ), EI(λ) and a
pressure area A(λ)) and gives ∂Q/∂θ, the derivative of the generalized force at a fixed configuration.
The fit (:mod:`validation.identification.identify`) needs the sensitivity of each equilibrium to θ,

    H δq = −(∂Q/∂θ) δθ   ⇒   ∂p/∂θ = −J_p H⁻¹ ∂Q/∂θ        (p a tip or marker position, J_p = ∂p/∂q),

and ∂Q/∂θ is exact and cheap because every stiffness term of the potential is *linear in its coefficient
vectors*: with EA(λ) = Σ ea_k λ^k, EI(λ) = Σ ei_k λ^k and A(λ) λ = Σ c_k λ^{k+1},

    Q(q; θ) = Q_axial(q; ea(θ)) + Q_bend(q; ei(θ)) + p Q_press(q; c(θ)) + (terms free of θ),

so ∂Q/∂θ_j is one assembly of the potential with the coefficient vectors ∂ea/∂θ_j, ∂ei/∂θ_j, p ∂c/∂θ_j and
every other load zero.  A pressure-dependent form scales the stretch laws by factors in p̂ = p / 100 kPa
(:mod:`ancf.stiffness`): at a state of pressure p the law's coefficient vectors are ea f_A(p), ei f_I(p), still
linear in what the assembly takes, so the column is the same single assembly with
∂(ea f_A)/∂θ_j = (∂ea/∂θ_j) f_A + ea ∂f_A/∂θ_j (likewise for EI) at that state's pressure — exact.
(The optional tendon routing distance d enters the tendon terms nonlinearly; its
column is a central difference of the assembly — not of a solve — with a relative step of 1e-6.)

Forms (``FORMS``; internal parameters in SI, λ the local stretch):

==================  ===================================================================  =========================
form                law                                                                  parameters θ
==================  ===================================================================  =========================
``paper``           EA = k(λ) = k₁ + a (λ − 1),  EI = (D_a²/8) λ k(λ),  A = π D_eff²/4  k₁ [N], a [N], D_a [m], D_eff [m]
``paper_area``      as ``paper``, A(λ) = A_eff (1 + β (λ − 1))                           + β [−]
``separate``        EA = EA₁ + s_A (λ − 1),  EI = EI₁ + s_I (λ − 1),  A = π D_eff²/4   EA₁ [N], s_A [N], EI₁ [N m²], s_I [N m²], D_eff [m]
``separate_area``   as ``separate``, A(λ) = A_eff (1 + β (λ − 1))                        + β [−]
``quadratic``       EA = EA₁ + s_A (λ − 1) + c_A (λ − 1)²,  EI as ``separate``            EA₁, s_A, c_A [N], EI₁, s_I, D_eff
``constant``        EA, EI constant,  A = π D_eff²/4                                     EA [N], EI [N m²], D_eff [m]
``pressure_ei``     as ``separate``, EI × (1 + pI1 p̂ + pI2 p̂²),  p̂ = p / 100 kPa             EA₁, s_A, EI₁, s_I, pI1 [−], pI2 [−], D_eff
``pressure_ei_ea``  as ``pressure_ei``, EA × (1 + pA1 p̂)                                   + pA1 [−]
``pressure_ei_shear`` as ``pressure_ei``, a series shear compliance s = s0 + s1 p̂            + s0, s1 [m/N]
==================  ===================================================================  =========================

The shear form (``pressure_ei_shear``; docs/identification.md §4b, :mod:`ancf.shear`) adds a rotation-free
tip compliance s(p) = s0 + s1 p̂ in series (s0, s1 ≥ 0, so s ≥ 0 at every p ≥ 0).  It does not enter Q: the
rod's equilibrium is unchanged and the tool point is x = p_end(q) + s P⊥ F, so with J_x = ∂x/∂q
(:meth:`ancf.Model.tool_jacobian`)

    ∂x/∂θ_j = −J_x H⁻¹ ∂Q/∂θ_j + (∂s/∂θ_j) P⊥ F,    ∂s/∂s0 = 1,  ∂s/∂s1 = p̂        (exact; linear in s0, s1).

Markers lie on the centreline and do not see s: it is identified by tip-force states against the markers and
the tendon bends at the same pressure.

k₁ = EA(1) rather than the paper's intercept b is fitted (b = k₁ − a is reported) so that the axial
stiffness at rest — the best-determined quantity — is one parameter, bounded positive.  Every form reports
the same derived values: ``a``, ``b`` (EA(λ) = a λ + b), ``EA``, ``EI`` (at λ = 1 and p = 0),
``D_a = √(8 EI/EA)`` at λ = 1 and ``D_eff``; ``beta`` for the area forms; ``EI_100kPa`` (and ``EA_100kPa``) for
the pressure forms.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from ancf import ActuatorParams, StiffnessLaw
from ancf.assembly import assemble
from ancf.stiffness import P_REF
from ancf.errors import InputError

__all__ = ["ModelForm", "FORMS", "get_form", "with_masses", "position_matrix", "REPORTED", "MEANINGS", "display_unit",
           "MASS_NAMES"]

#: Derived values every form reports, with units.
REPORTED = {"a": "N", "b": "N", "EA": "N", "EI": "N m^2", "D_a": "m", "D_eff": "m", "beta": "-", "d": "m",
            "EI_100kPa": "N m^2", "EA_100kPa": "N", "s_0kPa": "m/N", "s_100kPa": "m/N"}

#: What each parameter of a form (``ModelForm.names``) and each reported value means (tables of the report).
MEANINGS = {
    "k1": "axial stiffness at rest, k(1) = EA(1)", "a": "slope of the axial law, dEA/dλ",
    "b": "intercept of the axial law EA(λ) = a λ + b", "D_a": "bending diameter, EI(1) = D_a² EA(1)/8",
    "D_eff": "effective pressure diameter, A = π D_eff²/4", "beta": "slope of the pressure area, A(λ) = A_eff (1 + β (λ − 1))",
    "EA1": "axial stiffness at rest, EA(1)", "sA": "slope of the axial stiffness, dEA/dλ",
    "cA": "curvature of the axial stiffness, ½ d²EA/dλ²", "EI1": "bending stiffness at rest, EI(1)",
    "sI": "slope of the bending stiffness, dEI/dλ", "EA": "axial stiffness (at rest)", "EI": "bending stiffness (at rest)",
    "d": "tendon routing distance from the axis",
    "pI1": "pressure coefficient of EI: EI(λ, p) = EI(λ)(1 + pI1 p̂ + pI2 p̂²), p̂ = p/100 kPa",
    "pI2": "quadratic pressure coefficient of EI (see pI1)",
    "pA1": "pressure coefficient of EA: EA(λ, p) = EA(λ)(1 + pA1 p̂), p̂ = p/100 kPa",
    "EI_100kPa": "bending stiffness at rest at 100 kPa, EI(1, 100 kPa)",
    "EA_100kPa": "axial stiffness at rest at 100 kPa, EA(1, 100 kPa)",
    "s0": "series rotation-free (shear) tip compliance at 0 kPa: s(p) = s0 + s1 p̂, p̂ = p/100 kPa",
    "s1": "pressure coefficient of the shear tip compliance (see s0)",
    "s_0kPa": "shear tip compliance at 0 kPa, s(0)", "s_100kPa": "shear tip compliance at 100 kPa, s(100 kPa)",
    "line_mass": "line mass of the actuator (its distributed weight m' g)",
    "tip_mass": "tip mass (cap and tool; its weight acts at the tool point)",
}

#: The mass parameters :func:`with_masses` appends to a form: line mass [kg/m], tip mass [kg] (last, in this order).
MASS_NAMES = ("line_mass", "tip_mass")
#: their units and bounds (positive; the lower bounds are ``ActuatorParams``' smallest non-zero masses)
MASS_UNITS = ("kg/m", "kg")
MASS_LOWER = (1e-4, 1e-5)
MASS_UPPER = (100.0, 10.0)


#: How the tables show a parameter of each SI unit: unit → (scale, shown unit).
DISPLAY_UNITS = {"m": (1e3, "mm"), "N m^2": (1.0, "N m²"), "-": (1.0, "–"), "N": (1.0, "N"), "m/N": (1e3, "mm/N"),
                 "kg/m": (1e3, "g/m"), "kg": (1e3, "g")}


def display_unit(unit: str) -> tuple:
    """(scale, unit) in which the report and the command line show a value given in the SI ``unit``."""
    return DISPLAY_UNITS.get(unit, (1.0, unit))


@dataclass(frozen=True)
class ModelForm:
    """One parameterisation of the reduced model (see the module docstring).

    names / units : internal parameter names and units;  lower / upper : bounds for the fit (SI);
    laws(θ) → (ea, ei, c, d) coefficient vectors (c: A(λ)λ = Σ c_k λ^{k+1} [m²]; d: tendon distance or None);
    laws_jacobian(θ) → list over θ_j of (∂ea, ∂ei, ∂c) (the distance column is handled separately);
    pressure(θ) → (EA factor coefficients, EI factor coefficients) of the pressure-dependent forms
    (:meth:`ancf.StiffnessLaw.with_pressure`), None for the others; pressure_jacobian(θ) → list over θ_j of their
    derivatives.  shear(θ) → the shear compliance coefficients (s₀, s₁, …) [m/N] of
    ``ActuatorParams.shear_compliance`` (None: the form has none); shear_jacobian(θ) → list over θ_j of their
    derivatives (they do not enter Q: module docstring).
    """
    name: str
    names: tuple
    units: tuple
    lower: tuple
    upper: tuple
    laws: Callable
    laws_jacobian: Callable
    fits_distance: bool = False
    description: str = ""
    typical: tuple = ()
    pressure: Callable | None = None
    pressure_jacobian: Callable | None = None
    shear: Callable | None = None
    shear_jacobian: Callable | None = None
    fits_masses: bool = False

    @property
    def n(self) -> int:
        return len(self.names)

    def __reduce__(self):
        """Pickled by name (its laws are closures): a form of :func:`get_form` reaches a worker process as itself."""
        base = self.name[:-2] if self.fits_distance and self.name.endswith("+d") else self.name
        if base in _DEF:
            return get_form, (base, self.fits_distance, self.fits_masses)
        return super().__reduce__()

    def typical_scale(self, theta0) -> np.ndarray:
        """A fixed typical magnitude of each parameter (SI), set by the form's definition and the starting
        point ``theta0`` — never by a fitted value.  ``typical[j]`` is ``None`` (a positive magnitude: its
        starting value, at least its lower bound), the name of the magnitude it is a slope of (``a`` and
        ``s_A``, ``c_A`` take EA's size, ``s_I`` EI's: a unit change of stretch changes the stiffness by about
        its size) or a number (``beta``: 1, dimensionless).  The fit scales its Jacobian columns and steps by
        these, so a signed parameter whose value is near 0 is judged by the data, not by its value."""
        theta0 = np.asarray(theta0, float)
        spec = self.typical or (None,) * self.n
        own = np.maximum(np.abs(theta0), np.abs(np.asarray(self.lower, float)))
        out = np.empty(self.n)
        for j, t in enumerate(spec):
            if t is None:
                out[j] = own[j]
            elif isinstance(t, str):
                out[j] = own[self.names.index(t)]
            else:
                out[j] = float(t)
        if not np.all(np.isfinite(out) & (out > 0)):
            raise InputError(f"form {self.name}: no positive typical size of the parameters from the starting "
                             f"values {dict(zip(self.names, theta0))}")
        return out

    # ------------------------------------------------------------------ θ ↔ ActuatorParams
    def to_params(self, theta, base: ActuatorParams) -> ActuatorParams:
        """The actuator parameters for θ (everything the form does not fit is taken from ``base``)."""
        if self.fits_masses:
            theta = np.asarray(theta, float)
            inner = self._without_masses()
            return inner.to_params(theta[:inner.n], base).replace(line_mass=float(theta[-2]),
                                                                 tip_mass=float(theta[-1]))
        ea, ei, c, d = self.laws(np.asarray(theta, float))
        A1 = float(np.sum(c))                         # A(1) = Σ c_k
        if not (A1 > 0):
            raise InputError(f"form {self.name}: pressure area A(1) = {A1} m² must be positive")
        D_eff = math.sqrt(4 * A1 / math.pi)
        beta = float(c[1] / A1) if len(c) > 1 else 0.0
        if self.name.startswith("paper"):           # same coefficients, kept in the paper's readable form
            law = StiffnessLaw.linear(a=float(ea[1]), b=float(ea[0]), D_a=float(np.sqrt(8 * ei[2] / ea[1]))
                                      if ea[1] != 0 else float(np.sqrt(8 * ei[1] / ea[0])))
        elif self.name.startswith("constant"):
            law = StiffnessLaw.constant(EA=float(ea[0]), EI=float(ei[0]))
        else:
            law = StiffnessLaw.polynomial(EA=tuple(ea), EI=tuple(ei))
        if self.pressure is not None:
            pA, pI = self.pressure(np.asarray(theta, float))
            law = law.with_pressure(EA=tuple(float(c) for c in pA), EI=tuple(float(c) for c in pI))
        changes = dict(stiffness=law, D_eff=D_eff, pressure_area_slope=beta)
        if self.shear is not None:
            changes["shear_compliance"] = tuple(float(v) for v in self.shear(np.asarray(theta, float)))
        if d is not None:
            from ancf.params import Tendon
            changes["tendons"] = tuple(Tendon(distance=d, angle=t.angle) for t in base.tendons)
        return base.replace(**changes)

    def _without_masses(self) -> "ModelForm":
        """The form this one extends by the masses (:func:`with_masses`)."""
        base = self.name[:-2] if self.fits_distance and self.name.endswith("+d") else self.name
        return get_form(base, self.fits_distance)

    def derived(self, theta) -> dict:
        """The reported values (``REPORTED`` keys that apply) at θ."""
        ea, ei, c, d = self.laws(np.asarray(theta, float))
        EA1, EI1 = float(np.sum(ea)), float(np.sum(ei))
        dEA = float(sum(k * v for k, v in enumerate(ea)))      # dEA/dλ at λ = 1
        A1 = float(np.sum(c))
        out = {"a": dEA, "b": EA1 - dEA, "EA": EA1, "EI": EI1,
               "D_a": math.sqrt(8 * EI1 / EA1) if EA1 > 0 and EI1 > 0 else float("nan"),
               "D_eff": math.sqrt(4 * A1 / math.pi) if A1 > 0 else float("nan")}
        if len(c) > 1:
            out["beta"] = float(c[1] / A1)
        if d is not None:
            out["d"] = float(d)
        if self.pressure is not None:          # the stiffnesses at rest at 100 kPa (p̂ = 1)
            pA, pI = self.pressure(np.asarray(theta, float))
            out["EI_100kPa"] = EI1 * _factor(pI, 1.0)
            if len(pA):
                out["EA_100kPa"] = EA1 * _factor(pA, 1.0)
        if self.shear is not None:
            sc = self.shear(np.asarray(theta, float))
            out["s_0kPa"], out["s_100kPa"] = float(sc[0]), float(sum(sc))
        return out

    def shear_columns(self, theta, pressure: float) -> np.ndarray:
        """∂s/∂θ (n,) [m/N per unit θ_j] at ``pressure`` [Pa] (zeros for a form without shear)."""
        out = np.zeros(self.n)
        if self.shear is None:
            return out
        x = float(pressure) / P_REF
        for j, dc in enumerate(self.shear_jacobian(np.asarray(theta, float))):
            out[j] = sum(float(c) * x ** k for k, c in enumerate(dc))
        return out

    def derived_jacobian(self, theta) -> tuple[list, np.ndarray]:
        """(keys, ∂derived/∂θ (len(keys), n)) by central differences of the closed-form map (pure algebra)."""
        theta = np.asarray(theta, float)
        keys = list(self.derived(theta))
        J = np.zeros((len(keys), self.n))
        for j in range(self.n):
            h = 1e-6 * max(abs(theta[j]), 1e-8 if self.units[j] in ("m", "N m^2") else 1e-3)
            tp, tm = theta.copy(), theta.copy()
            tp[j] += h
            tm[j] -= h
            dp, dm = self.derived(tp), self.derived(tm)
            J[:, j] = [(dp[k] - dm[k]) / (2 * h) for k in keys]
        return keys, J

    # ------------------------------------------------------------------ sensitivities
    def dQ_dtheta(self, model, q: np.ndarray, pressure: float, theta) -> np.ndarray:
        """∂Q/∂θ (ndof, n) at full coordinates ``q`` (exact for the law coefficients; see the module docstring)."""
        theta = np.asarray(theta, float)
        out = np.zeros((model.ndof, self.n))
        zero3 = np.zeros(3)
        T0 = np.zeros(model.m)
        q = np.ascontiguousarray(q, dtype=float)
        cols = self.laws_jacobian(theta)
        if self.pressure is not None:
            # the law at this state's pressure: ea f_A(p̂), ei f_I(p̂); its θ-derivative by the product rule
            ea, ei, _, _ = self.laws(theta)
            pA, pI = self.pressure(theta)
            x = float(pressure) / P_REF
            fA, fI = _factor(pA, x), _factor(pI, x)
            pcols = self.pressure_jacobian(theta)
            cols = [(dea, dei, dc) if dea is None else
                    (_pad(_vec(dea) * fA, ea * (_factor(dpA, x) - 1.0)),
                     _pad(_vec(dei) * fI, ei * (_factor(dpI, x) - 1.0)), dc)
                    for (dea, dei, dc), (dpA, dpI) in zip(cols, pcols)]
        for j, (dea, dei, dc) in enumerate(cols):
            if dea is None:
                continue
            _, Q, *_ = assemble(q, model.n, model._N, model._wq, _vec(dea), _vec(dei), float(pressure) * _vec(dc),
                                zero3, model._E, model._d, model._co, model._so, T0, 0.0, zero3, False, 0)
            out[:, j] = Q
        if self.fits_masses:
            out[:, -2:] = mass_columns(model, q)
        return out


def mass_columns(model, q: np.ndarray) -> np.ndarray:
    """∂Q/∂(m', m_tip) (ndof, 2) [N/(kg/m), N/kg]: the gravity load of a unit line mass and of a unit tip mass (at
    the tool point) at full coordinates ``q`` — one assembly each with every stiffness, pressure and tendon term
    zero; exact, gravity's potential being linear in the masses.  Zero for a model without gravity."""
    out = np.zeros((model.ndof, 2))
    g = np.ascontiguousarray(model._g, dtype=float)
    if not np.any(g):
        return out
    q = np.ascontiguousarray(q, dtype=float)
    zero3, T0, z1 = np.zeros(3), np.zeros(model.m), np.zeros(1)
    for j, (mg, F) in enumerate(((g, zero3), (zero3, g))):
        _, Q, *_ = assemble(q, model.n, model._N, model._wq, z1, z1, z1, mg, model._E, model._d, model._co,
                            model._so, T0, model.params.tool_offset, F, False, 0)
        out[:, j] = Q
    return out


def _factor(coeffs, x: float) -> float:
    """1 + Σ_j coeffs[j−1] x^j (a pressure factor at p̂ = x; a derivative's coefficients give 1 + its value)."""
    return 1.0 + sum(float(c) * x ** (j + 1) for j, c in enumerate(coeffs))


def _pad(a, b) -> np.ndarray:
    """a + b for coefficient vectors of possibly different lengths."""
    a, b = np.atleast_1d(np.asarray(a, float)), np.atleast_1d(np.asarray(b, float))
    out = np.zeros(max(a.size, b.size))
    out[:a.size] += a
    out[:b.size] += b
    return out


def _vec(c) -> np.ndarray:
    a = np.ascontiguousarray(np.atleast_1d(np.asarray(c, float)))
    return a if a.size else np.zeros(1)


def distance_column(model, q, tensions, pressure, tip_force, rel: float = 1e-6) -> np.ndarray:
    """∂Q/∂d (ndof,) for a common tendon routing distance d: central difference of the assembly."""
    d0 = model._d.copy()
    h = rel * float(np.mean(d0))
    try:
        model._d = d0 + h
        Qp = model.residual(q, tensions, pressure, tip_force)
        model._d = d0 - h
        Qm = model.residual(q, tensions, pressure, tip_force)
    finally:
        model._d = d0
    return (Qp - Qm) / (2 * h)


def position_matrix(n_elements: int, length: float, s) -> np.ndarray:
    """S (3k, 6(n+1)) with r(s_i) = S[3i:3i+3] q: the centreline at undeformed arc lengths s (k,) [m]."""
    s = np.atleast_1d(np.asarray(s, float))
    if np.any(s < 0) or np.any(s > length * (1 + 1e-12)):
        raise InputError(f"arc lengths must lie in [0, {length}] m, got {s}")
    from ancf.kinematics import hermite
    l0 = length / n_elements
    S = np.zeros((3 * s.size, 6 * (n_elements + 1)))
    for i, si in enumerate(s):
        e = min(int(si / l0), n_elements - 1)
        xi = (si - e * l0) / l0
        N = hermite([xi], l0)[0][:, 0]                     # s1..s4
        for j in range(4):
            col = 6 * e + 3 * j
            S[3 * i:3 * i + 3, col:col + 3] += N[j] * np.eye(3)
    return S


# ---------------------------------------------------------------------------------------------- forms
def _paper_laws(th, area=False, dist=False):
    k1, a, Da = th[0], th[1], th[2]
    De = th[3]
    c8 = Da * Da / 8
    ea = np.array([k1 - a, a])                      # EA(λ) = (k1 − a) + a λ
    ei = np.array([0.0, c8 * (k1 - a), c8 * a])     # EI = c8 λ k(λ)
    A = math.pi * De * De / 4
    beta = th[4] if area else 0.0
    c = np.array([A * (1 - beta), A * beta]) if area else np.array([A])
    return ea, ei, c, (th[-1] if dist else None)


def _paper_jac(th, area=False):
    k1, a, Da, De = th[0], th[1], th[2], th[3]
    c8 = Da * Da / 8
    A = math.pi * De * De / 4
    dA = math.pi * De / 2
    beta = th[4] if area else 0.0
    z2, z3 = np.zeros(2), np.zeros(3)
    cols = [
        (np.array([1.0, 0.0]), np.array([0.0, c8, 0.0]), np.zeros(2 if area else 1)),                 # k1
        (np.array([-1.0, 1.0]), np.array([0.0, -c8, c8]), np.zeros(2 if area else 1)),                # a
        (z2, np.array([0.0, Da / 4 * (k1 - a), Da / 4 * a]), np.zeros(2 if area else 1)),             # D_a
        (z2, z3, np.array([dA * (1 - beta), dA * beta]) if area else np.array([dA])),                 # D_eff
    ]
    if area:
        cols.append((z2, z3, np.array([-A, A])))                                                      # β
    return cols


def _separate_laws(th, area=False, dist=False):
    EA1, sA, EI1, sI, De = th[:5]
    ea = np.array([EA1 - sA, sA])
    ei = np.array([EI1 - sI, sI])
    A = math.pi * De * De / 4
    beta = th[5] if area else 0.0
    c = np.array([A * (1 - beta), A * beta]) if area else np.array([A])
    return ea, ei, c, (th[-1] if dist else None)


def _separate_jac(th, area=False):
    De = th[4]
    A, dA = math.pi * De * De / 4, math.pi * De / 2
    beta = th[5] if area else 0.0
    z2 = np.zeros(2)
    zc = np.zeros(2 if area else 1)
    cols = [(np.array([1.0, 0.0]), z2, zc), (np.array([-1.0, 1.0]), z2, zc),
            (z2, np.array([1.0, 0.0]), zc), (z2, np.array([-1.0, 1.0]), zc),
            (z2, z2, np.array([dA * (1 - beta), dA * beta]) if area else np.array([dA]))]
    if area:
        cols.append((z2, z2, np.array([-A, A])))
    return cols


def _quadratic_laws(th, area=False, dist=False):
    EA1, sA, cA, EI1, sI, De = th[:6]
    ea = np.array([EA1 - sA + cA, sA - 2 * cA, cA])   # EA1 + sA (λ − 1) + cA (λ − 1)²
    ei = np.array([EI1 - sI, sI])
    return ea, ei, np.array([math.pi * De * De / 4]), (th[-1] if dist else None)


def _quadratic_jac(th, area=False):
    z2, z3 = np.zeros(2), np.zeros(3)
    zc = np.zeros(1)
    return [(np.array([1.0, 0.0, 0.0]), z2, zc), (np.array([-1.0, 1.0, 0.0]), z2, zc),
            (np.array([1.0, -2.0, 1.0]), z2, zc), (z3, np.array([1.0, 0.0]), zc), (z3, np.array([-1.0, 1.0]), zc),
            (z3, z2, np.array([math.pi * th[5] / 2]))]


def _constant_laws(th, area=False, dist=False):
    A = math.pi * th[2] ** 2 / 4
    return np.array([th[0]]), np.array([th[1]]), np.array([A]), (th[-1] if dist else None)


def _constant_jac(th, area=False):
    return [(np.array([1.0]), np.zeros(1), np.zeros(1)), (np.zeros(1), np.array([1.0]), np.zeros(1)),
            (np.zeros(1), np.zeros(1), np.array([math.pi * th[2] / 2]))]


def _pressure_laws(th, area=False, dist=False):
    """``pressure_ei`` (θ = EA₁, s_A, EI₁, s_I, p_I1, p_I2, D_eff) and ``pressure_ei_ea`` (…, p_I2, p_A1, D_eff):
    the ``separate`` stretch laws; the pressure factors are :func:`_pressure_factors`."""
    EA1, sA, EI1, sI = th[:4]
    De = th[7] if area else th[6]
    return (np.array([EA1 - sA, sA]), np.array([EI1 - sI, sI]), np.array([math.pi * De * De / 4]),
            (th[-1] if dist else None))


def _pressure_jac(th, area=False):
    De = th[7] if area else th[6]
    z2, zc = np.zeros(2), np.zeros(1)
    cols = [(np.array([1.0, 0.0]), z2, zc), (np.array([-1.0, 1.0]), z2, zc),
            (z2, np.array([1.0, 0.0]), zc), (z2, np.array([-1.0, 1.0]), zc),
            (z2, z2, zc), (z2, z2, zc)]
    if area:
        cols.append((z2, z2, zc))
    cols.append((z2, z2, np.array([math.pi * De / 2])))
    return cols


def _shear_form_jac(th, area=False):
    """``pressure_ei_shear``: the ``pressure_ei`` columns, then zero columns for s0, s1 (they do not enter Q)."""
    z2, zc = np.zeros(2), np.zeros(1)
    return _pressure_jac(th) + [(z2, z2, zc), (z2, z2, zc)]


def _pressure_factors(th, with_ea=False, dist=False):
    """(EA factor coefficients, EI factor coefficients) of the pressure forms (``with_ea``: ``pressure_ei_ea``)."""
    return ((th[6],) if with_ea else ()), (th[4], th[5])


def _pressure_factors_jac(th, with_ea=False, dist=False):
    n = len(th)
    out = []
    for j in range(n):
        dA = (1.0 if j == 6 else 0.0,) if with_ea else ()
        out.append((dA, (1.0 if j == 4 else 0.0, 1.0 if j == 5 else 0.0)))
    return out


_BIG = 1e7
_DEF = {
    "paper": (("k1", "a", "D_a", "D_eff"), ("N", "N", "m", "m"), (1e-3, -_BIG, 1e-4, 1e-4), (_BIG, _BIG, 1.0, 1.0),
              _paper_laws, _paper_jac, False,
              "the paper's law: EA = k(λ), EI = D_a² λ k(λ)/8, constant pressure area"),
    "paper_area": (("k1", "a", "D_a", "D_eff", "beta"), ("N", "N", "m", "m", "-"),
                   (1e-3, -_BIG, 1e-4, 1e-4, -1.9), (_BIG, _BIG, 1.0, 1.0, 1.9), _paper_laws, _paper_jac, True,
                   "the paper's law with a stretch-dependent pressure area A(λ) = A_eff (1 + β (λ − 1))"),
    "separate": (("EA1", "sA", "EI1", "sI", "D_eff"), ("N", "N", "N m^2", "N m^2", "m"),
                 (1e-3, -_BIG, 1e-9, -_BIG, 1e-4), (_BIG, _BIG, _BIG, _BIG, 1.0), _separate_laws, _separate_jac,
                 False, "separate linear laws EA(λ), EI(λ), constant pressure area"),
    "separate_area": (("EA1", "sA", "EI1", "sI", "D_eff", "beta"), ("N", "N", "N m^2", "N m^2", "m", "-"),
                      (1e-3, -_BIG, 1e-9, -_BIG, 1e-4, -1.9), (_BIG, _BIG, _BIG, _BIG, 1.0, 1.9), _separate_laws,
                      _separate_jac, True, "separate linear laws EA(λ), EI(λ) and a stretch-dependent pressure area"),
    "quadratic": (("EA1", "sA", "cA", "EI1", "sI", "D_eff"), ("N", "N", "N", "N m^2", "N m^2", "m"),
                  (1e-3, -_BIG, -_BIG, 1e-9, -_BIG, 1e-4), (_BIG, _BIG, _BIG, _BIG, _BIG, 1.0), _quadratic_laws,
                  _quadratic_jac, False, "separate laws, EA(λ) quadratic in the stretch, EI(λ) linear, constant "
                                         "pressure area"),
    "constant": (("EA", "EI", "D_eff"), ("N", "N m^2", "m"), (1e-3, 1e-9, 1e-4), (_BIG, _BIG, 1.0), _constant_laws,
                 _constant_jac, False, "constant EA and EI, constant pressure area"),
    # the pressure forms: the 'area' flag of the shared signature selects the EA factor (pressure_ei_ea)
    "pressure_ei": (("EA1", "sA", "EI1", "sI", "pI1", "pI2", "D_eff"), ("N", "N", "N m^2", "N m^2", "-", "-", "m"),
                    (1e-3, -_BIG, 1e-9, -_BIG, -10.0, -10.0, 1e-4), (_BIG, _BIG, _BIG, _BIG, 10.0, 10.0, 1.0),
                    _pressure_laws, _pressure_jac, False,
                    "separate linear laws; EI × (1 + pI1 p̂ + pI2 p̂²), p̂ = p/100 kPa; constant pressure area"),
    "pressure_ei_ea": (("EA1", "sA", "EI1", "sI", "pI1", "pI2", "pA1", "D_eff"),
                       ("N", "N", "N m^2", "N m^2", "-", "-", "-", "m"),
                       (1e-3, -_BIG, 1e-9, -_BIG, -10.0, -10.0, -10.0, 1e-4),
                       (_BIG, _BIG, _BIG, _BIG, 10.0, 10.0, 10.0, 1.0), _pressure_laws, _pressure_jac, True,
                       "separate linear laws; EI × (1 + pI1 p̂ + pI2 p̂²), EA × (1 + pA1 p̂), p̂ = p/100 kPa; "
                       "constant pressure area"),
    "pressure_ei_shear": (("EA1", "sA", "EI1", "sI", "pI1", "pI2", "D_eff", "s0", "s1"),
                          ("N", "N", "N m^2", "N m^2", "-", "-", "m", "m/N", "m/N"),
                          (1e-3, -_BIG, 1e-9, -_BIG, -10.0, -10.0, 1e-4, 0.0, 0.0),
                          (_BIG, _BIG, _BIG, _BIG, 10.0, 10.0, 1.0, 1.0, 1.0), _pressure_laws, _shear_form_jac,
                          False, "separate linear laws; EI × (1 + pI1 p̂ + pI2 p̂²), p̂ = p/100 kPa; constant pressure "
                                 "area; series shear tip compliance s = s0 + s1 p̂"),
}
_PRESSURE_FORMS = {"pressure_ei", "pressure_ei_ea", "pressure_ei_shear"}
#: forms with a series shear compliance: index of s0 in θ (s0, s1 follow D_eff)
_SHEAR_FORMS = {"pressure_ei_shear": 7}


def _shear_coeffs(th, first: int):
    """(s0, s1) [m/N] of a shear form."""
    return (float(th[first]), float(th[first + 1]))


def _shear_coeffs_jac(th, first: int, n: int):
    return [(1.0 if j == first else 0.0, 1.0 if j == first + 1 else 0.0) for j in range(n)]

#: Typical size of each signed parameter (:meth:`ModelForm.typical_scale`): the magnitude parameter it is a
#: slope of, or a number; every other parameter's typical size is its own starting value.
_TYPICAL = {"a": "k1", "sA": "EA1", "cA": "EA1", "sI": "EI1", "beta": 1.0, "pI1": 1.0, "pI2": 1.0, "pA1": 1.0,
            "s0": 1e-3, "s1": 1e-3}


def get_form(name: str, fit_distance: bool = False, fit_masses: bool = False) -> ModelForm:
    """The form ``name`` (one of :data:`FORMS`); ``fit_distance`` adds the tendon routing distance d [m],
    ``fit_masses`` the line and tip mass (:func:`with_masses`)."""
    if fit_masses:
        return with_masses(get_form(name, fit_distance))
    if name not in _DEF:
        raise InputError(f"unknown model form {name!r}; choose from {sorted(_DEF)}")
    names, units, lo, hi, laws, jac, area, desc = _DEF[name]
    typical = tuple(_TYPICAL.get(nm) for nm in names)
    if fit_distance:
        names, units, lo, hi = names + ("d",), units + ("m",), lo + (1e-4,), hi + (0.49,)
        typical = typical + (None,)
    pressure = pressure_jac = None
    if name in _PRESSURE_FORMS:
        pressure = lambda th, area=area: _pressure_factors(th, area)                    # noqa: E731
        pressure_jac = lambda th, area=area: _pressure_factors_jac(th, area)            # noqa: E731
    shear = shear_jac = None
    if name in _SHEAR_FORMS:
        first, n_all = _SHEAR_FORMS[name], len(names)
        shear = lambda th, k=first: _shear_coeffs(th, k)                                # noqa: E731
        shear_jac = lambda th, k=first, n=n_all: _shear_coeffs_jac(th, k, n)            # noqa: E731
    return ModelForm(name + ("+d" if fit_distance else ""), names, units, lo, hi,
                     lambda th, laws=laws, area=area, fd=fit_distance: laws(th, area, fd),
                     lambda th, jac=jac, area=area, fd=fit_distance: jac(th, area) + ([(None, None, None)] if fd else []),
                     fit_distance, desc + (", tendon distance fitted" if fit_distance else ""), typical,
                     pressure, pressure_jac, shear, shear_jac)


FORMS = tuple(_DEF)


def with_masses(form: ModelForm) -> ModelForm:
    """``form`` with the line mass m' [kg/m] and the tip mass m_tip [kg] appended to its parameters
    (:data:`MASS_NAMES`, bounded positive): a rig-data fit under gravity.  Its name is the form's (the masses do not
    change the law); the laws, pressure and shear maps are the form's on θ without the masses, and ∂Q/∂θ of the
    masses is the gravity load of a unit mass (:func:`mass_columns`)."""
    if form.fits_masses:
        return form
    n0 = form.n

    def pad(cols, zero):
        return list(cols) + [zero, zero]

    pressure = pressure_jac = shear = shear_jac = None
    if form.pressure is not None:
        pressure = lambda th: form.pressure(th[:n0])                                     # noqa: E731

        def pressure_jac(th):
            cols = form.pressure_jacobian(th[:n0])
            return pad(cols, (tuple(0.0 for _ in cols[0][0]), tuple(0.0 for _ in cols[0][1])))
    if form.shear is not None:
        shear = lambda th: form.shear(th[:n0])                                           # noqa: E731
        shear_jac = lambda th: pad(form.shear_jacobian(th[:n0]), (0.0, 0.0))              # noqa: E731
    return ModelForm(form.name, form.names + MASS_NAMES, form.units + MASS_UNITS, form.lower + MASS_LOWER,
                     form.upper + MASS_UPPER, lambda th: form.laws(np.asarray(th, float)[:n0]),
                     lambda th: pad(form.laws_jacobian(np.asarray(th, float)[:n0]), (None, None, None)),
                     form.fits_distance, form.description + ", line and tip mass fitted",
                     (form.typical or (None,) * n0) + (None, None), pressure, pressure_jac, shear, shear_jac,
                     fits_masses=True)
