"""``bellows fk | ik | locked | demo | params``: the ANCF model on the command line.

Units are in the option names (``--pressure-kpa``, ``--tip-force-n``, ``--target-mm``); ``--json`` prints
machine-readable output (SI units, unit in every key).

Rules every command keeps (docs/errors.md): a given option is used or rejected, never replaced; output
paths are checked before any computing and existing files are only replaced with ``--force``; the
actuator's operating limits apply to every mode (``--no-limits`` analyses outside them, and says so);
timings exclude loading the compiled kernels.
"""

from __future__ import annotations

import json
import pathlib
import time
from typing import Optional

import numpy as np
import typer
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from . import clitools, presets
from .chain import ChainParams
from .errors import InputError
from .export import equilibrium_summary, save_png, save_vtu, write_json
from .model import Model
from .outputs import atomic_write_text, prepare_output_dir, prepare_output_file
from .params import N_ELEMENTS_MAX, N_ELEMENTS_MIN
from .textfmt import number, one_of, vector

console = Console(width=120)

# lists of choices are built from the code's registries (presets.NAMES, LOCKED_METHODS): --help cannot drift
PRESET_HELP = f"Preset name {one_of(presets.NAMES)} or a path to an actuator .toml file."
#: methods of ``bellows locked --method``: the exact active-set solve, or the paper's eq. 6 tension law
LOCKED_METHODS = {"active_set": "exact", "gamma": "paper eq. 6"}
FORCE_HELP = "Overwrite existing output files."
NO_LIMITS_HELP = "Analyse loads outside the actuator's operating limits (tensions, pressure) instead of rejecting them."
#: ``--pressure-kpa`` of the model's commands: any finite number here; the actuator's limits are the model's check
#: (with --no-limits as the override)
PRESSURE_HELP = "Chamber pressure [kPa] (within the actuator's limits unless --no-limits)."
#: ``--pressure-kpa`` of ``fk``, ``locked``, ``compliance``: one number, or one per chamber of a chain
PRESSURES_HELP = ("Chamber pressure [kPa] (default 0; within the actuator's limits unless --no-limits); a "
                  "multi-segment actuator: one per chamber, comma separated, segment 1 first.")
#: ``--tensions-n`` of ``fk`` and ``compliance``
TENSIONS_HELP = ("Tendon tensions [N], comma separated (default: all 0); a multi-segment actuator: one per tendon, "
                 "segment 1's first.")
#: ``--preset`` of the commands that take one segment or a chain (``fk``, ``locked``, ``compliance``, ``params``)
ANY_PRESET_HELP = (f"Preset name {one_of([*presets.NAMES, *presets.CHAIN_NAMES])} or a path to an actuator .toml "
                   "file (one segment, or a chain with [[segment]] tables).")
#: ``--n-elements``: typer's own range check (shown in --help), the same range as the actuator file's n_elements
N_ELEMENTS_RANGE = {"min": N_ELEMENTS_MIN, "max": N_ELEMENTS_MAX}


def parse_vector(text: str, n: Optional[int], what: str) -> np.ndarray:
    """'2,0,0' → array; clear error on a wrong count, an empty entry ('2,,0') or a non-number."""
    parts = text.replace(" ", "").split(",")
    if parts and parts[-1] == "":
        parts.pop()                                    # a trailing comma: '2,0,0,'
    if "" in parts:
        raise InputError(f"{what}: expected comma-separated numbers, got an empty entry in {text!r}")
    try:
        v = np.array([float(x) for x in parts])
    except ValueError:
        raise InputError(f"{what}: expected comma-separated numbers, got {text!r}") from None
    if n is not None and v.size != n:
        raise InputError(f"{what}: expected {n} values, got {v.size} ({text!r})")
    if not np.all(np.isfinite(v)):
        raise InputError(f"{what}: values must be finite, got {text!r}")
    return v


def parse_pressures(text: Optional[str], n_chambers: int, option: str = "--pressure-kpa") -> np.ndarray:
    """'30,10' [kPa] → pressures (K,) [Pa], one per chamber (segment 1 first); None → zeros; a clear error on a
    wrong count."""
    if text is None:
        return np.zeros(n_chambers)
    v = parse_vector(text, None, option)
    if v.size != n_chambers:
        what = ("1 value (one chamber)" if n_chambers == 1
                else f"{n_chambers} values, one per chamber (segment 1 first)")
        raise InputError(f"{option}: expected {what}, got {v.size} ({text!r})")
    return v * 1e3


def _tensions(text: Optional[str], m: int) -> np.ndarray:
    """--tensions-n of a one-segment actuator: (m,) [N]; None → zeros."""
    return np.zeros(m) if text is None else parse_vector(text, m, "--tensions-n")


#: what a preset's parameters are, for the line that says which model produced a result (other presets: their
#: ``description``)
PRESET_NOTES = {"paper": "the paper's stiffness law"}


def model_info(preset: str, params) -> dict:
    """Which model and which parameter set produced a result: ``{"kind": "ANCF rod", "parameters": name,
    "source": "preset" | "file", "path": the file (absolute) or None, "description": one line}`` — the
    description, e.g. "ANCF rod model, actuator preset 'paper' (the paper's stiffness law)", is the title of the
    printed table; the dict is the JSON's ``model`` field.  ``preset``: the --preset option as given."""
    is_file = str(preset).endswith(".toml")
    note = PRESET_NOTES.get(params.name) if not is_file else None
    note = note or params.description
    where = (f"actuator file {pathlib.Path(preset).resolve()} (name '{params.name}')" if is_file
             else f"actuator preset '{params.name}'")
    return {"kind": "ANCF rod", "parameters": params.name, "source": "file" if is_file else "preset",
            "path": str(pathlib.Path(preset).resolve()) if is_file else None,
            "description": f"ANCF rod model, {where}" + (f" ({note})" if note else "")}


def _table(rows: list[dict], title: str) -> Table:
    t = Table(title=title)
    cols = ["case", "T [N]", "p [kPa]", "F [N]", "tip x,y,z [mm]", "slack [mm]", "its", "time [ms]"]
    for c in cols:   # escape: rich would read "[kPa]" as a style tag and drop the unit
        t.add_column(escape(c), justify="right" if c not in ("case",) else "left")
    for r in rows:
        eq = r["eq"]
        t.add_row(r["case"], " ".join(f"{x:.3f}" for x in eq.tensions), f"{eq.pressure / 1e3:.1f}",
                  " ".join(f"{x:.2f}" for x in eq.tip_force), " ".join(f"{x * 1e3:.2f}" for x in eq.tip),
                  "-" if eq.slack is None else " ".join(f"{x * 1e3:.3f}" for x in eq.slack),
                  str(eq.iterations), f"{r['seconds'] * 1e3:.2f}")
    return t


def _emit(rows, title, as_json, model: dict):
    """The rows as a table titled ``title`` — the model's description (:func:`model_info`) — or as JSON, one
    entry per case, each with the ``model`` field."""
    if as_json:
        typer.echo(json.dumps({r["case"]: dict(_summary(r), model=model) for r in rows}, indent=2))
    else:
        console.print(_table(rows, title))
        for r in rows:
            if r.get("note"):
                console.print(escape(f"  {r['case']:>7}: {r['note']}"))
            if r["eq"].limit_violations:
                console.print(escape(f"  {r['case']:>7}: OUTSIDE the actuator's limits: "
                                     f"{'; '.join(r['eq'].limit_violations)}"))


def _summary(row) -> dict:
    eq = row["eq"]
    return dict(equilibrium_summary(eq, row["seconds"]), stable=bool(eq.stable),
                min_eigenvalue=eq.min_eigenvalue, limit_violations=list(eq.limit_violations))


def _timed(fn, *a, **k):
    t = time.perf_counter()
    out = fn(*a, **k)
    return out, time.perf_counter() - t


def fk(tensions_n: Optional[str] = typer.Option(None, help=TENSIONS_HELP),
       pressure_kpa: Optional[str] = typer.Option(None, help=PRESSURES_HELP),
       tip_force_n: str = typer.Option("0,0,0", help="External tip force [N] (world frame)."),
       preset: str = typer.Option("paper", help=ANY_PRESET_HELP),
       n_elements: Optional[int] = typer.Option(None, help="Override the number of elements (of every segment).",
                                            **N_ELEMENTS_RANGE),
       vtu: Optional[pathlib.Path] = typer.Option(None, help="Write the shape to this .vtu file."),
       force: bool = typer.Option(False, "--force", help=FORCE_HELP),
       no_limits: bool = typer.Option(False, "--no-limits", help=NO_LIMITS_HELP),
       as_json: bool = typer.Option(False, "--json", help="Print JSON instead of a table.")):
    """Forward kinetostatics: tensions, pressure, tip load → equilibrium shape and tip (a chain: per segment
    and cap)."""
    vtu = _vtu_path(vtu, force)
    params = presets.get_any(preset)
    if isinstance(params, ChainParams):
        from . import cli_chain
        return cli_chain.fk(params, preset, tensions_n, pressure_kpa, tip_force_n, n_elements, vtu, no_limits, as_json)
    model = _model_of(params, n_elements)
    T = _tensions(tensions_n, model.m)
    pr = parse_pressures(pressure_kpa, 1)[0]
    F = parse_vector(tip_force_n, 3, "--tip-force-n")
    warm_up()
    eq, s = _timed(model.fk, T, pr, F, check_limits=not no_limits)
    if vtu:
        save_vtu(vtu, model, eq)
    info = model_info(preset, model.params)
    _emit([{"case": "fk", "eq": eq, "seconds": s}], f"FK — {info['description']}", as_json, info)


def ik(target_mm: str = typer.Option(..., help="Target tip position [mm], 'x,y,z'."),
       pressure_kpa: float = typer.Option(0.0, help=PRESSURE_HELP, callback=clitools.FINITE),
       tip_force_n: str = typer.Option("0,0,0", help="Known tip force [N]."),
       preset: str = typer.Option("paper", help=PRESET_HELP),
       n_elements: Optional[int] = typer.Option(None, help="Override the number of elements.",
                                            **N_ELEMENTS_RANGE),
       vtu: Optional[pathlib.Path] = typer.Option(None, help="Write the shape to this .vtu file."),
       force: bool = typer.Option(False, "--force", help=FORCE_HELP),
       no_limits: bool = typer.Option(False, "--no-limits", help="Accept a pressure outside the actuator's "
                                      "limits (the tensions always stay within theirs)."),
       as_json: bool = typer.Option(False, "--json", help="Print JSON instead of a table.")):
    """Inverse kinetostatics: target tip position → tensions (within their limits) and shape."""
    vtu = _vtu_path(vtu, force)
    model = _model(preset, n_elements)
    pd = parse_vector(target_mm, 3, "--target-mm") * 1e-3
    F = parse_vector(tip_force_n, 3, "--tip-force-n")
    warm_up(all_solvers=True)                  # the timed row is the IK alone, not its compilation
    eq, s = _timed(model.ik, pd, pressure_kpa * 1e3, F, check_limits=not no_limits)
    if vtu:
        save_vtu(vtu, model, eq)
    info = model_info(preset, model.params)
    _emit([{"case": "ik", "eq": eq, "seconds": s}], f"IK — {info['description']}", as_json, info)


def locked(lengths_mm: str = typer.Option(..., help="Locked tendon lengths [mm], comma separated (a multi-segment "
                                        "actuator: one per tendon, segment 1's first)."),
           pressure_kpa: Optional[str] = typer.Option(None, help=PRESSURES_HELP),
           tip_force_n: str = typer.Option("0,0,0", help="External tip force [N]."),
           method: str = typer.Option("active_set", help=f"Method {one_of(LOCKED_METHODS)}: "
                                      + ", ".join(f"{k} ({v})" for k, v in LOCKED_METHODS.items())
                                      + " (a multi-segment actuator: active_set)."),
           preset: str = typer.Option("paper", help=ANY_PRESET_HELP),
           vtu: Optional[pathlib.Path] = typer.Option(None, help="Write the shape to this .vtu file."),
           force: bool = typer.Option(False, "--force", help=FORCE_HELP),
           no_limits: bool = typer.Option(False, "--no-limits", help="Report states whose tensions exceed the "
                                          "actuator's limit (marked in the output) instead of rejecting them."),
           as_json: bool = typer.Option(False, "--json", help="Print JSON instead of a table.")):
    """Locked-tendon-length FK: tendon lengths, pressure, load → shape, tensions and slack."""
    vtu = _vtu_path(vtu, force)
    params = presets.get_any(preset)
    if isinstance(params, ChainParams):
        from . import cli_chain
        return cli_chain.locked(params, preset, lengths_mm, pressure_kpa, tip_force_n, method, vtu, no_limits, as_json)
    model = _model_of(params, None)
    l0 = parse_vector(lengths_mm, model.m, "--lengths-mm") * 1e-3
    if not np.all(l0 > 0):
        raise InputError(f"--lengths-mm: tendon lengths must be > 0 mm, got {lengths_mm!r}")
    pr = parse_pressures(pressure_kpa, 1)[0]
    F = parse_vector(tip_force_n, 3, "--tip-force-n")
    if method not in LOCKED_METHODS:
        raise InputError(f"--method must be one of {', '.join(LOCKED_METHODS)}, got {method!r}")
    warm_up(all_solvers=True)                  # the timed row is the locked solve alone
    eq, s = _timed(model.fk_locked, l0, pr, F, method=method, check_limits=not no_limits)
    if not no_limits:
        eq.require_within_limits()
    if vtu:
        save_vtu(vtu, model, eq)
    info = model_info(preset, model.params)
    _emit([{"case": "locked", "eq": eq, "seconds": s}], f"locked FK — {info['description']}", as_json, info)


def compliance(tensions_n: Optional[str] = typer.Option(None, help=TENSIONS_HELP),
               pressure_kpa: Optional[str] = typer.Option(None, help=PRESSURES_HELP),
               tip_force_n: str = typer.Option("0,0,0", help="Tip force [N] at the state."),
               load_direction: str = typer.Option("0,0,-1", help="Direction of the extra load (locked active set)."),
               preset: str = typer.Option("paper", help=ANY_PRESET_HELP),
               no_limits: bool = typer.Option(False, "--no-limits", help=NO_LIMITS_HELP),
               as_json: bool = typer.Option(False, "--json", help="Print JSON instead of a table.")):
    """Tip compliance [mm/N] and stiffness [N/m] at an FK state: constant tension and locked tendons
    (exact KKT form, paper eq. 13, paper eq. 15; a chain: the exact form)."""
    from . import compliance as cp
    params = presets.get_any(preset)
    u = parse_vector(load_direction, 3, "--load-direction")
    if not np.linalg.norm(u) > 0:
        raise InputError(f"--load-direction must be a non-zero vector, got {load_direction!r}")
    if isinstance(params, ChainParams):
        from . import cli_chain
        return cli_chain.compliance(params, preset, tensions_n, pressure_kpa, tip_force_n, u, no_limits, as_json)
    model = _model_of(params, None)
    T = _tensions(tensions_n, model.m)
    pr = parse_pressures(pressure_kpa, 1)[0]
    F = parse_vector(tip_force_n, 3, "--tip-force-n")
    eq = model.fk(T, pr, F, check_limits=not no_limits)
    forms = {"tension": cp.tension(model, eq)}
    for method in ("exact", "paper", "ik"):
        forms[f"locked/{method}"] = cp.locked(model, eq, method, load_direction=u)
    axes = {"x": (1, 0, 0), "y": (0, 1, 0), "z": (0, 0, 1)}
    data = {name: {"C_p_m_per_N": c.C_p.tolist(), "active": list(c.active),
                   "stiffness_N_per_m": {a: cp.directional_stiffness(c.C_p, v) for a, v in axes.items()}}
            for name, c in forms.items()}
    info = model_info(preset, model.params)
    if as_json:
        typer.echo(json.dumps({"tip_m": eq.tip.tolist(), "forms": data, "model": info}, indent=2))
        return
    t = Table(title=escape(f"tip compliance at T = {vector(T, 'N', digits=2)}, p = {number(pr / 1e3, 'kPa')} "
                           f"(tip {vector(eq.tip, 'mm', 1e3, 2)}) — {info['description']}"))
    for c in ("form", "active", "C_p [mm/N] rows", "k_x [N/m]", "k_y [N/m]", "k_z [N/m]"):
        t.add_column(escape(c))
    for name, d in data.items():
        C = np.array(d["C_p_m_per_N"]) * 1e3
        t.add_row(name, _tendons(d["active"]), "\n".join(" ".join(f"{x:8.3f}" for x in r) for r in C),
                  *(f"{d['stiffness_N_per_m'][a]:.1f}" for a in axes))
    console.print(t)
    console.print("  'exact' is the exact locked linearisation; 'paper'/'ik' are the paper's stacked "
                  "least-squares forms (see validation/checks/compliance_check.py for their error).")


#: ``bellows params --preset``: the one-segment presets and the multi-segment ones (ancf.chain)
PARAMS_PRESET_HELP = ANY_PRESET_HELP


def params(preset: str = typer.Option("paper", help=PARAMS_PRESET_HELP),
           out: Optional[pathlib.Path] = typer.Option(None, help="Write the TOML to this .toml file instead."),
           force: bool = typer.Option(False, "--force", help=FORCE_HELP)):
    """Print a preset as TOML (a starting point for your own actuator file; SI units in the key names —
    length_mm, angle_deg, pressure_max_kPa, ... are accepted too).  The file reads back to the same
    parameters; a multi-segment actuator prints as a chain file ([[segment]] and [[cap]] tables)."""
    path = None if out is None else prepare_output_file(out, force=force, suffixes=(".toml",))
    text = presets.get_any(preset).to_toml()
    if path is None:
        typer.echo(text, nl=False)
    else:
        atomic_write_text(path, text)
        console.print(f"wrote {path}")


DEMO_FILES = ("demo.png", "demo.json", "droop.vtu", "bend.vtu", "ik.vtu", "locked.vtu")


def demo(out: pathlib.Path = typer.Option(pathlib.Path("bellows_out"), help="Output folder."),
         preset: str = typer.Option("paper", help=PRESET_HELP),
         force: bool = typer.Option(False, "--force", help="Overwrite the results of an earlier demo in --out."),
         as_json: bool = typer.Option(False, "--json", help="Print JSON instead of a table.")):
    """A short tour on a preset: gravity droop, a bend, an IK target and a locked-tendon load case.

    Prints a table and writes demo.png, one .vtu per case and demo.json to the --out folder."""
    out = prepare_output_dir(out, DEMO_FILES, force=force)
    model = _model(preset, None)
    t0 = time.perf_counter()
    warm_up(all_solvers=True)                  # every solver the rows time: their times are the solves alone
    warm_up_s = time.perf_counter() - t0
    if not as_json:
        console.print(f"numba kernels ready in {warm_up_s:.1f} s "
                      "(compiled once, then cached; not in the rows' times)")
    rows = run_demo(model)
    out.mkdir(parents=True, exist_ok=True)
    for r in rows:
        save_vtu(out / f"{r['case'].split()[0]}.vtu", model, r["eq"])
    png = save_png(out / "demo.png", model, [(f"{r['case']}: {r['note']}", r["eq"]) for r in rows],
                   title=f"bellows demo — preset '{model.params.name}'")
    summary = {r["case"]: dict(equilibrium_summary(r["eq"], r["seconds"]), note=r["note"]) for r in rows}
    info = model_info(preset, model.params)
    write_json(out / "demo.json", {"preset": model.params.name, "model": info, "warm_up_s": warm_up_s,
                                   "cases": summary})
    _emit(rows, f"bellows demo — {info['description']}, n = {model.n} elements", as_json, info)
    if not as_json:
        console.print(f"wrote {png}, {out / 'demo.json'} and {len(rows)} .vtu files in {out}/")


def warm_up(*, all_solvers: bool = False) -> None:
    """Compile (first run) or load (later runs) the numba kernels, so timings show solver cost only: FK with a
    tip load and its stability check, the pressure sensitivity ∂Q/∂p and the admissibility rules, in every
    argument-type signature the solvers and the fits of :mod:`validation.identification.fit` call (types, not sizes, make a
    signature: one element is enough).  ``all_solvers``: also IK to an interior target and the locked-tendon
    FK under a tip load (the kernels ``bellows demo`` times; ≈ 0.3 s more once cached, their compilation the first time)."""
    model = Model(presets.paper().replace(n_elements=1))
    eq = model.fk((0.5, 0.0, 0.0), 1e3, (0.0, 0.0, -0.1))
    model.dQ_dp(eq.q, 1e3)
    model.inadmissibility(eq.q)
    if all_solvers:
        T = np.full(model.m, 0.5)
        T[0], T[-1] = 3.0, 1.5
        ik = model.ik(model.fk(T, 30e3, (0.0, 0.0, 0.0)).tip, 30e3, (0.0, 0.0, 0.0))
        model.fk_locked(ik.tendon_lengths, 30e3, (0.0, 0.0, -0.5), q0=ik.q, tensions0=ik.tensions)


def run_demo(model: Model) -> list[dict]:
    """The demo's four cases; returns rows {case, eq, seconds}."""
    rows = []
    droop, s = _timed(model.fk, np.zeros(model.m), 0.0, (0, 0, 0))
    rows.append({"case": "droop", "eq": droop, "seconds": s, "note": "gravity only, T = 0, p = 0"})
    T = np.zeros(model.m)
    T[0] = 3.0
    bend, s = _timed(model.fk, T, 30e3, (0, 0, 0))
    rows.append({"case": "bend", "eq": bend, "seconds": s, "note": "T1 = 3 N at 30 kPa"})
    # a target up and to the side, known to be inside the workspace: the tip at interior tensions,
    # rounded to 0.1 mm (IK then has to find the tensions itself, from a cold start)
    T_int = np.full(model.m, 0.5)
    T_int[0], T_int[-1] = 3.0, 1.5
    target = np.round(model.fk(T_int, 30e3, (0, 0, 0)).tip, 4)
    ik_eq, s = _timed(model.ik, target, 30e3, (0, 0, 0))
    rows.append({"case": "ik", "eq": ik_eq, "seconds": s,
                 "note": f"IK to {vector(target, 'mm', 1e3)} at 30 kPa (cold start)"})
    lk, s = _timed(model.fk_locked, ik_eq.tendon_lengths, 30e3, (0, 0, -0.05 * 9.81), q0=ik_eq.q,
                   tensions0=ik_eq.tensions)
    rows.append({"case": "locked", "eq": lk, "seconds": s,
                 "note": "motors locked at the IK state, then a 50 g tip load"})
    return rows


def _tendons(indices) -> str:
    """Tendon indices (0-based) as the tendons' names: ``(0, 2)`` → ``"T1, T3"``; none → ``"–"``."""
    return ", ".join(f"T{i + 1}" for i in indices) or "–"


def _vtu_path(vtu: Optional[pathlib.Path], force: bool) -> Optional[pathlib.Path]:
    return None if vtu is None else prepare_output_file(vtu, force=force, suffixes=(".vtu",))


def _model(preset: str, n_elements: Optional[int]) -> Model:
    return _model_of(presets.get(preset), n_elements)


def _model_of(p, n_elements: Optional[int]) -> Model:
    """The one-segment model of parameters ``p`` (ActuatorParams), with ``n_elements`` elements if given."""
    if n_elements is not None:
        p = p.replace(n_elements=n_elements)
    return Model(p)


SHORT_HELP = {
    "demo": "A short tour on a preset: droop, bend, IK, locked load case.",
    "fk": "Forward kinetostatics: T, p, tip load → shape and tip.",
    "ik": "Inverse kinetostatics: target tip → tensions and shape.",
    "locked": "Locked tendon lengths, p, load → shape, tensions, slack.",
    "compliance": "Tip compliance and stiffness at an FK state.",
    "params": "Print a preset as a TOML parameter file.",
}


def register(app: typer.Typer) -> None:
    """Attach this module's commands to the root ``bellows`` app."""
    for fn in (demo, fk, ik, locked, compliance, params):
        app.command(fn.__name__, short_help=SHORT_HELP[fn.__name__])(fn)
