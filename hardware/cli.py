"""``bellows log show|export``: inspect the run logs that ``bellows control`` writes.

(``bellows control`` itself runs a controller on a rig, so it lives above both packages, in
:mod:`validation.commands.control`: ``hardware`` never imports ``controller``.)  Handled errors are one ``error:``
line with exit status 2 (:func:`validation.commands.main.main`); an existing CSV is replaced only with ``--force``.
"""

from __future__ import annotations

import pathlib

import typer

log_app = typer.Typer(help="Inspect run logs (HDF5) written by 'bellows control'.", no_args_is_help=True,
                      add_completion=False, rich_markup_mode=None)


@log_app.command("show")
def log_show(path: pathlib.Path = typer.Argument(..., help="run log (.h5)")):
    """Summary of a run log: rig, controller, samples, errors, static states, last events.  A log left by a
    killed writer has its open-for-write flags cleared (like 'h5clear -s') so any HDF5 reader opens it."""
    from hardware.runlog import recover_crashed_log, summary
    _recover(path, recover_crashed_log)
    typer.echo(summary(path))


def _recover(path, recover) -> None:
    note = recover(path) if path.is_file() else None
    if note:
        typer.echo(f"note: {note}", err=True)


@log_app.command("export")
def log_export(path: pathlib.Path = typer.Argument(..., help="run log (.h5)"),
               csv: pathlib.Path = typer.Option(..., "--csv", help="CSV file to write (units in the headers)"),
               force: bool = typer.Option(False, "--force", help="overwrite an existing CSV file")):
    """Export the samples of a run log as CSV (one column per component, unit in each header).  A log left by
    a killed writer has its open-for-write flags cleared first (like 'h5clear -s')."""
    from hardware.runlog import export_csv, recover_crashed_log
    _recover(path, recover_crashed_log)
    out = export_csv(path, csv, force=force)
    typer.echo(f"wrote {out}")
