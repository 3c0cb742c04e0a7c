r"""A dynamic tip-load observer: a Kalman filter on a reduced modal model about the commanded locked state.

**The reduced model.**  About a locked equilibrium (motor lengths l₀ [m], pressure p, tip load F₀ [N]:
:meth:`ancf.Model.fk_locked`) the actuator is M δz̈ + C δż + K δz = J_pᵀ δF + J_Aᵀ λ with the taut tendons'
lengths prescribed, J_A δz = δl.  Split δz = S δl + y, S = ∂q/∂l the quasi-static response to the lengths
(J_A S = I, K S = J_Aᵀ Λ), y in the constraint null space spanned by the locked modes φ_k (mass-normalised,
:meth:`ancf.Model.modes`; φ_kᵀ J_Aᵀ = 0, φ_kᵀ K S = 0).  With mass-proportional damping C = α M (the simulated
rig's, :mod:`hardware.sim_dynamics`; 2 ζ_k ω_k = α) the modal coordinates η_k = φ_kᵀ M y obey
η̈_k + 2ζ_kω_k η̇_k + ω_k² η_k = t_k·δF − g_k·(δl̈ + α δl̇),  t_k = J_p φ_k (the tip shape [m]),
g_k = φ_kᵀ M S [kg/…].  The substitution ξ_k = η_k + g_k·δl removes the input's derivatives:

    ξ̈_k + 2ζ_kω_k ξ̇_k + ω_k² ξ_k = ω_k² g_k·δl + t_k·δF,
    δp = D_l δl + Σ_k t_k ξ_k + D_F δF,   D_l = J_l − Σ_k t_k g_kᵀ,   D_F = C_p − Σ_k t_k t_kᵀ / ω_k²,

J_l = ∂p/∂l and C_p the locked tip compliance: the truncated modes keep the exact static response (the
residual-flexibility terms D); each mode is the closed-form damped oscillator.  J_l and S come from central
differences of the locked FK (h = 1 µm), C_p from the exact KKT compliance (:func:`ancf.compliance.locked`).

**The load state.**  The load enters in displacement units, δd = C_p δF [m] (the static tip deflection it
causes), as an integrated random walk: d̈ = w, E[w wᵀ] = q I δ(t) [m²/s³].  In these units the process noise
is isotropic, so the filter has about the same bandwidth in every direction although the actuator is ~50×
stiffer along its axis; F̂ = F₀ + C_p⁻¹ d̂.  Observer state x = [ξ (k), ξ̇ (k), δd (r), ḋ (r)] (and the
oscillator's (h_c, h_s) (2r), below), measured tip p_m = p₀ + δp + v, v the tracker's white noise (std σ per coordinate).

**The filter.**  Exact zero-order-hold discretisation at the loop period h (matrix exponential; Q by Van
Loan), the steady-state Kalman gain K from the discrete Riccati equation.  Per period:
x⁻ = A x + B δl̄ (δl̄ the mean commanded length over the period), x = x⁻ + K (p_m − p₀ − D_l δl − H x⁻).

**Bandwidth and noise.**  Both follow from K, not from a simulation: the estimate's response to the true
load is the closed loop (true modal plant → filter); ``bandwidth_Hz()`` is the lowest −3 dB frequency of
the diagonal of that transfer F → F̂ over the three world axes, ``settling_time_s()`` the time its step
response stays within 5 %, and ``noise_std_N(σ)`` the standard deviation of F̂ per axis for white tip noise
σ [m] with a constant load: the discrete Lyapunov equation X = Φ X Φᵀ + σ² K Kᵀ, Φ = (I − K H) A, then
C_p⁻¹ X_dd C_p⁻ᵀ.  The process noise q is chosen (bisection in log q) so that the bandwidth is the one asked
for.  On the `paper` actuator at 60 kPa with the tendons of the cyclic-load experiment and a 12 Hz observer
the settling time is ≈ 0.06 s and the lateral load estimate's std for 0.05 mm tracker noise ≈ 3–4 mN
(``tests/test_controller/test_observer.py`` checks all three against the nonlinear model and simulated
noise).

**Robustness to model error** (``model_error``, :meth:`LoadObserver.stability_gain`).  The controller
built on the estimate (:mod:`controller.dynamic_lacc`) commands δl = G N(s) F̂, G = −J_l⁺ C the static inverse
and N its prediction / feed-forward / command filter (``loop_factor``), and the filter subtracts the model's
response to δl from the measured tip.  On a plant whose length-to-tip response P differs from the model's P̂,
the remainder (P − P̂) δl is read as load: the loop L(f) = O(f) (P − P̂)(f) G N(f) closes, O(f) (3 × 3) the
filter's map from a tip disturbance to F̂ (from its eigen-decomposition, exact for the discrete filter).  By
the small-gain theorem the loop is stable when the spectral radius of L stays below 1 at every frequency.
The plants bounded here have every locked mode's frequency scaled by 1 ± ε (a bending stiffness off by
(1 ± ε)²; the tip shapes, the input coupling g, D_l and the mass-proportional damping α as the model's):
P(f) − P̂(f) = Σ_k t_k g_kᵀ (H_k(sω_k) − H_k(ω_k)), H_k(ω) = ω²/(ω² − (2πf)² + iα 2πf).  Two findings set
the design: the lightly damped second mode pair (32 Hz; ζ = α/2ω ≈ 0.009) makes (P − P̂) large there and O
passes it — a 12 Hz filter on unfiltered commands is unstable for a plant 2.5 % soft in frequency — so the
commands must be low-passed below it (:class:`controller.DynamicLACC`'s ``command_filter_hz``); and near
the first mode the bound caps the bandwidth (≈ 3–6 Hz for ε = 12 % on the `paper` actuator).  With
``model_error`` the process noise is lowered (bisection in log q) until sup_f ρ(L) ≤ 1/``gain_margin``.
The bound is sufficient, not necessary, and holds for the modes the model keeps (``count``); the command
filter keeps the loop's gain small above them.

**Internal model of a periodic load** (:meth:`LoadObserver.set_harmonic`).  A load with a periodic part
(the cyclic experiment's 1 − cos) is a constant plus a harmonic at its fundamental ω_L; the random walk reads
the harmonic with the filter's lag.  With the oscillator the load along U is d + h_c, ḣ_c = ω_L h_s,
ḣ_s = −ω_L h_c, white noise of intensity q_h on (h_c, h_s): an undamped mode of the filter's model at ω_L,
so the steady-state filter's innovation has a zero there and a load at ω_L is read without lag or gain
error (the internal-model principle; ``response(f_L)`` is the identity up to the load's zero-order hold
e^{−iω_L h/2}).  Whatever the model mispredicts at ω_L is read as load too, and the controller cancels it:
the tip error at ω_L goes to zero on a plant that differs from the model, as long as the loop is stable.
The phasor :attr:`LoadObserver.phasor` = U (h_c − i h_s) is the harmonic a e^{i(ω_L t + φ)}: the controller
advances it by rotation (exact for a sinusoid) instead of a rate.  In :meth:`stability_gain` the loop's
controller map from a tip disturbance to the lengths is then G N(f) O_d(f) + M_h(f) O_h(f), O_d and O_h the
filter's maps to the walk and to (h_c, h_s), M_h the controller's map of the oscillator's states
(``harmonic_map``); the bound is the spectral radius of ΔP(f) times that map, as before.

**Re-linearisation.**  When the estimate or the commanded lengths move away from the linearisation point
(:meth:`LoadObserver.relinearise`), a new modal model is built about the new locked state; F̂ and its rate
carry over, and so does the modes' dynamic part (ξ minus its quasi-static value), mode by mode.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Optional

import numpy as np
import scipy.linalg as sla

from ancf import Model
from ancf import compliance as cp
from ancf.dynamics import consistent_mass, tip_mass_matrix
from ancf.errors import InputError

from .errors import check_finite, number

#: central-difference step of the lengths for S = ∂q/∂l and J_l = ∂p/∂l [m]
LENGTH_STEP = 1e-6


@dataclass(frozen=True)
class ModalModel:
    """The reduced modal model about one locked state (module docstring), SI.

    lengths (m,) [m], pressure [Pa], load (3,) [N]: the linearisation point; tip (3,) [m], tensions (m,) [N]
    there; omega (k,) [rad/s], zeta (k,) [-]; tip_shapes (k, 3) [m/√kg]; g (k, m) = φᵀ M S; J_l (3, m) [m/m];
    C (3, 3) [m/N] locked compliance; dT_dl (m, m) [N/m], dT_dF (m, 3) [N/N]: the tensions' sensitivities;
    shapes (k, ndof) the mass-normalised mode shapes φ_k, shapes_M (k, ndof) φ_kᵀ M (modal coordinates of a
    displacement: η = shapes_M δq)."""
    lengths: np.ndarray
    pressure: float
    load: np.ndarray
    tip: np.ndarray
    tensions: np.ndarray
    omega: np.ndarray
    zeta: np.ndarray
    tip_shapes: np.ndarray
    g: np.ndarray
    J_l: np.ndarray
    C: np.ndarray
    dT_dl: np.ndarray
    dT_dF: np.ndarray
    shapes: np.ndarray = None
    shapes_M: np.ndarray = None

    @property
    def frequencies_hz(self) -> np.ndarray:
        return self.omega / (2 * math.pi)

    @property
    def D_F(self) -> np.ndarray:
        """Residual flexibility of the load (3, 3) [m/N]: C − Σ t_k t_kᵀ / ω_k²."""
        return self.C - np.einsum("ki,kj,k->ij", self.tip_shapes, self.tip_shapes, 1.0 / self.omega ** 2)

    @property
    def D_l(self) -> np.ndarray:
        """Residual length-to-tip map (3, m): J_l − Σ t_k g_kᵀ."""
        return self.J_l - self.tip_shapes.T @ self.g

    def quasi_static(self, dl: np.ndarray, dF: np.ndarray) -> np.ndarray:
        """ξ (k,) at rest under δl (m,) [m] and δF (3,) [N]: g·δl + t·δF / ω²."""
        return self.g @ dl + self.tip_shapes @ dF / self.omega ** 2

    def step_response(self, t: np.ndarray, dF: np.ndarray) -> np.ndarray:
        """Tip motion δp (len(t), 3) [m] after a tip-load step δF (3,) [N] at t = 0 from rest, lengths held:
        the closed-form response of each damped mode plus the residual flexibility."""
        t = np.asarray(t, float)[:, None]
        z, w = self.zeta[None, :], self.omega[None, :]
        wd = w * np.sqrt(1 - z ** 2)
        h = 1 - np.exp(-z * w * t) * (np.cos(wd * t) + z / np.sqrt(1 - z ** 2) * np.sin(wd * t))
        amp = (self.tip_shapes @ dF) / self.omega ** 2                     # (k,) static modal amplitudes
        return (h * amp) @ self.tip_shapes + self.D_F @ dF


def modal_model(model: Model, lengths, pressure: float, load=(0.0, 0.0, 0.0), *, count: int = 4,
                damping_ratio: float = 0.05, near=None) -> ModalModel:
    """The reduced modal model (module docstring) of ``model`` about its locked state at motor ``lengths``
    (m,) [m], ``pressure`` [Pa], tip ``load`` (3,) [N], with ``count`` locked modes and mass-proportional
    damping of ratio ``damping_ratio`` at the first mode (every mode decays at ζ ω₁).  ``near``: an
    equilibrium to warm-start the locked FK from."""
    lengths = check_finite("lengths", lengths, (model.m,))
    load = check_finite("load", load, (3,))
    zeta1 = number("damping_ratio", damping_ratio)
    if not zeta1 < 1:
        raise InputError(f"damping_ratio must be in [0, 1), got {zeta1:g}")
    kw = {} if near is None else {"q0": near.q, "tensions0": near.tensions}
    eq = model.fk_locked(lengths, pressure, load, **kw)
    if not eq.active:
        raise InputError("the dynamic load observer needs at least one taut tendon at the linearisation point")
    r0 = model.modes(eq, 1)
    alpha = 2.0 * zeta1 * 2 * math.pi * float(r0.frequencies_hz[0])
    r = model.modes(eq, count, damping={"alpha": alpha, "beta": 0.0, "axial": 0.0})
    m = model.m
    dq, dp, dT = np.zeros((model.ndof, m)), np.zeros((3, m)), np.zeros((m, m))
    for i in range(m):
        e = np.zeros(m)
        e[i] = LENGTH_STEP
        a = model.fk_locked(lengths + e, pressure, load, q0=eq.q, tensions0=eq.tensions)
        b = model.fk_locked(lengths - e, pressure, load, q0=eq.q, tensions0=eq.tensions)
        dq[:, i] = (a.q - b.q) / (2 * LENGTH_STEP)
        dp[:, i] = (a.tip - b.tip) / (2 * LENGTH_STEP)
        dT[:, i] = (np.asarray(a.tensions) - np.asarray(b.tensions)) / (2 * LENGTH_STEP)
    p = model.params
    M = consistent_mass(model.n, model._N, model._wq, p.line_mass)
    if p.tip_mass > 0:
        M = M + tip_mass_matrix(eq.q, p.tool_offset, p.tip_mass)
    L = cp.locked(model, eq, "exact", active=eq.active)
    omega = 2 * math.pi * np.asarray(r.frequencies_hz, float)
    return ModalModel(lengths.copy(), float(pressure), load.copy(), eq.tip.copy(), np.asarray(eq.tensions, float),
                      omega, alpha / (2 * omega), np.asarray(r.tip_shapes, float), r.shapes @ M @ dq, dp, L.C_p,
                      dT, L.dT_dF, np.asarray(r.shapes, float), r.shapes @ M)


def load_basis(C: np.ndarray, rcond: float = 0.05) -> np.ndarray:
    """(3, r) orthonormal directions of the estimated load: the principal directions of the locked compliance
    C (3, 3) [m/N] whose compliance is above ``rcond`` × the largest (the stiff axial one is cut, as in LACC)."""
    U, s, _ = np.linalg.svd(0.5 * (C + C.T))
    return U[:, s > rcond * s[0]]


def _matrices(mm: ModalModel, U: np.ndarray, plant: bool = False):
    """Continuous (A (n, n), B (n, m), Gw (n, r), H (3, n), D_l (3, m)) of the observer's state space with the
    load along the columns of U (3, r); ``plant``: U = I, the true load as an input (the closed loop)."""
    k, m, r = len(mm.omega), mm.J_l.shape[1], U.shape[1]
    n = 2 * k + 2 * r
    A = np.zeros((n, n))
    A[:k, k:2 * k] = np.eye(k)
    A[k:2 * k, :k] = -np.diag(mm.omega ** 2)
    A[k:2 * k, k:2 * k] = -np.diag(2 * mm.zeta * mm.omega)
    A[k:2 * k, 2 * k:2 * k + r] = mm.tip_shapes @ U
    A[2 * k:2 * k + r, 2 * k + r:] = np.eye(r)
    B = np.zeros((n, m))
    B[k:2 * k] = (mm.omega ** 2)[:, None] * mm.g
    Gw = np.zeros((n, r))
    Gw[2 * k + r:] = np.eye(r)
    Gf = np.zeros((n, 3))                   # a white tip force: it drives the modes only
    Gf[k:2 * k] = mm.tip_shapes
    H = np.zeros((3, n))
    H[:, :k] = mm.tip_shapes.T
    H[:, 2 * k:2 * k + r] = mm.D_F @ U
    return A, B, Gw, Gf, H, mm.D_l


def _with_harmonic(A, B, Gw, Gf, H, k: int, r: int, U: np.ndarray, mm: ModalModel, omega: float, qh: float):
    """The state space of :func:`_matrices` extended by the load's oscillator at ``omega`` [rad/s] (module
    docstring, internal model): 2r states (h_c, h_s) after the random walk's, ḣ_c = ω h_s, ḣ_s = −ω h_c, the load
    along U being d + h_c; white noise of intensity ``qh`` [N²/s] drives both.  Returns (A, B, Gw, Gf, H) with
    the harmonic's noise as Gw's extra columns (scaled by √(qh / q) by the caller: Gw's first r are the walk's)."""
    n = A.shape[0]
    A2 = np.zeros((n + 2 * r, n + 2 * r))
    A2[:n, :n] = A
    A2[n:n + r, n + r:] = omega * np.eye(r)
    A2[n + r:, n:n + r] = -omega * np.eye(r)
    A2[k:2 * k, n:n + r] = mm.tip_shapes @ U
    B2 = np.vstack([B, np.zeros((2 * r, B.shape[1]))])
    Gh = np.zeros((n + 2 * r, 2 * r))
    Gh[n:] = math.sqrt(qh) * np.eye(2 * r)
    Gw2 = np.hstack([np.vstack([Gw, np.zeros((2 * r, Gw.shape[1]))]), Gh])
    Gf2 = np.vstack([Gf, np.zeros((2 * r, Gf.shape[1]))])
    H2 = np.hstack([H, mm.D_F @ U, np.zeros((3, r))])
    return A2, B2, Gw2, Gf2, H2


def _discretise(A, B, Gw, h: float):
    """Zero-order-hold (Ad, Bd) and the process-noise covariance per unit intensity Qd (Van Loan)."""
    n, m = B.shape
    E = sla.expm(np.block([[A, B], [np.zeros((m, n + m))]]) * h)
    Ad, Bd = E[:n, :n], E[:n, n:]
    V = sla.expm(np.block([[-A, Gw @ Gw.T], [np.zeros((n, n)), A.T]]) * h)
    Qd = Ad @ V[:n, n:]
    return Ad, Bd, 0.5 * (Qd + Qd.T)


class LoadObserver:
    """Steady-state Kalman filter for the tip load (module docstring).

    Parameters (SI)
    ----------
    modal : the :class:`ModalModel` to start from;  period : loop period h [s] (1 ms: 1 kHz)
    tip_noise_std : the tracker's noise σ [m] per coordinate (the measurement noise the filter assumes)
    bandwidth_hz : the estimate's −3 dB bandwidth [Hz] the process noise is tuned to (None: ``process_noise``)
    process_noise : intensity q of the load's integrated random walk [m²/s³] (used when no bandwidth is asked)
    model_error : the bound ε of the plant's modal frequencies' error (relative, every mode alike: a bending
        stiffness off by (1 ± ε)²) the loop must stay stable for (None: the model is taken as exact); the
        bandwidth is lowered below ``bandwidth_hz`` where needed (``robust_limited``; module docstring,
        robustness)
    gain_margin : the factor by which the small-gain bound holds (:meth:`stability_gain` ≤ 1/gain_margin)
    loop_factor : N(f) (len(f),) complex: the controller between F̂ and the lengths relative to the static
        inverse G = −J_l⁺ C (prediction, dynamic feed-forward, command filter; None: 1)
    """

    def __init__(self, modal: ModalModel, period: float = 1e-3, *, tip_noise_std: float = 5e-5,
                 bandwidth_hz: Optional[float] = 12.0, process_noise: float = 1.0, force_noise: float = 1e-6,
                 rcond: float = 0.05, model_error: Optional[float] = None, gain_margin: float = 1.5,
                 loop_factor: Optional[Callable[[np.ndarray], np.ndarray]] = None):
        self.force_noise = number("force_noise [N² s]", force_noise)
        self.rcond = number("rcond", rcond, strict=True)
        self.period = number("period [s]", period, strict=True)
        self.sigma = number("tip_noise_std [m]", tip_noise_std, strict=True)
        self.modal = modal
        self.model_error = None if model_error is None else number("model_error", model_error, strict=True)
        if self.model_error is not None and not self.model_error < 0.5:
            raise InputError(f"model_error (relative error of the modes' frequencies) must be in (0, 0.5), "
                             f"got {self.model_error:g}")
        self.gain_margin = number("gain_margin", gain_margin, strict=True)
        if not self.gain_margin >= 1:
            raise InputError(f"gain_margin must be at least 1, got {self.gain_margin:g}")
        self.loop_factor = loop_factor
        self.harmonic: Optional[tuple] = None       # (ω [rad/s], q_h [N²/s]) of the load's oscillator, or None
        self.harmonic_map: Optional[Callable[[np.ndarray], np.ndarray]] = None
        self.requested_bandwidth_hz = None
        if bandwidth_hz is not None:
            bw = number("bandwidth_hz", bandwidth_hz, strict=True)
            nyq = 0.5 / self.period
            if not bw < 0.25 * nyq:
                raise InputError(f"bandwidth_hz must be below a quarter of the loop's Nyquist frequency "
                                 f"({0.25 * nyq:g} Hz at {self.period * 1e3:g} ms), got {bw:g}")
            self.requested_bandwidth_hz = bw
            lo, hi = self._tune(self.bandwidth_Hz, bw, f"a bandwidth of {bw:g} Hz")
            self.q = 10.0 ** (0.5 * (lo + hi))
        else:
            self.q = number("process_noise [N²/s³]", process_noise, strict=True)
        self.robust_limited = False
        if self.model_error is not None:
            self._build()
            if self.stability_gain() > 1.0 / self.gain_margin:
                start = int(math.floor(math.log10(self.q))) - 3          # a few decades below: the scan is short
                lo, hi = self._tune(self.stability_gain, 1.0 / self.gain_margin, "a stable loop", first=start)
                if lo == hi and start > -12:
                    lo, hi = self._tune(self.stability_gain, 1.0 / self.gain_margin, "a stable loop", first=-12)
                if lo == hi:
                    raise InputError(f"no observer keeps the loop stable with gain margin {self.gain_margin:g} "
                                     f"for a modal frequency error of ±{self.model_error:.0%}")
                self.q = 10.0 ** lo
                self.robust_limited = True
        self._build()
        self.x = np.zeros(self.n)

    # ------------------------------------------------------------------------------ the filter
    def _gain(self, q: float):
        self.U = load_basis(self.modal.C, self.rcond)
        A, B, Gw, Gf, H, Dl = _matrices(self.modal, self.U)
        Gw = math.sqrt(q) * Gw
        if self.harmonic is not None:
            k, r = len(self.modal.omega), self.U.shape[1]
            A, B, Gw, Gf, H = _with_harmonic(A, B, Gw, Gf, H, k, r, self.U, self.modal, *self.harmonic)
        Ad, Bd, Qd = _discretise(A, B, np.hstack([Gw, math.sqrt(self.force_noise) * Gf]), self.period)
        R = self.sigma ** 2 * np.eye(3)
        P = sla.solve_discrete_are(Ad.T, H.T, Qd + 1e-30 * np.eye(len(Ad)), R)
        K = P @ H.T @ np.linalg.inv(H @ P @ H.T + R)
        return Ad, Bd, H, Dl, K

    def _build(self) -> None:
        self.Ad, self.Bd, self.H, self.Dl, self.K = self._gain(self.q)
        self.n = len(self.Ad)
        self.k = len(self.modal.omega)
        self.r = self.U.shape[1]
        k, r = self.k, self.r
        self._out = np.zeros((r, self.n))           # F̂ − F₀ along U: the walk d plus the oscillator's h_c
        self._out[:, 2 * k:2 * k + r] = np.eye(r)
        if self.harmonic is not None:
            self._out[:, 2 * k + 2 * r:2 * k + 3 * r] = np.eye(r)

    def _tune(self, measure: Callable[[], float], level: float, what: str, first: int = -8) -> tuple:
        """(lo, hi) in log10 q, 0.01 apart: ``measure()`` (rising with q: the bandwidth, the stability gain) is
        below ``level`` at 10^lo and reaches it at 10^hi (a scan up in decades, then bisection in log q)."""
        lo = float(first)
        for e in range(first, 13):
            self.q = 10.0 ** e
            self._build()
            if measure() >= level:
                break
            lo = float(e)
        else:
            raise InputError(f"no process noise gives the observer {what}")
        hi = float(e)
        for _ in range(40):
            mid = 0.5 * (lo + hi)
            self.q = 10.0 ** mid
            self._build()
            if measure() < level:
                lo = mid
            else:
                hi = mid
            if hi - lo < 0.01:
                break
        return lo, hi

    def update(self, measured_tip, lengths_now, lengths_mean=None) -> None:
        """One period: predict with the mean commanded lengths over it (m,) [m] (default ``lengths_now``), then
        correct with the measured tip (3,) [m] taken with the motors at ``lengths_now`` (m,) [m]."""
        y = check_finite("measured tip position", measured_tip, (3,))
        mm = self.modal
        ln = np.asarray(lengths_now, float)
        lm = ln if lengths_mean is None else np.asarray(lengths_mean, float)
        x = self.Ad @ self.x + self.Bd @ (lm - mm.lengths)
        innov = y - mm.tip - self.Dl @ (ln - mm.lengths) - self.H @ x
        self.x = x + self.K @ innov

    # ------------------------------------------------------------------------------ estimates
    @property
    def load(self) -> np.ndarray:
        """F̂ (3,) [N]: the tip load estimate (beyond the model's own weight)."""
        return self.modal.load + self.U @ (self._out @ self.x)

    @property
    def load_rate(self) -> np.ndarray:
        """dF̂/dt (3,) [N/s] (the walk's rate plus the oscillator's ω h_s)."""
        k, r = self.k, self.r
        rate = self.x[2 * k + r:2 * k + 2 * r].copy()
        if self.harmonic is not None:
            rate += self.harmonic[0] * self.x[2 * k + 3 * r:2 * k + 4 * r]
        return self.U @ rate

    @property
    def walk(self) -> tuple:
        """(F₀ + U d̂ (3,) [N], U ḋ̂ (3,) [N/s]): the load estimate without its oscillator part."""
        k, r = self.k, self.r
        return self.modal.load + self.U @ self.x[2 * k:2 * k + r], self.U @ self.x[2 * k + r:2 * k + 2 * r]

    @property
    def phasor(self) -> np.ndarray:
        """(3,) complex [N]: the oscillator's load U (h_c − i h_s) = the harmonic a e^{i(ωt + φ)} now (its real
        part is the harmonic load); zeros without an oscillator."""
        if self.harmonic is None:
            return np.zeros(3, complex)
        k, r = self.k, self.r
        return self.U @ (self.x[2 * k + 2 * r:2 * k + 3 * r] - 1j * self.x[2 * k + 3 * r:2 * k + 4 * r])

    def set_harmonic(self, freq_hz: Optional[float], noise: float = 0.0) -> None:
        """Add (or retune, or with None remove) the load's oscillator at ``freq_hz`` [Hz], driven by white noise
        of intensity ``noise`` [N²/s] (module docstring, internal model); the estimate carries over: F̂, its rate
        (the walk keeps what the oscillator no longer holds) and the modes."""
        F, Fdot, ph = self.load, self.load_rate, self.phasor
        old = self.harmonic
        x_modes = self.x[:2 * self.k].copy()
        if freq_hz is None:
            self.harmonic = None
        else:
            f = number("freq_hz", freq_hz, strict=True)
            if not f < 0.1 / self.period:
                raise InputError(f"the load's oscillator must be below a fifth of the Nyquist frequency, got {f:g} Hz")
            self.harmonic = (2 * math.pi * f, number("noise [N²/s]", noise, strict=True))
        self._build()
        k, r = self.k, self.r
        x = np.zeros(self.n)
        x[:2 * k] = x_modes
        keep = ph if (self.harmonic is not None and old is not None) else np.zeros(3, complex)
        x[2 * k:2 * k + r] = self.U.T @ (F - self.modal.load - keep.real)
        x[2 * k + r:2 * k + 2 * r] = self.U.T @ (Fdot - (old[0] * -keep.imag if old is not None and
                                                         self.harmonic is not None else 0.0))
        if self.harmonic is not None:
            x[2 * k + 2 * r:2 * k + 3 * r] = self.U.T @ keep.real
            x[2 * k + 3 * r:] = -(self.U.T @ keep.imag)
        self.x = x

    def relinearise(self, modal: ModalModel, lengths) -> None:
        """Move the filter to a new modal model (module docstring), the motors at ``lengths`` (m,) [m]: F̂, its
        rate and the modes' dynamic part (ξ minus its quasi-static value, carried over through the mode
        shapes: η_new = φ_newᵀ M Σ φ_old η_old) carry over."""
        old, k = self.modal, self.k
        ln = check_finite("lengths", lengths, (len(old.lengths),))
        F, (_, rate), ph = self.load, self.walk, self.phasor
        dyn = self.x[:k] - old.quasi_static(ln - old.lengths, F - old.load)
        to_new = modal.shapes_M @ old.shapes.T                             # (k_new, k_old)
        vel = self.x[k:2 * k].copy()
        self.modal = modal
        self._build()
        kk, r = self.k, self.r
        x = np.zeros(self.n)
        x[:kk] = modal.quasi_static(ln - modal.lengths, F - modal.load) + to_new @ dyn
        x[kk:2 * kk] = to_new @ vel
        x[2 * kk:2 * kk + r] = self.U.T @ (F - modal.load - ph.real)
        x[2 * kk + r:2 * kk + 2 * r] = self.U.T @ rate
        if self.harmonic is not None:
            x[2 * kk + 2 * r:2 * kk + 3 * r] = self.U.T @ ph.real
            x[2 * kk + 3 * r:] = -(self.U.T @ ph.imag)
        self.x = x

    def seed_harmonic(self, phasor, walk_load, walk_rate) -> None:
        """Set the oscillator's load to ``phasor`` (3,) complex [N] (:attr:`phasor`'s convention) and the walk to
        ``walk_load`` (3,) [N] and ``walk_rate`` (3,) [N/s] (a warm start from a fit; the modes kept)."""
        if self.harmonic is None:
            raise InputError("seed_harmonic needs the load's oscillator (set_harmonic first)")
        k, r = self.k, self.r
        ph = np.asarray(phasor, complex)
        self.x[2 * k:2 * k + r] = self.U.T @ (check_finite("walk_load", walk_load, (3,)) - self.modal.load)
        self.x[2 * k + r:2 * k + 2 * r] = self.U.T @ check_finite("walk_rate", walk_rate, (3,))
        self.x[2 * k + 2 * r:2 * k + 3 * r] = self.U.T @ ph.real
        self.x[2 * k + 3 * r:] = -(self.U.T @ ph.imag)

    def reset(self, load=(0.0, 0.0, 0.0)) -> None:
        """At rest under ``load`` (3,) [N] with the motors at the linearisation point."""
        F = check_finite("load", load, (3,))
        self.x = np.zeros(self.n)
        self.x[:self.k] = self.modal.quasi_static(np.zeros_like(self.modal.lengths), F - self.modal.load)
        self.x[2 * self.k:2 * self.k + self.r] = self.U.T @ (F - self.modal.load)

    # ------------------------------------------------------------------------------ stated properties
    def _closed_loop(self):
        """(Φ, Γ): the closed loop z_{j+1} = Φ z_j + Γ F of (true modal plant, filter), z = [plant modes (2k),
        filter state (n)], for a true load change F (3,) [N] held over each period (the plant is the observer's
        own model with the load as an input: the estimate's response to the truth).  Cached per gain."""
        if getattr(self, "_cl", None) is not None and self._cl[0] is self.K:
            return self._cl[1]
        n, k = self.n, self.k
        A, _, _, _, H, _ = _matrices(self.modal, np.eye(3))
        Ad, Bd, _ = _discretise(A[:2 * k, :2 * k], A[:2 * k, 2 * k:2 * k + 3], np.zeros((2 * k, 1)), self.period)
        Hs, Hd = H[:, :2 * k], H[:, 2 * k:2 * k + 3]
        IKH = np.eye(n) - self.K @ self.H
        Phi = np.vstack([np.hstack([Ad, np.zeros((2 * k, n))]), np.hstack([self.K @ Hs @ Ad, IKH @ self.Ad])])
        Gam = np.vstack([Bd, self.K @ (Hs @ Bd + Hd)])
        lam, V = np.linalg.eig(Phi)
        out = (Phi, Gam, lam, V, np.linalg.solve(V, Gam))
        self._cl = (self.K, out)
        return out

    def directions(self) -> np.ndarray:
        """(2, 3) unit vectors: the two most compliant principal directions of the locked compliance (the
        bending plane, across the actuator), along which the bandwidth is stated."""
        return self.U[:, :2].T

    def response(self, freq: float) -> np.ndarray:
        """(3, 3) complex transfer true load → estimate F̂ at ``freq`` [Hz] (world axes)."""
        _, _, lam, V, W = self._closed_loop()
        zc = np.exp(1j * 2 * math.pi * freq * self.period)
        X = V @ (W / (zc - lam)[:, None])
        return self.U @ (self._out @ X[2 * self.k:])

    def bandwidth_Hz(self) -> float:
        """The estimate's bandwidth [Hz]: the lowest frequency at which the response u·T(f) u of the estimate
        to a load along either direction u of :meth:`directions` falls to 1/√2 (module docstring)."""
        U = self.directions()
        fs = np.geomspace(0.01, 0.45 / self.period, 160)
        gains = np.array([min(abs(u @ self.response(f) @ u) for u in U) for f in fs])
        below = np.nonzero(gains < 1 / math.sqrt(2))[0]
        if len(below) == 0:
            return float(fs[-1])
        i = below[0]
        if i == 0:
            return float(fs[0])
        a, b = gains[i - 1], gains[i]
        w = (a - 1 / math.sqrt(2)) / (a - b)
        return float(math.exp(math.log(fs[i - 1]) + w * (math.log(fs[i]) - math.log(fs[i - 1]))))

    def settling_time_s(self, direction=None, within: float = 0.05, horizon: float = 2.0) -> float:
        """Time [s] after a tip-load step along ``direction`` (3,) (default: the most compliant direction) from
        which the estimate stays within ``within`` of the step (the linear closed loop, module docstring)."""
        u = self.directions()[0] if direction is None else check_finite("direction", direction, (3,))
        u = self.U @ (self.U.T @ u)                 # the part of the step the filter estimates (module docstring)
        u = u / np.linalg.norm(u)
        Phi, Gam = self._closed_loop()[:2]
        z = np.zeros(len(Phi))
        k, steps = self.k, int(round(horizon / self.period))
        g = Gam @ u
        err = np.empty(steps)
        for j in range(steps):
            z = Phi @ z + g
            err[j] = np.linalg.norm(self.U @ (self._out @ z[2 * k:]) - u)
        bad = np.nonzero(err > within)[0]
        return 0.0 if len(bad) == 0 else float((bad[-1] + 1) * self.period)

    def stability_gain(self, freq_error: Optional[float] = None) -> float:
        """sup over f and the plants of the bound of the spectral radius of the loop the model error closes
        (module docstring, robustness): L(f) = O(f) ΔP(f) G N(f), O the filter's map from a tip disturbance to
        F̂, ΔP the plant's minus the model's length-to-tip response with every mode's frequency scaled by
        1 ± ``freq_error`` (default ``model_error``; the same mass-proportional damping), G = −J_l⁺ C the static
        inverse, N the controller's ``loop_factor``.  Below 1 the loop is stable for every such plant."""
        eps = self.model_error if freq_error is None else number("freq_error", freq_error, strict=True)
        if eps is None:
            raise InputError("stability_gain needs a model error bound (freq_error or model_error)")
        mm, k, r = self.modal, self.k, self.r
        fs = np.geomspace(0.05, 0.45 / self.period, 300)
        w = 2 * math.pi * fs
        Phi = (np.eye(self.n) - self.K @ self.H) @ self.Ad
        lam, V = np.linalg.eig(Phi)
        W = np.linalg.solve(V, self.K)                                        # (n, 3)
        zc = np.exp(1j * w * self.period)
        resp = zc[:, None] / (zc[:, None] - lam[None, :])                     # (f, n)

        def to(rows):                   # the filter's map from a tip disturbance to the states ``rows``: (f, ., 3)
            return np.einsum("ij,fj,jl->fil", V[rows], resp, W)

        G = -np.linalg.pinv(mm.J_l) @ mm.C
        N = np.ones_like(w, dtype=complex) if self.loop_factor is None else np.asarray(self.loop_factor(fs), complex)
        ctrl = np.einsum("mc,fci->fmi", G, self.U @ to(slice(2 * k, 2 * k + r))) * N[:, None, None]   # (f, m, 3)
        if self.harmonic is not None and self.harmonic_map is not None:
            ctrl = ctrl + np.einsum("fmh,fhi->fmi", np.asarray(self.harmonic_map(fs), complex),
                                    to(slice(2 * k + 2 * r, 2 * k + 4 * r)))
        alpha = 2 * mm.zeta * mm.omega

        def modal(scale):
            om = scale * mm.omega
            return om[None, :] ** 2 / (om[None, :] ** 2 - w[:, None] ** 2 + 1j * alpha[None, :] * w[:, None])

        H0, worst = modal(1.0), 0.0
        for scale in np.linspace(1.0 - eps, 1.0 + eps, 25):
            dP = np.einsum("kc,fk,km->fcm", mm.tip_shapes, modal(scale) - H0, mm.g)      # (f, 3, m)
            L = np.einsum("fcm,fmi->fci", dP, ctrl)
            worst = max(worst, float(np.max(np.abs(np.linalg.eigvals(L)))))
        return worst

    def noise_std_N(self, tip_noise_m: float) -> np.ndarray:
        """Standard deviation (3,) [N] of F̂ per world axis for white tracker noise of ``tip_noise_m`` [m] per
        coordinate under a constant load (module docstring)."""
        s = number("tip_noise_m", tip_noise_m)
        Phi = (np.eye(self.n) - self.K @ self.H) @ self.Ad
        X = sla.solve_discrete_lyapunov(Phi, s ** 2 * self.K @ self.K.T)
        Xf = self.U @ self._out @ X @ self._out.T @ self.U.T
        return np.sqrt(np.diag(Xf))


class ModalPlant:
    """A :class:`ModalModel` as a plant (:class:`controller.plant.Plant`'s calls): its modes integrated exactly
    (zero-order hold per ``step`` [s]) under motor lengths that move at ≤ ``length_rate`` [m/s] towards the
    command and a tip load ``load(t)`` (3,) [N]; the tip as the model's output (module docstring).  For design
    checks and fast tests of the loop on a plant that differs from the controller's model (build the modal
    model of another :class:`ancf.Model`); ``noise_std`` [m]: white tracker noise per coordinate."""

    def __init__(self, modal: ModalModel, load: Callable[[float], np.ndarray], *, length_rate: float = 0.05,
                 step: float = 1e-3, noise_std: float = 0.0, seed: int = 0):
        self.modal, self._load = modal, load
        self.rate = number("length_rate [m/s]", length_rate, strict=True)
        self.h = number("step [s]", step, strict=True)
        self.noise = number("noise_std [m]", noise_std)
        A, B, _, _, _, _ = _matrices(modal, np.eye(3))
        k = len(modal.omega)
        inputs = np.hstack([B[:2 * k], A[:2 * k, 2 * k:2 * k + 3]])          # lengths (m), load (3)
        self.Ad, self.Bd, _ = _discretise(A[:2 * k, :2 * k], inputs, np.zeros((2 * k, 1)), self.h)
        self.k = k
        self.x = np.zeros(2 * k)
        self.lengths = modal.lengths.copy()
        self.commanded = modal.lengths.copy()
        self.time = 0.0
        self.rng = np.random.default_rng(seed)

    def command(self, lengths) -> float:
        self.commanded = check_finite("lengths", lengths, self.lengths.shape)
        return float(np.max(np.abs(self.commanded - self.lengths))) / self.rate

    def advance(self, dt) -> None:
        """Integrate dt [s] in whole steps (dt a multiple of ``step`` within 1 ns)."""
        n = int(round(float(dt) / self.h))
        if abs(n * self.h - float(dt)) > 1e-9:
            raise InputError(f"ModalPlant advances in whole steps of {self.h:g} s, got {dt!r}")
        mm = self.modal
        for _ in range(n):
            move = np.clip(self.commanded - self.lengths, -self.rate * self.h, self.rate * self.h)
            dF = self._load(self.time + 0.5 * self.h) - mm.load
            u = np.concatenate([self.lengths + 0.5 * move - mm.lengths, dF])
            self.x = self.Ad @ self.x + self.Bd @ u
            self.lengths = self.lengths + move
            self.time += self.h

    def load(self) -> np.ndarray:
        return np.asarray(self._load(self.time), float)

    def true_tip(self) -> np.ndarray:
        mm = self.modal
        return (mm.tip + mm.D_l @ (self.lengths - mm.lengths) + mm.tip_shapes.T @ self.x[:self.k]
                + mm.D_F @ (self.load() - mm.load))

    def measure(self) -> np.ndarray:
        tip = self.true_tip()
        return tip + self.rng.normal(0.0, self.noise, 3) if self.noise > 0 else tip
