"""Speed of the transient model (Model.simulate) beside a compiled peer, and its real-time factor.

Run:  python benchmarks/bench_dynamics.py [--repeats 5]

1. **The same cable in Exudyn** (``benchmarks/peer_exudyn.py``: ObjectANCFCable, generalized-α, the same
   ρ∞ = 0.9 and fixed step): a clamped-free cable (n = 6, L = 0.16 m, EA = 1000 N, EI = 0.005 N m²,
   m' = 0.3 kg/m) released straight under gravity — a large swing (the tip drops ~85 mm) — for 0.5 s at
   dt = 0.5 ms and 2 ms.  Both are timed interleaved in the same run; medians and their ratio, and the
   largest difference between the two tip trajectories (the two cables' strain measures differ at O(ε):
   docs/dynamics.md).
2. **The `paper` actuator at the step that resolves its first bending frequency to 1 %** (generalized-α
   shortens the period by about (ωh)²/12: h = √0.12 / ω₁), 2 s: a free vibration (released from the
   equilibrium under an extra 0.3 N vertical tip force, T₁ = 2 N at 30 kPa, undamped) and a step response
   (T₁ 0 → 2 N at 30 kPa, 5 % damping — the step excites every mode, and the first steps are subdivided):
   wall time and the real-time factor (simulated / wall time).  The target is ≥ 20×.
3. **The step response at dt = 1 ms** (a 1 kHz loop's step): real-time factor (> 1: the dynamic plant keeps
   up; the target is ≥ 20×) and the time per step, beside the same run on the Python path (the compiled rows
   of ``ancf.dynamics.compiled_step`` switched off, ``transient.COMPILED_ROWS = False``), interleaved.

4. **The dynamic simulated rig** (``SimulatedRig(..., dynamics=True)``, `paper`, ζ = 0.05, a 0.3 N load step and
   small motor moves): wall time per 1 ms rig period — one short run of ``Model.simulate`` with the motor
   lengths and the load as functions of time — with the compiled rows and on the Python path, interleaved.

5. **Tendon friction** (``ancf.dynamics.friction_step``, Python path only): the `paper` actuator with μ = 0.3
   against μ = 0, both on the Python path (``transient.COMPILED_ROWS = False``), interleaved: T₁ ramped
   0.5 → 3 N in 0.2 s then held 0.1 s at 20 kPa, dt = 1 ms, α = 40 /s; time per step and Newton iterations per
   step (medians).  ``--friction-only`` runs this item alone.

6. **The reduced (modal) model** of the same actuator (``controller.observer.modal_model`` about the tension
   step's final state, 4 locked modes, ζ = 0.05; ``ModalPlant``: its zero-order-hold matrices at 1 ms): time
   per 1 ms step of ``ModalPlant.advance`` (a NumPy step in Python) beside the full model's compiled step.

7. **Tendon friction in the dynamic simulated rig** (``ancf.dynamics.held_friction``): the `paper` actuator at
   30 kPa, μ = 0.3 against μ = 0, motor 1 pulling 2 mm at 20 mm/s (ζ = 1): wall time per 1 ms rig period while
   the motor moves, the two rigs interleaved period by period (medians, and the slowest period).
   ``--rig-friction-only`` runs this item alone.

Runs 1–3 have constant loads; run 4's are time-varying (sampled on the step grid for the compiled rows).
Per-step times are wall time / steps, everything included (setup, the energy check, the output rows).  The
last line sets the `paper` 1 kHz real-time factor (and its modal model's) beside the cable's ratio to Exudyn, with
the load average.
The machines are shared: read ratios of interleaved runs, not absolute times.
"""

from __future__ import annotations

import argparse
import math
import os
import pathlib
import statistics
import sys
import time

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).parent))

from ancf import Model, StiffnessLaw, presets
from ancf.dynamics import transient
from ancf.params import Tendon

L, EA, EI, MP = 0.16, 1000.0, 0.005, 0.3


def cable_model(n: int = 6) -> Model:
    """The peer's cable in our model: constant law, no tip mass, tendons at 1 mm that carry nothing."""
    return Model(presets.paper().replace(
        stiffness=StiffnessLaw.constant(EA=EA, EI=EI), line_mass=MP, tip_mass=0.0, tool_offset=0.0,
        n_elements=n, tendons=tuple(Tendon(distance=1e-3, angle=a) for a in (0.0, 2 * math.pi / 3, 4 * math.pi / 3))))


def ours_cable(m: Model, t_end: float, dt: float):
    return m.simulate(t_end, dt, q0=m.q_ref, tensions=(0, 0, 0), damping=0.0, check_limits=False)


def main(repeats: int = 5) -> dict:
    try:
        import peer_exudyn
        have_peer = peer_exudyn.available()
    except ImportError:
        have_peer = False
    out = {}
    m = cable_model()
    ours_cable(m, 0.01, 1e-3)                                   # compile / load kernels
    print("1. swinging cable, n = 6, 0.5 s (medians of %d)" % repeats)
    print(f"   {'dt [ms]':>8} {'ours [s]':>10} {'Exudyn [s]':>11} {'ours [µs/step]':>15} {'Exudyn [µs/step]':>17} "
          f"{'ratio':>7} {'max |Δtip| [mm]':>16}")
    for dt in (0.5e-3, 2e-3):
        ts, tp = [], []
        for _ in range(repeats):
            t0 = time.perf_counter()
            sim = ours_cable(m, 0.5, dt)
            ts.append(time.perf_counter() - t0)
            if have_peer:
                r = peer_exudyn.simulate_cantilever(6, L, EA, EI, MP, t_end=0.5, dt=dt)
                tp.append(r["solve_s"])
        s_ours = statistics.median(ts)
        if have_peer:
            s_peer = statistics.median(tp)
            k = min(len(sim.tip), len(r["tip"]))
            diff = float(np.abs(sim.tip[:k] - r["tip"][:k]).max()) * 1e3
            steps = round(0.5 / dt)
            print(f"   {dt * 1e3:8.2f} {s_ours:10.3f} {s_peer:11.3f} {s_ours / steps * 1e6:15.1f} "
                  f"{s_peer / steps * 1e6:17.1f} {s_ours / s_peer:7.2f} {diff:16.3f}")
            out[f"cable_{dt}"] = {"ours_s": s_ours, "exudyn_s": s_peer, "ratio": s_ours / s_peer, "max_diff_mm": diff}
        else:
            print(f"   {dt * 1e3:8.2f} {s_ours:10.3f} {'(no exudyn)':>11}")
            out[f"cable_{dt}"] = {"ours_s": s_ours}

    pm = Model(presets.paper())
    eq = pm.fk((2.0, 0.0, 0.0), 30e3)
    f1 = pm.modes(eq, 1).frequencies_hz[0]
    start = pm.fk((0.0, 0.0, 0.0), 30e3)
    h1 = math.sqrt(0.12) / (2 * math.pi * f1)
    lifted = pm.fk((2.0, 0.0, 0.0), 30e3, (0.0, 0.0, 0.3), q0=eq.q)
    print(f"2./3. 'paper', 2 s at 30 kPa (first bending mode {f1:.3f} Hz)")
    print(f"   {'dt [ms]':>8} {'wall [s]':>9} {'× real time':>12} {'µs/step':>9} {'Newton its/step':>16}")
    runs = (("free vibration, 1 % of f1", h1, lifted.q, 0.0), ("step response, 1 % of f1", h1, start.q, 0.05),
            ("step response, 1 kHz loop", 1e-3, start.q, 0.05))
    for name, dt, q0, zeta in runs:
        paths = (True, False) if dt == 1e-3 else (True,)
        ws, its = {k: [] for k in paths}, []
        for _ in range(repeats):
            for compiled in paths:                # interleaved: the compiled rows and the Python path
                transient.COMPILED_ROWS = compiled
                sim = pm.simulate(2.0, dt, q0=q0, tensions=(2, 0, 0), pressure=30e3, damping=zeta)
                ws[compiled].append(sim.wall_time)
                its.append(float(sim.newton_iterations[1:].mean()))
        transient.COMPILED_ROWS = True
        steps = len(sim.t) - 1
        for compiled in paths:
            w = statistics.median(ws[compiled])
            label = name if compiled else name + ", Python path"
            print(f"   {dt * 1e3:8.2f} {w:9.3f} {2.0 / w:12.1f} {w / steps * 1e6:9.1f} {statistics.median(its):16.2f}"
                  f"   ({label})")
            out[label] = {"dt_s": dt, "wall_s": w, "real_time_factor": 2.0 / w, "us_per_step": w / steps * 1e6}
    out["rig_period_ms"] = rig_periods(pm)
    out["modal_us_per_step"] = modal_step(pm, out["step response, 1 kHz loop"]["us_per_step"], repeats)
    out["friction"] = friction_steps(repeats)
    out["rig_friction_ms"] = friction_rig_periods()
    rtf = out["step response, 1 kHz loop"]["real_time_factor"]
    ratio = out.get("cable_0.0005", {}).get("ratio")
    print(f"summary: cable / Exudyn {'n/a' if ratio is None else f'{ratio:.2f}×'} time (dt = 0.5 ms); 'paper' at "
          f"1 kHz {rtf:.1f}× real time (target ≥ 20×), its modal model {1e3 / out['modal_us_per_step']:.0f}×; "
          f"load average {os.getloadavg()[0]:.1f}")
    return out


def modal_step(pm: Model, full_us: float, repeats: int, seconds: float = 2.0) -> float:
    """Wall time [µs] per 1 ms step of the reduced modal plant (``controller.observer.ModalPlant``) about the
    tension step's final state (T₁ = 2 N at 30 kPa), median of ``repeats`` runs of ``seconds``."""
    from controller.observer import ModalPlant, modal_model

    eq = pm.fk((2.0, 0.0, 0.0), 30e3)
    mm = modal_model(pm, eq.tendon_lengths, 30e3, count=4, damping_ratio=0.05, near=eq)
    load = np.zeros(3)
    ws = []
    for _ in range(repeats):
        plant = ModalPlant(mm, lambda t: load, step=1e-3)
        t0 = time.perf_counter()
        plant.advance(seconds)
        ws.append(time.perf_counter() - t0)
    us = statistics.median(ws) / round(seconds / 1e-3) * 1e6
    print(f"6. reduced modal model ({len(mm.omega)} modes, ModalPlant, 1 ms zero-order hold): {us:.1f} µs per step, "
          f"{1e3 / us:.0f}× real time ({full_us / us:.1f}× faster than the full model's compiled step)")
    return us


def rig_periods(pm: Model, periods: int = 200) -> dict:
    """Wall time [ms] per 1 ms period of the dynamic simulated rig, compiled rows and Python path interleaved
    period by period on two identical rigs (medians)."""
    from hardware import PlantOptions, SimulatedRig

    ref = pm.fk((2.0, 1.0, 0.5), 30e3)
    def load(t):
        return np.array([0.0, 0.0, -0.3 if t >= 0.02 else 0.0])
    rigs = {k: SimulatedRig(pm, 30e3, load=load, dynamics=True, options=PlantOptions(damping=0.05))
            for k in (True, False)}
    walls = {k: [] for k in rigs}
    for k in range(periods):
        for compiled, rig in rigs.items():
            if k % 50 == 0:
                rig.command(ref.tendon_lengths * (1 - 1e-4 * (k // 50)))
            transient.COMPILED_ROWS = compiled
            t0 = time.perf_counter()
            rig.advance(1e-3)
            walls[compiled].append(time.perf_counter() - t0)
    transient.COMPILED_ROWS = True
    res = {("compiled" if k else "python"): statistics.median(v[10:]) * 1e3 for k, v in walls.items()}
    print(f"4. dynamic simulated rig, 'paper': wall time per 1 ms period {res['compiled']:.2f} ms (compiled rows), "
          f"{res['python']:.2f} ms (Python path) — medians of {periods - 10}")
    return res


def friction_steps(repeats: int = 5) -> dict:
    """Item 5: wall time per step [µs] and Newton iterations per step of a run with tendon friction (μ = 0.3)
    and without (μ = 0), both on the Python path, interleaved (medians)."""
    base = presets.paper()
    models = {mu: Model(base.replace(tendon_friction=mu)) for mu in (0.0, 0.3)}
    s0 = models[0.3].fk_history((0.5, 0.0, 0.0), 20e3)
    def T(t):
        return np.array([0.5 + 2.5 * min(t / 0.2, 1.0), 0.0, 0.0])
    walls, its = {mu: [] for mu in models}, {mu: [] for mu in models}
    transient.COMPILED_ROWS = False
    try:
        for _ in range(repeats):
            for mu, m in models.items():
                kw = {"segment_tensions": s0.segment_tensions} if mu else {}
                sim = m.simulate(0.3, 1e-3, q0=s0.q, tensions=T, pressure=20e3, damping={"alpha": 40.0}, **kw)
                walls[mu].append(sim.wall_time / (len(sim.t) - 1))
                its[mu].append(float(sim.newton_iterations[1:].mean()))
    finally:
        transient.COMPILED_ROWS = True
    res = {mu: {"us_per_step": statistics.median(walls[mu]) * 1e6, "newton_per_step": statistics.median(its[mu])}
           for mu in models}
    r0, r1 = res[0.0], res[0.3]
    print(f"5. tendon friction, 'paper', Python path, dt = 1 ms (medians of {repeats}): μ = 0.3 "
          f"{r1['us_per_step']:.0f} µs/step ({r1['newton_per_step']:.2f} Newton its/step), μ = 0 "
          f"{r0['us_per_step']:.0f} µs/step ({r0['newton_per_step']:.2f}); ratio "
          f"{r1['us_per_step'] / r0['us_per_step']:.1f}×; load average {os.getloadavg()[0]:.1f}")
    return res


def friction_rig_periods(periods: int = 60) -> dict:
    """Item 7: wall time [ms] per 1 ms period of the dynamic simulated rig with tendon friction (μ = 0.3) and
    without, while motor 1 pulls 2 mm at 20 mm/s from T = (2, 1, 0.5) N at 30 kPa (medians and maxima)."""
    from hardware import PlantOptions, SimulatedRig

    ref = Model(presets.paper()).fk((2.0, 1.0, 0.5), 30e3)
    pulled = ref.tendon_lengths - np.array([2e-3, 0.0, 0.0])
    rigs = {mu: SimulatedRig(presets.paper().replace(tendon_friction=mu), 30e3, dynamics=True,
                             options=PlantOptions(damping=1.0, length_rate=0.02)) for mu in (0.0, 0.3)}
    for rig in rigs.values():
        rig.command(ref.tendon_lengths)
        rig.true_tip()
        rig.command(pulled)
    walls = {mu: [] for mu in rigs}
    for _ in range(periods):
        for mu, rig in rigs.items():
            t0 = time.perf_counter()
            rig.advance(1e-3)
            walls[mu].append(time.perf_counter() - t0)
    res = {mu: {"median_ms": statistics.median(w) * 1e3, "max_ms": max(w) * 1e3} for mu, w in walls.items()}
    print(f"7. dynamic simulated rig with tendon friction, 'paper', motor 1 pulling (medians of {periods} periods): "
          f"μ = 0.3 {res[0.3]['median_ms']:.1f} ms per 1 ms period (slowest {res[0.3]['max_ms']:.0f}), μ = 0 "
          f"{res[0.0]['median_ms']:.1f} ms (slowest {res[0.0]['max_ms']:.0f}); load average {os.getloadavg()[0]:.1f}")
    return res


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--friction-only", action="store_true", help="run item 5 (tendon friction) alone")
    ap.add_argument("--rig-friction-only", action="store_true",
                    help="run item 7 (tendon friction in the dynamic simulated rig) alone")
    args = ap.parse_args()
    if args.friction_only:
        friction_steps(args.repeats)
    elif args.rig_friction_only:
        friction_rig_periods()
    else:
        main(args.repeats)
