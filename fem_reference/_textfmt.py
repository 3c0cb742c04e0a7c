"""Text of the FEM command line and figure titles (its own copy of ancf.textfmt: fem_reference
does not import ancf): choice lists built from the code's registries, numbers and vectors with their
unit — never a numpy repr (``[ 1.7e+02 ...]``, ``np.float64(…)``).

``one_of(("coarse", "medium"))`` → ``"{coarse | medium}"``; ``vector((0.1717, 0, -0.0311), "mm", 1e3)`` →
``"(171.7, 0.0, -31.1) mm"``; ``number(30e3, "kPa", 1e-3)`` → ``"30.0 kPa"``.
"""

from __future__ import annotations

import math
from typing import Iterable, Optional

__all__ = ["one_of", "number", "vector"]


def one_of(values: Iterable) -> str:
    """The accepted values of an option as they appear in its help: ``{a | b | c}`` (in registry order)."""
    return "{" + " | ".join(str(v) for v in values) + "}"


def _num(x, digits: int) -> str:
    x = float(x)
    if not math.isfinite(x):
        return "nan" if math.isnan(x) else ("inf" if x > 0 else "-inf")
    s = f"{x:.{digits}f}"
    return s.lstrip("-") if float(s) == 0 else s          # no "-0.0"


def number(x, unit: Optional[str] = None, scale: float = 1.0, digits: int = 1) -> str:
    """One number with ``digits`` decimals after multiplying by ``scale``, and its unit: ``"30.0 kPa"``."""
    s = _num(float(x) * scale, digits)
    return f"{s} {unit}" if unit else s


def vector(v, unit: Optional[str] = None, scale: float = 1.0, digits: int = 1) -> str:
    """A vector as ``(x, y, z) unit`` with ``digits`` decimals after multiplying by ``scale``."""
    s = "(" + ", ".join(_num(float(x) * scale, digits) for x in v) + ")"
    return f"{s} {unit}" if unit else s
