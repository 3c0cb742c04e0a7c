"""Command line of the FEM reference (``typer``); the product mounts ``app`` as ``bellows fem``.

Examples::

    bellows fem solve --pressure-kpa 30 --tensions-n 2,0,0 --tip-force-n 0,0,-0.49 --mesh coarse --out out/
    bellows fem solve --json --compliance          # JSON summary on stdout (SI units)
    bellows fem info                               # preset values and the GUESSED table

Standalone: ``python -m fem_reference.cli solve ...``.
"""

from __future__ import annotations

import json
from enum import Enum
from pathlib import Path

import numpy as np
import typer

from ancf.errors import BellowsError

app = typer.Typer(help="scikit-fem 3-D hyperelastic reference model of the bellows actuator.",
                  no_args_is_help=True, add_completion=False)


class MeshChoice(str, Enum):
    coarse = "coarse"
    medium = "medium"
    reference = "reference"


class PresetChoice(str, Enum):
    paper = "paper"
    paper_deep = "paper-deep"
    tube = "tube"


def _floats(text: str, n: int, name: str) -> list[float]:
    try:
        vals = [float(v) for v in text.split(",")]
    except ValueError:
        raise typer.BadParameter(f"{name}: expected {n} comma-separated numbers, got {text!r}")
    if len(vals) != n:
        raise typer.BadParameter(f"{name}: expected {n} comma-separated numbers, got {text!r}")
    return vals


def _geometry(preset: PresetChoice):
    from . import presets

    if preset == PresetChoice.paper:
        return presets.paper_bellows()
    if preset == PresetChoice.paper_deep:
        return presets.paper_bellows("deep")
    return presets.straight_tube_test()


@app.command()
def solve(
    pressure_kpa: float = typer.Option(0.0, help="cavity gauge pressure [kPa]"),
    tensions_n: str = typer.Option("0,0,0", help="tendon tensions [N], comma-separated (θ = 0, 120°, 240°)"),
    tip_force_n: str = typer.Option("0,0,0", help="dead tip force (x,y,z) [N], world frame"),
    locked_lengths_mm: str | None = typer.Option(
        None, help="lock tendons at these cable lengths [mm], e.g. '159.5,,' (empty = tension mode)"),
    gravity: bool = typer.Option(True, help="include the dead weight (g = -9.81 m/s² along z)"),
    mesh: MeshChoice = typer.Option(MeshChoice.coarse, help="mesh level"),
    preset: PresetChoice = typer.Option(PresetChoice.paper, help="geometry preset"),
    mu_mpa: float | None = typer.Option(None, help="shear modulus [MPa] (default: preset)"),
    kappa_mpa: float | None = typer.Option(None, help="bulk modulus [MPa] (default: preset)"),
    solver: str = typer.Option("auto", help="linear solver: auto | pardiso | splu"),
    compliance: bool = typer.Option(False, help="also compute the 3×3 tip compliance (tension and locked)"),
    out: Path | None = typer.Option(None, help="output directory (result.json, result.vtu)"),
    png: bool = typer.Option(False, help="render result.png into --out (headless pyvista)"),
    json_out: bool = typer.Option(False, "--json", help="print the JSON summary on stdout"),
):
    """Solve one static load case and report tip pose, tensions, cable lengths and timings."""
    from rich.console import Console
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    from . import presets
    from .material import Material
    from .model import BellowsModel

    console = Console(stderr=True)
    T = _floats(tensions_n, 3, "--tensions-n")
    F = _floats(tip_force_n, 3, "--tip-force-n")
    locked = None
    if locked_lengths_mm is not None:
        parts = locked_lengths_mm.split(",")
        if len(parts) != 3:
            raise typer.BadParameter("--locked-lengths-mm needs 3 comma-separated entries (empty allowed)")
        locked = [float(p) * 1e-3 if p.strip() else None for p in parts]
    base = presets.paper_material()
    mat = Material.neo_hookean(mu=(mu_mpa * 1e6 if mu_mpa else base.mu),
                               kappa=(kappa_mpa * 1e6 if kappa_mpa else base.kappa), density=base.density)
    try:
        with console.status(f"building {mesh.value} mesh and assembler ..."):
            model = BellowsModel(_geometry(preset), mat, mesh.value, linear_solver=solver)
        console.print(f"[bold]{model.n_dofs}[/] reduced DOFs, {model.bmesh.n_elements} Hex2 elements")
        with Progress(TextColumn("load"), BarColumn(), TextColumn("λ = {task.completed:.3f}"),
                      TextColumn("{task.fields[info]}"), TimeElapsedColumn(), console=console,
                      transient=False) as prog:
            task = prog.add_task("solve", total=1.0, info="")

            def cb(d):
                prog.update(task, completed=d["lam"],
                            info=f"step {d['step']}: {d['iterations']} it, |r| {d['residuals'][-1]:.1e}")

            res = model.solve(tensions=T, pressure=pressure_kpa * 1e3, tip_force=F, gravity=gravity,
                              locked_lengths=locked, progress=cb)
        summary = res.summary()
        if compliance:
            summary["tip_compliance_tension_m_per_N"] = model.tip_compliance(res, "tension").tolist()
            summary["tip_compliance_locked_m_per_N"] = model.tip_compliance(res, "locked").tolist()
    except BellowsError as e:
        console.print(f"[red]error:[/] {e}")
        raise typer.Exit(code=1)
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        (out / "result.json").write_text(json.dumps(summary, indent=2))
        res.save_vtu(out / "result.vtu")
        if png:
            from .render import render_result

            render_result(res, out / "result.png")
        console.print(f"wrote {out}/result.json, result.vtu" + (", result.png" if png else ""))
    if json_out:
        typer.echo(json.dumps(summary))
    else:
        tip = 1e3 * res.tip_position
        console.print(f"tip position (mm): {np.array2string(tip, precision=3)}")
        console.print(f"cap rotation vector (deg): {np.array2string(np.degrees(res.cap_rotation_vector), precision=3)}")
        console.print(f"tensions (N): {np.array2string(res.tensions, precision=4)}  "
                      f"cable lengths (mm): {np.array2string(1e3 * res.tendon_lengths, precision=4)}")
        st = res.stats
        console.print(f"{res.iterations} Newton iterations in {len(st.steps)} load steps, {st.t_total:.2f} s "
                      f"(linear solver {st.t_linear:.2f} s, assembly {st.t_assembly:.2f} s)")


@app.command()
def info(preset: PresetChoice = typer.Option(PresetChoice.paper, help="geometry preset")):
    """Print a preset's geometry and the table of guessed parameters."""
    from rich.console import Console
    from rich.table import Table

    from . import presets

    c = Console()
    c.print(_geometry(preset))
    t = Table("parameter", "value", "unit", "why (GUESSED)")
    for k, (v, u, why) in presets.GUESSED.items():
        t.add_row(k, str(v), u, why)
    c.print(t)


def main():  # pragma: no cover
    app()


if __name__ == "__main__":  # pragma: no cover
    main()
