"""FEM reference quick start: one combined load case on the paper bellows, tip compliance, VTU + PNG.

Run:  python examples/fem_quickstart.py [--mesh coarse|reference] [--out DIR] [--force] [--png]
Writes quickstart.vtu (and quickstart.png) to ``--out`` (default: ``bellows_out/fem_quickstart`` under the
current folder, ignored by git); the folder is checked before the solve and an earlier result is kept
unless ``--force``.  Import-safe: nothing runs on import; ``main([...])`` is used as a smoke test.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np


def main(argv=None):
    from ancf.outputs import prepare_output_dir
    from fem_reference import BellowsModel, presets

    ap = argparse.ArgumentParser()
    ap.add_argument("--mesh", default="coarse")
    ap.add_argument("--out", type=Path, default=Path("bellows_out") / "fem_quickstart")
    ap.add_argument("--force", action="store_true", help="overwrite an earlier result in --out")
    ap.add_argument("--png", action="store_true")
    a = ap.parse_args(argv)
    files = ["quickstart.vtu"] + (["quickstart.png"] if a.png else [])
    prepare_output_dir(a.out, files, force=a.force)          # before the solve, not after it

    geo = presets.paper_bellows()
    model = BellowsModel(geo, presets.paper_material(), mesh=a.mesh)
    print(f"{model.bmesh.n_elements} Hex2 elements, {model.n_dofs} unknowns")
    res = model.solve(tensions=(2, 0, 0), pressure=30e3, tip_force=(0, 0, -0.49), gravity=True)
    print("tip position [mm]      ", np.round(1e3 * res.tip_position, 3))
    print("cap rotation [deg]     ", np.round(np.degrees(res.cap_rotation_vector), 3))
    print("cable lengths [mm]     ", np.round(1e3 * res.tendon_lengths, 3))
    print("Newton iterations      ", res.iterations, "in", len(res.stats.steps), "load steps,",
          f"{res.stats.t_total:.1f} s")
    Ct = model.tip_compliance(res, mode="tension")
    Cl = model.tip_compliance(res, mode="locked")
    print("vertical tip stiffness [N/m]: tension", round(1 / Ct[2, 2], 1), " locked", round(1 / Cl[2, 2], 1))
    res.save_vtu(a.out / "quickstart.vtu")
    if a.png:
        from fem_reference.render import render_result

        render_result(res, a.out / "quickstart.png")
    return res


if __name__ == "__main__":
    main()
