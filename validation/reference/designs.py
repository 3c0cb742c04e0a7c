"""Bellows designs for the FEM: named presets and TOML files with explicit units.

A lab describes its bellows in a TOML file (every dimensioned key states its unit, as actuator files do;
unknown keys and missing units are errors)::

    name = "my bellows"
    length_mm = 160
    n_convolutions = 8
    root_radius_mm = 10.0        # inner radius at a root (valley)
    crest_radius_mm = 19.5       # outer radius at a crest
    wall_thickness_mm = 1.6
    collar_length_mm = 5
    tendon_radius_mm = 27.5
    tendon_angles_deg = [0, 120, 240]
    cap_mass_g = 18
    cap_com_offset_mm = 2.5
    tip_offset_mm = 0
    mounting = "horizontal"      # or "vertical_down" (hanging, tip below the base), "vertical_up"
    tendon_friction = 0          # optional: Coulomb friction coefficient μ of the tendons at their guides, 0 … 1

    [material]
    model = "neo_hookean"        # or "mooney_rivlin" (with c10_MPa, c01_MPa)
    mu_MPa = 0.8
    kappa_MPa = 40
    density_kg_per_m3 = 1100

    [limits]                     # optional: the operating range the identification spans
    tension_max_N = 5
    pressure_max_kPa = 120

**A wall profile as data.**  ``profile_file = "wall.csv"`` (a path relative to the TOML file) gives the inner and
outer outline of the wall as a table (format, rules and errors: :mod:`fem_reference.profile`, docs/fem.md §3b), or
``profile_file = "wall.msh"`` (any 2-D mesh file meshio reads) as a mesh of the meridian section, x = radius,
y = axial, whose unit the design states as ``profile_unit = "mm"`` (or "m", "cm"; :mod:`fem_reference.section_mesh`);
the design then states ``n_convolutions`` and ``collar_length_*`` (mesh blocks, tendon guides at the roots) but not
``length``, ``root_radius``, ``crest_radius`` or ``wall_thickness``, which are read off the table.

**Plausibility.**  Every dimensioned key is checked against :data:`PLAUSIBLE` (a value outside is almost always a
unit mistake: the message names the key and the range in its unit), ``n_convolutions`` against 1 … 100,
``tendon_angles_*`` must be a list of 1 … 16 distinct angles (two tendons at one angle would make the tension →
tip map singular), the other keys single numbers.

**Mounting.**  ``mounting`` states how the actuator is held, which sets the gravity vector of its gravity load cases
in the world frame of the FEM and of the reduced model (axis along ``+x``, :data:`MOUNTINGS`): ``"horizontal"`` (the
default, as on the paper's rig: gravity ``−z``), ``"vertical_down"`` (hanging, the tip below the base: gravity
``+x``) or ``"vertical_up"`` (standing on its base: gravity ``−x``); :func:`design_mounting` reads it,
:func:`mounting_gravity` gives the vector [m/s²].  Any other value is a :class:`ConfigError`.

**Tendon friction.**  ``tendon_friction`` (dimensionless, 0 … 1 as ``ActuatorParams.tendon_friction``; default 0,
frictionless; every preset is frictionless) is the capstan coefficient μ of the tendons at their routing guides
(docs/friction.md); :func:`design_friction` reads it.  ``bellows report`` then checks the identified actuator's
hysteresis against the FEM's (:mod:`validation.checks.hysteresis`).

The operating range (:func:`design_limits`; default 5 N, 120 kPa) sets the loads of the virtual experiments.
The ``paper`` preset (the soft, calibrated bellows) states 100 kPa: its FEM has an inflation limit point
between 105 and 115 kPa (neo-Hookean wall, coarse mesh — no equilibrium beyond it; the Newton solve fails
there after many load-step cut-backs), so a design reaching 120 kPa would spend minutes on cases that
cannot converge.

:func:`load_design` takes such a file or a preset name (:data:`PRESETS`) and returns
``(BellowsGeometry, Material)``; :func:`design_to_toml` writes one back in SI units (read back unchanged).
"""

from __future__ import annotations

import json
import math
import pathlib

from ancf.errors import ConfigError
from ancf.params import UNITS, _parse_table
from fem_reference.geometry import N_CONVOLUTIONS_MAX, N_TENDONS_MAX

#: factor to SI of every unit suffix a design key may carry
UNITS_BY_NAME = {u: f for table in UNITS.values() for u, f in table.items() if u}

try:  # Python >= 3.11
    import tomllib
except ModuleNotFoundError:  # pragma: no cover
    import tomli as tomllib

__all__ = ["load_design", "design_to_toml", "design_limits", "design_mounting", "design_friction", "mounting_gravity",
           "PRESETS",
           "DEFAULT_LIMITS", "MOUNTINGS", "DEFAULT_MOUNTING"]

#: standard gravity [m/s²]
G_STANDARD = 9.81
#: gravity vector [m/s²] of each mounting, in the world frame with the undeformed axis along +x
MOUNTINGS = {"horizontal": (0.0, 0.0, -G_STANDARD), "vertical_down": (G_STANDARD, 0.0, 0.0),
             "vertical_up": (-G_STANDARD, 0.0, 0.0)}
DEFAULT_MOUNTING = "horizontal"

GEOMETRY_FIELDS = {"name": None, "description": None, "profile_file": None, "profile_unit": None, "length": "length",
                   "n_convolutions": None,
                   "root_radius": "length", "crest_radius": "length", "wall_thickness": "length",
                   "collar_length": "length", "tendon_radius": "length", "tendon_angles": "angle",
                   "cap_mass": "mass", "cap_com_offset": "length", "tip_offset": "length"}
MATERIAL_FIELDS = {"model": None, "mu": "modulus", "kappa": "modulus", "c10": "modulus", "c01": "modulus",
                   "density": "density", "formulation": None}


#: Plausible SI range of every dimensioned design key: (low, high, zero allowed).
PLAUSIBLE = {
    "length": (5e-3, 2.0, False), "root_radius": (1e-4, 0.5, False), "crest_radius": (1e-4, 0.5, False),
    "wall_thickness": (5e-5, 0.05, False), "collar_length": (1e-5, 1.0, True), "tendon_radius": (1e-4, 0.5, False),
    "tendon_angles": (-2 * math.pi, 2 * math.pi, True), "cap_mass": (1e-6, 10.0, True),
    "cap_com_offset": (1e-5, 1.0, True), "tip_offset": (1e-5, 1.0, True),
    "mu": (1e3, 1e9, False), "kappa": (1e3, 1e11, False), "c10": (-1e9, 1e9, True), "c01": (-1e9, 1e9, True),
    "density": (100.0, 20000.0, False), "tension_max": (1e-3, 1e3, False), "pressure_max": (1e3, 10e6, False),
}
#: largest tendon friction coefficient a design may state (as ActuatorParams.tendon_friction)
FRICTION_MAX = 1.0
TEXT_KEYS = ("name", "description", "profile_file", "profile_unit", "model", "formulation", "mounting")
#: keys a design with a profile_file must not state (read off the table)
TABLE_DERIVED = ("length", "root_radius", "crest_radius", "wall_thickness")


def _check_values(raw: dict, parsed: dict, where: str) -> None:
    """Types, list/scalar shape and plausible magnitude of every parsed value; the message names the key as
    written and the range in its unit."""
    written = {}
    for key in raw:
        for f in parsed:
            if key == f or key.startswith(f + "_"):
                written.setdefault(f, key)
    for f, v in parsed.items():
        key = written.get(f, f)
        unit = key[len(f) + 1:]
        if f in TEXT_KEYS:
            if not isinstance(v, str):
                raise ConfigError(f"{where}: {key} must be text in quotes, got {v!r}")
            continue
        if f == "n_convolutions":
            if isinstance(v, bool) or not isinstance(v, int) or not 1 <= v <= N_CONVOLUTIONS_MAX:
                raise ConfigError(f"{where}: n_convolutions must be a whole number in 1 … {N_CONVOLUTIONS_MAX}, "
                                  f"got {v!r}")
            continue
        if isinstance(v, list):
            raise ConfigError(f"{where}: {key} must be a single number, got the list {v!r}")
        _plausible(f, v, raw[key], key, unit, where)


def _plausible(field: str, si: float, given, key: str, unit: str, where: str) -> None:
    lo, hi, zero_ok = PLAUSIBLE[field]
    if (zero_ok and si == 0.0) or lo <= si <= hi:
        return
    fac = UNITS_BY_NAME.get(unit, 1.0)
    raise ConfigError(f"{where}: {key} = {given!r} is implausible: expected {lo / fac:g} … {hi / fac:g}"
                      f"{' ' + unit if unit else ''}{' (or 0)' if zero_ok else ''}; check the unit in the key name")


def _presets():
    from fem_reference import presets as fp
    return {
        "paper": lambda: (fp.paper_bellows(), fp.paper_material()),
        "paper_stiff": lambda: (fp.paper_bellows("stiff"), fp.paper_material()),
        "paper_deep": lambda: (fp.paper_bellows("deep"), fp.paper_material()),
        "straight_tube": lambda: (fp.straight_tube_test(), fp.paper_material()),
    }


#: Names accepted by :func:`load_design` besides file paths.
PRESETS = ("paper", "paper_stiff", "paper_deep", "straight_tube")
#: Operating range of a design without a [limits] table: tendon tension [N], pressure [Pa].
DEFAULT_LIMITS = {"tension_max": 5.0, "pressure_max": 120e3}
_PRESET_LIMITS = {"paper": {"tension_max": 5.0, "pressure_max": 100e3}}
LIMIT_FIELDS = {"tension_max": "force", "pressure_max": "pressure"}


def design_limits(source) -> dict:
    """Operating range ``{"tension_max": N, "pressure_max": Pa}`` of a preset or a design file (its optional
    ``[limits]`` table; module docstring)."""
    if isinstance(source, str) and source in PRESETS:
        return dict(DEFAULT_LIMITS, **_PRESET_LIMITS.get(source, {}))
    raw = _read(source)
    lim = raw.get("limits", {})
    if not isinstance(lim, dict):
        raise ConfigError(f"{source}: [limits] must be a table")
    parsed = _parse_table(dict(lim), LIMIT_FIELDS, f"{source}[limits]")
    for k, v in parsed.items():
        if isinstance(v, (str, bool, list)) or not (v > 0):
            raise ConfigError(f"{source}[limits]: {k} must be a positive number, got {v!r}")
    _check_values(lim, parsed, f"{source}[limits]")
    return dict(DEFAULT_LIMITS, **parsed)


def mounting_gravity(mounting: str) -> tuple:
    """Gravity vector (3,) [m/s²] of the mounting ``mounting`` (:data:`MOUNTINGS`); ConfigError for another name."""
    if not isinstance(mounting, str) or mounting not in MOUNTINGS:
        raise ConfigError(f"mounting must be one of {', '.join(MOUNTINGS)}, got {mounting!r}")
    return MOUNTINGS[mounting]


def design_mounting(source) -> str:
    """How the design is mounted (module docstring): a preset's is ``"horizontal"``; a design file's is its
    ``mounting`` key (default ``"horizontal"``), checked — ConfigError for an unknown value."""
    if isinstance(source, str) and source in PRESETS:
        return DEFAULT_MOUNTING
    value = _read(source).get("mounting", DEFAULT_MOUNTING)
    if not isinstance(value, str) or value not in MOUNTINGS:
        raise ConfigError(f"{source}: mounting must be one of {', '.join(MOUNTINGS)} (text in quotes), got {value!r}")
    return value


def design_friction(source) -> float:
    """The tendons' friction coefficient μ [-] of the design (module docstring): 0 for a preset; a design file's
    ``tendon_friction`` key (default 0), a number in 0 … 1 — ConfigError otherwise."""
    if isinstance(source, str) and source in PRESETS:
        return 0.0
    value = _read(source).get("tendon_friction", 0.0)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not (0.0 <= value <= FRICTION_MAX):
        raise ConfigError(f"{source}: tendon_friction must be a friction coefficient μ in 0 … {FRICTION_MAX:g} "
                          f"(dimensionless, no unit), got {value!r}")
    return float(value)


def _read(source) -> dict:
    path = pathlib.Path(source)
    if path.suffix.lower() != ".toml":
        raise ConfigError(f"design {source!r} is neither a preset ({', '.join(PRESETS)}) nor a .toml file")
    try:
        return tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{path}: not valid TOML: {exc}") from None
    except (OSError, ValueError) as exc:           # ValueError: undecodable bytes, a NUL in the path
        raise ConfigError(f"cannot read design file {path}: {getattr(exc, 'strerror', None) or exc}") from None


def load_design(source):
    """``(BellowsGeometry, Material)`` from a preset name or a design TOML file (module docstring).  Any file gives
    either a valid design or a :class:`ConfigError` naming the key (tested with random files)."""
    if isinstance(source, str) and source in PRESETS:
        return _presets()[source]()
    path = pathlib.Path(source)
    raw = _read(source)
    design_limits(source)                      # the optional [limits] table is checked here too
    design_mounting(source)                    # and the mounting
    design_friction(source)                    # and the tendon friction
    raw.pop("limits", None)
    raw.pop("mounting", None)
    raw.pop("tendon_friction", None)
    mat_raw = raw.pop("material", None)
    if not isinstance(mat_raw, dict):
        raise ConfigError(f"{path}: missing [material] table")
    return _geometry(raw, path), _material(mat_raw, f"{path}[material]")


def _geometry(raw: dict, path: pathlib.Path):
    from fem_reference import BellowsGeometry
    from fem_reference.profile import read_profile

    raw, angles = _tendon_angles(raw, str(path))
    g = _parse_table(raw, GEOMETRY_FIELDS, str(path))
    _check_values(raw, g, str(path))
    g.update(angles)
    for k in ("name", "description"):
        g.pop(k, None)
    if "tendon_angles" in g:
        g["tendon_angles"] = tuple(g["tendon_angles"])
    profile_file = g.pop("profile_file", None)
    profile_unit = g.pop("profile_unit", None)
    if profile_unit is not None and profile_file is None:
        raise ConfigError(f"{path}: profile_unit is the length unit of a profile_file mesh; there is no profile_file")
    needed = ("n_convolutions",) if profile_file else ("length", "n_convolutions", "root_radius", "crest_radius",
                                                        "wall_thickness")
    missing = [k for k in needed if k not in g]
    if missing:
        raise ConfigError(f"{path}: missing {', '.join(missing)} (with units, e.g. length_mm)")
    if profile_file is None:
        return BellowsGeometry(**g)
    extra = [k for k in TABLE_DERIVED if k in g]
    if extra:
        raise ConfigError(f"{path}: {', '.join(extra)} must not be given with profile_file: they are read off the "
                          f"profile table")
    profile = read_profile(_relative(path, profile_file), profile_unit)
    return BellowsGeometry.from_profile(profile, **g)


def _tendon_angles(raw: dict, where: str) -> tuple[dict, dict]:
    """Split the list key ``tendon_angles_<unit>`` off ``raw``: (the rest, {"tendon_angles": [rad, ...]})."""
    keys = [k for k in raw if k == "tendon_angles" or k.startswith("tendon_angles_")]
    if len(keys) != 1:
        return raw, {}                          # none, or twice: _parse_table names the problem
    key = keys[0]
    rest = {k: v for k, v in raw.items() if k != key}
    value = raw[key]
    if not isinstance(value, list):
        raise ConfigError(f"{where}: {key} must be a list of numbers, e.g. [0, 120, 240], got {value!r}")
    if not 1 <= len(value) <= N_TENDONS_MAX:
        raise ConfigError(f"{where}: {key} must list 1 … {N_TENDONS_MAX} angles, got {len(value)}")
    out = []
    for i, x in enumerate(value):
        parsed = _parse_table({key: x}, {"tendon_angles": "angle"}, f"{where}[{i}]")
        _check_values({key: x}, parsed, f"{where}[{i}]")
        out.append(parsed["tendon_angles"])
    return rest, {"tendon_angles": out}


def _relative(path: pathlib.Path, name: str) -> pathlib.Path:
    """``name`` relative to the design file's folder (absolute paths kept), resolved."""
    p = pathlib.Path(name)
    if not name.strip():
        raise ConfigError(f"{path}: profile_file is empty")
    return (p if p.is_absolute() else path.parent / p).resolve()


def _material(mat_raw: dict, where: str):
    from fem_reference import Material

    m = _parse_table(mat_raw, MATERIAL_FIELDS, where)
    _check_values(mat_raw, m, where)
    model = m.pop("model", "neo_hookean")
    density = m.pop("density", 1100.0)
    try:
        if model == "neo_hookean":
            material = Material.neo_hookean(mu=m.pop("mu"), kappa=m.pop("kappa"), density=density,
                                            **({"formulation": m.pop("formulation")} if "formulation" in m else {}))
        elif model == "mooney_rivlin":
            material = Material.mooney_rivlin(c10=m.pop("c10"), c01=m.pop("c01"), kappa=m.pop("kappa"),
                                              density=density)
        else:
            raise ConfigError(f"{where}: model must be 'neo_hookean' or 'mooney_rivlin', got {model!r}")
    except KeyError as exc:
        raise ConfigError(f"{where}: missing {exc.args[0]} (with a unit, e.g. {exc.args[0]}_MPa)") from None
    except (TypeError, ValueError) as exc:
        if isinstance(exc, ConfigError):
            raise
        raise ConfigError(f"{where}: {exc}") from None
    if m:
        raise ConfigError(f"{where}: keys {sorted(m)} do not apply to model '{model}'")
    return material


def design_to_toml(geometry, material, name: str = "bellows", limits: dict | None = None,
                   mounting: str = DEFAULT_MOUNTING, tendon_friction: float = 0.0) -> str:
    """The design as TOML in the format of :func:`load_design`, in SI units (m, kg, rad, Pa) so that it reads
    back exactly (a table profile is referred to by the absolute path of its file); ``limits`` ({"tension_max": N,
    "pressure_max": Pa}) adds the [limits] table; ``mounting`` (:data:`MOUNTINGS`) is written as given;
    ``tendon_friction`` μ (0 … 1) is written when > 0."""
    mounting_gravity(mounting)
    if isinstance(tendon_friction, bool) or not isinstance(tendon_friction, (int, float)) \
            or not 0.0 <= tendon_friction <= FRICTION_MAX:
        raise ConfigError(f"tendon_friction must be in 0 … {FRICTION_MAX:g}, got {tendon_friction!r}")
    g = geometry
    if getattr(g, "is_table", False):
        if not g.profile.source:
            raise ConfigError("a design with a profile table needs its profile file: write it with "
                              "fem_reference.profile.write_profile_csv and read it back first")
        shape = [f"profile_file = {json.dumps(pathlib.Path(g.profile.source).resolve().as_posix())}"]
        if g.profile.source_unit:
            shape.append(f"profile_unit = {json.dumps(g.profile.source_unit)}")
    else:
        shape = [f"length_m = {g.length!r}", f"root_radius_m = {g.root_radius!r}",
                 f"crest_radius_m = {g.crest_radius!r}", f"wall_thickness_m = {g.wall_thickness!r}"]
    lines = [f"name = {json.dumps(str(name))}", *shape, f"n_convolutions = {int(g.n_convolutions)}", f"collar_length_m = {g.collar_length!r}",
             f"tendon_radius_m = {g.tendon_radius!r}", f"tendon_angles_rad = {list(g.tendon_angles)!r}",
             f"cap_mass_kg = {g.cap_mass!r}", f"cap_com_offset_m = {g.cap_com_offset!r}",
             f"tip_offset_m = {g.tip_offset!r}", f"mounting = {json.dumps(mounting)}",
             *([f"tendon_friction = {float(tendon_friction)!r}"] if tendon_friction else []), "", "[material]"]
    if material.c01:
        lines += ['model = "mooney_rivlin"', f"c10_Pa = {material.mu / 2 - material.c01!r}", f"c01_Pa = {material.c01!r}"]
    else:
        lines += ['model = "neo_hookean"', f"mu_Pa = {material.mu!r}", f'formulation = "{material.formulation}"']
    lines += [f"kappa_Pa = {material.kappa!r}", f"density_kg_per_m3 = {material.density!r}"]
    if limits:
        lines += ["", "[limits]", f"tension_max_N = {float(limits['tension_max'])!r}",
                  f"pressure_max_Pa = {float(limits['pressure_max'])!r}"]
    return "\n".join(lines) + "\n"
