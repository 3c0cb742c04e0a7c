"""Workspace of the tendon-driven (TD) and tendon-pneumatic hybrid-driven (TPHD) modes (paper Sec. IV-A).

Monte Carlo FK over T ∈ [0, 5]³ N at p = 0 (TD) and with p ∈ [0, 120] kPa (TPHD), convex-hull volumes of
the two tip clouds and their ratio (paper: TPHD +108.6 % vs TD), on all cores, with a progress bar.

Run:  python examples/workspace_td_vs_tphd.py [samples]      (the paper uses 10 000 per mode)
Same as:  bellows paper workspace --samples 10000

Import-safe: ``main(samples=..., out=...)`` returns the result dict (tests run it on a few samples).
"""

from __future__ import annotations

import pathlib
import sys

from validation import paper


def main(samples: int = 2000, out="bellows_out/examples/workspace", workers=None, progress: bool = True) -> dict:
    res = paper.workspace(samples=samples, seed=0, workers=workers, out=pathlib.Path(out), progress=progress,
                          force=True)
    paper.print_workspace(res)
    td, tphd = res["modes"]["TD"], res["modes"]["TPHD"]
    print(f"TD   : {td['volume_cm3']:8.2f} cm³ from {td['solved']} tips ({td['failures']} failed)")
    print(f"TPHD : {tphd['volume_cm3']:8.2f} cm³ from {tphd['solved']} tips ({tphd['failures']} failed)")
    print(f"TPHD vs TD: {res['increase_percent']:+.1f} % (paper {paper.PAPER['workspace']['increase_percent']:+.1f} %)"
          f"; figures and clouds in {out}/")
    return res


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 2000)
