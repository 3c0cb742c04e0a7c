"""Provenance of a result: package versions, the git revision of the code, the time it was made."""

from __future__ import annotations

import datetime
import pathlib
import platform
import subprocess
from importlib import metadata

_PACKAGES = ("bellows", "numpy", "scipy", "numba", "scikit-fem", "pydantic", "h5py", "matplotlib")


def git_revision(path=None) -> str:
    """``<sha>`` (with ``+dirty`` when the work tree has changes) of the checkout holding this code, or
    ``"unknown"`` outside a git checkout."""
    root = pathlib.Path(path or __file__).resolve().parent
    try:
        sha = subprocess.run(["git", "rev-parse", "HEAD"], cwd=root, capture_output=True, text=True, timeout=5)
        if sha.returncode != 0:
            return "unknown"
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=root,
                               capture_output=True, text=True, timeout=5)
        return sha.stdout.strip() + ("+dirty" if dirty.stdout.strip() else "")
    except (OSError, subprocess.SubprocessError):
        return "unknown"


def versions() -> dict:
    out = {"python": platform.python_version()}
    for name in _PACKAGES:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = "not installed"
    return out


def provenance() -> dict:
    """{"versions": {...}, "git_revision": ..., "created": ISO time (UTC), "platform": ...}."""
    return {"versions": versions(), "git_revision": git_revision(),
            "created": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
            "platform": platform.platform()}
