"""Stiffness vs the top-tendon tension with the motors locked vs at constant tension (paper Sec. V-C,
Fig. 9): a 50 g payload at 0, 25, 50 kPa, from the nonlinear solvers and from the compliance matrices.

Run:  python examples/workspace_locked_stiffness.py
Same as:  bellows paper stiffness

Import-safe: ``main(pressures=..., tensions=..., out=...)`` returns the result dict.
"""

from __future__ import annotations

import pathlib

from validation import paper


def main(pressures=(0.0, 25e3, 50e3), tensions=(0, 1, 2, 3, 4, 5), out="bellows_out/examples/stiffness") -> dict:
    res = paper.stiffness_vs_tension(pressures=pressures, tensions=tensions, out=pathlib.Path(out),
                                     force=True)
    paper.print_stiffness(res)
    return res


if __name__ == "__main__":
    main()
