"""Quick start with the reduced ANCF model (doubles as a regression test: tests/test_examples.py).

Builds the paper's actuator, bends it with one tendon, finds the tensions for a nearby target (IK),
locks the motors and hangs a 50 g load, and compares the tip stiffness with constant and locked tendons.
Run:  python examples/ancf_quickstart.py
"""

import numpy as np

from ancf import Model, presets
from ancf import compliance as cp


def main(verbose: bool = True) -> dict:
    model = Model(presets.paper())
    droop = model.droop()                                          # gravity only
    bend = model.fk(tensions=(3.0, 1.0, 1.0), pressure=30e3)      # interior tensions: margin for IK
    target = bend.tip + np.array([0.0, 0.004, -0.002])             # 4 mm sideways, 2 mm down
    ik = model.ik(target, pressure=30e3)
    load = (0.0, 0.0, -0.05 * 9.81)
    locked = model.fk_locked(ik.tendon_lengths, 30e3, load, q0=ik.q, tensions0=ik.tensions)
    k_tension = cp.directional_stiffness(cp.tension(model, ik).C_p, (0, 0, 1))
    k_locked = cp.directional_stiffness(cp.locked(model, ik, "exact", load_direction=load).C_p, (0, 0, 1))
    out = {
        "droop_tip_mm": droop.tip * 1e3,
        "bend_tip_mm": bend.tip * 1e3,
        "ik_tensions_N": ik.tensions,
        "ik_error_m": float(np.linalg.norm(ik.tip - target)),
        "locked_drift_mm": float(np.linalg.norm(locked.tip - ik.tip) * 1e3),
        "locked_tensions_N": locked.tensions,
        "stiffness_z_N_per_m": {"constant_tension": k_tension, "locked": k_locked},
    }
    if verbose:
        for k, v in out.items():
            print(f"{k:>22}: {np.round(v, 4) if not isinstance(v, dict) else {a: round(b, 1) for a, b in v.items()}}")
    return out


if __name__ == "__main__":
    main()
