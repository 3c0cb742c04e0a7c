"""LACC under a slowly growing load in time, with the real solver clock in the loop (Sec. V-E, short).

Run:  python examples/lacc_loading.py [--seconds 6] [--peak-g 60] [--loop-s 0]
(import-safe; ``main([])`` is used as a regression test).

The load ramps from 0 to ``--peak-g`` over the first 2/3 of the run and is then held.  Each correction
costs the measured compute time of the LACC step, the motor move at 5 mm/s and 0.1 s of settling;
``--loop-s`` replaces the compute time by a fixed one (e.g. 0.4 to emulate the paper's ≈ 0.5 s loop).
"""

from __future__ import annotations

import argparse

import numpy as np


def main(argv=None, verbose: bool = True) -> dict:
    from ancf import Model, presets
    from controller import LACC, PlantOptions, SimulatedPlant, run_timed

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=6.0)
    ap.add_argument("--peak-g", type=float, default=60.0)
    ap.add_argument("--loop-s", type=float, default=0.0, help="fixed compute time per step [s]; 0: measured")
    ap.add_argument("--compliance", default="exact", choices=["exact", "ik", "paper"])
    a = ap.parse_args(argv)

    model = Model(presets.paper())
    p = 60e3
    target = model.fk((1.6, 2.2, 2.2), p, (0, 0, 0)).tip
    t_ramp = 2.0 * a.seconds / 3.0
    load = lambda t: np.array([0.0, 0.0, -9.81e-3 * a.peak_g * min(t / t_ramp, 1.0)])
    plant = SimulatedPlant(model, p, load=load, options=PlantOptions(length_rate=5e-3))
    res = run_timed(LACC(model, p, compliance=a.compliance), plant, target, duration=a.seconds,
                    compute_time="measured" if a.loop_s <= 0 else a.loop_s, actuation_latency=0.02,
                    settle_time=0.1, sample_dt=0.1)
    en = res.error_norm
    out = {"t_s": res.t, "error_mm": en * 1e3, "max_error_mm": float(en.max() * 1e3),
           "final_error_mm": float(en[-1] * 1e3), "corrections": res.corrections,
           "final_estimate_N": res.estimate[-1], "true_final_load_N": load(a.seconds),
           "compute_ms_median": float(np.median(res.compute_times) * 1e3)}
    if verbose:
        print(f"max tip error {out['max_error_mm']:.3f} mm, final {out['final_error_mm']:.3f} mm after "
              f"{res.corrections} corrections; LACC step {out['compute_ms_median']:.2f} ms (median)")
        print(f"final load estimate {np.round(out['final_estimate_N'], 3).tolist()} N, "
              f"true {np.round(out['true_final_load_N'], 3).tolist()} N")
    return out


if __name__ == "__main__":
    main()
