"""``bellows fem …``: the command line of the FEM reference (``typer``); :mod:`validation.commands.main` mounts
``app`` as ``bellows fem``.

Examples::

    bellows fem solve --pressure-kpa 30 --tensions-n 2,0,0 --tip-force-n 0,0,-0.49 --mesh coarse --out out/
    bellows fem solve --json --compliance          # JSON summary on stdout (SI units)
    bellows fem solve --design my_bellows.toml --tensions-n 2,0,0 --pressure-kpa 30   # a design file of one's own
    bellows fem info                               # preset values and the GUESSED table
    bellows fem profile --export wall.csv          # the built-in wall profile as a table (exact at the mesh rows)

It lives in :mod:`validation` (which may use both :mod:`ancf` and :mod:`fem_reference`) so that
:mod:`fem_reference` itself needs no other package of the product.

Rules (docs/errors.md): every option given is used or rejected (``--mu-mpa 0`` is an error, not the
preset's value); ``--out`` is checked before the mesh is built and existing results are only replaced with
``--force``; loads outside the model's operating limits are rejected unless ``--no-limits``; every handled
error prints one ``error:`` line and exits with status 2.
"""

from __future__ import annotations

import json
import sys
import time
from enum import Enum
from pathlib import Path

import numpy as np
import typer

from ancf import clitools
from ancf.errors import InputError
from ancf.outputs import atomic_write_text, prepare_output_dir
from ancf.textfmt import one_of, vector
from fem_reference.assembly import ELEMENTS
from fem_reference.mesh import MESH_LEVELS
from fem_reference.model import LINEAR_SOLVERS, OperatingLimits
from validation.commands.fem_profile import profile as _profile
# the design presets of ``--preset``: the names load_design accepts (one registry for --preset and --design)
from validation.reference.designs import PRESETS, load_design

app = typer.Typer(help="scikit-fem 3-D hyperelastic reference model of the bellows actuator.",
                  no_args_is_help=True, add_completion=False, pretty_exceptions_enable=False,
                  rich_markup_mode=None, context_settings=clitools.HELP_SETTINGS)


# the choices of --mesh and --preset are generated from the registries, so --help lists exactly what is accepted
MeshChoice = Enum("MeshChoice", {name: name for name in MESH_LEVELS}, type=str)
ElementChoice = Enum("ElementChoice", {name: name for name in ELEMENTS}, type=str)
PresetChoice = Enum("PresetChoice", {name: name for name in PRESETS}, type=str)


def _floats(text: str, n: int, name: str) -> list[float]:
    try:
        vals = [float(v) for v in text.split(",")]
    except ValueError:
        raise InputError(f"{name}: expected {n} comma-separated numbers, got {text!r}") from None
    if len(vals) != n or not all(np.isfinite(vals)):
        raise InputError(f"{name}: expected {n} comma-separated finite numbers, got {text!r}")
    return vals


def _locked(text: str | None) -> list[float | None] | None:
    if text is None:
        return None
    parts = text.split(",")
    if len(parts) != 3:
        raise InputError("--locked-lengths-mm needs 3 comma-separated entries (empty allowed)")
    try:
        vals = [float(p) * 1e-3 if p.strip() else None for p in parts]
    except ValueError:
        raise InputError(f"--locked-lengths-mm: expected numbers or empty entries, got {text!r}") from None
    if any(v is not None and not (np.isfinite(v) and v > 0) for v in vals):
        raise InputError(f"--locked-lengths-mm: lengths must be positive, got {text!r}")
    return vals


# option ranges, checked while the command line is parsed (ancf.clitools: a value outside is a usage error, exit 2)
#: moduli [MPa]: positive, at most 1 TPa (stiffer than any solid; the wall is a rubber of a few MPa)
MODULUS_MPA = clitools.number_range(0.0, 1e6, low_open=True, unit="MPa")
MAX_TIME_S = clitools.number_range(0.0, low_open=True, unit="s")


def _modulus(value_mpa: float | None, default_pa: float, option: str) -> float:
    """A given modulus is used (and must be positive); only an absent one takes the preset's value."""
    if value_mpa is None:
        return default_pa
    if not (np.isfinite(value_mpa) and value_mpa > 0):
        raise InputError(f"{option} must be a positive modulus in MPa, got {value_mpa:g}")
    return value_mpa * 1e6


def _geometry(preset):
    return load_design(preset.value if isinstance(preset, Enum) else str(preset))[0]


@app.command(short_help="Solve one static load case: tip pose, tensions, cable lengths, timings.")
def solve(
    pressure_kpa: float = typer.Option(0.0, callback=clitools.FINITE,
                                       help="cavity gauge pressure [kPa] (within "
                                            f"{OperatingLimits.pressure_min / 1e3:g} to "
                                            f"{OperatingLimits.pressure_max / 1e3:g} kPa unless --no-limits)"),
    tensions_n: str = typer.Option("0,0,0", help="tendon tensions [N], comma-separated (θ = 0, 120°, 240°)"),
    tip_force_n: str = typer.Option("0,0,0", help="dead tip force (x,y,z) [N], world frame"),
    locked_lengths_mm: str | None = typer.Option(
        None, help="lock tendons at these cable lengths [mm], e.g. '159.5,,' (empty = tension mode)"),
    gravity: bool = typer.Option(True, help="include the dead weight (g = -9.81 m/s² along z)"),
    mesh: MeshChoice = typer.Option(MeshChoice("coarse"), help="mesh level"),
    element: ElementChoice = typer.Option(ElementChoice("mixed"), help="wall element: mixed (u–p, locking-free) "
                                          "or displacement (Hex27 alone; locks in bending, docs/fem.md §3a)"),
    preset: PresetChoice | None = typer.Option(None, help="geometry preset (default: paper)"),
    design: str | None = typer.Option(None, "--design", help="a bellows design of one's own instead of --preset: a "
                                      "design .toml file (wall profile, tendons, material; docs/data-formats.md) or a "
                                      "design preset name"),
    mu_mpa: float | None = typer.Option(None, callback=MODULUS_MPA,
                                        help=f"shear modulus, {MODULUS_MPA.text} (default: the design's)"),
    kappa_mpa: float | None = typer.Option(None, callback=MODULUS_MPA,
                                           help=f"bulk modulus, {MODULUS_MPA.text}, above 2/3 of the shear modulus "
                                                "(default: the design's)"),
    solver: str = typer.Option("auto", help=f"linear solver {one_of(LINEAR_SOLVERS)} (a library's solver where it "
                                            "is installed; auto: pardiso if installed, else splu)"),
    compliance: bool = typer.Option(False, help="also compute the 3×3 tip compliance (tension and locked)"),
    out: Path | None = typer.Option(None, help="output directory (result.json, result.vtu)"),
    png: bool = typer.Option(False, help="render result.png into --out (headless pyvista)"),
    force: bool = typer.Option(False, "--force", help="overwrite results already in --out"),
    no_limits: bool = typer.Option(False, "--no-limits", help="analyse loads outside the model's operating "
                                   "limits (pressure, tensions, tip force) instead of rejecting them"),
    max_time_s: float | None = typer.Option(None, callback=MAX_TIME_S,
                                            help=f"give up after this many seconds of solving, {MAX_TIME_S.text}"),
    json_out: bool = typer.Option(False, "--json", help="print the JSON summary on stdout"),
):
    """Solve one static load case and report tip pose, tensions, cable lengths and timings."""
    from rich.console import Console
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    from fem_reference.material import Material
    from fem_reference.model import BellowsModel

    console = Console(stderr=True)
    if png and out is None:
        raise InputError("--png writes result.png into --out: give --out")
    if out is not None:   # checked before any work: a bad --out fails now, not after the solve
        files = ["result.json", "result.vtu"] + (["result.png"] if png else [])
        out = prepare_output_dir(out, files, force=force)
    T = _floats(tensions_n, 3, "--tensions-n")
    if min(T) < 0:
        raise InputError(f"--tensions-n must be >= 0 N (a cable cannot push), got {tensions_n!r}")
    F = _floats(tip_force_n, 3, "--tip-force-n")
    if not np.isfinite(pressure_kpa):
        raise InputError(f"--pressure-kpa must be finite, got {pressure_kpa}")
    locked = _locked(locked_lengths_mm)
    if not no_limits:     # the loads, before minutes of meshing and solving
        OperatingLimits().check_loads(T, pressure_kpa * 1e3, F, [v is not None for v in locked or [None] * 3])
    geometry, base, name, source = _design(preset, design)
    mu, kappa = _modulus(mu_mpa, base.mu, "--mu-mpa"), _modulus(kappa_mpa, base.kappa, "--kappa-mpa")
    if not kappa > 2 * mu / 3:          # a positive Poisson ratio (Material's own rule, in the options' terms)
        raise InputError(f"--kappa-mpa must exceed 2/3 of --mu-mpa (a Poisson ratio > 0), got {kappa / 1e6:g} MPa and "
                         f"{mu / 1e6:g} MPa (an option not given is the preset's)")
    mat = Material.neo_hookean(mu=mu, kappa=kappa, density=base.density)
    with console.status(f"building {mesh.value} mesh and assembler ..."):
        model = BellowsModel(geometry, mat, mesh.value, linear_solver=solver, element=element.value)
    console.print(f"[bold]{model.n_dofs}[/] reduced DOFs, {model.bmesh.n_elements} Hex2 elements")
    plain = not console.is_terminal      # a log file or a pipe: one plain line per load step, as it happens

    def line(d) -> str:
        return f"step {d['step']}: {d['iterations']} it, |r| {d['residuals'][-1]:.1e}"
    with Progress(TextColumn("load"), BarColumn(), TextColumn("λ = {task.completed:.3f}"),
                  TextColumn("{task.fields[info]}"), TimeElapsedColumn(), console=console,
                  transient=False, disable=plain) as prog:
        task = prog.add_task("solve", total=1.0, info="")
        t_start = time.perf_counter()

        def cb(d):
            if plain:
                print(f"load λ = {d['lam']:.3f}, {line(d)}, {time.perf_counter() - t_start:.0f} s",
                      file=sys.stderr, flush=True)
            prog.update(task, completed=d["lam"], info=line(d))

        res = model.solve(tensions=T, pressure=pressure_kpa * 1e3, tip_force=F, gravity=gravity,
                          locked_lengths=locked, progress=cb, check_limits=not no_limits,
                          time_limit_s=max_time_s)
    summary = res.summary()
    summary.update(element=element.value, model=model_info(name, mu_mpa, kappa_mpa, source=source))
    if compliance:
        summary["tip_compliance_tension_m_per_N"] = model.tip_compliance(res, "tension").tolist()
        summary["tip_compliance_locked_m_per_N"] = model.tip_compliance(res, "locked").tolist()
    if out is not None:
        atomic_write_text(out / "result.json", json.dumps(summary, indent=2))
        res.save_vtu(out / "result.vtu")
        if png:
            from fem_reference.render import render_result

            render_result(res, out / "result.png")
        console.print(f"wrote {out}/result.json, result.vtu" + (", result.png" if png else ""))
    if json_out:
        typer.echo(json.dumps(summary))
    else:
        for line in [summary["model"]["description"], *summary_lines(res)]:
            console.print(line, markup=False, highlight=False, soft_wrap=True)     # a log line is not cut


def _design(preset, design: str | None) -> tuple:
    """(geometry, material, name, source) of ``--preset`` or ``--design`` (not both): a design file is read by
    :func:`validation.reference.designs.load_design` (its errors name the key)."""
    if design is not None and preset is not None:
        raise InputError("give --preset or --design, not both (--design takes a design file or a design preset name)")
    if design is None:
        name = preset.value if isinstance(preset, Enum) else str(preset or "paper")
        return (*load_design(name), name, "design preset")
    geometry, material = load_design(design)
    if design in PRESETS:
        return geometry, material, design, "design preset"
    return geometry, material, Path(design).name, f"design file {design}"


def model_info(design: str, mu_mpa: float | None = None, kappa_mpa: float | None = None, *,
               source: str = "design preset") -> dict:
    """Which model and which parameter set produced a result: ``{"kind": "FEM reference", "parameters": the
    bellows design, "source": "design preset", "material": "preset" | the moduli given, "description": one
    line}``, e.g. "FEM reference (3-D hyperelastic), bellows design 'paper' (wall geometry and material)" — the
    first line of ``bellows fem solve``'s text and its JSON's ``model`` field."""
    given = [f"{nm} = {v:g} MPa" for nm, v in (("shear modulus", mu_mpa), ("bulk modulus", kappa_mpa))
             if v is not None]
    material = "and material" if not given else f"and material, {', '.join(given)} given"
    where = "" if source == "design preset" else f", {source}"
    return {"kind": "FEM reference", "parameters": design, "source": source,
            "material": ("preset" if source == "design preset" else "design file") if not given
            else {"mu_MPa": mu_mpa, "kappa_MPa": kappa_mpa},
            "description": f"FEM reference (3-D hyperelastic), bellows design '{design}' (wall geometry {material}"
                           f"{where})"}


def summary_lines(res) -> list[str]:
    """The text summary of a solved load case: vectors as ``(x, y, z) unit``, never a numpy repr."""
    st = res.stats
    return [f"tip position: {vector(res.tip_position, 'mm', 1e3, 2)}",
            f"cap rotation vector: {vector(np.degrees(res.cap_rotation_vector), 'deg', digits=3)}",
            f"tensions: {vector(res.tensions, 'N', digits=3)}; cable lengths: {vector(res.tendon_lengths, 'mm', 1e3, 2)}",
            f"{res.iterations} Newton iterations in {len(st.steps)} load steps, {st.t_total:.2f} s "
            f"(linear solver {st.t_linear:.2f} s, assembly {st.t_assembly:.2f} s)"]


@app.command()
def info(preset: PresetChoice = typer.Option(PresetChoice("paper"), help="geometry preset")):
    """Print a preset's geometry and the table of guessed parameters."""
    from rich.console import Console
    from rich.table import Table

    from fem_reference import presets

    c = Console()
    c.print(_geometry(preset))
    t = Table("parameter", "value", "unit", "why (GUESSED)")
    for k, (v, u, why) in presets.GUESSED.items():
        t.add_row(k, str(v), u, why)
    c.print(t)


def main():  # pragma: no cover
    clitools.run(app, prog_name="python -m validation.commands.fem")


if __name__ == "__main__":  # pragma: no cover
    main()


app.command("profile", short_help="Write a design's built-in wall profile as a table, exact at the mesh rows.")(_profile)
