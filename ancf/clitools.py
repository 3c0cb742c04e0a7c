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
import math
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
    (re.compile(r"pascals in the Python API; "), ""),
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


# ---- option ranges, checked at the command-line boundary -------------------------------------------------------
#
# Every numeric option is checked while the command line is parsed, before any work: an out-of-range value is a
# usage error (click's "Invalid value for '--option': …", one ``error:`` line, exit status 2), never a library's
# own check surfacing later as an unexpected error.  Integers use typer's own ``min=``/``max=`` (typer shows the
# range in --help); floats use :func:`number_range` as the option's ``callback`` (a float must also be finite,
# and ranges may be open, which ``min=``/``max=`` cannot say); comma lists are parsed by :func:`parse_numbers`.
# tests/test_cli_option_ranges.py holds refused values per option and fails on a numeric option without a row.

#: largest seed: seeds are 32-bit, 0 … 2**32 − 1 (numpy's RandomState range; a seed stays one number in logs/JSON)
SEED_MAX = 2**32 - 1
#: most worker processes an option asks for (a local pool or a dask LocalCluster starts that many processes)
WORKERS_MAX = 1024
#: most Monte Carlo samples per mode (1000× the paper's 10 000; their inputs alone take ≈ 0.6 GB in memory)
SAMPLES_MAX = 10_000_000


def _g(x: float) -> str:
    return str(x) if isinstance(x, int) else f"{x:g}"


def describe_range(low: float | None = None, high: float | None = None, *, low_open: bool = False,
                   high_open: bool = False) -> str:
    """``"> 0"``, ``">= 0"``, ``"< 1"``, ``"in [0, 1)"``, ``"in (0, 20]"`` — or ``""`` for any finite number."""
    if low is not None and high is not None:
        return f"in {'(' if low_open else '['}{_g(low)}, {_g(high)}{')' if high_open else ']'}"
    if low is not None:
        return f"{'>' if low_open else '>='} {_g(low)}"
    if high is not None:
        return f"{'<' if high_open else '<='} {_g(high)}"
    return ""


def _in_range(v: float, low, high, low_open: bool, high_open: bool) -> bool:
    return (math.isfinite(v)
            and (low is None or (v > low if low_open else v >= low))
            and (high is None or (v < high if high_open else v <= high)))


def number_range(low: float | None = None, high: float | None = None, *, low_open: bool = False,
                 high_open: bool = False, unit: str = ""):
    """The ``callback`` of a float option: a given value must be a finite number in the range (``None``, an
    optional option not given, passes); otherwise a usage error naming the option, e.g.
    ``error: Invalid value for '--dt-ms': must be a finite number > 0 ms, got nan``.

    The callback's ``.text`` is the range in words (``"a finite number > 0 ms"``, ``"a number in [0, 1)"``), for
    the option's help."""
    rng = describe_range(low, high, low_open=low_open, high_open=high_open)
    bounded = low is not None and high is not None
    text = ("a number" if bounded else "a finite number") + (f" {rng}" if rng else "") + (f" {unit}" if unit else "")

    def check(value):
        if value is None or _in_range(float(value), low, high, low_open, high_open):
            return value
        raise typer.BadParameter(f"must be {text}, got {_g(float(value))}")
    check.text = text
    return check


#: any finite number (a pressure whose limits the model checks, with --no-limits as the override)
FINITE = number_range()


def parse_numbers(text: str, option: str, *, low: float | None = None, high: float | None = None,
                  low_open: bool = False, high_open: bool = False, integer: bool = False, count: int | None = None,
                  min_count: int = 1, scale: float = 1.0) -> list:
    """A comma-separated list of numbers (``"0,25,50"``; spaces and a trailing comma are allowed) → a list of
    floats (times ``scale``) or, with ``integer``, of ints; every entry finite and in the range, at least
    ``min_count`` entries (exactly ``count`` if given).  Else a usage error naming ``option`` (exit status 2)."""
    def bad(why: str):
        raise typer.BadParameter(f"{why}, got {text!r}", param_hint=f"'{option}'")

    parts = text.replace(" ", "").split(",")
    if parts and parts[-1] == "":
        parts.pop()                                            # "1,2," is "1,2"
    what = "integers" if integer else "numbers"
    if any(x == "" for x in parts):
        bad(f"expected comma-separated {what} (an empty entry)")
    try:
        values = [float(x) for x in parts]
    except ValueError:
        bad(f"expected comma-separated {what}")
    if integer and any(math.isfinite(v) and v != int(v) for v in values):
        bad("expected whole numbers")
    if count is not None and len(values) != count:
        bad(f"expected {count} values")
    if len(values) < min_count:
        bad(f"expected at least {min_count} value{'s' if min_count > 1 else ''}")
    rng = describe_range(low, high, low_open=low_open, high_open=high_open)
    if any(not _in_range(v, low, high, low_open, high_open) for v in values):
        bad(f"every value must be finite{' and ' + rng if rng else ''}")
    return [int(v) for v in values] if integer else [v * scale for v in values]


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
