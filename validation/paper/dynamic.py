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
from controller import LACC, run_timed, zv_shaper
from hardware import PlantOptions, SimulatedRig

from validation.paper.control import (G, LOADING_DIRECTION, PAPER_CYCLIC_MASS, PRESSURE, PathLike, _fmt_table, _pyplot,
                              _write, configurations)


def _cyclic(mass: float, frequency: float):
    def load(t):
        return np.array([0.0, 0.0, -G * mass * 0.5 * (1.0 - math.cos(2 * math.pi * frequency * t))])
    return load


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


def dynamic_loading(*, frequencies: Sequence[float] = (0.125, 0.25, 0.5, 1.0, 2.0), cycles: int = 3,
                    pressure: float = PRESSURE, tensions=None, cyclic_mass: float = PAPER_CYCLIC_MASS,
                    damping: float = 0.1, motor_rate: float = 5e-3, actuation_latency: float = 0.02,
                    settle_time=0.1, compute_time: float = 0.01, dynamics_step: float = 2e-3,
                    shaping: bool = False, params=None, out: PathLike = None, progress=None) -> dict:
    """Cyclic tip loading (``cyclic_mass`` [kg], 0 → m → 0 as 1 − cos) at each of ``frequencies`` [Hz] for
    ``cycles`` cycles, LACC in the loop, on the static and the dynamic plant (module docstring).

    ``shaping``: also run the dynamic plant with every move ZV-shaped at the model's first locked mode and
    the plant's damping ratio (:mod:`controller.shaping`; columns ``shaped_*``).

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
    if tensions is None:
        tensions = configurations(params, pressure=pressure, directions={"loading": LOADING_DIRECTION},
                                  max_load_mass=cyclic_mass)["loading"]["tensions"]
    tensions = [float(t) for t in tensions]
    target = model.fk(tensions, pressure, (0, 0, 0)).tip
    lengths0 = model.ik(target, pressure, (0, 0, 0)).tendon_lengths
    locked = model.fk_locked(lengths0, pressure, (0, 0, 0))
    f1 = float(model.modes(locked, 1).frequencies_hz[0])
    static_opts = PlantOptions(length_rate=motor_rate)
    dyn_opts = PlantOptions(length_rate=motor_rate, dynamics=True, damping=damping, dynamics_step=dynamics_step)
    rows, series = [], {}
    t_wall = time.perf_counter()
    for f in freqs:
        load = _cyclic(cyclic_mass, f)
        duration = cycles / f
        row = {"frequency_Hz": f}
        plants = [("static", static_opts, None), ("dynamic", dyn_opts, None)]
        if shaping:
            plants.append(("shaped", dyn_opts, zv_shaper(f1, damping)))
        for name, opts, shaper in plants:
            rig = SimulatedRig(model, pressure, load=load, options=opts)
            r = run_timed(LACC(model, pressure), rig, target, duration=duration, compute_time=compute_time,
                          actuation_latency=actuation_latency, settle_time=settle_time,
                          sample_dt=min(0.01, 0.02 / f), shaper=shaper)
            judged = r.t >= 1.0 / f
            en = r.error_norm[judged]
            row[f"{name}_max_mm"] = float(en.max()) * 1e3
            row[f"{name}_rms_mm"] = float(np.sqrt(np.mean(en ** 2))) * 1e3
            row[f"corrections_{name}"] = int(r.corrections)
            if name != "shaped":
                tips = _uncontrolled(model, pressure, lengths0, load, r.t, opts)
                row[f"uncontrolled_{name}_mm"] = float(np.linalg.norm(tips - tips[0], axis=1)[judged].max()) * 1e3
            series[(f, name)] = (r.t, r.error_norm)
            if progress is not None:
                progress(f, name)
        rows.append(row)
    header = ["load [Hz]", "LACC static", "LACC dynamic", "LACC dyn. RMS", *(["dynamic, ZV"] if shaping else []),
              "free static", "free dynamic", "corrections s/d" + ("/ZV" if shaping else "")]
    table = _fmt_table(header, [[f"{r['frequency_Hz']:g}", f"{r['static_max_mm']:.3f}", f"{r['dynamic_max_mm']:.3f}",
                                 f"{r['dynamic_rms_mm']:.3f}", *([f"{r['shaped_max_mm']:.3f}"] if shaping else []),
                                 f"{r['uncontrolled_static_mm']:.2f}", f"{r['uncontrolled_dynamic_mm']:.2f}",
                                 f"{r['corrections_static']}/{r['corrections_dynamic']}"
                                 + (f"/{r['corrections_shaped']}" if shaping else "")] for r in rows])
    table += ("\ntip errors after the first cycle [mm] (max, and RMS where said); free: the motors held at the "
              "unloaded IK lengths"
              f"\nfirst locked bending mode {f1:.2f} Hz; {cyclic_mass * 1e3:.0f} g cyclic load; loop: compute "
              f"{compute_time * 1e3:g} ms + motors at {motor_rate * 1e3:g} mm/s + {actuation_latency * 1e3:g} ms "
              + (f"+ settle {settle_time * 1e3:g} ms" if settle_time != "still" else "+ wait for a still tip")
              + f"; dynamic plant ζ = {damping:g}")
    res = {"rows": rows, "table": table, "first_mode_Hz": f1, "wall_s": time.perf_counter() - t_wall,
           "settings": {"pressure_Pa": pressure, "tensions_N": tensions, "target_m": target,
                        "cyclic_mass_kg": cyclic_mass, "cycles": cycles, "damping_ratio": damping,
                        "motor_rate_m_per_s": motor_rate, "actuation_latency_s": actuation_latency,
                        "settle_time_s": settle_time, "compute_time_s": compute_time,
                        "dynamics_step_s": dynamics_step, "shaping": shaping, "actuator": params.name}}
    fig = None
    if out is not None:
        plt = _pyplot()
        fig, (a, b) = plt.subplots(1, 2, figsize=(12, 4.2))
        fs = [r["frequency_Hz"] for r in rows]
        a.loglog(fs, [r["static_max_mm"] for r in rows], "o-", label="LACC, static plant")
        a.loglog(fs, [r["dynamic_max_mm"] for r in rows], "s-", label="LACC, dynamic plant")
        if shaping:
            a.loglog(fs, [r["shaped_max_mm"] for r in rows], "^-", label="LACC, dynamic plant, ZV-shaped moves")
        a.loglog(fs, [r["uncontrolled_static_mm"] for r in rows], "o:", color="0.5", label="uncontrolled, static")
        a.loglog(fs, [r["uncontrolled_dynamic_mm"] for r in rows], "s:", color="0.3", label="uncontrolled, dynamic")
        a.set_xlabel("load frequency [Hz]"), a.set_ylabel("max tip error after the first cycle [mm]")
        a.grid(alpha=0.3, which="both"), a.legend(fontsize=8)
        a.set_title(f"{cyclic_mass * 1e3:.0f} g cyclic load; first locked mode {f1:.2f} Hz", fontsize=9)
        fmax = fs[-1]
        for name, style in (("static", "C0-"), ("dynamic", "C1-"), ("shaped", "C2-")):
            if (fmax, name) in series:
                t, e = series[(fmax, name)]
                b.plot(t, e * 1e3, style, label=f"LACC, {'dynamic plant, ZV-shaped moves' if name == 'shaped' else name + ' plant'}")
        b.set_xlabel("t [s]"), b.set_ylabel("tip error [mm]"), b.grid(alpha=0.3), b.legend(fontsize=8)
        b.set_title(f"at {fmax:g} Hz", fontsize=9)
        fig.tight_layout()
    _write(out, "dynamic_loading", res, fig)
    return res
