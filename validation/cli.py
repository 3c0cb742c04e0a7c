"""The ``bellows`` console command: one entry point, subcommands from each package.

``bellows demo | fk | ik | locked | params`` come from :mod:`ancf.cli`; ``bellows fem ...`` from
:mod:`fem_reference.cli` (needs scikit-fem).  Every handled error (a product error or a usage error) is
printed as one ``error: …`` line and exits with status 2 (:mod:`ancf.clitools`); nothing is returned
silently wrong.
"""

from __future__ import annotations

import typer

from ancf import cli as ancf_cli
from ancf import clitools

app = typer.Typer(help="Tendon-pneumatic bellows actuators: ANCF model, FEM reference, compliance control.",
                  no_args_is_help=True, add_completion=False, pretty_exceptions_enable=False,
                  rich_markup_mode=None,   # help texts state units as "[kPa]": no markup parsing
                  context_settings=clitools.HELP_SETTINGS)   # whole command summaries in --help
ancf_cli.register(app)

try:  # the paper's studies (workspace, stiffness, Table I, loading)
    from validation.paper_cli import app as paper_app
    app.add_typer(paper_app, name="paper", help="Reproduce the paper's studies, beside the paper's numbers.")
except ImportError:  # pragma: no cover - during development of the studies
    pass

try:  # identification, validation against the FEM, report, calibration (needs scikit-fem for the FEM)
    from validation import identify_cli
    identify_cli.register(app)
except ImportError:  # pragma: no cover - depends on the installation
    pass

try:  # the FEM reference is optional at run time (scikit-fem)
    from fem_reference.cli import app as fem_app
    app.add_typer(fem_app, name="fem", help="3-D hyperelastic FEM reference of the bellows.")
except ImportError:  # pragma: no cover - depends on the installation
    pass

from hardware import cli as rig_cli  # noqa: E402  (rig: control runs and run logs)
app.command("control")(rig_cli.control)
app.add_typer(rig_cli.log_app, name="log", help="Inspect run logs: show | export.")


def main(args=None) -> None:
    """Console entry point: runs ``app`` under the one-line error contract (exit status 2)."""
    clitools.run(app, args)


if __name__ == "__main__":
    main()
