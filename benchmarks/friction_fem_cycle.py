"""Tendon friction, rod against FEM: one tension cycle per pressure, both with the same μ.

Run:  python benchmarks/friction_fem_cycle.py [--mu 0.2] [--pressures-kpa 0,50,100] [--actuator docs/data/paper_identified.toml]

The rod is the actuator the quick report identified from the `paper` design's FEM (its actuator.toml, kept in
docs/data/paper_identified.toml; gravity as the design is mounted, validated by that report) with
``tendon_friction = μ``; the FEM is the `paper` design on the coarse mesh with ``friction = μ`` and gravity on.
Tendon 1 is pulled 0 → 3 N → 0 in 6 steps per branch at each pressure (``Model.tension_cycle`` and
``BellowsModel.tension_cycle``, docs/friction.md).  Printed per pressure: the tip distance between the two models
over all 13 states of the cycle [% of L] (mean, max) and the loop areas [N mm] with their ratio.  One FEM cycle
takes 2–3 min on 2 idle cores.
"""

from __future__ import annotations

import argparse
import pathlib
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parent.parent
PEAK = (3.0, 0.0, 0.0)
STEPS = 6


def cycle_row(params, mu: float, pressure_kpa: float) -> dict:
    """One pressure's comparison (module docstring): {pressure_kPa, tip_mean_pct, tip_max_pct, loop_rod_Nmm,
    loop_fem_Nmm, loop_ratio, fem_s}."""
    from ancf import Model
    from validation.reference.designs import design_mounting, mounting_gravity
    from validation.reference.fem_sweep import FemSpec, fem_model
    from validation.report.pipeline import fem_design
    name, geo, mat, _ = fem_design("paper")
    g = mounting_gravity(design_mounting(name))
    rod = Model(params.replace(tendon_friction=mu, gravity=g)).tension_cycle(PEAK, pressure_kpa * 1e3, steps=STEPS)
    t0 = time.perf_counter()
    fem = fem_model(FemSpec(geo, mat, "coarse", gravity=g)).tension_cycle(PEAK, pressure_kpa * 1e3, steps=STEPS,
                                                                           friction=mu, gravity=True)
    d = np.linalg.norm(rod.tip - fem.tip, axis=1) / geo.length * 100.0
    return dict(pressure_kPa=pressure_kpa, tip_mean_pct=float(d.mean()), tip_max_pct=float(d.max()),
                loop_rod_Nmm=rod.loop_area * 1e3, loop_fem_Nmm=fem.loop_area * 1e3,
                loop_ratio=rod.loop_area / fem.loop_area, fem_s=time.perf_counter() - t0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mu", type=float, default=0.2)
    ap.add_argument("--pressures-kpa", default="0,50,100")
    ap.add_argument("--actuator", default=str(ROOT / "docs" / "data" / "paper_identified.toml"))
    a = ap.parse_args()
    from ancf import ActuatorParams
    params = ActuatorParams.from_toml(a.actuator)
    print(f"{'p [kPa]':>8} {'tip mean [% L]':>15} {'tip max [% L]':>14} {'loop rod':>9} {'loop FEM':>9} {'ratio':>6}")
    for p in (float(x) for x in a.pressures_kpa.split(",")):
        r = cycle_row(params, a.mu, p)
        print(f"{p:8g} {r['tip_mean_pct']:15.2f} {r['tip_max_pct']:14.2f} {r['loop_rod_Nmm']:9.2f} "
              f"{r['loop_fem_Nmm']:9.2f} {r['loop_ratio']:6.2f}   (FEM {r['fem_s']:.0f} s)", flush=True)


if __name__ == "__main__":
    main()
