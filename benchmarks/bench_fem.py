"""Benchmark of the FEM reference: time per load case, Newton iterations per step, share of the
linear solver, and a side-by-side of the available sparse direct solvers on the same tangent.

Usage::

    python benchmarks/bench_fem.py                       # coarse mesh, all load cases, solver table
    python benchmarks/bench_fem.py --levels coarse reference --repeat 3 --json bench_fem.json

Prints medians over ``--repeat`` runs and ratios to the fastest solver.
"""

from __future__ import annotations

import argparse
import json
import platform
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from fem_reference import BellowsModel, presets
from fem_reference.solver import available_solvers, factorize

CASES = {
    "tip_0.49N+gravity": dict(tip_force=(0.0, 0.0, -0.49), gravity=True),
    "pressure_30kPa": dict(pressure=30e3),
    "tendon_2N": dict(tensions=(2.0, 0.0, 0.0)),
    "combined": dict(tensions=(2.0, 0.0, 0.0), pressure=30e3, tip_force=(0.0, 0.0, -0.49), gravity=True),
}


def _solver_candidates(n: int, all_solvers: bool = False):
    cands = {}
    names = available_solvers()
    if "pardiso" in names:
        cands["pypardiso mtype 11, analysis+factor"] = lambda A: factorize(A, "pardiso_no_reuse")
        # what a Newton iteration pays: same pattern as the previous factorisation -> phase 22 only
        cands["pypardiso mtype 11, pattern reused"] = lambda A: factorize(A, "pardiso")
    cands["splu MMD_AT_PLUS_A, symmetric mode"] = lambda A: factorize(A, "splu")
    if n < 30000 or all_solvers:  # ~12x slower at 14k DOFs and growing; minutes on the reference mesh
        cands["splu MMD_AT_PLUS_A, partial pivoting"] = lambda A: factorize(A, "splu_partial_pivoting")
    if "umfpack" in names:
        cands["umfpack"] = lambda A: factorize(A, "umfpack")
    try:
        import pyamg

        def amg(A):
            import scipy.sparse.linalg as spla

            ml = pyamg.smoothed_aggregation_solver(A.tocsr())
            M = ml.aspreconditioner()

            class _F:
                def solve(self, b):
                    x, info = spla.gmres(A, b, M=M, rtol=1e-10, restart=100, maxiter=20)
                    return x

            return _F()

        cands["pyamg SA + GMRES"] = amg
    except ImportError:
        pass
    return cands


def bench_cases(level: str, repeat: int, cases: list[str]) -> dict:
    t0 = time.perf_counter()
    model = BellowsModel(presets.paper_bellows(), presets.paper_material(), level)
    setup = time.perf_counter() - t0
    out = dict(level=level, n_dofs=model.n_dofs, n_elements=model.bmesh.n_elements,
               tangent_nnz=int(model.asm.pattern.nnz), setup_s=setup, cases={})
    print(f"\n== mesh {level}: {model.bmesh.n_elements} Hex2, {model.n_dofs} reduced DOFs, "
          f"tangent nnz {model.asm.pattern.nnz / 1e6:.1f} M, setup {setup:.1f} s")
    print(f"{'case':<22} {'time/s':>8} {'steps':>5} {'its':>4} {'its/step':>8} {'linear':>7} {'assembly':>8}")
    res_last = None
    for name in cases:
        runs = []
        for _ in range(repeat):
            res = model.solve(**CASES[name])
            runs.append(res.stats)
        tt = statistics.median(s.t_total for s in runs)
        st = runs[-1]
        lin = statistics.median(s.t_linear / s.t_total for s in runs)
        asm = statistics.median(s.t_assembly / s.t_total for s in runs)
        its = [s["iterations"] for s in st.steps]
        out["cases"][name] = dict(median_s=tt, steps=len(its), iterations=sum(its), its_per_step=its,
                                  linear_share=lin, assembly_share=asm,
                                  tip_position_m=res.tip_position.tolist())
        print(f"{name:<22} {tt:8.2f} {len(its):5d} {sum(its):4d} {np.mean(its):8.1f} {lin:7.0%} {asm:8.0%}")
        res_last = res
    return out, model, res_last


def bench_solvers(model, res, repeat: int, all_solvers: bool = False) -> dict:
    ev = model.evaluate(res.state, res.loadcase, tangent=True)
    A = ev["K"].tocsr()
    b = ev["r"]
    print(f"\n-- linear solvers on the tangent of '{list(CASES)[-1]}' ({A.shape[0]} DOFs, nnz {A.nnz / 1e6:.2f} M)")
    rows = {}
    for name, make in _solver_candidates(A.shape[0], all_solvers).items():
        ts, tsol = [], []
        ok = True
        for _ in range(repeat):
            t0 = time.perf_counter()
            try:
                f = make(A)
                t1 = time.perf_counter()
                x = f.solve(b)
                t2 = time.perf_counter()
            except Exception as e:  # pragma: no cover
                print(f"{name:<40} failed: {e}")
                ok = False
                break
            ts.append(t1 - t0)
            tsol.append(t2 - t1)
            del f
        if not ok:
            continue
        err = float(np.linalg.norm(A @ x - b) / np.linalg.norm(b))
        rows[name] = dict(factor_s=statistics.median(ts), solve_s=statistics.median(tsol), rel_residual=err)
    best = min(r["factor_s"] + r["solve_s"] for r in rows.values())
    print(f"{'solver':<40} {'factor/s':>9} {'solve/s':>8} {'ratio':>6} {'rel.res':>9}")
    for name, r in rows.items():
        tot = r["factor_s"] + r["solve_s"]
        r["ratio_to_best"] = tot / best
        print(f"{name:<40} {r['factor_s']:9.3f} {r['solve_s']:8.3f} {tot / best:6.2f} {r['rel_residual']:9.1e}")
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--levels", nargs="+", default=["coarse"], choices=["coarse", "medium", "reference"])
    ap.add_argument("--cases", nargs="+", default=list(CASES), choices=list(CASES))
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--json", type=Path, default=None)
    ap.add_argument("--all-solvers", action="store_true", help="also SuperLU partial pivoting on big meshes")
    a = ap.parse_args(argv)
    report = dict(python=sys.version.split()[0], machine=platform.machine(), levels=[])
    for level in a.levels:
        rep = 1 if level == "reference" else a.repeat
        out, model, res = bench_cases(level, rep, a.cases)
        out["solvers"] = bench_solvers(model, res, rep, a.all_solvers)
        report["levels"].append(out)
    if a.json:
        a.json.write_text(json.dumps(report, indent=2))
        print(f"\nwrote {a.json}")
    return report


if __name__ == "__main__":
    main()
