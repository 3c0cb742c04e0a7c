"""Printed tables of the paper's studies (rich), our numbers beside the paper's (no computation)."""

from __future__ import annotations

import json

import numpy as np

from ancf.export import to_jsonable

from validation.paper.numbers import PAPER
from validation.paper.workspace_volume import MODES


def print_workspace(res: dict, console=None) -> None:
    """Rich table: our workspace numbers beside the paper's."""
    from rich.console import Console
    from rich.table import Table

    console = console or Console(width=130)
    t = Table(title="Workspace (Sec. IV-A, Fig. 4): convex-hull volume of the tip cloud")
    for c in ("quantity", "ours", "paper"):
        t.add_column(c, justify="left" if c == "quantity" else "right")
    md = res["modes"]
    t.add_row("samples per mode", f"{res['samples']:,}", f"{PAPER['workspace']['samples_per_mode']:,}")
    for mode in MODES:
        t.add_row(f"{mode} volume (cm³)", f"{md[mode]['volume_cm3']:.2f}", "–")
        t.add_row(f"{mode} collapsed samples (law past its limit)", f"{md[mode]['collapsed']}", "–")
        t.add_row(f"{mode} failed FK solves (near the law's limit)",
                  f"{md[mode]['failures']} ({md[mode].get('failures_near_limit', 0)})", "–")
    t.add_row("TPHD vs TD", f"{res['increase_percent']:+.1f} %", f"{PAPER['workspace']['increase_percent']:+.1f} %")
    se = res.get("sampling_error")
    if se:
        a, b = se["halves_increase_percent"]
        t.add_row("  on two disjoint halves (sampling error)",
                  f"{a:+.1f} / {b:+.1f} % (± {se['half_difference_percent']:.1f})",
                  "–")
    t.add_row("TD tips inside TPHD hull", f"{res['inside_fraction'] * 100:.1f} %", "–")
    tm = res["timing"]
    t.add_row("wall time (s)", f"{tm['wall_s']:.1f} ({tm['backend']}, {tm['workers']} workers)", "–")
    t.add_row("time per FK (ms, worker wall / CPU)",
              f"{tm['per_sample_ms']:.2f} / {tm.get('per_sample_cpu_ms', float('nan')):.2f}", "–")
    console.print(t)



def print_stiffness(res: dict, console=None) -> None:
    from rich.console import Console
    from rich.table import Table

    console = console or Console(width=130)
    cv = res["curves_N_per_m"]
    t = Table(title=f"Stiffness along z, {res['mass_kg'] * 1e3:g} g payload (Sec. V-C, Fig. 9), k in N/m")
    cols = ["p (kPa)", f"T{res['tendon'] + 1} (N)", "const NL", "const lin", "locked NL", "locked exact"]
    cols += [f"locked {m}" for m in res["methods"] if m != "exact"]
    cols += ["locked/const NL", "paper"]
    for c in cols:
        t.add_column(c, justify="right")
    ratio = res["ratio_locked_over_constant"]["nonlinear"]
    for i, p in enumerate(res["pressures_Pa"]):
        for j, T1 in enumerate(res["tensions_N"]):
            vals = [cv["constant_nonlinear"][i, j], cv["constant_linear"][i, j], cv["locked_nonlinear"][i, j],
                    cv.get("locked_linear_exact", np.full_like(ratio, np.nan))[i, j]]
            vals += [cv[f"locked_linear_{m}"][i, j] for m in res["methods"] if m != "exact"]
            t.add_row(f"{p / 1e3:g}", f"{T1:g}", *[f"{v:.1f}" for v in vals], f"{ratio[i, j]:.2f}", "≈ 2")
    console.print(t)
    s = res["summary"]
    console.print(f"mean locked/constant ratio: nonlinear {s['mean_ratio_nonlinear']:.2f}, "
                  + ", ".join(f"linear {m} {s[f'mean_ratio_linear_{m}']:.2f}" for m in res["methods"])
                  + f"; paper: about {s['paper_ratio']:g}.  Failed solves: {res['failures']}.")



def print_control_study(name: str, res: dict, console=None) -> None:
    """Best-effort table of a controller study's scalar results beside the paper's (the result layout
    belongs to :mod:`validation.paper.control`)."""
    from rich.console import Console
    from rich.markup import escape
    from rich.table import Table

    console = console or Console(width=130)
    paper = PAPER.get(name, {})
    if isinstance(res.get("table"), str):     # the study's own comparison table (ours beside the paper's)
        console.print(f"[bold]{escape(name)}[/bold] (controller study)")
        console.print(escape(res["table"]), highlight=False)
        return
    t = Table(title=f"{name} (controller study)")
    t.add_column("result", justify="left")
    t.add_column("ours", justify="right")
    t.add_column("paper", justify="right")

    def walk(prefix, d, pp):
        for k, v in d.items():
            key = f"{prefix}{k}"
            pv = pp.get(k) if isinstance(pp, dict) else None
            if isinstance(v, dict):
                walk(key + ".", v, pv if isinstance(pv, dict) else {})
            elif isinstance(v, (int, float, np.floating, np.integer)) and not isinstance(v, bool):
                t.add_row(escape(key), f"{float(v):.6g}", "" if pv is None or isinstance(pv, dict) else f"{pv:g}")
    walk("", res, paper)
    console.print(t)
    if paper:
        console.print(escape(f"paper: {json.dumps(to_jsonable(paper))}"))


def _fmt(v) -> str:
    if v is None:
        return "–"
    if isinstance(v, str):
        return v
    if isinstance(v, bool):
        return "yes" if v else "no"
    v = float(v)
    if not np.isfinite(v):
        return "nan"
    return f"{v:.3g}" if abs(v) < 1e4 else f"{v:.0f}"


def print_comparison(res: dict, console=None) -> None:
    """One row per headline, the paper's value, then one column per preset (✓ reproduced, ✗ missed)."""
    from rich.console import Console
    from rich.markup import escape
    from rich.table import Table

    console = console or Console(width=160)
    t = Table(title="Headline numbers of the paper, by preset")
    t.add_column("headline", justify="left")
    t.add_column("paper", justify="right")
    for p in res["presets"]:
        t.add_column(p["preset"], justify="right")
    for k, label in res["labels"].items():
        cells = []
        for p in res["presets"]:
            v = p["numbers"].get(k)
            mark = {True: " ✓", False: " ✗"}.get(p["verdicts"].get(k), "")
            cells.append(escape(_fmt(v)) + mark)
        if all(c == "–" for c in cells):
            continue
        t.add_row(escape(label), escape(_fmt(res["paper"].get(k))), *cells)
    t.add_row("[bold]reproduced[/bold]", "", *[f"{p['reproduced']} of {p['judged']}" for p in res["presets"]])
    console.print(t)
    for p in res["presets"]:
        for study, msg in p["notes"].items():
            console.print(f"[yellow]{escape(p['preset'])} {escape(study)}: {escape(msg)}[/yellow]")
