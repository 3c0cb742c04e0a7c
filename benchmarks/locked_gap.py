"""The locked-compliance gap on a straight tube, decomposed (docs/identification.md, "The locked-compliance gap").

Solves straight states of the FEM of a design (pressure only and equal tensions at 0, 50 and 100 % of the
design's pressure limit; coarse mesh, warm-started in order, ≈ 20–30 s each on 2 cores) and prints, per
state, the FEM's locked/held vertical stiffness ratio, the same computed from the cap compliance with
straight-line tendons (the reduced model's tendon), the deviation of the guided tendon's length gradient
from the straight line's, EI from a pure moment and from a tip force, the rotation-free share of the lateral
compliance, the FEM's ratio without it, the ratio of the reduced model matched to the FEM's held compliance
and its locked-compliance error, and the same for a rod with a series rotation-free compliance
(validation/checks/locked_gap.py).

Usage::

    python benchmarks/locked_gap.py                            # the `paper` design, table in Markdown
    python benchmarks/locked_gap.py --cache /tmp/locked15      # keep (and reuse) each FEM state as .npz
    python benchmarks/locked_gap.py --design my_bellows.toml --mesh coarse --json gap.json
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from ancf.export import to_jsonable  # noqa: E402
from validation.checks.locked_gap import format_table, measure  # noqa: E402


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--design", default="paper", help="design preset or TOML file (validation/reference/designs.py)")
    ap.add_argument("--mesh", default="coarse", help="FEM mesh level")
    ap.add_argument("--cache", default=None, help="directory for one .npz per FEM state (reused when present)")
    ap.add_argument("--json", default=None, help="also write every number to this JSON file")
    a = ap.parse_args(argv)
    t0 = time.perf_counter()
    printed = []

    def log(line):
        print(line if not printed else line.split("\n")[-1], flush=True)
        printed.append(line)

    rows = measure(a.design, a.mesh, cache=a.cache, log=log)
    print(f"({len(rows)} states, {time.perf_counter() - t0:.0f} s)")
    if a.json:
        Path(a.json).write_text(json.dumps(to_jsonable(rows), indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
