r"""Virtual experiments: the design of load cases used to identify and validate the reduced model.

A *design* is data — a list of :class:`LoadCase` records, each tagged with the experiment it belongs to
and whether it trains the fit or is held out for validation — not code buried in a loop.  The default
design (:func:`default_design`) is stated as fractions of the actuator's operating range so that it
scales to any actuator: tensions as fractions of ``T_max``, pressures as fractions of ``p_max``, lateral tip
forces in units of ``F_ref = T_max d / L`` (the tip force whose moment about the base equals that of one
tendon at full tension).  Materialised for the paper's range (``T_max = 5 N``, ``p_max = 120 kPa``,
``d = 27.5 mm``, ``L = 160 mm``: ``F_ref ≈ 0.86 N``; loads rounded to 0.01 N, 0.1 kPa and 1 mN):

=================  ==================================================  ========================================
experiment         training cases                                      what it determines
=================  ==================================================  ========================================
``axial``          equal tensions 0.2, 0.6, 1.0 T_max, p = 0            EA(λ) for λ < 1 (compression)
``pressure``       p = 0.25, 0.5, 0.75, 1.0 p_max, no tension            A_eff (D_eff) and EA(λ) for λ > 1
``combined``       (0.5 p_max, 0.8 T_max ×3), (p_max, T_max ×3),        separates k(λ) from A_eff: the same
                   (p_max, 0.4 T_max ×3)                                stretch reached by different loads
``bending``        T1 = 0.4, 1.0 T_max at p = 0; T1 = 0.8 T_max at       EI (D_a), with the tendon's own
                   0.5 p_max; T2 = 0.6 T_max at 0.25 p_max; T3 = 0.8     axial load; three tendon directions
                   T_max at p_max
``lateral``        F = −0.35 F_ref e_z, +0.35 F_ref e_y at p = 0;        EI under a tip force and the rotation-
                   +0.7 F_ref e_y at 0.5 p_max; −0.35 F_ref e_z at       free tip compliance s(p) beside the
                   0.75 p_max; −0.7 F_ref e_z at p_max                  tendon bends at the same pressures
=================  ==================================================  ========================================

Held out (never used in a fit): mixed states across the range — one and two tendons with pressure, a
tip load with a tendon, full-range combinations (see :data:`HELD_OUT`).  Both signs of axial strain are
covered (equal tensions shorten the actuator, pressure lengthens it).

**Gravity.**  The mounted actuator always carries its own weight, so the default design has states with gravity
on (the weight along the design's mounting, default horizontal: −z with the axis along +x) in both sets:
:data:`GRAVITY_TRAINING` (experiment ``gravity``: self-weight alone at 0 and p_max, and at 0.5 p_max against
0.6 T_max on the top tendon) and :data:`GRAVITY_HELD_OUT` (self-weight alone at 0.5 p_max; at 0.25 p_max with
0.5 T_max on the second tendon).  The reduced model takes the weight from the FEM design's wall and cap masses
(not fitted; :func:`validation.identification.identify.fem_masses`), so these states check the masses too.
Every other state is gravity-free (``gravity=True`` turns the weight on in all of them).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, replace
from typing import Iterable, Optional, Sequence

import numpy as np

from ancf.errors import InputError, check_finite

#: experiment name of held-out states outside the training hull (reported apart: validation.checks.compare;
#: chosen by validation.identification.design_select)
EXTRAPOLATION = "extrapolation"

__all__ = ["LoadCase", "Design", "default_design", "TRAINING", "HELD_OUT", "GRAVITY_TRAINING", "GRAVITY_HELD_OUT",
           "force_reference"]


@dataclass(frozen=True)
class LoadCase:
    """One static state to compute (SI units).

    tensions (m,) [N]; pressure [Pa]; tip_force (3,) [N] (dead load at the tip point, world frame);
    gravity: whether the actuator's weight acts; experiment: the experiment's name; role: "train" or
    "heldout"; label: a short human-readable name.
    """
    tensions: tuple
    pressure: float
    tip_force: tuple = (0.0, 0.0, 0.0)
    gravity: bool = False
    experiment: str = ""
    role: str = "train"
    label: str = ""

    def __post_init__(self):
        T = check_finite("LoadCase.tensions", self.tensions)
        if T.ndim != 1 or T.size < 1 or np.any(T < 0):
            raise InputError(f"LoadCase.tensions must be a list of tensions >= 0 N, got {self.tensions!r}")
        check_finite("LoadCase.pressure", self.pressure, ())
        check_finite("LoadCase.tip_force", self.tip_force, (3,))
        if self.role not in ("train", "heldout"):
            raise InputError(f"LoadCase.role must be 'train' or 'heldout', got {self.role!r}")
        object.__setattr__(self, "tensions", tuple(float(t) for t in T))
        object.__setattr__(self, "pressure", float(self.pressure))
        object.__setattr__(self, "tip_force", tuple(float(f) for f in self.tip_force))
        object.__setattr__(self, "gravity", bool(self.gravity))
        if not self.label:
            object.__setattr__(self, "label", self.describe())

    def describe(self) -> str:
        T = "/".join(f"{t:g}" for t in self.tensions)
        s = f"T={T} N, p={self.pressure / 1e3:g} kPa"
        if any(self.tip_force):
            s += ", F=(" + ",".join(f"{f:g}" for f in self.tip_force) + ") N"
        return s + (", gravity" if self.gravity else "")

    def to_dict(self) -> dict:
        d = asdict(self)
        d["tensions_N"] = list(d.pop("tensions"))
        d["pressure_Pa"] = d.pop("pressure")
        d["tip_force_N"] = list(d.pop("tip_force"))
        return d


@dataclass(frozen=True)
class _Spec:
    """A load case in fractions of the operating range: tensions/T_max, pressure/p_max, force/F_ref; gravity: the
    actuator's weight acts (along the design's mounting, :data:`validation.reference.designs.MOUNTINGS`)."""
    experiment: str
    tensions: tuple
    pressure: float
    force: tuple = (0.0, 0.0, 0.0)
    gravity: bool = False


#: Training cases of the default design (fractions of the range; see the module docstring).
TRAINING: tuple[_Spec, ...] = (
    _Spec("axial", (0.2, 0.2, 0.2), 0.0), _Spec("axial", (0.6, 0.6, 0.6), 0.0), _Spec("axial", (1.0, 1.0, 1.0), 0.0),
    _Spec("pressure", (0, 0, 0), 0.25), _Spec("pressure", (0, 0, 0), 0.5), _Spec("pressure", (0, 0, 0), 0.75),
    _Spec("pressure", (0, 0, 0), 1.0),
    _Spec("combined", (0.8, 0.8, 0.8), 0.5), _Spec("combined", (1.0, 1.0, 1.0), 1.0),
    _Spec("combined", (0.4, 0.4, 0.4), 1.0),
    _Spec("bending", (0.4, 0, 0), 0.0), _Spec("bending", (1.0, 0, 0), 0.0), _Spec("bending", (0.8, 0, 0), 0.5),
    _Spec("bending", (0, 0.6, 0), 0.25), _Spec("bending", (0, 0, 0.8), 1.0),
    _Spec("lateral", (0, 0, 0), 0.0, (0, 0, -0.35)), _Spec("lateral", (0, 0, 0), 0.0, (0, 0.35, 0)),
    _Spec("lateral", (0, 0, 0), 0.5, (0, 0.7, 0)), _Spec("lateral", (0, 0, 0), 0.75, (0, 0, -0.35)),
    _Spec("lateral", (0, 0, 0), 1.0, (0, 0, -0.7)),
)

#: Held-out cases of the default design.
HELD_OUT: tuple[_Spec, ...] = (
    _Spec("heldout", (0.6, 0, 0), 0.75), _Spec("heldout", (0, 0.4, 0.8), 0.375),
    _Spec("heldout", (0.8, 0.8, 0.8), 0.833), _Spec("heldout", (0.4, 0, 0), 0.25, (0, 0, -0.57)),
    _Spec("heldout", (0.2, 0.5, 0), 0.125), _Spec("heldout", (1.0, 1.0, 0), 1.0),
    _Spec("heldout", (0.5, 0.5, 0.5), 0.167), _Spec("heldout", (0, 0, 0.3), 0.625, (0, 0.3, 0)),
)


#: Training cases with the actuator's own weight (experiment ``gravity``): the self-weight sag alone at 0 and p_max
#: and against the top tendon — they check the masses taken from the FEM design and make the fit see the load the
#: mounted actuator always carries.
GRAVITY_TRAINING: tuple[_Spec, ...] = (
    _Spec("gravity", (0, 0, 0), 0.0, gravity=True), _Spec("gravity", (0, 0, 0), 1.0, gravity=True),
    _Spec("gravity", (0.6, 0, 0), 0.5, gravity=True),
)

#: Held-out cases with the actuator's own weight (experiment ``heldout``, gravity on).
GRAVITY_HELD_OUT: tuple[_Spec, ...] = (
    _Spec("heldout", (0, 0, 0), 0.5, gravity=True), _Spec("heldout", (0, 0.5, 0), 0.25, gravity=True),
)


def force_reference(tension_max: float, tendon_distance: float, length: float) -> float:
    """F_ref = T_max d / L [N]: the tip force with the base moment of one tendon at full tension."""
    return tension_max * tendon_distance / length


@dataclass(frozen=True)
class Design:
    """A list of load cases with their roles; ``training`` and ``heldout`` select by role."""
    cases: tuple
    description: str = ""
    meta: dict = field(default_factory=dict)

    @property
    def training(self) -> list[LoadCase]:
        return [c for c in self.cases if c.role == "train"]

    @property
    def heldout(self) -> list[LoadCase]:
        return [c for c in self.cases if c.role == "heldout"]

    def experiments(self) -> list[str]:
        return sorted({c.experiment for c in self.cases})

    def without(self, *experiments: str) -> "Design":
        """The same design without the named experiments (e.g. to test identifiability)."""
        return replace(self, cases=tuple(c for c in self.cases if c.experiment not in experiments))

    def to_dict(self) -> dict:
        return {"description": self.description, "meta": self.meta, "cases": [c.to_dict() for c in self.cases]}


def _materialise(specs: Iterable[_Spec], role: str, n_tendons: int, T_max: float, p_max: float, F_ref: float,
                 gravity: bool) -> list[LoadCase]:
    out = []
    for s in specs:
        T = np.zeros(n_tendons)
        T[:3] = np.asarray(s.tensions) * T_max
        # rounded to 0.01 N, 0.1 kPa and 1 mN: readable labels, reproducible cache keys
        out.append(LoadCase(tuple(np.round(T, 2)), round(s.pressure * p_max, -2),
                            tuple(np.round(np.asarray(s.force) * F_ref, 3)), gravity or s.gravity, s.experiment,
                            role))
    return out


def check_range(who: str, tension_max, pressure_max, tendon_distance, length, n_tendons) -> None:
    """InputError (naming ``who``) unless T_max [N], p_max [Pa], d [m] and L [m] are positive numbers and there
    are at least 3 tendons."""
    for nm, v in (("tension_max", tension_max), ("pressure_max", pressure_max),
                  ("tendon_distance", tendon_distance), ("length", length)):
        if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
            raise InputError(f"{who}: {nm} must be a positive number, got {v!r}")
    if n_tendons < 3:
        raise InputError(f"{who}: needs at least 3 tendons")


def default_design(*, tension_max: float = 5.0, pressure_max: float = 120e3, tendon_distance: float = 0.0275,
                   length: float = 0.16, n_tendons: int = 3, gravity: bool = False,
                   training: Optional[Sequence[_Spec]] = None, heldout: Optional[Sequence[_Spec]] = None,
                   self_weight: bool = True) -> Design:
    """The default design of virtual experiments for an actuator with the given operating range
    (T_max [N], p_max [Pa]), tendon routing distance d [m] and length L [m] (see the module docstring).
    ``training`` / ``heldout`` replace :data:`TRAINING` / :data:`HELD_OUT`; ``self_weight`` adds
    :data:`GRAVITY_TRAINING` and :data:`GRAVITY_HELD_OUT` (the actuator's weight along its mounting);
    ``gravity`` turns the weight on in every case."""
    check_range("default_design", tension_max, pressure_max, tendon_distance, length, n_tendons)
    F_ref = force_reference(tension_max, tendon_distance, length)
    train = tuple(TRAINING if training is None else training) + (GRAVITY_TRAINING if self_weight else ())
    held = tuple(HELD_OUT if heldout is None else heldout) + (GRAVITY_HELD_OUT if self_weight else ())
    cases = (_materialise(train, "train", n_tendons, tension_max, pressure_max, F_ref, gravity)
             + _materialise(held, "heldout", n_tendons, tension_max, pressure_max, F_ref, gravity))
    return Design(tuple(cases), "default design: axial, pressure, combined, bending, lateral and self-weight "
                  "experiments",
                  {"tension_max_N": tension_max, "pressure_max_Pa": pressure_max, "force_reference_N": F_ref})
