"""The part of the product's exception tree the FEM raises, for the FEM used without the ``ancf`` package.

Used only through :mod:`fem_reference.errors`, and only when ``ancf`` cannot be imported; with the product
installed the same names are :mod:`ancf.errors`' own classes.  Names, bases and constructors mirror
:mod:`ancf.errors` (tests/test_layout.py compares the two trees).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np


class BellowsError(Exception):
    """Base class of every error the product raises on purpose (picklable with its attributes)."""

    def __reduce__(self):
        return _rebuild_error, (type(self), self.args, dict(self.__dict__))


def _rebuild_error(cls, args, state):
    err = cls.__new__(cls, *args)
    Exception.__init__(err, *args)
    err.__dict__.update(state)
    return err


class ConfigError(BellowsError, ValueError):
    """A configuration (geometry, material, mesh level, keyword) is invalid."""


class InputError(BellowsError, ValueError):
    """A call argument is invalid (NaN, wrong shape, outside the operating range, ...)."""


class LimitError(InputError):
    """A load is outside the model's stated operating limits (``check_limits=False`` analyses it anyway)."""


class ConvergenceError(BellowsError, RuntimeError):
    """A nonlinear solve did not converge; ``solver``, ``iterations``, ``residual_norm``, ``tolerance`` and
    ``history`` (residual norm per iteration) as in :class:`ancf.errors.ConvergenceError`."""

    def __init__(self, message: str, *, solver: str, iterations: int, residual_norm: float,
                 tolerance: float, history: Sequence[float] = ()):
        self.solver = solver
        self.iterations = int(iterations)
        self.residual_norm = float(residual_norm)
        self.tolerance = float(tolerance)
        self.history = [float(h) for h in history]
        super().__init__(
            f"{solver}: {message} (residual {self.residual_norm:.3e} > tolerance {self.tolerance:.1e} "
            f"after {self.iterations} iterations)")


class UnstableEquilibriumError(BellowsError, RuntimeError):
    """A solve reached an equilibrium that is not stable; ``min_eigenvalue`` is the smallest (negative)
    eigenvalue found."""

    def __init__(self, message: str, *, solver: str, min_eigenvalue: float):
        self.solver = solver
        self.min_eigenvalue = float(min_eigenvalue)
        super().__init__(f"{solver}: {message} (smallest reduced stiffness eigenvalue {self.min_eigenvalue:.3e})")


def check_finite(name: str, value, shape: tuple[int, ...] | None = None) -> np.ndarray:
    """``value`` as a C-contiguous float64 array; :class:`InputError` on NaN/inf, a wrong shape, or a value
    that is not real numbers (text, booleans, complex numbers, ``None``, objects)."""
    if isinstance(value, (str, bytes)) or value is None:
        raise InputError(f"{name} must be a number or an array of numbers, got {value!r}")
    try:
        raw = np.asarray(value)
    except (ValueError, TypeError) as exc:  # ragged nested sequences
        raise InputError(f"{name} must be a regular array of numbers: {exc}") from None
    if raw.dtype.kind not in "iuf":
        raise InputError(f"{name} must be real numbers, got dtype {raw.dtype} ({_short(value)})")
    arr = np.asarray(raw, dtype=np.float64, order="C")
    if shape is not None and arr.shape != tuple(shape):
        raise InputError(f"{name} must have shape {tuple(shape)}, got {arr.shape}")
    if not np.isfinite(arr).all():
        first = float(arr.ravel()[np.flatnonzero(~np.isfinite(arr.ravel()))[0]])
        raise InputError(f"{name} contains NaN or inf (the first {first})")
    return arr


def _short(value) -> str:
    text = repr(value)
    return text if len(text) <= 80 else text[:77] + "..."
