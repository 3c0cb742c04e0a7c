"""LACC quick start: hold a tip position under a load the controller does not know (Algorithm 1).

Run:  python examples/lacc_quickstart.py [--compliance ik|paper|exact] [--mass-g 40] [--mismatch]
(import-safe: nothing runs on import; ``main([])`` returns the numbers and is used as a regression test).

The plant is the locked-tendon-length model with a hidden 40 g tip load (optionally with model mismatch,
tracker noise, motor quantisation/speed and tendon friction).  LACC runs beside the VF-CC baseline.
"""

from __future__ import annotations

import argparse

import numpy as np


def main(argv=None, verbose: bool = True) -> dict:
    from ancf import Model, presets
    from controller import LACC, VFCC, PlantOptions, SimulatedPlant, run_iterations

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--compliance", default="exact", choices=["exact", "ik", "paper"])
    ap.add_argument("--mass-g", type=float, default=40.0)
    ap.add_argument("--iterations", type=int, default=12)
    ap.add_argument("--mismatch", action="store_true", help="imperfect plant (PlantOptions.mismatched)")
    ap.add_argument("--preset", default="paper", help="actuator preset name or .toml file")
    a = ap.parse_args(argv)

    model = Model(presets.get(a.preset))
    p = 60e3                                                    # Pa
    target = model.fk((2.2, 1.6, 1.6), p, (0, 0, 0)).tip        # near-horizontal tip [m]
    load = np.array([0.0, 0.0, -9.81 * a.mass_g * 1e-3])        # N, hidden from the controllers
    opts = PlantOptions.mismatched() if a.mismatch else PlantOptions()
    out = {"target_mm": target * 1e3, "load_N": load}
    for ctrl in (LACC(model, p, compliance=a.compliance), VFCC(model, p)):
        plant = SimulatedPlant(model, p, load=load, options=opts)
        res = run_iterations(ctrl, plant, target, iterations=a.iterations)
        key = ctrl.name.lower().replace("-", "")
        out[key] = {"errors_mm": [e * 1e3 for e in res.errors], "converged": res.converged,
                    "iterations": res.iterations, "estimate_N": ctrl.estimate,
                    "compute_ms": [t * 1e3 for t in res.compute_times]}
        if verbose:
            print(f"{ctrl.name:6s} tip error per iteration [mm]: {np.round(out[key]['errors_mm'], 4).tolist()}")
            print(f"{'':6s} converged below 0.2 mm: {res.converged} after {res.iterations} iterations; "
                  f"estimate {np.round(ctrl.estimate, 3).tolist()} N (true {load.round(3).tolist()} N)")
    return out


if __name__ == "__main__":
    main()
