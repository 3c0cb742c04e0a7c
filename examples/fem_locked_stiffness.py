"""Virtual version of the paper's locked-tendon stiffness experiment (Sec. V-C, Fig. 9) on the FEM.

For p ∈ {0, 25, 50} kPa and top-tendon tension T1 ∈ {0, 1, ..., 5} N (others 0), with gravity:
solve the equilibrium, then the vertical tip stiffness under a 50 g payload both at constant tension
and with the motors locked (every cable length fixed; a locked cable may go slack, never push — the same
experiment as the reduced model's exact locked compliance), (a) from the condensed tangent (linearised,
:func:`validation.reference.fem_sweep.locked_compliance`) and (b) from the nonlinear solve with the payload,
k = 0.05·9.81/(z_unload − z_load).  ``bellows report`` runs the same protocol on both models.

Run:  python examples/fem_locked_stiffness.py [--mesh coarse] [--quick]
"""

from __future__ import annotations

import argparse

import numpy as np


def main(argv=None):
    from fem_reference import BellowsModel, presets
    from validation.reference.fem_sweep import locked_compliance

    ap = argparse.ArgumentParser()
    ap.add_argument("--mesh", default="coarse")
    ap.add_argument("--quick", action="store_true", help="p = 0 and T1 ∈ {0, 2} only")
    a = ap.parse_args(argv)
    model = BellowsModel(presets.paper_bellows(), presets.paper_material(), mesh=a.mesh)
    W = 0.05 * 9.81
    pressures = [0.0] if a.quick else [0.0, 25e3, 50e3]
    tensions = [0.0, 2.0] if a.quick else [0.0, 1.0, 2.0, 3.0, 4.0, 5.0]
    rows = []
    print(f"{'p/kPa':>6} {'T1/N':>5} {'k_tension':>10} {'k_locked':>9} {'k_locked(nl)':>12}  [N/m]")
    for p in pressures:
        prev = None
        for T1 in tensions:
            res = model.solve(tensions=(T1, 0, 0), pressure=p, gravity=True, initial=prev)
            prev = res
            kt = 1 / model.tip_compliance(res, "tension")[2, 2]
            kl = 1 / locked_compliance(model, res, (0.0, 0.0, -1.0))[0][2, 2]
            locked = [float(x) for x in res.tendon_lengths]
            loaded = model.solve(tensions=(T1, 0, 0), pressure=p, gravity=True, tip_force=(0, 0, -W),
                                 locked_lengths=locked, initial=res)
            knl = W / (res.tip_position[2] - loaded.tip_position[2])
            rows.append((p, T1, kt, kl, knl))
            print(f"{p / 1e3:6.0f} {T1:5.1f} {kt:10.1f} {kl:9.1f} {knl:12.1f}")
    return np.array(rows)


if __name__ == "__main__":
    main()
