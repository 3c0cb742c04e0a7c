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

    [material]
    model = "neo_hookean"        # or "mooney_rivlin" (with c10_MPa, c01_MPa)
    mu_MPa = 0.8
    kappa_MPa = 40
    density_kg_per_m3 = 1100

    [limits]                     # optional: the operating range the identification spans
    tension_max_N = 5
    pressure_max_kPa = 120

The operating range (:func:`design_limits`; default 5 N, 120 kPa) sets the loads of the virtual experiments.
The ``paper`` preset (the soft, calibrated bellows) states 100 kPa: its FEM has an inflation limit point
between 105 and 115 kPa (neo-Hookean wall, coarse mesh — no equilibrium beyond it; the Newton solve fails
there after many load-step cut-backs), so a design reaching 120 kPa would spend minutes on cases that
cannot converge.

:func:`load_design` takes such a file or a preset name (:data:`PRESETS`) and returns
``(BellowsGeometry, Material)``; :func:`design_to_toml` writes one back in SI units (read back unchanged).
"""

from __future__ import annotations

import pathlib

from ancf.errors import ConfigError
from ancf.params import _parse_table

try:  # Python >= 3.11
    import tomllib
except ModuleNotFoundError:  # pragma: no cover
    import tomli as tomllib

__all__ = ["load_design", "design_to_toml", "design_limits", "PRESETS", "DEFAULT_LIMITS"]

GEOMETRY_FIELDS = {"name": None, "description": None, "length": "length", "n_convolutions": None,
                   "root_radius": "length", "crest_radius": "length", "wall_thickness": "length",
                   "collar_length": "length", "tendon_radius": "length", "tendon_angles": "angle",
                   "cap_mass": "mass", "cap_com_offset": "length", "tip_offset": "length"}
MATERIAL_FIELDS = {"model": None, "mu": "modulus", "kappa": "modulus", "c10": "modulus", "c01": "modulus",
                   "density": "density", "formulation": None}


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
    out = dict(DEFAULT_LIMITS, **_parse_table(dict(lim), LIMIT_FIELDS, f"{source}[limits]"))
    for k, v in out.items():
        if isinstance(v, (str, bool)) or not (v > 0):
            raise ConfigError(f"{source}[limits]: {k} must be a positive number, got {v!r}")
    return out


def _read(source) -> dict:
    path = pathlib.Path(source)
    if path.suffix.lower() != ".toml":
        raise ConfigError(f"design {source!r} is neither a preset ({', '.join(PRESETS)}) nor a .toml file")
    try:
        return tomllib.loads(path.read_text())
    except OSError as exc:
        raise ConfigError(f"cannot read design file {path}: {exc.strerror or exc}") from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{path}: not valid TOML: {exc}") from None


def load_design(source):
    """``(BellowsGeometry, Material)`` from a preset name or a design TOML file (module docstring)."""
    from fem_reference import BellowsGeometry, Material
    if isinstance(source, str) and source in PRESETS:
        return _presets()[source]()
    path = pathlib.Path(source)
    raw = _read(source)
    design_limits(source)                      # the optional [limits] table is checked here too
    raw.pop("limits", None)
    mat_raw = raw.pop("material", None)
    if not isinstance(mat_raw, dict):
        raise ConfigError(f"{path}: missing [material] table")
    g = _parse_table(raw, GEOMETRY_FIELDS, str(path))
    m = _parse_table(mat_raw, MATERIAL_FIELDS, f"{path}[material]")
    for k in ("name", "description"):
        g.pop(k, None)
    if "tendon_angles" in g:
        g["tendon_angles"] = tuple(g["tendon_angles"])
    if "n_convolutions" in g and (isinstance(g["n_convolutions"], bool) or not isinstance(g["n_convolutions"], int)):
        raise ConfigError(f"{path}: n_convolutions must be an integer, got {g['n_convolutions']!r}")
    missing = [k for k in ("length", "n_convolutions", "root_radius", "crest_radius", "wall_thickness") if k not in g]
    if missing:
        raise ConfigError(f"{path}: missing {', '.join(missing)} (with units, e.g. length_mm)")
    for k, v in g.items():
        if isinstance(v, (str, bool)):
            raise ConfigError(f"{path}: {k} must be a number, got {v!r}")
    geometry = BellowsGeometry(**g)
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
            raise ConfigError(f"{path}[material]: model must be 'neo_hookean' or 'mooney_rivlin', got {model!r}")
    except KeyError as exc:
        raise ConfigError(f"{path}[material]: missing {exc.args[0]} (with a unit, e.g. {exc.args[0]}_MPa)") from None
    except TypeError as exc:
        raise ConfigError(f"{path}[material]: {exc}") from None
    if m:
        raise ConfigError(f"{path}[material]: keys {sorted(m)} do not apply to model '{model}'")
    return geometry, material


def design_to_toml(geometry, material, name: str = "bellows", limits: dict | None = None) -> str:
    """The design as TOML in the format of :func:`load_design`, in SI units (m, kg, rad, Pa) so that it reads
    back exactly; ``limits`` ({"tension_max": N, "pressure_max": Pa}) adds the [limits] table."""
    g = geometry
    lines = [f'name = "{name}"', f"length_m = {g.length!r}", f"n_convolutions = {int(g.n_convolutions)}",
             f"root_radius_m = {g.root_radius!r}", f"crest_radius_m = {g.crest_radius!r}",
             f"wall_thickness_m = {g.wall_thickness!r}", f"collar_length_m = {g.collar_length!r}",
             f"tendon_radius_m = {g.tendon_radius!r}", f"tendon_angles_rad = {list(g.tendon_angles)!r}",
             f"cap_mass_kg = {g.cap_mass!r}", f"cap_com_offset_m = {g.cap_com_offset!r}",
             f"tip_offset_m = {g.tip_offset!r}", "", "[material]"]
    if material.c01:
        lines += ['model = "mooney_rivlin"', f"c10_Pa = {material.mu / 2 - material.c01!r}", f"c01_Pa = {material.c01!r}"]
    else:
        lines += ['model = "neo_hookean"', f"mu_Pa = {material.mu!r}", f'formulation = "{material.formulation}"']
    lines += [f"kappa_Pa = {material.kappa!r}", f"density_kg_per_m3 = {material.density!r}"]
    if limits:
        lines += ["", "[limits]", f"tension_max_N = {float(limits['tension_max'])!r}",
                  f"pressure_max_Pa = {float(limits['pressure_max'])!r}"]
    return "\n".join(lines) + "\n"
