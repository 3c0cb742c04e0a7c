"""Command-line error contract shared by every ``bellows`` command (cheap to import: no numba).

Rules (README "Errors and guarantees", docs/errors.md):

* every handled error — a product error (:class:`~ancf.errors.BellowsError`) or a usage error (unknown
  option, a value that is not a number, a missing option) — prints **one** line ``error: …`` on stderr and
  exits with status **2**; no traceback, no usage box;
* Ctrl-C prints ``error: interrupted`` and exits with status 130 (the shell's convention);
* messages speak the command line's terms: the Python API's ``check_limits=False`` is ``--no-limits``,
  ``force=True`` is ``--force``, pressures are in kPa.
"""

from __future__ import annotations

import re
import sys
from typing import Sequence

import click
import typer

from .errors import BellowsError


def _exception_modules():
    """click's exception module, and typer's vendored copy of it (typer >= 0.17 ships its own click)."""
    mods = [click.exceptions]
    try:
        from typer._click import exceptions as vendored
        mods.append(vendored)
    except ImportError:  # pragma: no cover - typer using the installed click
        pass
    return mods


_MODS = _exception_modules()
_NO_ARGS = tuple(m.NoArgsIsHelpError for m in _MODS if hasattr(m, "NoArgsIsHelpError"))
_USAGE = tuple(m.UsageError for m in _MODS)
_CLICK = tuple(m.ClickException for m in _MODS)
_ABORT = (click.exceptions.Abort, typer.Abort)

# --help is laid out for 120 columns (inherited by every subcommand), so that command summaries are not
# cut with "..." at the 80-column default
HELP_SETTINGS = {"terminal_width": 120, "max_content_width": 120}

# Python-API phrases in error messages and their command-line equivalents
_CLI_TERMS = [
    (re.compile(r"check_limits=False"), "--no-limits"),
    (re.compile(r"force=True"), "--force"),
    (re.compile(r" ?\(?the Python API takes pascals: 30 kPa = 30e3;? ?\)?"), " "),
    (re.compile(r"pass (--no-limits)"), r"use \1"),
    (re.compile(r"\s{2,}"), " "),
    (re.compile(r"\( "), "("),
]


def cli_message(exc: BaseException) -> str:
    """One line: the error's message in the command line's terms."""
    text = " ".join(str(exc).split())
    for pattern, repl in _CLI_TERMS:
        text = pattern.sub(repl, text)
    return text.strip()


def error_exit(message: str, code: int = 2) -> "None":
    click.secho(f"error: {message}", fg="red", err=True)
    sys.exit(code)


def run(app, args: Sequence[str] | None = None, prog_name: str = "bellows") -> None:
    """Run a typer/click ``app`` under the error contract above; exits the process."""
    try:
        rv = app(args=None if args is None else list(args), prog_name=prog_name, standalone_mode=False)
    except BellowsError as exc:
        error_exit(cli_message(exc))
    except _NO_ARGS as exc:                           # bare command: show its help
        click.echo(exc.ctx.get_help() if exc.ctx is not None else str(exc))
        sys.exit(0)
    except _USAGE as exc:
        hint = f" (see '{exc.ctx.command_path} --help')" if exc.ctx is not None else ""
        error_exit(cli_message(exc.format_message()) + hint)
    except _CLICK as exc:                             # e.g. a file option that cannot be opened
        error_exit(cli_message(exc.format_message()))
    except (*_ABORT, KeyboardInterrupt):
        error_exit("interrupted", 130)
    if rv == 130:                                     # typer turns Ctrl-C into a silent Exit(130)
        error_exit("interrupted", 130)
    sys.exit(rv if isinstance(rv, int) else 0)
