"""Speed of the reduced model: cold/warm FK and IK at n = 6 and n = 12, beside a compiled peer.

Run:  python benchmarks/bench_ancf.py [--repeats 200]

The peer (Exudyn's ANCF cable, ``benchmarks/peer_exudyn.py``) solves the same clamped cantilever under a
tip load (constant EA, EI, no gravity, no tendon tension).  Both are timed in the same run, interleaved,
so machine noise affects them alike; medians and their ratio are printed.  "Cold" means a solve from the
straight reference with no initial guess; "warm" restarts from a neighbouring solution.

"IK warm, slack tendon" is the IK a control loop runs on a state with one slack tendon (T = (2, 0.5, 0) N at
30 kPa): targets a few µm apart on that tendon's slack manifold (the tips at T = (2 + δ₁, 0.5 + δ₂, 0) N,
δ ~ 0.2 mN), each solve warm-started from the state the previous one returned (q0, tensions0), as LACC's step
does; its ratio to the peer's static solve is printed beside the others.  The IK keeps its evaluations where
its latest solves started and ended (``Model.IK_KEPT_EVALUATIONS``): the warm rows, whose solves start where an
earlier one started or ended, reuse them; the cold row's start is cleared before each of its solves.

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


def slack_case(model: Model, count: int = 20):
    """(the state with tendon 3 slack: T = (2, 0.5, 0) N at 30 kPa; ``count`` IK targets a few µm from its tip on
    the slack manifold: the tips at T = (2 + δ₁, 0.5 + δ₂, 0) N, δ ~ N(0, 0.2 mN))."""
    state = model.fk((2.0, 0.5, 0.0), 30e3)
    rng = np.random.default_rng(1)
    deltas = rng.normal(size=(count, 2)) * 2e-4
    targets = [model.fk((2.0 + a, 0.5 + b, 0.0), 30e3, q0=state.q).tip for a, b in deltas]
    return state, targets


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
        prev, slack_targets = slack_case(paper)
        t = {k: [] for k in ("fk_cold", "fk_warm", "ik_cold", "ik_warm", "ik_slack", "fk_paper_cold", "peer_solve",
                             "peer_total")}
        rng = np.random.default_rng(0)
        for _ in range(repeats):
            e, s = timed(cantilever.fk, (0, 0, 0), 0.0, F_TIP)
            t["fk_cold"].append(s)
            _, s = timed(cantilever.fk, (0, 0, 0), 0.0, (0.0, 0.0, -0.5), q0=e.q)
            t["fk_warm"].append(s)
            _, s = timed(paper.fk, (2.0, 0.5, 1.0), 30e3, (0, 0, -0.2))
            t["fk_paper_cold"].append(s)
            paper._ik_evaluations.clear()           # cold: nothing kept from an earlier solve
            _, s = timed(paper.ik, target, 30e3, (0, 0, -0.2), q0=paper.q_ref)
            t["ik_cold"].append(s)
            dp = rng.normal(size=3) * 2e-5      # late LACC corrections are this small
            _, s = timed(paper.ik, target + dp, 30e3, (0, 0, -0.2), q0=ref.q, tensions0=ref.tensions)
            t["ik_warm"].append(s)
            prev, s = timed(paper.ik, slack_targets[len(t["ik_slack"]) % len(slack_targets)], 30e3, q0=prev.q,
                            tensions0=prev.tensions)
            t["ik_slack"].append(s)
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
        print(f"  ours  IK warm, slack tendon, paper      {med['ik_slack']:8.3f}")
        if have_peer:
            print(f"  peer  Exudyn SolveStatic only           {med['peer_solve']:8.3f}")
            print(f"  peer  Exudyn build + solve              {med['peer_total']:8.3f}")
            print(f"  ratio ours FK cold / peer solve         {med['fk_cold'] / med['peer_solve']:8.2f}")
            print(f"  ratio ours IK cold / peer solve         {med['ik_cold'] / med['peer_solve']:8.2f}")
            print(f"  ratio ours IK warm / peer solve         {med['ik_warm'] / med['peer_solve']:8.2f}")
            print(f"  ratio ours IK slack / peer solve        {med['ik_slack'] / med['peer_solve']:8.2f}")
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


def friction_cost(repeats: int = 50) -> dict:
    """What tendon friction costs per FK and IK (docs/friction.md): a warm frictionless FK (``Model.fk``) beside one
    step of the friction history (``Model.fk_history``, μ = 0.3, from the previous step's state), the same small
    tension increment at n = 6, and a warm frictionless IK beside the IK with friction
    (``controller.friction_aware.friction_ik``, with the number of locked friction solves it makes), interleaved;
    medians [ms]."""
    free = Model(presets.paper())
    fric = Model(presets.paper().replace(tendon_friction=0.3))
    ref = free.fk((2.0, 0.5, 0.0), 30e3)
    prev = fric.fk_history((2.0, 0.5, 0.0), 30e3)
    fric.fk_history((2.05, 0.5, 0.0), 30e3, state=prev)                 # compile / load kernels
    from controller.friction_aware import friction_ik
    target, load = free.fk((2.05, 0.52, 0.0), 30e3).tip, np.zeros(3)     # reachable, ≈ 0.5 mm from the state
    solves = friction_ik(fric, free, prev, target, 30e3, load)[3]
    t = {"FK warm, frictionless": [], "FK history step, mu = 0.3": [], "IK warm, frictionless": [],
         "IK with friction, mu = 0.3": []}
    for _ in range(repeats):
        t["FK warm, frictionless"].append(timed(free.fk, (2.05, 0.5, 0.0), 30e3, q0=ref.q)[1])
        t["FK history step, mu = 0.3"].append(timed(fric.fk_history, (2.05, 0.5, 0.0), 30e3, state=prev)[1])
        t["IK warm, frictionless"].append(timed(free.ik, target, 30e3, load, q0=ref.q, tensions0=ref.tensions)[1])
        t["IK with friction, mu = 0.3"].append(timed(friction_ik, fric, free, prev, target, 30e3, load)[1])
    med = {k: statistics.median(v) * 1e3 for k, v in t.items()}
    print(f"\nwhat friction costs per FK and IK (median of {repeats}, milliseconds, n = 6; the IK with friction is "
          f"controller.friction_aware.friction_ik, a LACC-sized correction from a friction state: Newton steps with "
          f"the exact Jacobian of the locked friction step, {solves} locked friction solves)")
    for k, v in med.items():
        print(f"  {k:28s} {v:9.3f}")
    print(f"  ratio FK {med['FK history step, mu = 0.3'] / med['FK warm, frictionless']:.1f}x, "
          f"IK {med['IK with friction, mu = 0.3'] / med['IK warm, frictionless']:.1f}x")
    return med


def chain_cost(repeats: int = 50) -> dict:
    """FK of a chain per segment count K = 1, 2, 3 (ancf.chain_model.ChainModel; docs/multisegment.md): each segment
    the ``two_segment`` preset's (the paper bellows at half length, n = 3, three tendons, turned 120°/K from the
    previous segment's), 10 g / 10 mm caps; 2 N on the distal segment's first tendon, 30 kPa in every chamber.
    Cold: from the straight chain; warm: from the solution at 1.95 N.  The one-segment row has ancf.Model's FK
    beside it (the same numbers; the chain's Newton loop runs in Python, Model's compiled).

    IK (ancf.chain_ik, least tension and stiffest along z) of the tip that the tensions T_j = 0.2 + 0.3 j N
    (j = 0 … 3K − 1, every tendon taut) reach at those pressures, from the default start; with ``Model.ik``'s
    cold IK beside the one-segment row."""
    import math

    from ancf import Cap, ChainModel, ChainParams, Tendon
    seg = presets.two_segment().segments[1]
    rows, ik_rows = {}, {}
    for K in (1, 2, 3):
        segs = tuple(seg.replace(name=f"s{k + 1}", tip_mass=seg.tip_mass if k == K - 1 else 0.0,
                                 tool_offset=seg.tool_offset if k == K - 1 else 0.0,
                                 tendons=tuple(Tendon(distance=t.distance, angle=t.angle + math.radians(120 * k / K))
                                               for t in presets.two_segment().segments[0].tendons))
                     for k in range(K))
        model = ChainModel(ChainParams(segments=segs, caps=(Cap(mass=0.01, length=0.01),) * (K - 1)))
        T = np.zeros(3 * K)
        T[-3] = 2.0
        pr = np.full(K, 30e3)
        T0 = T.copy()
        T0[-3] = 1.95
        z0 = model.fk(T0, pr).z
        cold = [timed(model.fk, T, pr)[1] for _ in range(repeats)]
        warm = [timed(model.fk, T, pr, z0=z0)[1] for _ in range(repeats)]
        rows[K] = (statistics.median(cold) * 1e3, statistics.median(warm) * 1e3)
        ik_rows[K] = _chain_ik_times(model, pr, max(3, repeats // 10))
        if K == 1:
            single = Model(segs[0])                  # the one-segment chain's own actuator
    q0 = single.fk((1.95, 0, 0), 30e3).q
    ref = (statistics.median([timed(single.fk, (2.0, 0, 0), 30e3)[1] for _ in range(repeats)]) * 1e3,
           statistics.median([timed(single.fk, (2.0, 0, 0), 30e3, q0=q0)[1] for _ in range(repeats)]) * 1e3)
    print(f"\nFK of a chain per segment count (median of {repeats}, milliseconds; segments of 80 mm, n = 3)")
    print(f"  {'segments':10s} {'cold':>9s} {'warm':>9s}")
    for K, (c, w) in rows.items():
        print(f"  {K:<10d} {c:9.3f} {w:9.3f}")
    print(f"  {'Model (1)':10s} {ref[0]:9.3f} {ref[1]:9.3f}")
    tip1 = single.fk(0.2 + 0.3 * np.arange(3), 30e3).tip
    ik_ref = statistics.median([timed(single.ik, tip1, 30e3)[1] for _ in range(max(3, repeats // 10))]) * 1e3
    print(f"\nIK of a chain per segment count (median of {max(3, repeats // 10)}, milliseconds; tip of "
          "T_j = 0.2 + 0.3 j N, 30 kPa)")
    print(f"  {'segments':10s} {'least Σ T²':>12s} {'stiff in z':>12s} {'FK solves':>16s}")
    for K, (lt, cz, n_lt, n_cz) in ik_rows.items():
        print(f"  {K:<10d} {lt:12.1f} {cz:12.1f} {n_lt:>8d} {n_cz:>7d}")
    print(f"  {'Model (1)':10s} {ik_ref:12.1f}")
    return {"chain": rows, "model": ref, "chain_ik": ik_rows, "model_ik": ik_ref}


def _chain_ik_times(model, pr, repeats: int) -> tuple:
    """(median IK time [ms] least tension, stiff along z; FK solves of each) of a chain (see chain_cost)."""
    tip = model.fk(0.2 + 0.3 * np.arange(model.m), pr).tip
    out = []
    for kw in ({}, {"objective": "compliance", "compliance_direction": (0.0, 0.0, 1.0)}):
        runs = [timed(model.ik, tip, pr, **kw) for _ in range(repeats)]
        out.append((statistics.median(t for _, t in runs) * 1e3, runs[0][0].iterations))
    return out[0][0], out[1][0], out[0][1], out[1][1]


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeats", type=int, default=200)
    ap.add_argument("--verification-only", action="store_true", help="only the verification cost table")
    ap.add_argument("--friction-only", action="store_true", help="only the friction cost table")
    ap.add_argument("--chain-only", action="store_true", help="only the FK and IK per segment count tables")
    args = ap.parse_args()
    if args.chain_only:
        chain_cost(min(args.repeats, 50))
        sys.exit(0)
    if args.friction_only:
        friction_cost(args.repeats)
        sys.exit(0)
    if not args.verification_only:
        main(args.repeats)
    verification_cost(args.repeats)
