"""Typed errors of the controller package.

::

    ancf.errors.BellowsError
    └── ControllerError (RuntimeError)         a controller could not do what it was asked
        └── NotConvergedError                  the loop did not reach its tolerance in its budget

Invalid arguments (NaN target, wrong shape) raise :class:`ancf.errors.InputError`; a target (or a load
estimate) that needs tensions outside their bounds propagates :class:`ancf.errors.InfeasibleTargetError`
from the IK, unchanged.
"""

from __future__ import annotations

from typing import Sequence

from ancf.errors import BellowsError


class ControllerError(BellowsError, RuntimeError):
    """A controller or the simulated plant failed (bad measurement, plant solve failure, ...)."""


class NotConvergedError(ControllerError):
    """The control loop did not bring ‖p_m − p_d‖ below its tolerance.

    Attributes
    ----------
    iterations : int        control iterations spent
    error : float           final tip error ‖p_m − p_d‖ [m]
    tolerance : float       required tip error [m]
    history : list[float]   tip error per iteration [m] (index 0: before the first correction)
    """

    def __init__(self, message: str, *, iterations: int, error: float, tolerance: float,
                 history: Sequence[float] = ()):
        self.iterations = int(iterations)
        self.error = float(error)
        self.tolerance = float(tolerance)
        self.history = [float(h) for h in history]
        super().__init__(
            f"{message}: tip error {self.error * 1e3:.4f} mm > tolerance {self.tolerance * 1e3:.4f} mm after "
            f"{self.iterations} iterations ({self.error / self.tolerance:.2f}× the tolerance; "
            f"history [mm]: {[round(h * 1e3, 4) for h in self.history]})")


def check_finite(name: str, value, shape=None):
    """:func:`ancf.errors.check_finite` that also turns non-numeric input (text, None, ragged lists) into
    :class:`~ancf.errors.InputError` instead of a ValueError/TypeError."""
    from ancf.errors import InputError, check_finite as _cf
    if isinstance(value, (str, bytes)) or value is None:
        raise InputError(f"{name} must be numeric, got {value!r}")
    try:
        return _cf(name, value, shape)
    except InputError:
        raise
    except (TypeError, ValueError, OverflowError):
        raise InputError(f"{name} must be numeric{'' if shape is None else f' with shape {shape}'}, "
                         f"got {value!r}") from None


def number(name: str, value, *, lower: float = 0.0, strict: bool = False, allow_inf: bool = False) -> float:
    """A real number ≥ ``lower`` (> with ``strict``), finite unless ``allow_inf``; else InputError."""
    import math
    from ancf.errors import InputError
    if isinstance(value, (bool, str, bytes)) or value is None:
        raise InputError(f"{name} must be a number, got {value!r}")
    try:
        x = float(value)
    except (TypeError, ValueError, OverflowError):
        raise InputError(f"{name} must be a number, got {value!r}") from None
    if math.isnan(x) or (math.isinf(x) and not allow_inf) or x < lower or (strict and x == lower):
        raise InputError(f"{name} must be {'>' if strict else '>='} {lower:g}"
                         f"{'' if allow_inf else ' and finite'}, got {value!r}")
    return x
