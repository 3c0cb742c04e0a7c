"""Typed exception tree shared by every package of the product.

All errors raised on purpose derive from :class:`BellowsError`, so a script can catch the whole family
with one ``except``.  Each subclass also derives from the matching builtin (``ValueError``,
``RuntimeError``) so generic handlers keep working.

::

    BellowsError
    ├── ConfigError (ValueError)            bad parameter file / value / unit, unknown key
    ├── InputError (ValueError)             NaN / inf / wrong shape / out-of-range call argument
    │   ├── LimitError                      outside the actuator's stated operating limits
    │   └── OutputExistsError               an output exists and overwriting was not asked for
    ├── ConvergenceError (RuntimeError)     a nonlinear solve did not converge (carries residual history)
    ├── UnstableEquilibriumError (RuntimeError)  a solve reached an equilibrium that is not a minimum
    ├── CollapsedStateError (RuntimeError)  a state outside the stiffness law's validity range
    ├── InfeasibleTargetError (ValueError)  IK target needs a tension outside its bounds / is unreachable
    └── HardwareError (RuntimeError)        rig layer: limits, faults, timeouts (see ``hardware``)
"""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np


class BellowsError(Exception):
    """Base class of every error the product raises on purpose.

    Picklable with its attributes (a worker process's error reaches the caller as itself), though several
    subclasses take required keyword arguments that ``Exception``'s default pickling would not pass back."""

    def __reduce__(self):
        return _rebuild_error, (type(self), self.args, dict(self.__dict__))


def _rebuild_error(cls, args, state):
    err = cls.__new__(cls, *args)
    Exception.__init__(err, *args)
    err.__dict__.update(state)
    return err


class ConfigError(BellowsError, ValueError):
    """A configuration (parameter file, preset override, keyword) is invalid."""


class InputError(BellowsError, ValueError):
    """A call argument is invalid (NaN, wrong shape, outside the operating range, ...)."""


class LimitError(InputError):
    """An input, or the state it leads to, is outside the actuator's stated operating limits (tension,
    pressure, tip load).  The API analyses it anyway with ``check_limits=False``; the CLI with
    ``--no-limits``."""


class OutputExistsError(InputError):
    """An output file exists and overwriting it was not asked for (``force=True`` / ``--force``)."""


class ConvergenceError(BellowsError, RuntimeError):
    """A nonlinear solve did not converge.

    Attributes
    ----------
    solver : str
        Which solve failed (``"fk"``, ``"ik"``, ``"fk_locked"``, ...).
    iterations : int
        Iterations spent.
    residual_norm : float
        Final residual norm (units of the solver's residual, stated in ``message``).
    tolerance : float
        Tolerance that was not met.
    history : list[float]
        Residual norm per iteration.
    """

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
    """A solve converged to an equilibrium that is not stable (a saddle or maximum of the potential).

    Such a state is never returned as a result.  Attributes
    ----------
    solver : str
        Which solve found it.
    min_eigenvalue : float
        Smallest eigenvalue of the reduced Hessian (on the constraint tangent space for rigid locked
        tendons, with k_s ∇l ∇lᵀ added for elastic ones); negative.  Units of the model's generalized stiffness.
    """

    def __init__(self, message: str, *, solver: str, min_eigenvalue: float):
        self.solver = solver
        self.min_eigenvalue = float(min_eigenvalue)
        super().__init__(f"{solver}: {message} (smallest reduced stiffness eigenvalue {self.min_eigenvalue:.3e})")


class CollapsedStateError(BellowsError, RuntimeError):
    """A solve reached a state outside the validity range of the stiffness law (e.g. a stretch where
    EA(λ) or EI(λ) is no longer positive: the section has collapsed).  Such a state is not a valid
    equilibrium of the model and is never returned.  ``stretch`` holds the offending stretch λ."""

    def __init__(self, message: str, *, solver: str = "", stretch: float = float("nan")):
        self.solver = solver
        self.stretch = float(stretch)
        super().__init__(message)


class InfeasibleTargetError(BellowsError, ValueError):
    """An IK target cannot be reached with tensions inside their bounds.

    Attributes
    ----------
    target : ndarray (3,)
        Requested tip position [m].
    nearest : ndarray (3,) or None
        Nearest tip position reachable within the bounds [m].
    tensions : ndarray (m,) or None
        Tensions [N] that reach ``nearest``.
    violated : list[str]
        Human-readable list of the bounds that the unconstrained solution violates,
        e.g. ``["T2 >= 0 N (needs -0.41 N)"]``.
    state : ancf.Equilibrium or None
        The equilibrium at ``tensions`` (its tip is ``nearest``), verified like any FK result (admissible,
        inside the stiffness law's range, stable), or None when the solver could not verify one.  A controller
        that saturates commands it without solving the FK again.
    """

    def __init__(self, message: str, *, target, nearest=None, tensions=None, violated=(), state=None):
        self.target = np.asarray(target, float)
        self.nearest = None if nearest is None else np.asarray(nearest, float)
        self.tensions = None if tensions is None else np.asarray(tensions, float)
        self.violated = list(violated)
        self.state = state
        super().__init__(message)


class HardwareError(BellowsError, RuntimeError):
    """Base of rig-layer errors (limits, faults, timeouts)."""


def check_finite(name: str, value, shape: tuple[int, ...] | None = None) -> np.ndarray:
    """Return ``value`` as a C-contiguous float64 array, raising :class:`InputError` on NaN/inf, a wrong
    shape, or a value that is not real numbers (a string, a boolean, a complex number, ``None``, an
    object array).  The one gate every array passes before it reaches a compiled kernel."""
    if isinstance(value, (str, bytes)) or value is None:
        raise InputError(f"{name} must be a number or an array of numbers, got {value!r}")
    try:
        raw = np.asarray(value)
    except (ValueError, TypeError) as exc:  # ragged nested sequences
        raise InputError(f"{name} must be a regular array of numbers: {exc}") from None
    if raw.dtype.kind not in "iuf":
        kind = {"b": "booleans", "c": "complex numbers", "U": "text", "S": "text", "O": "objects",
                "M": "dates", "m": "time spans", "V": "records"}.get(raw.dtype.kind, str(raw.dtype))
        raise InputError(f"{name} must be real numbers, got {kind} ({_short(value)})")
    arr = np.asarray(raw, dtype=np.float64, order="C")
    if shape is not None and arr.shape != tuple(shape):
        raise InputError(f"{name} must have shape {tuple(shape)}, got {arr.shape}")
    # small arrays (the loads and tensions of every solve) through Python floats: ≈ 8× cheaper than a ufunc
    if not (all(map(math.isfinite, arr.ravel().tolist())) if arr.size <= 64 else np.isfinite(arr).all()):
        bad = np.flatnonzero(~np.isfinite(arr.ravel()))
        where = (f"{float(arr.ravel()[0])}" if arr.ndim == 0 else
                 f"{bad.size} of {arr.size} entries, the first {float(arr.ravel()[bad[0]])} at flat index {bad[0]}")
        raise InputError(f"{name} contains NaN or inf ({where})")
    return arr


def check_scalar(name: str, value, *, low: float | None = None, high: float | None = None,
                 unit: str = "") -> float:
    """A finite real number (not a string or a boolean) inside ``[low, high]``, as a float; else
    :class:`InputError` naming ``name``, the value and the unit."""
    v = float(check_finite(name, value, ()))
    if (low is not None and v < low) or (high is not None and v > high):
        rng = f"[{'-inf' if low is None else f'{low:g}'}, {'inf' if high is None else f'{high:g}'}]"
        raise InputError(f"{name} = {v:g}{' ' + unit if unit else ''} is outside {rng}{' ' + unit if unit else ''}")
    return v


def _short(value) -> str:
    text = repr(value)
    return text if len(text) <= 80 else text[:77] + "..."
