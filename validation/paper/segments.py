"""What a second segment buys: one bellows segment against two in series (docs/multisegment.md, "What a second
segment buys").

Compared.  The chain is the ``two_segment`` preset: two ``paper`` bellows of 80 mm (the same section law, D_eff,
line mass), a rigid 10 mm, 10 g cap between them, a chamber and three tendons each.  The single segment is the
``paper`` section at the chain's length from the base to the last cap, 170 mm by default (``single_length``; the
``paper`` preset itself is 160 mm: its bellows are as long as the chain's, its tool point 10 mm nearer the base).
170 mm is the default because a 160 mm segment is 10 mm shorter straight, which alone moves its workspace and its
reach; the 160 mm ``paper`` preset's workspace is reported beside it.  Every segment has the same input ranges:
tensions [0, 5] N, pressure [0, 120] kPa.  The pressures are inputs everywhere (one regulator per chamber), as in
:meth:`ancf.ChainModel.ik`.

(1) Workspace.  Monte Carlo inputs uniform in each box; the single segment's cloud is the TPHD cloud of
:func:`validation.paper.workspace_volume.workspace` (the same code, the same samples for the same seed); the chain's
FK runs chunk by chunk along a Morton curve of its inputs with warm starts (:func:`solve_chain_chunk`).  A sample
whose axial compression Σ T − p A_eff on some segment exceeds its law's largest plus the chain's whole weight has no
equilibrium and is not solved (``collapsed``); a solve that ends in CollapsedStateError is ``collapsed`` too, any
other failed solve ``failed``.  Both are counted and left out of the hull.  Volume: the convex hull of the tips;
reach: the largest distance of a tip from the base.

(2) Directions at a point.  A target point p_d, the tip of the single segment at given inputs (so inside its
workspace), which the chain reaches too (checked).  One segment has 3 tensions for 3 position constraints: at its
pressure, ∂p/∂T (3 × 3) is regular, the solution isolated and the tip direction one vector (reported: the rank and
the direction; over its pressure range, a curve of directions, its angular extent reported too).  The chain has
6 tensions: a pose IK (:meth:`ancf.ChainModel.ik` with ``tip_direction``) decides whether a direction d is
reachable at p_d.  Around the chain's least-tension direction d_c, along ``rays`` azimuths ψ, the largest reachable
tilt θ(ψ) is bracketed (doubling from ``first_tilt``, then ``bisections`` halvings: θ(ψ) is known to within the last
bracket, reported).  The set is taken as star-shaped about d_c; its angular extent is max_ψ θ(ψ) + θ(ψ + π), the
largest angle between two reachable directions along a line through d_c (a lower bound of the set's diameter).

(3) Stiffness range at the point.  u the unit vector of ``compliance_direction`` (default z, the payload direction).
For every chain state found on p_d (least tension, the IK minimising uᵀCu, and every reachable pose of (2)): uᵀCu
with the tensions held (:meth:`ancf.ChainModel.compliance`) and with the taut tendons' lengths held
(:meth:`ancf.ChainModel.locked_compliance`); their least and largest.  The IK minimum is a true minimum over the
redundant solutions (a KKT point); the largest is the largest sampled, a lower bound of the maximum.

(4) Obstacle.  A sphere placed across the single segment's centreline on the way to p_d (on the outer side of its
bend, at its middle); the single segment's shape is fixed by the target, so it crosses the sphere; the chain's IK
with ``obstacles`` keeps every body point at least radius + margin from the sphere's centre (the margin stands
for the body's radius about its centreline).

Nothing finished is lost: on Ctrl-C the finished parts are written to ``segments_partial.json`` in ``out`` and
:class:`~validation.infra.runner.RunInterrupted` names it.  The result files are checked before any work and are
not overwritten without ``force``.
"""

from __future__ import annotations

import pathlib
import time
from typing import Optional, Sequence, Union

import numpy as np

from ancf import ActuatorParams, ChainModel, presets
from ancf.chain import ChainParams
from ancf.errors import BellowsError, CollapsedStateError, InputError
from ancf.export import write_json
from ancf.outputs import prepare_output_dir

from validation.infra.runner import RunInterrupted, run_tasks
from validation.paper import states
from validation.paper.common import G
from validation.paper.hulls import hull_volume
from validation.paper.workspace_volume import morton_order
from validation.paper.workspace_volume import workspace as single_workspace_study

FILES = ("segments.json", "segments_clouds.npz", "segments_workspace.png", "segments_directions.png",
         "segments_obstacle.png")
STATUS = ("ok", "collapsed", "failed")
#: the single segment's inputs that make the target points: (tensions (3,) [N], pressure [Pa]); the chain is asked
#: to reach each at the same pressure in both chambers
POINTS = (((3.0, 1.5, 1.5), 60e3), ((1.0, 3.0, 3.0), 90e3), ((1.5, 3.5, 1.0), 75e3))
#: the obstacle case: its target point (an index of POINTS), the sphere's radius [m], its centre's distance from the
#: single segment's centreline [m] (outside its bend), the margin [m]
OBSTACLE = {"point": 1, "radius_m": 0.015, "offset_m": 0.020, "margin_m": 0.010}
#: the default sample counts, and those of ``quick`` (seconds: the tests and the documented command)
#: (``pressures``: how many pressures, evenly over the single segment's range, its direction is solved at)
DEFAULTS = {"samples": 1000, "rays": 8, "bisections": 3, "points": len(POINTS), "pressures": 13}
QUICK = {"samples": 40, "rays": 4, "bisections": 1, "points": 1, "pressures": 5}


def single_params(length: float = 0.17) -> ActuatorParams:
    """The ``paper`` section as one segment of ``length`` [m] (the ``paper`` preset itself at 0.16 m)."""
    if not 0.05 <= length <= 0.5:
        raise InputError(f"single segment length {length * 1e3:g} mm is outside [50, 500] mm")
    base = presets.paper()
    if abs(length - base.length) < 1e-12:
        return base
    return base.replace(length=float(length), name=f"paper_{length * 1e3:g}mm",
                        description=f"the paper section, one segment of {length * 1e3:g} mm")


# ----------------------------------------------------------------------------- (1) workspace
def chain_inputs(chain: ChainParams, samples: int, seed: int = 0) -> np.ndarray:
    """Monte Carlo inputs (samples, m + K): [T_1 … T_m [N], p_1 … p_K [Pa]], uniform in each tendon's and chamber's
    limits (the tensions drawn first, then the pressures, from one seeded generator)."""
    if samples < 1:
        raise InputError(f"samples must be ≥ 1, got {samples}")
    rng = np.random.default_rng(seed)
    lo = np.array([chain.segments[k].tension_min for k in chain.tendon_segment])
    hi = np.array([chain.segments[k].tension_max for k in chain.tendon_segment])
    T = rng.uniform(lo, hi, (samples, lo.size))
    plo = np.array([s.pressure_min for s in chain.segments])
    phi = np.array([s.pressure_max for s in chain.segments])
    return np.column_stack([T, rng.uniform(plo, phi, (samples, plo.size))])


def chain_certainly_collapsed(chain: ChainParams, T, p) -> bool:
    """True when some segment's Σ T (its own and every distal tendon) − p_k A_eff exceeds its law's largest
    compression plus the whole chain's weight: no equilibrium exists."""
    owner = np.asarray(chain.tendon_segment)
    weight = G * (sum(s.line_mass * s.length + s.tip_mass for s in chain.segments) + sum(c.mass for c in chain.caps))
    for k, s in enumerate(chain.segments):
        comp = float(np.sum(np.asarray(T)[owner >= k]) - p[k] * s.A_eff)
        if comp > states.law_limits(s)["max_compression_N"] + weight:
            return True
    return False


def solve_chain_chunk(task: dict) -> dict:
    """Chain FK for one chunk (runs in a worker): ``task`` holds chain, X (k, m + K), start.  Returns tips (k, 3)
    [m] (NaN unless ok), status (k,) (an index into STATUS), iterations, errors [(i, message)], seconds."""
    t0 = time.perf_counter()
    chain = task["chain"]
    model = ChainModel(chain)
    X = np.asarray(task["X"], float)
    k, m = len(X), model.m
    tips, status = np.full((k, 3), np.nan), np.zeros(k, np.int8)
    iters, errors, z_prev = np.zeros(k, np.int64), [], None
    for i in (morton_order(X) if k > 1 else range(k)):
        T, p = X[i, :m], X[i, m:]
        if chain_certainly_collapsed(chain, T, p):
            status[i] = 1
            errors.append((int(i), "collapsed: the axial compression exceeds the law's largest (not solved)"))
            continue
        eq, err = None, ""
        for z0 in ((z_prev, None) if z_prev is not None else (None,)):   # warm, then cold
            try:
                eq = model.fk(T, p, z0=z0)
                break
            except CollapsedStateError as exc:
                err = f"collapsed: {exc}"
                break
            except (BellowsError, FloatingPointError, np.linalg.LinAlgError) as exc:
                err = f"{type(exc).__name__}: {exc}"
        if eq is None:
            status[i] = 1 if err.startswith("collapsed") else 2
            errors.append((int(i), err))
            continue
        tips[i], iters[i], z_prev = eq.tip, eq.iterations, eq.z
    return {"start": task["start"], "tips": tips, "status": status, "iterations": iters, "errors": errors,
            "seconds": time.perf_counter() - t0}


def cloud_summary(tips: np.ndarray, status: np.ndarray) -> dict:
    """Volume [m³], reach [m] (largest |tip|), bounding box and counts of a cloud (tips (N, 3), status (N,) of
    STATUS indices)."""
    ok = status == 0
    P = tips[ok]
    return {"samples": int(len(tips)), "solved": int(ok.sum()), "collapsed": int((status == 1).sum()),
            "failed": int((status == 2).sum()), "volume_m3": hull_volume(P),
            "reach_m": float(np.linalg.norm(P, axis=1).max()) if len(P) else float("nan"),
            "bbox_min_m": P.min(axis=0) if len(P) else None, "bbox_max_m": P.max(axis=0) if len(P) else None}


def chain_workspace(chain: ChainParams, samples: int, seed: int = 0, *, workers: Optional[int] = 1,
                    progress: bool = False, chunk_size: int = 50) -> dict:
    """The chain's Monte Carlo workspace: {"inputs" (N, m + K), "tips" (N, 3) [m], "status" (N,), "summary",
    "first_errors"} (module docstring, (1))."""
    X = chain_inputs(chain, samples, seed)
    tasks = [{"chain": chain, "X": X[s:s + chunk_size], "start": s} for s in range(0, samples, chunk_size)]
    run = run_tasks(solve_chain_chunk, tasks, workers=workers, progress=progress,
                    description=f"chain workspace FK ({chain.name}, {samples} samples)",
                    weights=[len(t["X"]) for t in tasks])
    tips, status, errors = np.full((samples, 3), np.nan), np.full(samples, 2, np.int8), []
    for r in run.results:
        s, k = r["start"], len(r["tips"])
        tips[s:s + k], status[s:s + k] = r["tips"], r["status"]
        errors += [(s + i, msg) for i, msg in r["errors"]]
    return {"inputs": X, "tips": tips, "status": status, "summary": cloud_summary(tips, status),
            "first_errors": [msg for _, msg in sorted(errors)][:5],
            "busy_s": float(sum(r["seconds"] for r in run.results))}


def single_workspace(params: ActuatorParams, samples: int, seed: int = 0, *, workers: Optional[int] = 1,
                     progress: bool = False) -> dict:
    """The single segment's workspace: the TPHD mode of :func:`validation.paper.workspace_volume.workspace` (its
    inputs, tips and status; the same code and samples as ``bellows paper workspace``)."""
    res = single_workspace_study(samples=samples, seed=seed, workers=workers, progress=progress, params=params,
                                 figure=False)
    c = res["clouds"]["TPHD"]
    status = np.array([STATUS.index(s) for s in c["status"]], np.int8)
    return {"inputs": c["inputs"], "tips": c["tips"], "status": status, "summary": cloud_summary(c["tips"], status),
            "first_errors": res["modes"]["TPHD"]["first_errors"]}


# ----------------------------------------------------------------------------- (2) directions
def angle(a, b) -> float:
    """Angle between two vectors [rad]."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.arctan2(np.linalg.norm(np.cross(a, b)), a @ b))


def tilt(d0, theta: float, psi: float) -> np.ndarray:
    """The unit vector at angle ``theta`` [rad] from the unit vector d0, towards azimuth ``psi`` [rad] about it
    (ψ measured in the plane ⊥ d0 from the projection of z, or of y when d0 ∥ z)."""
    d0 = np.asarray(d0, float) / np.linalg.norm(d0)
    ref = np.array([0.0, 0.0, 1.0]) if abs(d0[2]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = ref - (ref @ d0) * d0
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(d0, e1)
    return np.cos(theta) * d0 + np.sin(theta) * (np.cos(psi) * e1 + np.sin(psi) * e2)


def _pose(chain: ChainModel, target, pressures, d, start):
    """The pose IK at (target, d) from ``start`` (an equilibrium), or None when no reachable pose is found."""
    try:
        return chain.ik(target, pressures, tip_direction=d, tensions0=start.tensions, z0=start.z)
    except BellowsError:
        return None


def ray_extent(chain: ChainModel, target, pressures, d_c, psi: float, start, *, first_tilt: float = np.radians(8),
               bisections: int = 3, max_tilt: float = np.radians(90)):
    """Bracket the largest reachable tilt from d_c along azimuth ψ: (θ_lo, θ_hi) [rad] (θ_lo reachable, θ_hi not;
    θ_hi = max_tilt when every tilt tried was reachable) and the states found."""
    lo, hi, found, last = 0.0, None, [], start
    th = first_tilt
    while hi is None:                                     # doubling until a tilt fails
        r = _pose(chain, target, pressures, tilt(d_c, th, psi), last)
        if r is None:
            hi = th
        else:
            lo, last = th, r
            found.append(r)
            if th >= max_tilt:
                return lo, max_tilt, found
            th = min(2 * th, max_tilt)
    for _ in range(bisections):
        mid = 0.5 * (lo + hi)
        r = _pose(chain, target, pressures, tilt(d_c, mid, psi), last)
        if r is None:
            hi = mid
        else:
            lo, last = mid, r
            found.append(r)
    return lo, hi, found


def direction_set(chain: ChainModel, target, pressures, *, rays: int = 8, bisections: int = 3) -> dict:
    """The chain's reachable tip directions at ``target`` (module docstring, (2)): the least-tension state, d_c,
    per ray ψ the bracket [θ_lo, θ_hi] [rad], the extent (lower and upper bound) [rad], and every state found."""
    base = chain.ik(target, pressures)
    d_c = base.tip_rotation[:, 0]
    psis = np.arange(rays) * 2 * np.pi / rays
    brackets, states_found = [], [base]
    for psi in psis:
        lo, hi, found = ray_extent(chain, target, pressures, d_c, psi, base, bisections=bisections)
        brackets.append((lo, hi))
        states_found += found
    B = np.array(brackets)
    half = rays // 2 if rays % 2 == 0 else 0
    if half:
        ext_lo = float(max(B[i, 0] + B[(i + half) % rays, 0] for i in range(rays)))
        ext_hi = float(max(B[i, 1] + B[(i + half) % rays, 1] for i in range(rays)))
    else:
        ext_lo, ext_hi = float(B[:, 0].max()), float(2 * B[:, 1].max())
    dirs = [s.tip_rotation[:, 0] for s in states_found]
    return {"least_tension": base, "center_direction": d_c, "azimuths_rad": psis, "tilt_brackets_rad": B,
            "extent_rad": (ext_lo, ext_hi), "states": states_found, "directions": np.array(dirs)}


def single_direction(single: ChainModel, target, pressure: float) -> dict:
    """The single segment's one direction at ``target`` and ``pressure`` [Pa]: its state, the tip direction and the
    rank of ∂p/∂T (3 = the solution is isolated)."""
    eq = single.ik(target, [pressure])
    J = tip_tension_jacobian(single, eq)
    return {"state": eq, "direction": eq.tip_rotation[:, 0], "rank": int(np.linalg.matrix_rank(J, tol=1e-9 * np.abs(
        J).max())), "singular_values": np.linalg.svd(J, compute_uv=False)}


def tip_tension_jacobian(model: ChainModel, eq) -> np.ndarray:
    """∂p_end/∂T (3, m) [m/N] at an equilibrium: J_p dz/dT with H dz/dT = −J_lᵀ (the FK's tangent)."""
    _, _, H, _, Jl = model.sys.evaluate(eq.z, eq.tensions, eq.pressures, eq.tip_force, hessian=True, lengths=2)
    return model.sys.tip_jacobian(eq.z) @ -np.linalg.solve(H, Jl.T)


def single_pressure_sweep(single: ChainModel, target, pressures: Sequence[float]) -> dict:
    """The single segment's direction at ``target`` for each pressure [Pa] it reaches it at: the directions, the
    pressures, and their angular extent (the largest angle between two) [rad]."""
    ok_p, dirs = [], []
    for p in pressures:
        try:
            dirs.append(single.ik(target, [p]).tip_rotation[:, 0])
            ok_p.append(float(p))
        except BellowsError:
            continue
    ext = max((angle(a, b) for a in dirs for b in dirs), default=0.0)
    return {"pressures_Pa": ok_p, "directions": np.array(dirs).reshape(-1, 3), "extent_rad": float(ext)}


# ----------------------------------------------------------------------------- (3) stiffness
def directional_compliances(model: ChainModel, eq, u) -> tuple[float, float]:
    """(uᵀCu with the tensions held, uᵀC'u with the taut tendons' lengths held) [m/N] at ``eq``."""
    u = np.asarray(u, float) / np.linalg.norm(u)
    c_t = float(u @ model.compliance(eq) @ u)
    taut = tuple(int(j) for j in np.nonzero(eq.tensions > 1e-9)[0])
    c_l = float(u @ model.locked_compliance(eq, taut) @ u) if taut else c_t
    return c_t, c_l


def stiffness_range(chain: ChainModel, target, pressures, found: Sequence, u) -> dict:
    """uᵀCu over the chain's states on ``target`` (module docstring, (3)) [m/N]: the IK's minimum (``min_ik``), and
    the least and largest over ``found`` plus that minimum, tensions held and lengths held."""
    best = chain.ik(target, pressures, objective="compliance", compliance_direction=u,
                    tensions0=found[0].tensions, z0=found[0].z)
    vals = np.array([directional_compliances(chain, s, u) for s in [best, *found]])
    return {"min_ik_m_per_N": float(vals[0, 0]), "held_m_per_N": (float(vals[:, 0].min()), float(vals[:, 0].max())),
            "locked_m_per_N": (float(vals[:, 1].min()), float(vals[:, 1].max())),
            "least_tension_m_per_N": float(vals[1, 0]), "states": int(len(vals)), "stiffest": best}


# ----------------------------------------------------------------------------- (4) obstacle
def obstacle_case(chain: ChainModel, single: ChainModel, single_eq, pressures, *, radius: float,
                  offset: float, margin: float, samples: int = 4) -> dict:
    """The sphere across the single segment's shape (module docstring, (4)): its centre ``offset`` [m] from the
    single centreline's middle body point, away from the chord (outside the bend), ``radius`` [m]; the single
    segment's clearance, the chain's without and with the ``obstacles`` constraint (clearance = least distance of a
    body point from the centre − radius − margin [m])."""
    from ancf.chain_ik import Body
    target = single_eq.tip

    def line(model, eq):
        """The centreline's points and the tool point (the caps' midpoints left out: a polyline from the base)."""
        body = Body(model, samples)
        x = body.points(eq.z)
        return np.vstack([x[:body.n_centreline], x[-1:]])
    xs = line(single, single_eq)
    mid = xs[len(xs) // 2]
    n = mid - 0.5 * (xs[0] + xs[-1])
    centre = mid + offset * n / np.linalg.norm(n)

    def clearance(model, eq):
        return float(np.min(np.linalg.norm(Body(model, samples).points(eq.z) - centre, axis=1)) - radius - margin)
    free = chain.ik(target, pressures)
    kept = chain.ik(target, pressures, obstacles=[(centre, radius)], obstacle_margin=margin,
                    obstacle_samples=samples, tensions0=free.tensions, z0=free.z)
    return {"target_m": target, "centre_m": centre, "radius_m": radius, "margin_m": margin,
            "single_clearance_m": clearance(single, single_eq), "chain_free_clearance_m": clearance(chain, free),
            "chain_clearance_m": clearance(chain, kept), "chain_tip_error_m": float(np.linalg.norm(kept.tip - target)),
            "chain_tensions_N": kept.tensions, "chain_free_tensions_N": free.tensions,
            "single_tensions_N": single_eq.tensions, "kkt": kept.kkt,
            "shapes_m": {"single": xs, "chain_free": line(chain, free), "chain": line(chain, kept)}}


# ----------------------------------------------------------------------------- the study
def _point(chain, single, spec, sweep_pressures, rays, bisections, u) -> dict:
    """Directions (2) and stiffness (3) at the point of one POINTS entry."""
    T, p = spec
    s_eq = single.fk(T, [p])
    target = s_eq.tip
    sd = single_direction(single, target, p)
    sweep = single_pressure_sweep(single, target, sweep_pressures)
    ds = direction_set(chain, target, [p, p], rays=rays, bisections=bisections)
    st = stiffness_range(chain, target, [p, p], ds["states"], u)
    c_t, c_l = directional_compliances(single, sd["state"], u)
    return {"single_inputs": {"tensions_N": np.asarray(T, float), "pressure_Pa": p}, "target_m": target,
            "pressures_Pa": [p, p],
            "single": {"direction": sd["direction"], "jacobian_rank": sd["rank"],
                       "singular_values_m_per_N": sd["singular_values"], "tensions_N": sd["state"].tensions,
                       "held_m_per_N": c_t, "locked_m_per_N": c_l,
                       "pressure_sweep": sweep, "pressure_extent_deg": float(np.degrees(sweep["extent_rad"]))},
            "chain": {"center_direction": ds["center_direction"], "azimuths_rad": ds["azimuths_rad"],
                      "tilt_brackets_deg": np.degrees(ds["tilt_brackets_rad"]),
                      "extent_deg": tuple(float(np.degrees(e)) for e in ds["extent_rad"]),
                      "directions": ds["directions"], "poses_found": int(len(ds["states"])),
                      "least_tension_N": ds["least_tension"].tensions,
                      "stiffness": {k: v for k, v in st.items() if k != "stiffest"},
                      "stiffest_tensions_N": st["stiffest"].tensions},
            "single_to_chain_center_deg": float(np.degrees(angle(sd["direction"], ds["center_direction"])))}


def segments_study(samples: Optional[int] = None, seed: int = 0, *, rays: Optional[int] = None,
                   bisections: Optional[int] = None, n_points: Optional[int] = None, quick: bool = False,
                   single_length: float = 0.17, workers: Optional[int] = 1, progress: bool = False,
                   out: Union[str, pathlib.Path, None] = None, force: bool = False, figure: bool = True,
                   compliance_direction=(0.0, 0.0, 1.0), log=lambda s: None) -> dict:
    """One segment against two (module docstring).  Sample counts default to :data:`DEFAULTS` (:data:`QUICK` with
    ``quick``).  Returns a dict (SI units, the unit in each key; angles in degrees): ``workspace`` (``single``,
    ``single_160mm`` (the ``paper`` preset), ``chain``: :func:`cloud_summary` each, and ``volume_ratio``),
    ``points`` (per target point: the single segment's direction, its Jacobian rank and pressure sweep, the chain's
    direction brackets and extent, the stiffness ranges), ``obstacle``, ``timing``.  With ``out``: segments.json,
    segments_clouds.npz and the figures."""
    cfg = dict(QUICK if quick else DEFAULTS)
    for k, v in (("samples", samples), ("rays", rays), ("bisections", bisections), ("points", n_points)):
        if v is not None:
            cfg[k] = int(v)
    if not 1 <= cfg["points"] <= len(POINTS):
        raise InputError(f"points must be 1 to {len(POINTS)}, got {cfg['points']}")
    if not 2 <= cfg["rays"] <= 64 or not 0 <= cfg["bisections"] <= 10:
        raise InputError("rays must be 2 to 64 and bisections 0 to 10")
    files = FILES if figure else FILES[:2]
    if out is not None:
        out = prepare_output_dir(out, files, force=force)
    u = np.asarray(compliance_direction, float)
    chain_p, single_p = presets.two_segment(), single_params(single_length)
    chain, single = ChainModel(chain_p), ChainModel(single_p)
    res: dict = {"study": "what a second segment buys: one segment against two", "chain": chain_p.name,
                 "single": single_p.name, "single_length_m": single_p.length, "chain_length_m": chain_p.length,
                 "settings": {**cfg, "seed": seed, "compliance_direction": u / np.linalg.norm(u)},
                 "points": [], "timing": {}}
    t0 = time.perf_counter()
    try:
        _run_parts(res, cfg, seed, chain_p, chain, single_p, single, u, workers, progress, log)
    except (KeyboardInterrupt, RunInterrupted) as exc:
        saved = None
        if out is not None:
            saved = write_json(out / "segments_partial.json", public_result(res))
        raise RunInterrupted("the segments study was interrupted", completed={i: p for i, p in enumerate(
            res["points"])}, total=cfg["points"], saved_to=saved) from exc
    res["timing"]["wall_s"] = time.perf_counter() - t0
    if out is not None:
        write_outputs(res, out, figure=figure)
    return res


def _run_parts(res, cfg, seed, chain_p, chain, single_p, single, u, workers, progress, log) -> None:
    """Fill ``res`` part by part (so an interruption keeps the finished parts)."""
    t = time.perf_counter()
    log(f"workspace: {cfg['samples']} samples each")
    ws = {"single": single_workspace(single_p, cfg["samples"], seed, workers=workers, progress=progress),
          "chain": chain_workspace(chain_p, cfg["samples"], seed, workers=workers, progress=progress)}
    paper160 = single_p if abs(single_p.length - 0.16) < 1e-12 else presets.paper()
    ws["single_160mm"] = single_workspace(paper160, cfg["samples"], seed, workers=workers, progress=progress)
    res["clouds"] = ws
    v1, v2 = ws["single"]["summary"]["volume_m3"], ws["chain"]["summary"]["volume_m3"]
    res["workspace"] = {k: w["summary"] for k, w in ws.items()}
    res["workspace"]["volume_ratio"] = v2 / v1 if v1 > 0 else float("nan")
    res["workspace"]["first_errors"] = {k: w["first_errors"] for k, w in ws.items()}
    res["timing"]["workspace_s"] = time.perf_counter() - t
    sweep = np.linspace(single_p.pressure_min, single_p.pressure_max, cfg["pressures"])
    for i, spec in enumerate(POINTS[:cfg["points"]]):
        t = time.perf_counter()
        log(f"point {i + 1} of {cfg['points']}: directions and stiffness")
        res["points"].append(_point(chain, single, spec, sweep, cfg["rays"], cfg["bisections"], u))
        res["timing"][f"point_{i + 1}_s"] = time.perf_counter() - t
    t = time.perf_counter()
    spec = POINTS[OBSTACLE["point"]]
    s_eq = single.fk(spec[0], [spec[1]])
    log("obstacle")
    res["obstacle"] = obstacle_case(chain, single, s_eq, [spec[1], spec[1]], radius=OBSTACLE["radius_m"],
                                    offset=OBSTACLE["offset_m"], margin=OBSTACLE["margin_m"])
    res["timing"]["obstacle_s"] = time.perf_counter() - t


def public_result(res: dict) -> dict:
    """The result without the clouds and states (what segments.json holds)."""
    return {k: v for k, v in res.items() if k != "clouds"}


def write_outputs(res: dict, out: Union[str, pathlib.Path], *, figure: bool = True) -> dict:
    """segments_clouds.npz, the figures (with ``figure``) and segments.json into ``out``."""
    out = pathlib.Path(out)
    files: dict = {"clouds": out / "segments_clouds.npz"}
    np.savez_compressed(files["clouds"], **{f"{k}_{a}": w[a] for k, w in res["clouds"].items()
                                            for a in ("inputs", "tips", "status")})
    if figure:
        files["figures"] = [plot_workspace(res, out), plot_directions(res, out), plot_obstacle(res, out)]
    files["json"] = out / "segments.json"
    res["files"] = files
    write_json(files["json"], public_result(res))
    return files


# ----------------------------------------------------------------------------- the table
def table_rows(res: dict) -> list[tuple[str, str, str]]:
    """(quantity, one segment, two segments) rows of the documentation's table (3 or 4 significant figures)."""
    w = res["workspace"]
    ws, wc = w["single"], w["chain"]
    rows = [("workspace volume [cm³]", f"{ws['volume_m3'] * 1e6:.3g}", f"{wc['volume_m3'] * 1e6:.3g}"),
            ("reach from the base [mm]", f"{ws['reach_m'] * 1e3:.4g}", f"{wc['reach_m'] * 1e3:.4g}"),
            ("samples solved / collapsed / failed", f"{ws['solved']} / {ws['collapsed']} / {ws['failed']}",
             f"{wc['solved']} / {wc['collapsed']} / {wc['failed']}")]
    for i, pt in enumerate(res["points"]):
        tg = ", ".join(f"{round(v * 1e3) + 0:.0f}" for v in pt["target_m"])
        s, c = pt["single"], pt["chain"]
        lo, hi = c["extent_deg"]
        one = (f"one (rank {s['jacobian_rank']}); {s['pressure_extent_deg']:.2f}° apart over the "
               f"{len(s['pressure_sweep']['pressures_Pa'])} of {res['settings']['pressures']} pressures reaching it")
        rows.append((f"point {i + 1} ({tg}) mm at {pt['pressures_Pa'][0] / 1e3:g} kPa: tip directions", one,
                     f"a set {lo:.3g}°–{hi:.3g}° across"))
        st = c["stiffness"]
        rows.append((f"point {i + 1}: uᵀCu along z, tensions held [mm/N]", f"{s['held_m_per_N'] * 1e3:.4g}",
                     f"{st['held_m_per_N'][0] * 1e3:.4g} – {st['held_m_per_N'][1] * 1e3:.4g}"))
        rows.append((f"point {i + 1}: uᵀC'u along z, lengths held [mm/N]", f"{s['locked_m_per_N'] * 1e3:.3g}",
                     f"{st['locked_m_per_N'][0] * 1e3:.3g} – {st['locked_m_per_N'][1] * 1e3:.3g}"))
    ob = res["obstacle"]
    what = f"obstacle (sphere r = {ob['radius_m'] * 1e3:g} mm, margin {ob['margin_m'] * 1e3:g} mm): clearance [mm]"
    chain = (f"{round(ob['chain_clearance_m'] * 1e3, 4) + 0.0:.3g} (without the constraint "
             f"{ob['chain_free_clearance_m'] * 1e3:.3g})")
    rows.append((what, f"{ob['single_clearance_m'] * 1e3:.3g} (crosses)", chain))
    return rows


def markdown_table(res: dict) -> str:
    """The documentation's table of the study (docs/multisegment.md), from its result or its segments.json."""
    lines = ["| quantity | one segment | two segments |", "|---|---|---|"]
    lines += [f"| {a} | {b} | {c} |" for a, b, c in table_rows(res)]
    return "\n".join(lines) + "\n"


# ----------------------------------------------------------------------------- figures (no computation)
def _hull_loop(P2):
    from scipy.spatial import ConvexHull
    v = ConvexHull(P2).vertices
    return np.append(v, v[0])


def plot_workspace(res: dict, out) -> pathlib.Path:
    """segments_workspace.png: the tip clouds of one segment and of the chain, side (x–z) and top (x–y) views with
    their hulls' outlines."""
    from validation.paper.common import pyplot
    plt = pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.6))
    style = (("single", "tab:blue", "one segment"), ("chain", "tab:red", "two segments"))
    for key, col, name in style:
        c = res["clouds"][key]
        P = c["tips"][c["status"] == 0] * 1e3
        w = res["workspace"][key]
        for ax, (i, j) in zip(axes, ((0, 2), (0, 1))):
            ax.scatter(P[:, i], P[:, j], s=2, color=col, alpha=0.35, rasterized=True,
                       label=f"{name}: {w['volume_m3'] * 1e6:.0f} cm³, reach {w['reach_m'] * 1e3:.0f} mm")
            if len(P) >= 3:
                loop = _hull_loop(P[:, [i, j]])
                ax.plot(P[loop, i], P[loop, j], color=col, lw=1)
    for pt in res["points"]:
        for ax, (i, j) in zip(axes, ((0, 2), (0, 1))):
            ax.plot(pt["target_m"][i] * 1e3, pt["target_m"][j] * 1e3, "k*", ms=9)
    for ax, (h, v, view) in zip(axes, (("x", "z", "side"), ("x", "y", "top"))):
        ax.set(xlabel=f"{h} [mm]", ylabel=f"{v} [mm]", title=f"{view} view")
        ax.set_aspect("equal", adjustable="datalim")
        ax.grid(alpha=0.3)
    axes[0].legend(loc="lower left", fontsize=8, markerscale=4)
    fig.suptitle(f"Workspace, {res['settings']['samples']} samples each ({res['single']} vs {res['chain']}; "
                 "stars: the target points)")
    fig.tight_layout()
    return _save(fig, out, "segments_workspace.png")


def plot_directions(res: dict, out) -> pathlib.Path:
    """segments_directions.png: per target point, the reachable tip directions as tilts from the chain's
    least-tension direction (the bracketed boundary, the poses found) and the single segment's one direction."""
    from validation.paper.common import pyplot
    plt = pyplot()
    n = len(res["points"])
    fig, axes = plt.subplots(1, n, figsize=(4.2 * n, 4.2), squeeze=False)
    for ax, pt, k in zip(axes[0], res["points"], range(n)):
        c = pt["chain"]
        d_c, psi = np.asarray(c["center_direction"]), np.asarray(c["azimuths_rad"])
        B = np.asarray(c["tilt_brackets_deg"])
        for col, lab, r in (("tab:red", "reachable (bracket low)", B[:, 0]), ("0.6", "unreachable", B[:, 1])):
            ax.plot(np.append(r, r[0]) * np.cos(np.append(psi, psi[0])),
                    np.append(r, r[0]) * np.sin(np.append(psi, psi[0])), color=col, lw=1.3, label=lab)
        XY = np.array([_tilt_coords(d_c, d) for d in c["directions"]])
        ax.plot(XY[:, 0], XY[:, 1], ".", color="tab:red", ms=5, label="chain poses found")
        s = _tilt_coords(d_c, pt["single"]["direction"])
        ax.plot(*s, "o", color="tab:blue", ms=8, label="one segment (its only direction)")
        ax.set(title=f"point {k + 1}: extent {c['extent_deg'][0]:.0f}–{c['extent_deg'][1]:.0f}°",
               xlabel="tilt · cos ψ [deg]", ylabel="tilt · sin ψ [deg]")
        ax.set_aspect("equal", adjustable="datalim")
        ax.grid(alpha=0.3)
    axes[0][0].legend(fontsize=7, loc="best")
    fig.suptitle("Tip directions reachable at a point (tilt from the chain's least-tension direction)")
    fig.tight_layout()
    return _save(fig, out, "segments_directions.png")


def _tilt_coords(d_c, d) -> tuple[float, float]:
    """(θ cos ψ, θ sin ψ) [deg] of the unit vector d about d_c, in :func:`tilt`'s azimuth convention."""
    d_c = np.asarray(d_c, float)
    e1 = tilt(d_c, np.pi / 2, 0.0)
    e2 = np.cross(d_c, e1)
    th = np.degrees(angle(d_c, d))
    psi = np.arctan2(np.asarray(d) @ e2, np.asarray(d) @ e1)
    return th * np.cos(psi), th * np.sin(psi)


def plot_obstacle(res: dict, out) -> pathlib.Path:
    """segments_obstacle.png: side and top views of the single segment's shape, the chain's without and with the
    obstacle constraint, and the sphere (its radius, and radius + margin dashed)."""
    from validation.paper.common import pyplot
    plt = pyplot()
    ob = res["obstacle"]
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.6))
    C = np.asarray(ob["centre_m"]) * 1e3
    lines = (("single", "tab:blue", f"one segment ({ob['single_clearance_m'] * 1e3:+.1f} mm)"),
             ("chain_free", "0.5", f"two, least tension ({ob['chain_free_clearance_m'] * 1e3:+.1f} mm)"),
             ("chain", "tab:red", f"two, with the obstacle ({ob['chain_clearance_m'] * 1e3:+.1f} mm)"))
    for ax, (i, j) in zip(axes, ((0, 2), (0, 1))):
        for key, col, lab in lines:
            X = np.asarray(ob["shapes_m"][key]) * 1e3
            ax.plot(X[:, i], X[:, j], "-o", color=col, ms=2.5, lw=1.5, label=lab)
        for r, ls in ((ob["radius_m"], "-"), (ob["radius_m"] + ob["margin_m"], "--")):
            ax.add_patch(plt.Circle((C[i], C[j]), r * 1e3, fill=ls == "-", alpha=0.25 if ls == "-" else 1,
                                    ls=ls, color="k", lw=1))
        ax.plot(ob["target_m"][i] * 1e3, ob["target_m"][j] * 1e3, "k*", ms=10)
        ax.set_aspect("equal", adjustable="datalim")
        ax.grid(alpha=0.3)
    axes[0].set(xlabel="x [mm]", ylabel="z [mm]", title="side view")
    axes[1].set(xlabel="x [mm]", ylabel="y [mm]", title="top view")
    axes[0].legend(fontsize=8, loc="best", title="clearance of radius + margin")
    fig.suptitle("A sphere across the one segment's shape: the chain reaches the same tip around it")
    fig.tight_layout()
    return _save(fig, out, "segments_obstacle.png")


def _save(fig, out, name: str) -> pathlib.Path:
    import matplotlib.pyplot as plt
    path = pathlib.Path(out) / name
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
