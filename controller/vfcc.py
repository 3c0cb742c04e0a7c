r"""Virtual-force compliance controller (VF-CC), the paper's baseline (Sec. IV-B, ref. [25]).

The measured error is turned into a virtual tip force and the IK is re-solved with it as an additional
load::

    F_v = χ ∘ (p_m − p_d)            χ = (χ_x, χ_y, χ_z) [N/m], paper: 10 each
    [q, T] ← IK(p_d, p, F_v);  send l_c(q)

**Units of χ (flagged interpretation).**  The paper gives χ = 10 without units.  We read it as N/m:
with the plant's locked compliance C_L ≈ 4–6 mm/N the loop gain C_L χ is then ≈ 0.05 and VF-CC leaves
most of the load deflection uncorrected — the behaviour Table I reports (errors of several mm).  Read as
N/mm (10⁴ N/m) the loop gain would be ≈ 50 and both laws below would diverge (|1 − C_L χ| > 1), which the
paper's finite residuals rule out.  χ is a parameter; pass an array for per-axis gains.

Saturation: a virtual force the tensions cannot carry at the target commands the nearest reachable state
(the step is reported ``saturated``; the integral law holds F_v meanwhile — anti-windup) instead of ending
the run.

``law="proportional"`` (default, the literal description): F_v is recomputed from the current error each
step, so at the fixed point e* = (I + C_L χ)⁻¹ C_L F — a residual error proportional to the load that
shrinks only as 1/(1 + C_L χ).  ``law="integral"``: F_v ← F_v + χ e (an integral variant, converging at
the rate |1 − C_L χ| per step).
"""

from __future__ import annotations

import time

import numpy as np

from ancf import Model
from ancf.errors import InputError

from .errors import check_finite

from .base import Controller, StepReport


class VFCC(Controller):
    """Virtual-force compliance controller.

    Parameters (SI)
    ----------
    model : controller's :class:`ancf.Model`;  pressure : p [Pa]
    chi : gain χ [N/m], scalar or (3,) per axis (paper: 10)
    law : "proportional" (F_v = χ e) | "integral" (F_v += χ e)
    tolerance : stop when ‖p_m − p_d‖ < tolerance [m]
    """

    name = "VF-CC"

    def __init__(self, model: Model, pressure: float, *, chi=10.0, law: str = "proportional",
                 tolerance: float = 2e-4):
        super().__init__(model, pressure, tolerance=tolerance)
        chi = check_finite("chi", chi)
        if chi.shape not in ((), (1,), (3,)):
            raise InputError(f"chi must be a scalar or (3,) [N/m], got shape {chi.shape}")
        chi = np.broadcast_to(chi, (3,)).astype(float).copy()
        if np.any(chi < 0):
            raise InputError(f"chi must be >= 0 N/m, got {chi}")
        if not isinstance(law, str) or law not in ("proportional", "integral"):
            raise InputError(f"VF-CC law must be 'proportional' or 'integral', got {law!r}")
        self.chi = chi
        self.law = law
        self._F = np.zeros(3)

    @property
    def estimate(self) -> np.ndarray:
        """The virtual force F_v [N] (3,)."""
        return self._F.copy()

    def start(self, target, initial_load=(0.0, 0.0, 0.0)) -> np.ndarray:
        pd = check_finite("target", target, (3,))
        F0 = check_finite("initial_load", initial_load, (3,))
        droop = self._warm_start()
        eq = self.model.ik(pd, self.pressure, F0, q0=droop.q, tensions0=droop.tensions)
        self.target, self.state, self._F = pd, eq, F0.copy()
        return eq.tendon_lengths.copy()

    def step(self, measured_tip) -> StepReport:
        e, en, t0, idle = self._begin_step(measured_tip)
        if idle is not None:
            return idle
        F = self.chi * e if self.law == "proportional" else self._F + self.chi * e
        eq, saturated, note = self._reach(self.target, F)
        if not (saturated and self.law == "integral"):   # anti-windup: the integral holds while saturated
            self._F = F
        self.state = eq
        return StepReport(e, en, False, eq.tendon_lengths.copy(), self.estimate, "vfcc",
                          time.perf_counter() - t0, ik_iterations=eq.iterations, notes=[note] if note else [],
                          saturated=saturated,
                          reach_gap=float(np.linalg.norm(eq.tip - self.target)) if saturated else 0.0)
