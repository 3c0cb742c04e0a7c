r"""Quasi-static control on a plant with inertia: where does it stop working as the load speeds up?

The paper's cyclic-loading experiment (Sec. V-E: 80 g at 0.125 Hz, LACC within 3.57 mm) runs its
controller on the assumption that the actuator is at rest at every instant.  :func:`dynamic_loading` repeats
that experiment at rising load frequencies (0.125 → 2 Hz) on two plants that differ only in that
assumption — the simulated rig's static plant (locked equilibrium at every instant) and its dynamic plant
(:mod:`hardware.sim_dynamics`: the actuator integrated in time, damping ratio ``damping`` of its first
mode) — with the same loop timing (compute, motor travel at ``motor_rate``, ``actuation_latency``,
``settle_time`` before each measurement: :func:`controller.loop.run_timed`).  For each frequency it
reports the largest and the RMS true tip error after the first cycle with LACC in the loop, and the
uncontrolled motion of the tip (motors held at the unloaded IK lengths) on both plants.

The first locked bending mode of the `paper` actuator at 60 kPa is ≈ 5.5 Hz (docs/dynamics.md), so a
2 Hz load is about a third of it: the uncontrolled dynamic response is amplified by 1/(1 − (f/f₁)²) and
lags the load, and a loop that measures 0.1 s after each move corrects on a tip that is still moving.
"""

from __future__ import annotations

import math
import time
from typing import Optional, Sequence

import numpy as np

from ancf import Model, presets
from ancf.errors import InputError
from controller import LACC, DynamicLACC, run_periodic, run_timed, zv_shaper
from hardware import PlantOptions, SimulatedRig

from validation.paper.control import (G, LOADING_DIRECTION, PAPER_CYCLIC_MASS, PRESSURE, PathLike, _fmt_table, _pyplot,
                              _write, configurations)


def _cyclic(mass: float, frequency: float):
    def load(t):
        return np.array([0.0, 0.0, -G * mass * 0.5 * (1.0 - math.cos(2 * math.pi * frequency * t))])
    return load


def mismatched_plant(params, damping: float) -> tuple:
    """(plant parameters, plant damping ratio, tracker noise [m]) of the mismatched cyclic experiment: EI −20 %,
    D_eff +2.5 %, the plant's damping ratio ``damping`` twice the model's (the model assumes ``damping``/2),
    0.05 mm tracker noise."""
    from ancf import StiffnessLaw
    law = params.stiffness
    scaled = StiffnessLaw.polynomial(EA=list(law.EA_coeffs), EI=[0.8 * c for c in law.EI_coeffs]) \
        .with_pressure(EA=law.EA_pressure, EI=law.EI_pressure)
    return params.replace(D_eff=1.025 * params.D_eff, stiffness=scaled), damping, 5e-5


def _dynamic_lacc_run(model, pressure, target, load, duration, opts, *, model_damping, noise, bandwidth_hz,
                      latency, motor_rate, sample_dt, model_error, internal_model=True):
    """One run of the dynamic LACC at 1 kHz on the dynamic plant (:func:`controller.loop.run_periodic`):
    (the run, the observer's bandwidth as built [Hz])."""
    ctrl = DynamicLACC(model, pressure, period=1e-3, latency=latency, bandwidth_hz=bandwidth_hz,
                       tip_noise_std=max(noise, 1e-5), damping_ratio=model_damping, length_rate=motor_rate,
                       model_error=model_error, internal_model=internal_model)
    rig = SimulatedRig(model, pressure, load=load, options=opts)
    run = run_periodic(ctrl, rig, target, duration=duration, latency=latency, sample_dt=sample_dt)
    return run, ctrl.bandwidth_used_hz, ctrl.harmonic_hz


def _uncontrolled(model, pressure, lengths, load, times, options) -> np.ndarray:
    """Tip positions (k, 3) [m] with the motors held at ``lengths`` under ``load`` at ``times``."""
    rig = SimulatedRig(model, pressure, load=load, options=options)
    rig.command(lengths)
    tips = []
    for t in times:
        if t > rig.time:
            rig.advance(t - rig.time)
        tips.append(rig.true_tip().copy())
    return np.array(tips)


def _figure(rows: list, series: dict, shaping: bool, dl: bool, cyclic_mass: float, f1: float):
    """The study's figure: max error per load frequency (left), the error in time at the highest (right)."""
    plt = _pyplot()
    fig, (a, b) = plt.subplots(1, 2, figsize=(12, 4.2))
    fs = [r["frequency_Hz"] for r in rows]
    a.loglog(fs, [r["static_max_mm"] for r in rows], "o-", label="LACC, static plant")
    a.loglog(fs, [r["dynamic_max_mm"] for r in rows], "s-", label="LACC, dynamic plant")
    if shaping:
        a.loglog(fs, [r["shaped_max_mm"] for r in rows], "^-", label="LACC, dynamic plant, ZV-shaped moves")
    if dl:
        a.loglog(fs, [r["dlacc_max_mm"] for r in rows], "D-", label="dynamic LACC (1 kHz), dynamic plant")
    a.loglog(fs, [r["uncontrolled_static_mm"] for r in rows], "o:", color="0.5", label="uncontrolled, static")
    a.loglog(fs, [r["uncontrolled_dynamic_mm"] for r in rows], "s:", color="0.3", label="uncontrolled, dynamic")
    a.set_xlabel("load frequency [Hz]"), a.set_ylabel("max tip error after the first cycle [mm]")
    a.grid(alpha=0.3, which="both"), a.legend(fontsize=8)
    a.set_title(f"{cyclic_mass * 1e3:.0f} g cyclic load; first locked mode {f1:.2f} Hz", fontsize=9)
    fmax = fs[-1]
    labels = {"static": "LACC, static plant", "dynamic": "LACC, dynamic plant",
              "shaped": "LACC, dynamic plant, ZV-shaped moves", "dlacc": "dynamic LACC, dynamic plant"}
    for name, style in (("static", "C0-"), ("dynamic", "C1-"), ("shaped", "C2-"), ("dlacc", "C3-")):
        if (fmax, name) in series:
            t, e = series[(fmax, name)]
            b.plot(t, e * 1e3, style, label=labels[name])
    b.set_xlabel("t [s]"), b.set_ylabel("tip error [mm]"), b.grid(alpha=0.3), b.legend(fontsize=8)
    b.set_title(f"at {fmax:g} Hz", fontsize=9)
    fig.tight_layout()
    return fig


def _rows_table(rows: list, shaping: bool, dl: bool) -> str:
    """The study's text table of its rows (errors [mm]; the ZV and dynamic-LACC columns where run)."""
    header = ["load [Hz]", "LACC static", "LACC dynamic", "LACC dyn. RMS", *(["dynamic, ZV"] if shaping else []),
              *(["dyn. LACC", "dyn. LACC RMS"] if dl else []),
              "free static", "free dynamic", "corrections s/d" + ("/ZV" if shaping else "")]
    table = _fmt_table(header, [[f"{r['frequency_Hz']:g}", f"{r['static_max_mm']:.3f}", f"{r['dynamic_max_mm']:.3f}",
                                 f"{r['dynamic_rms_mm']:.3f}", *([f"{r['shaped_max_mm']:.3f}"] if shaping else []),
                                 *([f"{r['dlacc_max_mm']:.3f}", f"{r['dlacc_rms_mm']:.3f}"] if dl else []),
                                 f"{r['uncontrolled_static_mm']:.2f}", f"{r['uncontrolled_dynamic_mm']:.2f}",
                                 f"{r['corrections_static']}/{r['corrections_dynamic']}"
                                 + (f"/{r['corrections_shaped']}" if shaping else "")] for r in rows])
    return table


def dynamic_loading(*, frequencies: Sequence[float] = (0.125, 0.25, 0.5, 1.0, 2.0), cycles: int = 3,
                    pressure: float = PRESSURE, tensions=None, cyclic_mass: float = PAPER_CYCLIC_MASS,
                    damping: float = 0.1, motor_rate: float = 5e-3, actuation_latency: float = 0.02,
                    settle_time=0.1, compute_time: float = 0.01, dynamics_step: float = 2e-3,
                    shaping: bool = False, dynamic_lacc: bool = False, mismatch: bool = False,
                    observer_bandwidth_hz: float = 12.0, loop_latency: float = 2e-3,
                    model_error: Optional[float] = 0.12, internal_model: bool = True, params=None,
                    out: PathLike = None, progress=None) -> dict:
    """Cyclic tip loading (``cyclic_mass`` [kg], 0 → m → 0 as 1 − cos) at each of ``frequencies`` [Hz] for
    ``cycles`` cycles, LACC in the loop, on the static and the dynamic plant (module docstring).

    ``shaping``: also run the dynamic plant with every move ZV-shaped at the model's first locked mode and
    the plant's damping ratio (:mod:`controller.shaping`; columns ``shaped_*``).  ``dynamic_lacc``: also run
    the dynamic LACC (:mod:`controller.dynamic_lacc`: the load observer at 1 kHz, commands ``loop_latency``
    [s] after each measurement, motors at ``motor_rate``) on the dynamic plant (columns ``dlacc_*``).
    ``mismatch``: every plant differs from the controllers' model (:func:`mismatched_plant`: EI −20 %,
    D_eff +2.5 %, the model assuming half the plant's damping ratio, 0.05 mm tracker noise).  ``model_error``:
    the dynamic LACC's bound of the modal frequencies' error (its observer bandwidth lowered until the loop
    is stable for it, :class:`controller.DynamicLACC`; None: the model taken as exact, ``observer_bandwidth_hz``
    as asked); the bandwidth built is the row's ``dlacc_bandwidth_Hz``.  ``internal_model``: the dynamic LACC
    learns a periodic load's frequency and adds its oscillator to the observer (:class:`controller.DynamicLACC`;
    the frequency it ends with is the row's ``dlacc_internal_model_Hz``, None without one; the largest error
    over the last cycle ``dlacc_last_cycle_mm``).

    Returns ``{"rows": [{frequency_Hz, static_max_mm, dynamic_max_mm, static_rms_mm, dynamic_rms_mm,
    uncontrolled_static_mm, uncontrolled_dynamic_mm, corrections_static, corrections_dynamic}], "table",
    "settings", "first_mode_Hz"}``; errors are true tip errors after the first cycle [mm]."""
    freqs = [float(f) for f in frequencies]
    if not freqs or any(not (0 < f <= 20) for f in freqs):
        raise InputError(f"frequencies must be in (0, 20] Hz, got {frequencies!r}")
    if isinstance(cycles, bool) or not isinstance(cycles, int) or not 2 <= cycles <= 50:
        raise InputError(f"cycles must be an integer 2…50 (the first is not judged), got {cycles!r}")
    if not (isinstance(cyclic_mass, (int, float)) and 0 < cyclic_mass <= 1.0):
        raise InputError(f"cyclic_mass must be in (0, 1] kg, got {cyclic_mass!r}")
    params = params or presets.paper()
    model = Model(params)
    if dynamic_lacc:            # its options refused up front, before any run (the constructor only checks them)
        DynamicLACC(model, pressure, latency=loop_latency, bandwidth_hz=observer_bandwidth_hz,
                    length_rate=motor_rate, model_error=model_error, internal_model=internal_model)
    plant_params, noise, model_damping = None, 0.0, damping
    if mismatch:
        plant_params, _, noise = mismatched_plant(params, damping)
        model_damping = 0.5 * damping
    if tensions is None:
        tensions = configurations(params, pressure=pressure, directions={"loading": LOADING_DIRECTION},
                                  max_load_mass=cyclic_mass)["loading"]["tensions"]
    tensions = [float(t) for t in tensions]
    target = model.fk(tensions, pressure, (0, 0, 0)).tip
    lengths0 = model.ik(target, pressure, (0, 0, 0)).tendon_lengths
    locked = model.fk_locked(lengths0, pressure, (0, 0, 0))
    f1 = float(model.modes(locked, 1).frequencies_hz[0])
    static_opts = PlantOptions(params=plant_params, noise_std=noise, length_rate=motor_rate)
    dyn_opts = PlantOptions(params=plant_params, noise_std=noise, length_rate=motor_rate, dynamics=True,
                            damping=damping, dynamics_step=dynamics_step)
    rows, series = [], {}
    t_wall = time.perf_counter()
    for f in freqs:
        load = _cyclic(cyclic_mass, f)
        duration = cycles / f
        row = {"frequency_Hz": f}
        plants = [("static", static_opts, None), ("dynamic", dyn_opts, None)]
        if shaping:
            plants.append(("shaped", dyn_opts, zv_shaper(f1, model_damping)))
        if dynamic_lacc:
            plants.append(("dlacc", PlantOptions(**{**dyn_opts.__dict__, "dynamics_step": 1e-3}), None))
        for name, opts, shaper in plants:
            if name == "dlacc":
                r, row["dlacc_bandwidth_Hz"], row["dlacc_internal_model_Hz"] = _dynamic_lacc_run(
                    model, pressure, target, load, duration, opts, model_damping=model_damping, noise=noise,
                    bandwidth_hz=observer_bandwidth_hz, latency=loop_latency, motor_rate=motor_rate,
                    sample_dt=min(0.005, 0.02 / f), model_error=model_error, internal_model=internal_model)
                row["dlacc_last_cycle_mm"] = float(r.error_norm[r.t >= duration - 1.0 / f].max()) * 1e3
            else:
                rig = SimulatedRig(model, pressure, load=load, options=opts)
                r = run_timed(LACC(model, pressure), rig, target, duration=duration, compute_time=compute_time,
                              actuation_latency=actuation_latency, settle_time=settle_time,
                              sample_dt=min(0.01, 0.02 / f), shaper=shaper)
            judged = r.t >= 1.0 / f
            en = r.error_norm[judged]
            row[f"{name}_max_mm"] = float(en.max()) * 1e3
            row[f"{name}_rms_mm"] = float(np.sqrt(np.mean(en ** 2))) * 1e3
            row[f"corrections_{name}"] = int(r.corrections)
            if name in ("static", "dynamic"):
                tips = _uncontrolled(model, pressure, lengths0, load, r.t, opts)
                row[f"uncontrolled_{name}_mm"] = float(np.linalg.norm(tips - tips[0], axis=1)[judged].max()) * 1e3
            series[(f, name)] = (r.t, r.error_norm)
            if progress is not None:
                progress(f, name)
        rows.append(row)
    dl = dynamic_lacc
    table = _rows_table(rows, shaping, dl)
    table += ("\ntip errors after the first cycle [mm] (max, and RMS where said); free: the motors held at the "
              "unloaded IK lengths"
              f"\nfirst locked bending mode {f1:.2f} Hz; {cyclic_mass * 1e3:.0f} g cyclic load; loop: compute "
              f"{compute_time * 1e3:g} ms + motors at {motor_rate * 1e3:g} mm/s + {actuation_latency * 1e3:g} ms "
              + (f"+ settle {settle_time * 1e3:g} ms" if settle_time != "still" else "+ wait for a still tip")
              + f"; dynamic plant ζ = {damping:g}"
              + (f"\ndynamic LACC: 1 kHz, observer {observer_bandwidth_hz:g} Hz asked ("
                 + ("the model as exact" if model_error is None else
                    f"stable for a modal frequency error of ±{model_error:.0%}: built "
                    + ", ".join(sorted({f"{r['dlacc_bandwidth_Hz']:.2f}" for r in rows})) + " Hz")
                 + f"), commands {loop_latency * 1e3:g} ms after each measurement" if dl else "")
              + ("\nmismatched plant: EI −20 %, D_eff +2.5 %, the model's damping ratio half the plant's, "
                 "0.05 mm tracker noise" if mismatch else ""))
    res = {"rows": rows, "table": table, "first_mode_Hz": f1, "wall_s": time.perf_counter() - t_wall,
           "settings": {"pressure_Pa": pressure, "tensions_N": tensions, "target_m": target,
                        "cyclic_mass_kg": cyclic_mass, "cycles": cycles, "damping_ratio": damping,
                        "motor_rate_m_per_s": motor_rate, "actuation_latency_s": actuation_latency,
                        "settle_time_s": settle_time, "compute_time_s": compute_time,
                        "dynamics_step_s": dynamics_step, "shaping": shaping, "actuator": params.name,
                        "dynamic_lacc": dynamic_lacc, "mismatch": mismatch, "model_damping_ratio": model_damping,
                        "tracker_noise_m": noise, "observer_bandwidth_Hz": observer_bandwidth_hz,
                        "loop_latency_s": loop_latency, "model_error": model_error,
                        "internal_model": internal_model}}
    fig = None if out is None else _figure(rows, series, shaping, dl, cyclic_mass, f1)
    _write(out, "dynamic_loading", res, fig)
    return res


#: docs/dynamics.md's controller table: (plant label, the study's ``mismatch``)
CONTROLLER_TABLE_PLANTS = (("model", False), ("mismatch", True))
#: the fast loop of that table (and of the quasi-static table's "fast" rows)
FAST_LOOP = dict(motor_rate=0.05, settle_time=0.02, compute_time=0.002, actuation_latency=0.005)


def controller_table(runs: dict) -> list:
    """Markdown lines of docs/dynamics.md's controller table from :func:`dynamic_loading` results with
    ``shaping`` and ``dynamic_lacc``: ``runs`` maps each label of :data:`CONTROLLER_TABLE_PLANTS` to its
    result.  Columns: max tip error after the first cycle [mm] of LACC on the dynamic plant, of ZV-shaped LACC,
    of the dynamic LACC (and its RMS), the dynamic LACC's observer bandwidth [Hz], the free dynamic motion."""
    lines = ["| plant | load [Hz] | LACC | LACC, ZV | dyn. LACC | dyn. LACC RMS | observer [Hz] | free |",
             "|---|---|---|---|---|---|---|---|"]
    for label, _ in CONTROLLER_TABLE_PLANTS:
        for r in runs[label]["rows"]:
            lines.append(f"| {label} | {r['frequency_Hz']:g} | {r['dynamic_max_mm']:.2f} | {r['shaped_max_mm']:.2f} | "
                         f"{r['dlacc_max_mm']:.2f} | {r['dlacc_rms_mm']:.2f} | {r['dlacc_bandwidth_Hz']:.2f} | "
                         f"{r['uncontrolled_dynamic_mm']:.2f} |")
    return lines


#: docs/dynamics.md's internal-model table: (load frequency [Hz], cycles) on the fast loop with the mismatch
#: (a 0.125 Hz row, 16 s of simulated time, costs over an hour on the shared 2 cores: not in the table)
INTERNAL_MODEL_ROWS = ((1.0, 4), (2.0, 6))


def internal_model_row(frequency: float, cycles: int, *, pressure: float = PRESSURE,
                       cyclic_mass: float = PAPER_CYCLIC_MASS, damping: float = 0.1, internal_model: bool = True,
                       params=None) -> dict:
    """One row of docs/dynamics.md's internal-model table: the dynamic LACC alone (the settings of
    :func:`dynamic_loading` with ``dynamic_lacc``, ``mismatch`` and :data:`FAST_LOOP`'s motors, 2 ms loop
    latency) on the mismatched dynamic plant under the cyclic load at ``frequency`` [Hz] for ``cycles``, and
    the free dynamic motion.  Keys as :func:`dynamic_loading`'s rows (``dlacc_*``, ``uncontrolled_dynamic_mm``)."""
    if not 0 < frequency <= 20 or isinstance(cycles, bool) or not isinstance(cycles, int) or not 2 <= cycles <= 50:
        raise InputError(f"frequency must be in (0, 20] Hz and cycles an integer 2…50, got {frequency!r}, {cycles!r}")
    params = params or presets.paper()
    model = Model(params)
    plant_params, _, noise = mismatched_plant(params, damping)
    tensions = configurations(params, pressure=pressure, directions={"loading": LOADING_DIRECTION},
                              max_load_mass=cyclic_mass)["loading"]["tensions"]
    target = model.fk(tensions, pressure, (0, 0, 0)).tip
    lengths0 = model.ik(target, pressure, (0, 0, 0)).tendon_lengths
    opts = PlantOptions(params=plant_params, noise_std=noise, length_rate=FAST_LOOP["motor_rate"], dynamics=True,
                        damping=damping, dynamics_step=1e-3)
    load, duration = _cyclic(cyclic_mass, frequency), cycles / frequency
    r, bw, hz = _dynamic_lacc_run(model, pressure, target, load, duration, opts, model_damping=0.5 * damping,
                                  noise=noise, bandwidth_hz=12.0, latency=2e-3, motor_rate=FAST_LOOP["motor_rate"],
                                  sample_dt=min(0.005, 0.02 / frequency), model_error=0.12,
                                  internal_model=internal_model)
    judged = r.t >= 1.0 / frequency
    en = r.error_norm[judged]
    tips = _uncontrolled(model, pressure, lengths0, load, r.t, PlantOptions(**{**opts.__dict__, "dynamics_step": 2e-3}))
    return {"frequency_Hz": float(frequency), "cycles": cycles, "dlacc_max_mm": float(en.max()) * 1e3,
            "dlacc_rms_mm": float(np.sqrt(np.mean(en ** 2))) * 1e3,
            "dlacc_last_cycle_mm": float(r.error_norm[r.t >= duration - 1.0 / frequency].max()) * 1e3,
            "dlacc_bandwidth_Hz": bw, "dlacc_internal_model_Hz": hz,
            "uncontrolled_dynamic_mm": float(np.linalg.norm(tips - tips[0], axis=1)[judged].max()) * 1e3}


def internal_model_table(rows: Sequence[dict]) -> list:
    """Markdown lines of docs/dynamics.md's internal-model table from :func:`internal_model_row` rows: max tip error after the first cycle and over the last cycle [mm], RMS
    after the first cycle, the internal model's frequency as learnt [Hz], the free dynamic motion [mm]."""
    lines = ["| load [Hz] | cycles | dyn. LACC + internal model, max after cycle 1 | max, last cycle | RMS | "
             "learnt [Hz] | free |", "|---|---|---|---|---|---|---|"]
    for r in rows:
        hz = r["dlacc_internal_model_Hz"]
        lines.append(f"| {r['frequency_Hz']:g} | {r['cycles']} | {r['dlacc_max_mm']:.2f} | {r['dlacc_last_cycle_mm']:.2f} | "
                     f"{r['dlacc_rms_mm']:.2f} | {'–' if hz is None else f'{hz:.3f}'} | "
                     f"{r['uncontrolled_dynamic_mm']:.2f} |")
    return lines
