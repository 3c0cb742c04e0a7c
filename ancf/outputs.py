"""Output paths checked before any work: writable, and no finished result overwritten unless asked.

Every command and study that writes files calls one of these *before* it computes anything, so that a
bad ``--out`` fails in a second instead of after minutes, and an existing result is only replaced with
``force=True`` (CLI: ``--force``).
"""

from __future__ import annotations

import os
import pathlib
import tempfile
from typing import Iterable

from .errors import InputError, OutputExistsError


def _writable_dir(d: pathlib.Path) -> None:
    try:
        d.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create the output folder {d}: {exc.strerror or exc}") from None
    if not d.is_dir():
        raise InputError(f"output folder {d} is not a folder")
    try:
        with tempfile.NamedTemporaryFile(dir=d, prefix=".write-test-"):
            pass
    except OSError as exc:
        raise InputError(f"output folder {d} is not writable: {exc.strerror or exc}") from None


def prepare_output_file(path, *, force: bool = False, suffixes: Iterable[str] | None = None) -> pathlib.Path:
    """Check that ``path`` can be written: its folder exists or can be made and is writable, it is not a
    folder, its suffix is one of ``suffixes`` (e.g. ``(".h5", ".hdf5")``) if given, and it does not exist
    unless ``force``.  Returns the path."""
    p = pathlib.Path(path).expanduser()
    if suffixes is not None:
        suffixes = tuple(suffixes)
        if p.suffix.lower() not in suffixes:
            raise InputError(f"output file {p} must end in {' or '.join(suffixes)}")
    if p.is_dir():
        raise InputError(f"output {p} is a folder; give a file name")
    if p.exists() and not force:
        raise OutputExistsError(f"{p} exists; use --force to overwrite it, or another name")
    _writable_dir(p.parent if str(p.parent) else pathlib.Path("."))
    return p


def prepare_output_dir(path, files: Iterable[str] = (), *, force: bool = False) -> pathlib.Path:
    """Check that the folder ``path`` can hold the result ``files`` (names relative to it): it can be made
    and written, and none of ``files`` exists unless ``force``.  Returns the folder."""
    d = pathlib.Path(path).expanduser()
    if d.exists() and not d.is_dir():
        raise InputError(f"output {d} exists and is not a folder")
    existing = [f for f in files if (d / f).exists()]
    if existing and not force:
        shown = ", ".join(existing[:4]) + (" …" if len(existing) > 4 else "")
        raise OutputExistsError(f"{d} already holds results ({shown}); use --force to overwrite them, "
                                f"or another --out folder")
    _writable_dir(d)
    return d


def atomic_write_text(path, text: str) -> pathlib.Path:
    """Write ``text`` to ``path`` through a temporary file and a rename (never a half-written file)."""
    p = pathlib.Path(path)
    tmp = p.with_name(f".{p.name}.tmp{os.getpid()}")
    tmp.write_text(text)
    os.replace(tmp, p)
    return p
