"""The ``bellows`` console command: one entry point, subcommands from each package.

``bellows demo | fk | ik | locked | params`` come from :mod:`ancf.cli`; ``bellows fem ...`` from
:mod:`validation.commands.fem`.  Every subcommand's package is imported here unconditionally: a missing dependency
is an install error to see at once, not a subcommand that silently disappears.  Every handled error (a product error or a usage error) is
printed as one ``error: …`` line and exits with status 2 (:mod:`ancf.clitools`); nothing is returned
silently wrong.
"""

from __future__ import annotations

import typer

import ancf
from ancf import cli as ancf_cli
from ancf import clitools
from ancf.dynamics import cli as dynamics_cli
from hardware import cli as rig_cli
from validation.commands import control as control_cli
from validation.commands import experiment as experiment_cli
from validation.commands import identify as identify_cli
from validation.commands.fem import app as fem_app
from validation.commands.paper import app as paper_app

app = typer.Typer(help="Tendon-pneumatic bellows actuators: ANCF model, FEM reference, compliance control.",
                  no_args_is_help=True, add_completion=False, pretty_exceptions_enable=False,
                  rich_markup_mode=None,   # help texts state units as "[kPa]": no markup parsing
                  context_settings=clitools.HELP_SETTINGS)   # whole command summaries in --help


def _print_version(value: bool) -> None:
    if value:
        typer.echo(f"bellows {ancf.distribution_version()}")
        raise typer.Exit()


@app.callback()
def _root(version: bool = typer.Option(False, "--version", callback=_print_version, is_eager=True,
                                       help="Print the installed version (bellows <version>) and exit.")) -> None:
    pass      # no docstring: the help text is the app's own


ancf_cli.register(app)                                       # demo | fk | ik | locked | compliance | params
dynamics_cli.register(app)                                   # modes | simulate
app.add_typer(paper_app, name="paper", help="Reproduce the paper's studies, beside the paper's numbers.")
identify_cli.register(app)                                   # identify | validate | report | calibrate
app.add_typer(fem_app, name="fem", help="3-D hyperelastic FEM reference of the bellows.")
app.command("control")(control_cli.control)                  # a controller on a rig (above both)
experiment_cli.register(app)                                 # an identification experiment on a rig
app.add_typer(rig_cli.log_app, name="log", help="Inspect run logs: show | export.")


def main(args=None) -> None:
    """Console entry point: runs ``app`` under the one-line error contract (exit status 2)."""
    clitools.run(app, args)


if __name__ == "__main__":
    main()
