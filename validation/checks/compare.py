r"""The identified reduced model against the FEM on held-out states: shapes, tips and compliance matrices.

For every held-out state (loads never used in the fit) both models are solved and compared:

* tip position error ‖p_ANCF − p_FEM‖ [m] and in % of the length L;
* centreline shape error: the largest distance between the two centrelines at the same undeformed arc
  length (17 points along the body) [m], in % of L;
* tip compliance 3×3 [m/N], tensions held (``C_t``) and all tendons locked (``C_l``), both models with the
  same rule for which locked tendons are taut (complementarity along a small downward load, see
  :func:`ancf.compliance.active_set` and :func:`validation.reference.fem_sweep.locked_compliance`); the FEM's from its
  condensed tangent;
* per-direction stiffness k(u) = 1/(uᵀ C u) along x, y, z [N/m] and its relative error; the relative error of
  the whole matrix ‖C_ANCF − C_FEM‖_F / ‖C_FEM‖_F; the locked/constant-tension stiffness ratio along z, per
  state side by side (``ratio_per_state``: FEM, reduced model, their difference and the taut tendons of each;
  on a straight tube the difference is the FEM's rotation-free lateral compliance, docs/identification.md §4b);
* for a state with a slack tendon, the locked compliance of both signs of the load direction, each with the taut
  set that sign makes taut (a slack tendon that −z stretches is slack under +z), both models by the same rule
  (:func:`locked_both_signs`; ``locked_by_sign`` of each row and of the result).

Targets (the paper, against experiments): shape error < 2.5 % of L, compliance error < 5 %.  A target is
``"met"`` only when it was checked on every held-out state; a state that failed (FEM or ANCF) or gave a NaN
makes it ``"incomplete"`` (``met`` False, the states listed under ``incomplete``), never met.

Gravity acts in both models exactly as in the FEM state: a held-out state with gravity loads the rod with its
weight along the identified actuator's gravity vector (the design's mounting), a gravity-free state runs the rod
without weight; every row states which (``gravity``: on/off, ``gravity_m_per_s2``: the vector the rod used).

The Fig. 9 analogue (:func:`stiffness_vs_tension`): the vertical tip stiffness vs the top tendon's tension
T1 ∈ {0, …, 5} N at p ∈ {0, 25, 50} kPa, with gravity, tensions held and tendons locked, both models.
"""

from __future__ import annotations

import math

from dataclasses import dataclass, field
from typing import Optional, Sequence

import numpy as np

from ancf import ActuatorParams, Model
from ancf import compliance as cp
from ancf.errors import BellowsError, ConfigError, InputError
from ancf.export import to_jsonable

from validation.reference.experiments import EXTRAPOLATION, Design, LoadCase, default_design
from validation.reference.fem_sweep import FemRecord, FemSpec, run_cases
from validation.identification.forms import position_matrix

__all__ = ["ValidationResult", "validate", "compare_records", "ratio_row", "locked_both_signs", "stiffness_vs_tension",
           "SHAPE_TARGET_PCT", "COMPLIANCE_TARGET_PCT"]

SHAPE_TARGET_PCT = 2.5
COMPLIANCE_TARGET_PCT = 5.0
N_SHAPE_POINTS = 17
AXES = {"x": np.array([1.0, 0.0, 0.0]), "y": np.array([0.0, 1.0, 0.0]), "z": np.array([0.0, 0.0, 1.0])}


@dataclass
class ValidationResult:
    """ANCF vs FEM on held-out states (SI; see the module docstring).

    rows : one dict per state (label, loads, tips, errors, compliances, stiffnesses, ratios)
    tip_error_pct : {"mean", "max"} of the tip error in % of L;  shape_error_pct : {"mean", "max"}
    compliance_error_pct : {"tension": {"mean", "max"}, "locked": {...}} of the matrix error (Frobenius)
    stiffness_error_pct : {"tension"|"locked": {"x"|"y"|"z": max |k_ANCF/k_FEM − 1| × 100}}
    ratio : {"ancf"|"fem": {"mean", "max"}} of the locked/constant vertical stiffness ratio k_z,locked/k_z,held
    ratio_per_state : one dict per state with compliances: label, pressure_kPa, tensions_N, tip_force_N,
    ``fem``, ``ancf`` (the ratio [–]), ``difference_pct`` = 100 (ancf/fem − 1), ``taut_fem``, ``taut_ancf``
    (indices of the locked taut tendons)
    targets : the paper's targets and whether they are met;  params : the reduced model used
    fem_error : the FEM's own discretisation error beside these errors (:func:`validation.checks.fem_error.assess`;
    empty when not estimated)
    extrapolation : held-out states outside the training hull (experiment ``"extrapolation"``,
    :mod:`validation.identification.design_select`), reported apart and left out of every figure above: ``states`` (labels),
    ``tip_error_pct``, ``shape_error_pct``, ``compliance_error_pct`` ({"mean", "max"}); empty without such states
    locked_by_sign : states with a slack tendon, whose locked response is piecewise linear (a slack tendon is taut
    for one sign of the load and not the other): ``states`` (labels), ``directions`` (the load direction u and −u),
    ``error_pct`` ({"u"|"-u": {"mean", "max"}} of the Frobenius error of the locked compliance with the taut set of
    that sign) and ``along_error_pct`` (the same for the compliance along the load, uᵀ C u); per state in the
    row's ``locked_by_sign`` (:func:`locked_both_signs`); empty without such states or FEM data for −u
    """
    rows: list
    length: float
    params: ActuatorParams
    tip_error_pct: dict = field(default_factory=dict)
    shape_error_pct: dict = field(default_factory=dict)
    compliance_error_pct: dict = field(default_factory=dict)
    stiffness_error_pct: dict = field(default_factory=dict)
    ratio: dict = field(default_factory=dict)
    ratio_per_state: list = field(default_factory=list)
    targets: dict = field(default_factory=dict)
    failures: list = field(default_factory=list)
    fem_error: dict = field(default_factory=dict)
    extrapolation: dict = field(default_factory=dict)
    locked_by_sign: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        return to_jsonable({k: getattr(self, k) for k in ("rows", "length", "tip_error_pct", "shape_error_pct",
                                                         "compliance_error_pct", "stiffness_error_pct", "ratio",
                                                         "ratio_per_state", "targets", "failures", "extrapolation",
                                                         "locked_by_sign")}
                           | {"params": self.params.to_toml()}
                           | {"fem_discretisation_error": self.fem_error or None})

    # -------------------------------------------------------------------- display
    def _display_rows(self) -> list[tuple[str, str]]:
        """(quantity, value) of the summary, errors in % of the length L."""
        pct = lambda d: f"mean {d['mean']:.2f} %, max {d['max']:.2f} %" if d else "–"  # noqa: E731
        rows = [("held-out states compared", str(len(self.rows))), ("tip error [% L]", pct(self.tip_error_pct)),
                ("shape error [% L]", pct(self.shape_error_pct))]
        if self.compliance_error_pct:
            rows += [(f"compliance error, {w} [%]", pct(self.compliance_error_pct[m]))
                     for m, w in (("tension", "tensions held"), ("locked", "tendons locked"))]
        for name, t in self.targets.items():
            rows.append((f"target {name} < {t['target']:g} %", f"{t['value']:.2f} %: {t.get('status', '')}"))
        if self.failures:
            rows.append(("not compared", ", ".join(f"{f['label']} ({f['model']})" for f in self.failures)))
        if self.locked_by_sign:
            rows += [(f"locked compliance, slack tendon taut as load {k} makes it [%]",
                      pct(self.locked_by_sign["error_pct"][k])) for k in ("u", "-u")]
        if self.extrapolation:
            rows.append(("extrapolation, tip error [% L]", pct(self.extrapolation.get("tip_error_pct"))))
        return rows

    def __repr__(self) -> str:
        """One line: states compared, tip and shape errors (mean/max, % of L), the targets' verdicts."""
        st = lambda d: f"{d['mean']:.2f}/{d['max']:.2f} % L" if d else "–"  # noqa: E731
        targets = ", ".join(f"{k}: {t.get('status', '')}" for k, t in self.targets.items())
        return (f"ValidationResult({len(self.rows)} states, tip error mean/max {st(self.tip_error_pct)}, "
                f"shape error mean/max {st(self.shape_error_pct)}, {len(self.failures)} not compared"
                + (f", targets {targets}" if targets else "") + ")")

    def _repr_html_(self) -> str:
        from ancf.htmlrepr import table
        return table(f"Reduced model vs FEM on held-out states (L = {1e3 * self.length:.1f} mm)",
                     self._display_rows(), header=("quantity", "value"))


def _max_abs(x) -> float:
    x = np.abs(np.asarray([v for v in x if v is not None and np.isfinite(v)], float))
    return float(x.max()) if x.size else float("nan")


def _stats(x) -> dict:
    x = np.asarray([v for v in x if v is not None and np.isfinite(v)], float)
    return {"mean": float(x.mean()), "max": float(x.max())} if x.size else {"mean": float("nan"), "max": float("nan")}


#: A compliance along an axis below this share of the matrix norm counts as rigid (e.g. the axial direction
#: with every inextensible tendon locked and taut: exactly zero up to round-off).
RIGID_SHARE = 1e-9


def _axis_stiffness(C: np.ndarray, u: np.ndarray) -> float:
    """1/(uᵀ C u) [N/m]; ``inf`` where the compliance along u vanishes (rigid direction)."""
    c = float(u @ C @ u)
    return float("inf") if c <= RIGID_SHARE * float(np.linalg.norm(C)) else 1.0 / c


def _stiffness_error_pct(ka: float, kf: float) -> float:
    """100 (k_ANCF/k_FEM − 1); 0 when both are rigid, NaN when only one is (reported, not averaged)."""
    if math.isinf(ka) or math.isinf(kf):
        return 0.0 if math.isinf(ka) and math.isinf(kf) else float("nan")
    return 100 * (ka / kf - 1)


def compare_records(params: ActuatorParams, records: Sequence[FemRecord], *, load_direction=(0.0, 0.0, -1.0),
                    compliance: bool = True) -> ValidationResult:
    """Compare the reduced model with ``params`` against FEM records of the same load cases."""
    if not isinstance(params, ActuatorParams):
        raise InputError(f"params must be ActuatorParams, got {type(params).__name__}")
    L = params.length
    # gravity as the FEM state had it, in both models alike: a state with gravity loads the rod with its weight
    # along params.gravity (the design's mounting), a gravity-free state runs the rod without weight; each row
    # says which ("gravity", "gravity_m_per_s2")
    model_g = Model(params)
    model_0 = Model(params.replace(gravity=(0.0, 0.0, 0.0))) if np.any(params.gravity) else model_g
    s = np.linspace(0.0, L, N_SHAPE_POINTS)
    S = position_matrix(params.n_elements, L, s)
    rows, failures = [], []
    for rec in records:
        c = rec.case
        if not rec.ok:
            failures.append({"label": c.label, "model": "FEM", "error": rec.error})
            continue
        model = model_g if c.gravity else model_0
        try:
            eq = model.fk(c.tensions, c.pressure, c.tip_force, check_limits=False)
        except BellowsError as exc:
            failures.append({"label": c.label, "model": "ANCF", "error": f"{type(exc).__name__}: {exc}"})
            continue
        shape_ancf = (S @ eq.q).reshape(-1, 3)
        shape_fem = rec.centreline_at(s)
        d_shape = np.linalg.norm(shape_ancf - shape_fem, axis=1)
        row = {"label": c.label, "experiment": c.experiment, "tensions_N": list(c.tensions),
               "pressure_Pa": c.pressure, "tip_force_N": list(c.tip_force), "gravity": c.gravity,
               "gravity_m_per_s2": list(model.params.gravity),
               "tip_fem_m": rec.tip_position, "tip_ancf_m": eq.tip,
               "tip_error_m": float(np.linalg.norm(eq.tip - rec.tip_position)),
               "shape_error_m": float(d_shape.max()), "shape_s_m": s, "shape_deviation_m": d_shape,
               "centreline_fem_m": shape_fem, "centreline_ancf_m": shape_ancf}
        row["tip_error_pct"] = 100 * row["tip_error_m"] / L
        row["shape_error_pct"] = 100 * row["shape_error_m"] / L
        if compliance and rec.compliance_tension is not None:
            Ct = cp.tension(model, eq).C_p
            Cl = cp.locked(model, eq, method="exact", load_direction=load_direction)
            row.update(C_tension_fem=rec.compliance_tension, C_tension_ancf=Ct, C_locked_fem=rec.compliance_locked,
                       C_locked_ancf=Cl.C_p, locked_active_ancf=list(Cl.active),
                       locked_active_fem=list(rec.extra.get("locked_active", [])))
            for mode, Ca, Cf in (("tension", Ct, rec.compliance_tension), ("locked", Cl.C_p, rec.compliance_locked)):
                row[f"C_{mode}_error_pct"] = float(100 * np.linalg.norm(Ca - Cf) / np.linalg.norm(Cf))
                for ax, u in AXES.items():
                    ka, kf = _axis_stiffness(Ca, u), _axis_stiffness(Cf, u)
                    row[f"k_{mode}_{ax}_ancf_N_per_m"], row[f"k_{mode}_{ax}_fem_N_per_m"] = ka, kf
                    row[f"k_{mode}_{ax}_error_pct"] = _stiffness_error_pct(ka, kf)
            for who in ("ancf", "fem"):
                row[f"ratio_z_{who}"] = row[f"k_locked_z_{who}_N_per_m"] / row[f"k_tension_z_{who}_N_per_m"]
            if "compliance_locked_opposite" in rec.extra:      # a slack tendon: the taut set depends on the sign
                row["locked_by_sign"] = locked_both_signs(model, eq, rec, load_direction, Cl)
        rows.append(row)
    out = ValidationResult(rows, L, params, failures=failures)
    failed = [f["label"] for f in failures]
    # states outside the training hull (validation.identification.design_select) are reported apart: the figures below judge
    # the model where it was identified
    ex_rows = [r for r in rows if r["experiment"] == EXTRAPOLATION]
    rows = [r for r in rows if r["experiment"] != EXTRAPOLATION]
    if ex_rows:
        ex_c = [r for r in ex_rows if "C_tension_error_pct" in r]
        out.extrapolation = {"states": [r["label"] for r in ex_rows],
                             "tip_error_pct": _stats([r["tip_error_pct"] for r in ex_rows]),
                             "shape_error_pct": _stats([r["shape_error_pct"] for r in ex_rows])}
        if ex_c:
            out.extrapolation["compliance_error_pct"] = {
                m: _stats([r[f"C_{m}_error_pct"] for r in ex_c]) for m in ("tension", "locked")}
    if not rows:
        out.targets = {name: _target(t, float("nan"), failed) for name, t in
                       (("shape_pct", SHAPE_TARGET_PCT), ("compliance_pct", COMPLIANCE_TARGET_PCT))}
        return out
    out.tip_error_pct = _stats([r["tip_error_pct"] for r in rows])
    out.shape_error_pct = _stats([r["shape_error_pct"] for r in rows])
    with_c = [r for r in rows if "C_tension_error_pct" in r]
    if with_c:
        out.compliance_error_pct = {m: _stats([r[f"C_{m}_error_pct"] for r in with_c]) for m in ("tension", "locked")}
        out.stiffness_error_pct = {m: {ax: _max_abs([r[f"k_{m}_{ax}_error_pct"] for r in with_c]) for ax in AXES}
                                   for m in ("tension", "locked")}
        out.ratio = {"ancf": _stats([r["ratio_z_ancf"] for r in with_c]), "fem": _stats([r["ratio_z_fem"] for r in with_c])}
        out.ratio_per_state = [ratio_row(r) for r in with_c]
        out.locked_by_sign = _sign_summary([r for r in with_c if "locked_by_sign" in r], load_direction)
    bad_shape = failed + [r["label"] for r in rows if not np.isfinite(r["shape_error_pct"])]
    out.targets = {"shape_pct": _target(SHAPE_TARGET_PCT, out.shape_error_pct["max"], bad_shape)}
    if with_c:
        worst = max(out.compliance_error_pct["tension"]["max"], out.compliance_error_pct["locked"]["max"])
        # a state without compliances (when others have them) or with a NaN compliance error was not checked
        bad_c = failed + [r["label"] for r in rows if r not in with_c or not (
            np.isfinite(r["C_tension_error_pct"]) and np.isfinite(r["C_locked_error_pct"]))]
        out.targets["compliance_pct"] = _target(COMPLIANCE_TARGET_PCT, worst, bad_c)
    return out


def locked_both_signs(model: Model, eq, rec: FemRecord, load_direction, locked_u: cp.Compliance) -> list:
    """The locked tip compliance of a state with a slack tendon for both signs of the load direction u (3,):
    each with the taut set that sign makes taut, by the same complementarity rule in both models (the FEM's:
    :func:`validation.reference.fem_sweep.locked_compliance`; the rod's: :func:`ancf.compliance.locked`).  One
    dict per sign ("u" then "-u"): ``direction``, ``taut_fem`` / ``taut_ancf`` (tendon indices),
    ``C_fem_m_per_N`` / ``C_ancf_m_per_N`` (3, 3), ``error_pct`` (Frobenius, 100 ‖C_ANCF − C_FEM‖/‖C_FEM‖),
    ``along_fem_m_per_N`` / ``along_ancf_m_per_N`` (uᵀ C u) and ``along_error_pct`` = 100 (ancf/fem − 1)."""
    u = np.asarray(load_direction, float) / np.linalg.norm(load_direction)
    locked_opp = cp.locked(model, eq, method="exact", load_direction=-u)
    out = []
    for name, d, Cf, taut_f, Ca in (
            ("u", u, rec.compliance_locked, rec.extra.get("locked_active", []), locked_u),
            ("-u", -u, rec.extra["compliance_locked_opposite"], rec.extra.get("locked_active_opposite", []),
             locked_opp)):
        cf, ca = float(d @ Cf @ d), float(d @ Ca.C_p @ d)
        out.append({"sign": name, "direction": d, "taut_fem": [int(i) for i in taut_f],
                    "taut_ancf": [int(i) for i in Ca.active], "C_fem_m_per_N": Cf, "C_ancf_m_per_N": Ca.C_p,
                    "error_pct": float(100 * np.linalg.norm(Ca.C_p - Cf) / np.linalg.norm(Cf)),
                    "along_fem_m_per_N": cf, "along_ancf_m_per_N": ca,
                    "along_error_pct": 100 * (ca / cf - 1) if cf > 0 else float("nan")})
    return out


def _sign_summary(rows: list, load_direction) -> dict:
    """:attr:`ValidationResult.locked_by_sign` from the rows that carry both signs."""
    if not rows:
        return {}
    u = np.asarray(load_direction, float) / np.linalg.norm(load_direction)
    return {"states": [r["label"] for r in rows], "directions": {"u": u, "-u": -u},
            "error_pct": {k: _stats([s["error_pct"] for r in rows for s in r["locked_by_sign"] if s["sign"] == k])
                          for k in ("u", "-u")},
            "along_error_pct": {k: _stats([abs(s["along_error_pct"]) for r in rows for s in r["locked_by_sign"]
                                           if s["sign"] == k]) for k in ("u", "-u")}}


def ratio_row(row: dict) -> dict:
    """The locked/constant vertical stiffness ratio of one compared state, FEM and reduced model side by side
    (see :class:`ValidationResult`); NaN difference when either ratio is not finite (a rigid direction)."""
    f, a = float(row["ratio_z_fem"]), float(row["ratio_z_ancf"])
    diff = 100 * (a / f - 1) if math.isfinite(a) and math.isfinite(f) and f != 0 else float("nan")
    return {"label": row["label"], "pressure_kPa": row["pressure_Pa"] / 1e3, "tensions_N": list(row["tensions_N"]),
            "tip_force_N": list(row["tip_force_N"]), "fem": f, "ancf": a, "difference_pct": diff,
            "taut_fem": list(row.get("locked_active_fem", [])), "taut_ancf": list(row.get("locked_active_ancf", []))}


def _target(target: float, value: float, incomplete: list) -> dict:
    """A target's verdict: ``"met"`` only when every state was checked (no failed state, no NaN) and the worst
    value is below the target; ``"incomplete"`` (``met`` False) when any state is missing, ``"not met"``
    otherwise."""
    complete = not incomplete and math.isfinite(value)
    met = bool(complete and value < target)
    status = "met" if met else ("incomplete" if not complete else "not met")
    return {"target": target, "value": value, "met": met, "status": status, "incomplete": list(incomplete)}


def _spec(fem_model) -> FemSpec:
    if isinstance(fem_model, FemSpec):
        return fem_model
    geo, mat = getattr(fem_model, "geometry", None), getattr(fem_model, "material", None)
    if geo is None or mat is None:
        raise InputError("fem_model must be a fem_reference.BellowsModel or a validation.reference.fem_sweep.FemSpec")
    level = getattr(fem_model.bmesh, "level_name", None) or "coarse"
    return FemSpec(geo, mat, level)


def check_actuator_matches(params: ActuatorParams, geometry) -> None:
    """ConfigError unless the reduced model describes the FEM design's actuator: the same number of tendons
    and the same length (within 0.1 %).  Checked before any FEM solve: comparing a 200 mm model with a
    160 mm bellows would spend minutes on FEM solves to report a meaningless error."""
    m = len(geometry.tendon_angles)
    if params.n_tendons != m:
        raise ConfigError(f"the actuator {params.name!r} has {params.n_tendons} tendons and the FEM design {m}: "
                          "validate an actuator file identified from this design (or choose its design with --design)")
    if abs(params.length - geometry.length) > 1e-3 * geometry.length:
        raise ConfigError(f"the actuator {params.name!r} is {params.length * 1e3:g} mm long and the FEM design "
                          f"{geometry.length * 1e3:g} mm: validate an actuator file identified from this design (or "
                          "choose its design with --design)")


def default_heldout(params: ActuatorParams, geometry) -> list[LoadCase]:
    """The held-out states of :func:`validation.reference.experiments.default_design` for this actuator's range on the
    FEM design ``geometry``."""
    return list(default_design(tension_max=params.tension_max, pressure_max=params.pressure_max,
                               tendon_distance=geometry.tendon_radius, length=geometry.length,
                               n_tendons=len(geometry.tendon_angles)).heldout)


def validate(params: ActuatorParams, fem_model, states=None, *, workers: Optional[int] = None, scheduler=None,
             cache_dir=None, progress: bool = True, records: Optional[Sequence[FemRecord]] = None) -> ValidationResult:
    """Identified reduced model vs the FEM on held-out states.

    params : the reduced model's parameters; fem_model : a ``fem_reference.BellowsModel`` (its geometry,
    material and mesh are used; the solves run through the cached sweep) or a ``FemSpec``; states : a
    :class:`Design` (its held-out cases), a list of :class:`LoadCase`, or None for the default held-out
    design of this actuator's range; records : FEM results already computed for these states (skips the FEM).
    """
    if records is None:
        spec = _spec(fem_model)
        check_actuator_matches(params, spec.geometry)
        if states is None:
            states = default_heldout(params, spec.geometry)
        elif isinstance(states, Design):
            states = states.heldout
        states = list(states)
        if not states or not all(isinstance(c, LoadCase) for c in states):
            raise InputError("states must be a non-empty list of validation.reference.experiments.LoadCase")
        records = run_cases(spec, states, compliance=True, workers=workers, scheduler=scheduler,
                            cache_dir=cache_dir, progress=progress)
    return compare_records(params, records)


def stiffness_cases(pressures=(0.0, 25e3, 50e3), tensions=(0, 1, 2, 3, 4, 5), n_tendons: int = 3) -> list[LoadCase]:
    """The Fig. 9 protocol's states: top tendon at T1, the others slack, with gravity."""
    out = []
    for p in pressures:
        for t in tensions:
            T = np.zeros(n_tendons)
            T[0] = t
            out.append(LoadCase(tuple(T), p, (0.0, 0.0, 0.0), True, "fig9", "heldout"))
    return out


def stiffness_vs_tension(params: ActuatorParams, fem_model, *, pressures=(0.0, 25e3, 50e3),
                         tensions=(0, 1, 2, 3, 4, 5), workers: Optional[int] = None, scheduler=None,
                         cache_dir=None, progress: bool = True, records=None) -> dict:
    """Fig. 9 analogue: vertical tip stiffness [N/m] vs T1 [N] at each pressure [Pa], tensions held and tendons
    locked (same taut-set rule in both models), ANCF and FEM, with gravity."""
    cases = stiffness_cases(pressures, tensions, params.n_tendons)
    if records is None:
        records = run_cases(_spec(fem_model), cases, compliance=True, workers=workers, scheduler=scheduler,
                            cache_dir=cache_dir, progress=progress)
    val = compare_records(params, records)
    out = {"pressures_Pa": list(pressures), "tensions_N": list(tensions), "curves": {}, "failures": val.failures}
    for p in pressures:
        rows = [r for r in val.rows if r["pressure_Pa"] == p]
        out["curves"][f"{p / 1e3:g} kPa"] = {
            "T1_N": [r["tensions_N"][0] for r in rows],
            **{f"k_{m}_{w}_N_per_m": [r[f"k_{m}_z_{w}_N_per_m"] for r in rows]
               for m in ("tension", "locked") for w in ("ancf", "fem")}}
    out["rows"] = val.rows
    return out
