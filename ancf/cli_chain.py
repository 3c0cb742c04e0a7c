"""``bellows fk | locked | compliance`` on a multi-segment actuator (docs/multisegment.md, "Command line").

A chain is given like a one-segment actuator, by ``--preset`` (a chain preset such as ``two_segment``, or an
actuator file with ``[[segment]]`` tables).  Its inputs are lists, checked against the chain before any solve:

* ``--tensions-n``: one tension [N] per tendon, numbered segment by segment, segment 1's first (the numbering of
  :class:`ancf.chain_model.ChainModel`): ``1,0,0,0.5,0,0`` for two segments of three tendons;
* ``--pressure-kpa``: one pressure [kPa] per chamber, segment 1 first: ``30,10``;
* ``--lengths-mm``: one locked length [mm] per tendon, numbered as the tensions.

A wrong count is an :class:`~ancf.errors.InputError` naming the option and the count expected; loads outside a
segment's limits are the model's :class:`~ancf.errors.LimitError` (``--no-limits`` analyses them).

The printed table has one row per part, proximal first — each segment (its chamber pressure, its own tendons'
tensions and, for the locked FK, their slack), each rigid cap — with the part's start and end point
[mm]: a segment's first and last node, a cap's two faces (the end of the segment below it and the first node of
the segment above it); the last row is the tool point.  ``--json`` prints the same in SI units with the unit in
every key; ``--vtu`` writes the centreline and every tendon path (:func:`chain_mesh`).
"""

from __future__ import annotations

import json
import pathlib
from typing import Optional

import numpy as np
import typer
from rich.markup import escape
from rich.table import Table

from . import cli as _cli
from .chain import ChainParams
from .chain_model import ChainEquilibrium, ChainModel
from .errors import InputError, LimitError
from .textfmt import vector


# ============================================================================ inputs
def chain_model(chain: ChainParams, n_elements: Optional[int] = None) -> ChainModel:
    """The chain's model; ``n_elements`` (the --n-elements override) sets every segment's element count."""
    if n_elements is not None:
        chain = ChainParams(name=chain.name, description=chain.description, caps=chain.caps,
                            junction_stretch=chain.junction_stretch,
                            segments=tuple(s.replace(n_elements=n_elements) for s in chain.segments))
    return ChainModel(chain)


def _tendon_ranges(cm: ChainModel) -> str:
    """"T1–T3 of segment 1, T4–T6 of segment 2": the tendons' numbering, for error messages."""
    parts = []
    for k in range(cm.n_segments):
        idx = np.flatnonzero(cm.sys.owner == k) + 1
        parts.append(f"T{idx[0]}–T{idx[-1]} of segment {k + 1}" if idx.size > 1 else f"T{idx[0]} of segment {k + 1}")
    return ", ".join(parts)


def per_tendon(cm: ChainModel, text: Optional[str], option: str) -> np.ndarray:
    """``text`` ('1,0,0,0.5,0,0') → (m,) values, one per tendon of the chain (segment 1's first); None → zeros."""
    if text is None:
        return np.zeros(cm.m)
    v = _cli.parse_vector(text, None, option)
    if v.size != cm.m:
        raise InputError(f"{option}: expected {cm.m} values, one per tendon ({_tendon_ranges(cm)}), got {v.size} "
                         f"({text!r})")
    return v


# ============================================================================ results
def parts(cm: ChainModel, eq: ChainEquilibrium) -> tuple[list[dict], list[dict]]:
    """(segments, caps) of ``eq`` as JSON-ready records in SI units: a segment's number, chamber pressure, its
    tendons (1-based), their tensions [N] (and slack [m] for the locked FK), its first and last node [m]; a
    cap's number, mass [kg], length [m] and its two faces [m]."""
    q = eq.q
    starts = [cm.sys.segment_q(q, k)[:3] for k in range(cm.n_segments)]
    segs = []
    for k in range(cm.n_segments):
        idx = np.flatnonzero(cm.sys.owner == k)
        rec = {"segment": k + 1, "pressure_Pa": float(eq.pressures[k]), "tendons": [int(j) + 1 for j in idx],
               "tensions_N": eq.tensions[idx].tolist(), "start_m": starts[k].tolist(),
               "end_m": eq.segment_ends[k].tolist()}
        if eq.slack is not None:
            rec["slack_m"] = eq.slack[idx].tolist()
        segs.append(rec)
    caps = [{"cap": k + 1, "mass_kg": c.mass, "length_m": c.length, "start_m": eq.segment_ends[k].tolist(),
             "end_m": starts[k + 1].tolist()} for k, c in enumerate(cm.chain.caps)]
    return segs, caps


def summary(cm: ChainModel, eq: ChainEquilibrium, seconds: Optional[float] = None) -> dict:
    """The JSON of one chain state (SI units, the unit in every key)."""
    segs, caps = parts(cm, eq)
    out = {"tip_m": eq.tip.tolist(), "tensions_N": eq.tensions.tolist(), "pressures_Pa": eq.pressures.tolist(),
           "tip_force_N": eq.tip_force.tolist(), "tendon_lengths_m": eq.tendon_lengths.tolist(),
           "segments": segs, "caps": caps, "iterations": eq.iterations, "residual_norm": eq.residual_norm,
           "solver": eq.solver, "stable": bool(eq.stable), "limit_violations": list(eq.limit_violations)}
    if eq.slack is not None:
        out["slack_m"] = eq.slack.tolist()
        out["active"] = [int(j) for j in eq.active]
    if seconds is not None:
        out["solve_time_s"] = seconds
    return out


def _mm(p) -> str:
    return " ".join(f"{x * 1e3:.2f}" for x in p)


def table(cm: ChainModel, eq: ChainEquilibrium, title: str) -> Table:
    """One row per segment and cap (proximal first), then the tool point (module docstring)."""
    segs, caps = parts(cm, eq)
    t = Table(title=escape(title))
    for c in ("part", "p [kPa]", "T [N]", "slack [mm]", "start x,y,z [mm]", "end x,y,z [mm]"):
        t.add_column(escape(c), justify="left" if c == "part" else "right")
    for k, s in enumerate(segs):
        slack = " ".join(f"{x * 1e3:.3f}" for x in s["slack_m"]) if "slack_m" in s else "-"
        names = s["tendons"]
        tendons = f"T{names[0]}–T{names[-1]}" if len(names) > 1 else f"T{names[0]}"
        t.add_row(f"segment {k + 1} ({tendons})", f"{s['pressure_Pa'] / 1e3:.1f}",
                  " ".join(f"{x:.3f}" for x in s["tensions_N"]), slack, _mm(s["start_m"]), _mm(s["end_m"]))
        if k < len(caps):
            c = caps[k]
            t.add_row(f"cap {k + 1}", "", "", "", _mm(c["start_m"]), _mm(c["end_m"]))
    t.add_row("tool point", "", "", "", "", _mm(eq.tip))
    return t


def emit(cm: ChainModel, eq: ChainEquilibrium, case: str, seconds: float, title: str, as_json: bool,
         info: dict) -> None:
    """Print one chain state as a table (with its tip force, iterations and time) or as JSON {case: …}."""
    if as_json:
        typer.echo(json.dumps({case: dict(summary(cm, eq, seconds), model=info)}, indent=2))
        return
    _cli.console.print(table(cm, eq, title))
    _cli.console.print(escape(f"  tip force {vector(eq.tip_force, 'N', digits=2)}; {eq.iterations} iterations, "
                              f"{seconds * 1e3:.2f} ms"))
    if eq.limit_violations:
        _cli.console.print(escape(f"  {case}: OUTSIDE the actuator's limits: {'; '.join(eq.limit_violations)}"))


# ============================================================================ ParaView
def _segment_rod(cm: ChainModel, k: int):
    """A one-segment :class:`ancf.Model` of segment k with every tendon passing it (its own and the distal
    segments'): its centreline and tendon paths are the chain's over that segment."""
    from .model import Model
    tendons = tuple(t for s in cm.chain.segments[k:] for t in s.tendons)    # the chain's numbering from segment k
    return Model(cm.chain.segments[k].replace(tendons=tendons))


def chain_mesh(cm: ChainModel, eq: ChainEquilibrium, per_element: int = 10):
    """A :class:`meshio.Mesh` of a chain state: the centreline (cell data ``curve`` = 0) and each tendon's path
    (``curve`` = j for tendon j) as polylines through every segment and cap they pass (a cap is a straight piece
    between the segments' sample points).  Point data: those of :mod:`ancf.paraview` per segment at its chamber's
    pressure (``undeformed_arc_length_m`` along the whole chain, caps included), ``tension_N``, and ``segment``
    (1-based)."""
    from .paraview import TENDON_DISPLAY_RADIUS, section_fields
    centre, fields, paths = [], [], [[] for _ in range(cm.m)]
    x0 = 0.0
    for k in range(cm.n_segments):
        rod, qk = _segment_rod(cm, k), cm.sys.segment_q(eq.q, k)
        centre.append(rod.centreline(qk, per_element))
        sec = section_fields(rod, qk, float(eq.pressures[k]), per_element)
        sec["undeformed_arc_length_m"] = sec["undeformed_arc_length_m"] + x0
        sec["segment"] = np.full(len(centre[-1]), k + 1.0)
        fields.append(sec)
        on_tendon = dict(sec, radius_m=np.full(len(centre[-1]), rod.params.D_eff * TENDON_DISPLAY_RADIUS))
        for j, path in zip(cm.sys.segments[k].tendons, rod.tendon_paths(qk, per_element)):
            paths[j].append((path, on_tendon))
        x0 += rod.params.length + (cm.chain.caps[k].length if k < len(cm.chain.caps) else 0.0)
    lines = [(np.vstack(centre), {n: np.concatenate([f[n] for f in fields]) for n in fields[0]}, 0.0)]
    for j in range(cm.m):
        data = {n: np.concatenate([f[n] for _, f in paths[j]]) for n in fields[0]}
        lines.append((np.vstack([p for p, _ in paths[j]]), data, float(eq.tensions[j])))
    return _polylines(lines, [*fields[0], "tension_N"])


def _polylines(lines: list, names: list):
    """A :class:`meshio.Mesh` of polylines ``lines`` [(points (k, 3), {name: (k,)}, tension [N])], cell data
    ``curve`` = the line's index, point data ``names`` (``tension_N`` from each line's tension)."""
    import meshio
    cells, offset = [], 0
    for pts, _, _ in lines:
        idx = np.arange(offset, offset + len(pts))
        cells.append(np.column_stack([idx[:-1], idx[1:]]))
        offset += len(pts)
    data = {n: np.concatenate([d[n] if n in d else np.full(len(pts), t) for pts, d, t in lines]) for n in names}
    return meshio.Mesh(np.vstack([pts for pts, _, _ in lines]), [("line", c) for c in cells], point_data=data,
                       cell_data={"curve": [np.full(len(c), i) for i, c in enumerate(cells)]})


def save_chain_vtu(path, cm: ChainModel, eq: ChainEquilibrium, per_element: int = 10) -> pathlib.Path:
    """Write :func:`chain_mesh` to ``path`` (.vtu), creating the folder.  Returns the path."""
    path = pathlib.Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    chain_mesh(cm, eq, per_element).write(path)
    return path


# ============================================================================ the commands
def _info(preset: str, cm: ChainModel) -> dict:
    info = _cli.model_info(preset, cm.chain)
    info.update(kind="ANCF rod chain", segments=cm.n_segments,
                description=info["description"] + f", {cm.n_segments} segment" + ("s" if cm.n_segments > 1 else ""))
    return info


def fk(chain: ChainParams, preset: str, tensions_n: Optional[str], pressure_kpa: str, tip_force_n: str,
       n_elements: Optional[int], vtu: Optional[pathlib.Path], no_limits: bool, as_json: bool) -> None:
    """``bellows fk`` on a chain (the output path is checked by the caller)."""
    cm = chain_model(chain, n_elements)
    T = per_tendon(cm, tensions_n, "--tensions-n")
    pr = _cli.parse_pressures(pressure_kpa, cm.n_segments)
    F = _cli.parse_vector(tip_force_n, 3, "--tip-force-n")
    _cli.warm_up()
    eq, s = _cli._timed(cm.fk, T, pr, F, check_limits=not no_limits)
    if vtu:
        save_chain_vtu(vtu, cm, eq)
    info = _info(preset, cm)
    emit(cm, eq, "fk", s, f"FK — {info['description']}", as_json, info)


def locked(chain: ChainParams, preset: str, lengths_mm: str, pressure_kpa: str, tip_force_n: str, method: str,
           vtu: Optional[pathlib.Path], no_limits: bool, as_json: bool) -> None:
    """``bellows locked`` on a chain: the exact active set only (the caller has checked ``method``)."""
    if method != "active_set":
        raise InputError(f"--method {method}: a multi-segment actuator's locked FK has the exact active-set "
                         "method only (--method active_set)")
    cm = chain_model(chain)
    l0 = per_tendon(cm, lengths_mm, "--lengths-mm") * 1e-3
    if not np.all(l0 > 0):
        raise InputError(f"--lengths-mm: tendon lengths must be > 0 mm, got {lengths_mm!r}")
    pr = _cli.parse_pressures(pressure_kpa, cm.n_segments)
    F = _cli.parse_vector(tip_force_n, 3, "--tip-force-n")
    _cli.warm_up()
    eq, s = _cli._timed(cm.fk_locked, l0, pr, F, check_limits=not no_limits)
    if eq.limit_violations and not no_limits:
        raise LimitError(f"the locked state's tensions exceed their limits: {'; '.join(eq.limit_violations)} "
                         "(use --no-limits to report it anyway)")
    if vtu:
        save_chain_vtu(vtu, cm, eq)
    info = _info(preset, cm)
    emit(cm, eq, "locked", s, f"locked FK — {info['description']}", as_json, info)


def compliance(chain: ChainParams, preset: str, tensions_n: Optional[str], pressure_kpa: str, tip_force_n: str,
               load_direction: np.ndarray, no_limits: bool, as_json: bool) -> None:
    """``bellows compliance`` on a chain: tensions held, and the lengths of the taut tendons held (exact KKT;
    the taut set under a small extra load along ``load_direction``, :func:`ancf.chain_locked.locked_active`)."""
    from . import compliance as cp
    from .chain_locked import locked_active
    cm = chain_model(chain)
    T = per_tendon(cm, tensions_n, "--tensions-n")
    pr = _cli.parse_pressures(pressure_kpa, cm.n_segments)
    F = _cli.parse_vector(tip_force_n, 3, "--tip-force-n")
    eq = cm.fk(T, pr, F, check_limits=not no_limits)
    active = locked_active(cm, eq, load_direction)
    forms = {"tension": (cm.compliance(eq), ()), "locked/exact": (cm.locked_compliance(eq, active), active)}
    axes = {"x": (1, 0, 0), "y": (0, 1, 0), "z": (0, 0, 1)}
    data = {name: {"C_p_m_per_N": C.tolist(), "active": [int(j) for j in A],
                   "stiffness_N_per_m": {a: cp.directional_stiffness(C, v) for a, v in axes.items()}}
            for name, (C, A) in forms.items()}
    info = _info(preset, cm)
    segs, caps = parts(cm, eq)
    if as_json:
        typer.echo(json.dumps({"tip_m": eq.tip.tolist(), "segments": segs, "caps": caps, "forms": data,
                               "model": info}, indent=2))
        return
    _cli.console.print(table(cm, eq, f"the state — {info['description']}"))
    t = Table(title=escape(f"tip compliance at p = {vector(pr, 'kPa', 1e-3, 1)} (tip {vector(eq.tip, 'mm', 1e3, 2)})"))
    for c in ("form", "active", "C_p [mm/N] rows", "k_x [N/m]", "k_y [N/m]", "k_z [N/m]"):
        t.add_column(escape(c))
    for name, d in data.items():
        C = np.array(d["C_p_m_per_N"]) * 1e3
        t.add_row(name, _cli._tendons(d["active"]), "\n".join(" ".join(f"{x:8.3f}" for x in r) for r in C),
                  *(f"{d['stiffness_N_per_m'][a]:.1f}" for a in axes))
    _cli.console.print(t)
    _cli.console.print("  'exact': the exact locked linearisation (a chain has no paper/ik forms yet).")
