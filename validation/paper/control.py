r"""The paper's controller studies, reproduced on the simulated plant (Sec. IV-B Table I, the FK- vs
IK-derived compliance ablation, Sec. V-E continuous and cyclic loading).

Every function takes keyword arguments only (all with defaults), returns a JSON-friendly dict (SI units:
errors in metres, plus ``*_mm`` copies for display beside the paper) with a printable comparison in
``"table"``, and writes ``<name>.json`` and ``<name>.png`` into ``out`` when it is given.

Set-up shared by the studies (flagged choices — the paper does not give them):

* Configurations at p = 60 kPa, defined by the direction of the unloaded tip (the elevation of the tip
  tangent): upward +4.2°, horizontal −0.5°, downward −8.8° (``DIRECTIONS``; with today's ``paper``
  preset these are the tensions (3.4, 1.2, 1.2), (2.2, 1.6, 1.6), (0.8, 3.0, 3.0) N).  The tensions are
  derived from the preset by :func:`configurations`: for each direction, among symmetric tension pairs
  (T₁, T₂ = T₃) that give it, the one whose IK keeps the most margin to the tension limits both unloaded
  and under the heaviest stated load (60 g for Table I, 110 g for the loading study).  So the studies
  run on any preset — e.g. a softer reading of the paper — without hand-tuned tension triples.
* "Stochastic tip load": per configuration a seeded draw, mass m ~ U(20, 60) g along gravity plus
  horizontal components ~ N(0, 0.03 N); a draw the IK cannot compensate within [0, 5] N is re-drawn.
* The plant is the locked-length FK with the load hidden (:class:`controller.SimulatedPlant`); by default
  perfect (the controllers' own model, no noise), optionally mismatched and noisy (``plant_options``, e.g.
  ``PlantOptions.mismatched``; ``bellows paper table1 --mismatch``).  :func:`plant_summary` states which, in
  each result's ``settings``.  The paper's numbers are measurements on its physical rig.
* VF-CC with χ = 10 N/m per axis (proportional law, :mod:`controller.vfcc`).
* Tendon friction (:func:`table1_friction`, ``table1(friction=…)``, ``bellows paper table1 --plant-friction``):
  Table I once per plant coefficient μ, the controllers' model frictionless, and optionally the friction-aware
  LACC (:mod:`controller.friction_aware`) whose model has the plant's μ (docs/friction.md).
* LACC as Algorithm 1 with the exact locked compliance (the product's default) and, beside it, with the
  paper's IK-derived compliance (eq. 15/16): with the exact one Table I comes out ≈ 1e-5 mm instead of
  0.2–0.44 mm on the perfect plant, and 0.1–0.4 mm on the mismatched one with 0.05 mm tracker noise.

Paper numbers: Table I VF-CC 9.054 / 10.23 / 2.090 mm, LACC 0.020 / 0.028 / 0.006 mm (≥ 99.71 %
reduction); IK-derived compliance converges ≈ 50 % faster than the FK-derived one; loading: continuous
(0 → 110 g → 0 over 50 s) within 0.722 mm, cyclic (0.125 Hz) within 3.573 mm, loop time ≈ 0.5 s.
"""

from __future__ import annotations

import json
import math
import pathlib
import statistics
import time
from typing import Optional, Sequence, Union

import numpy as np

from ancf.export import to_jsonable
from ancf import InfeasibleTargetError, Model, presets
from ancf.errors import BellowsError
from ancf.textfmt import vector
from controller import LACC, VFCC, PlantOptions, SimulatedPlant, run_iterations, run_timed

G = 9.81
PRESSURE = 60e3
DIRECTIONS = {"upward": 4.2, "horizontal": -0.5, "downward": -8.8}     # unloaded tip elevation [deg]
LOADING_DIRECTION = -4.1                # near-horizontal, with room for 110 g
PAPER_PEAK_MASS, PAPER_CYCLIC_MASS = 0.110, 0.080     # Sec. V-E: 0 → 110 g → 0; cyclic (see loading())
#: today's ``paper`` preset: the tensions :func:`configurations` finds for ``DIRECTIONS`` (for reference)
CONFIGURATIONS = {"upward": (3.4, 1.2, 1.2), "horizontal": (2.2, 1.6, 1.6), "downward": (0.8, 3.0, 3.0)}

from validation.paper.numbers import ABLATION as PAPER_ABLATION, LOADING as PAPER_LOADING, TABLE1 as PAPER_TABLE1  # noqa: E402

PathLike = Union[str, pathlib.Path, None]


# ============================================================================== helpers
def _write(out: PathLike, name: str, res: dict, fig=None) -> None:
    if out is None:
        if fig is not None:
            import matplotlib.pyplot as plt
            plt.close(fig)
        return
    out = pathlib.Path(out)
    out.mkdir(parents=True, exist_ok=True)
    (out / f"{name}.json").write_text(json.dumps(to_jsonable(res), indent=2))
    if fig is not None:
        import matplotlib.pyplot as plt
        fig.savefig(out / f"{name}.png", dpi=130)
        plt.close(fig)


def _pyplot():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def _finish_axes(fig, axs, ylabel: str) -> None:
    """Shared end of the one-row figures: y label and legend on the first axes, tight layout."""
    first = np.atleast_1d(axs)[0]
    first.set_ylabel(ylabel)
    first.legend(fontsize=8)
    fig.tight_layout()


def _fmt_table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> str:
    w = [max(len(str(r[i])) for r in [header, *rows]) for i in range(len(header))]
    line = lambda r: "  ".join(str(c).rjust(w[i]) if i else str(c).ljust(w[i]) for i, c in enumerate(r))
    return "\n".join([line(header), line(["-" * x for x in w]), *map(line, rows)])


def _draw_load(model: Model, target, pressure, rng, mass_range, lateral_std, q0, T0, tries: int = 50):
    """A compensable stochastic tip load [N] (see module docstring)."""
    for _ in range(tries):
        mass = rng.uniform(*mass_range)
        F = np.array([rng.normal(0, lateral_std), rng.normal(0, lateral_std), -G * mass])
        try:
            model.ik(target, pressure, F, q0=q0, tensions0=T0)
            return F, mass
        except InfeasibleTargetError:
            continue
    raise BellowsError(f"no compensable load found in {tries} draws (mass range {mass_range} kg)")


def _plant(model, pressure, load, plant_options: Optional[PlantOptions]):
    return SimulatedPlant(model, pressure, load=load, options=plant_options or PlantOptions())


def plant_summary(params, plant_options: Optional[PlantOptions]) -> dict:
    """What the simulated plant of a study is, beside the controllers' model ``params``: ``text`` (one sentence),
    ``model_mismatch`` (the actuator parameters in which the plant differs from the controllers' model),
    ``tracker_noise_std_m`` [m] per axis, ``length_resolution_m``, ``tendon_friction_N``, ``seed``.  The paper's
    numbers come from its physical rig (motion-capture tracker, real actuator); ours from this plant."""
    opts = plant_options or PlantOptions()
    truth = opts.params or params
    skip = ("name", "description")
    mismatch = [k for k in type(params).model_fields if k not in skip and getattr(params, k) != getattr(truth, k)]
    parts = ["simulated plant (locked-length FK, the tip load hidden from the controllers)"]
    parts.append(f"model mismatch in {', '.join(mismatch)}" if mismatch else "no model mismatch (the controllers' own "
                 "model)")
    parts.append(f"tracker noise σ = {opts.noise_std * 1e3:g} mm per axis" if opts.noise_std > 0 else "no tracker noise")
    if opts.length_resolution > 0 or opts.tendon_friction > 0:
        parts.append(f"motor resolution {opts.length_resolution * 1e6:g} µm, tendon friction {opts.tendon_friction:g} N")
    return {"text": ", ".join(parts), "model_mismatch": mismatch, "tracker_noise_std_m": opts.noise_std,
            "length_resolution_m": opts.length_resolution, "tendon_friction_N": opts.tendon_friction,
            "seed": opts.seed}


def tip_elevation_deg(eq) -> float:
    """Elevation of the tip tangent above the base plane [deg] (rotation of the base axis x towards z)."""
    R = eq.tip_rotation
    return math.degrees(math.atan2(R[2, 0], R[0, 0]))


_CONFIG_CACHE: dict = {}


def configurations(params=None, *, pressure: float = PRESSURE, directions: Optional[dict] = None,
                   max_load_mass: float = 0.06, levels: int = 25) -> dict:
    """Tension configurations for stated tip directions, derived from the preset.

    For each ``directions[name]`` (unloaded tip elevation [deg]) and each tension level c on a grid of
    ``levels`` values in [0.05, 0.8] × tension_max, the bending split d (T₁ = c + max(d, 0), T₂ = T₃ = c +
    max(−d, 0)) that gives the direction is found by root finding on the FK; the level whose IK tensions
    keep the largest margin to [tension_min, tension_max] — unloaded and under ``max_load_mass`` [kg]
    hanging on the tip — is chosen.  Returns ``{name: {"tensions": (3,) N, "target": (3,) m,
    "elevation_deg", "margin_N"}}``; raises :class:`BellowsError` if no level has a positive margin."""
    from scipy.optimize import brentq
    params = params or presets.paper()
    directions = DIRECTIONS if directions is None else directions
    key = (params.to_toml(), float(pressure), tuple(sorted(directions.items())), float(max_load_mass), int(levels))
    if key in _CONFIG_CACHE:
        return _CONFIG_CACHE[key]
    model = Model(params)
    if model.m != 3:
        raise BellowsError(f"configurations are defined for 3 tendons; this actuator has {model.m}")
    tmin, tmax = params.tension_min, params.tension_max
    F_load = np.array([0.0, 0.0, -G * max_load_mass])

    def tensions(c, d):
        return np.array([c + max(d, 0.0), c + max(-d, 0.0), c + max(-d, 0.0)])

    out = {}
    for name, theta in directions.items():
        best = None
        for c in np.linspace(0.05, 0.8, levels) * tmax:
            span = tmax - c

            def f(d):
                return tip_elevation_deg(model.fk(tensions(c, d), pressure, (0, 0, 0))) - theta
            try:
                lo, hi = f(-span), f(span)
                if lo * hi > 0:
                    continue
                d = brentq(f, -span, span, xtol=1e-6)
            except BellowsError:
                continue
            T = tensions(c, d)
            ref = model.fk(T, pressure, (0, 0, 0))
            margin = math.inf
            for F in (np.zeros(3), F_load):
                try:
                    ik = model.ik(ref.tip, pressure, F, q0=ref.q, tensions0=ref.tensions)
                except BellowsError:
                    margin = -math.inf
                    break
                margin = min(margin, float(np.min(ik.tensions - tmin)), float(np.min(tmax - ik.tensions)))
            if best is None or margin > best["margin_N"]:
                best = {"tensions": T, "target": ref.tip, "elevation_deg": tip_elevation_deg(ref), "margin_N": margin}
        if best is None or not best["margin_N"] > 0:
            raise BellowsError(f"no tension configuration for a tip elevation of {theta:g}° at {pressure / 1e3:g} kPa "
                               f"keeps the IK within [{tmin:g}, {tmax:g}] N with {max_load_mass * 1e3:g} g on the tip")
        out[name] = best
    _CONFIG_CACHE[key] = out
    return out


def _resolve_configurations(params, pressure, configurations_arg, max_load_mass) -> dict:
    """``{name: tensions}`` from a ``configurations=`` argument: None (the stated directions), ``{name:
    elevation_deg}`` or ``{name: (T1, T2, T3)}``."""
    if configurations_arg is None:
        return {k: v["tensions"] for k, v in configurations(params, pressure=pressure,
                                                             max_load_mass=max_load_mass).items()}
    out, dirs = {}, {}
    for k, v in configurations_arg.items():
        if np.ndim(v) == 0:
            dirs[k] = float(v)
        else:
            out[k] = np.asarray(v, float)
    if dirs:
        for k, v in configurations(params, pressure=pressure, directions=dirs, max_load_mass=max_load_mass).items():
            out[k] = v["tensions"]
    return {k: out[k] for k in configurations_arg}


# ============================================================================== Table I
def table1(*, iterations: int = 5, seed: int = 0, pressure: float = PRESSURE,
           configurations: Optional[dict] = None, mass_range=(0.02, 0.06), lateral_std: float = 0.03,
           compliance: str = "exact", compare: Optional[str] = "ik", chi: float = 10.0,
           vfcc_law: str = "proportional", plant_options: Optional[PlantOptions] = None, params=None,
           friction: Optional[Sequence[float]] = None, friction_aware: bool = False, out: PathLike = None) -> dict:
    """Table I: tip error after ``iterations`` corrections for VF-CC and LACC under a hidden stochastic load.

    configurations : None (the stated tip directions, tensions derived from ``params``), ``{name:
        elevation_deg}`` or ``{name: (T1, T2, T3) [N]}``
    compliance : LACC's compliance ("exact", the default; "ik" = the paper's eq. 15/16; "paper" = eq. 13);
        compare : a second LACC compliance run beside it (None: none)
    friction : plant friction coefficients μ (e.g. ``(0, 0.1, 0.3)``): run :func:`table1_friction` instead — the
        table once per μ on a plant with tendon friction, the controllers' model frictionless (``compare`` unused);
        friction_aware : there, also the friction-aware LACC (:mod:`controller.friction_aware`); None: as before

    Returns ``{configuration: {...}}`` with, each, ``vfcc_error`` / ``lacc_error`` [m] after the last
    iteration, ``reduction`` (fraction, 1 − LACC/VF-CC), ``vfcc_history`` / ``lacc_history`` [m] (index 0 =
    after the initial IK, before any correction), ``compare_error`` / ``compare_history`` (LACC with
    ``compare``), the drawn ``load`` [N], ``target`` [m], the ``tensions_unloaded`` [N], mm copies for
    display and the paper's numbers; plus ``"table"`` (str) and ``"settings"``.  All controllers make all
    ``iterations`` corrections (tolerance 0), as in the paper's "after five iterations".
    """
    if friction is not None or friction_aware:     # plant μ values: the friction study
        mus = (0.0, 0.1, 0.3) if friction is None else friction
        return table1_friction(friction=mus, friction_aware=friction_aware,
                               iterations=iterations, seed=seed, pressure=pressure, configurations=configurations,
                               mass_range=mass_range, lateral_std=lateral_std, compliance=compliance, chi=chi,
                               vfcc_law=vfcc_law, plant_options=plant_options, params=params, out=out)
    params = params or presets.paper()
    model = Model(params)
    truth = Model(plant_options.params) if plant_options is not None and plant_options.params is not None else model
    configs = _resolve_configurations(params, pressure, configurations, mass_range[1])
    rng = np.random.default_rng(seed)
    res: dict = {}
    rows = []
    for name, T in configs.items():
        ref = model.fk(T, pressure, (0, 0, 0))
        F, mass = _draw_load(truth, ref.tip, pressure, rng, mass_range, lateral_std, ref.q, ref.tensions)
        runs = {}
        ctrls = [("vfcc", VFCC(model, pressure, chi=chi, law=vfcc_law, tolerance=0.0)),
                 ("lacc", LACC(model, pressure, compliance=compliance, tolerance=0.0))]
        if compare:
            ctrls.append(("compare", LACC(model, pressure, compliance=compare, tolerance=0.0)))
        for key, ctrl in ctrls:
            runs[key] = run_iterations(ctrl, _plant(model, pressure, F, plant_options), ref.tip,
                                       iterations=iterations, stop_at_tolerance=False, on_error="stop")
        v, lc = runs["vfcc"], runs["lacc"]
        red = 1.0 - lc.final_error / v.final_error if v.final_error > 0 else float("nan")
        entry = {
            "vfcc_error": v.final_error, "lacc_error": lc.final_error, "reduction": red,
            "vfcc_history": v.errors, "lacc_history": lc.errors, "lacc_estimate": lc.estimates[-1],
            "uncompensated_error": lc.errors[0], "lacc_iterations_to_0.2mm": lc.iterations_to(2e-4),
            "load": F, "load_mass_g": mass * 1e3, "target": ref.tip, "tensions_unloaded": list(map(float, T)),
            "elevation_deg": tip_elevation_deg(ref),
            "vfcc_mm": v.final_error * 1e3, "lacc_mm": lc.final_error * 1e3, "reduction_percent": 100 * red,
            "lacc_compute_ms_median": 1e3 * statistics.median(lc.compute_times) if lc.compute_times else None,
            "failures": {k: r.failure for k, r in runs.items() if r.failure},
            "paper": PAPER_TABLE1.get(name, {}),
        }
        if compare:
            x = runs["compare"]
            entry.update({"compare_error": x.final_error, "compare_history": x.errors, "compare_mm": x.final_error * 1e3,
                          "compare_estimate": x.estimates[-1], "compare_iterations_to_0.2mm": x.iterations_to(2e-4)})
        res[name] = entry
        pp = PAPER_TABLE1.get(name, {})
        row = [name, f"{mass * 1e3:.1f}", f"{entry['vfcc_mm']:.3f}", f"{pp.get('vfcc_mm', float('nan')):.3f}",
               f"{entry['lacc_mm']:.2e}", f"{pp.get('lacc_mm', float('nan')):.3f}",
               f"{entry['reduction_percent']:.2f}", f"{pp.get('reduction_percent', float('nan')):.2f}"]
        if compare:
            row.append(f"{entry['compare_mm']:.4f}")
        rows.append(row)
    header = ["config", "load g", "VF-CC mm", "paper", f"LACC({compliance}) mm", "paper", "reduction %", "paper"]
    if compare:
        header.append(f"LACC({compare}) mm")
    table = _fmt_table(header, rows)
    for name in configs:
        for k, msg in res[name]["failures"].items():
            table += f"\n{name} {k} stopped early: {msg[:200]}"
    res["table"] = table + f"\nplant: {plant_summary(params, plant_options)['text']}"
    res["settings"] = {"iterations": iterations, "seed": seed, "pressure_Pa": pressure, "mass_range_kg": mass_range,
                       "lateral_std_N": lateral_std, "compliance": compliance, "compare": compare,
                       "chi_N_per_m": chi, "vfcc_law": vfcc_law, "actuator": params.name,
                       "plant": plant_summary(params, plant_options)["text"],
                       "plant_summary": plant_summary(params, plant_options)}
    fig = None
    if out is not None:
        plt = _pyplot()
        names = list(configs)
        fig, axs = plt.subplots(1, len(names), figsize=(4.2 * len(names), 3.6), sharey=True)
        for ax, name in zip(np.atleast_1d(axs), names):
            e = res[name]
            k = np.arange(len(e["vfcc_history"]))
            ax.semilogy(k, np.maximum(np.array(e["vfcc_history"]) * 1e3, 1e-7), "o-", label="VF-CC (χ = 10 N/m)")
            ax.semilogy(k, np.maximum(np.array(e["lacc_history"]) * 1e3, 1e-7), "s-", label=f"LACC ({compliance})")
            if compare:
                ax.semilogy(k, np.maximum(np.array(e["compare_history"]) * 1e3, 1e-7), "^-", label=f"LACC ({compare})")
            ax.axhline(0.2, color="k", lw=0.8, ls="--")
            ax.set_title(f"{name}: {e['load_mass_g']:.0f} g")
            ax.set_xlabel("iteration")
        _finish_axes(fig, axs, "tip error [mm]")
    _write(out, "table1", res, fig)
    return res


# ============================================================================== Table I with tendon friction
#: the tip error the friction study counts iterations to [m] (0.1 mm)
FRICTION_REACH = 1e-4


def _friction_values(friction) -> list:
    """The plant friction coefficients μ of the friction study: a non-empty sequence of numbers in 0 … 1."""
    from ancf.errors import InputError
    from ancf.params import TENDON_FRICTION_MAX
    try:
        mus = [float(x) for x in friction]
    except (TypeError, ValueError):
        raise InputError(f"friction must be a sequence of coefficients μ, got {friction!r}") from None
    if not mus or not all(0.0 <= x <= TENDON_FRICTION_MAX for x in mus):
        raise InputError(f"friction needs at least one μ, each in 0 … {TENDON_FRICTION_MAX:g}, got {friction!r}")
    return mus


def _friction_plant(params, plant_options: Optional[PlantOptions], mu: float) -> PlantOptions:
    """``plant_options`` (default: the perfect plant) with the plant actuator's ``tendon_friction`` set to μ."""
    import dataclasses
    base = plant_options or PlantOptions()
    return dataclasses.replace(base, params=(base.params or params).replace(tendon_friction=mu))


def _at(history: list, k: int) -> float:
    """The error after ``k`` corrections (the last one when the run stopped earlier)."""
    return float(history[min(k, len(history) - 1)])


def _reach_text(its, history) -> str:
    """The iterations to 0.1 mm, or "> k (the error after the last [mm])"."""
    return str(its) if its is not None else f"> {len(history) - 1} ({1e3 * history[-1]:.3f})"


def _friction_entry(core: dict, name: str, iterations: int) -> dict:
    """One configuration of the friction study from a Table I run of ``reach_iterations`` corrections: the errors
    after ``iterations`` (the run's prefix: a deterministic plant and controllers), LACC's reach."""
    c = core[name]
    lh = [float(x) for x in c["lacc_history"]]
    reach = next((k for k, e in enumerate(lh) if e < FRICTION_REACH), None)
    return {"vfcc_error": _at(c["vfcc_history"], iterations), "lacc_error": _at(lh, iterations),
            "vfcc_history": c["vfcc_history"][:iterations + 1], "lacc_history": lh,
            "lacc_iterations_to_0.1mm": reach, "lacc_error_last": lh[-1], "load": c["load"],
            "load_mass_g": c["load_mass_g"], "target": c["target"], "failures": c["failures"],
            "vfcc_mm": 1e3 * _at(c["vfcc_history"], iterations), "lacc_mm": 1e3 * _at(lh, iterations)}


def _aware_run(plant_params, pressure, entry: dict, iterations: int, plant_options: PlantOptions) -> dict:
    """The friction-aware LACC (its model: the plant's actuator, μ included) on the configuration's plant."""
    from controller.friction_aware import FrictionAwareLACC
    truth = Model(plant_params)
    ctrl = FrictionAwareLACC(truth, pressure, tolerance=0.0)
    r = run_iterations(ctrl, SimulatedPlant(truth, pressure, load=entry["load"], options=plant_options),
                       entry["target"], iterations=iterations, stop_at_tolerance=False, on_error="stop")
    return {"aware_error": r.final_error, "aware_mm": 1e3 * r.final_error, "aware_history": r.errors,
            "aware_iterations_to_0.1mm": r.iterations_to(FRICTION_REACH),
            "aware_compute_s_median": statistics.median(r.compute_times) if r.compute_times else None,
            **({"failures_aware": r.failure} if r.failure else {})}


def table1_friction(*, friction: Sequence[float] = (0.0, 0.1, 0.3), friction_aware: bool = False,
                    iterations: int = 5, reach_iterations: int = 20, seed: int = 0, pressure: float = PRESSURE,
                    configurations: Optional[dict] = None, mass_range=(0.02, 0.06), lateral_std: float = 0.03,
                    compliance: str = "exact", chi: float = 10.0, vfcc_law: str = "proportional",
                    plant_options: Optional[PlantOptions] = None, params=None, out: PathLike = None) -> dict:
    """Table I on a plant with tendon friction (docs/friction.md, "Controller on a plant with friction").

    For each plant coefficient μ in ``friction`` the plant actuator's ``tendon_friction`` is μ (the capstan
    law with its stick/slip history, :mod:`hardware.simulated`), the controllers' model frictionless; the
    loads are the seeded draws of :func:`table1` (the same for every μ: the IK that vets them ignores friction).
    VF-CC and LACC(``compliance``) make ``reach_iterations`` corrections; the table gives the errors after
    ``iterations`` (the runs' prefix — μ = 0 is :func:`table1`'s numbers) and how far LACC gets: the iterations
    to 0.1 mm, or the error after the last.  With ``friction_aware`` each μ > 0 also runs
    :class:`controller.friction_aware.FrictionAwareLACC` whose model is the plant's actuator (μ included) for
    ``iterations`` corrections.

    Returns ``{"friction": {f"{μ:g}": {configuration: {vfcc_error, lacc_error [m] after ``iterations``,
    vfcc_history, lacc_history [m], "lacc_iterations_to_0.1mm" (None: not within ``reach_iterations``),
    lacc_error_last [m], load [N], target [m], aware_error / aware_history / "aware_iterations_to_0.1mm",
    mm copies}}}, "table": str, "settings": {...}}``."""
    from ancf.errors import InputError
    mus = _friction_values(friction)
    if isinstance(reach_iterations, bool) or not isinstance(reach_iterations, (int, np.integer)) \
            or not iterations <= reach_iterations <= 200:
        raise InputError(f"reach_iterations must be an integer in [iterations = {iterations}, 200], "
                         f"got {reach_iterations!r}")
    params = params or presets.paper()
    res: dict = {"friction": {}}
    rows = []
    for mu in mus:
        opts = _friction_plant(params, plant_options, mu)
        core = table1(iterations=reach_iterations, seed=seed, pressure=pressure, configurations=configurations,
                      mass_range=mass_range, lateral_std=lateral_std, compliance=compliance, compare=None, chi=chi,
                      vfcc_law=vfcc_law, plant_options=opts, params=params)
        block = {}
        for name in (k for k in core if k not in ("table", "settings")):
            e = block[name] = _friction_entry(core, name, iterations)
            if friction_aware and mu > 0:
                e.update(_aware_run(opts.params, pressure, e, iterations, opts))
            rows.append(_friction_row(mu, name, e, friction_aware))
        res["friction"][f"{mu:g}"] = block
    header = ["plant μ", "config", "load g", "VF-CC mm", f"LACC({compliance}) mm", "LACC iters to 0.1 mm (mm)"]
    if friction_aware:
        header += ["friction-aware LACC mm", "iters to 0.1 mm"]
    res["table"] = (_fmt_table(header, rows) + f"\nerrors after {iterations} corrections; LACC runs up to "
                    f"{reach_iterations}; controllers' model frictionless"
                    + (", the friction-aware LACC's the plant's actuator" if friction_aware else ""))
    res["settings"] = {"friction": mus, "friction_aware": friction_aware, "iterations": iterations,
                       "reach_iterations": reach_iterations, "seed": seed, "pressure_Pa": pressure,
                       "compliance": compliance, "actuator": params.name,
                       "plant": plant_summary(params, plant_options)["text"]}
    fig = _friction_figure(res, friction_aware) if out is not None else None
    _write(out, "table1", res, fig)
    return res


def _friction_row(mu: float, name: str, e: dict, aware: bool) -> list:
    """One row of the friction study's table."""
    row = [f"{mu:g}", name, f"{e['load_mass_g']:.1f}", f"{e['vfcc_mm']:.3f}", f"{e['lacc_mm']:.4f}",
           _reach_text(e["lacc_iterations_to_0.1mm"], e["lacc_history"])]
    if aware:
        if "aware_history" in e:
            row += [f"{e['aware_mm']:.4f}", _reach_text(e["aware_iterations_to_0.1mm"], e["aware_history"])]
        else:
            row += ["–", "–"]
    return row


def _friction_figure(res: dict, aware: bool):
    """LACC's error history per configuration, one line per plant μ (the friction-aware LACC dashed)."""
    plt = _pyplot()
    blocks = res["friction"]
    names = list(next(iter(blocks.values())))
    fig, axs = plt.subplots(1, len(names), figsize=(4.2 * len(names), 3.6), sharey=True)
    for ax, name in zip(np.atleast_1d(axs), names):
        for i, (mu, block) in enumerate(blocks.items()):
            h = np.maximum(np.array(block[name]["lacc_history"]) * 1e3, 1e-7)
            ax.semilogy(np.arange(h.size), h, "o-", color=f"C{i}", ms=3, label=f"LACC, plant μ = {mu}")
            if aware and "aware_history" in block[name]:
                h = np.maximum(np.array(block[name]["aware_history"]) * 1e3, 1e-7)
                ax.semilogy(np.arange(h.size), h, "s--", color=f"C{i}", ms=3, label=f"friction-aware, μ = {mu}")
        ax.axhline(0.1, color="k", lw=0.8, ls="--")
        ax.set_title(name)
        ax.set_xlabel("iteration")
    _finish_axes(fig, axs, "tip error [mm]")
    return fig


# ============================================================================== ablation
def compliance_ablation(*, seed: int = 1, loads_per_configuration: int = 4, max_iterations: int = 40,
                        tolerance: float = 2e-4, pressure: float = PRESSURE, configurations: Optional[dict] = None,
                        methods: Sequence = (("paper", 1.0), ("ik", 1.0), ("exact", 1.0)),
                        mass_range=(0.02, 0.06), lateral_std: float = 0.03,
                        plant_options: Optional[PlantOptions] = None, params=None, out: PathLike = None) -> dict:
    """FK-derived (eq. 13, "paper") vs IK-derived (eq. 15/16, "ik") vs exact locked compliance in the
    LACC loop: iterations until ‖p_m − p_d‖ < ``tolerance`` over seeded stochastic loads.

    ``methods``: (method, constraint_weight) pairs (weight 1 = the paper's literal stack).  Returns
    ``{"methods": {label: {"iterations": [...], "mean_iterations", "median_iterations", "converged_fraction",
    "mean_rate"}}, "ik_faster_percent": 100 (1 − mean_ik / mean_paper), "runs": [...], "table": str}``.
    ``mean_rate`` is the geometric-mean error ratio per iteration over the first three steps.
    """
    params = params or presets.paper()
    model = Model(params)
    truth = Model(plant_options.params) if plant_options is not None and plant_options.params is not None else model
    configs = _resolve_configurations(params, pressure, configurations, mass_range[1])
    rng = np.random.default_rng(seed)
    cases = []
    for name, T in configs.items():
        ref = model.fk(T, pressure, (0, 0, 0))
        for _ in range(loads_per_configuration):
            F, mass = _draw_load(truth, ref.tip, pressure, rng, mass_range, lateral_std, ref.q, ref.tensions)
            cases.append((name, ref.tip, F, mass))
    out_methods: dict = {}
    runs = []
    for meth, w in methods:
        label = meth if w == 1.0 else f"{meth}(w={w:g})"
        its, rates, conv = [], [], 0
        for name, tip, F, mass in cases:
            ctrl = LACC(model, pressure, compliance=meth, constraint_weight=w, tolerance=tolerance)
            # divergence ends in an infeasible IK or a failed solve: recorded, not raised
            r = run_iterations(ctrl, _plant(model, pressure, F, plant_options), tip, iterations=max_iterations,
                               on_error="stop")
            errs, ok, err_msg = r.errors, r.converged and r.failure is None, r.failure
            n_it = r.iterations if ok else None
            conv += ok
            its.append(n_it)
            if len(errs) >= 2:
                k = min(3, len(errs) - 1)
                rates.append((errs[k] / errs[0]) ** (1 / k) if errs[0] > 0 else float("nan"))
            runs.append({"method": label, "configuration": name, "load": F, "mass_g": mass * 1e3,
                         "iterations": n_it, "errors": errs, "error": err_msg})
        ok_its = [i for i in its if i is not None]
        out_methods[label] = {"iterations": its, "converged_fraction": conv / len(cases),
                              "mean_iterations": float(np.mean(ok_its)) if ok_its else None,
                              "median_iterations": float(np.median(ok_its)) if ok_its else None,
                              "mean_rate": float(np.exp(np.mean(np.log(rates)))) if rates else None,
                              "constraint_weight": w, "method": meth}
    res: dict = {"methods": out_methods}
    a, b = out_methods.get("ik"), out_methods.get("paper")
    if a and b:
        # paired over the cases where both converged
        pairs = [(i, j) for i, j in zip(a["iterations"], b["iterations"]) if i is not None and j is not None]
        if pairs:
            res["ik_faster_percent"] = 100.0 * (1.0 - np.mean([i for i, _ in pairs]) / np.mean([j for _, j in pairs]))
            res["paired_cases"] = len(pairs)
    rows = [[k, f"{v['converged_fraction'] * 100:.0f}%",
             "-" if v["mean_iterations"] is None else f"{v['mean_iterations']:.2f}",
             "-" if v["median_iterations"] is None else f"{v['median_iterations']:.1f}",
             "-" if v["mean_rate"] is None else f"{v['mean_rate']:.3f}"] for k, v in out_methods.items()]
    table = _fmt_table(["compliance", "converged", "mean iters", "median", "error ratio/iter"], rows)
    if "ik_faster_percent" in res:
        table += (f"\nIK-derived vs FK-derived: {res['ik_faster_percent']:.1f} % fewer iterations over the "
                  f"{res['paired_cases']} cases both converged "
                  f"(paper: {PAPER_ABLATION['ik_faster_percent']:.0f} %)")
    res["table"] = table
    res["runs"] = runs
    res["paper"] = PAPER_ABLATION
    res["settings"] = {"seed": seed, "cases": len(cases), "tolerance_m": tolerance, "max_iterations": max_iterations,
                       "pressure_Pa": pressure, "mass_range_kg": mass_range, "lateral_std_N": lateral_std}
    fig = None
    if out is not None:
        plt = _pyplot()
        fig, ax = plt.subplots(figsize=(6, 3.6))
        for i, (label, v) in enumerate(out_methods.items()):
            for r in runs:
                if r["method"] == label and r["errors"]:
                    ax.semilogy(np.maximum(np.array(r["errors"]) * 1e3, 1e-7), color=f"C{i}", alpha=0.6,
                                label=label if r is next(rr for rr in runs if rr["method"] == label) else None)
        ax.axhline(0.2, color="k", lw=0.8, ls="--")
        ax.set_xlabel("iteration")
        ax.set_ylabel("tip error [mm]")
        ax.legend(fontsize=8)
        fig.tight_layout()
    _write(out, "compliance_ablation", res, fig)
    return res


# ============================================================================== loading
def _profiles(peak_mass, ramp_up, ramp_down, cyclic_mass, frequency):
    def continuous(t):
        if t <= ramp_up:
            m = peak_mass * t / ramp_up
        else:
            m = peak_mass * max(0.0, 1.0 - (t - ramp_up) / ramp_down)
        return np.array([0.0, 0.0, -G * m])

    def cyclic(t):
        return np.array([0.0, 0.0, -G * cyclic_mass * 0.5 * (1.0 - math.cos(2 * math.pi * frequency * t))])
    return continuous, cyclic


def _uncontrolled_drift(model, pressure, lengths, profile, times, plant_options):
    plant = _plant(model, pressure, profile, plant_options)
    plant.command(lengths)
    drift = []
    tip0 = None
    for t in times:
        plant.time = float(t)
        tip = plant.true_tip()
        tip0 = tip if tip0 is None else tip0
        drift.append(float(np.linalg.norm(tip - tip0)))
    return np.array(drift)


def _carryable_mass(params, pressure, direction, wanted: float, steps: int = 5):
    """Largest tip mass ≤ ``wanted`` [kg] (bisection to 1/32 of it, coarse level grid) for which a
    configuration with headroom exists."""
    lo, hi = 0.0, wanted
    for _ in range(steps):
        mid = 0.5 * (lo + hi)
        try:
            configurations(params, pressure=pressure, directions={"loading": direction}, max_load_mass=mid, levels=9)
            lo = mid
        except BellowsError:
            hi = mid
    return lo


def _loading_masses(params, pressure, tensions, peak_mass, cyclic_mass) -> tuple[float, float, str]:
    """(peak, cyclic [kg], note): the paper's 110 g / 80 g when neither is given, scaled down (with a note) if the
    preset cannot carry them within its tension limits; the given masses otherwise (both or neither)."""
    if peak_mass is not None and cyclic_mass is not None:
        return peak_mass, cyclic_mass, ""
    if peak_mass is not None or cyclic_mass is not None:
        from ancf.errors import InputError
        raise InputError("give both peak_mass and cyclic_mass [kg], or neither (the paper's 110 g / 80 g)")
    peak_mass, cyclic_mass = PAPER_PEAK_MASS, PAPER_CYCLIC_MASS
    if tensions is not None:
        return peak_mass, cyclic_mass, ""
    try:            # the paper's masses, scaled down if this preset cannot carry them
        configurations(params, pressure=pressure, directions={"loading": LOADING_DIRECTION}, max_load_mass=peak_mass)
        return peak_mass, cyclic_mass, ""
    except BellowsError:
        scale = 0.9 * _carryable_mass(params, pressure, LOADING_DIRECTION, peak_mass) / peak_mass
        if scale <= 0:
            raise
    peak_mass, cyclic_mass = peak_mass * scale, cyclic_mass * scale
    return peak_mass, cyclic_mass, (f"this actuator cannot carry the paper's {PAPER_PEAK_MASS * 1e3:.0f} g within its "
                                    f"tension limits: masses scaled by {scale:.3f} ({peak_mass * 1e3:.1f} g peak, "
                                    f"{cyclic_mass * 1e3:.1f} g cyclic)")


def _loading_plant_options(plant_options: Optional[PlantOptions], motor_rate: float) -> PlantOptions:
    """The plant of the loading study: ``plant_options`` with motors at ``motor_rate`` [m/s] unless it sets a rate."""
    if plant_options is None:
        return PlantOptions(length_rate=motor_rate)
    if math.isinf(plant_options.length_rate):
        return PlantOptions(**{**plant_options.__dict__, "length_rate": motor_rate})
    return plant_options


def _loading_run(model, pressure, target, opts, timing: dict, profile, duration, compliance, fixed_compute=None,
                 ctrl=None):
    """One timed LACC episode under the load ``profile``: (TimedResult, summary dict with SI and mm keys).
    ``timing``: compute_scale, actuation_latency, settle_time, sample_dt (run_timed's keywords); ``ctrl`` the
    controller to run instead of LACC(``compliance``) on ``model``."""
    ctrl = ctrl or LACC(model, pressure, compliance=compliance)
    plant = SimulatedPlant(model, pressure, load=profile, options=opts)
    t0 = time.perf_counter()
    r = run_timed(ctrl, plant, target, duration=duration,
                  compute_time="measured" if fixed_compute is None else fixed_compute, **timing)
    wall = time.perf_counter() - t0
    en = r.error_norm
    cyc = [c[1] + c[2] + c[3] for c in r.cycle_times]
    return r, {"max_error": float(en.max()), "rms_error": float(np.sqrt(np.mean(en ** 2))),
               "max_error_mm": float(en.max() * 1e3), "corrections": r.corrections,
               "median_cycle_s": float(np.median(cyc)) if cyc else None,
               "median_compute_ms": 1e3 * float(np.median(r.compute_times)) if r.compute_times else None,
               "peak_estimate_N": float(np.max(np.linalg.norm(r.estimate, axis=1))), "wall_s": wall}


def _loading_cases(run, model, pressure, lengths0, opts, cases: dict, compliance, compare) -> tuple[dict, dict]:
    """The continuous and cyclic episodes (``cases``: {key: (profile, duration [s])}) with LACC(``compliance``),
    the uncontrolled drift of the locked tendons beside each, and LACC(``compare``) when it differs.
    Returns (results {key: summary and time series}, {key: TimedResult})."""
    res, series = {}, {}
    for key, (prof, dur) in cases.items():
        r, s = run(prof, dur, compliance)
        s["uncontrolled_max_drift"] = float(_uncontrolled_drift(model, pressure, lengths0, prof, r.t, opts).max())
        s["uncontrolled_max_drift_mm"] = s["uncontrolled_max_drift"] * 1e3
        if compare and compare != compliance:
            _, sx = run(prof, dur, compare)
            s["compare_max_error"] = sx["max_error"]
            s["compare_max_error_mm"] = sx["max_error_mm"]
        s["t"] = r.t
        s["error"] = r.error
        s["load_N"] = r.load
        s["estimate_N"] = r.estimate
        res[key] = s
        series[key] = r
    return res, series


def _loading_bandwidth(run, cyclic, duration, cyclic_summary: dict, loop_periods, compliance, compare) -> list:
    """The cyclic case with a slower loop: a fixed compute time [s] stands in for a slower solver, chosen so that
    one correction cycle lasts each of ``loop_periods`` [s]."""
    band = []
    base_cycle = cyclic_summary["median_cycle_s"] or 0.0
    for T_loop in loop_periods:
        fixed = max(T_loop - (base_cycle - (cyclic_summary["median_compute_ms"] or 0) / 1e3), 0.0)
        _, s = run(cyclic, duration, compliance, fixed_compute=fixed)
        row = {"loop_period_s": T_loop, "compute_s": fixed, "max_error": s["max_error"],
               "max_error_mm": s["max_error_mm"], "corrections": s["corrections"],
               "median_cycle_s": s["median_cycle_s"]}
        if compare and compare != compliance:
            _, sx = run(cyclic, duration, compare, fixed_compute=fixed)
            row["compare_max_error_mm"] = sx["max_error_mm"]
        band.append(row)
    return band


def _loading_table(res: dict, compliance, compare, load_note: str) -> str:
    """The printed comparison of the loading study with the paper's numbers."""
    c, y, band = res["continuous"], res["cyclic"], res["bandwidth"]
    rows = [["continuous max error [mm]", f"{c['max_error_mm']:.3f}", f"{c.get('compare_max_error_mm', float('nan')):.3f}",
             f"{PAPER_LOADING['continuous_max_error_mm']:.3f}"],
            ["continuous uncontrolled drift [mm]", f"{c['uncontrolled_max_drift_mm']:.2f}", "", "> 10"],
            ["cyclic max error [mm]", f"{y['max_error_mm']:.3f}", f"{y.get('compare_max_error_mm', float('nan')):.3f}",
             f"{PAPER_LOADING['cyclic_max_error_mm']:.3f}"],
            ["cyclic uncontrolled drift [mm]", f"{y['uncontrolled_max_drift_mm']:.2f}", "", "> 7"],
            ["loop period (median) [s]", f"{y['median_cycle_s']:.3f}", "", "≈ 0.5"],
            ["LACC compute per step [ms]", f"{res['compute_ms_median']:.2f}", "", "(MATLAB IK 2.95 s)"]]
    for b in band:
        rows.append([f"cyclic, loop period {b['loop_period_s']:g} s [mm]", f"{b['max_error_mm']:.3f}",
                     f"{b.get('compare_max_error_mm', float('nan')):.3f}", "3.573" if b["loop_period_s"] == 0.5 else ""])
    table = _fmt_table(["loading (horizontal)", f"LACC({compliance})", f"LACC({compare})", "paper"], rows)
    return table + ("\n" + load_note if load_note else "")


def _loading_figure(res: dict, series: dict, compliance, compare, frequency):
    """Loads and estimates, tip errors over time, and the cyclic error vs the loop period (2 × 3 axes)."""
    plt = _pyplot()
    band, y = res["bandwidth"], res["cyclic"]
    fig, axs = plt.subplots(2, 3, figsize=(15, 6))
    lp = [b["loop_period_s"] for b in band]
    axs[0, 2].plot(lp, [b["max_error_mm"] for b in band], "o-", label=f"LACC ({compliance})")
    if band and "compare_max_error_mm" in band[0]:
        axs[0, 2].plot(lp, [b["compare_max_error_mm"] for b in band], "^-", label=f"LACC ({compare})")
    axs[0, 2].axhline(PAPER_LOADING["cyclic_max_error_mm"], color="k", ls="--", lw=0.8, label="paper (≈ 0.5 s loop)")
    axs[0, 2].axhline(y["uncontrolled_max_drift_mm"], color="gray", ls=":", lw=0.8, label="uncontrolled")
    axs[0, 2].set_xlabel("loop period [s]")
    axs[0, 2].set_ylabel("cyclic max tip error [mm]")
    axs[0, 2].set_title(f"bandwidth at {frequency:g} Hz")
    axs[0, 2].legend(fontsize=8)
    axs[1, 2].axis("off")
    for j, key in enumerate(("continuous", "cyclic")):
        r = series[key]
        axs[0, j].plot(r.t, -r.load[:, 2] / G * 1e3, "k-", label="true load")
        axs[0, j].plot(r.t, -r.estimate[:, 2] / G * 1e3, "C0--", label="LACC estimate")
        axs[0, j].set_ylabel("load [g]")
        axs[0, j].set_title(key)
        axs[0, j].legend(fontsize=8)
        axs[1, j].plot(r.t, r.error_norm * 1e3, "C0-", label=f"LACC ({compliance})")
        axs[1, j].set_ylabel("tip error [mm]")
        axs[1, j].set_xlabel("t [s]")
    fig.tight_layout()
    return fig


def loading(*, pressure: float = PRESSURE, tensions=None, peak_mass: Optional[float] = None,
            ramp_up: float = 35.0, ramp_down: float = 15.0, cyclic_mass: Optional[float] = None,
            frequency: float = 0.125,
            cycles: int = 4, compliance: str = "exact", motor_rate: float = 5e-3, actuation_latency: float = 0.02,
            settle_time: float = 0.1, compute_scale: float = 1.0, sample_dt: float = 0.05,
            loop_periods: Sequence[float] = (0.25, 0.5, 1.0, 2.0), compare: Optional[str] = "ik",
            plant_options: Optional[PlantOptions] = None, params=None, out: PathLike = None,
            friction: Optional[Sequence[float]] = None, friction_aware: bool = False,
            friction_compute: Optional[Sequence[float]] = None) -> dict:
    """Continuous (0 → ``peak_mass`` → 0 over ``ramp_up`` + ``ramp_down`` s) and cyclic (``cyclic_mass``
    at ``frequency`` Hz, ``cycles`` cycles) tip loading with LACC in the loop (Sec. V-E).

    Loop timing: the controller's compute time is the real wall-clock time of each LACC step (× 
    ``compute_scale``), the motors move at ``motor_rate`` [m/s] plus ``actuation_latency`` [s], then
    ``settle_time`` [s] passes before the next measurement (zero-velocity lock + tracker frame).  The
    bandwidth study re-runs the cyclic case with a fixed compute time chosen so that one correction cycle
    lasts ``loop_periods`` [s] (the paper's ≈ 0.5 s among them).  ``cyclic_mass`` 80 g: the paper's
    uncontrolled cyclic drift ("over 7 mm") is ≈ 0.7× its ramp drift ("over 10 mm" at 110 g).

    Steps: the masses (:func:`_loading_masses`), the configuration, the continuous and cyclic episodes with
    the uncontrolled drift (:func:`_loading_cases`), the slower loops (:func:`_loading_bandwidth`), the
    table and the figure.

    Returns ``{"continuous": {...}, "cyclic": {...}, "bandwidth": [...], "compute_ms_median", "table", ...}``
    with ``max_error`` [m], ``rms_error`` [m], ``uncontrolled_max_drift`` [m], ``corrections`` and the
    time series.

    Tendon friction (docs/friction.md, "Loading experiments with friction"): with ``friction`` (plant
    coefficients μ, each in 0 … 1) the same two load cases run once per μ on the plant whose actuator has
    ``tendon_friction`` μ, LACC(``compliance``) with the frictionless model, and with ``friction_aware`` (μ > 0)
    :class:`controller.friction_aware.FrictionAwareLACC` whose model is the plant's actuator.  Each
    correction takes a fixed time on the loop's clock, ``friction_compute`` = (LACC, friction-aware LACC) [s]
    (default, or a None entry: :data:`FRICTION_LOADING_COMPUTE`), so that the runs repeat exactly; ``compare``
    and the bandwidth study are not run.  Returns ``{"friction": {f"{μ:g}": {case: {"uncontrolled_max_drift" [m], "lacc": {...},
    "aware": {...}}}}, "table", "settings", "load_note"}``, each controller's entry with ``max_error``,
    ``rms_error`` [m], mm copies, ``corrections``, ``error_norm`` [m] over ``t`` [s] and the measured
    ``compute_wall_ms_median``.
    """
    if friction is not None:            # checked before anything runs
        friction = _friction_values(friction)
        friction_compute = _loading_compute((None, None) if friction_compute is None else friction_compute)
    elif friction_aware or friction_compute is not None:
        from ancf.errors import InputError
        raise InputError("friction_aware and friction_compute need friction (the plant's coefficients μ)")
    params = params or presets.paper()
    model = Model(params)
    peak_mass, cyclic_mass, load_note = _loading_masses(params, pressure, tensions, peak_mass, cyclic_mass)
    if tensions is None:        # near-horizontal, with headroom for the peak load (derived from the preset)
        tensions = configurations(params, pressure=pressure, directions={"loading": LOADING_DIRECTION},
                                  max_load_mass=max(peak_mass, cyclic_mass))["loading"]["tensions"]
    tensions = [float(t) for t in tensions]
    target = model.fk(tensions, pressure, (0, 0, 0)).tip
    continuous, cyclic = _profiles(peak_mass, ramp_up, ramp_down, cyclic_mass, frequency)
    opts = _loading_plant_options(plant_options, motor_rate)
    lengths0 = model.ik(target, pressure, (0, 0, 0)).tendon_lengths
    timing = {"compute_scale": compute_scale, "actuation_latency": actuation_latency, "settle_time": settle_time,
              "sample_dt": sample_dt}

    def run(profile, duration, comp, fixed_compute=None):
        return _loading_run(model, pressure, target, opts, timing, profile, duration, comp, fixed_compute)

    duration_y = cycles / frequency
    settings = {"pressure_Pa": pressure, "tensions_N": list(tensions), "target_m": target,
                "peak_mass_kg": peak_mass, "ramp_up_s": ramp_up, "ramp_down_s": ramp_down,
                "cyclic_mass_kg": cyclic_mass, "frequency_Hz": frequency, "cycles": cycles,
                "compliance": compliance, "motor_rate_m_per_s": motor_rate,
                "actuation_latency_s": actuation_latency, "settle_time_s": settle_time,
                "compute_scale": compute_scale, "sample_dt_s": sample_dt, "compare": compare,
                "actuator": params.name}
    if friction is not None:
        setup = {"model": model, "pressure": pressure, "target": target, "opts": opts, "timing": timing,
                 "lengths0": lengths0, "compliance": compliance, "load_note": load_note,
                 "cases": {"continuous": (continuous, ramp_up + ramp_down), "cyclic": (cyclic, duration_y)},
                 "settings": {k: v for k, v in settings.items() if k not in ("compare", "compute_scale")}}
        return _loading_friction(setup, friction, friction_aware, friction_compute, out)
    res, series = _loading_cases(run, model, pressure, lengths0, opts,
                                 {"continuous": (continuous, ramp_up + ramp_down), "cyclic": (cyclic, duration_y)},
                                 compliance, compare)
    busy = [c for c in series["continuous"].compute_times + series["cyclic"].compute_times if c > 0]
    res["compute_ms_median"] = 1e3 * float(np.median(busy)) if busy else None
    res["bandwidth"] = _loading_bandwidth(run, cyclic, duration_y, res["cyclic"], loop_periods, compliance, compare)
    res["table"] = _loading_table(res, compliance, compare, load_note)
    res["load_note"] = load_note
    res["paper"] = PAPER_LOADING
    res["settings"] = settings
    fig = _loading_figure(res, series, compliance, compare, frequency) if out is not None else None
    _write(out, "loading", res, fig)
    return res



# ============================================================================== loading with tendon friction
#: compute time per correction [s] on the loop's clock in the loading study with friction: (LACC, the
#: friction-aware LACC).  Fixed, so that the runs repeat exactly (the frictionless study times each step by the
#: wall clock): LACC's steps take 2–8 ms; the friction-aware LACC's corrections (≈ 12–14 locked friction solves)
#: took a median 0.44–0.46 s in short runs of this study on a shared 2-core machine (0.8–1.9 s when it was more
#: loaded); each run's ``compute_wall_ms_median`` states the machine's own.
FRICTION_LOADING_COMPUTE = (0.01, 0.5)


def _loading_compute(values) -> tuple[float, float]:
    """(LACC, friction-aware LACC) compute times [s]: two numbers in 0 … 10 s (None: the default's)."""
    from ancf.errors import InputError
    try:
        out = tuple(float(d if x is None else x) for x, d in zip(values, FRICTION_LOADING_COMPUTE, strict=True))
    except (TypeError, ValueError):
        raise InputError(f"friction_compute must be (LACC, friction-aware LACC) times [s], got {values!r}") from None
    if not all(0.0 <= x <= 10.0 for x in out):
        raise InputError(f"friction_compute must be two times in 0 … 10 s, got {values!r}")
    return out


def _friction_summary(r, s: dict) -> dict:
    """The run's summary (:func:`_loading_run`) with its tip error norm [m] over its sample times t [s], the
    measured wall-clock compute renamed (the loop used the fixed time)."""
    out = {k: v for k, v in s.items() if k not in ("median_compute_ms", "wall_s")}
    out["compute_wall_ms_median"] = s["median_compute_ms"]
    out["rms_error_mm"] = 1e3 * s["rms_error"]
    out["t"], out["error_norm"] = r.t, r.error_norm
    return out


def _loading_friction_block(setup: dict, mu: float, aware: bool, computes) -> dict:
    """One plant μ of the loading study with friction: per load case the uncontrolled drift, LACC (frictionless
    model) and, with ``aware`` and μ > 0, the friction-aware LACC (the plant's actuator as its model)."""
    from controller.friction_aware import FrictionAwareLACC
    model, pressure, target, timing = setup["model"], setup["pressure"], setup["target"], setup["timing"]
    opts = _friction_plant(model.params, setup["opts"], mu)
    block = {}
    for key, (prof, dur) in setup["cases"].items():
        r, s = _loading_run(model, pressure, target, opts, timing, prof, dur, setup["compliance"], computes[0])
        drift = float(_uncontrolled_drift(model, pressure, setup["lengths0"], prof, r.t, opts).max())
        case = {"uncontrolled_max_drift": drift, "uncontrolled_max_drift_mm": 1e3 * drift,
                "lacc": _friction_summary(r, s)}
        if aware and mu > 0:
            ctrl = FrictionAwareLACC(Model(opts.params), pressure)
            ra, sa = _loading_run(model, pressure, target, opts, timing, prof, dur, None, computes[1], ctrl=ctrl)
            case["aware"] = _friction_summary(ra, sa)
        block[key] = case
    return block


def _loading_friction_table(res: dict, aware: bool, compliance: str, computes) -> str:
    """The printed table of the loading study with friction: per plant μ and load case the drift and the errors."""
    header = ["plant μ", "load case", "uncontrolled drift mm", f"LACC({compliance}) max mm", "rms mm", "corrections"]
    if aware:
        header += ["friction-aware max mm", "rms mm", "corrections"]
    rows = []
    for mu, block in res["friction"].items():
        for key, c in block.items():
            row = [mu, key, f"{c['uncontrolled_max_drift_mm']:.2f}", f"{c['lacc']['max_error_mm']:.3f}",
                   f"{c['lacc']['rms_error_mm']:.3f}", str(c["lacc"]["corrections"])]
            if aware:
                a = c.get("aware")
                row += ["–", "–", "–"] if a is None else [f"{a['max_error_mm']:.3f}", f"{a['rms_error_mm']:.3f}",
                                                          str(a["corrections"])]
            rows.append(row)
    note = ("\ncontrollers' model frictionless" + (", the friction-aware LACC's the plant's actuator" if aware else "")
            + f"; compute per correction on the loop's clock: LACC {1e3 * computes[0]:g} ms"
            + (f", friction-aware LACC {1e3 * computes[1]:g} ms" if aware else "") + " (fixed)")
    return _fmt_table(header, rows) + note


def _loading_friction_figure(res: dict, aware: bool):
    """Tip error over time per load case, one colour per plant μ (the friction-aware LACC dashed)."""
    plt = _pyplot()
    blocks = res["friction"]
    fig, axs = plt.subplots(1, 2, figsize=(13, 4))
    for ax, key in zip(axs, ("continuous", "cyclic")):
        for i, (mu, block) in enumerate(blocks.items()):
            c = block[key]
            ax.plot(c["lacc"]["t"], np.asarray(c["lacc"]["error_norm"]) * 1e3, "-", color=f"C{i}", lw=1,
                    label=f"LACC, plant μ = {mu}")
            if aware and "aware" in c:
                ax.plot(c["aware"]["t"], np.asarray(c["aware"]["error_norm"]) * 1e3, "--", color=f"C{i}", lw=1,
                        label=f"friction-aware, μ = {mu}")
        ax.set_title(key)
        ax.set_xlabel("t [s]")
    _finish_axes(fig, axs, "tip error [mm]")
    return fig


def _loading_friction(setup: dict, mus: list, aware: bool, computes: tuple, out: PathLike) -> dict:
    """The loading study per plant μ (:func:`loading` with ``friction``: the checked μ values and compute times)."""
    res: dict = {"friction": {f"{mu:g}": _loading_friction_block(setup, mu, aware, computes) for mu in mus}}
    res["table"] = _loading_friction_table(res, aware, setup["compliance"], computes)
    res["load_note"] = setup["load_note"]
    res["settings"] = {**setup["settings"], "friction": mus, "friction_aware": aware,
                       "compute_s": {"lacc": computes[0], "friction_aware": computes[1] if aware else None}}
    fig = _loading_friction_figure(res, aware) if out is not None else None
    _write(out, "loading", res, fig)
    return res


# ============================================================================== Sec. V-B / V-D / V-E on the rig
_LETTERS = {   # strokes in a 1 × 1.4 box (y right, z up); pen moves between strokes are traced too
    "S": [(1.0, 1.3), (0.8, 1.4), (0.2, 1.4), (0.0, 1.2), (0.0, 0.9), (0.2, 0.7), (0.8, 0.7), (1.0, 0.5),
          (1.0, 0.2), (0.8, 0.0), (0.2, 0.0), (0.0, 0.1)],
    "J": [(0.3, 1.4), (1.0, 1.4), (0.7, 1.4), (0.7, 0.2), (0.5, 0.0), (0.2, 0.0), (0.0, 0.2)],
    "T": [(0.0, 1.4), (1.0, 1.4), (0.5, 1.4), (0.5, 0.0)],
    "U": [(0.0, 1.4), (0.0, 0.2), (0.2, 0.0), (0.8, 0.0), (1.0, 0.2), (1.0, 1.4)],
}
TRAJECTORIES = ("circle", "rose", "SJTU")


def _resample(poly: np.ndarray, n: int) -> np.ndarray:
    seg = np.linalg.norm(np.diff(poly, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    u = np.linspace(0.0, s[-1], n)
    return np.column_stack([np.interp(u, s, poly[:, j]) for j in range(poly.shape[1])])


def trajectory_points(name: str, center, *, points: int = 60, scale: float = 1.0, length: float = 0.16) -> np.ndarray:
    """Waypoints (points, 3) [m] of the paper's Sec. V-B geometries around ``center`` (3,) [m], in the plane
    normal to the base axis: "circle" (30 mm diameter), "rose" (50 mm diameter four-petal rose r = R cos 2θ
    on a dome x = x_c − r² / (2 L)), "SJTU" (letters 10 × 14 mm, 49 mm wide, traced as one path).
    ``scale`` multiplies the sizes."""
    c = np.asarray(center, float)
    if name == "circle":
        th = np.linspace(0, 2 * np.pi, points)
        R = 0.015 * scale
        return c + np.column_stack([np.zeros(points), R * np.cos(th), R * np.sin(th)])
    if name == "rose":
        th = np.linspace(0, 2 * np.pi, points)
        R = 0.025 * scale
        r = R * np.cos(2 * th)
        y, z = r * np.cos(th), r * np.sin(th)
        return c + np.column_stack([-(y ** 2 + z ** 2) / (2 * length), y, z])
    if name == "SJTU":
        poly = np.concatenate([np.array(_LETTERS[ch]) + [1.3 * k, 0.0] for k, ch in enumerate("SJTU")])
        poly = (poly - [2.45, 0.7]) * 0.010 * scale
        yz = _resample(poly, points)
        return c + np.column_stack([np.zeros(points), yz])
    raise BellowsError(f"unknown trajectory {name!r}; one of {', '.join(TRAJECTORIES)}")


def _feasible(model, pts, pressure, load) -> bool:
    prev = model.droop(pressure)
    for p in pts:
        try:
            prev = model.ik(p, pressure, load, q0=prev.q, tensions0=prev.tensions)
        except BellowsError:
            return False
    return True


def trajectory_tracking(*, params=None, shapes: Sequence[str] = TRAJECTORIES, points: int = 60,
                        pressure: float = 0.0, center_tension: Optional[float] = None,
                        plant_options: Optional[PlantOptions] = None, mismatch: bool = True,
                        out: PathLike = None) -> dict:
    """Open-loop trajectory tracking by IK (Sec. V-B, Fig. 7) on the simulated rig: RMSE [m] and % of the
    actuator length per geometry.

    The geometries are centred on the tip with equal tensions ``center_tension`` (default tension_max / 2)
    at ``pressure`` (paper: 0 kPa).  Each is scaled down (bisection, noted in ``scale``) if the preset
    cannot reach all of it within its tension limits.  The plant is mismatched by default
    (:meth:`PlantOptions.mismatched` around the preset: other parameters, friction, tracker noise) — a
    perfect plant would reproduce the IK exactly; the controller's model is the preset.
    """
    from controller import run_open_loop
    params = params or presets.paper()
    model = Model(params)
    c = params.tension_max / 2 if center_tension is None else float(center_tension)
    center = model.fk([c] * model.m, pressure, (0, 0, 0)).tip
    opts = plant_options or (PlantOptions.mismatched(base=params) if mismatch else PlantOptions())
    L = params.length
    res: dict = {"shapes": {}}
    rows = []
    for name in shapes:
        scale = 1.0
        if not _feasible(model, trajectory_points(name, center, points=points, length=L), pressure, (0, 0, 0)):
            lo, hi = 0.0, 1.0
            for _ in range(6):
                mid = 0.5 * (lo + hi)
                ok = _feasible(model, trajectory_points(name, center, points=points, scale=mid, length=L), pressure,
                               (0, 0, 0))
                lo, hi = (mid, hi) if ok else (lo, mid)
            scale = lo
            if scale <= 0:
                raise BellowsError(f"trajectory {name}: not reachable at any scale around {vector(center, 'mm', 1e3)}")
        pts = trajectory_points(name, center, points=points, scale=scale, length=L)
        rig = SimulatedPlant(model, pressure, options=opts)
        r = run_open_loop(model, rig, pts, pressure=pressure)
        rmse = r.rmse()
        res["shapes"][name] = {"scale": scale, "rmse": rmse, "rmse_mm": rmse * 1e3, "rmse_percent_length": 100 * rmse / L,
                               "max_error_mm": float(r.true_errors.max() * 1e3), "targets": pts, "reached": r.true}
        rows.append([name, f"{scale:.3f}", f"{rmse * 1e3:.3f}", f"{100 * rmse / L:.2f}", "< 2.5"])
    res["table"] = _fmt_table(["trajectory", "size scale", "RMSE mm", "RMSE % L", "paper % L"], rows)
    res["settings"] = {"pressure_Pa": pressure, "center_m": center, "center_tension_N": c, "points": points,
                       "actuator": params.name, "plant": repr(opts)}
    fig = None
    if out is not None:
        plt = _pyplot()
        fig, axs = plt.subplots(1, len(shapes), figsize=(4.2 * len(shapes), 3.8))
        for ax, name in zip(np.atleast_1d(axs), shapes):
            e = res["shapes"][name]
            ax.plot(e["targets"][:, 1] * 1e3, e["targets"][:, 2] * 1e3, "k--", lw=0.8, label="target")
            ax.plot(e["reached"][:, 1] * 1e3, e["reached"][:, 2] * 1e3, "C0.-", ms=3, label="reached (open loop)")
            ax.set_aspect("equal")
            ax.set_title(f"{name}: RMSE {e['rmse_mm']:.2f} mm ({e['rmse_percent_length']:.2f} % L)")
            ax.set_xlabel("y [mm]")
        _finish_axes(fig, axs, "z [mm]")
    _write(out, "trajectories", res, fig)
    return res


FIG8_MASSES = (0.015, 0.040, 0.065, 0.115)     # 15 g container + 25 + 25 + 50 g of water


def feedforward_loading(*, params=None, masses: Sequence[float] = FIG8_MASSES, directions: Optional[dict] = None,
                        pressure: float = PRESSURE, plant_options: Optional[PlantOptions] = None,
                        mismatch: bool = True, out: PathLike = None) -> dict:
    """Fig. 8 protocol: hold a tip position under stepped, *known* loads by recomputing the IK for each
    (feed-forward, no feedback).  Per configuration and mass: the steady-state error [m] on the simulated
    rig (mismatched by default).  Masses the preset cannot carry within its tension limits are reported
    as infeasible, not dropped silently."""
    from controller import run_open_loop
    params = params or presets.paper()
    model = Model(params)
    directions = directions or {"horizontal": DIRECTIONS["horizontal"], "downward": DIRECTIONS["downward"]}
    conf = configurations(params, pressure=pressure, directions=directions, max_load_mass=0.0)
    opts = plant_options or (PlantOptions.mismatched(base=params) if mismatch else PlantOptions())
    res: dict = {"configurations": {}}
    rows = []
    for name, cfg in conf.items():
        out_c = {}
        for mass in masses:
            F = np.array([0.0, 0.0, -G * mass])
            rig = SimulatedPlant(model, pressure, load=F, options=opts)
            try:
                r = run_open_loop(model, rig, cfg["target"][None, :], pressure=pressure, load=F)
                err = float(r.true_errors[0])
                out_c[f"{mass * 1e3:.0f}g"] = {"error": err, "error_mm": err * 1e3, "tensions_N": r.tensions[0]}
                rows.append([name, f"{mass * 1e3:.0f}", f"{err * 1e3:.3f}", "< 1 (mean)"])
            except InfeasibleTargetError as exc:
                out_c[f"{mass * 1e3:.0f}g"] = {"error": None, "infeasible": str(exc)[:200]}
                rows.append([name, f"{mass * 1e3:.0f}", "infeasible", ""])
        errs = [v["error"] for v in out_c.values() if v.get("error") is not None]
        out_c["mean_error_mm"] = 1e3 * float(np.mean(errs)) if errs else None
        res["configurations"][name] = out_c
    res["table"] = _fmt_table(["configuration", "load g", "error mm", "paper mm"], rows)
    res["settings"] = {"pressure_Pa": pressure, "masses_kg": list(masses), "actuator": params.name, "plant": repr(opts)}
    _write(out, "feedforward_loading", res)
    return res


def loading_replay(*, params=None, profile: str = "continuous", duration: Optional[float] = None,
                   mass: Optional[float] = None, pressure: float = PRESSURE, compliance: str = "exact",
                   plant_options: Optional[PlantOptions] = None, seed: int = 0, log=None, force: bool = False,
                   sim_compute_time="measured") -> dict:
    """Replay a loading experiment (Sec. V-D/E) on the simulated rig through :func:`controller.run_on_rig`
    — the code path of a real run (limits, health checks, run log).  ``profile``: step | stochastic |
    continuous | cyclic (:mod:`hardware.loads`); default durations: step 10 s, stochastic 30 s, continuous
    50 s, cyclic 4 periods.  Returns the true maximum tip error after the first correction [m], the
    uncontrolled drift is not part of this (see :func:`loading`)."""
    from controller import RunOptions, run_on_rig
    from hardware.loads import load_profile
    params = params or presets.paper()
    model = Model(params)
    kw = {} if mass is None else {"mass": mass}
    if mass is None and profile in ("continuous", "cyclic"):
        kw["mass"] = PAPER_PEAK_MASS if profile == "continuous" else PAPER_CYCLIC_MASS
    prof = load_profile(profile, seed=seed, **kw)
    dur = duration or {"step": 10.0, "stochastic": 30.0, "continuous": 50.0, "cyclic": 32.0, "none": 5.0}[profile]
    tensions = configurations(params, pressure=pressure, directions={"loading": LOADING_DIRECTION},
                              max_load_mass=kw.get("mass", 0.06))["loading"]["tensions"]
    target = model.fk(tensions, pressure, (0, 0, 0)).tip
    opts = plant_options or PlantOptions(length_rate=5e-3, seed=seed)
    rig = SimulatedPlant(model, options=opts, load=prof)
    r = run_on_rig(LACC(model, pressure, compliance=compliance), rig, target,
                   RunOptions(log=log, force=force, duration=dur, idle_period=0.1, sim_compute_time=sim_compute_time))
    te = np.array(r.true_errors)
    return {"profile": profile, "status": r.status, "corrections": r.iterations, "max_error": float(te.max()),
            "max_error_mm": float(te.max() * 1e3), "rms_error_mm": float(np.sqrt(np.mean(te ** 2)) * 1e3),
            "samples": r.samples, "log": None if r.log_path is None else str(r.log_path), "duration_s": r.duration,
            "target_m": target}


if __name__ == "__main__":   # pragma: no cover
    import sys
    outdir = sys.argv[1] if len(sys.argv) > 1 else "bellows_out/control"
    for fn in (table1, compliance_ablation, loading, trajectory_tracking, feedforward_loading):
        r = fn(out=outdir)
        print(f"\n== {fn.__name__}\n{r['table']}")
