r"""An identification experiment for a rig: which static states to measure, chosen by the information they add.

A control log holds the states a controller happened to reach (one target, one pressure: it determines
nothing, :mod:`validation.identification.information`).  This module designs the states a rig should be driven
through so that :func:`validation.identification.identify.from_measurements` can identify the actuator;
:mod:`validation.identification.experiment_run` drives a rig through them.

Candidate grid (the actuator's own range: tension limits T_min … T_max of its file, pressures 0 … p_max), at
every pressure p ∈ {0, ¼, ½, ¾, 1} p_max and every known tip load:

* no tension (pressure alone, the tendons slack);
* each tendon alone at T_min + f (T_max − T_min), f ∈ {0.35, 0.7, 1};
* each pair of neighbouring tendons at f = 0.6;
* all tendons equal at f ∈ {0.3, 0.65, 1}.

Known tip loads are masses hung at the tip (``masses_kg``; the force m g along the actuator's gravity vector;
default none: only 0).  Every candidate is measured under gravity (the actuator's weight from the actuator file
acts, as in ``from_measurements``).

Selection: the fit's scaled sensitivities J_i (3 × n) of each candidate's tip at the form's start θ₀ (the
base actuator's law, :func:`validation.identification.identify.initial_theta`, as ``from_measurements`` starts)
and greedy D-optimality on M = Σ J_iᵀ J_i (:func:`validation.identification.design_select.sensitivities`,
:func:`~validation.identification.design_select.d_optimal`; module docstring there).  A candidate without a
verified equilibrium at θ₀, or none of the base actuator itself, or tendon lengths outside the rig's travel (whose lengths the rig is sent), is left
out (measured: all tendons at 5 N at 0 kPa buckle the ``paper`` preset under its weight, not its law at θ₀); so
is one it does not hold with its tensions and tip load × :data:`LOAD_MARGIN` (near a limit point, where a plant or
an identified law a few % softer has no equilibrium: measured, equal 3.25 N at 0 kPa with 50 g hung on the
``--mismatch`` plant).

Form: by default the one ``identify --measurements`` needs most — the richest of its forms whose parameters the
candidates can carry information on: ``pressure_ei_shear`` (its shear compliance is seen only through a tip
force) when masses are hung, otherwise ``pressure_ei_ea``.

Order on the rig: grouped by the hung mass (ascending: the operator hangs each mass once), then by pressure
(ascending), then by the total tension (ascending) — small moves between neighbouring states.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Optional, Sequence

import numpy as np

from ancf import ActuatorParams
from ancf.errors import BellowsError, InputError

from validation.identification.design_select import d_optimal, sensitivities
from validation.identification.forms import FORMS, get_form
from validation.reference.experiments import LoadCase

__all__ = ["ExperimentState", "ExperimentPlan", "candidate_states", "design_experiment", "default_form",
           "logdet_information", "rig_order", "PRESSURE_FRACTIONS", "DEFAULT_STATES", "MASS_MAX_KG"]

#: pressure levels of the grid [fractions of p_max]
PRESSURE_FRACTIONS = (0.0, 0.25, 0.5, 0.75, 1.0)
#: one tendon alone, pairs, all equal [fractions of the tension range]
SINGLE_FRACTIONS = (0.35, 0.7, 1.0)
PAIR_FRACTION = 0.6
EQUAL_FRACTIONS = (0.3, 0.65, 1.0)
#: states of an experiment unless asked otherwise
DEFAULT_STATES = 40
#: extra length a tendon designed slack is given on the rig [m] (it stays slack on a plant that differs)
SLACK_MARGIN = 2e-3
#: a candidate is kept only if the base actuator also holds its tensions and tip load × this factor
LOAD_MARGIN = 1.25
#: heaviest mass hung at the tip [kg]
MASS_MAX_KG = 1.0


@dataclass(frozen=True)
class ExperimentState:
    """One designed state (SI): ``tensions`` (m,) [N], ``pressure`` [Pa], ``mass`` [kg] hung at the tip and its
    force ``tip_force`` (3,) [N], ``label`` (the state's id in the run log)."""
    tensions: tuple
    pressure: float
    mass: float
    tip_force: tuple
    label: str

    def to_dict(self) -> dict:
        return {"tensions_N": list(self.tensions), "pressure_Pa": self.pressure, "mass_kg": self.mass,
                "tip_force_N": list(self.tip_force), "label": self.label}

    @classmethod
    def from_dict(cls, d: dict) -> "ExperimentState":
        return cls(tuple(float(t) for t in d["tensions_N"]), float(d["pressure_Pa"]), float(d["mass_kg"]),
                   tuple(float(f) for f in d["tip_force_N"]), str(d["label"]))


@dataclass
class ExperimentPlan:
    """The designed experiment: ``states`` in the order to run them, the ``form`` it was chosen for, the log-det
    information of the chosen set [scaled units] (``logdet``), the candidates that had an equilibrium, the
    masses [kg] and the base actuator's parameters as TOML (``actuator_toml``)."""
    states: tuple
    form: str
    logdet: float
    n_candidates: int
    masses: tuple
    actuator_toml: str = field(default="", repr=False)

    def to_dict(self) -> dict:
        return {"form": self.form, "logdet": self.logdet, "n_candidates": self.n_candidates,
                "masses_kg": list(self.masses), "states": [s.to_dict() for s in self.states]}

    @classmethod
    def from_dict(cls, d: dict, actuator_toml: str = "") -> "ExperimentPlan":
        return cls(tuple(ExperimentState.from_dict(s) for s in d["states"]), str(d["form"]), float(d["logdet"]),
                   int(d["n_candidates"]), tuple(float(m) for m in d["masses_kg"]), actuator_toml)


def _tension_patterns(m: int, lo: float, hi: float) -> list[tuple]:
    """The tension patterns of the module docstring [N] (m tendons, range lo … hi)."""
    at = lambda f: round(lo + f * (hi - lo), 3)                 # noqa: E731
    out = [tuple([0.0] * m)]
    for i in range(m):
        for f in SINGLE_FRACTIONS:
            T = [0.0] * m
            T[i] = at(f)
            out.append(tuple(T))
    if m > 2:
        for i in range(m):
            T = [0.0] * m
            T[i] = T[(i + 1) % m] = at(PAIR_FRACTION)
            out.append(tuple(T))
    out += [tuple([at(f)] * m) for f in EQUAL_FRACTIONS]
    return list(dict.fromkeys(out))


def _check_masses(masses_kg: Sequence[float], base: ActuatorParams) -> tuple:
    masses = tuple(float(x) for x in masses_kg) if masses_kg else (0.0,)
    if any(not (math.isfinite(x) and 0 <= x <= MASS_MAX_KG) for x in masses):
        raise InputError(f"masses must be in [0, {MASS_MAX_KG * 1e3:g}] g, got {[x * 1e3 for x in masses]} g")
    if len(set(masses)) != len(masses):
        raise InputError(f"masses must be distinct, got {[x * 1e3 for x in masses]} g")
    if any(x > 0 for x in masses) and not np.any(base.gravity):
        raise InputError(f"actuator {base.name!r} has no gravity: a hung mass would load nothing")
    return tuple(sorted(masses))


def candidate_states(base: ActuatorParams, masses_kg: Sequence[float] = ()) -> list[LoadCase]:
    """The candidate grid (module docstring) as load cases under gravity, for ``base``'s range; ``masses_kg``:
    the masses that can be hung at the tip [kg] (default: none).  ``experiment`` holds the mass in grams."""
    masses = _check_masses(masses_kg, base)
    g = np.asarray(base.gravity, float)
    out = []
    for mass in masses:
        F = tuple(float(v) for v in np.round(mass * g, 6))
        for fp in PRESSURE_FRACTIONS:
            p = round(fp * base.pressure_max, -2)
            for T in _tension_patterns(base.n_tendons, base.tension_min, base.tension_max):
                out.append(LoadCase(T, p, F, True, f"{mass * 1e3:g} g", "train",
                                    f"T=({', '.join(f'{t:g}' for t in T)}) N p={p / 1e3:g} kPa m={mass * 1e3:g} g"))
    return out


def default_form(masses_kg: Sequence[float] = ()) -> str:
    """The form an experiment is designed for by default (module docstring)."""
    return "pressure_ei_shear" if any(m > 0 for m in masses_kg) else "pressure_ei_ea"


def logdet_information(J: np.ndarray, index: Optional[Sequence[int]] = None) -> float:
    """log det Σ_{i ∈ index} J_iᵀ J_i of sensitivities ``J`` (N, r, n) (all rows without ``index``); −inf when
    the information is singular."""
    J = np.asarray(J, float)
    sel = J if index is None else J[list(index)]
    sign, ld = np.linalg.slogdet(np.einsum("irn,irm->nm", sel, sel))
    return float(ld) if sign > 0 else -math.inf


def candidate_sensitivities(form, cases: Sequence[LoadCase], base: ActuatorParams, theta0,
                            travel: Optional[tuple] = None) -> tuple:
    """(the cases with an equilibrium both at θ₀ and of ``base`` itself — the model that commands the rig —
    whose tendon lengths lie within ``travel`` (lo, hi) [m] (a slack tendon's with :data:`SLACK_MARGIN` more),
    their scaled sensitivities (N, 3, n))."""
    from ancf import Model
    model = Model(base)
    ok, J = [], []
    for c in cases:
        try:
            eq = model.fk(c.tensions, c.pressure, c.tip_force)
            # away from a limit point (buckling): a plant or a fitted law a little softer must hold it too
            model.fk(LOAD_MARGIN * np.asarray(c.tensions), c.pressure, LOAD_MARGIN * np.asarray(c.tip_force),
                     check_limits=False)
            if travel is not None:
                ln = np.asarray(eq.tendon_lengths) + np.where(np.asarray(c.tensions) > 0, 0.0, SLACK_MARGIN)
                if np.any(ln < travel[0]) or np.any(ln > travel[1]):
                    continue
            J.append(sensitivities(form, [c], base, theta0)[0])
            ok.append(c)
        except BellowsError:
            continue
    return ok, np.array(J)


def rig_order(cases: Sequence[LoadCase]) -> list[LoadCase]:
    """The order to run ``cases`` on a rig: by hung mass (the force's size), pressure, total tension."""
    return sorted(cases, key=lambda c: (round(float(np.linalg.norm(c.tip_force)), 9), c.pressure, sum(c.tensions),
                                        c.tensions))


def design_experiment(base: ActuatorParams, n_states: int = DEFAULT_STATES, *, form: Optional[str] = None,
                      masses_kg: Sequence[float] = (), travel: Optional[tuple] = None) -> ExperimentPlan:
    """The D-optimal experiment of ``n_states`` states for ``form`` (default :func:`default_form`) on the
    actuator ``base`` with the masses ``masses_kg`` [kg] that can be hung at the tip (module docstring);
    ``travel``: the rig's tendon travel (lo, hi) [m] — candidates whose lengths leave it are left out."""
    from validation.identification.identify import initial_theta
    if not isinstance(base, ActuatorParams):
        raise InputError(f"base must be ActuatorParams, got {type(base).__name__}")
    masses = _check_masses(masses_kg, base)
    name = default_form(masses) if form is None else form
    if name not in FORMS:
        raise InputError(f"unknown model form {name!r}; choose from {', '.join(FORMS)}")
    fm = get_form(name)
    cases = candidate_states(base, masses)
    if isinstance(n_states, bool) or not isinstance(n_states, (int, np.integer)) or not fm.n <= n_states:
        raise InputError(f"n_states must be an integer >= {fm.n} (the parameters of form {name}), got {n_states!r}")
    ok, J = candidate_sensitivities(fm, cases, base, initial_theta(fm, None, base), travel)
    if len(ok) < n_states:
        raise InputError(f"only {len(ok)} candidate states of actuator {base.name!r} have an equilibrium; "
                         f"{n_states} states asked for")
    chosen = d_optimal(J, int(n_states))
    ordered = rig_order([ok[i] for i in chosen])
    states = tuple(ExperimentState(c.tensions, c.pressure, round(float(c.experiment.split()[0]) * 1e-3, 9),
                                   c.tip_force, f"e{k:03d} {c.label}") for k, c in enumerate(ordered))
    return ExperimentPlan(states, name, logdet_information(J, chosen), len(ok), masses, base.to_toml())
