"""Speed of one LACC step (Algorithm 1 lines 6–12: IK + two compliance evaluations) at n = 6.

Run:  python benchmarks/bench_lacc.py [--repeats 200]

One step = constant-tension compliance C_q (eq. 8) + taut set + locked compliance C'_p + the load update
+ a warm-started IK + the tendon lengths, i.e. ``LACC.step`` exactly as the loop calls it (the plant's
solve is not part of the controller's time).  Each repeat starts from the same converged controller state
with a fresh tip error of ≈ 0.5 mm, so every step does real work.  An FK solve of the same preset (warm
start from a neighbouring state, and cold from the straight reference) is timed in the same run,
interleaved, and the ratio printed.  Target: ≤ 10 ms per step (≥ 50× under the paper's ≈ 0.5 s loop).

Against a compiled peer, in the same run (interleaved): Exudyn's static solve of an n = 6 ANCF cable
cantilever under a tip load (``benchmarks/peer_exudyn.py``; ``pip install -e .[bench]``), beside our cold FK of
the same cantilever, the warm IK and the LACC step.  Targets for a 1 kHz loop: LACC step ≤ 2×, IK ≤ 1.5×,
FK ≤ 0.5× the peer's solve.

Then a saturated LACC step (the target out of reach under the estimated load: the bounded IK of
:mod:`ancf.compiled_bounded` and the nearest reachable state), beside the same step with scipy's
``least_squares`` (the path before it; still the fallback), interleaved.

Last: one ``run_on_rig`` cycle on the simulated rig with and without the run log (interleaved), a log append
in blocks against a flush per row, and the loop timing budget of a busy cycle (controller, rig I/O, log,
whole cycle: median and 99th percentile) as the run log records it (docs/rig.md, "Loop timing budget").

Profile of the step (cProfile, n = 6, paper preset, before the compiled loops): ≈ 60 % IK (3–4 Newton
iterations; per iteration one assembly — 0.14 ms with three taut tendons, their Hessians being most of it —
and ≈ 0.1 ms of Python around it), ≈ 25 % compliances (a second assembly at the same state and five dense
solves with H), the rest the load update and bookkeeping.  Now: the FK and IK Newton loops run compiled
(:mod:`ancf.compiled_solvers`; the energy and lengths of the last iterate and the Cholesky of its tangent are
kept, so no assembly or factorisation is repeated for the result and its stability check), the IK hands its
final tangent to the compliances, and one solve with H serves every compliance form at a state.
"""

from __future__ import annotations

import argparse
import copy
import statistics
import time

import numpy as np

from ancf import Model, presets
from ancf import compliance as cp
from controller import LACC

P = 60e3
TENSIONS = (2.2, 1.6, 1.6)
LOAD = np.array([0.0, 0.02, -0.4])


def timed(fn, *a, **k):
    t = time.perf_counter()
    out = fn(*a, **k)
    return out, time.perf_counter() - t


def _peer():
    """Exudyn's n = 6 cantilever solve and our cold FK of the same cantilever, or None without the peer."""
    import pathlib
    import sys
    sys.path.insert(0, str(pathlib.Path(__file__).parent))
    try:
        import peer_exudyn
    except ImportError:
        return None
    if not peer_exudyn.available():
        return None
    from ancf import StiffnessLaw
    L, EA, EI, F = 0.16, 767.2, 0.0839, (0.0, 0.0, -0.49)
    cant = Model(presets.paper().replace(n_elements=6, stiffness=StiffnessLaw.constant(EA=EA, EI=EI),
                                         line_mass=0.0, tip_mass=0.0, tool_offset=0.0))
    cant.fk((0, 0, 0), 0.0, F)
    return (lambda: peer_exudyn.solve_cantilever(6, L, EA, EI, F)["solve_s"],
            lambda: timed(cant.fk, (0, 0, 0), 0.0, F)[1])


def main(repeats: int = 200, seed: int = 0) -> dict:
    m = Model(presets.paper())
    ref = m.fk(TENSIONS, P, (0, 0, 0))
    target = ref.tip
    rng = np.random.default_rng(seed)
    ctrls = {meth: LACC(m, P, compliance=meth, tolerance=0.0) for meth in ("ik", "paper", "exact")}
    for c in ctrls.values():
        c.start(target, initial_load=0.5 * LOAD)
    saved = {k: (copy.deepcopy(c.state), c.estimate, c.mode, c.command_target.copy()) for k, c in ctrls.items()}
    t = {k: [] for k in ("step_ik", "step_paper", "step_exact", "ik_warm", "C_tension", "active_set",
                         "C_locked_ik", "C_locked_exact", "fk_warm", "fk_cold", "peer_solve", "fk_cold_cantilever")}
    peer = _peer()
    for k, c in ctrls.items():                      # compile/warm up
        c.step(target + np.array([0, 0, -5e-4]))
    for _ in range(repeats):
        e = np.array([0.0, *rng.normal(size=2)]) * 3e-4       # lateral/vertical error (axis: stiff)
        dF = np.array([0.0, *rng.normal(size=2)]) * 0.05      # the kind of load update a step makes
        for k, c in ctrls.items():
            st, F, mode, ct = saved[k]
            c.state, c._F, c.mode, c.command_target = st, F.copy(), mode, ct.copy()
            _, s = timed(c.step, target + e)
            t[f"step_{k}"].append(s)
        st = saved["ik"][0]
        _, s = timed(m.ik, target, P, st.tip_force + dF, q0=st.q, tensions0=st.tensions)
        t["ik_warm"].append(s)
        _, s = timed(cp.tension, m, st)
        t["C_tension"].append(s)
        _, s = timed(cp.active_set, m, st, LOAD, "paper")
        t["active_set"].append(s)
        _, s = timed(cp.locked, m, st, "ik")
        t["C_locked_ik"].append(s)
        _, s = timed(cp.locked, m, st, "exact")
        t["C_locked_exact"].append(s)
        _, s = timed(m.fk, st.tensions, P, LOAD, q0=ref.q)
        t["fk_warm"].append(s)
        _, s = timed(m.fk, st.tensions, P, LOAD)
        t["fk_cold"].append(s)
        if peer is not None:
            t["peer_solve"].append(peer[0]())
            t["fk_cold_cantilever"].append(peer[1]())
    med = {k: statistics.median(v) * 1e3 for k, v in t.items() if v}
    print(f"LACC step at n = {m.n} (median of {repeats}, milliseconds)")
    for k in ("step_ik", "step_paper", "step_exact"):
        print(f"  LACC step, compliance={k[5:]:<6}          {med[k]:8.3f}   = {med[k] / med['fk_warm']:5.2f} × FK warm"
              f"   = {med[k] / med['fk_cold']:5.2f} × FK cold")
    print("  parts:")
    for k in ("ik_warm", "C_tension", "active_set", "C_locked_ik", "C_locked_exact"):
        print(f"    {k:<32} {med[k]:8.3f}")
    print(f"  FK warm (neighbouring state)            {med['fk_warm']:8.3f}")
    print(f"  FK cold (straight reference)            {med['fk_cold']:8.3f}")
    if peer is not None:
        x = med["peer_solve"]
        print(f"\nagainst Exudyn's static solve of the n = 6 cantilever, same run ({x:.3f} ms):")
        print(f"  {'':40s} {'ms':>8s} {'× Exudyn':>9s}  target")
        for label, k, target in (("LACC step (exact)", "step_exact", 2.0), ("IK warm (the step's IK)", "ik_warm", 1.5),
                                 ("FK cold, the same cantilever", "fk_cold_cantilever", 0.5)):
            r = med[k] / x
            print(f"  {label:40s} {med[k]:8.3f} {r:9.2f}  ≤ {target:g}: {'met' if r <= target else 'NOT met'}")
    else:
        print("  (Exudyn not installed: pip install -e .[bench] for the peer's ratios)")
    ok = med["step_exact"] <= 10.0
    print(f"target ≤ 10 ms per step (default, exact): {'met' if ok else 'NOT met'} ({med['step_exact']:.2f} ms; "
          f"paper loop ≈ 500 ms → {500 / med['step_exact']:.0f}× faster)")
    med.update(saturated_step(max(repeats // 5, 10), unsaturated=med["step_exact"]))
    med.update(rig_cycle(max(repeats // 4, 10)))
    return med


def saturated_step(repeats: int = 40, unsaturated: float | None = None) -> dict:
    """A saturated LACC step (the target out of reach under the estimated load: the bounded IK and the nearest
    reachable state) with the compiled bounded IK and with scipy's least_squares (``Model.fast_bounded_ik =
    False``, the path before it), interleaved; the paper preset at 30 kPa, a target 0.6 N inside T3's bound
    and a 0.5 N lateral load (tests/test_controller/test_saturation.py), a fresh tracker noise each repeat."""
    P_sat, load = 30e3, np.array([0.0, 0.5, 0.0])
    m = Model(presets.paper())
    target = m.fk((2.0, 1.0, 0.6), P_sat).tip
    c = LACC(m, P_sat, tolerance=0.0)
    c.start(target)
    for _ in range(6):                         # the plant (locked lengths under the hidden load) until settled
        rep = c.step(m.fk_locked(m.rest_lengths(c.state), P_sat, load, q0=c.state.q).tip)
    assert rep.saturated, "the benchmark's load must saturate the actuator"
    meas = m.fk_locked(m.rest_lengths(c.state), P_sat, load, q0=c.state.q).tip
    saved = (copy.deepcopy(c.state), c._F.copy(), c.mode, c.command_target.copy(), c._offset.copy())
    rng = np.random.default_rng(1)
    t = {True: [], False: []}
    try:
        for _ in range(repeats):
            noise = rng.normal(size=3) * 5e-5
            for fast in (True, False):
                Model.fast_bounded_ik = fast
                st, F, mode, ct, off = saved
                c.state, c._F, c.mode, c.command_target, c._offset = st, F.copy(), mode, ct.copy(), off.copy()
                rep, s = timed(c.step, meas + noise)
                assert rep.saturated
                t[fast].append(s)
    finally:
        Model.fast_bounded_ik = True
    out = {"step_saturated": statistics.median(t[True]) * 1e3,
           "step_saturated_least_squares": statistics.median(t[False]) * 1e3}
    print(f"saturated LACC step (bounded IK, nearest reachable state; median of {repeats}, ms): "
          f"{out['step_saturated']:.2f} compiled, {out['step_saturated_least_squares']:.2f} with least_squares "
          f"({out['step_saturated_least_squares'] / out['step_saturated']:.1f}×)"
          + ("" if unsaturated is None else f"; unsaturated step {unsaturated:.2f}"))
    return out


def rig_cycle(repeats: int = 50) -> dict:
    """One cycle of ``controller.run_on_rig`` on the simulated rig (health check + measurement + LACC step +
    command + the plant's locked FK), with and without the SWMR run log, and one log append alone."""
    import tempfile
    from controller import RunOptions, run_on_rig
    from hardware import PlantOptions, SimulatedRig
    from hardware.loads import load_profile
    from hardware.runlog import RunLog, loop_timing, read_run_log
    m = Model(presets.paper())
    target = m.fk(TENSIONS, P, (0, 0, 0)).tip
    out = {}
    with tempfile.TemporaryDirectory() as tmp:
        cycles = {"cycle_no_log": [], "cycle_with_log": []}
        for i in range(2):                       # interleaved: without, with, without, with
            for key, log in (("cycle_no_log", None), ("cycle_with_log", f"{tmp}/b{i}.h5")):
                rig = SimulatedRig(m, load=load_profile("stochastic", period=0.5, seed=1),
                                   options=PlantOptions(noise_std=5e-5, length_rate=5e-3))
                stamps = []
                run_on_rig(LACC(m, P, tolerance=1e-4), rig, target,
                           RunOptions(log=log, duration=repeats * 0.1, idle_period=0.1, sim_compute_time=0.0,
                                      status=lambda s: stamps.append(time.perf_counter())))
                cycles[key] += list(np.diff(stamps))
        for key, v in cycles.items():
            out[key] = statistics.median(v) * 1e3
        # the loop timing budget as the run log records it (docs/rig.md, "Loop timing budget"): busy cycles only
        # (a step whose error is within tolerance computes nothing and is left out)
        budget = {k: [] for k in ("compute_time", "io_time", "cycle_time")}
        for i in range(2):
            smp = read_run_log(f"{tmp}/b{i}.h5").samples
            busy = np.asarray(smp["compute_time"], float) > 1e-4
            for k in budget:
                budget[k] += list(np.asarray(smp[k], float)[busy])
        lt = loop_timing(budget)
        for k in budget:
            out[f"budget_{k}"], out[f"budget_{k}_p99"] = lt[k]["median"] * 1e3, lt[k]["p99"] * 1e3
        for flush_rows, key in ((1, "log_append_flush_each_row"), (50, "log_append_blocks")):
            with RunLog(f"{tmp}/c{flush_rows}.h5", n_tendons=3, flush_rows=flush_rows) as log:
                t0 = time.perf_counter()
                for k in range(10 * repeats):
                    log.sample(t=float(k), tip=target, tension=TENSIONS, pressure=P)
                out[key] = (time.perf_counter() - t0) / (10 * repeats) * 1e3
    print(f"run_on_rig cycle on the simulated rig (median, ms): {out['cycle_no_log']:.2f} without a log, "
          f"{out['cycle_with_log']:.2f} with the SWMR log (+{100 * (out['cycle_with_log'] / out['cycle_no_log'] - 1):.0f} %); "
          f"one log append incl. its share of the flushes (mean) {out['log_append_blocks']:.3f} ms in blocks of 50 rows, "
          f"{out['log_append_flush_each_row']:.3f} ms flushing every row")
    print("loop timing budget of a busy cycle, from the run log (median / p99, ms): controller "
          f"{out['budget_compute_time']:.2f} / {out['budget_compute_time_p99']:.2f}, rig I/O "
          f"{out['budget_io_time']:.2f} / {out['budget_io_time_p99']:.2f}, log append {out['log_append_blocks']:.2f}, "
          f"whole cycle {out['budget_cycle_time']:.2f} / {out['budget_cycle_time_p99']:.2f}")
    return out


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=200)
    main(ap.parse_args().repeats)
