r"""Identify the reduced model's parameters (k(λ), D_a, D_eff, …) from the FEM or from rig data.

Protocol (``docs/identification.md``):

1. **Virtual experiments** on the FEM of the design (:mod:`validation.reference.experiments`: a list of load cases —
   equal tensions, pressure steps, combined pressure and tension, single-tendon bending, small lateral tip
   forces — in training and held-out roles), run in parallel and cached (:mod:`validation.reference.fem_sweep`).
   From rig data: the measured static states (:mod:`hardware.static_states`) take their place.
2. **First estimate** from closed forms: the equivalent rod of the unloaded FEM (condensed cap tangent:
   EA = L/C_uF, EI = L/C_θM, D_a = √(8 EI/EA), D_eff from the blocked pressure force); from rig data, the
   base actuator's values.
3. **Fit** of every candidate model form (:mod:`validation.identification.forms`) with the reduced model in the loop
   (:mod:`validation.identification.fit`): its tip positions and centreline points (markers at L/4, L/2, 3L/4) are matched
   to the training states; 95 % CIs, correlations and residuals per state; non-identifiable parameters
   reported as such.
4. **Model selection** on held-out states: each form predicts the held-out states it was not fitted to; the
   form with the smallest held-out RMS error wins, except that a simpler form (fewer parameters) is preferred
   when its held-out error is within 10 % of the best — evidence, not a default, sets the form.  From the FEM
   the held-out tip compliances (tensions held, tendons locked) count too: a form must be within 10 % of the best
   on the tip error and on the mean compliance error (a rotation-free tip compliance hardly moves the held-out
   tips of tendon bends but sets the locked compliance; docs/identification.md §4b).  A form that
   had too few states for its parameters (:data:`validation.identification.fit.MIN_SPARE_STATES`, ``MIN_DOF``) identified
   nothing and is chosen only when every form did.

``from_fem(geometry, material, …)`` and ``from_measurements(path, base=…)`` return an
:class:`IdentificationResult`: ``values`` / ``ci95`` / ``identifiable`` (keys ``a``, ``b``, ``EA``, ``EI``,
``D_a``, ``D_eff`` and, for the area forms, ``beta``), ``params`` (an :class:`ancf.ActuatorParams` ready
to use), ``to_toml(path)`` (loads unchanged with ``ActuatorParams.from_toml``) and ``save(path)`` (the fit data
as JSON: load cases, the FEM results used, every form's fit, versions and git revision).
"""

from __future__ import annotations

import json
import math
import pathlib
from dataclasses import dataclass, field
from typing import Any, Callable, Optional, Sequence

import numpy as np

from ancf import ActuatorParams
from ancf.errors import BellowsError, ConfigError, InputError
from ancf.export import to_jsonable
from ancf.outputs import atomic_write_text, prepare_output_file

from validation.reference.experiments import EXTRAPOLATION
from validation.reference.experiments import Design, default_design
from validation.identification.fit import FitResult, Observations, fit, predict
from validation.identification.forms import FORMS, REPORTED, get_form
from validation.infra.provenance import provenance

__all__ = ["IdentificationResult", "from_fem", "from_measurements", "identify", "fem_base_params",
           "observations_from_records", "observations_from_states", "MARKER_FRACTIONS", "PARSIMONY", "MASS_CHOICES"]

#: Markers used in the fit: centreline points at these fractions of the length.
MARKER_FRACTIONS = (0.25, 0.5, 0.75)
#: A simpler form wins when its held-out error is within this factor of the best form's.
PARSIMONY = 1.10
#: ``from_measurements(masses=…)``: the masses fitted (``free``) or held at the base actuator's (``base``).
MASS_CHOICES = ("free", "base")


# ---------------------------------------------------------------------------------------------- data
def observations_from_records(records, marker_s: Optional[Sequence[float]] = None) -> Observations:
    """Observations (tips and centreline markers) from FEM records (:class:`validation.reference.fem_sweep.FemRecord`)."""
    recs = list(records)
    bad = [r.case.label for r in recs if not r.ok]
    if bad:
        raise InputError(f"FEM solves failed for {len(bad)} load case(s): {bad[:3]}; fix or drop them first")
    ms = None if marker_s is None else np.asarray(marker_s, float)
    return Observations(
        tensions=np.array([r.case.tensions for r in recs]), pressure=np.array([r.case.pressure for r in recs]),
        tip_force=np.array([r.case.tip_force for r in recs]), gravity=np.array([r.case.gravity for r in recs]),
        tip=np.array([r.tip_position for r in recs]),
        markers=None if ms is None else np.array([r.centreline_at(ms) for r in recs]), marker_s=ms,
        labels=[r.case.label for r in recs])


def observations_from_states(states, gravity: bool = True) -> Observations:
    """Observations from measured static states (:class:`hardware.static_states.StaticStates`).  A state
    whose tip load is unknown (NaN) is an error for the fit: say which."""
    F = np.zeros((states.n_states, 3)) if states.tip_force is None else states.tip_force
    unknown = np.flatnonzero(np.any(np.isnan(F), axis=1))
    if unknown.size:
        raise InputError(f"static states {unknown[:5].tolist()} have an unknown tip load (NaN); the fit needs "
                         "the load of every state: drop them or state the load")
    labels = states.label or [f"state {i}" for i in range(states.n_states)]
    return Observations(states.tensions, states.pressure, F, np.full(states.n_states, bool(gravity)),
                        states.tip_position, states.tip_position_std, states.markers, states.marker_arclength,
                        states.markers_std, list(labels), tensions_std=states.tensions_std,
                        pressure_std=states.pressure_std, tip_force_std=states.tip_force_std)


def _geometry_meta(geometry) -> dict:
    """The geometry's fields for a result's metadata; a profile table is named by its file and data hash
    (:meth:`fem_reference.profile.TableProfile.describe`), not copied point by point."""
    meta = dict(vars(geometry))
    if getattr(geometry, "is_table", False):
        meta["profile"] = geometry.profile.describe()
    return meta


def describe_geometry(geometry) -> str:
    """What the FEM design is, in words: ``"straight tube"`` (zero convolution depth) or ``"8-convolution
    bellows"``."""
    if getattr(geometry, "is_straight", False):
        return "straight tube"
    return f"{geometry.n_convolutions}-convolution bellows"


def compile_fit_kernels() -> None:
    """Compile (first run) or load (later runs) every numba kernel of the ANCF model that the fits and the
    report use (:func:`ancf.cli.warm_up`, the same warm-up as ``bellows demo``'s).  :func:`from_fem` runs it in a
    background process while the FEM sweep leaves a core idle, so that the first run of a fresh install does
    not wait for the compiler (≈ 25 s of one core: docs/identification.md §Measured)."""
    from ancf.cli import warm_up
    warm_up()


def fem_masses(geometry, material) -> dict:
    """The FEM design's masses as the reduced model takes them (the FEM's own: its wall's weight is the density
    times the wall's volume, its cap's a point weight at the cap's centre of mass, fem_reference.loads.gravity):

    ``line_mass_kg_per_m`` = wall volume × density / L (:meth:`fem_reference.BellowsGeometry.wall_volume`, the wall
    spread evenly along the axis); ``tip_mass_kg`` = the cap's mass; ``tip_mass_offset_m`` = how far the cap's
    centre of mass lies beyond the tip point along the tip tangent (``cap_com_offset − tip_offset``).  The reduced
    model puts the tip mass at the tip point: the offset's share of the self-weight sag is < 1 %
    (docs/identification.md §Gravity)."""
    return {"line_mass_kg_per_m": float(geometry.wall_volume() * material.density / geometry.length),
            "tip_mass_kg": float(geometry.cap_mass),
            "tip_mass_offset_m": float(geometry.cap_com_offset - geometry.tip_offset)}


def fem_base_params(geometry, material, *, n_elements: int = 6, tension_max: float = 5.0,
                    pressure_max: float = 120e3, rod: Optional[dict] = None, name: str = "identified",
                    gravity=(0.0, 0.0, -9.81)) -> ActuatorParams:
    """Reduced-model parameters for the FEM design: its length, tendon routing and tip offset, the wall's line
    mass and the cap as tip mass (:func:`fem_masses`: known from the geometry and material, not fitted), the
    gravity vector (3,) [m/s²] of its mounting, and the stiffness of the closed-form equivalent rod ``rod``
    (``EA``, ``EI``, ``D_a``, ``D_eff``) as the starting point."""
    from ancf import StiffnessLaw
    from ancf.params import Tendon
    g = geometry
    EA = rod["EA"] if rod else 700.0
    EI = rod["EI"] if rod else 0.08
    D_eff = rod["D_eff"] if rod and rod.get("D_eff", 0) > 1e-4 else 0.02
    masses = fem_masses(g, material)
    return ActuatorParams(
        name=name, description=f"identified from the FEM of a {describe_geometry(g)}",
        length=g.length, n_elements=n_elements, stiffness=StiffnessLaw.constant(EA=EA, EI=EI), D_eff=D_eff,
        tendons=tuple(Tendon(distance=g.tendon_radius, angle=a) for a in g.tendon_angles),
        line_mass=masses["line_mass_kg_per_m"], tip_mass=masses["tip_mass_kg"], tool_offset=g.tip_offset,
        tension_max=tension_max, pressure_max=pressure_max, gravity=tuple(float(v) for v in gravity))


#: the weight is validated when every held-out state with gravity has a tip error within this share of the
#: length [%] (the paper's shape target, validation.checks.compare.SHAPE_TARGET_PCT)
GRAVITY_TOLERANCE_PCT = 2.5


def gravity_check(train_gravity, heldout_gravity, heldout_errors_m, length: float,
                  tolerance_pct: float = GRAVITY_TOLERANCE_PCT) -> dict:
    """Whether the identification validated the actuator's weight, and so whether its file may state gravity.

    train_gravity (N,) bool, heldout_gravity (K,) bool: which states had gravity; heldout_errors_m (K,) [m]: the
    held-out tip errors (None: no held-out states); length [m].  Returns ``{"status", "stated", "states",
    "max_tip_error_pct", "text"}`` with status ``"validated"`` (held-out states with gravity, each within
    ``tolerance_pct`` % of L: stated), ``"failed"`` (one is not, or is NaN: not stated), ``"trained"`` (no
    held-out state with gravity, but training states had it: the fit explained them with the weight acting —
    stated, and said to be not checked on held-out states) or ``"absent"`` (no state had gravity: not stated)."""
    hg = np.asarray(heldout_gravity if heldout_gravity is not None else [], bool).reshape(-1)
    err = np.asarray(heldout_errors_m if heldout_errors_m is not None else np.full(hg.size, np.nan), float)
    if err.shape != hg.shape:
        raise InputError(f"gravity_check: {err.size} held-out errors for {hg.size} held-out states")
    pct = 100.0 * err[hg] / float(length)
    worst = float(np.max(pct)) if pct.size and np.all(np.isfinite(pct)) else float("nan")
    if pct.size:
        ok = bool(np.all(np.isfinite(pct)) and np.all(pct <= tolerance_pct))
        status = "validated" if ok else "failed"
        text = (f"gravity {'validated' if ok else 'NOT VALIDATED'} on {pct.size} held-out state(s) with gravity: "
                f"largest tip error {worst:.3g} % of L (tolerance {tolerance_pct:g} %)")
    elif np.any(np.asarray(train_gravity, bool)):
        status, text = "trained", ("gravity acted in training states only: the fit explained them with the "
                                   "weight acting; no held-out state with gravity checked it")
    else:
        status, text = "absent", "gravity NOT VALIDATED: no state of the identification had gravity"
    return {"status": status, "stated": status in ("validated", "trained"), "states": int(pct.size),
            "max_tip_error_pct": worst, "text": text}


def initial_shear(rod: Optional[dict], base: ActuatorParams) -> float:
    """First estimate of the shear tip compliance s₀ [m/N] at 0 kPa: the FEM's rotation-free lateral compliance
    from its unloaded cap compliance (``rod["cap_compliance"]``, :func:`validation.identification.cap_compliance.shear_compliance`:
    c_δF − (4/3) c_θF c_δM / c_θM, docs/identification.md §4b), mean of the two lateral directions, at least 0;
    without the FEM the base actuator's s(0)."""
    C6 = None if not rod else rod.get("cap_compliance")
    if C6 is None:
        return float(base.shear_compliance[0]) if base.shear_compliance else 0.0
    from validation.identification.cap_compliance import lateral_shear
    s = lateral_shear(C6)
    return max(float(s), 0.0) if math.isfinite(s) else 0.0


#: ``FitResult.held_at`` (and reason) of the shear coefficients measured on the FEM's straight states
MEASURED_SHEAR = "measured on the FEM's straight states"


def straight_states(records) -> list:
    """The training records of straight pressure-only states (tensions 0, no tip force, no gravity, p > 0) that
    the FEM solved: where its rotation-free lateral compliance is measured (:func:`measure_straight_shear`)."""
    return [r for r in records if r.case.role == "train" and r.ok and r.case.pressure > 0
            and not np.any(r.case.tensions) and not np.any(r.case.tip_force) and not r.case.gravity]


def straight_shear_task(task: dict) -> float:
    """Worker: the FEM's rotation-free lateral compliance s [m/N] about one straight state (``task``: spec, case,
    start — its equilibrium snapshot or None): the 6×6 cap compliance there
    (:meth:`fem_reference.BellowsModel.cap_compliance`) through
    :func:`validation.identification.cap_compliance.lateral_shear`."""
    from validation.identification.cap_compliance import lateral_shear
    from validation.reference.fem_sweep import fem_model, start_solve
    model, case = fem_model(task["spec"]), task["case"]
    loads = dict(tensions=case.tensions, pressure=case.pressure, tip_force=case.tip_force, gravity=case.gravity)
    res = start_solve(model, task["start"], loads)[0] if task.get("start") is not None else None
    if res is None:
        res = model.solve(**loads)
    return float(lateral_shear(model.cap_compliance(res)))


def measure_straight_shear(spec, records, rod: Optional[dict], *, cache_dir=None) -> Optional[dict]:
    """The FEM's shear law s(p) = s0 + s1 p̂ [m/N] (p̂ = p / 100 kPa) from its straight states: s at 0 kPa from
    the unloaded cap compliance (``rod["cap_compliance"]``), at each straight pressure-only training state
    (:func:`straight_states`) from the cap compliance about it (:func:`straight_shear_task`: re-solved from the
    record's equilibrium in one step, cached like the load cases), fitted by non-negative least squares
    (:func:`validation.identification.cap_compliance.fit_shear_law`; docs/identification.md §4b).  Returns
    ``{"pressures_Pa", "s_m_per_N", "coeffs_m_per_N"}``, or None without the unloaded cap compliance or any
    straight state."""
    from validation.identification.cap_compliance import fit_shear_law, lateral_shear
    from validation.infra.runner import ResultCache, run_tasks
    from validation.reference.fem_sweep import fem_fingerprint
    recs = straight_states(records)
    C6 = None if not rod else rod.get("cap_compliance")
    if C6 is None or not recs:
        return None
    cache = None if cache_dir is None else ResultCache(cache_dir, version=fem_fingerprint())
    tasks = [{"spec": spec, "case": r.case, "start": r.state} for r in recs]
    out = run_tasks(straight_shear_task, tasks, workers=1, progress=False, cache=cache,
                    key_inputs=lambda t: {**t["spec"].key(), "kind": "straight_shear", "case": t["case"]})
    p = [0.0] + [float(r.case.pressure) for r in recs]
    s = [float(lateral_shear(np.asarray(C6, float)))] + [float(v) for v in out.results]
    return {"pressures_Pa": p, "s_m_per_N": s, "coeffs_m_per_N": fit_shear_law(p, s, degree=1).tolist()}


def initial_theta(form, rod: Optional[dict], base: ActuatorParams, *, slopes: bool = False) -> np.ndarray:
    """Starting point of ``form``: the closed-form rod values (FEM) or the base actuator's law at rest, slopes and
    pressure coefficients 0.  ``slopes`` (rig data only): with the base law's slopes dEA/dλ, dEI/dλ, ½ d²EA/dλ² —
    the *prior* a parameter the data do not determine is held at (:func:`prior_theta`).  The fits start with
    slopes 0: from the base's slopes a soft base law collapses under data of a stiffer one (measured: the
    `paper` form at k₁ = 122.8 N, a = 213.8 N cannot start on T = 5/5/5 N states of a 767 N actuator)."""
    sA = sI = cA = 0.0
    if rod:
        EA, EI, D_eff = rod["EA"], rod["EI"], max(rod.get("D_eff", 0.0), 1e-3)
    else:
        law, h = base.stiffness, 1e-3
        EA, EI, D_eff = float(law.EA(1.0)), float(law.EI(1.0)), base.D_eff
        if slopes:
            sA, sI = float(law.EA(1 + h) - law.EA(1 - h)) / (2 * h), float(law.EI(1 + h) - law.EI(1 - h)) / (2 * h)
            cA = float(law.EA(1 + h) - 2 * EA + law.EA(1 - h)) / (2 * h * h)
    D_a = math.sqrt(8 * EI / EA)
    name = form.name.split("+")[0]
    th = {"paper": [EA, sA, D_a, D_eff], "paper_area": [EA, sA, D_a, D_eff, 0.0],
          "separate": [EA, sA, EI, sI, D_eff], "separate_area": [EA, sA, EI, sI, D_eff, 0.0],
          "quadratic": [EA, sA, cA, EI, sI, D_eff],
          "constant": [EA, EI, D_eff], "pressure_ei": [EA, sA, EI, sI, 0.0, 0.0, D_eff],
          "pressure_ei_ea": [EA, sA, EI, sI, 0.0, 0.0, 0.0, D_eff],
          "pressure_ei_shear": [EA, sA, EI, sI, 0.0, 0.0, D_eff, initial_shear(rod, base), 0.0]}[name]
    if form.fits_distance:
        th.append(float(np.mean(base.tendon_distances)))
    if form.fits_masses:          # the base actuator's masses (from_measurements: the masses stated in its file)
        th += [float(base.line_mass), float(base.tip_mass)]
    return np.array(th, float)


def prior_theta(form, rod: Optional[dict], base: ActuatorParams) -> np.ndarray:
    """The value a parameter of ``form`` the data do not determine is held at: the base actuator's law with its
    slopes (rig data), the closed-form rod (FEM)."""
    return initial_theta(form, rod, base, slopes=rod is None)


# ---------------------------------------------------------------------------------------------- result
@dataclass
class IdentificationResult:
    """Identified parameters of the reduced model, with their uncertainty and the evidence behind them.

    values / ci95 / identifiable : the reported values of the chosen form (``a``, ``b`` [N], ``EA`` [N],
        ``EI`` [N m²], ``D_a``, ``D_eff`` [m], ``beta`` [-]); a value that is not identifiable is ``None``
    params : ActuatorParams of the chosen form (a non-identifiable parameter is held at the first-pass
        optimum — ``fit.held`` — and marked with that value in the TOML file)
    form : name of the chosen form; fits : {form: FitResult}; comparison : rows per form with the training
        and held-out errors [m]; heldout_errors : per held-out state [m] for the chosen form
    source : "fem" or "measurements"; design, records (FEM), rod (closed-form first estimate); provenance
    """
    form: str
    fits: dict
    comparison: list
    params: ActuatorParams
    source: str
    train: Observations
    heldout: Optional[Observations] = None
    design: Optional[Design] = None
    records: list = field(default_factory=list)
    rod: Optional[dict] = None
    provenance: dict = field(default_factory=dict)
    meta: dict = field(default_factory=dict)
    #: the report's Dynamics section (:func:`validation.checks.modes_compare.compare_modes`), None if not computed
    modes: Optional[dict] = None
    #: what :func:`from_fem`'s ``after_sweep`` returned (run beside the fits), None without one
    after_sweep: Any = field(default=None, repr=False)
    #: what the data can tell, checked before the fits (:mod:`validation.identification.information`):
    #: {"coverage": …, "forms": {form: …}, "warnings": [text]}; None when not checked (FEM designs)
    information: Optional[dict] = None

    @property
    def warnings(self) -> list:
        """Lines saying what the data do not determine and whether the chosen form fits them within their
        stated noise (empty when neither applies)."""
        out = [] if not self.information else list(self.information.get("warnings", []))
        return out + ([f"form {self.form}: {self.fit.misfit}"] if self.fits and self.fit.misfit else [])

    @property
    def fit(self) -> FitResult:
        return self.fits[self.form]

    @property
    def values(self) -> dict:
        return dict(self.fit.values)

    @property
    def ci95(self) -> dict:
        return dict(self.fit.values_ci95)

    @property
    def identifiable(self) -> dict:
        return dict(self.fit.values_identifiable)

    @property
    def not_identifiable(self) -> list:
        return [k for k, ok in self.identifiable.items() if not ok]

    @property
    def heldout_errors(self) -> Optional[np.ndarray]:
        row = next(r for r in self.comparison if r["form"] == self.form)
        return None if row.get("heldout_tip_errors_m") is None else np.asarray(row["heldout_tip_errors_m"])

    @property
    def gravity_validation(self) -> dict:
        """Whether the identification validated the actuator's weight, and so whether :meth:`to_toml` states
        gravity (:func:`gravity_check` on the training and held-out states of the chosen form)."""
        held = self.heldout is not None and self.heldout_errors is not None
        return gravity_check(self.train.gravity, self.heldout.gravity if held else None,
                             self.heldout_errors if held else None, self.params.length)

    # -------------------------------------------------------------------- display
    def _value_text(self, key: str) -> str:
        """A reported value with its unit (lengths in mm), or "not identifiable"."""
        v = self.values.get(key)
        if v is None:
            return "not identifiable"
        unit = REPORTED.get(key, "")
        scale, unit = (1e3, "mm") if unit == "m" else (1.0, unit.replace("^2", "²"))
        return f"{v * scale:.4g} {unit}".rstrip(" -")

    def _ci_text(self, key: str) -> str:
        lo, hi = self.ci95.get(key, (float("nan"), float("nan")))
        if self.values.get(key) is None or not (math.isfinite(lo) and math.isfinite(hi)):
            return ""
        scale = 1e3 if REPORTED.get(key) == "m" else 1.0
        return f"{lo * scale:.4g} … {hi * scale:.4g}"

    def _heldout_rms_text(self) -> str:
        row = next((r for r in self.comparison if r.get("form") == self.form), {})
        v = row.get("heldout_rms_tip_m")
        return "–" if v is None else f"{1e3 * v:.3f} mm"

    def __repr__(self) -> str:
        """One line: the chosen form, the source, the identified values (lengths in mm) and the held-out tip RMS."""
        vals = ", ".join(f"{k}={self._value_text(k)}" for k in self.values)
        return (f"IdentificationResult(form={self.form!r}, source={self.source!r}, {vals}, "
                f"held-out tip RMS={self._heldout_rms_text()})")

    def _repr_html_(self) -> str:
        from ancf.htmlrepr import table
        rows = [(k, self._value_text(k), self._ci_text(k)) for k in self.values]
        rows += [("held-out tip RMS", self._heldout_rms_text(), ""),
                 ("states", f"{self.train.n} training, {0 if self.heldout is None else self.heldout.n} held out", "")]
        return table(f"Identified parameters, form '{self.form}' (from {self.source})", rows,
                     header=("parameter", "value", "95 % CI"))

    # -------------------------------------------------------------------- output
    def default_name(self) -> str:
        """The identified actuator's name: ``<base>-identified`` — the base actuator's name (rig data) or the FEM
        design's (``meta["design_name"]``, a design file's stem; ``fem`` when unknown)."""
        if self.source == "fem":
            design = self.meta.get("design_name")
            base = pathlib.Path(design).stem if design and str(design).endswith(".toml") else (design or "fem")
        else:
            base = self.params.name
        return base if base.endswith("-identified") else f"{base}-identified"

    def provenance_toml(self) -> str:
        """The ``[provenance]`` table of :meth:`to_toml`: the source (FEM design and mesh, or the measurement
        file with the SHA-256 of its bytes when the table is written), the chosen form, when it was made and
        by which package version and git revision.  ``ActuatorParams.from_toml`` accepts and ignores it."""
        from ancf.params import _toml_string
        import hashlib
        rec = {"source": self.source, "form": self.form, "created": self.provenance.get("created", ""),
               "bellows_version": self.provenance.get("versions", {}).get("bellows", "unknown"),
               "git_revision": self.provenance.get("git_revision", "unknown"),
               "gravity": self.gravity_validation["status"]}
        if self.source == "fem":
            rec.update(design=str(self.meta.get("design_name", "")), design_description=self.meta.get("design", ""),
                       mesh=self.meta.get("mesh", ""))
            files = {"design_file": self.meta.get("design_name")}
        else:
            rec.update(base_actuator=self.params.name, measurements=self.meta.get("path", ""))
            files = {"measurements": self.meta.get("path")}
        for key, f in files.items():
            p = pathlib.Path(str(f)) if f and str(f).endswith((".toml", ".h5", ".hdf5", ".csv")) else None
            if p is not None and p.is_file():
                rec[key] = str(p.resolve())
                rec[f"{key}_sha256"] = hashlib.sha256(p.read_bytes()).hexdigest()
        return "\n[provenance]\n" + "".join(f"{k} = {_toml_string(str(v))}\n" for k, v in rec.items())

    def to_toml(self, path=None, *, force: bool = False, name: Optional[str] = None) -> str:
        """The identified actuator as TOML (``ActuatorParams.from_toml`` reads it unchanged apart from its
        ``name``) with a ``[provenance]`` table (:meth:`provenance_toml`); written to ``path`` if given (not
        overwritten without ``force``).  ``name``: the actuator's name in the file (default
        :meth:`default_name`, ``<base>-identified``).  Returns the text."""
        if name is not None and not (isinstance(name, str) and name.strip()):
            raise InputError(f"name must be a non-empty text, got {name!r}")
        params = self.params.replace(name=self.default_name() if name is None else name)
        lines = [f"# Identified by bellows ({self.source}), form '{self.form}': {self.fit.form.description}",
                 f"# git revision {self.provenance.get('git_revision', 'unknown')}, "
                 f"created {self.provenance.get('created', '')}"]
        f = self.fit
        at = {"first-pass optimum": "first-pass optimum", "base actuator's value": "base actuator's value",
              MEASURED_SHEAR: "value " + MEASURED_SHEAR + ":"}
        held = ", ".join(f"{nm} held at the {at.get(f.held_at.get(nm), 'given value')} {v:.6g} "
                         f"{dict(zip(f.names, f.form.units))[nm]}" for nm, v in f.held.items())
        for k, v in self.values.items():
            lo, hi = self.ci95.get(k, (float('nan'), float('nan')))
            unit = REPORTED.get(k, "")
            if v is not None and not (math.isfinite(lo) and math.isfinite(hi)) and k in f.reasons:
                lines.append(f"#   {k:6s} = {v:.6g} {unit}  ({f.reasons[k]})")
            elif v is not None:
                lines.append(f"#   {k:6s} = {v:.6g} {unit}  (95 % CI {lo:.6g} .. {hi:.6g})")
            elif held:
                lines.append(f"#   {k:6s} NOT IDENTIFIABLE from these data: the value below follows from {held}")
            else:
                lines.append(f"#   {k:6s} NOT IDENTIFIABLE from these data ({f.reasons.get(k, 'see fit.json')}): "
                             "the value below is the fit's optimum, not determined by the data")
        for nm in f.names:                         # pressure coefficients (dimensionless, per power of p/100 kPa)
            if nm in ("pI1", "pI2", "pA1"):
                lo, hi = f.ci95.get(nm, (float("nan"), float("nan")))
                v = float(f.theta[f.names.index(nm)])
                lines.append(f"#   {nm:6s} = {v:.6g} per (p/100 kPa)^{2 if nm == 'pI2' else 1}"
                             + (f"  (95 % CI {lo:.6g} .. {hi:.6g})" if f.identifiable.get(nm) else
                                "  NOT IDENTIFIABLE from these data"))
        for nm, unit in zip(f.names, f.form.units):          # fitted masses (they are in the table below)
            if nm in ("line_mass", "tip_mass"):
                lo, hi = f.ci95.get(nm, (float("nan"), float("nan")))
                v = float(f.theta[f.names.index(nm)])
                lines.append(f"#   {nm:9s} = {v:.6g} {unit}" + (f"  (95 % CI {lo:.6g} .. {hi:.6g})"
                             if f.identifiable.get(nm) else f"  NOT IDENTIFIED: {f.held_at.get(nm, 'not determined')}"))
        if f.misfit:
            lines.append(f"# WARNING: {f.misfit}")
        if held:
            lines.append(f"# held: {held}; the intervals above are {f.intervals}")
        lines += self._gravity_lines()
        if not self.gravity_validation["stated"]:
            params = params.replace(gravity=(0.0, 0.0, 0.0))
        text = "\n".join(lines) + "\n" + params.to_toml() + self.provenance_toml()
        if path is not None:
            p = prepare_output_file(path, force=force, suffixes=(".toml",))
            atomic_write_text(p, text)
        return text

    def _gravity_lines(self) -> list:
        """The comment lines of :meth:`to_toml` on gravity: what validated it, or why the file does not state it."""
        gv = self.gravity_validation
        p = self.params
        masses = f"line_mass {p.line_mass:.6g} kg/m, tip_mass {p.tip_mass:.6g} kg"
        if gv["stated"]:
            return [f"# {gv['text']}; gravity {list(p.gravity)} m/s², {masses}"]
        return [f"# {gv['text']}.", f"# gravity_m_per_s2 is therefore 0 in this file: state the gravity of your mounting "
                f"(the design's: {list(p.gravity)} m/s²) only after checking it; the masses ({masses}) are the "
                "design's, for the dynamics"]

    def to_dict(self) -> dict:
        fits = {}
        for name, f in self.fits.items():
            fits[name] = {"parameters": dict(zip(f.names, f.theta.tolist())), "units": dict(zip(f.names, f.form.units)),
                          "ci95": f.ci95, "identifiable": f.identifiable, "correlation": f.correlation,
                          "values": f.values, "values_ci95": f.values_ci95,
                          "values_identifiable": f.values_identifiable, "rms_tip_m": f.rms_tip, "dof": f.dof,
                          "variance_scale": f.s2, "singular_values": f.singular_values, "nfev": f.nfev,
                          "rejected_trials": f.rejected, "not_identifiable_reasons": f.reasons,
                          "held": {nm: {"value": v, "unit": dict(zip(f.names, f.form.units))[nm],
                                        "held_at": f.held_at.get(nm, "")} for nm, v in f.held.items()},
                          "intervals": f.intervals, "interval_basis": f.interval_basis, "misfit": f.misfit,
                          "chi2_per_dof": f.chi2_per_dof, "readmitted_states": list(f.readmitted),
                          "residuals_m": f.residuals, "description": f.form.description}
        return to_jsonable({
            "source": self.source, "form": self.form, "values": self.values, "ci95": self.ci95,
            "identifiable": self.identifiable, "units": REPORTED, "comparison": self.comparison, "fits": fits,
            "misfit": self.fit.misfit, "warnings": self.warnings, "gravity_validation": self.gravity_validation,
            "training_labels": self.train.labels,
            "heldout_labels": None if self.heldout is None else self.heldout.labels,
            "design": None if self.design is None else self.design.to_dict(),
            "fem_records": [r.to_dict() for r in self.records], "rod_estimate": self.rod,
            "actuator_toml": self.params.to_toml(), "provenance": self.provenance, "meta": self.meta}
            | ({} if self.modes is None else {"modes": self.modes})
            | ({} if self.information is None else {"information": self.information}))

    def save(self, path, *, force: bool = False) -> pathlib.Path:
        """Write the fit data as JSON (see :meth:`to_dict`)."""
        p = prepare_output_file(path, force=force, suffixes=(".json",))
        return atomic_write_text(p, json.dumps(self.to_dict(), indent=1))

    def summary_rows(self) -> list[dict]:
        rows = []
        for k, v in self.values.items():
            lo, hi = self.ci95[k]
            rows.append({"parameter": k, "unit": REPORTED.get(k, ""), "value": v, "ci95_low": lo, "ci95_high": hi,
                         "identifiable": self.identifiable[k]})
        return rows


# ---------------------------------------------------------------------------------------------- fit all forms
#: rounds of refits between nested forms (each: every form from its richest nested form's optimum and from a
#: better richer form's optimum restricted; stops early when no fit improves)
NESTED_ROUNDS = 3


def starting_points(form, theta0, fitted: dict) -> list:
    """Starts of a fit of ``form``: its own ``theta0`` and, when a form already fitted has parameters that are a
    subset of this one's (nested forms: ``separate`` ⊂ ``pressure_ei`` ⊂ ``pressure_ei_shear``), the optimum of
    the richest such fit with this form's extra parameters at ``theta0`` — the richer form is then at least as good on the
    training states as the one it extends (from ``theta0`` alone it landed in a worse local minimum: measured
    16.4 vs 11.6 mm training RMS for pressure_ei_shear vs pressure_ei)."""
    starts = [np.asarray(theta0, float)]
    names = list(form.names)
    nested = [f for f in fitted.values() if f.form.name != form.name and set(f.form.names) < set(names)]
    if nested:
        f = max(nested, key=lambda g: g.form.n)          # the richest form this one extends
        th = starts[0].copy()
        for nm, v in zip(f.form.names, f.theta):
            th[names.index(nm)] = v
        if not np.array_equal(th, starts[0]):
            starts.append(th)
    return starts


def restricted_starts(form, fitted: dict) -> list:
    """Starts of a refit of ``form`` from the optimum of every richer fitted form that contains it (its extra
    parameters — pressure coefficients, shear compliance — are zero in this form), restricted to this form's
    parameters; only where that fit is better than this form's own (a nested form can only fit worse, so the
    richer optimum restricted is a start near a better basin: measured, pressure_ei from 11.6 to 0.7 mm training
    RMS — its own start, with the pressure coefficients at their lower bound 0, stayed at that bound)."""
    own = fitted.get(form.name)
    names = list(form.names)
    out = []
    for f in fitted.values():
        if f.form.name == form.name or not set(names) < set(f.form.names):
            continue
        if own is not None and f.rss >= own.rss:
            continue
        sup = list(f.form.names)
        out.append(np.array([f.theta[sup.index(nm)] for nm in names], float))
    return out


def identify(train: Observations, base: ActuatorParams, *, heldout: Optional[Observations] = None,
             forms: Sequence[str] = FORMS, rod: Optional[dict] = None, fit_distance: bool = False,
             absolute_sigma: Optional[bool] = None, source: str = "data", progress: Optional[Callable[[str], Any]] = None,
             check_information: bool = False, fit_masses: bool = False,
             heldout_compliance: Optional[Sequence] = None, workers: Optional[int] = 1,
             measured: Optional[dict] = None) -> IdentificationResult:
    """Fit every form in ``forms`` to ``train``, compare them on ``heldout`` (or on the training error when
    there is no held-out set) and return the chosen form's result (see the module docstring).  Each form is
    fitted from its own start, from the optimum of the richest nested form fitted before it
    (:func:`starting_points`) and from the optimum of a better-fitting richer form restricted to its parameters
    (:func:`restricted_starts`); the fit with the smallest weighted residual is kept.

    check_information : first measure what the data can tell (:mod:`validation.identification.information`):
    the parameters they do not determine are held at their prior (``base``'s value, the form's start) and
    reported as not determined with the reason; a form with nothing determined is not fitted (its row says
    ``refused``).  progress : ``progress(line)`` after each form's fit and after the refits (which form, how
    long, the result).  fit_masses : the line and tip mass are parameters of every form
    (:func:`~validation.identification.forms.with_masses`; rig data under gravity), starting at ``base``'s.
    heldout_compliance : per held-out state None or the reference's tip compliances (C_tension, C_locked), each
    (3, 3) [m/N], locked along −z by the exact taut-set rule (the FEM's, :mod:`validation.reference.fem_sweep`);
    then the form is chosen on them too (:func:`_choose`).  workers : processes fitting forms side by side
    (None: one per core; 1: in this process); the result does not depend on it (:func:`_fit_all`).
    measured : {parameter name: (value, reason)} held at the value given in every form that has it and reported
    held with the reason (e.g. the shear coefficients s0, s1 measured on the FEM's straight states,
    :func:`from_fem`); the others are fitted given them."""
    if not forms:
        raise InputError("identify: no model form given")
    all_forms = [get_form(name, fit_distance, fit_masses) for name in forms]
    info, information = ({}, None) if not check_information else _check_information(all_forms, train, base, rod)
    say = progress or (lambda line: None)
    fits, errors = _fit_all(all_forms, train, base, rod, absolute_sigma, info, say,
                            _fit_workers(workers, len(all_forms)), measured)
    rows, failures = [], {}
    for form in all_forms:
        if form.name not in fits:
            err = errors.get(form.name)
            failures[form.name] = f"{type(err).__name__}: {err}"
            rows.append({"form": form.name, "n_params": form.n, "failed": failures[form.name]})
            continue
        rows.append(_comparison_row(form, fits[form.name], heldout, info.get(form.name)))
        if heldout is not None and heldout_compliance is not None:
            rows[-1].update(heldout_compliance_errors(fits[form.name].params, heldout, heldout_compliance))
    if not fits:
        raise ConfigError(f"no model form could be fitted: {failures}")
    chosen = _choose(rows, heldout is not None)
    return IdentificationResult(chosen["form"], fits, rows, fits[chosen["form"]].params, source, train, heldout,
                                rod=rod, provenance=provenance(), information=information)


def _fit_workers(workers: Optional[int], n_forms: int) -> int:
    """The fit processes for ``workers`` (None: one per core), at most one per form; 1 inside a daemonic process
    (which cannot start any: :func:`from_fem` fits beside the FEM's solves in one)."""
    import multiprocessing as mp
    import os
    from validation.infra.runner import check_workers
    check_workers(workers)
    n = (os.cpu_count() or 1) if workers is None else int(workers)
    return 1 if mp.current_process().daemon else max(1, min(n, n_forms))


def _check_information(all_forms, train: Observations, base: ActuatorParams, rod: Optional[dict]) -> tuple:
    """({form: Information}, the record for fit.json with its warning lines) of what ``train`` can tell each
    form at its start (:func:`validation.identification.information.check_form`)."""
    from validation.identification.information import check_form, coverage
    from validation.identification.fit import _too_few_data
    cov = coverage(train, base)
    n_obs = train.weights().size
    # a form with too few data for all its parameters claims nothing (fit's rule); holding some would dodge it
    info = {form.name: check_form(form, train, base, initial_theta(form, rod, base), cov) for form in all_forms
            if not _too_few_data(train.n, n_obs, form.n)}
    warnings = list(cov.findings.values())
    refused = [name for name, inf in info.items() if inf.refused]
    if refused:
        warnings.append(("every form" if len(refused) == len(info) else "form(s) " + ", ".join(refused))
                        + ": nothing determined by these data; refused (every parameter at the base actuator's "
                        "value, reported as not determined)")
    for name, inf in info.items():
        if inf.held and not inf.refused:
            warnings.append(f"form {name}: not determined by these data, held at the base actuator's value: "
                            + "; ".join(f"{nm} ({why.split(';')[0]})" for nm, why in inf.held.items()))
    if warnings:
        warnings.insert(0, "coverage: " + cov.summary())
    return info, {"coverage": cov.to_dict(), "forms": {n: i.to_dict() for n, i in info.items()},
                  "warnings": warnings}


def _fit_all(all_forms, train: Observations, base: ActuatorParams, rod, absolute_sigma, info: dict, say,
             workers: int = 1, measured: Optional[dict] = None) -> tuple:
    """({form: best FitResult}, {form: first error}): each form from its own start, then the nested refits
    (:data:`NESTED_ROUNDS`); parameters the data do not determine (``info``) held at their start; a refused
    form evaluated at its start only (:func:`validation.identification.fit.prior_result`); the ``measured``
    parameters ({name: (value, reason)}) held at their value in every form that has them.

    Each fit (one form, one start: a pure function of them) is a task on ``workers`` processes; a form's batch of
    starts is formed when every fit they are taken from is in (:class:`_FitPlan`) and merged when its fits are,
    so the result is the one of the sequential order for any ``workers``
    (tests/test_identification/test_forms_parallel.py).  A worker with nothing ready meanwhile fits the starts
    the fits so far suggest (:meth:`_FitPlan.speculative`); a batch takes such a fit when it has the same start,
    and one it has not is dropped unused."""
    import time
    measured = dict(measured or {})
    held = {form.name: tuple(info[form.name].held) if form.name in info else () for form in all_forms}
    held = {form.name: held[form.name] + tuple(nm for nm in form.names if nm in measured and nm not in held[form.name])
            for form in all_forms}
    ctx = _FitContext(list(all_forms), train, base, absolute_sigma, held,
                      {f.name: dict(info[f.name].held) for f in all_forms if f.name in info})
    plan = _FitPlan(all_forms, rod, base, info, held, measured)
    run = _FitTasks(ctx, workers)
    t_refits, batches = None, []
    try:
        while True:
            for index, rnd, starts in plan.ready():
                if rnd == 1 and t_refits is None:
                    t_refits = time.perf_counter()
                batches.append((index, rnd, [run.submit(index, s) for s in starts]))
            done = [b for b in batches if all(f.done() for f in b[2])]
            for b in done:
                batches.remove(b)
                results = [f.result() for f in b[2]]
                plan.merge(b[0], results)
                if b[1] == 0:
                    name = all_forms[b[0]].name
                    say(_progress_line(name, plan.fits.get(name), plan.errors.get(name), results[0][1]))
            if not batches:
                if done:
                    continue
                break
            run.speculate(plan.speculative())
            if not done:
                run.wait([f for b in batches for f in b[2]])
    finally:
        run.close()
    if plan.n_refits:
        say(f"{plan.n_refits} refit(s) from the nested forms' optima: {time.perf_counter() - t_refits:.1f} s; "
            + (f"improved {', '.join(sorted(plan.better))}" if plan.better else "no fit improved"))
    return plan.fits, plan.errors


class _FitTasks:
    """The fits of :func:`_fit_all` as futures, one per (form, start): on a process pool of ``workers`` (started
    as the task runner starts its own, :mod:`validation.infra.runner`: ``fork`` where safe, one BLAS thread
    each), or run here at once (``workers`` 1).  A fit asked again is the same future."""

    def __init__(self, ctx: "_FitContext", workers: int):
        import concurrent.futures as cf
        import multiprocessing as mp
        from validation.infra.runner import _single_thread_env, _start_method
        self.ctx, self.workers, self.futures, self.pool = ctx, workers, {}, None
        if workers > 1:
            with _single_thread_env():
                self.pool = cf.ProcessPoolExecutor(max_workers=workers, mp_context=mp.get_context(_start_method()),
                                                   initializer=_init_fit_worker, initargs=(ctx,))

    def submit(self, index: int, start: np.ndarray):
        """The future of the fit of form ``index`` from ``start``: (FitResult or its error, seconds)."""
        import concurrent.futures as cf
        key = (index, start.tobytes())
        if key not in self.futures:
            if self.pool is None:
                fut = cf.Future()
                fut.set_result(_fit_one(self.ctx, index, start))
            else:
                fut = self.pool.submit(_fit_one, None, index, start)
            self.futures[key] = fut
        return self.futures[key]

    def speculate(self, candidates: list) -> None:
        """Start fits of ``candidates`` [(form index, start)] on the workers that would idle (none without a pool)."""
        if self.pool is None:
            return
        busy = sum(not f.done() for f in self.futures.values())
        for index, start in candidates:
            if busy >= self.workers:
                break
            if (index, start.tobytes()) not in self.futures:
                self.submit(index, start)
                busy += 1

    def wait(self, futures: list) -> None:
        import concurrent.futures as cf
        cf.wait(futures, return_when=cf.FIRST_COMPLETED)

    def close(self) -> None:
        """Stop the workers (fits still running were speculative or the run was interrupted: not waited for)."""
        if self.pool is not None:
            from validation.infra.runner import _kill_pool
            if all(f.done() for f in self.futures.values()):
                self.pool.shutdown(wait=True)
            else:
                _kill_pool(self.pool)


def _related(a, b) -> bool:
    """Whether a fit of form ``a`` may start from one of form ``b`` or the other way round (nested forms: the
    parameters of one a strict subset of the other's; :func:`starting_points`, :func:`restricted_starts`)."""
    return set(a.names) < set(b.names) or set(b.names) < set(a.names)


@dataclass
class _FitContext:
    """What every fit of :func:`_fit_all` shares (given once to each worker process)."""
    forms: list
    train: Observations
    base: ActuatorParams
    absolute_sigma: Optional[bool]
    held: dict                    # {form: names held at their prior}
    held_reasons: dict            # {form: {name: why it is not determined}}


_WORKER_CONTEXT: Optional[_FitContext] = None


def _init_fit_worker(ctx: _FitContext) -> None:
    """A worker process of :func:`_fit_all`: one BLAS thread, the shared context."""
    global _WORKER_CONTEXT
    from validation.infra.runner import limit_threads
    limit_threads()
    _WORKER_CONTEXT = ctx


def _fit_one(ctx: Optional[_FitContext], index: int, start: np.ndarray) -> tuple:
    """(FitResult or the BellowsError it raised, seconds) of the fit of form ``index`` from ``start``, with
    ``ctx`` (None in a worker process: its own).  An error that would not survive the way back to the parent
    process is sent as a ConfigError with its type and text."""
    import pickle
    import time
    from validation.identification.fit import prior_result
    remote = ctx is None
    ctx = _WORKER_CONTEXT if remote else ctx
    form = ctx.forms[index]
    held = ctx.held[form.name]
    t0 = time.perf_counter()
    try:
        if len(held) == form.n:
            g = prior_result(form, ctx.train, ctx.base, start, ctx.held_reasons[form.name])
        else:
            g = fit(form, ctx.train, ctx.base, start, absolute_sigma=ctx.absolute_sigma, fixed=held)
    except BellowsError as exc:
        g = exc
        if remote:
            try:
                pickle.loads(pickle.dumps(exc))
            except Exception:
                g = ConfigError(f"{type(exc).__name__}: {exc}")
    return g, time.perf_counter() - t0


class _FitPlan:
    """The order of :func:`_fit_all`'s fits as a graph, and their results.

    Sequentially the fits run as: every form from its own start (round 0), then up to :data:`NESTED_ROUNDS`
    rounds, each refitting the forms in order from the starts the fits so far give (:func:`starting_points`,
    :func:`restricted_starts`), until a round improves nothing.  A form's starts read only the fits of forms
    nested with it (:func:`_related`), so (1) the round-0 fits are independent; (2) in a round, the batch of a
    form waits only for the batches of the earlier related forms of that round; (3) groups of forms that are not
    related (connected components) run their rounds apart — a group whose round improved nothing would only
    meet starts it has tried in the next one.  Batches started in this order and merged per form (a batch only
    changes its own form's fit) give the sequential result."""

    def __init__(self, all_forms, rod, base: ActuatorParams, info: dict, held: dict, measured: Optional[dict] = None):
        self.forms, self.info, self.held, self.measured = list(all_forms), info, held, dict(measured or {})
        self.theta0 = [_with_measured(f, initial_theta(f, rod, base), self.measured) for f in self.forms]
        self.prior = [_with_measured(f, prior_theta(f, rod, base), self.measured) for f in self.forms]
        self.fits, self.errors, self.tried, self.better, self.n_refits = {}, {}, {}, set(), 0
        self.first: dict = {}         # {form: (round, form index) of its first fit}
        n = len(self.forms)
        self.rel = [[_related(self.forms[i], self.forms[j]) for j in range(n)] for i in range(n)]
        self.groups = [dict(members=g, round=0, started=set(), merged=set(), improved=False, done=False)
                       for g in _groups(self.rel)]

    def _at_prior(self, i: int, starts: list) -> list:
        """``starts`` of form ``i`` with the parameters the data do not determine at their prior."""
        form = self.forms[i]
        out = []
        for start in starts:
            s = np.asarray(start, float).copy()
            for nm in self.held[form.name]:
                s[form.names.index(nm)] = self.prior[i][form.names.index(nm)]
            out.append(s)
        return out

    def _new_starts(self, i: int, starts: list) -> list:
        """``starts`` of form ``i`` (:meth:`_at_prior`) less those tried before, recorded as tried."""
        seen = self.tried.setdefault(self.forms[i].name, set())
        out = []
        for s in self._at_prior(i, starts):
            if s.tobytes() not in seen:
                seen.add(s.tobytes())
                out.append(s)
        return out

    def _refit_starts(self, i: int) -> list:
        form = self.forms[i]
        return starting_points(form, self.theta0[i], self.fits)[1:] + restricted_starts(form, self.fits)

    def speculative(self) -> list:
        """[(form index, start)] that a batch not yet formed may ask for, from the fits so far: the refit starts
        of the forms whose batch of this round has not started (of round 1 during round 0), not tried yet.
        Nothing is recorded: only :meth:`ready` decides what the result uses."""
        out = []
        for g in self.groups:
            for i in ([] if g["done"] else g["members"]):
                if g["round"] and i in g["started"]:
                    continue
                seen = self.tried.get(self.forms[i].name, set())
                out += [(i, s) for s in self._at_prior(i, self._refit_starts(i)) if s.tobytes() not in seen]
        return out

    def ready(self) -> list:
        """[(form index, round, new starts)] of the batches that can start now (each returned once); a batch
        without new starts is merged at once."""
        out = []
        for g in self.groups:
            progressed = True
            while progressed and not g["done"]:
                progressed = False
                for i in g["members"]:
                    earlier = [j for j in g["members"] if j < i and self.rel[i][j]]
                    if i in g["started"] or (g["round"] and not set(earlier) <= g["merged"]):
                        continue
                    g["started"].add(i)
                    cand = [self.theta0[i]] if g["round"] == 0 else self._refit_starts(i)
                    starts = self._new_starts(i, cand)
                    if g["round"]:
                        self.n_refits += len(starts)
                    if starts or g["round"] == 0:
                        out.append((i, g["round"], starts))
                    else:
                        progressed |= self._merged(g, i, False)
        return out

    def merge(self, i: int, results: list) -> None:
        """The results of form ``i``'s batch, in the order of its starts: keep the best (sequential rule)."""
        form = self.forms[i]
        improved = False
        for g, _ in results:
            if isinstance(g, BaseException):
                self.errors.setdefault(form.name, g)
                continue
            if len(self.held[form.name]) < form.n:
                _mark_prior(g, self.info.get(form.name))
                _mark_measured(g, self.measured)
            if form.name not in self.fits or g.rss < self.fits[form.name].rss * (1 - 1e-9):
                improved = True
                self._keep(i, g)
        group = next(g for g in self.groups if i in g["members"])
        if improved and group["round"]:
            self.better.add(form.name)
        self._merged(group, i, improved)

    def _keep(self, i: int, g: FitResult) -> None:
        """Keep ``g`` as form ``i``'s fit; ``fits`` in the order the sequential loop fills it (by the round, then
        the form of each form's first fit): the starts read it in that order (:func:`restricted_starts`)."""
        name = self.forms[i].name
        if name not in self.fits:
            group = next(gr for gr in self.groups if i in gr["members"])
            self.first[name] = (group["round"], i)
        self.fits[name] = g
        self.fits = {n: self.fits[n] for n in sorted(self.fits, key=self.first.get)}

    def _merged(self, g: dict, i: int, improved: bool) -> bool:
        """Record form ``i``'s batch of group ``g``'s round as merged; at the end of the round start the next
        one (or end the group).  Returns True (something changed)."""
        g["merged"].add(i)
        g["improved"] |= improved
        if g["merged"] == set(g["members"]):
            if g["round"] and (not g["improved"] or g["round"] == NESTED_ROUNDS):
                g["done"] = True
            g.update(round=g["round"] + 1, started=set(), merged=set(), improved=False)
        return True


def _groups(rel: list) -> list:
    """Connected components (sorted index lists) of the symmetric relation ``rel`` (n × n bools)."""
    n, seen, out = len(rel), set(), []
    for i in range(n):
        if i in seen:
            continue
        comp, todo = set(), [i]
        while todo:
            k = todo.pop()
            if k not in comp:
                comp.add(k)
                todo += [j for j in range(n) if rel[k][j] and j not in comp]
        seen |= comp
        out.append(sorted(comp))
    return out


def _progress_line(name: str, f: Optional[FitResult], err, seconds: float) -> str:
    """'form paper: 2.1 s, training RMS 0.08 mm (58 solves)' — or its failure, or that it was refused."""
    if f is None:
        return f"form {name}: {seconds:.1f} s, failed ({type(err).__name__})"
    if f.intervals.startswith("none: not determined"):
        return f"form {name}: refused — nothing determined by these data (training RMS at the prior {1e3 * f.rms_tip:.3g} mm)"
    held = [nm for nm, at in f.held_at.items() if at == PRIOR]
    return (f"form {name}: {seconds:.1f} s, training RMS {1e3 * f.rms_tip:.3g} mm ({f.nfev} solves)"
            + (f", held at the prior: {', '.join(held)}" if held else "") + _readmitted_text(f))


def _readmitted_text(f: FitResult) -> str:
    """'; state(s) … had no equilibrium at the start: …' when the fit re-admitted states (``f.readmitted``)."""
    if not f.readmitted:
        return ""
    return (f"; state(s) {', '.join(map(repr, f.readmitted))} had no equilibrium at the starting parameters: fitted "
            "first without them, then with them from that optimum")


#: ``FitResult.held_at`` of a parameter the data do not determine (held at the base actuator's value).
PRIOR = "prior (the base actuator's value: not determined by the data)"


def _mark_prior(f: FitResult, inf) -> None:
    """Record on ``f`` the parameters held at their prior because the data do not determine them (``inf``:
    :class:`~validation.identification.information.Information`), and the derived values that depend on them."""
    if inf is None or not inf.held:
        return
    for nm, why in inf.held.items():
        f.held_at[nm] = PRIOR
        f.reasons[nm] = "not determined by the data: " + why
        f.identifiable[nm] = False
    for k, ok in f.values_identifiable.items():
        if not ok and k not in f.reasons:
            f.reasons[k] = "depends on " + ", ".join(inf.held) + ", not determined by the data"


def _with_measured(form, theta, measured: dict) -> np.ndarray:
    """``theta`` of ``form`` with its ``measured`` parameters ({name: (value, reason)}) at their value."""
    th = np.array(theta, float)
    for nm, (v, _) in measured.items():
        if nm in form.names:
            th[form.names.index(nm)] = float(v)
    return th


def _mark_measured(f: FitResult, measured: dict) -> None:
    """Record on ``f`` the parameters it held at a measured value ({name: (value, reason)}) with that reason, and
    the derived values that follow from them alone (e.g. s at 0 and 100 kPa from s0, s1) with their value."""
    mine = {nm: why for nm, (_, why) in measured.items() if nm in f.held}
    if not mine:
        return
    for nm, why in mine.items():
        f.held_at[nm] = why
        f.reasons[nm] = why
    names = list(f.form.names)
    keys, D = f.form.derived_jacobian(f.theta)
    vals = f.form.derived(f.theta)
    other = np.array([nm not in mine for nm in names])
    for i, k in enumerate(keys):
        uses = np.abs(D[i]) > 1e-12 * (np.abs(D[i]).max() + 1e-300)
        if uses.any() and not (uses & other).any() and math.isfinite(vals[k]):
            f.values[k] = float(vals[k])
            f.values_identifiable[k], f.values_ci95[k] = True, (float("nan"), float("nan"))   # given, not fitted
            f.reasons[k] = "from " + ", ".join(nm for nm, u in zip(names, uses) if u) + ", " + next(iter(mine.values()))


def _comparison_row(form, f: FitResult, heldout: Optional[Observations], inf) -> dict:
    """The form's row of the comparison: training and held-out tip errors [m], what it does not identify."""
    row = {"form": form.name, "n_params": form.n, "description": form.description,
           "train_rms_tip_m": f.rms_tip, "train_max_tip_m": float(f.tip_errors().max()),
           "not_identifiable": [k for k, ok in f.values_identifiable.items() if not ok]}
    if inf is not None and inf.held:
        row["not_determined"] = dict(inf.held)
    if inf is not None and inf.refused:
        row["refused"] = "nothing determined by these data"
    elif f.intervals.startswith("none"):          # too few data for this form: it identified nothing
        row["too_few_data"] = f.intervals[len("none: "):]
    if heldout is not None:
        try:
            pred = predict(f.params, heldout)
            e = np.linalg.norm(pred[:, :3] - heldout.tip, axis=1)
            row.update(heldout_rms_tip_m=float(np.sqrt(np.mean(e ** 2))), heldout_max_tip_m=float(e.max()),
                       heldout_tip_errors_m=e.tolist())
            if heldout.markers is not None:
                k = heldout.marker_s.size
                em = np.linalg.norm((pred[:, 3:] - heldout.markers.reshape(heldout.n, 3 * k))
                                    .reshape(heldout.n, k, 3), axis=2)
                row["heldout_rms_marker_m"] = float(np.sqrt(np.mean(em ** 2)))
        except BellowsError as exc:
            row["heldout_failed"] = f"{type(exc).__name__}: {exc}"
    return row


def heldout_compliance_errors(params: ActuatorParams, heldout: Observations, reference: Sequence) -> dict:
    """{"heldout_compliance_error_pct": mean over the held-out states and both modes (tensions held, tendons
    locked along −z, exact taut-set rule) of 100 ‖C_model − C_ref‖_F / ‖C_ref‖_F, plus the mean per mode} for
    the states whose ``reference`` entry is (C_tension, C_locked) (3, 3) [m/N]; {} when any of them fails (the
    form is then chosen on the tip alone)."""
    from ancf import Model
    from ancf import compliance as cp
    err = {"tension": [], "locked": []}
    models = {True: Model(params), False: Model(params.replace(gravity=(0.0, 0.0, 0.0)))}   # as each state was
    for i, ref in enumerate(reference):
        if ref is None or ref[0] is None or (heldout.gravity[i] and not np.any(params.gravity)):
            continue
        model = models[bool(heldout.gravity[i])]
        try:
            eq = model.fk(heldout.tensions[i], heldout.pressure[i], heldout.tip_force[i], check_limits=False)
            mine = (cp.tension(model, eq).C_p, cp.locked(model, eq, method="exact", load_direction=(0, 0, -1)).C_p)
        except BellowsError:
            return {}
        for mode, C, Cr in zip(("tension", "locked"), mine, ref):
            err[mode].append(100 * np.linalg.norm(C - np.asarray(Cr)) / np.linalg.norm(Cr))
    if not err["locked"]:
        return {}
    return {"heldout_compliance_error_pct": float(np.mean(err["tension"] + err["locked"])),
            "heldout_compliance_tension_error_pct": float(np.mean(err["tension"])),
            "heldout_compliance_locked_error_pct": float(np.mean(err["locked"]))}


#: the held-out measures a form is chosen on, when every candidate has them (tip error always)
CHOICE_KEYS = ("heldout_rms_tip_m", "heldout_compliance_error_pct")


def _choose(rows: list, by_heldout: bool) -> dict:
    """The chosen row: the simplest form within :data:`PARSIMONY` × the best error; forms that identified
    nothing (too few data, refused) only when every form did.  With held-out compliances for every candidate
    (:func:`heldout_compliance_errors`) a form must be within PARSIMONY of the best on the tip error *and* on the
    compliance error (the tip states alone are blind to a rotation-free tip compliance, which the locked
    compliance sees, docs/identification.md §4b); when no form is, the one closest to that (the smallest largest
    ratio to the best) is taken."""
    key = "heldout_rms_tip_m" if by_heldout else "train_rms_tip_m"
    ok = [r for r in rows if key in r]
    if not ok:
        raise ConfigError(f"no fitted form could predict the held-out states: "
                          f"{[r.get('heldout_failed') for r in rows]}")
    ok = [r for r in ok if "too_few_data" not in r and "refused" not in r] or ok
    keys = [key] + [k for k in CHOICE_KEYS[1:] if by_heldout and all(k in r for r in ok)]
    best = {k: min(r[k] for r in ok) for k in keys}
    ratio = lambda r: max(r[k] / best[k] if best[k] > 0 else (1.0 if r[k] <= 0 else math.inf)  # noqa: E731
                          for k in keys)
    if all("refused" in r for r in ok):      # nothing fitted: the first form asked for, at the base's values
        chosen = ok[0]
    else:
        near = [r for r in ok if ratio(r) <= PARSIMONY + 1e-12] or [min(ok, key=ratio)]
        chosen = min(near, key=lambda r: (r["n_params"], r[key]))
    for r in rows:
        r["chosen"] = r is chosen
    return chosen


def _finalise_params(res: IdentificationResult, base: ActuatorParams) -> None:
    """Give the chosen parameters the base actuator's name, gravity, damping and limits, and its masses unless the
    form fitted them (the fit ran without gravity where the data had none; static states say nothing about
    damping; a fitted mass held at the prior is the base's value anyway)."""
    keep = dict(gravity=base.gravity, rayleigh_alpha=base.rayleigh_alpha, rayleigh_beta=base.rayleigh_beta,
                axial_damping=base.axial_damping)
    masses = dict(line_mass=base.line_mass, tip_mass=base.tip_mass)
    for f in res.fits.values():
        f.params = f.params.replace(**keep, **({} if f.form.fits_masses else masses))
    res.params = res.fit.params


# ---------------------------------------------------------------------------------------------- from the FEM
def from_fem(geometry, material, mesh="coarse", workers: Optional[int] = None, scheduler=None, cache_dir=None, *,
             design: Optional[Design] = None, forms: Sequence[str] = FORMS, n_elements: int = 6,
             tension_max: float = 5.0, pressure_max: float = 120e3, fit_distance: bool = False,
             progress: bool = True, compliance: bool = True, cases: str = "default",
             after_sweep: Optional[Callable[[list], Any]] = None, mounting: str = "horizontal") -> IdentificationResult:
    """Identify the reduced model from virtual experiments on the FEM of ``geometry`` and ``material``.

    mesh : FEM mesh level ("coarse" for minutes, "reference" for the full report); workers / scheduler :
    parallel FEM solves (local processes, or a dask scheduler address); cache_dir : on-disk cache of the FEM
    results (re-runs compute only what changed; an interrupted sweep resumes); design : the load cases
    (default: :func:`validation.reference.experiments.default_design` for this actuator's range); forms : model forms
    to compare; compliance : also compute the FEM tip compliances of the held-out states (used by
    :mod:`validation.checks.compare`); cases : without ``design``, ``"default"`` (that design) or ``"informative"``
    (:func:`validation.identification.design_select.informative_design` for the form with the most parameters, at its start
    from the closed-form rod estimate).  Held-out states of the experiment ``"extrapolation"`` are compared but
    do not choose the form.  after_sweep : ``after_sweep(records)`` is run here while the forms are fitted in
    a worker process (:func:`validation.infra.runner.run_beside`; e.g. the FEM's refined solves of
    :func:`validation.checks.fem_error.estimate_for_heldout`, which use the other cores); its result is
    ``res.after_sweep``.  mounting : how the actuator is held (:data:`validation.reference.designs.MOUNTINGS`;
    the gravity vector of the states with gravity, in the FEM and in the reduced model alike).

    A form with the series shear compliance (``pressure_ei_shear``) does not fit it: s(p) = s0 + s1 p̂ is measured
    on the FEM's straight pressure-only states (:func:`measure_straight_shear`; the tips and markers of the fit
    see only part of the FEM's rotation-free motion, which is spread along the body, docs/identification.md §4b)
    and held there, reported as held at the value measured on the FEM's straight states
    (``res.meta["straight_shear"]``: the pressures, the values and the law); the rest is fitted given it.
    """
    from ancf.params import TENDONS_MAX, TENDONS_MIN
    from validation.reference.designs import mounting_gravity
    from validation.reference.fem_sweep import FemSpec, check_cases, run_cases, run_rod
    from validation.infra.runner import check_workers, in_background
    check_workers(workers)
    n_tendons = len(geometry.tendon_angles)
    if not TENDONS_MIN <= n_tendons <= TENDONS_MAX:      # before any FEM solve: the result could not be written
        raise ConfigError(f"the design has {n_tendons} tendon(s): the reduced model (an actuator file) takes "
                          f"{TENDONS_MIN} … {TENDONS_MAX}, so it cannot be identified from it; the FEM alone "
                          f"(bellows fem solve --design) takes it")
    g_vec = mounting_gravity(mounting)
    spec = FemSpec(geometry, material, mesh, gravity=g_vec)
    if cases not in ("default", "informative"):
        raise InputError(f"cases must be 'default' or 'informative', got {cases!r}")
    if design is None and cases == "default":
        design = default_design(tension_max=tension_max, pressure_max=pressure_max,
                                tendon_distance=geometry.tendon_radius, length=geometry.length,
                                n_tendons=len(geometry.tendon_angles))
    if design is not None:
        if not design.training:
            raise InputError("the design has no training cases")
        check_cases(spec, design.cases)                  # before the first FEM solve
    # the fits' kernels compile beside the FEM (its own kernels compile in run_rod, on the other core) at the same
    # priority: at nice 19 the sweep's two workers starved the compiler, it was stopped unfinished when the sweep
    # ended and the fits compiled again on the critical path (docs/identification.md §Measured)
    with in_background(compile_fit_kernels, nice=0):
        rod = run_rod(spec, cache_dir=cache_dir)
        base = fem_base_params(geometry, material, n_elements=n_elements, tension_max=tension_max,
                               pressure_max=pressure_max, rod=rod, gravity=g_vec)
        if design is None:
            from validation.identification.design_select import informative_design
            richest = max((get_form(f, fit_distance) for f in forms), key=lambda fm: fm.n)
            b0 = base.replace(gravity=(0.0, 0.0, 0.0))
            design = informative_design(richest, b0, initial_theta(richest, rod, b0), tension_max=tension_max,
                                        pressure_max=pressure_max, tendon_distance=geometry.tendon_radius,
                                        length=geometry.length, n_tendons=len(geometry.tendon_angles),
                                        tendon_angles=geometry.tendon_angles).design
            check_cases(spec, design.cases)
        records = run_cases(spec, design.cases, compliance=(lambda c: c.role == "heldout") if compliance else False,
                            workers=workers, scheduler=scheduler, cache_dir=cache_dir, progress=progress)
        shear = measure_straight_shear(spec, records, rod, cache_dir=cache_dir) if any(
            "s0" in get_form(f, fit_distance).names for f in forms) else None
    marker_s = [f * geometry.length for f in MARKER_FRACTIONS]
    failed = [{"label": r.case.label, "role": r.case.role, "error": r.error} for r in records if not r.ok]
    tr = [r for r in records if r.case.role == "train" and r.ok]
    ho = [r for r in records if r.case.role == "heldout" and r.ok and r.case.experiment != EXTRAPOLATION]
    if len(tr) < max(4, len(design.training) // 2):
        # a ConfigError (the design cannot be identified on this FEM): ConvergenceError needs a residual history
        raise ConfigError(f"the FEM failed on {len(design.training) - len(tr)} of {len(design.training)} "
                          f"training cases (e.g. {failed[0]['label']}: {failed[0]['error']}); too few remain "
                          "to identify the model — lower the design's loads or refine the mesh")
    train = observations_from_records(tr, marker_s)
    heldout = observations_from_records(ho, marker_s) if ho else None
    fit_base = base.replace(gravity=(0.0, 0.0, 0.0)) if not np.any(train.gravity) else base
    fit_kw = dict(train=train, base=fit_base, heldout=heldout, forms=forms, rod=rod, fit_distance=fit_distance,
                  absolute_sigma=False, source="fem", measured=_measured_shear(shear),
                  heldout_compliance=[None if r.compliance_tension is None else
                                      (r.compliance_tension, r.compliance_locked) for r in ho] if ho else None)
    if after_sweep is None:
        res = identify(**fit_kw)
    else:
        from validation.infra.runner import run_beside
        res, side = run_beside(identify, fit_kw, lambda: after_sweep(records))
        res.after_sweep = side
    _finalise_params(res, base)
    res.design, res.records = design, records
    res.meta = {"mesh": str(mesh), "design": describe_geometry(geometry), "geometry": to_jsonable(_geometry_meta(geometry)),
                "material": to_jsonable(vars(material)),
                "marker_s_m": marker_s, "failed_cases": failed, "mounting": mounting, "straight_shear": shear}
    return res


def _measured_shear(shear: Optional[dict]) -> Optional[dict]:
    """The ``measured`` argument of :func:`identify` from :func:`measure_straight_shear`'s result: s0, s1 held at the
    FEM's straight-state law (None: nothing measured, the fit identifies them)."""
    if not shear:
        return None
    s0, s1 = shear["coeffs_m_per_N"][:2]
    return {"s0": (float(s0), MEASURED_SHEAR), "s1": (float(s1), MEASURED_SHEAR)}


# ---------------------------------------------------------------------------------------------- from rig data
def from_measurements(path, base: Optional[ActuatorParams] = None, *, forms: Sequence[str] = FORMS,
                      heldout_fraction: float = 0.25, seed: int = 0, fit_distance: bool = False,
                      gravity: bool = True, absolute_sigma: Optional[bool] = None,
                      progress: Optional[Callable[[str], Any]] = None, masses: str = "free",
                      workers: Optional[int] = None) -> IdentificationResult:
    """Identify the reduced model from measured static states (HDF5 run log / static-states file or CSV;
    ``docs/data-formats.md``).

    base : the actuator the states were measured on (length, tendon routing, masses, limits; required — there
    is no default, a wrong actuator gives wrong numbers), whose stiffness is the starting point; heldout_fraction : share of the states held out (random, seeded)
    to choose the model form (0: choose on the training error); gravity : the states were measured under
    gravity (the actuator's weight from ``base`` acts).  States with labels starting with ``heldout`` are
    held out deterministically instead.  What the states cannot tell is checked before the fits
    (``res.information``, ``res.warnings``; :mod:`validation.identification.information`): parameters they do not
    determine are held at ``base``'s values and reported as not determined.  progress : ``progress(line)`` per
    form fitted (:func:`identify`).  masses : ``"free"`` (default, under gravity) — the line mass [kg/m] and the
    tip mass [kg] are parameters of the fit, starting at ``base``'s (held there, and said so, when the states do
    not determine them: known tip loads at several pressures do); ``"base"`` — held at ``base``'s values.
    workers : processes fitting the forms side by side (default: one per core; the result is the same for any
    number, :func:`identify`).
    """
    from hardware.static_states import StaticStates, read_static_states
    if base is None:
        raise InputError("from_measurements needs base=: the actuator the states were measured on (ActuatorParams, "
                         "e.g. ancf.presets.get('actuator.toml')); there is no default")
    if not isinstance(base, ActuatorParams):
        raise InputError(f"base must be ActuatorParams, got {type(base).__name__}")
    states = path if isinstance(path, StaticStates) else read_static_states(path)
    if states.n_tendons != base.n_tendons:
        raise InputError(f"the states have {states.n_tendons} tensions per state; the base actuator has "
                         f"{base.n_tendons} tendons")
    if not (0.0 <= heldout_fraction < 1.0):
        raise InputError(f"heldout_fraction must be in [0, 1), got {heldout_fraction}")
    if masses not in MASS_CHOICES:
        raise InputError(f"masses must be one of {', '.join(MASS_CHOICES)}, got {masses!r}")
    obs = observations_from_states(states, gravity=gravity)
    labels = obs.labels
    ho = np.array([str(lb).startswith("heldout") for lb in labels])
    if not ho.any() and heldout_fraction > 0:
        rng = np.random.default_rng(seed)
        n_ho = int(round(heldout_fraction * obs.n))
        ho[rng.choice(obs.n, size=n_ho, replace=False)] = True
    train, heldout = obs.subset(~ho), (obs.subset(ho) if ho.any() else None)
    fit_base = base if gravity else base.replace(gravity=(0.0, 0.0, 0.0))
    res = identify(train, fit_base, heldout=heldout, forms=forms, fit_distance=fit_distance,
                   absolute_sigma=absolute_sigma, source="measurements", progress=progress, check_information=True,
                   fit_masses=masses == "free" and gravity and bool(np.any(base.gravity)), workers=workers)
    _finalise_params(res, base)
    res.meta = {"path": str(path) if not isinstance(path, StaticStates) else "<StaticStates>",
                "n_states": obs.n, "n_heldout": int(ho.sum()), "seed": seed}
    if states.meta.get("torn_rows"):              # a state the writer did not finish: not used, reported
        res.meta["torn_rows"] = list(states.meta["torn_rows"])
    return res
