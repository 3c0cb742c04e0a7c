"""Benchmark of the FEM reference: time per load case, Newton iterations per step, share of the
linear solver, and a side-by-side of the available sparse direct solvers on the same tangent.

Usage::

    python benchmarks/bench_fem.py                       # coarse mesh, all load cases, solver table
    python benchmarks/bench_fem.py --levels coarse reference --repeat 3 --json bench_fem.json
    python benchmarks/bench_fem.py --compare-kernels --repeat 5   # numpy vs numba assembly, interleaved
    python benchmarks/bench_fem.py --symmetry --repeat 3   # symmetric-subspace vs full Newton, interleaved
    python benchmarks/bench_fem.py --rings --repeat 3      # ring rotations in the Newton update on/off, cold bends
    python benchmarks/bench_fem.py --transfer --repeat 3   # refined solves from the coarse equilibrium / from rest
    python benchmarks/bench_fem.py --worker-threads --repeat 3   # two forked FEM workers: 1 thread per pool / inherited

Prints medians over ``--repeat`` runs and ratios to the fastest solver.  ``--compare-kernels`` times the
numpy reference assembly (``HexAssembler(kernel="numpy")``) against the compiled kernel (``"numba"``,
the default) in one process, alternating old/new on every repetition: the tangent assembly alone, the
reduced residual + tangent (``BellowsModel.evaluate``), and one full coarse solve of the ``fem solve``
case (30 kPa, T = (2, 0, 0) N, gravity), with medians, ratios and the tip-position difference.
Run it once more with ``OPENBLAS_NUM_THREADS=1`` to see the numpy path without BLAS thread contention.
``--symmetry`` times ``solve(symmetry=True)`` (Newton steps in the invariant subspace,
:mod:`fem_reference.symmetry`) against ``solve(symmetry=False)`` on :data:`SYMMETRY_CASES`, alternating the two on
every repetition: median wall time, factorisation time, Newton iterations, the group order used, the ratio, and
the tip-position difference.  ``--rings`` does the same for the ring rotations of the Newton update
(:mod:`fem_reference.corotation`, ``RING_UPDATE`` on/off) on :data:`BEND_CASES`, cold bends from rest, with the
factorisations; ``--transfer`` for the discretisation error's refined solves (the level refined 2× along the
profile) started from the same case solved on the level (:mod:`fem_reference.transfer`) or from rest.
``--worker-threads`` solves two bends at once in two worker processes forked by :func:`validation.infra.runner.run_tasks`
(as the report's sweep does) after the parent ran PARDISO on 2 threads: each worker's BLAS and MKL pools limited to
one thread (:func:`validation.infra.runner.limit_threads`, the default) against the pools the fork inherited.
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
        # what a Newton iteration paid: same pattern as the previous factorisation -> phase 22 only
        cands["pypardiso mtype 11, pattern reused"] = lambda A: factorize(A, "pardiso_lu")
        # exact solves now: LDLᵀ of the symmetric part, the cap block's asymmetry corrected (refinement/Woodbury)
        cands["pypardiso mtype -2 + correction (exact)"] = lambda A: factorize(A, "pardiso")
        # what a Newton iteration pays now: the symmetric part alone
        cands["pypardiso mtype -2, symmetric part (Newton)"] = lambda A: factorize(A, "pardiso", exact=False)
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


KERNEL_CASE = dict(pressure=30e3, tensions=(2.0, 0.0, 0.0), gravity=True)  # `fem solve --pressure-kpa 30 --tensions-n 2,0,0`


def bench_kernels(level: str, repeat: int) -> dict:
    """numpy vs numba assembly, interleaved in one process (see the module docstring)."""
    from fem_reference.mesh import build_mesh

    geo, mat = presets.paper_bellows(), presets.paper_material()
    bm = build_mesh(geo, level)
    models = {k: BellowsModel(geo, mat, bm, assembly_kernel=k) for k in ("numpy", "numba")}
    t0 = time.perf_counter()
    models["numba"].asm.assemble(models["numba"].zero_state().U)  # compile, or load numba's cache
    t_jit = time.perf_counter() - t0
    ref = models["numba"].solve(**KERNEL_CASE)
    st, lc = ref.state, ref.loadcase
    print(f"\n== assembly kernels, mesh {level}: {bm.n_elements} Hex2, {models['numba'].n_dofs} reduced DOFs; "
          f"numba kernel ready in {t_jit:.2f} s; {repeat} interleaved repetitions")
    timers = {
        "hyperelastic f + K (HexAssembler)": lambda m: m.asm.assemble(st.U),
        "hyperelastic f only": lambda m: m.asm.assemble(st.U, tangent=False),
        "reduced r + K (evaluate)": lambda m: m.evaluate(st, lc, tangent=True),
    }
    out = dict(level=level, n_elements=bm.n_elements, n_dofs=models["numba"].n_dofs, jit_s=t_jit, rows={})
    print(f"{'':<36} {'numpy/s':>9} {'numba/s':>9} {'ratio':>7}")
    for name, fn in timers.items():
        t = {"numpy": [], "numba": []}
        for _ in range(repeat):
            for k in ("numpy", "numba"):
                t0 = time.perf_counter()
                fn(models[k])
                t[k].append(time.perf_counter() - t0)
        med = {k: statistics.median(v) for k, v in t.items()}
        out["rows"][name] = dict(**{f"{k}_s": v for k, v in med.items()}, ratio=med["numpy"] / med["numba"])
        print(f"{name:<36} {med['numpy']:9.3f} {med['numba']:9.3f} {med['numpy'] / med['numba']:7.1f}")
    f1, K1, _ = models["numpy"].asm.assemble(st.U)
    f2, K2, _ = models["numba"].asm.assemble(st.U)
    out["max_rel_diff_f"] = float(np.abs(f2 - f1).max() / np.abs(f1).max())
    out["max_rel_diff_K"] = float(abs(K2 - K1).max() / abs(K1).max())
    runs = {"numpy": [], "numba": []}
    tips = {}
    for _ in range(max(1, repeat // 2)):
        for k in ("numpy", "numba"):
            res = models[k].solve(**KERNEL_CASE)
            runs[k].append(res.stats)
            tips[k] = res.tip_position
    print(f"full solve ({KERNEL_CASE}), {len(runs['numba'])} interleaved run(s):")
    print(f"{'':<36} {'numpy/s':>9} {'numba/s':>9} {'ratio':>7}")
    for key in ("t_total", "t_assembly", "t_linear"):
        med = {k: statistics.median(getattr(s_, key) for s_ in v) for k, v in runs.items()}
        out["rows"][f"solve {key}"] = dict(**{f"{k}_s": v for k, v in med.items()}, ratio=med["numpy"] / med["numba"])
        print(f"{'solve ' + key:<36} {med['numpy']:9.3f} {med['numba']:9.3f} {med['numpy'] / med['numba']:7.1f}")
    its = {k: [s_.n_iterations for s_ in v] for k, v in runs.items()}
    dtip = float(np.abs(tips["numpy"] - tips["numba"]).max())
    out.update(iterations=its, tip_diff_m=dtip, tip_m=tips["numba"].tolist())
    print(f"Newton iterations {its}; tip {np.round(tips['numba'] * 1e3, 6)} mm; |Δtip| = {dtip:.1e} m; "
          f"max rel. diff f {out['max_rel_diff_f']:.1e}, K {out['max_rel_diff_K']:.1e}")
    return out


SYMMETRY_CASES = {
    "T=3/3/3 N, p=50 kPa": dict(tensions=(3.0, 3.0, 3.0), pressure=50e3),
    "T=2/0/0 N, p=0": dict(tensions=(2.0, 0.0, 0.0)),
    "T=0/2/4 N, p=37.5 kPa": dict(tensions=(0.0, 2.0, 4.0), pressure=37.5e3),
    "p=30 kPa": dict(pressure=30e3),
}


def bench_symmetry(level: str, repeat: int) -> dict:
    """Symmetric-subspace vs full Newton, interleaved in one process (see the module docstring)."""
    geo, mat = presets.paper_bellows(), presets.paper_material()
    model = BellowsModel(geo, mat, level)
    model.solve(tensions=(1.0, 1.0, 1.0), symmetry=False)  # compile / load numba's cache, PARDISO set up
    print(f"\n== symmetric subspace vs full system, mesh {level}: {model.n_dofs} reduced DOFs; "
          f"{repeat} interleaved repetitions (medians)")
    print(f"{'case':<24} {'|H|':>4} {'sym/s':>7} {'full/s':>7} {'ratio':>6} {'lin sym':>8} {'lin full':>8} "
          f"{'it sym':>6} {'it full':>7} {'|Δtip|/m':>9}")
    out = dict(level=level, n_dofs=model.n_dofs, rows={})
    for name, kw in SYMMETRY_CASES.items():
        runs = {True: [], False: []}
        tips = {}
        for _ in range(repeat):
            for flag in (True, False):
                res = model.solve(**kw, symmetry=flag)
                runs[flag].append(res.stats)
                tips[flag] = res.tip_position
        med = {f: statistics.median(s_.t_total for s_ in v) for f, v in runs.items()}
        lin = {f: statistics.median(s_.t_linear for s_ in v) for f, v in runs.items()}
        its = {f: runs[f][-1].n_iterations for f in runs}
        order = runs[True][-1].symmetry_order
        dtip = float(np.abs(tips[True] - tips[False]).max())
        out["rows"][name] = dict(order=order, sym_s=med[True], full_s=med[False], ratio=med[False] / med[True],
                                 linear_sym_s=lin[True], linear_full_s=lin[False], iterations_sym=its[True],
                                 iterations_full=its[False], tip_diff_m=dtip)
        print(f"{name:<24} {order:4d} {med[True]:7.2f} {med[False]:7.2f} {med[False] / med[True]:6.2f} "
              f"{lin[True]:8.2f} {lin[False]:8.2f} {its[True]:6d} {its[False]:7d} {dtip:9.1e}")
    return out


#: cold bends of the default design (docs/fem.md §8): single-tendon, two-tendon and combined
BEND_CASES = {
    "T=2/0/0": dict(tensions=(2.0, 0.0, 0.0)),
    "T=4/0/0,50kPa": dict(tensions=(4.0, 0.0, 0.0), pressure=50e3),
    "T=0/2/4,37.5kPa": dict(tensions=(0.0, 2.0, 4.0), pressure=37.5e3),
    "T=1/2.5/0,12.5kPa": dict(tensions=(1.0, 2.5, 0.0), pressure=12.5e3),
}


def _interleaved(name_b: str, rows: dict, run, repeat: int) -> dict:
    """``run(case_kw, flag) -> (seconds, factorisations, tip)`` for flag True (the new way) and False, alternated
    ``repeat`` times per case; prints and returns medians, the ratio and the tip difference."""
    print(f"{'case':<20} {'new/s':>7} {name_b + '/s':>9} {'ratio':>6} {'facs new':>8} {'facs ' + name_b:>10} "
          f"{'|Δtip|/m':>9}")
    out = {}
    for name, kw in rows.items():
        got = {True: [], False: []}
        for _ in range(repeat):
            for flag in (True, False):
                got[flag].append(run(kw, flag))
        med = {f: statistics.median(g[0] for g in got[f]) for f in got}
        facs = {f: got[f][-1][1] for f in got}
        dtip = float(np.abs(got[True][-1][2] - got[False][-1][2]).max())
        out[name] = dict(new_s=med[True], old_s=med[False], ratio=med[False] / med[True], factorisations_new=facs[True],
                         factorisations_old=facs[False], tip_diff_m=dtip)
        print(f"{name:<20} {med[True]:7.2f} {med[False]:9.2f} {med[False] / med[True]:6.2f} {facs[True]:8d} "
              f"{facs[False]:10d} {dtip:9.1e}")
    return out


def bench_rings(level: str, repeat: int) -> dict:
    """Ring rotations in the Newton update on / off (see the module docstring)."""
    import fem_reference.model as fm
    model = BellowsModel(presets.paper_bellows(), presets.paper_material(), level)
    model.solve(tensions=(1.0, 1.0, 1.0))  # compile / load numba's cache, PARDISO set up
    print(f"\n== ring rotations on / off, mesh {level}: {model.n_dofs} reduced DOFs; {repeat} interleaved repetitions")

    def run(kw, flag):
        old, fm.RING_UPDATE = fm.RING_UPDATE, flag
        try:
            res = model.solve(**kw)
        finally:
            fm.RING_UPDATE = old
        return res.stats.t_total, res.stats.n_factorizations, res.tip_position

    return dict(level=level, rows=_interleaved("off", BEND_CASES, run, repeat))


def bench_transfer(level: str, repeat: int) -> dict:
    """Refined solves from the coarse equilibrium or from rest (see the module docstring)."""
    from dataclasses import replace

    from fem_reference.mesh import MESH_LEVELS
    from fem_reference.transfer import snapshot, start_from
    geo, mat = presets.paper_bellows(), presets.paper_material()
    lvl = MESH_LEVELS[level]
    fine_level = replace(lvl, n_per_conv=2 * lvl.n_per_conv, n_collar=2 * lvl.n_collar)
    coarse, fine = BellowsModel(geo, mat, level), BellowsModel(geo, mat, fine_level)
    fine.solve(tensions=(1.0, 1.0, 1.0))
    cases = {k: BEND_CASES[k] for k in ("T=0/2/4,37.5kPa",)} | {"T=5/5/0,100kPa": dict(tensions=(5.0, 5.0, 0.0),
                                                                                        pressure=100e3)}
    snaps = {k: snapshot(coarse.solve(**kw)) for k, kw in cases.items()}
    print(f"\n== refined solves ({fine.n_dofs} reduced DOFs) from the {level} equilibrium / from rest; {repeat} "
          "interleaved repetitions (the start's interpolation and relaxation included)")

    def run(kw, flag):
        t0 = time.perf_counter()
        snap = next(snaps[k] for k, v in cases.items() if v is kw)
        res = fine.solve(**kw, initial=start_from(snap, fine), max_cuts=0) if flag else fine.solve(**kw)
        return time.perf_counter() - t0, res.stats.n_factorizations, res.tip_position

    return dict(level=level, fine_level=vars(fine_level), rows=_interleaved("rest", cases, run, repeat))


_WORKER_MODELS: dict = {}


def _worker_solve(task: dict) -> tuple:
    """Pool task of ``--worker-threads``: one cold solve on the coarse model of this process → (seconds, tip)."""
    level = task["level"]
    if level not in _WORKER_MODELS:
        _WORKER_MODELS[level] = BellowsModel(presets.paper_bellows(), presets.paper_material(), level)
    t0 = time.perf_counter()
    res = _WORKER_MODELS[level].solve(**task["kw"])
    return time.perf_counter() - t0, res.tip_position


def bench_worker_threads(level: str, repeat: int) -> dict:
    """Two bends in two forked workers, thread pools limited or inherited (see the module docstring)."""
    import validation.infra.runner as vr
    from threadpoolctl import threadpool_info, threadpool_limits
    pair = [BEND_CASES["T=2/0/0"], BEND_CASES["T=1/2.5/0,12.5kPa"]]
    model = BellowsModel(presets.paper_bellows(), presets.paper_material(), level)
    with threadpool_limits(2):
        model.solve(tensions=(1.0, 1.0, 1.0))   # PARDISO started in this process, as the sweep's rod estimate does
        pools = {i["internal_api"]: i["num_threads"] for i in threadpool_info()}
        print(f"\n== two forked workers solving {len(pair)} bends at once, mesh {level}; parent's pools {pools}; "
              f"{repeat} interleaved repetitions (wall time of the pair, the workers' model builds included)")

        def run(kw, flag):
            old = vr.limit_threads
            if not flag:
                vr.limit_threads = lambda: None          # the pools the fork inherited
            try:
                t0 = time.perf_counter()
                out = vr.run_tasks(_worker_solve, [{"level": level, "kw": k} for k in pair], workers=2,
                                   progress=False)
                return time.perf_counter() - t0, 0, np.concatenate([r[1] for r in out.results])
            finally:
                vr.limit_threads = old

        return dict(level=level, parent_pools=pools,
                    rows=_interleaved("inherit", {"T=2/0/0 + T=1/2.5/0": {}}, run, repeat))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--levels", nargs="+", default=["coarse"], choices=["coarse", "medium", "reference"])
    ap.add_argument("--cases", nargs="+", default=list(CASES), choices=list(CASES))
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--json", type=Path, default=None)
    ap.add_argument("--all-solvers", action="store_true", help="also SuperLU partial pivoting on big meshes")
    ap.add_argument("--compare-kernels", action="store_true",
                    help="only the numpy-vs-numba assembly comparison (interleaved), on each level")
    ap.add_argument("--symmetry", action="store_true",
                    help="only symmetric-subspace vs full Newton solves (interleaved), on each level")
    ap.add_argument("--rings", action="store_true", help="only ring rotations on/off on cold bends (interleaved)")
    ap.add_argument("--transfer", action="store_true",
                    help="only refined solves from the coarse equilibrium vs from rest (interleaved)")
    ap.add_argument("--worker-threads", action="store_true",
                    help="only two forked FEM workers with thread pools limited vs inherited (interleaved)")
    a = ap.parse_args(argv)
    report = dict(python=sys.version.split()[0], machine=platform.machine(), levels=[])
    for flag, fn in (("rings", bench_rings), ("transfer", bench_transfer), ("worker_threads", bench_worker_threads)):
        if getattr(a, flag):
            report[flag] = [fn(level, a.repeat) for level in a.levels]
            if a.json:
                a.json.write_text(json.dumps(report, indent=2))
            return report
    if a.symmetry:
        report["symmetry"] = [bench_symmetry(level, a.repeat) for level in a.levels]
        if a.json:
            a.json.write_text(json.dumps(report, indent=2))
        return report
    if a.compare_kernels:
        report["kernels"] = [bench_kernels(level, a.repeat) for level in a.levels]
        if a.json:
            a.json.write_text(json.dumps(report, indent=2))
        return report
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
