"""Mesh convergence and locking of the FEM wall elements on a soft bellows (docs/fem.md §3a).

Prints, for each mesh (elements per convolution × through the wall) and wall element, the unloaded equivalent
rod (EA [N], EI [N m²], blocked-force D_eff [mm]) with the time it took, then the curved-wall bending table
(one element through a thin curved wall, tip deflection over the closed form, κ/μ = 5 … 5000).

Usage::

    python benchmarks/fem_convergence.py                          # the table's meshes (8 × 6 takes minutes)
    python benchmarks/fem_convergence.py --meshes 4x1 4x2 --elements mixed --json conv.json
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from fem_reference import BellowsModel, Material, MeshLevel, presets  # noqa: E402
from fem_reference.verification import curved_wall_bending  # noqa: E402

MESHES = ("4x1", "4x2", "4x3", "8x2", "8x3", "8x6")


def study_geometry():
    """The soft bellows of the study: the `paper` design's convolutions with a 2.6 mm wall, 10.5 mm root and
    20 mm crest radius (the design calibrated on the displacement element)."""
    return presets.paper_bellows().replace(wall_thickness=0.0026, root_radius=0.0105, crest_radius=0.020)


def rod_row(mesh: str, element: str) -> dict:
    n_per_conv, n_thick = (int(v) for v in mesh.split("x"))
    t0 = time.perf_counter()
    model = BellowsModel(study_geometry(), presets.paper_material(),
                         mesh=MeshLevel(n_per_conv, n_thick, 12, 1), element=element)
    rod = model.equivalent_rod()
    return dict(mesh=mesh, element=element, dofs=model.n_dofs, EA_N=rod["EA"], EI_N_m2=rod["EI"],
                D_eff_mm=rod["D_eff"] * 1e3, seconds=time.perf_counter() - t0)


def curved_wall_rows(ratios=(5, 50, 500, 5000)) -> list[dict]:
    return [dict(kappa_over_mu=k, **{el: curved_wall_bending(Material.neo_hookean(0.8e6, 0.8e6 * k), element=el)
                                     for el in ("mixed", "displacement")}) for k in ratios]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--meshes", nargs="+", default=list(MESHES), help="n_per_conv x n_thick, e.g. 4x2")
    ap.add_argument("--elements", nargs="+", default=["mixed", "displacement"], choices=["mixed", "displacement"])
    ap.add_argument("--json", type=Path, default=None, help="also write the rows to this JSON file")
    args = ap.parse_args(argv)
    rows = []
    print(f"{'mesh':>5} {'element':>12} {'DOFs':>7} {'EA/N':>7} {'EI/N m²':>9} {'D_eff/mm':>8} {'time/s':>7}")
    for mesh in args.meshes:
        for el in args.elements:
            r = rod_row(mesh, el)
            rows.append(r)
            print(f"{mesh:>5} {el:>12} {r['dofs']:>7} {r['EA_N']:7.1f} {r['EI_N_m2']:9.5f} {r['D_eff_mm']:8.2f} "
                  f"{r['seconds']:7.1f}", flush=True)
    wall = curved_wall_rows()
    print("\ncurved wall, one element through it (deflection / closed form)")
    print(f"{'κ/μ':>6} {'mixed':>7} {'displacement':>13}")
    for w in wall:
        print(f"{w['kappa_over_mu']:>6} {w['mixed']:7.3f} {w['displacement']:13.3f}")
    if args.json:
        args.json.write_text(json.dumps(dict(rods=rows, curved_wall=wall), indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
