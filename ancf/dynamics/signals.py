"""Load signals of a transient run: a constant, a function of time, or a table to interpolate.

Every signal is checked where it is first seen (shape, finite numbers) and again at every time the
integrator asks for it, so a function that returns NaN at t = 1.3 s stops the run with an
:class:`~ancf.errors.InputError` naming the signal and the time, never a silent NaN in the state.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from ..errors import InputError


class Signal:
    """``Signal(name, value, shape, unit)``: value is a number/array (constant), a callable ``f(t [s])``
    returning that shape, or a table ``(times [s] (k,), values (k, *shape))`` interpolated linearly (held
    constant outside)."""

    def __init__(self, name: str, value, shape: tuple, unit: str):
        self.name, self.shape, self.unit = name, tuple(shape), unit
        self.constant = not callable(value) and not _is_table(value, shape)
        if callable(value):
            self._f: Callable[[float], np.ndarray] = value
        elif self.constant:
            c = self._check(value, None)
            self._f = lambda t, c=c: c
        else:
            tt = np.asarray(value[0], float)
            vv = np.asarray(value[1], float)
            if tt.ndim != 1 or len(tt) < 2 or vv.shape != (len(tt), *self.shape):
                raise InputError(f"{name}: a table needs times (k,) and values (k, {', '.join(map(str, shape))})"
                                 f" with k ≥ 2, got {tt.shape} and {vv.shape}")
            if not (np.all(np.isfinite(tt)) and np.all(np.isfinite(vv)) and np.all(np.diff(tt) > 0)):
                raise InputError(f"{name}: table times must be finite and increasing and values finite")
            flat = vv.reshape(len(tt), -1)
            self._f = lambda t: np.array([np.interp(t, tt, flat[:, j]) for j in range(flat.shape[1])]
                                         ).reshape(self.shape)

    def __call__(self, t: float) -> np.ndarray:
        if self.constant:
            return self._f(t)                # checked once, when it was given
        return self._check(self._f(t), t)

    def _check(self, v, t) -> np.ndarray:
        at = "" if t is None else f" at t = {t:.6g} s"
        try:
            a = np.asarray(v, dtype=float)
        except (TypeError, ValueError):
            raise InputError(f"{self.name}{at}: expected numbers [{self.unit}], got {v!r}") from None
        if a.shape != self.shape:
            raise InputError(f"{self.name}{at}: expected shape {self.shape} [{self.unit}], got {a.shape}")
        if not np.all(np.isfinite(a)):
            raise InputError(f"{self.name}{at}: not finite ({a})")
        return a


def _is_table(value, shape) -> bool:
    if not isinstance(value, tuple) or len(value) != 2:
        return False
    try:
        t = np.asarray(value[0], float)
    except (TypeError, ValueError):
        return False
    # a constant of shape (2,) is never a table: tables hold arrays of times
    return t.ndim == 1 and len(t) >= 2 and np.ndim(value[1]) == 1 + len(shape)
