"""``bellows log show|export``: inspect the run logs that ``bellows control`` writes.

(``bellows control`` itself runs a controller on a rig, so it lives above both packages, in
:mod:`validation.commands.control`: ``hardware`` never imports ``controller``.)  Handled errors are one ``error:``
line with exit status 2 (:func:`validation.commands.main.main`); an existing CSV or ``.pvd`` is replaced only with
``--force``.
"""

from __future__ import annotations

import pathlib
from typing import Optional

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
               csv: Optional[pathlib.Path] = typer.Option(None, "--csv", help="CSV file to write (units in the "
                                                          "headers)"),
               pvd: Optional[pathlib.Path] = typer.Option(None, "--pvd", help="ParaView collection (.pvd) to write: "
                                                          "the measured tip's trajectory over time, its frames in "
                                                          "the folder of the same name beside it"),
               max_frames: int = typer.Option(200, "--max-frames", min=2, max=100_000, help="most frames of the "
                                              "--pvd time series (spread evenly over the samples)"),
               force: bool = typer.Option(False, "--force", help="overwrite existing output files")):
    """Export the samples of a run log as CSV (one column per component, unit in each header) and/or as a
    ParaView time series of the tip trajectory (the log holds the measured tip, not the rod's shape).  A
    log left by a killed writer has its open-for-write flags cleared first (like 'h5clear -s')."""
    from ancf.errors import InputError
    from ancf.outputs import prepare_output_file
    from ancf.paraview import prepare_pvd
    from hardware.runlog import export_csv, recover_crashed_log
    from hardware.runlog_paraview import export_pvd
    if csv is None and pvd is None:
        raise InputError("give --csv FILE.csv and/or --pvd FILE.pvd")
    if csv is not None:                              # both outputs checked before either is written
        prepare_output_file(csv, force=force, suffixes=(".csv",))
    if pvd is not None:
        prepare_pvd(pvd, force=force)
    _recover(path, recover_crashed_log)
    outs = ([export_csv(path, csv, force=force)] if csv is not None else []) + \
        ([export_pvd(path, pvd, force=force, max_frames=max_frames)] if pvd is not None else [])
    typer.echo("wrote " + " and ".join(str(o) for o in outs))
