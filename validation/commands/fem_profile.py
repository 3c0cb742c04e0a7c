"""``bellows fem profile --export wall.csv``: a design's built-in wall profile written as a profile table.

The table lists the inner and outer outline with their slopes ``dr/dz`` at every lattice row of the chosen mesh
levels (and filling rows at most ``--spacing-mm`` apart), so that a design that names it as ``profile_file``
meshes and solves as the built-in design to round-off (:mod:`fem_reference.profile_export`; docs/fem.md §3b).
A starting point for a profile of one's own, and the check that the table path adds no error of its own.

Mounted by :mod:`validation.commands.fem` as ``bellows fem profile``.
"""

from __future__ import annotations

import os
from pathlib import Path

import typer

from ancf import clitools
from ancf.errors import InputError, OutputExistsError

__all__ = ["profile"]

#: largest gap between table rows [mm]: the mesh rows are exact whatever it is; beyond 10 mm the spline between
#: them is no longer a picture of the profile
SPACING_MM = clitools.number_range(0.0, 10.0, low_open=True, unit="mm")


def _levels(text: str) -> list[str]:
    from fem_reference.mesh import MESH_LEVELS

    names = list(MESH_LEVELS) if text.strip() == "all" else [t.strip() for t in text.split(",") if t.strip()]
    bad = [n for n in names if n not in MESH_LEVELS]
    if bad or not names:
        raise InputError(f"--mesh must be 'all' or a comma-separated list of {', '.join(MESH_LEVELS)}, got {text!r}")
    return names


def profile(
    export: Path = typer.Option(..., help="CSV file to write (outline,z_mm,r_mm,dr_dz)"),
    design: str = typer.Option("paper", help="design: a preset name or a design .toml file (a built-in profile)"),
    mesh: str = typer.Option("all", help="mesh levels whose rows the table lists exactly: 'all' or a "
                                         "comma-separated list of coarse, medium, reference"),
    spacing_mm: float = typer.Option(0.1, callback=SPACING_MM,
                                     help=f"largest gap between rows [mm], {SPACING_MM.text}"),
    force: bool = typer.Option(False, "--force", help="overwrite --export if it exists"),
):
    """Write the design's built-in wall profile as a profile table exact at the meshes' rows."""
    from fem_reference.profile import write_profile_csv
    from fem_reference.profile_export import export_profile
    from validation.reference.designs import load_design

    export = Path(export).expanduser()
    if export.suffix.lower() != ".csv":
        raise InputError(f"--export writes a CSV table: give a file name ending in .csv, got {str(export)!r}")
    if export.exists() and not force:
        raise OutputExistsError(f"{export} exists; add --force to overwrite it")
    if not export.parent.is_dir():
        raise InputError(f"--export: the folder {export.parent} does not exist")
    levels = _levels(mesh)
    geo, _ = load_design(design)
    prof = export_profile(geo, levels, spacing_mm * 1e-3)
    tmp = export.with_name(f".{export.name}.tmp{os.getpid()}")
    comment = (f"design {design}: built-in profile, exact (points and slopes) at every row of the meshes "
               f"{', '.join(levels)}; rows at most {spacing_mm:g} mm apart")
    write_profile_csv(prof, tmp, comments=(comment,))
    os.replace(tmp, export)
    typer.echo(f"wrote {export}: {len(prof.z_inner)} points per outline (length {geo.length * 1e3:g} mm), exact at "
               f"the rows of the {', '.join(levels)} meshes")
