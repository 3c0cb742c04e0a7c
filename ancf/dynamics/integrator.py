r"""Generalized-α time integration (Chung & Hulbert 1993, in the form of Arnold & Brüls 2007).

For M(z) z̈ + g(z, ż, t) = 0 the step n → n+1 (size h) solves for the acceleration z̈_{n+1} with an
auxiliary acceleration a:

    (1 − α_m) a_{n+1} + α_m a_n = (1 − α_f) z̈_{n+1} + α_f z̈_n
    z_{n+1} = z_n + h ż_n + h² (½ − β) a_n + h² β a_{n+1}
    ż_{n+1} = ż_n + h (1 − γ) a_n + h γ a_{n+1}
    M(z_{n+1}) z̈_{n+1} + g(z_{n+1}, ż_{n+1}, t_{n+1}) = 0          (equilibrium exactly at t_{n+1})

with, from the spectral radius at infinite frequency ρ∞ ∈ [0, 1],

    α_m = (2ρ∞ − 1)/(ρ∞ + 1),  α_f = ρ∞/(ρ∞ + 1),  γ = ½ + α_f − α_m,  β = ¼ (γ + ½)².

It is second-order accurate for every ρ∞; ρ∞ = 1 is the trapezoidal rule (no numerical dissipation: the
energy of an undamped linear system is conserved exactly, of a nonlinear one to O(h²) without drift), and
ρ∞ < 1 damps the highest frequencies (ωh → ∞) by the factor ρ∞ per step while leaving the low ones nearly
untouched.  Newton on z̈_{n+1} starts from z̈_n, or from −ρ∞ z̈_n when the last steps show unresolved (ωh ≫ 1)
components dominating (their accelerations alternate with the factor −ρ∞), and uses the exact iteration
matrix

    ∂r/∂z̈_{n+1} = M + γ' ∂g/∂ż + β' ∂g/∂z,   β' = h² β (1 − α_f)/(1 − α_m),  γ' = h γ (1 − α_f)/(1 − α_m)

(plus ∂(M z̈)/∂z β', which the caller includes in ∂g/∂z when M depends on z, or omits — a quasi-Newton).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Optional

import numpy as np


@dataclass(frozen=True)
class AlphaCoefficients:
    """The generalized-α coefficients of one spectral radius ρ∞ (module docstring)."""
    rho_inf: float
    alpha_m: float
    alpha_f: float
    gamma: float
    beta: float

    @classmethod
    def from_rho(cls, rho_inf: float) -> "AlphaCoefficients":
        r = float(rho_inf)
        am = (2 * r - 1) / (r + 1)
        af = r / (r + 1)
        g = 0.5 + af - am
        return cls(r, am, af, g, 0.25 * (g + 0.5) ** 2)


@dataclass
class StepState:
    """z (nz,) coordinates, v (nz,) velocities, acc (nz,) accelerations z̈, a (nz,) the auxiliary
    acceleration of the scheme; prev_acc (nz,) or None: z̈ of the step before (chooses the predictor)."""
    z: np.ndarray
    v: np.ndarray
    acc: np.ndarray
    a: np.ndarray
    prev_acc: Optional[np.ndarray] = None


class StepFailed(Exception):
    """A step's Newton iteration did not converge (internal: the caller subdivides or raises a typed
    error).  ``reason`` says why, ``residual`` is the last residual norm."""

    def __init__(self, reason: str, residual: float = float("nan"), iterations: int = 0):
        super().__init__(reason)
        self.reason, self.residual, self.iterations = reason, residual, iterations


# system(z, v, acc) -> (r (nz,), M (nz, nz), Kt (nz, nz), Ct (nz, nz), scale [force])
System = Callable[[np.ndarray, np.ndarray, np.ndarray], tuple]


def alpha_step(s: StepState, h: float, c: AlphaCoefficients, system: System, *, rtol: float = 1e-9,
               atol: float = 1e-10, vtol: float = 1e-9, max_iter: int = 12) -> tuple[StepState, int]:
    """One generalized-α step of size h [s] from state ``s``; ``system`` gives the residual
    r = M z̈ + g and its derivatives at (z, ż, z̈).  Converged when ‖r‖ ≤ atol + rtol·scale (scale: the size
    of the force terms the system reports), or when a Newton update changes the velocities by at most
    ``vtol`` (max norm; [m/s] for positions, [1/s] for slopes) — the residual alone is a poor measure for the
    light slope coordinates, whose accelerations a tiny force moves a lot.  Returns (new state, Newton
    iterations = system evaluations); raises StepFailed."""
    k = (1.0 - c.alpha_f) / (1.0 - c.alpha_m)
    bp, gp = h * h * c.beta * k, h * c.gamma * k
    # predictor: z̈_n when the motion is resolved (smooth accelerations), −ρ∞ z̈_n when unresolved (ωh ≫ 1)
    # components dominate — their accelerations change sign every step with the factor −ρ∞; the last two
    # steps tell which model fits (measured on the `paper` actuator at the step resolving its first mode to
    # 1 %: 4.0 Newton iterations per step instead of 5.0 with z̈_n alone, and as few as before at 1 ms)
    x = s.acc.copy()
    if s.prev_acc is not None and \
            np.linalg.norm(s.acc + c.rho_inf * s.prev_acc) < np.linalg.norm(s.acc - s.prev_acc):
        x = -c.rho_inf * s.acc
    a_const = (c.alpha_f * s.acc - c.alpha_m * s.a) / (1.0 - c.alpha_m)
    z_pred = s.z + h * s.v + h * h * (0.5 - c.beta) * s.a
    v_pred = s.v + h * (1.0 - c.gamma) * s.a
    def evaluate(x):
        a1 = k * x + a_const
        z1 = z_pred + h * h * c.beta * a1
        v1 = v_pred + h * c.gamma * a1
        return a1, z1, v1, system(z1, v1, x)

    try:
        a1, z1, v1, out = evaluate(x)
    except StepFailed:
        # the predictor left the model's domain: start Newton from the last state instead (z_{n+1} = z_n,
        # an admissible point), and let the backtracking below keep its iterates admissible
        x = ((s.z - z_pred) / (h * h * c.beta) - a_const) / k
        a1, z1, v1, out = evaluate(x)
    for it in range(1, max_iter + 1):
        r, M, Kt, Ct, scale = out
        rn = float(np.linalg.norm(r))
        if not np.isfinite(rn):
            raise StepFailed("the residual is not finite", rn, it)
        if rn <= atol + rtol * scale:                  # an exact solution (e.g. a state at rest)
            return StepState(z1, v1, x, a1, s.acc), it
        J = M + gp * Ct + bp * Kt
        try:
            dx = np.linalg.solve(J, r)
        except np.linalg.LinAlgError as exc:
            raise StepFailed(f"singular iteration matrix ({exc})", rn, it) from None
        if gp * float(np.abs(dx).max()) <= vtol:        # quadratic convergence: the next update is far smaller
            x = x - dx
            a1 = k * x + a_const
            return StepState(z_pred + h * h * c.beta * a1, v_pred + h * c.gamma * a1, x, a1, s.acc), it
        # backtrack along the Newton direction while the trial state leaves the model's domain
        lam = 1.0
        for _ in range(10):
            try:
                a1, z1, v1, out = evaluate(x - lam * dx)
                x = x - lam * dx
                break
            except StepFailed:
                lam *= 0.5
        else:
            raise StepFailed("every Newton trial left the model's domain", rn, it)
    raise StepFailed(f"Newton did not converge in {max_iter} iterations", rn, max_iter)
