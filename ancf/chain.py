"""A multi-segment actuator: a chain of bellows segments joined by rigid intermediate caps (docs/multisegment.md).

:class:`ChainParams` is one immutable, validated description: ``segments`` (each a full
:class:`~ancf.params.ActuatorParams`: its bellows, its chamber with its own pressure limits, its tendons anchored
at its own distal cap, its element count) and ``caps`` (one :class:`Cap` between consecutive segments: mass [kg],
length [m] along the axis, centre-of-mass offset [m] from the proximal segment's end).  Tendons are numbered
segment by segment (segment 1's first); a tendon of segment k runs through the routing of segments 1 … k at its
own distance and angle, so every tendon passes segment 1 and all their angles must differ.

Rules a chain adds to those of each segment (:class:`~ancf.errors.ConfigError` naming the key otherwise):

* the frame and gravity (``base_axis``, ``reference_direction``, ``gravity``) are the chain's: one value, at the
  top of a chain file, the same in every segment;
* only segment 1 may have ``free_base_stretch`` (the others start at a cap, ``junction_stretch``);
* ``tip_mass``, ``tool_offset`` and ``shear_compliance`` belong to the distal segment (an inner segment's end is
  a cap: its mass and length are the cap's);
* tendon angles of the whole chain at least 1° apart (every tendon passes segment 1).

TOML: a file without ``[[segment]]`` tables is today's actuator file and loads as ``ActuatorParams``
(:func:`load_actuator`); a chain file has top-level ``name``, ``description``, ``junction_stretch``, the frame
keys, then ``[[segment]]`` tables (each an actuator table without the frame keys, with ``[segment.stiffness]``
and ``[[segment.tendons]]``) and ``[[cap]]`` tables (``mass_…``, ``length_…``, ``mass_offset_…``).
"""

from __future__ import annotations

import difflib
import math
import pathlib

from pydantic import BaseModel, ConfigDict, field_validator, model_validator

try:  # Python >= 3.11
    import tomllib
except ModuleNotFoundError:  # pragma: no cover
    import tomli as tomllib

from .errors import ConfigError
from .params import (
    TENDON_SEPARATION_MIN,
    UNITS,
    ActuatorParams,
    _located,
    _parse_table,
    _pydantic_init,
    _real_number,
    _short,
    _toml_string,
)

#: segments a chain may have
SEGMENTS_MIN, SEGMENTS_MAX = 1, 8
#: junction rules: "free" — segment k+1's base slope has the direction of segment k's end tangent and its own
#: stretch (a free coordinate); "continuous" — it equals segment k's end slope (stretch continuous across the cap)
JUNCTION_STRETCH = ("free", "continuous")
#: the chain's keys (top level of a chain file; SI dimension or None)
CHAIN_FIELDS = {"name": None, "description": None, "junction_stretch": None, "base_axis": "dimensionless",
                "reference_direction": "dimensionless", "gravity": "acceleration"}
#: the fields of a [[cap]] table
CAP_FIELDS = {"mass": "mass", "length": "length", "mass_offset": "length"}
#: plausible cap values (SI): mass 0 … 10 kg, length 0 … 1 m
CAP_MASS_MAX, CAP_LENGTH_MAX = 10.0, 1.0
#: segment fields that only the distal segment may set (an inner segment's end is a cap)
DISTAL_ONLY = ("tip_mass", "tool_offset", "shear_compliance")
FRAME_KEYS = ("base_axis", "reference_direction", "gravity")


class Cap(BaseModel):
    """A rigid intermediate cap between segment k and k + 1: ``mass`` [kg], ``length`` [m] along the end tangent
    of segment k (segment k + 1 starts at r_k(L_k) + length t_k), ``mass_offset`` [m] of its centre of mass along
    that tangent (0 … length; default length/2)."""

    model_config = ConfigDict(frozen=True, extra="forbid")
    mass: float = 0.0
    length: float = 0.0
    mass_offset: float | None = None

    def __init__(self, **data):
        _pydantic_init(super().__init__, data, "invalid cap")

    @field_validator("mass", "length", "mass_offset", mode="before")
    @classmethod
    def _real(cls, v, info):
        return v if v is None else _real_number(v, info.field_name)

    @field_validator("mass", "length", "mass_offset")
    @classmethod
    def _range(cls, v, info):
        hi = CAP_MASS_MAX if info.field_name == "mass" else CAP_LENGTH_MAX
        unit = "kg" if info.field_name == "mass" else "m"
        if v is not None and not (math.isfinite(v) and 0.0 <= v <= hi):
            raise ValueError(f"{info.field_name} = {v!r} {unit} must be within 0 … {hi:g} {unit} (SI units in the "
                             "Python API)")
        return v

    @model_validator(mode="after")
    def _offset(self):
        if self.mass_offset is None:
            object.__setattr__(self, "mass_offset", self.length / 2)
        elif self.mass_offset > self.length:
            raise ValueError(f"mass_offset = {self.mass_offset:g} m must be within the cap's length "
                             f"0 … {self.length:g} m")
        return self


class ChainParams(BaseModel):
    """A chain of segments (module docstring).  ``segments`` (K,) ActuatorParams, ``caps`` (K − 1,) Cap,
    ``junction_stretch`` one of :data:`JUNCTION_STRETCH`."""

    model_config = ConfigDict(frozen=True, extra="forbid")
    name: str = "chain"
    description: str = ""
    segments: tuple[ActuatorParams, ...]
    caps: tuple[Cap, ...] = ()
    junction_stretch: str = "free"

    def __init__(self, **data):
        _pydantic_init(super().__init__, data, "invalid chain")

    @field_validator("segments")
    @classmethod
    def _count(cls, v):
        if not SEGMENTS_MIN <= len(v) <= SEGMENTS_MAX:
            raise ValueError(f"a chain has {SEGMENTS_MIN} … {SEGMENTS_MAX} segments, got {len(v)}")
        return v

    @field_validator("junction_stretch")
    @classmethod
    def _junction(cls, v):
        if v not in JUNCTION_STRETCH:
            raise ValueError(f"junction_stretch must be one of {', '.join(JUNCTION_STRETCH)}, got {v!r}")
        return v

    @model_validator(mode="after")
    def _rules(self):
        segs = self.segments
        if len(self.caps) != len(segs) - 1:
            raise ValueError(f"{len(segs)} segments need {len(segs) - 1} caps, got {len(self.caps)}")
        for k, s in enumerate(segs):
            for key in FRAME_KEYS:
                if getattr(s, key) != getattr(segs[0], key):
                    raise ValueError(f"segment {k + 1}: {key} {getattr(s, key)} differs from segment 1's "
                                     f"{getattr(segs[0], key)}; the frame and gravity are the chain's")
            if k > 0 and s.free_base_stretch:
                raise ValueError(f"segment {k + 1}: free_base_stretch applies to segment 1 only (segment "
                                 f"{k + 1} starts at a cap: junction_stretch)")
            for key in DISTAL_ONLY if k < len(segs) - 1 else ():
                if getattr(s, key):
                    raise ValueError(f"segment {k + 1}: {key} must be unset for an inner segment (its end is a "
                                     "cap: [[cap]] mass, length; only the distal segment has a tool)")
        _check_angles(segs)
        return self

    # ----------------------------------------------------------------------------- derived quantities
    @property
    def n_segments(self) -> int:
        return len(self.segments)

    @property
    def n_tendons(self) -> int:
        """All tendons of the chain (segment 1's first)."""
        return sum(s.n_tendons for s in self.segments)

    @property
    def tendon_segment(self) -> tuple[int, ...]:
        """(m,) index of the segment whose distal cap anchors each tendon (0-based)."""
        return tuple(k for k, s in enumerate(self.segments) for _ in s.tendons)

    @property
    def length(self) -> float:
        """Undeformed length of the chain: segments plus caps [m] (the distal tool offset excluded)."""
        return sum(s.length for s in self.segments) + sum(c.length for c in self.caps)

    def to_toml(self) -> str:
        """The chain file format (module docstring), SI units spelled out; reads back to an equal object."""
        s0 = self.segments[0]
        lines = [f"name = {_toml_string(self.name)}"]
        if self.description:
            lines.append(f"description = {_toml_string(self.description)}")
        lines += [f"junction_stretch = {_toml_string(self.junction_stretch)}", f"base_axis = {list(s0.base_axis)}",
                  f"reference_direction = {list(s0.reference_direction)}", f"gravity_m_per_s2 = {list(s0.gravity)}"]
        for s in self.segments:
            lines += ["", "[[segment]]", *_segment_lines(s)]
        for c in self.caps:
            lines += ["", "[[cap]]", f"mass_kg = {c.mass!r}", f"length_m = {c.length!r}",
                      f"mass_offset_m = {c.mass_offset!r}"]
        return "\n".join(lines) + "\n"

    @classmethod
    def from_toml(cls, path) -> ChainParams:
        """A chain file (module docstring); a one-segment actuator file of today's format is accepted too (a chain
        of that one segment)."""
        out = load_actuator(path)
        return out if isinstance(out, ChainParams) else cls(name=out.name, segments=(out,))

    @classmethod
    def from_toml_string(cls, text: str, where: str = "<string>") -> ChainParams:
        out = load_actuator_string(text, where)
        return out if isinstance(out, ChainParams) else cls(name=out.name, segments=(out,))

    def _repr_args(self) -> str:
        return f"{self.name!r}, {self.n_segments} segments, {self.n_tendons} tendons"


def _check_angles(segs) -> None:
    """ValueError when two tendons of the chain are less than 1° apart about the axis (all pass segment 1)."""
    flat = [(k, i, t.angle) for k, s in enumerate(segs) for i, t in enumerate(s.tendons)]
    for a in range(len(flat)):
        for b in range(a):
            gap = abs(math.remainder(flat[a][2] - flat[b][2], 2 * math.pi))
            if gap < TENDON_SEPARATION_MIN:
                (kb, ib, _), (ka, ia, _) = flat[b], flat[a]
                raise ValueError(f"segment {kb + 1} tendon {ib + 1} and segment {ka + 1} tendon {ia + 1} are at the "
                                 f"same angle about the axis ({math.degrees(gap):.3g}° apart); every tendon runs "
                                 f"through segment 1, so tendon angles must be at least "
                                 f"{math.degrees(TENDON_SEPARATION_MIN):g}° apart over the whole chain")


def _segment_lines(s: ActuatorParams) -> list[str]:
    """A segment's [[segment]] table body: its actuator TOML without the chain's keys, tables renamed."""
    out = []
    for line in s.to_toml().splitlines():
        key = line.split("=", 1)[0].strip()
        if key in ("base_axis", "reference_direction", "gravity_m_per_s2"):
            continue
        out.append({"[stiffness]": "[segment.stiffness]", "[[tendons]]": "[[segment.tendons]]"}.get(line, line))
    return out


# ------------------------------------------------------------------------------------------------- loading
def load_actuator(path) -> ActuatorParams | ChainParams:
    """An actuator file: ``ActuatorParams`` for today's format, ``ChainParams`` for a file with [[segment]]
    tables (ConfigError naming the file otherwise)."""
    path = pathlib.Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"cannot read actuator file {path}: {exc}") from None
    return load_actuator_string(text, str(path))


def load_actuator_string(text: str, where: str = "<string>") -> ActuatorParams | ChainParams:
    """:func:`load_actuator` of a TOML text (``where`` names it in errors)."""
    try:
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{where}: not valid TOML: {exc}") from None
    if "segment" not in raw:
        if "cap" in raw:
            raise ConfigError(f"{where}: [[cap]] tables need [[segment]] tables (a chain file)")
        return ActuatorParams.from_toml_string(text, where)
    return _chain_from_raw(dict(raw), where)


def _chain_from_raw(raw: dict, where: str) -> ChainParams:
    segs, caps = raw.pop("segment"), raw.pop("cap", [])
    for key, v in (("segment", segs), ("cap", caps)):
        if not isinstance(v, list) or not all(isinstance(t, dict) for t in v):
            raise ConfigError(f"{where}: '{key}' must be [[{key}]] tables, got {_short(v)}")
    if not SEGMENTS_MIN <= len(segs) <= SEGMENTS_MAX:
        raise ConfigError(f"{where}: {len(segs)} [[segment]] tables; a chain has {SEGMENTS_MIN} … {SEGMENTS_MAX}")
    if len(caps) != len(segs) - 1:
        raise ConfigError(f"{where}: {len(segs)} [[segment]] tables need {len(segs) - 1} [[cap]] tables (one "
                          f"between consecutive segments), got {len(caps)}")
    top = _parse_table(raw, CHAIN_FIELDS, where)
    for k in ("name", "description", "junction_stretch"):
        if k in top and not isinstance(top[k], str):
            raise ConfigError(f"{where}.{k}: expected text in quotes, got {_short(top[k])}")
    frame_lines = [_frame_line(raw, key) for key in raw if key not in ("name", "description", "junction_stretch")]
    segments = tuple(_segment(t, k, frame_lines, top.get("name", "chain"), where) for k, t in enumerate(segs))
    cap_objs = tuple(_cap(t, k, where) for k, t in enumerate(caps))
    chain = {k: top[k] for k in ("name", "description", "junction_stretch") if k in top}
    try:
        return ChainParams(segments=segments, caps=cap_objs, **chain)
    except ConfigError as exc:
        raise ConfigError(_located(str(exc), where)) from None


def _frame_line(raw: dict, key: str) -> str:
    """The TOML line of one chain frame key (already checked by :func:`_parse_table`), for every segment."""
    return f"{key} = {_toml_value(raw[key])}"


def _segment(table: dict, k: int, frame_lines: list[str], chain_name: str, where: str) -> ActuatorParams:
    """Segment ``k``'s ActuatorParams from its [[segment]] table, with the chain's frame keys."""
    here = f"{where}[[segment]][{k}]"
    for key in table:
        if key.split("_m_per")[0] in FRAME_KEYS or key in FRAME_KEYS:
            raise ConfigError(f"{here}: '{key}' is the chain's: write it once at the top of the file")
    body = {key: v for key, v in table.items() if key not in ("stiffness", "tendons")}
    body.setdefault("name", f"{chain_name}/segment{k + 1}")
    stiff, tendons = table.get("stiffness"), table.get("tendons")
    if stiff is not None and not isinstance(stiff, dict):
        raise ConfigError(f"{here}: 'stiffness' must be a table ([segment.stiffness]), got {_short(stiff)}")
    if tendons is not None and not (isinstance(tendons, list) and all(isinstance(t, dict) for t in tendons)):
        raise ConfigError(f"{here}: 'tendons' must be [[segment.tendons]] tables, got {_short(tendons)}")
    try:
        lines = [*_lines(body, here), *frame_lines]
        if stiff is not None:
            lines += ["[stiffness]", *_lines(stiff, f"{here}[segment.stiffness]")]
        for i, t in enumerate(tendons or ()):
            lines += ["[[tendons]]", *_lines(t, f"{here}[[segment.tendons]][{i}]")]
        return ActuatorParams.from_toml_string("\n".join(lines) + "\n", here)
    except ConfigError as exc:
        raise ConfigError(_located(str(exc).replace("[[tendons]]", "[[segment.tendons]]")
                                   .replace("[stiffness]", "[segment.stiffness]"), here)) from None


def _cap(table: dict, k: int, where: str) -> Cap:
    """Cap ``k`` from its [[cap]] table: every key a field of :data:`CAP_FIELDS` with a unit of its dimension."""
    here = f"{where}[[cap]][{k}]"
    spellings = {f"{f}_{u}": (f, fac) for f, dim in CAP_FIELDS.items() for u, fac in UNITS[dim].items()}
    out = {}
    for key, value in table.items():
        if key in CAP_FIELDS:
            raise ConfigError(f"{here}: '{key}' needs an explicit unit; write one of: "
                              f"{', '.join(s for s in spellings if spellings[s][0] == key)}")
        if key not in spellings:
            close = difflib.get_close_matches(key, list(spellings), n=3, cutoff=0.5)
            raise ConfigError(f"{here}: unknown key '{key}'" + (f"; did you mean {', '.join(close)}?" if close else ""))
        f, fac = spellings[key]
        if f in out:
            raise ConfigError(f"{here}: '{f}' given twice (e.g. in two units)")
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(f"{here}.{key}: expected a number without quotes, got {_short(value)}")
        out[f] = float(value) * fac
    try:
        return Cap(**out)
    except ConfigError as exc:
        raise ConfigError(_located(str(exc), here)) from None


def _lines(table: dict, where: str) -> list[str]:
    """``key = value`` TOML lines of a table of plain values (ConfigError naming the key for a nested table)."""
    out = []
    for key, v in table.items():
        if isinstance(v, dict) or (isinstance(v, list) and any(isinstance(x, (dict, list)) for x in v)):
            raise ConfigError(f"{where}.{key}: expected a number, text or a list of numbers, got {_short(v)}")
        bare = key.replace("_", "").replace("-", "").isalnum() and key.isascii()
        out.append(f"{key if bare else _toml_string(key)} = {_toml_value(v)}")
    return out


def _toml_value(v) -> str:
    """A TOML literal of a value tomllib returned (text, boolean, number, list of them)."""
    if isinstance(v, str):
        return _toml_string(v)
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(v)
    if isinstance(v, list):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    raise ConfigError(f"expected a number, text or a list, got {_short(v)}")
