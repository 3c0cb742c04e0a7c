r"""Input shaping of motor moves for a plant with inertia: the zero-vibration (ZV) shaper.

A quasi-static controller commands tendon lengths as steps; on a plant whose first locked bending mode
(frequency f, damping ratio ζ) is lightly damped, each step starts a ringing that the next measurement
mistakes for a load (docs/dynamics.md: a 30 ms loop on the `paper` actuator ends worse than no control).
The ZV shaper splits every move Δl into two parts,

    A₁ Δl at t = 0  and  A₂ Δl at t = T_d / 2,    A₁ = 1/(1 + K),  A₂ = K/(1 + K),  K = exp(−ζπ/√(1 − ζ²)),

T_d = 1/(f √(1 − ζ²)) the damped period: the second impulse starts a vibration of the same amplitude in
antiphase, so the mode is left at rest (Singer & Seering 1990).  It needs the mode's frequency (the model's
:meth:`ancf.Model.modes` about the locked state) and damping (identified from a free decay,
:mod:`validation.identification.damping`); it costs half a damped period per move.
"""

from __future__ import annotations

import math

from .errors import number


def zv_shaper(frequency_hz: float, damping_ratio: float = 0.0) -> tuple[float, float]:
    """(A₁ [-], delay [s]) of the ZV shaper for a mode of ``frequency_hz`` [Hz] and ``damping_ratio`` [-]
    (module docstring); the second part A₂ = 1 − A₁ follows after ``delay``."""
    f = number("frequency_hz", frequency_hz, strict=True)
    z = number("damping_ratio", damping_ratio)
    if not z < 1:
        from ancf.errors import InputError
        raise InputError(f"damping_ratio must be < 1 (an oscillating mode), got {z:g}")
    root = math.sqrt(1.0 - z * z)
    K = math.exp(-z * math.pi / root)
    return 1.0 / (1.0 + K), 0.5 / (f * root)
