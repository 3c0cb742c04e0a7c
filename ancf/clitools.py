"""Command-line error contract shared by every ``bellows`` command (cheap to import: no numba).

Rules (README "Errors and guarantees", docs/errors.md):

* every handled error — a product error (:class:`~ancf.errors.BellowsError`) or a usage error (unknown
  option, a value that is not a number, a missing option) — prints **one** line ``error: …`` on stderr and
  exits with status **2**; no traceback, no usage box;
* Ctrl-C prints ``error: interrupted`` and exits with status 130 (the shell's convention);
* anything else (a bug) never shows a raw traceback either: the traceback is written to a file
  (``$BELLOWS_TRACEBACK_DIR``, default ``<temp>/bellows-tracebacks/``), one ``error:`` line names the
  exception and that file, and the exit status is **1**;
* messages speak the command line's terms: the Python API's ``check_limits=False`` is ``--no-limits``,
  ``force=True`` is ``--force``, pressures are in kPa.
"""

from __future__ import annotations

import datetime
import os
import pathlib
import re
import sys
import tempfile
import traceback
from typing import Sequence

import typer

from .errors import BellowsError


def _click_kind(exc: BaseException) -> str | None:
    """The click exception class ``exc`` is (most specific first), by name: typer >= 0.26 raises its vendored
    click's classes, older typer the stand-alone click's; matching by name serves both without importing
    either (the base install has no stand-alone click)."""
    for cls in type(exc).__mro__:
        if "click" in cls.__module__ and cls.__name__ in ("NoArgsIsHelpError", "UsageError", "ClickException",
                                                          "Abort"):
            return cls.__name__
    return None


# --help is laid out for 120 columns (inherited by every subcommand), so that command summaries are not
# cut with "..." at the 80-column default
HELP_SETTINGS = {"terminal_width": 120, "max_content_width": 120}

# Python-API phrases in error messages and their command-line equivalents
_CLI_TERMS = [
    (re.compile(r";? ?the Python API takes pascals: 30 kPa = 30e3;? ?"), ""),
    (re.compile(r"check_limits=False analyses (it|them) anyway"), r"use --no-limits to analyse \1 anyway"),
    (re.compile(r"check_limits=False"), "--no-limits"),
    (re.compile(r"force=True"), "--force"),
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
    typer.secho(f"error: {message}", fg="red", err=True)
    sys.exit(code)


def traceback_dir() -> pathlib.Path:
    """Folder for the tracebacks of unexpected errors: ``$BELLOWS_TRACEBACK_DIR`` or ``<temp>/bellows-tracebacks``."""
    env = os.environ.get("BELLOWS_TRACEBACK_DIR")
    return pathlib.Path(env) if env else pathlib.Path(tempfile.gettempdir()) / "bellows-tracebacks"


def write_traceback(exc: BaseException, argv: Sequence[str] | None = None) -> pathlib.Path | None:
    """Write ``exc``'s traceback (and the command line) to a new file; its path, or None if none could be written."""
    stamp = datetime.datetime.now().strftime("%Y%m%d-%H%M%S")
    try:
        folder = traceback_dir()
        folder.mkdir(parents=True, exist_ok=True)
        path = folder / f"bellows-{stamp}-{os.getpid()}.txt"
        cmd = " ".join(["bellows", *(sys.argv[1:] if argv is None else argv)])
        path.write_text(f"command: {cmd}\ncwd: {os.getcwd()}\n\n"
                        + "".join(traceback.format_exception(type(exc), exc, exc.__traceback__)))
        return path
    except OSError:
        return None


def run(app, args: Sequence[str] | None = None, prog_name: str = "bellows") -> None:
    """Run a typer/click ``app`` under the error contract above; exits the process."""
    try:
        rv = app(args=None if args is None else list(args), prog_name=prog_name, standalone_mode=False)
    except BellowsError as exc:
        error_exit(cli_message(exc))
    except (typer.Abort, KeyboardInterrupt):
        error_exit("interrupted", 130)
    except Exception as exc:                          # (SystemExit is no Exception: exits pass through)
        kind = _click_kind(exc)
        if kind == "NoArgsIsHelpError":               # bare command: show its help
            ctx = getattr(exc, "ctx", None)
            typer.echo(ctx.get_help() if ctx is not None else str(exc))
            sys.exit(0)
        if kind == "UsageError":
            ctx = getattr(exc, "ctx", None)
            hint = f" (see '{ctx.command_path} --help')" if ctx is not None else ""
            error_exit(cli_message(exc.format_message()) + hint)
        if kind == "ClickException":                  # e.g. a file option that cannot be opened
            error_exit(cli_message(exc.format_message()))
        if kind == "Abort":
            error_exit("interrupted", 130)
        # a bug: never a raw traceback (see the module docstring)
        path = write_traceback(exc, args)
        where = f"the traceback is in {path}" if path else "the traceback could not be written"
        what = " ".join(str(exc).split())[:300]
        error_exit(f"unexpected {type(exc).__name__}{': ' + what if what else ''} ({where}; please report it)", 1)
    if rv == 130:                                     # typer turns Ctrl-C into a silent Exit(130)
        error_exit("interrupted", 130)
    sys.exit(rv if isinstance(rv, int) else 0)
