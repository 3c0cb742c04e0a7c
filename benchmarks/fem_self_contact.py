"""Flank contact on the medium mesh of the `paper` design (docs/fem.md §5a, "Flank contact in the FEM, measured").

Tendons 1 and 2 at equal tension, no pressure, warm-started 2.5 → 3.5 → 4.0 → 4.5 → 5.0 N (``n_steps=6``,
``max_steps=120``) on ``BellowsModel(..., mesh="medium", contact=True)`` (default k_c), the 4.5 N state also without
contact (from the same 4.0 N state: every gap is open up to there, so both models agree bit for bit), then the
last state again with k_c × 10, × 100 and ÷ 10.  Prints per state: the tip [mm], the smallest flank gap
(:func:`fem_reference.contact.flank_gaps`) [mm] and over the unloaded one, the pairs in contact (grooves, level,
meridians), the contact's total normal force [N] per groove, its largest pressure [kPa] and the tip's change
against the contact-free solve or the default k_c.  ≈ 15 min on 2 shared cores.

Usage::

    python benchmarks/fem_self_contact.py
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def describe(model, res, g0) -> dict:
    """Tip [mm], smallest flank gap [mm] and g/g₀, and the contact's pairs and forces at ``res``."""
    from fem_reference.contact import flank_gaps

    bm, pr = model.bmesh, model.contact_pairs
    g = flank_gaps(bm, bm.X + res.state.U, "outer")
    out = {"tip_mm": res.tip_position * 1e3, "min_gap_mm": g.minimum * 1e3,
           "min_rel": float(np.nanmin(g.gaps / g0.gaps)), "N_per_groove": {}}
    ct = model.contact_forces(res.state)
    if ct is not None and ct.active.size:
        a, N = ct.active, ct.normal_force
        out["N_per_groove"] = {int(k) + 1: float(N[pr.groove[a] == k].sum()) for k in np.unique(pr.groove[a])}
        out["levels"] = sorted(set(pr.level[a].tolist()))
        out["theta_deg"] = (pr.angle[a].min() * 180 / bm.shape[2], pr.angle[a].max() * 180 / bm.shape[2])
        out["p_max_kPa"] = float(model.contact_stiffness * (-ct.gaps[a]).max() / 1e3)
    return out


def _print(name, d, ref=None) -> None:
    N = d["N_per_groove"]
    extra = "" if ref is None else f", tip moved {np.linalg.norm(d['tip_mm'] - ref):.2f} mm"
    print(f"{name}: tip {np.round(d['tip_mm'], 2)} mm, smallest gap {d['min_gap_mm']:+.3f} mm "
          f"(g/g0 {d['min_rel']:+.3f}){extra}")
    if N:
        print(f"    contact: level(s) {d['levels']}, θ {d['theta_deg'][0]:.0f}…{d['theta_deg'][1]:.0f}°, "
              f"total normal force {sum(N.values()):.2f} N, per groove "
              + ", ".join(f"{k}: {v:.2f}" for k, v in N.items()) + f" N, largest pressure {d['p_max_kPa']:.0f} kPa")


def main() -> int:
    from fem_reference import BellowsModel
    from fem_reference.contact import flank_gaps
    from fem_reference.loads.contact import default_stiffness
    from validation.reference.designs import load_design

    geo, mat = load_design("paper")
    t0 = time.perf_counter()
    with_c = BellowsModel(geo, mat, mesh="medium", contact=True)
    free = BellowsModel(geo, mat, mesh=with_c.bmesh)
    g0 = flank_gaps(with_c.bmesh, with_c.bmesh.X, "outer")
    print(f"k_c = {with_c.contact_stiffness:.3e} N/m^3 (default), {with_c.contact_pairs.n_pairs} pairs")
    prev, prev_free, res = None, None, {}
    for T in (2.5, 3.5, 4.0, 4.5, 5.0):
        loads = dict(tensions=[T, T, 0.0], n_steps=6, max_steps=120)
        prev = res[T] = with_c.solve(initial=prev, **loads)
        if T <= 4.5:
            prev_free = free.solve(initial=prev_free, **loads)
            _print(f"{T} N without contact", describe(free, prev_free, g0))
        _print(f"{T} N with contact", describe(with_c, prev, g0),
               ref=prev_free.tip_position * 1e3 if T <= 4.5 else None)
    ref = res[5.0].tip_position * 1e3
    for factor in (10.0, 100.0, 0.1):
        with_c.contact_stiffness = default_stiffness(mat, geo) * factor
        r = with_c.solve(tensions=[5.0, 5.0, 0.0], initial=res[5.0], n_steps=1, max_steps=60)
        _print(f"5.0 N, k_c x {factor:g}", describe(with_c, r, g0), ref=ref)
    print(f"({time.perf_counter() - t0:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
