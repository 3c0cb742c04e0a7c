"""Speed of the reduced model: cold/warm FK and IK at n = 6 and n = 12, beside a compiled peer.

Run:  python benchmarks/bench_ancf.py [--repeats 200]

The peer (Exudyn's ANCF cable, ``benchmarks/peer_exudyn.py``) solves the same clamped cantilever under a
tip load (constant EA, EI, no gravity, no tendon tension).  Both are timed in the same run, interleaved,
so machine noise affects them alike; medians and their ratio are printed.  "Cold" means a solve from the
straight reference with no initial guess; "warm" restarts from a neighbouring solution.

Reference point: the paper's MATLAB IK takes 2.95 s at n = 6.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
import pathlib

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).parent))

from ancf import Model, StiffnessLaw, presets  # noqa: E402

L, EA, EI = 0.16, 767.2, 0.0839
F_TIP = (0.0, 0.0, -0.49)


def timed(fn, *a, **k):
    t = time.perf_counter()
    out = fn(*a, **k)
    return out, time.perf_counter() - t


def main(repeats: int = 200) -> dict:
    try:
        import peer_exudyn
        have_peer = peer_exudyn.available()
    except ImportError:
        have_peer = False
    rows = {}
    for n in (6, 12):
        cantilever = Model(presets.paper().replace(
            n_elements=n, stiffness=StiffnessLaw.constant(EA=EA, EI=EI), line_mass=0.0, tip_mass=0.0,
            tool_offset=0.0))
        paper = Model(presets.paper().replace(n_elements=n))
        cantilever.fk((0, 0, 0), 0.0, F_TIP)            # compile / load kernels
        ref = paper.fk((2.0, 0.5, 1.0), 30e3, (0, 0, -0.2))   # interior tensions: targets nearby stay feasible
        target = ref.tip
        t = {k: [] for k in ("fk_cold", "fk_warm", "ik_cold", "ik_warm", "fk_paper_cold", "peer_solve",
                             "peer_total")}
        rng = np.random.default_rng(0)
        for _ in range(repeats):
            e, s = timed(cantilever.fk, (0, 0, 0), 0.0, F_TIP)
            t["fk_cold"].append(s)
            _, s = timed(cantilever.fk, (0, 0, 0), 0.0, (0.0, 0.0, -0.5), q0=e.q)
            t["fk_warm"].append(s)
            _, s = timed(paper.fk, (2.0, 0.5, 1.0), 30e3, (0, 0, -0.2))
            t["fk_paper_cold"].append(s)
            _, s = timed(paper.ik, target, 30e3, (0, 0, -0.2), q0=paper.q_ref)
            t["ik_cold"].append(s)
            dp = rng.normal(size=3) * 2e-5      # late LACC corrections are this small
            _, s = timed(paper.ik, target + dp, 30e3, (0, 0, -0.2), q0=ref.q, tensions0=ref.tensions)
            t["ik_warm"].append(s)
            if have_peer:
                r = peer_exudyn.solve_cantilever(n, L, EA, EI, F_TIP)
                t["peer_solve"].append(r["solve_s"])
                t["peer_total"].append(r["build_s"] + r["solve_s"])
        med = {k: statistics.median(v) * 1e3 for k, v in t.items() if v}
        rows[n] = med
        print(f"\nn = {n}  (median of {repeats}, milliseconds)")
        print(f"  ours  FK cold, cantilever tip load      {med['fk_cold']:8.3f}")
        print(f"  ours  FK warm, cantilever               {med['fk_warm']:8.3f}")
        print(f"  ours  FK cold, paper preset, T+p+F      {med['fk_paper_cold']:8.3f}")
        print(f"  ours  IK cold (from straight), paper    {med['ik_cold']:8.3f}")
        print(f"  ours  IK warm, paper                    {med['ik_warm']:8.3f}")
        if have_peer:
            print(f"  peer  Exudyn SolveStatic only           {med['peer_solve']:8.3f}")
            print(f"  peer  Exudyn build + solve              {med['peer_total']:8.3f}")
            print(f"  ratio ours FK cold / peer solve         {med['fk_cold'] / med['peer_solve']:8.2f}")
            print(f"  ratio ours IK cold / peer solve         {med['ik_cold'] / med['peer_solve']:8.2f}")
        else:
            print("  (peer not installed: pip install -e .[bench])")
        print(f"  paper's MATLAB IK at n = 6: 2950 ms -> ours warm IK is {2950 / med['ik_warm']:.0f}x faster")
    return rows


def verification_cost(repeats: int = 200) -> dict:
    """Cost of the result verification every solve now does (stretch inside the law's validity range,
    Cholesky of the reduced Hessian / of its projection on the locked tendons' tangent space): the same
    calls with ``Model._verify`` bypassed ("without") and as shipped ("with"), interleaved; medians [ms]."""
    m = Model(presets.paper())
    ref = m.fk((2.0, 0.5, 1.0), 30e3, (0, 0, -0.2))
    calls = {
        "FK cold, paper": lambda: m.fk((2.0, 0.5, 1.0), 30e3, (0, 0, -0.2)),
        "FK warm, paper": lambda: m.fk((2.05, 0.5, 1.0), 30e3, (0, 0, -0.2), q0=ref.q),
        "IK warm, paper": lambda: m.ik(ref.tip + 2e-5, 30e3, (0, 0, -0.2), q0=ref.q, tensions0=ref.tensions),
        "locked FK warm, paper": lambda: m.fk_locked(ref.tendon_lengths, 30e3, (0, 0, -0.5), q0=ref.q,
                                                     tensions0=ref.tensions),
    }
    shipped = Model._verify
    t = {k: {"with": [], "without": []} for k in calls}
    for _ in range(repeats):
        for name, fn in calls.items():
            for mode in ("without", "with"):
                Model._verify = (lambda self, q, H, JA, solver, cs, **kw: (H, True)) if mode == "without" else shipped
                _, s = timed(fn)
                t[name][mode].append(s)
    Model._verify = shipped
    print(f"\nresult verification (median of {repeats}, milliseconds)")
    print(f"  {'call':28s} {'without':>9s} {'with':>9s} {'ratio':>7s}")
    out = {}
    for name, d in t.items():
        a, b = statistics.median(d["without"]) * 1e3, statistics.median(d["with"]) * 1e3
        out[name] = (a, b)
        print(f"  {name:28s} {a:9.3f} {b:9.3f} {b / a:7.3f}")
    return out


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeats", type=int, default=200)
    ap.add_argument("--verification-only", action="store_true", help="only the verification cost table")
    args = ap.parse_args()
    if not args.verification_only:
        main(args.repeats)
    verification_cost(args.repeats)
