"""Throughput of the workspace study (paper Sec. IV-A): FK solves per second for the Monte Carlo clouds.

Run:  python benchmarks/bench_workspace.py [--samples 1000] [--workers 2]

Cases (same seed, same samples, TD + TPHD): serial in this process with cold starts (the default per
sample), serial with warm starts along a Morton order inside chunks, and a process pool with ``--workers``
processes (warm).  Prints wall time, FK/s, mean per-sample CPU time and the speed-ups, and checks that the
warm-started tips equal the cold ones to 1e-8 m and that the pool gives the serial warm run's clouds (to
round-off: the workers run one BLAS thread).  Parallel speed-up needs idle cores: on a shared machine the pool's timings are noise.  Reference point: the paper solves 2 × 10 000 FK problems (MATLAB,
no timing given); its IK takes 2.95 s at n = 6.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from ancf import Model, presets
from validation import paper


def main(samples: int = 1000, workers: int | None = None, preset: str = "paper") -> dict:
    workers = workers or os.cpu_count() or 1
    Model(presets.get(preset)).fk((1.0, 0.0, 0.0), 10e3)           # load the numba kernels once
    rows = {}
    ref = None
    for name, kw in (("serial cold", dict(workers=1, warm_start=False)),
                     ("serial warm (Morton)", dict(workers=1, warm_start=True)),
                     (f"{workers} processes, warm", dict(workers=workers, warm_start=True))):
        t = time.perf_counter()
        res = paper.workspace(samples=samples, seed=0, progress=False, figure=False, params=preset, **kw)
        wall = time.perf_counter() - t
        tips = np.vstack([res["clouds"][m]["tips"] for m in paper.MODES])
        if ref is None:
            ref = tips
        if name.startswith("serial warm"):
            ref_warm = tips
        same = (bool(np.allclose(tips, ref_warm, rtol=0, atol=1e-12, equal_nan=True)) if "processes" in name
                else bool(np.allclose(tips, ref, atol=1e-8, equal_nan=True)))
        it = np.mean([res["modes"][m]["mean_fk_iterations"] for m in paper.MODES])
        rows[name] = {"wall_s": wall, "fk_per_s": 2 * samples / wall,
                      "cpu_ms_per_fk": res["timing"]["per_sample_cpu_ms"], "mean_iterations": it,
                      "same_cloud": same, "failures": res["failures"], "collapsed": res["collapsed"],
                      "increase_percent": res["increase_percent"]}
    base = rows["serial cold"]["wall_s"]
    print(f"workspace benchmark ({preset}): {samples} samples per mode (2 × {samples} FK), n = 6, "
          f"{os.cpu_count()} cores")
    print(f"{'case':<24}{'wall [s]':>10}{'FK/s':>10}{'ms/FK':>9}{'its':>7}{'speed-up':>10}  same cloud")
    for name, r in rows.items():
        print(f"{name:<24}{r['wall_s']:>10.2f}{r['fk_per_s']:>10.0f}{r['cpu_ms_per_fk']:>9.2f}"
              f"{r['mean_iterations']:>7.2f}{base / r['wall_s']:>10.2f}  {r['same_cloud']}")
    est = 2 * 10_000 / rows[f"{workers} processes, warm"]["fk_per_s"]
    print(f"estimated wall time of the paper's 2 × 10 000 samples with {workers} processes: {est:.0f} s")
    return rows


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=1000)
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument("--preset", default="paper")
    a = ap.parse_args()
    main(a.samples, a.workers, a.preset)
