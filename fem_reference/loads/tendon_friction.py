r"""Tendon friction at the guide points: a discrete capstan (Coulomb) law with stick/slip history.

The frictionless cable of :mod:`fem_reference.loads.tendons` is the polyline ``x_0 … x_n`` (``x_0`` the fixed
exit on the base cap, ``x_1 … x_{n-1}`` the guides on the root flanges, ``x_n`` the anchor on the distal cap).
With friction each segment ``s`` (from ``x_s`` to ``x_{s+1}``, length ``ℓ_s``) carries its own tension ``T_s``.

**Guides.**  Guide ``k = 0 … n−1`` is the point ``x_k``: the exit (``k = 0``; the tendon comes in from the motor
along the base axis ``e_in``) and the flange guides.  The anchor has no friction.  The wrap angle at guide ``k``
is the angle between the adjacent directions ``a = x_k − x_{k−1}`` (``e_in`` for ``k = 0``) and
``b = x_{k+1} − x_k``,

.. math::

    α_k = \operatorname{atan2}(|a × b|, a·b), \qquad
    \frac{∂α}{∂a} = -\frac{b - (a·b)\,a/|a|^2}{|a × b|}, \qquad
    \frac{∂α}{∂b} = -\frac{a - (a·b)\,b/|b|^2}{|a × b|},

so ``∂α_k/∂x_{k+1} = ∂α/∂b``, ``∂α_k/∂x_k = ∂α/∂a − ∂α/∂b``, ``∂α_k/∂x_{k−1} = −∂α/∂a`` (no ``a`` terms for
``k = 0``: ``e_in`` is fixed).  At ``α = 0`` (a straight run) α has no derivative; its gradient is taken as zero.

**Capstan cone and history** (the law of ``docs/friction.md``, implemented independently here).  Static
friction holds any ratio ``T_{k−1} e^{−μα_k} ≤ T_k ≤ T_{k−1} e^{μα_k}`` (``T_{−1}`` the motor tension).  From
the previous state's segment tensions ``H_k``, walking out from the motor,

.. math::

    T_k = \operatorname{clip}\big(H_k,\ T_{k−1} e^{−μα_k},\ T_{k−1} e^{μα_k}\big):

below the cone the tendon slips toward the motor (code +1, ``T_k = T_{k−1} e^{−μα_k}``: loading), above it it
slips back out (−1, ``T_k = T_{k−1} e^{μα_k}``: unloading), inside it sticks (0) and **keeps its tension**
``H_k`` (not its length) — the rod's choice, so that the two can be compared.  The law is applied once per
history step with the previous state's ``H`` (monotone changes between steps are assumed); the FEM's load
ramp inside a step is only a continuation path to that step's equilibrium.

**Forces and tangent.**  The tendon acts on the structure through its segments,
``r_f = Σ_s T_s ∂ℓ_s/∂q``; the tangent is ``Σ_s T_s ∂²ℓ_s/∂q² + Σ_s ∂ℓ_s/∂q (∂T_s/∂q)ᵀ`` with
``∂T_k = e^{∓μα_k} ∂T_{k−1} ∓ μ T_k ∂α_k`` on a slipping segment (upper signs: +1) and 0 on a stuck one.  The
second term is not symmetric (friction is not conservative).  With ``μ = 0`` every segment carries the motor
tension and ``r_f = T ∂L/∂q``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = [
    "SLIP_IN",
    "SLIP_OUT",
    "STICK",
    "FemTensionCycle",
    "FrictionLaw",
    "FrictionProfile",
    "friction_block",
    "loop_area",
    "tension_profile",
    "weighted_gradient",
    "wrap_angles",
]

#: sliding codes of a segment (:func:`tension_profile`)
SLIP_IN, STICK, SLIP_OUT = 1, 0, -1


@dataclass(frozen=True)
class FrictionLaw:
    """The friction of one history step: ``mu`` [-] and ``held`` (m, n) [N], the previous state's segment
    tensions (zeros: the slack actuator); ``e_in`` (3,) the motor-side direction at the exit (the base axis)."""

    mu: float
    held: np.ndarray
    e_in: np.ndarray


@dataclass
class FrictionProfile:
    """Segment tensions of an equilibrium with friction: the next history step's ``held``.

    mu [-]; segment_tensions (m, n) [N] (segment 0 next to the motor); sliding (m, n) int8 codes
    (:data:`SLIP_IN` / :data:`STICK` / :data:`SLIP_OUT`); wrap_angles (m, n) [rad] at guides 0 … n−1.
    """

    mu: float
    segment_tensions: np.ndarray
    sliding: np.ndarray
    wrap_angles: np.ndarray


@dataclass
class FemTensionCycle:
    """A quasi-static tension cycle 0 → T_peak → 0 of the FEM with friction.

    scale (2 s + 1,) load factors; tip (2 s + 1, 3) [m] tip points; results: the BellowsResult of each point;
    profiles: their FrictionProfile; loop_area [N m] in the plane (T_max × scale, u), u the tip displacement
    along the loading direction (start → peak), as ``ancf``'s ``TensionCycle.loop_area``.
    """

    scale: np.ndarray
    tip: np.ndarray
    results: list
    profiles: list
    loop_area: float = 0.0
    peak_tensions: np.ndarray = field(default_factory=lambda: np.zeros(0))

    def branches(self) -> tuple[np.ndarray, np.ndarray]:
        """(loading, unloading) tip points [m], each (s + 1, 3) ordered by increasing scale."""
        s = (len(self.scale) - 1) // 2
        return self.tip[:s + 1], self.tip[s:][::-1]


def wrap_angles(x: np.ndarray, e_in: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Wrap angles α (n,) [rad] at guides 0 … n−1 of the polyline ``x`` (n+1, 3) [m] and their gradients
    ∂α_k/∂x_j, shape (n, n+1, 3) [rad/m] (module docstring); ``e_in`` (3,) the motor side of guide 0."""
    n = x.shape[0] - 1
    C = np.diff(x, axis=0)
    A = np.vstack([np.asarray(e_in, float)[None], C[:-1]])
    B = C
    s = np.linalg.norm(np.cross(A, B), axis=1)
    p = np.einsum("kc,kc->k", A, B)
    alpha = np.arctan2(s, p)
    na2, nb2 = np.einsum("kc,kc->k", A, A), np.einsum("kc,kc->k", B, B)
    ok = s > 1e-14 * np.sqrt(na2 * nb2)
    safe = np.where(ok, s, 1.0)[:, None]
    ga = np.where(ok[:, None], -(B - (p / na2)[:, None] * A) / safe, 0.0)
    gb = np.where(ok[:, None], -(A - (p / nb2)[:, None] * B) / safe, 0.0)
    d = np.zeros((n, n + 1, 3))
    k = np.arange(n)
    d[k, k + 1] += gb
    d[k, k] -= gb
    d[k[1:], k[1:]] += ga[1:]
    d[k[1:], k[:-1]] -= ga[1:]
    return alpha, d


def tension_profile(motor: float, held: np.ndarray, alpha: np.ndarray, mu: float,
                    dalpha: np.ndarray | None = None):
    """Segment tensions of one tendon under the capstan law with history (module docstring).

    ``motor`` [N]; ``held`` (n,) [N] the previous segment tensions; ``alpha`` (n,) [rad]; ``mu`` [-];
    ``dalpha`` (n, n+1, 3) or None.  Returns (T (n,) [N], codes (n,) int8, ∂T/∂x (n, n+1, 3) [N/m] or None).
    """
    n = alpha.size
    T = np.empty(n)
    code = np.zeros(n, np.int8)
    dT = None if dalpha is None else np.zeros(dalpha.shape)
    t_prev = float(motor)
    for k in range(n):
        f = float(np.exp(mu * alpha[k]))
        lo, hi, h = t_prev / f, t_prev * f, float(held[k])
        if h < lo:
            T[k], code[k] = lo, SLIP_IN
            if dT is not None:
                dT[k] = (dT[k - 1] / f if k else 0.0) - mu * lo * dalpha[k]
        elif h > hi:
            T[k], code[k] = hi, SLIP_OUT
            if dT is not None:
                dT[k] = (dT[k - 1] * f if k else 0.0) + mu * hi * dalpha[k]
        else:
            T[k] = h
        t_prev = T[k]
    return T, code, dT


def weighted_gradient(x: np.ndarray, w: np.ndarray) -> np.ndarray:
    """``∂(Σ_s w_s ℓ_s)/∂x`` (n+1, 3) at constant weights ``w`` (n,): ``w_{j−1} e_{j−1} − w_j e_j``."""
    d = np.diff(x, axis=0)
    e = d / np.linalg.norm(d, axis=1)[:, None] * np.asarray(w, float)[:, None]
    g = np.zeros_like(x)
    g[:-1] -= e
    g[1:] += e
    return g


def friction_block(x: np.ndarray, dT: np.ndarray) -> np.ndarray:
    """``Σ_s ∂ℓ_s/∂x_j (∂T_s/∂x_l)ᵀ``, shape (n+1, 3, n+1, 3), from ``dT`` (n, n+1, 3) [N/m]."""
    d = np.diff(x, axis=0)
    e = d / np.linalg.norm(d, axis=1)[:, None]
    n = e.shape[0]
    K = np.zeros((n + 1, 3, n + 1, 3))
    for s in range(n):
        outer = e[s][:, None, None] * dT[s][None, :, :]          # (3, n+1, 3)
        K[s + 1] += outer
        K[s] -= outer
    return K


def loop_area(force: np.ndarray, u: np.ndarray) -> float:
    """Area of the closed polygon (force [N], u [m]) by the shoelace formula [N m]."""
    x, y = np.asarray(force, float), np.asarray(u, float)
    return float(abs(0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)))
