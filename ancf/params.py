"""Actuator parameters: one immutable, validated object, loadable from TOML with explicit units.

Everything inside is SI (m, kg, N, Pa, rad).  TOML files state units in the key names
(``length_mm = 160``, ``pressure_max_kPa = 120``, ``angle_deg = 120``); a dimensioned key without a unit,
an unknown unit or an unknown key is rejected with a message that names the key and suggests the
accepted spellings.  See ``ancf/presets/paper.toml`` for a complete, commented example.
"""

from __future__ import annotations

import difflib
import math
import pathlib
from typing import Any, Optional

import numpy as np
from pydantic import (
    BaseModel,
    ConfigDict,
    ValidationError,
    field_validator,
    model_validator,
)

try:  # Python >= 3.11
    import tomllib
except ModuleNotFoundError:  # pragma: no cover
    import tomli as tomllib

from .errors import ConfigError
from .stiffness import StiffnessLaw

# ----------------------------------------------------------------------------------------------- units
UNITS: dict[str, dict[str, float]] = {
    "length": {"m": 1.0, "cm": 1e-2, "mm": 1e-3},
    "angle": {"rad": 1.0, "deg": math.pi / 180},
    "mass": {"kg": 1.0, "g": 1e-3},
    "line_mass": {"kg_per_m": 1.0, "g_per_m": 1e-3, "g_per_mm": 1.0},
    "force": {"N": 1.0},
    "pressure": {"Pa": 1.0, "kPa": 1e3, "bar": 1e5, "MPa": 1e6},
    "acceleration": {"m_per_s2": 1.0},
    "bending_stiffness": {"N_m2": 1.0, "N_mm2": 1e-6},
    "modulus": {"Pa": 1.0, "kPa": 1e3, "MPa": 1e6},
    "density": {"kg_per_m3": 1.0, "g_per_cm3": 1e3},
    "dimensionless": {"": 1.0},
    "stiffness": {"N_per_m": 1.0, "N_per_mm": 1e3},
    "rate": {"per_s": 1.0},
    "time": {"s": 1.0, "ms": 1e-3},
    "force_time": {"N_s": 1.0},
    # coefficients of powers of the normalised pressure p̂ = p/100 kPa (ancf.stiffness, pressure factors);
    # only this spelling: a coefficient of (p/1 kPa)^j would need a different factor per power
    "pressure_polynomial": {"per_100kPa": 1.0},
    # coefficients s_j [m/N] of s(p) = Σ s_j p̂^j, p̂ = p/100 kPa (the series shear compliance, ancf.shear)
    "compliance_polynomial": {"m_per_N_per_100kPa": 1.0, "mm_per_N_per_100kPa": 1e-3},
}

# field name -> dimension, for the top level of an actuator TOML file
TOP_FIELDS = {
    "name": None, "description": None,
    "length": "length", "n_elements": "dimensionless", "quadrature_points": "dimensionless",
    "D_eff": "length", "line_mass": "line_mass", "tip_mass": "mass", "tool_offset": "length",
    "base_axis": "dimensionless", "reference_direction": "dimensionless", "gravity": "acceleration",
    "tension_min": "force", "tension_max": "force", "pressure_min": "pressure", "pressure_max": "pressure",
    "free_base_stretch": None, "pressure_area_slope": "dimensionless",
    "tendon_stiffness": "stiffness", "shear_compliance_coeffs": "compliance_polynomial",
    "rayleigh_alpha": "rate", "rayleigh_beta": "time", "axial_damping": "force_time",
    "tendon_friction": "dimensionless",
}
STIFFNESS_FIELDS = {"law": None, "a": "force", "b": "force", "D_a": "length", "EA": "force",
                    "EI": "bending_stiffness", "EA_coeffs": "force", "EI_coeffs": "bending_stiffness",
                    "EA_pressure_coeffs": "pressure_polynomial", "EI_pressure_coeffs": "pressure_polynomial"}
TENDON_FIELDS = {"distance": "length", "angle": "angle"}

# Plausible magnitudes (SI) for a soft bellows actuator: (low, high, zero allowed).  A value outside is
# almost always a unit mistake (160 written under length_m, 0.16 under length_mm) and is rejected with the
# range in the unit the value was given in.  Fields not listed are checked by their own validators.  The
# table is docs/data-formats.md's "Plausible ranges" (tests/test_reliability/test_actuator_file_checks.py
# checks the two agree).  For a list (coefficients), the range applies to each entry.
PLAUSIBLE: dict[str, tuple[float, float, bool]] = {
    "length": (1e-3, 10.0, False),             # 1 mm … 10 m
    "D_eff": (1e-3, 1.0, False),               # 1 mm … 1 m
    "D_a": (1e-3, 1.0, False),
    "distance": (1e-4, 0.5, False),            # 0.1 mm … 0.5 m
    "tool_offset": (1e-4, 1.0, True),          # 0, or 0.1 mm … 1 m
    "tip_mass": (1e-5, 10.0, True),            # 0, or 0.01 g … 10 kg
    "line_mass": (1e-4, 100.0, True),          # 0, or 0.1 g/m … 100 kg/m
    "tension_min": (0.0, 1e3, True),
    "tension_max": (1e-3, 1e3, False),         # 1 mN … 1 kN
    "pressure_min": (0.0, 10e6, True),
    "pressure_max": (1e3, 10e6, True),         # 0, or 1 kPa … 10 MPa
    "angle": (-2 * math.pi, 2 * math.pi, True),
    "EA": (1e-3, 1e9, False),                  # N
    "EI": (1e-9, 1e6, False),                  # N m²
    "a": (-1e9, 1e9, True),
    "b": (-1e9, 1e9, True),
    "rayleigh_alpha": (1e-6, 1e4, True),       # 0, or 1e-6 … 1e4 1/s
    "rayleigh_beta": (1e-9, 1.0, True),        # 0, or 1 ns … 1 s
    "axial_damping": (1e-6, 1e6, True),        # 0, or 1e-6 … 1e6 N s
    "shear_compliance_coeffs": (-0.1, 0.1, True),   # each s_j within ±0.1 m/N = ±100 mm/N (a bellows: ~1–10 mm/N)
    "tendon_stiffness": (1.0, 1e10, False),         # N/m (a rope with its load cell: ~1e3 … 1e5 N/m)
    "EA_pressure_coeffs": (-100.0, 100.0, True),    # per (p/100 kPa)^j: each c_j within ±100
    "EI_pressure_coeffs": (-100.0, 100.0, True),
}
INT_FIELDS = ("n_elements", "quadrature_points")
#: the number of elements an actuator may have (``n_elements``; the CLI's ``--n-elements``, ``--n-ref`` share it)
N_ELEMENTS_MIN, N_ELEMENTS_MAX = 1, 200
#: Gauss points per element
QUADRATURE_MIN, QUADRATURE_MAX = 4, 20
#: tendons an actuator may have
TENDONS_MIN, TENDONS_MAX = 3, 16
#: the largest tendon friction coefficient μ an actuator may state (``tendon_friction``)
TENDON_FRICTION_MAX = 1.0
#: the smallest angle between two tendons' directions about the axis [rad] (1°): closer, they are one tendon
TENDON_SEPARATION_MIN = math.pi / 180
#: the fields whose value is a list, with its allowed lengths (checked before anything is converted)
LIST_FIELDS = {"base_axis": (3, 3), "reference_direction": (3, 3), "gravity": (3, 3),
               "shear_compliance_coeffs": (1, 6), "EA_coeffs": (1, 8), "EI_coeffs": (1, 8),
               "EA_pressure_coeffs": (1, 4), "EI_pressure_coeffs": (1, 4)}
BOOL_FIELDS = ("free_base_stretch",)
TEXT_FIELDS = ("name", "description", "law")


def plausible_ranges() -> list[tuple[str, str, str]]:
    """The checks on an actuator file's values as rows (key, SI unit, accepted range): :data:`PLAUSIBLE`
    and the counts.  docs/data-formats.md shows this table (a test compares the two)."""
    dims = {**TOP_FIELDS, **STIFFNESS_FIELDS, **TENDON_FIELDS}
    rows = []
    for f, (lo, hi, zero_ok) in PLAUSIBLE.items():
        unit = next(u for u, fac in UNITS[dims[f]].items() if fac == 1.0)
        each = "each entry " if f in LIST_FIELDS else ""
        rows.append((f, unit or "—",
                     f"{each}{lo:g} … {hi:g}" + (" or 0" if zero_ok and lo > 0 else "")))
    rows += [("n_elements", "—", f"{N_ELEMENTS_MIN} … {N_ELEMENTS_MAX}"),
             ("quadrature_points", "—", f"{QUADRATURE_MIN} … {QUADRATURE_MAX}"),
             ("[[tendons]] tables", "—", f"{TENDONS_MIN} … {TENDONS_MAX}, angles at least "
                                         f"{math.degrees(TENDON_SEPARATION_MIN):g}° apart")]
    rows += [(f, "—", f"a list of {lo} … {hi} numbers" if lo != hi else f"a list of {lo} numbers")
             for f, (lo, hi) in LIST_FIELDS.items()]
    return rows


def _implausible(field: str, si_value: float) -> str | None:
    """None if ``si_value`` is plausible for ``field`` (see PLAUSIBLE), else the SI range as text."""
    rng = PLAUSIBLE.get(field)
    if rng is None:
        return None
    lo, hi, zero_ok = rng
    if (zero_ok and si_value == 0.0) or lo <= si_value <= hi:
        return None
    return f"{lo:g} … {hi:g}" + (" (or 0)" if zero_ok and lo > 0 else "")


def _parse_table(table, fields: dict[str, str | None], where: str) -> dict[str, Any]:
    """Map ``{key_with_unit: value}`` to ``{field: SI value}``; reject unknown keys, missing units, values
    of the wrong type and implausible magnitudes for the stated unit."""
    if not isinstance(table, dict):
        raise ConfigError(f"{where}: expected a table of keys, got {table!r}")
    out: dict[str, Any] = {}
    spellings = {}
    for f, dim in fields.items():
        if dim is None or dim == "dimensionless":
            spellings[f] = (f, 1.0, "")
        else:
            for u, fac in UNITS[dim].items():
                spellings[f"{f}_{u}"] = (f, fac, u)
    for key, value in table.items():
        if key in spellings:
            f, fac, unit = spellings[key]
            if f in out:
                raise ConfigError(f"{where}: '{f}' given twice (e.g. in two units)")
            out[f] = _typed_value(value, f, fac, unit, fields[f], f"{where}.{key}")
            continue
        if key in fields and fields[key] not in (None, "dimensionless"):
            units = ", ".join(f"{key}_{u}" for u in UNITS[fields[key]])
            raise ConfigError(f"{where}: '{key}' needs an explicit unit; write one of: {units}")
        close = difflib.get_close_matches(key, list(spellings), n=3, cutoff=0.5)
        hint = f"; did you mean {', '.join(close)}?" if close else ""
        raise ConfigError(f"{where}: unknown key '{key}'{hint}")
    return out


def _typed_value(value, field: str, fac: float, unit: str, dim: str | None, where: str):
    """Check the TOML type of one value and convert it to SI (numbers, lists of numbers)."""
    if field in TEXT_FIELDS:
        if not isinstance(value, str):
            raise ConfigError(f"{where}: expected text in quotes, got {value!r}")
        return value
    if field in BOOL_FIELDS:
        if not isinstance(value, bool):
            raise ConfigError(f"{where}: expected true or false, got {value!r}")
        return value
    if field in INT_FIELDS:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(f"{where}: expected a whole number (no quotes, no decimal point), got {_short(value)}")
        lo, hi = (N_ELEMENTS_MIN, N_ELEMENTS_MAX) if field == "n_elements" else (QUADRATURE_MIN, QUADRATURE_MAX)
        if not lo <= value <= hi:
            raise ConfigError(f"{where} = {_short(value)} is outside the plausible range {lo} … {hi}")
        return value
    if dim is None:
        return value
    if field in LIST_FIELDS:
        lo, hi = LIST_FIELDS[field]
        size = f"{lo}" if lo == hi else f"{lo} to {hi}"
        if not isinstance(value, list):
            raise ConfigError(f"{where}: expected a list of {size} numbers in brackets, got {_short(value)}")
        if not lo <= len(value) <= hi:
            raise ConfigError(f"{where}: expected a list of {size} numbers, got {len(value)}")
        return [_number(v, fac, field, unit, f"{where}[{i}]") for i, v in enumerate(value)]
    if isinstance(value, list):
        raise ConfigError(f"{where}: expected one number, got a list {_short(value)}")
    return _number(value, fac, field, unit, where)


def _located(message: str, where: str) -> str:
    """``message`` prefixed with ``where`` (the file and table) unless it already starts with it."""
    return message if message.startswith(where) else f"{where}: {message}"


def _short(value) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _number(value, fac: float, field: str, unit: str, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        what = "quoted text" if isinstance(value, str) else type(value).__name__
        raise ConfigError(f"{where}: expected a number without quotes, got {what} {_short(value)} (a value of the "
                          "wrong type is never converted)")
    try:
        v = float(value) * fac
    except OverflowError:                                   # an integer beyond any float
        v = math.inf
    if not math.isfinite(v):
        raise ConfigError(f"{where}: value must be a finite number, got {_short(value)}")
    rng = _implausible(field, v)
    if rng is not None:
        lo, hi, zero_ok = PLAUSIBLE[field]
        shown = f"{lo / fac:g} … {hi / fac:g}{' ' + unit if unit else ''}" + (" (or 0)" if zero_ok and lo > 0 else "")
        raise ConfigError(f"{where} = {_short(value)} is implausible for this unit: expected {shown}; check the unit "
                          "in the key name")
    return v


# ------------------------------------------------------------------------------------------- objects
def _pydantic_init(init, data: dict, what: str) -> None:
    """Run a pydantic constructor, turning its ValidationError into one readable ConfigError line."""
    try:
        init(**data)
    except ValidationError as exc:
        msgs = "; ".join(f"{'.'.join(str(p) for p in e['loc']) or 'value'}: "
                         f"{e['msg'].removeprefix('Value error, ')}" for e in exc.errors())
        raise ConfigError(f"{what}: {msgs}") from None


def _real_number(v, name: str):
    """Before-validator: a real number (int or float, numpy scalars included), never text or a boolean."""
    if isinstance(v, (bool, np.bool_, str, bytes)) or v is None:
        raise ValueError(f"expected a number, got {v!r}")
    if isinstance(v, (int, float, np.integer, np.floating)):
        return float(v)
    return v


def _plausible(v: float, name: str, unit: str) -> float:
    if not math.isfinite(v):
        raise ValueError(f"{name} must be finite, got {v}")
    rng = _implausible(name, v)
    if rng is not None:
        raise ValueError(f"{name} = {v:g} {unit} is implausible: expected {rng} {unit} (SI units in the Python "
                         "API: metres, kilograms, pascals)")
    return v


class Tendon(BaseModel):
    """One tendon: routing distance ``distance`` [m] from the axis, angle ``angle`` [rad] about the
    axis measured from the reference direction."""

    model_config = ConfigDict(frozen=True, extra="forbid")
    distance: float
    angle: float

    def __init__(self, **data):
        _pydantic_init(super().__init__, data, "invalid tendon")

    @field_validator("distance", "angle", mode="before")
    @classmethod
    def _real(cls, v, info):
        return _real_number(v, info.field_name)

    @field_validator("distance", "angle")
    @classmethod
    def _d(cls, v, info):
        return _plausible(v, info.field_name, "m" if info.field_name == "distance" else "rad")


class ActuatorParams(BaseModel):
    """Complete description of a tendon-pneumatic bellows actuator (SI units).

    Attributes
    ----------
    name : str
    length : float                 undeformed length L [m]
    n_elements : int               number of ANCF elements n (paper: 6)
    quadrature_points : int        Gauss points per element (≥ 4)
    stiffness : StiffnessLaw       EA(λ, p), EI(λ, p) (pressure factors optional; :mod:`ancf.stiffness`)
    D_eff : float                  effective pressure diameter [m]; A_eff = π D_eff²/4
    pressure_area_slope : float    β of the pressure area A(λ) = A_eff (1 + β (λ − 1)) [-]; 0: constant area
    tendons : tuple[Tendon, ...]   ≥ 3 tendons
    line_mass : float              m' [kg/m] (distributed self-weight)
    tip_mass : float               lumped mass at the tool point [kg]
    tool_offset : float            rigid tool offset h along the tip tangent [m]
    base_axis : tuple              undeformed axis direction (unit)
    reference_direction : tuple    direction of θ = 0 (unit, ⟂ base_axis)
    gravity : tuple                gravity vector [m/s²]
    tension_min, tension_max       tendon tension limits [N]
    pressure_min, pressure_max     pressure limits [Pa]
    free_base_stretch : bool       leave |r_x| at the base free (default: clamped to 1)
    tendon_stiffness : float|None  series stiffness k_s of each tendon path (rope, sensor, screw) [N/m];
                                   None: inextensible.  Locked tendons obey l(q) − T/k_s = l⁰ (rest length)
    rayleigh_alpha : float         mass-proportional damping α [1/s] (C = α M + β K₀; docs/dynamics.md)
    rayleigh_beta : float          stiffness-proportional damping β [s] (K₀: the tangent at the start state)
    axial_damping : float          Kelvin–Voigt axial strain-rate damping c_a [N s]: axial force c_a ε̇,
                                   ε = ½(λ² − 1); the retardation time is c_a / EA
    shear_compliance : tuple       coefficients (s₀, s₁, s₂, …) [m/N] of the series rotation-free tip
                                   compliance s(p) = Σ s_j p̂^j, p̂ = p/100 kPa (:mod:`ancf.shear`); () : none.
                                   s(p) ≥ 0 over [pressure_min, pressure_max] is checked
    tendon_friction : float        Coulomb friction coefficient μ [-] of the tendons at their routing guides
                                   (0 … 1; 0: frictionless, every result as without it); used by
                                   ``Model.fk_history`` / ``Model.tension_cycle`` (:mod:`ancf.friction`)
    """

    model_config = ConfigDict(frozen=True, extra="forbid", arbitrary_types_allowed=False)

    name: str = "custom"
    description: str = ""
    length: float
    n_elements: int = 6
    quadrature_points: int = 5
    stiffness: StiffnessLaw
    D_eff: float
    pressure_area_slope: float = 0.0
    tendons: tuple[Tendon, ...]
    line_mass: float = 0.0
    tip_mass: float = 0.0
    tool_offset: float = 0.0
    base_axis: tuple[float, float, float] = (1.0, 0.0, 0.0)
    reference_direction: tuple[float, float, float] = (0.0, 0.0, 1.0)
    gravity: tuple[float, float, float] = (0.0, 0.0, -9.81)
    tension_min: float = 0.0
    tension_max: float = 5.0
    pressure_min: float = 0.0
    pressure_max: float = 120e3
    free_base_stretch: bool = False
    tendon_stiffness: Optional[float] = None
    rayleigh_alpha: float = 0.0
    rayleigh_beta: float = 0.0
    axial_damping: float = 0.0
    shear_compliance: tuple[float, ...] = ()
    tendon_friction: float = 0.0

    @field_validator("shear_compliance", mode="before")
    @classmethod
    def _shear(cls, v):
        if isinstance(v, (str, bytes)) or not hasattr(v, "__len__"):
            raise ValueError(f"shear_compliance must be a sequence of coefficients [m/N], got {v!r}")
        out = tuple(_real_number(x, "shear_compliance") for x in v)
        if len(out) > 6:
            raise ValueError(f"shear_compliance takes at most 6 coefficients (s₀ … s₅), got {len(out)}")
        lo, hi, _ = PLAUSIBLE["shear_compliance_coeffs"]
        for x in out:
            if not (isinstance(x, float) and math.isfinite(x) and lo <= x <= hi):
                raise ValueError(f"shear_compliance coefficient {x!r} must be finite and within {lo:g} … {hi:g} m/N "
                                 "(SI units in the Python API: 4 mm/N = 0.004)")
        return out

    @field_validator("tendon_friction")
    @classmethod
    def _mu(cls, v):
        if not (math.isfinite(v) and 0.0 <= v <= TENDON_FRICTION_MAX):
            raise ValueError(f"tendon_friction μ = {v!r} must be within 0 … {TENDON_FRICTION_MAX:g} (a Coulomb "
                             "coefficient; tendons on guides: ~0.05 … 0.3)")
        return v

    @field_validator("tendon_stiffness")
    @classmethod
    def _ks(cls, v):
        if v is not None and not (math.isfinite(v) and v > 0):
            raise ValueError(f"tendon_stiffness {v} N/m must be finite and > 0 (omit it for inextensible tendons)")
        if v is not None and _implausible("tendon_stiffness", v):
            raise ValueError(f"tendon_stiffness = {v:g} N/m is implausible: expected "
                             f"{_implausible('tendon_stiffness', v)} N/m (omit it for inextensible tendons)")
        return v

    @field_validator("length", "D_eff", "pressure_area_slope", "line_mass", "tip_mass", "tool_offset",
                     "tension_min", "tension_max", "pressure_min", "pressure_max", "rayleigh_alpha",
                     "rayleigh_beta", "axial_damping", "tendon_friction", mode="before")
    @classmethod
    def _real(cls, v, info):
        return _real_number(v, info.field_name)

    @field_validator("base_axis", "reference_direction", "gravity", mode="before")
    @classmethod
    def _real_vec(cls, v, info):
        if isinstance(v, (str, bytes)) or not hasattr(v, "__len__"):
            raise ValueError(f"expected 3 numbers, got {v!r}")
        return tuple(_real_number(x, info.field_name) for x in v)

    @field_validator("n_elements", "quadrature_points", mode="before")
    @classmethod
    def _int(cls, v):
        if isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, np.integer)):
            raise ValueError(f"expected a whole number, got {v!r}")
        return int(v)

    @field_validator("free_base_stretch", mode="before")
    @classmethod
    def _bool(cls, v):
        if not isinstance(v, (bool, np.bool_)):
            raise ValueError(f"expected True or False, got {v!r}")
        return bool(v)

    @field_validator("name", "description", mode="before")
    @classmethod
    def _text(cls, v):
        if not isinstance(v, str):
            raise ValueError(f"expected text, got {v!r}")
        return v

    @field_validator("length", "D_eff", "line_mass", "tip_mass", "tool_offset", "tension_min", "tension_max",
                     "pressure_min", "pressure_max", "rayleigh_alpha", "rayleigh_beta", "axial_damping")
    @classmethod
    def _magnitude(cls, v, info):
        unit = {"line_mass": "kg/m", "tip_mass": "kg", "tension_min": "N", "tension_max": "N",
                "pressure_min": "Pa", "pressure_max": "Pa", "rayleigh_alpha": "1/s", "rayleigh_beta": "s",
                "axial_damping": "N s"}.get(info.field_name, "m")
        return _plausible(v, info.field_name, unit)

    @field_validator("n_elements")
    @classmethod
    def _n(cls, v):
        if not (N_ELEMENTS_MIN <= v <= N_ELEMENTS_MAX):
            raise ValueError(f"n_elements must be in [{N_ELEMENTS_MIN}, {N_ELEMENTS_MAX}]")
        return v

    @field_validator("quadrature_points")
    @classmethod
    def _ng(cls, v):
        if not (QUADRATURE_MIN <= v <= QUADRATURE_MAX):
            raise ValueError(f"quadrature_points must be in [{QUADRATURE_MIN}, {QUADRATURE_MAX}]")
        return v

    @field_validator("pressure_area_slope")
    @classmethod
    def _beta(cls, v):
        if not (math.isfinite(v) and -2.0 < v < 2.0):
            raise ValueError(f"pressure_area_slope {v} must be in (-2, 2) (A(λ) must stay positive for "
                             "0.5 < λ < 1.5)")
        return v

    @field_validator("line_mass", "tip_mass", "tool_offset", "tension_min", "pressure_min", "rayleigh_alpha",
                     "rayleigh_beta", "axial_damping")
    @classmethod
    def _nonneg(cls, v):
        if not (v >= 0 and math.isfinite(v)):
            raise ValueError("must be finite and >= 0")
        return v

    @field_validator("tendons")
    @classmethod
    def _tendons(cls, v):
        if len(v) < TENDONS_MIN:
            raise ValueError(f"need at least {TENDONS_MIN} tendons, got {len(v)}")
        if len(v) > TENDONS_MAX:
            raise ValueError(f"at most {TENDONS_MAX} tendons, got {len(v)}")
        for i in range(len(v)):
            for j in range(i):
                gap = abs(math.remainder(v[i].angle - v[j].angle, 2 * math.pi))
                if gap < TENDON_SEPARATION_MIN:
                    raise ValueError(f"tendons {j + 1} and {i + 1} are at the same angle about the axis "
                                     f"({math.degrees(v[j].angle):g}° and {math.degrees(v[i].angle):g}°, "
                                     f"{math.degrees(gap):.3g}° apart); tendons must be at least "
                                     f"{math.degrees(TENDON_SEPARATION_MIN):g}° apart")
        return v

    @model_validator(mode="after")
    def _frame(self):
        e1 = np.asarray(self.base_axis, float)
        er = np.asarray(self.reference_direction, float)
        if not np.all(np.isfinite(e1)) or abs(np.linalg.norm(e1) - 1) > 1e-9:
            raise ValueError(f"base_axis {self.base_axis} must be a unit vector")
        if not np.all(np.isfinite(er)) or abs(np.linalg.norm(er) - 1) > 1e-9 or abs(e1 @ er) > 1e-9:
            raise ValueError(f"reference_direction {self.reference_direction} must be a unit vector "
                             f"perpendicular to base_axis {self.base_axis}")
        if not np.all(np.isfinite(self.gravity)) or np.linalg.norm(self.gravity) > 100.0:
            raise ValueError(f"gravity {self.gravity} m/s² must be finite and at most 100 m/s² in magnitude")
        if not (self.tension_max > self.tension_min):
            raise ValueError("tension_max must exceed tension_min")
        if not (self.pressure_max >= self.pressure_min):
            raise ValueError("pressure_max must be >= pressure_min")
        for which, coeffs in (("EA", self.stiffness.EA_pressure), ("EI", self.stiffness.EI_pressure)):
            lo, hi, _ = PLAUSIBLE[f"{which}_pressure_coeffs"]
            if any(not lo <= c <= hi for c in coeffs):
                raise ValueError(f"{which}_pressure_coeffs {list(coeffs)} per (p/100 kPa)^j: each coefficient must "
                                 f"be within {lo:g} … {hi:g}")
        if self.stiffness.pressure_dependent:
            f, p, which = self.stiffness.pressure_factor_minimum(self.pressure_min, self.pressure_max)
            if not f > 0:
                raise ValueError(f"the stiffness law's pressure factor of {which} is {f:.4g} ≤ 0 at p = {p / 1e3:g} "
                                 f"kPa, inside the pressure limits [{self.pressure_min / 1e3:g}, "
                                 f"{self.pressure_max / 1e3:g}] kPa: {which} must stay positive over the "
                                 "operating range")
        if any(self.shear_compliance):
            from .shear import minimum
            smin, p = minimum(self.shear_compliance, self.pressure_min, self.pressure_max)
            if not smin >= 0:
                raise ValueError(f"the shear compliance s(p) = {smin:.4g} m/N < 0 at p = {p / 1e3:g} kPa, inside "
                                 f"the pressure limits [{self.pressure_min / 1e3:g}, {self.pressure_max / 1e3:g}] "
                                 "kPa: s must be ≥ 0 over the operating range")
        return self

    def __init__(self, **data):
        # re-raise as the product's own error with a readable message
        _pydantic_init(super().__init__, data, "invalid actuator parameters")

    # ----------------------------------------------------------------------------- derived quantities
    @property
    def A_eff(self) -> float:
        """Effective pressure area π D_eff²/4 [m²]."""
        return math.pi * self.D_eff ** 2 / 4

    def pressure_area(self, lam):
        """Effective pressure area A(λ) = A_eff (1 + β (λ − 1)) [m²] at stretch λ."""
        return self.A_eff * (1.0 + self.pressure_area_slope * (np.asarray(lam, float) - 1.0))

    @property
    def volume_coeffs(self) -> np.ndarray:
        """Coefficients c of the volume per reference length A(λ) λ = Σ_k c_k λ^{k+1} [m²]."""
        b = self.pressure_area_slope
        return np.array([self.A_eff * (1.0 - b), self.A_eff * b]) if b != 0.0 else np.array([self.A_eff])

    @property
    def element_length(self) -> float:
        return self.length / self.n_elements

    @property
    def n_tendons(self) -> int:
        return len(self.tendons)

    @property
    def tendon_distances(self) -> np.ndarray:
        return np.array([t.distance for t in self.tendons])

    @property
    def tendon_angles(self) -> np.ndarray:
        return np.array([t.angle for t in self.tendons])

    @property
    def frame(self) -> np.ndarray:
        """Actuator frame as columns ``[e1, e2, e3]``: base axis, reference direction, e1 × e2."""
        e1 = np.asarray(self.base_axis, float)
        e2 = np.asarray(self.reference_direction, float)
        return np.column_stack([e1, e2, np.cross(e1, e2)])

    def replace(self, **changes) -> "ActuatorParams":
        """A validated copy with some fields changed, e.g. ``params.replace(n_elements=8)``."""
        unknown = set(changes) - set(type(self).model_fields)
        if unknown:
            raise ConfigError(f"unknown parameter(s) {sorted(unknown)}; known: {sorted(type(self).model_fields)}")
        data = self.model_dump()
        data.update(changes)
        data["stiffness"] = changes.get("stiffness", self.stiffness)
        data["shear_compliance"] = changes.get("shear_compliance", self.shear_compliance)
        if "tendons" not in changes:
            data["tendons"] = self.tendons
        return ActuatorParams(**data)

    # ----------------------------------------------------------------------------------------- TOML
    @classmethod
    def from_toml(cls, path) -> "ActuatorParams":
        """Load parameters from a TOML file with unit-suffixed keys (see module docstring)."""
        path = pathlib.Path(path)
        try:
            text = path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            raise ConfigError(f"cannot read actuator file {path}: {exc}") from None
        return cls.from_toml_string(text, where=str(path))

    @classmethod
    def from_toml_string(cls, text: str, where: str = "<string>") -> "ActuatorParams":
        try:
            raw = tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise ConfigError(f"{where}: not valid TOML: {exc}") from None
        raw = dict(raw)
        stiff = raw.pop("stiffness", None)
        tendons = raw.pop("tendons", None)
        # [provenance]: where the parameters came from (written by `bellows identify`); a record for people and
        # run logs, not a parameter: accepted as a table and otherwise ignored
        if not isinstance(raw.pop("provenance", {}), dict):
            raise ConfigError(f"{where}: 'provenance' must be a table ([provenance])")
        if stiff is None:
            raise ConfigError(f"{where}: missing [stiffness] table")
        if not isinstance(stiff, dict):
            raise ConfigError(f"{where}: 'stiffness' must be a table ([stiffness]), got {stiff!r}")
        if not tendons:
            raise ConfigError(f"{where}: missing [[tendons]] entries")
        if not isinstance(tendons, list) or not all(isinstance(t, dict) for t in tendons):
            raise ConfigError(f"{where}: 'tendons' must be [[tendons]] tables, got {_short(tendons)}")
        if not TENDONS_MIN <= len(tendons) <= TENDONS_MAX:
            raise ConfigError(f"{where}: {len(tendons)} [[tendons]] tables; an actuator has {TENDONS_MIN} … "
                              f"{TENDONS_MAX} tendons")
        top = _parse_table(raw, TOP_FIELDS, where)
        s = _parse_table(stiff, STIFFNESS_FIELDS, f"{where}[stiffness]")
        law = s.pop("law", None)
        p_ea, p_ei = s.pop("EA_pressure_coeffs", None), s.pop("EI_pressure_coeffs", None)
        for key, v in (("EA_pressure_coeffs_per_100kPa", p_ea), ("EI_pressure_coeffs_per_100kPa", p_ei)):
            if v is not None and not isinstance(v, list):
                raise ConfigError(f"{where}[stiffness].{key}: expected a list of numbers (coefficients of "
                                  f"(p/100 kPa)^1, ^2, …), got {v!r}")
        try:
            if law == "linear":
                stiffness = StiffnessLaw.linear(**s)
            elif law == "constant":
                stiffness = StiffnessLaw.constant(**s)
            elif law == "polynomial":
                if set(s) != {"EA_coeffs", "EI_coeffs"}:
                    raise TypeError(f"needs EA_coeffs and EI_coeffs, got {sorted(s)}")
                stiffness = StiffnessLaw.polynomial(EA=s["EA_coeffs"], EI=s["EI_coeffs"])
            else:
                raise ConfigError(f"{where}[stiffness]: law must be 'linear', 'constant' or 'polynomial', "
                                  f"got {law!r}")
            if p_ea or p_ei:
                stiffness = stiffness.with_pressure(EA=p_ea or (), EI=p_ei or ())
        except TypeError as exc:
            raise ConfigError(f"{where}[stiffness]: wrong keys for law '{law}': {exc}") from None
        except ConfigError as exc:
            raise ConfigError(_located(str(exc), f"{where}[stiffness]")) from None
        tl = []
        for i, t in enumerate(tendons):
            try:
                tl.append(Tendon(**_parse_table(t, TENDON_FIELDS, f"{where}[[tendons]][{i}]")))
            except ConfigError as exc:
                raise ConfigError(_located(str(exc), f"{where}[[tendons]][{i}]")) from None
        for k in ("base_axis", "reference_direction", "gravity"):
            if k in top:
                if not isinstance(top[k], list) or len(top[k]) != 3:
                    raise ConfigError(f"{where}.{k}: expected a list of 3 numbers, got {top[k]!r}")
                top[k] = tuple(_number(x, 1.0, k, "", f"{where}.{k}") for x in top[k])
                v = np.asarray(top[k])
                if k != "gravity" and abs(np.linalg.norm(v) - 1.0) > 1e-12 and np.linalg.norm(v) > 0:
                    top[k] = tuple(float(x) for x in v / np.linalg.norm(v))   # exact unit vectors are kept
        if "shear_compliance_coeffs" in top:
            v = top.pop("shear_compliance_coeffs")
            if not isinstance(v, list):
                raise ConfigError(f"{where}.shear_compliance_coeffs_mm_per_N_per_100kPa: expected a list of numbers "
                                  f"(coefficients of (p/100 kPa)^0, ^1, ^2, …), got {v!r}")
            top["shear_compliance"] = tuple(v)
        try:
            return cls(stiffness=stiffness, tendons=tuple(tl), **top)
        except ConfigError as exc:
            raise ConfigError(_located(str(exc), where)) from None

    def to_toml(self) -> str:
        """Serialise to the TOML format read by :meth:`from_toml` (SI units spelled out)."""
        lines = [f"name = {_toml_string(self.name)}"]
        if self.description:
            lines.append(f"description = {_toml_string(self.description)}")
        lines += [
            f"length_m = {self.length!r}", f"n_elements = {self.n_elements}",
            f"quadrature_points = {self.quadrature_points}", f"D_eff_m = {self.D_eff!r}",
            f"pressure_area_slope = {self.pressure_area_slope!r}",
            f"line_mass_kg_per_m = {self.line_mass!r}", f"tip_mass_kg = {self.tip_mass!r}",
            f"tool_offset_m = {self.tool_offset!r}", f"base_axis = {list(self.base_axis)}",
            f"reference_direction = {list(self.reference_direction)}",
            f"gravity_m_per_s2 = {list(self.gravity)}", f"tension_min_N = {self.tension_min!r}",
            f"tension_max_N = {self.tension_max!r}", f"pressure_min_Pa = {self.pressure_min!r}",
            f"pressure_max_Pa = {self.pressure_max!r}",
            f"free_base_stretch = {'true' if self.free_base_stretch else 'false'}",
            *([f"tendon_stiffness_N_per_m = {self.tendon_stiffness!r}"] if self.tendon_stiffness else []),
            *([f"rayleigh_alpha_per_s = {self.rayleigh_alpha!r}"] if self.rayleigh_alpha else []),
            *([f"rayleigh_beta_s = {self.rayleigh_beta!r}"] if self.rayleigh_beta else []),
            *([f"axial_damping_N_s = {self.axial_damping!r}"] if self.axial_damping else []),
            *([f"shear_compliance_coeffs_m_per_N_per_100kPa = {list(self.shear_compliance)}"]
              if self.shear_compliance else []),
            *([f"tendon_friction = {self.tendon_friction!r}"] if self.tendon_friction else []),
            "", "[stiffness]",
            f'law = "{self.stiffness.kind}"']
        s = self.stiffness
        if s.kind == "linear":
            lines += [f"a_N = {s.source['a']!r}", f"b_N = {s.source['b']!r}", f"D_a_m = {s.source['D_a']!r}"]
        elif s.kind == "constant":
            lines += [f"EA_N = {s.EA_coeffs[0]!r}", f"EI_N_m2 = {s.EI_coeffs[0]!r}"]
        else:
            lines += [f"EA_coeffs_N = {list(s.EA_coeffs)}", f"EI_coeffs_N_m2 = {list(s.EI_coeffs)}"]
        if s.EA_pressure:
            lines.append(f"EA_pressure_coeffs_per_100kPa = {list(s.EA_pressure)}")
        if s.EI_pressure:
            lines.append(f"EI_pressure_coeffs_per_100kPa = {list(s.EI_pressure)}")
        for t in self.tendons:
            lines += ["", "[[tendons]]", f"distance_m = {t.distance!r}", f"angle_rad = {t.angle!r}"]
        return "\n".join(lines) + "\n"


def _toml_string(text: str) -> str:
    """A TOML basic string (quotes, backslashes and control characters escaped)."""
    out = []
    for ch in text:
        if ch in ('"', "\\"):
            out.append("\\" + ch)
        elif ch == "\n":
            out.append("\\n")
        elif ch == "\t":
            out.append("\\t")
        elif ord(ch) < 0x20 or ord(ch) == 0x7F:
            out.append(f"\\u{ord(ch):04x}")
        else:
            out.append(ch)
    return '"' + "".join(out) + '"'
