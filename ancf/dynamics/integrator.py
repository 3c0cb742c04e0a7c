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

Globalisation (for stiff one-sided springs: a tendon held by its motor through a series spring,
T = k max(0, l − l⁰) with k ≈ 10⁶ N/m, a motor move at the start of a step, tendons switching slack/taut).  Plain
Newton fails there: the force is linear on each side of its kink, so a full step from an iterate where a tendon
is slack stretches it by what the linearisation without its spring asks — 10–100 × the step's own tensions —
and the next steps swing between slack and taut (a cycle, or tensions growing until the state leaves the
domain).  Three parts, each the identity where plain Newton is fine:

* the start: with springs, the better (by ‖r‖) of the predictor and the last state z_{n+1} = z_n — the predictor
  extrapolates the unresolved (ωh ≫ 1) accelerations of the springs' modes (measured: 765 µm from the step's
  stretch, i.e. 765 N, where z_n, the motor's move alone, was 40 µm);
* the direction knows the kinks: the system may report its springs (``springs`` below: stretches
  s_i = l_i − l⁰_i [m], gradients ∇l_i, stiffness k, force cap F_hold), whose force is piecewise linear in s —
  0 (slack), k s (taut), F_hold (held) —, and the update is that of the piecewise-linear model: from Δx = J⁻¹ r
  the predicted stretches s_i − β' ∇l_i·Δx choose each spring's branch, the system is re-linearised on them
  (J ± β' k ∇l ∇lᵀ for a spring entering / leaving its taut branch, r + (f_branch(s_i) − T_i) ∇l_i) and solved
  again until the branches repeat (:data:`ACTIVE_SET_PASSES` passes, the primal–dual active-set step of contact
  mechanics; if they cycle, the first consistent branches in order of the fewest changes).  An update that
  crosses no kink is plain Newton's;
* the length: x ← x − λ Δx with the first λ of a backtracking line search on the residual norm (Armijo)

      ‖r(x − λ Δx)‖ ≤ (1 − c λ) ‖r(x)‖,   c = :data:`ARMIJO`,

  the domain check inside it (a trial outside the model's domain is rejected, λ halved), the next λ the
  minimiser of the quadratic through f(0) = ‖r‖², f'(0) = −2‖r‖² (Δx = J⁻¹ r descends ‖r‖² wherever r is
  differentiable) and f(λ), kept in [λ/10, λ/2]; a trial below the round-off floor (:data:`RESIDUAL_FLOOR` ×
  the force scale) is always taken.  A full step that lowers the residual is taken as before.

Steps that converged without these take the same iterates (to round-off where the start changes).
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


# system(z, v, acc) -> (r (nz,), M (nz, nz), Kt (nz, nz), Ct (nz, nz), scale [force]) or the same with a sixth
# item, the one-sided springs (module docstring) or None: (s (m,) [m], G (m, nz) ∇l in z, k [N/m], F_hold [N]);
# Kt holds k ∇l ∇lᵀ of the springs on their taut branch
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

    x_hold = ((s.z - z_pred) / (h * h * c.beta) - a_const) / k        # the start z_{n+1} = z_n
    try:
        a1, z1, v1, out = evaluate(x)
    except StepFailed:
        # the predictor left the model's domain: start Newton from the last state instead (an admissible
        # point), and let the line search below keep its iterates admissible
        x = x_hold
        a1, z1, v1, out = evaluate(x)
    else:
        if len(out) > 5 and out[5] is not None:
            x, (a1, z1, v1, out) = _spring_start(evaluate, x, (a1, z1, v1, out), x_hold)
    for it in range(1, max_iter + 1):
        r, M, Kt, Ct, scale = out[:5]
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
        if len(out) > 5 and out[5] is not None:
            dx = active_set_update(J, r, dx, out[5], bp)
        if gp * float(np.abs(dx).max()) <= vtol:        # quadratic convergence: the next update is far smaller
            x = x - dx
            a1 = k * x + a_const
            return StepState(z_pred + h * h * c.beta * a1, v_pred + h * c.gamma * a1, x, a1, s.acc), it
        x, (a1, z1, v1, out) = line_search(evaluate, x, dx, rn, scale, it)
    raise StepFailed(f"Newton did not converge in {max_iter} iterations", rn, max_iter)


#: re-chosen branches of one active-set update before the search over all branches (:func:`active_set_update`)
ACTIVE_SET_PASSES = 4


def _spring_start(evaluate: Callable, x: np.ndarray, pred: tuple, x_hold: np.ndarray) -> tuple:
    """(x, its evaluation): of the predictor and the last state (z_{n+1} = z_n, ``x_hold``) the start with the
    smaller residual, for a system with one-sided springs (module docstring)."""
    try:
        held = evaluate(x_hold)
    except StepFailed:
        return x, pred
    if float(np.linalg.norm(held[3][0])) < float(np.linalg.norm(pred[3][0])):
        return x_hold, held
    return x, pred


def spring_branches(s: np.ndarray, k: float, F_hold: float) -> tuple[np.ndarray, np.ndarray]:
    """(branch (m,) int: 0 slack, 1 taut, 2 held at the cap; force T = min(k max(0, s), F_hold) (m,) [N]) of
    one-sided springs at stretches s (m,) [m] (the plant's rule: taut where 0 < T < F_hold)."""
    T = np.minimum(k * np.maximum(s, 0.0), F_hold)
    return np.where(T <= 0.0, 0, np.where(T >= F_hold, 2, 1)), T


def branch_solve(J: np.ndarray, r: np.ndarray, springs: tuple, bp: float, cur: np.ndarray, T: np.ndarray,
                 new: np.ndarray) -> Optional[np.ndarray]:
    """The Newton update (nz,) of the model with the springs on the branches ``new`` (m,) instead of their current
    ``cur`` (forces T (m,) [N]): J ± β' k ∇l ∇lᵀ, r + (f_new(s) − T) ∇l (module docstring); None for a singular
    matrix."""
    s, G, k, F_hold = springs
    JA, rA = J.copy(), r.copy()
    for i in np.flatnonzero(new != cur):
        JA += (bp * k * (float(new[i] == 1) - float(cur[i] == 1))) * np.outer(G[i], G[i])
        rA += ((0.0, k * s[i], F_hold)[new[i]] - T[i]) * G[i]
    try:
        return np.linalg.solve(JA, rA)
    except np.linalg.LinAlgError:
        return None


def active_set_update(J: np.ndarray, r: np.ndarray, dx: np.ndarray, springs: tuple, bp: float,
                      passes: int = ACTIVE_SET_PASSES) -> np.ndarray:
    """The Newton update (nz,) of the piecewise-linear spring model (module docstring) from plain Newton's
    dx = J⁻¹ r: springs = (s (m,) [m], G (m, nz), k [N/m], F_hold [N]), bp = β' [s²] (∂z/∂z̈ of the step).  The
    same dx when no predicted stretch leaves its spring's branch; else the branches re-chosen from the last
    update's predicted stretches (``passes`` times), and when they still do not settle (the passes
    can cycle, e.g. {1} → {2, 3} → {1} for a tendon pulled against its two neighbours released) the first
    consistent branches in order of the fewest changes from the current ones (all 2^m, or 3^m with a holding
    force), or the last update (the line search guards it)."""
    s, G, k, F_hold = springs
    cur, T = spring_branches(s, k, F_hold)

    def predicted(d):
        return spring_branches(s - bp * (G @ d), k, F_hold)[0]

    used = cur
    for _ in range(passes):
        new = predicted(dx)
        if np.array_equal(new, used):
            return dx
        d = branch_solve(J, r, springs, bp, cur, T, new)
        if d is None:
            return dx
        used, dx = new, d
    if np.array_equal(predicted(dx), used):
        return dx
    n_br = 3 if F_hold < float("inf") else 2
    for changes in range(1, len(s) + 1):
        for code in range(n_br ** len(s)):
            new = np.array([(code // n_br ** i) % n_br for i in range(len(s))])
            if int(np.count_nonzero(new != cur)) != changes:
                continue
            d = branch_solve(J, r, springs, bp, cur, T, new)
            if d is not None and np.array_equal(predicted(d), new):
                return d
    return dx


#: Armijo's constant of the line search (module docstring): the least relative decrease of ‖r‖ per unit λ
ARMIJO = 1e-4
#: trials of one line search (λ from 1 down to at least 10⁻¹⁰ … 2⁻⁹)
LINE_SEARCH_TRIES = 10
#: a trial whose residual is below this fraction of the force scale [1] is taken without the decrease test: the
#: round-off of the force terms (sums of ≈ 10³ N terms to 10⁻¹⁶ relative), far below the Newton tolerance's reach
RESIDUAL_FLOOR = 1e-10


def next_lambda(lam: float, f0: float, ft: float) -> float:
    """The next step length after a rejected trial λ (module docstring): the minimiser of the quadratic through
    f(0) = f0 = ‖r‖², f'(0) = −2 f0 and f(λ) = ft, kept in [λ/10, λ/2]; λ/2 for a non-finite ft."""
    if not ft < float("inf"):
        return 0.5 * lam
    curv = (ft - f0 * (1.0 - 2.0 * lam)) / (lam * lam)
    best = f0 / curv if curv > 0.0 else 0.5 * lam
    return min(0.5 * lam, max(0.1 * lam, best))


def line_search(evaluate: Callable, x: np.ndarray, dx: np.ndarray, rn: float, scale: float, it: int):
    """(x − λ Δx, its evaluation) for the first λ of the backtracking line search (module docstring) whose trial is
    admissible and lowers ‖r‖ from rn [N] enough (or lies below the round-off floor of the force scale [N]);
    StepFailed when none of :data:`LINE_SEARCH_TRIES` trials does (``it``: the Newton iteration, for the error)."""
    lam, f0, admissible = 1.0, rn * rn, False
    for _ in range(LINE_SEARCH_TRIES):
        xt = x - lam * dx
        try:
            trial = evaluate(xt)
        except StepFailed:
            lam *= 0.5
            continue
        admissible = True
        rt = float(np.linalg.norm(trial[3][0]))
        if rt <= (1.0 - ARMIJO * lam) * rn or rt <= RESIDUAL_FLOOR * scale:
            return xt, trial
        lam = next_lambda(lam, f0, rt * rt)
    if not admissible:
        raise StepFailed("every Newton trial left the model's domain", rn, it)
    raise StepFailed("no Newton trial lowered the residual (line search)", rn, it)
