"""Self-contact margin and routing radius of the `paper` design over its operating range, measured on the FEM
(docs/fem.md §5a, "Self-contact and routing radius over the operating range, measured").

Solves a grid of the operating range on the coarse mesh (tensions up to 5 N on one, two and three tendons,
pressure 0 / 50 / 100 kPa, a 0.2 kg·g tip load up, down and sideways, 0.1 kg·g down; 15 solves, 10–110 s each on
2 shared cores, warm-started along short chains, a failed warm start solved again from the unloaded state) and
prints, per state:

* the gap between the facing outer flanks of adjacent convolutions (:func:`fem_reference.contact.flank_gaps`):
  its minimum over the grooves [mm], that minimum over the unloaded one, the smallest gap relative to the
  unloaded gap at the same place, and the groove and angle where the minimum is;
* the same for the inner grooves (the two flanks of one convolution across its crest), the end flanks'
  distance from the cap planes (:func:`fem_reference.contact.cap_gaps`) and the cap's bending angle;
* each tendon's distance from the local centreline (:func:`fem_reference.contact.tendon_radii`) at each guide
  and half-way between two guides, relative to the unloaded d, and the largest local curvature;

then the tip displacement of the rod preset `paper` when every routing radius is scaled by the largest
measured change, at the loads of the state where that change occurs.

Usage::

    python benchmarks/fem_contact_margin.py                        # solves (≈ 10 min), prints the tables
    python benchmarks/fem_contact_margin.py --cache /tmp/contact   # keep / reuse each FEM state as .npz
    python benchmarks/fem_contact_margin.py --mesh medium --states "T1 5 N"   # one state (and its warm start)
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

#: tip load of the operating range: 0.2 kg under standard gravity [N]
TIP_N = 0.2 * 9.81

#: The measured states: (name, tensions [N], pressure [kPa], tip force [N] (world frame, axis +x, tendon 1 at +z),
#: the state it is warm-started from or None).  Tendon 1 pulls the tip towards +z ("upward"); "tip −z" is a
#: weight hanging on an actuator bent upwards ("tip -z/2" half of it), "tip +z" a load that bends it further.
STATES = (
    ("T1 2.5 N", (2.5, 0, 0), 0, (0, 0, 0), None),
    ("T1 5 N", (5, 0, 0), 0, (0, 0, 0), "T1 2.5 N"),
    ("T1 5 N, tip +z", (5, 0, 0), 0, (0, 0, TIP_N), "T1 5 N"),
    ("T1 5 N, tip -z", (5, 0, 0), 0, (0, 0, -TIP_N), "T1 5 N"),
    ("T1 5 N, tip +y", (5, 0, 0), 0, (0, TIP_N, 0), "T1 5 N"),
    ("tip +z", (0, 0, 0), 0, (0, 0, TIP_N), None),
    ("T1+T2 5 N", (5, 5, 0), 0, (0, 0, 0), None),
    ("T1+T2+T3 5 N", (5, 5, 5), 0, (0, 0, 0), None),
    ("100 kPa", (0, 0, 0), 100, (0, 0, 0), None),
    ("T1 5 N, 50 kPa", (5, 0, 0), 50, (0, 0, 0), None),
    ("T1 5 N, 100 kPa", (5, 0, 0), 100, (0, 0, 0), "T1 5 N, 50 kPa"),
    ("T1 5 N, 100 kPa, tip +z", (5, 0, 0), 100, (0, 0, TIP_N), "T1 5 N, 100 kPa"),
    ("T1 5 N, 100 kPa, tip -z", (5, 0, 0), 100, (0, 0, -TIP_N), "T1 5 N, 100 kPa"),
    ("T1+T2 5 N, 100 kPa", (5, 5, 0), 100, (0, 0, 0), None),
    ("T1 5 N, tip -z/2", (5, 0, 0), 0, (0, 0, -TIP_N / 2), "T1 5 N"),
)


def _path(cache, name: str, mesh: str) -> Path:
    safe = "".join(c if c.isalnum() else {"+": "p", "-": "m", "/": "h"}.get(c, "_") for c in name)
    return Path(cache) / f"paper_{mesh}_{safe}.npz"


def paper_model(mesh: str = "coarse"):
    """The FEM model of the `paper` design on ``mesh``."""
    from fem_reference import BellowsModel
    from validation.reference.designs import load_design

    geo, mat = load_design("paper")
    return BellowsModel(geo, mat, mesh=mesh)


def _state_of(model, data):
    st = model.zero_state()
    st.U[:] = data["U"]
    st.uc[:] = data["uc"]
    st.R[:] = data["R"]
    st.T[:] = data["T"]
    return st


def solve_states(cache, states=STATES, model=None, log=print, mesh: str = "coarse") -> tuple[dict, dict]:
    """Solve ``states`` (or read them from ``cache``, one .npz each, or a .failed note); returns
    ({name: State}, {name: the failure of a state without an equilibrium})."""
    from ancf.errors import BellowsError

    model = paper_model(mesh) if model is None else model
    Path(cache).mkdir(parents=True, exist_ok=True)
    out, results, failed = {}, {}, {}
    for name, T, p_kPa, F, start in states:
        path = _path(cache, name, mesh)
        if path.with_suffix(".failed").exists():
            failed[name] = path.with_suffix(".failed").read_text()
            continue
        if path.exists():
            out[name] = _state_of(model, np.load(path))
            continue
        t0 = time.perf_counter()
        init = results.get(start)
        if init is None and start in out:
            init = _as_result(model, out[start], {s[0]: s for s in states}[start])
        loads = {"tensions": np.asarray(T, float), "pressure": p_kPa * 1e3, "tip_force": np.asarray(F, float)}
        try:
            res = model.solve(**loads, initial=init)
        except BellowsError as exc:
            if init is None:
                raise
            log(f"{name}: warm start failed ({str(exc)[:80]}…); solving from the unloaded state")
            try:
                res = model.solve(**loads)
            except BellowsError as exc2:
                failed[name] = str(exc2)
                path.with_suffix(".failed").write_text(str(exc2))
                log(f"{name}: no equilibrium found: {exc2}")
                continue
        results[name] = res
        out[name] = res.state
        np.savez(path, U=res.state.U, uc=res.state.uc, R=res.state.R, T=res.state.T,
                 seconds=time.perf_counter() - t0, iterations=res.iterations)
        log(f"{name}: {time.perf_counter() - t0:.0f} s, {res.iterations} iterations, "
            f"tip {np.round(res.tip_position * 1e3, 2)} mm")
    return out, failed


def _as_result(model, st, spec):
    """A BellowsResult of a cached state (for a warm start)."""
    from fem_reference.results import BellowsResult
    from fem_reference.solver import NewtonStats

    _, T, p_kPa, F, _ = spec
    lc = model._loadcase(np.asarray(T, float), p_kPa * 1e3, np.asarray(F, float), False, None)
    return BellowsResult(model, st, lc, NewtonStats(), model.tendon_lengths(st))


def _selected(names) -> tuple:
    """The STATES named in ``names`` (';'-separated) and the states they are warm-started from; all if None."""
    if names is None:
        return STATES
    by = {s[0]: s for s in STATES}
    want = [n.strip() for n in names.split(";") if n.strip()]
    unknown = [n for n in want if n not in by]
    if unknown:
        raise SystemExit(f"error: unknown state(s) {unknown}; choose from {list(by)}")
    need = set()
    for n in want:
        while n is not None and n not in need:
            need.add(n)
            n = by[n][4]
    return tuple(s for s in STATES if s[0] in need)


def _bend_deg(st) -> float:
    """Angle of the distal cap's axis from the base axis [deg]."""
    return float(np.degrees(np.arccos(np.clip(st.R[0, 0], -1.0, 1.0))))


def _local_curvature(model, x) -> np.ndarray:
    """Curvature of the centreline at each interior root [1/m]: turn of its tangent between the crest rows either
    side over the deformed centreline length between them (n_guides,)."""
    from fem_reference.contact import groove_rows

    rows, h = groove_rows(model.bmesh, "outer")
    bm = model.bmesh
    n_t = bm.shape[1]
    sel = bm.lattice[1] == n_t
    cnt = np.bincount(bm.lattice[0, sel])
    cl = np.stack([np.bincount(bm.lattice[0, sel], weights=x[k, sel]) / cnt for k in range(3)], 1)
    tan = np.gradient(cl, axis=0)
    tan /= np.linalg.norm(tan, axis=1)[:, None]
    seg = np.linalg.norm(np.diff(cl, axis=0), axis=1)
    out = []
    for r in rows:
        a, b = r - h, r + h
        turn = np.arccos(np.clip(tan[a] @ tan[b], -1, 1))
        out.append(turn / seg[a:b].sum())
    return np.array(out)


def measure_state(model, st, gaps0) -> dict:
    """Flank gaps, routing radii and bending of one state (SI; module doc)."""
    from fem_reference.contact import cap_gaps, flank_gaps, tendon_radii

    bm = model.bmesh
    x = bm.X + st.U
    out = {"bend_deg": _bend_deg(st), "tip_mm": (model.tip_position(st) * 1e3).round(1),
           "caps_mm": cap_gaps(bm, x, model.X_c + st.uc, st.R) * 1e3}
    for surface in ("outer", "inner"):
        fg = flank_gaps(bm, x, surface)
        k, j, i = fg.argmin()
        rel = fg.gaps / gaps0[surface].gaps
        out[surface] = {"min_mm": fg.minimum * 1e3, "ratio": fg.minimum / gaps0[surface].minimum,
                            "rel_min": float(np.nanmin(rel)), "groove": k + 1, "level": j + 1,
                            "theta_deg": float(np.degrees(np.pi * i / bm.shape[2]))}
    pts = [tp.points(x, model.X_c + st.uc, st.R) for tp in model.tendons]
    tr = tendon_radii(bm, x, pts)
    d = model.geometry.tendon_radius
    out["guides"] = tr.guides / d
    out["spans"] = tr.spans / d
    out["spans_smooth"] = tr.spans_smooth / d
    out["kappa"] = _local_curvature(model, x)
    return out


def rod_tip_error(name: str, factor: float) -> float:
    """Tip distance [m] between the rod preset `paper` with every routing radius scaled by ``factor`` and the
    nominal one, at the loads of state ``name``."""
    from ancf import presets
    from ancf.model import Model
    from ancf.params import Tendon

    _, T, p_kPa, F, _ = {s[0]: s for s in STATES}[name]
    par = presets.get("paper")
    scaled = par.replace(tendons=tuple(Tendon(distance=t.distance * factor, angle=t.angle) for t in par.tendons))
    tips = [Model(p).fk(np.asarray(T, float), p_kPa * 1e3, tip_force=np.asarray(F, float)).tip for p in (par, scaled)]
    return float(np.linalg.norm(tips[1] - tips[0]))


def _print_tables(rows: dict, mesh: str = "coarse") -> None:
    print(f"\n### Flank gaps ({mesh} mesh; groove counted from the base, θ from tendon 1)\n")
    print("| state | outer min gap [mm] | / unloaded | smallest g/g₀ | at groove, θ [deg] | inner min gap [mm] "
          "| / unloaded | smallest g/g₀ | flank to cap, base / distal [mm] | cap bend [deg] |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for name, r in rows.items():
        o, i = r["outer"], r["inner"]
        print(f"| {name} | {o['min_mm']:.2f} | {o['ratio']:.2f} | {o['rel_min']:.2f} | {o['groove']}, "
              f"{o['theta_deg']:.0f} | {i['min_mm']:.2f} | {i['ratio']:.2f} | {i['rel_min']:.2f} | "
              f"{r['caps_mm'][0]:.2f} / {r['caps_mm'][1]:.2f} | {r['bend_deg']:.0f} |")
    print("\n### Routing radius: distance from the local centreline, change from d₀ = 27.5 mm [%]\n")
    print("| state | largest local curvature [1/m] | at the guides: min … max | mid-span from the crest ring, "
          "tendon 1 / all: min … max | mid-span from the smooth centreline, all: min … max |")
    print("|---|---|---|---|---|")
    for name, r in rows.items():
        if "guides" not in r:
            continue
        g, s, sm = (100 * (r[k] - 1) for k in ("guides", "spans", "spans_smooth"))
        print(f"| {name} | {r['kappa'].max():.1f} | {g.min():+.4f} … {g.max():+.4f} | {s[0].min():+.2f} … "
              f"{s[0].max():+.2f} / {s.min():+.2f} … {s.max():+.2f} | {sm.min():+.2f} … {sm.max():+.2f} |")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cache", default="/tmp/fem_contact_margin", help="directory of one .npz per FEM state")
    ap.add_argument("--mesh", default="coarse", help="FEM mesh level (coarse, medium: ≈ 3× the time per solve)")
    ap.add_argument("--states", default=None,
                    help="only these states, ';'-separated names of STATES (their warm starts are solved too)")
    a = ap.parse_args(argv)
    from fem_reference.contact import cap_gaps, flank_gaps

    t0 = time.perf_counter()
    model = paper_model(a.mesh)
    states, failed = solve_states(a.cache, _selected(a.states), model=model, mesh=a.mesh)
    bm = model.bmesh
    gaps0 = {s: flank_gaps(bm, bm.X, s) for s in ("outer", "inner")}
    rows = {"unloaded": {"outer": {"min_mm": gaps0["outer"].minimum * 1e3, "ratio": 1.0, "rel_min": 1.0, "groove": 1,
                                       "theta_deg": 0.0},
                         "inner": {"min_mm": gaps0["inner"].minimum * 1e3, "ratio": 1.0, "rel_min": 1.0},
                         "bend_deg": 0.0, "caps_mm": cap_gaps(bm, bm.X, model.X_c, np.eye(3)) * 1e3}}
    rows.update({name: measure_state(model, st, gaps0) for name, st in states.items()})
    _print_tables(rows, a.mesh)
    for name, why in failed.items():
        print(f"\n{name}: no equilibrium found on the FEM ({why})")
    meas = {n: r for n, r in rows.items() if "guides" in r}
    for key in ("guides", "spans", "spans_smooth"):
        name, f = max(((n, r[key].flat[np.argmax(np.abs(r[key] - 1))]) for n, r in meas.items()),
                      key=lambda v: abs(v[1] - 1))
        err = rod_tip_error(name, f)
        print(f"\nlargest change, {key}: {100 * (f - 1):+.3f} % ({name}); the rod preset `paper` "
              f"with every d scaled by {f:.5f} at those loads: tip moves {err * 1e3:.2f} mm")
    print(f"\n({len(states)} states, {time.perf_counter() - t0:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
