"""Coverage of the identification's 95 % intervals on a simulated rig whose truth is known.

Each seed: the rig of ``hardware.simulated.PlantOptions.mismatched(seed)`` (the `paper` actuator with its
stiffness law × 0.95, 15 % more line mass, a 5 g heavier tip, 0.05 mm tracker noise, 0.1 N tendon friction
over a 20 kN/m tendon) with force-sensor noise 0.02 N and pressure-sensor noise 0.3 kPa is driven through the
states of ``bellows experiment`` (:func:`experiment_targets`: :func:`~validation.identification.experiment.design_experiment`
for the `paper` preset with 20 g and 50 g hung at the tip — designed once, the design does not depend on the
seed); each state is recorded with the sensor noise stated in the ``*_std`` fields of the static-states format,
and the `paper` form is identified from the states with ``from_measurements`` — base: the `paper` preset with
its NOMINAL masses (not the plant's), the line and tip mass fitted.  Counted: how often the 95 % interval of
EA, EI and D_eff contains the plant's own value (EA(1), EI(1) at 0 kPa, D_eff), the mean interval width, and the
time per identification.  The states are driven by :func:`simulate_states` (the nominal model's tendon lengths
for each designed state, the plant decides where the actuator goes; ≈ 1 s a seed) rather than by
:func:`~validation.identification.experiment_run.run_experiment`'s closed-loop moves.

    python benchmarks/identification_coverage.py --seeds 50
    python benchmarks/identification_coverage.py --seeds 8 --no-input-std     # the inputs' noise not stated
    python benchmarks/identification_coverage.py --seeds 8 --targets fixed --weighed   # the older study

:func:`simulate_states` is the state generation: replaceable by any designed experiment on a rig.
"""

from __future__ import annotations

import argparse
import time
from typing import Optional, Sequence

import numpy as np

from ancf import ActuatorParams, Model, presets
from hardware.simulated import PlantOptions, SimulatedRig
from hardware.static_states import StaticStates

#: Sensor noise of the study (one standard deviation): force sensors [N], pressure sensor [Pa], tip load [N].
TENSION_STD = 0.02
PRESSURE_STD = 300.0
FORCE_STD = 0.005
#: Tension [N] every tendon keeps when the state does not pull it (a slack tendon's sensor reads noise about 0).
PRETENSION = 0.2
REPORTED = ("EA", "EI", "D_eff")


def designed_targets(pressures_kPa: Sequence[float] = (0, 25, 50, 75, 100)) -> list:
    """Targets (tensions (3,) [N], pressure [Pa], tip load (3,) [N]) over the operating range, ten at each
    pressure: the tendons at the pretension, each alone at 3 N, all three at 2 N, one at 4 N with the others
    at 1 N, two pairs at 2 N, a known vertical load of 0.3 N and a lateral 0.2 N with one tendon at 2 N."""
    lo = PRETENSION
    loads = [((lo, lo, lo), (0, 0, 0)), ((3, lo, lo), (0, 0, 0)), ((lo, 3, lo), (0, 0, 0)), ((lo, lo, 3), (0, 0, 0)),
             ((2, 2, 2), (0, 0, 0)), ((4, 1, 1), (0, 0, 0)), ((lo, lo, lo), (0, 0, -0.3)),
             ((2, lo, lo), (0, 0.2, 0)), ((2, 2, lo), (0, 0, 0)), ((lo, 2, 2), (0, 0, 0))]
    return [(np.array(T, float), 1e3 * float(p), np.array(F, float)) for p in pressures_kPa for T, F in loads]


#: Masses [kg] the designed experiment hangs at the tip.
HUNG_MASSES_KG = (0.02, 0.05)


def experiment_plan(base: Optional[ActuatorParams] = None, masses_kg: Sequence[float] = HUNG_MASSES_KG):
    """The designed experiment of ``base`` (default the `paper` preset; its default form and size, ``masses_kg``
    hung) within the simulated rig's travel (``SimulatedRig``'s default limits)."""
    from hardware.limits import SafetyLimits
    from validation.identification.experiment import design_experiment
    base = base or presets.paper()
    lim = SafetyLimits.around(base.length)
    return design_experiment(base, masses_kg=masses_kg, travel=(lim.length_min, lim.length_max))


def experiment_targets(base: Optional[ActuatorParams] = None, masses_kg: Sequence[float] = HUNG_MASSES_KG) -> list:
    """Targets (tensions (m,) [N], pressure [Pa], tip load (3,) [N]) of the designed experiment of ``base``
    (default the `paper` preset; :func:`~validation.identification.experiment.design_experiment`, its default form
    and size, ``masses_kg`` hung).  A tendon the design leaves slack is held at :data:`PRETENSION` (its sensor
    then reads a tension, not a clipped noise about 0)."""
    plan = experiment_plan(base, masses_kg)
    return [(np.maximum(np.asarray(st.tensions, float), PRETENSION), float(st.pressure),
             np.asarray(st.tip_force, float)) for st in plan.states]


def _commanded_lengths(model: Model, target, tendon_stiffness: float) -> np.ndarray:
    """Motor lengths [m] that put the nominal model at ``target`` (its tendon path lengths less the tendon's
    stretch T/k_s); the plant, not the nominal model, decides where the actuator goes."""
    T, p, F = target
    eq = model.fk(T, p, F, check_limits=False)
    return eq.tendon_lengths - T / tendon_stiffness


def simulate_states(seed: int, targets: Optional[list] = None, *, base: Optional[ActuatorParams] = None,
                    state_input_std: bool = True, **plant_changes) -> tuple:
    """(StaticStates, plant ActuatorParams): ``targets`` (default :func:`designed_targets`) driven on the rig of
    ``PlantOptions.mismatched(seed)`` with the study's sensor noise; each state records the force sensors, the
    pressure sensor, one tracker frame and the known tip load (+ its noise), with the noise stated in the
    ``*_std`` fields (``state_input_std=False``: only the tip's).  ``plant_changes`` override plant options."""
    base = base or presets.paper()
    targets = designed_targets() if targets is None else targets
    opts = PlantOptions.mismatched(seed, base, force_noise_std=TENSION_STD, pressure_noise_std=PRESSURE_STD,
                                   **plant_changes)
    rig = SimulatedRig(opts.params, options=opts)
    nominal = Model(base)
    rng = np.random.default_rng(10_000 + seed)
    T_rec, p_rec, F_rec, tips = [], [], [], []
    ks = opts.tendon_stiffness
    for target in targets:
        rig.set_pressure(target[1])
        rig.set_load(target[2])
        lengths = _commanded_lengths(nominal, target, ks if np.isfinite(ks) else np.inf)
        _move(rig, lengths)
        T_rec.append(rig.read_tensions())
        p_rec.append(rig.read_pressure())
        tips.append(rig.measure())
        F_rec.append(target[2] + rng.normal(0.0, FORCE_STD, 3))
    n = len(targets)
    std = dict(tensions_std=np.full((n, 3), TENSION_STD), pressure_std=np.full(n, PRESSURE_STD),
               tip_force_std=np.full((n, 3), FORCE_STD)) if state_input_std else {}
    states = StaticStates(tensions=np.clip(T_rec, 0.0, None), pressure=np.array(p_rec), tip_position=np.array(tips),
                          tip_force=np.array(F_rec), tip_position_std=np.full((n, 3), opts.noise_std),
                          label=[f"state {i}" for i in range(n)], **std)
    return states, opts.params


def experiment_states(seed: int, folder, *, base: Optional[ActuatorParams] = None, plan=None,
                      samples: int = 3) -> tuple:
    """(run log path, plant ActuatorParams): ``bellows experiment``'s own runner
    (:func:`~validation.identification.experiment_run.run_experiment`: tensions reached on the measured values,
    ``samples`` readings averaged, standard errors stated) driving ``plan`` (default: the designed experiment of
    ``base``, masses :data:`HUNG_MASSES_KG`) on the rig of ``PlantOptions.mismatched(seed)`` with the study's sensor
    noise; the log is what ``identify --measurements`` reads."""
    import pathlib

    from validation.identification.experiment_run import ExperimentOptions, run_experiment
    base = base or presets.paper()
    plan = experiment_plan(base) if plan is None else plan
    opts = PlantOptions.mismatched(seed, base, force_noise_std=TENSION_STD, pressure_noise_std=PRESSURE_STD)
    log = pathlib.Path(folder) / f"experiment_seed{seed}.h5"
    with SimulatedRig(opts.params, options=opts) as rig:
        run_experiment(plan, rig, base, log, options=ExperimentOptions(samples=samples), force=True)
    return log, opts.params


def _move(rig: SimulatedRig, lengths: np.ndarray) -> None:
    """Command ``lengths`` [m] in steps within the rig's largest step, waiting for each move."""
    cur = rig.commanded if rig.commanded is not None else None
    if cur is None:
        rig.command(lengths)
        return
    n = max(1, int(np.ceil(np.max(np.abs(lengths - cur)) / (0.9 * rig.limits.max_step))))
    for k in range(1, n + 1):
        rig.command(cur + (lengths - cur) * k / n)
        rig.advance()


def truth(params: ActuatorParams) -> dict:
    """The plant's own values: EA(1) [N], EI(1) [N m²] at 0 kPa, D_eff [m]."""
    return {"EA": float(params.stiffness.EA(1.0)), "EI": float(params.stiffness.EI(1.0)), "D_eff": params.D_eff}


def identification_base(plant: ActuatorParams, weighed: bool = True) -> ActuatorParams:
    """The actuator given to the identification: the `paper` preset, with the plant's line and tip mass when
    ``weighed`` (masses are weighed, not identified; the nominal masses are a model error of 12 g)."""
    base = presets.paper()
    return base.replace(line_mass=plant.line_mass, tip_mass=plant.tip_mass) if weighed else base


def one_seed(seed: int, *, state_input_std: bool = True, forms=("paper",), weighed: bool = False,
             targets: Optional[list] = None, masses: str = "free", driver=None, **plant_changes) -> dict:
    """Simulate ``targets`` (default :func:`designed_targets`), identify and compare one seed: {"hit": {key: bool},
    "width": {key: relative width}, "error": {key: relative error}, "seconds": identification time, "basis":
    what the intervals contain, "chi2": χ²/dof, "masses": fitted (line [kg/m], tip [kg]), "misfit": warning}."""
    from validation.identification.identify import from_measurements
    if driver is not None:                       # bellows experiment's runner: a run log, as a lab would have it
        states, plant = driver(seed)
    else:
        states, plant = simulate_states(seed, targets, state_input_std=state_input_std, **plant_changes)
    t0 = time.perf_counter()
    res = from_measurements(states, identification_base(plant, weighed), forms=forms, heldout_fraction=0.0,
                            masses=masses)
    dt = time.perf_counter() - t0
    true = truth(plant)
    out = {"hit": {}, "width": {}, "error": {}, "seconds": dt, "basis": res.fit.interval_basis,
           "chi2": res.fit.chi2_per_dof, "masses": (res.params.line_mass, res.params.tip_mass),
           "plant_masses": (plant.line_mass, plant.tip_mass), "misfit": res.fit.misfit}
    for k in REPORTED:
        lo, hi = res.ci95[k]
        v = res.values[k]
        out["hit"][k] = bool(v is not None and lo <= true[k] <= hi)
        out["width"][k] = float((hi - lo) / true[k]) if v is not None else float("nan")
        out["error"][k] = float(v / true[k] - 1) if v is not None else float("nan")
    return out


def coverage(seeds: Sequence[int], targets: Optional[list] = None, **kw) -> dict:
    """{"coverage": {key: share of seeds whose interval holds the truth}, "width": {key: mean relative
    width}, "rms_error": {key: RMS relative error}, "seconds": mean time per identification, "runs": […]}:
    :func:`one_seed` of every seed on the same ``targets`` (default :func:`experiment_targets`, designed once)."""
    targets = experiment_targets() if targets is None else targets
    runs = [one_seed(s, targets=targets, **kw) for s in seeds]
    return {"coverage": {k: float(np.mean([r["hit"][k] for r in runs])) for k in REPORTED},
            "width": {k: float(np.nanmean([r["width"][k] for r in runs])) for k in REPORTED},
            "rms_error": {k: float(np.sqrt(np.nanmean([r["error"][k] ** 2 for r in runs]))) for k in REPORTED},
            "seconds": float(np.mean([r["seconds"] for r in runs])), "runs": runs}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=50, help="number of seeds (plants), from 0")
    ap.add_argument("--no-input-std", action="store_true", help="do not state the inputs' noise in the states")
    ap.add_argument("--targets", choices=("experiment", "fixed"), default="experiment",
                    help="states: the designed experiment (default) or the fixed grid designed_targets()")
    ap.add_argument("--weighed", action="store_true", help="give the fit the plant's own masses")
    ap.add_argument("--masses", choices=("free", "base"), default="free", help="fit the masses or hold them")
    ap.add_argument("--runner", action="store_true", help="measure each seed's states with bellows experiment's "
                    "runner (tension corrections, averaged readings; ~10–30 s a seed) instead of one reading per "
                    "designed state")
    a = ap.parse_args(argv)
    if a.seeds < 1:
        ap.error("--seeds must be >= 1")
    targets = experiment_targets() if a.targets == "experiment" else designed_targets()
    driver = None
    if a.runner:                                 # the states measured by bellows experiment's runner on the rig
        import tempfile

        plan = experiment_plan()
        folder = tempfile.mkdtemp(prefix="coverage_")
        driver = lambda seed: experiment_states(seed, folder, plan=plan)        # noqa: E731
    c = coverage(range(a.seeds), targets, state_input_std=not a.no_input_std, weighed=a.weighed, masses=a.masses,
                 driver=driver)
    print(f"{a.seeds} seeds, {len(targets)} states each ({a.targets}{', bellows experiment runner' if a.runner else ''}); "
          f"input noise stated: {not a.no_input_std}; "
          f"masses: {'the plant' if a.weighed else 'nominal'} base, {a.masses}")
    print(f"{'':8s}{'coverage':>10s}{'mean 95 % width':>18s}{'RMS error':>12s}")
    for k in REPORTED:
        print(f"{k:8s}{100 * c['coverage'][k]:9.0f} %{100 * c['width'][k]:16.2f} %{100 * c['rms_error'][k]:10.2f} %")
    chi2 = [r["chi2"] for r in c["runs"]]
    print(f"χ²/dof median {np.median(chi2):.3g} (max {max(chi2):.3g}); misfit warnings: "
          f"{sum(bool(r['misfit']) for r in c['runs'])} of {a.seeds}")
    print(f"time per identification: {c['seconds']:.2f} s; intervals: {c['runs'][-1]['basis']}")


if __name__ == "__main__":
    main()
