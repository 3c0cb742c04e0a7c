r"""Dynamic load-aware compliance control: LACC with a dynamic load observer, run every loop period (1 kHz).

Quasi-static LACC (:mod:`controller.lacc`) reads the load from the position error through the locked
compliance, assuming the actuator at rest; on a plant with inertia it must wait for the tip to settle
(docs/dynamics.md).  The dynamic LACC reads the load with the observer of :mod:`controller.observer` (a
Kalman filter on the reduced modal model about the commanded locked state) at every period h, and commands
at once::

    F̂, dF̂/dt ← observer(p_m, the lengths the motors had)                       every period
    F_p     ← F̂ + τ dF̂/dt,   τ = latency + h/2  (the load when the command acts)
    δl      ← G (F_p − F₀)  +  δl_dyn                                          G = −J_l⁺ C_p
    l_c     ← LP(l₀ + δl)   (tension limits: scaled back; motor speed: rate-limited)

about the linearisation point (l₀, F₀): the IK state for the target under F₀ (:meth:`Controller._reach`,
the nearest reachable state when the tensions cannot carry F₀ — LACC's saturation), rebuilt whenever
‖F̂ − F₀‖ exceeds ``relinearise_force``.  G is the static part: the lengths that hold the tip at the target
under a load change to first order, from the locked compliance C_p and J_l = ∂p/∂l.

**The dynamic part** (``feedforward="dynamic"``).  Under l = l₀ + G δF each locked mode k is driven by
f_k = w_k · δF, w_k = ω_k² Gᵀ g_k + t_k (the load's and the tendons' modal forces no longer cancel, only
their static tip deflections do).  Expanding the mode's response below its frequency,
ξ_k = f_k/ω_k² − (f̈_k + 2ζ_kω_k ḟ_k)/ω_k⁴ + …, leaves the tip error e ≈ −Σ_k t_k (w_k·(F̈ + 2ζ_kω_k Ḟ))/ω_k⁴,
which the lengths cancel: δl_dyn = J_l⁺ Σ_k t_k w_k·(F̈ + 2ζ_kω_k Ḟ)/ω_k⁴.  F̈ is the derivative of the
observer's rate through a first-order filter at the observer's bandwidth.  The dynamic compliance is of the
order (f/f₁)² of the static one: 3 % at 1 Hz against the `paper` actuator's 5.5 Hz locked mode.

**Robustness** (``model_error``, ``gain_margin``, ``command_filter_hz``).  The observer reads as load
whatever of the tip's response to the commands the model mispredicts, so the commands close a loop through
the model error (:mod:`controller.observer`, robustness).  Two measures keep it stable for plants whose
modal frequencies are within ±``model_error`` of the model's: the commands pass two first-order low-passes
at ``command_filter_hz`` (LP above; default 5 Hz), so that they do not drive the lightly damped second mode
pair (≈ 32 Hz), the model's least certain part; and the observer's bandwidth is lowered below
``bandwidth_hz`` until the small-gain bound holds with ``gain_margin`` (default ±12 %, margin 1.5: 3.1 Hz with
the dynamic feed-forward, 5.5 Hz with the static one on the `paper` actuator; ``bandwidth_used_hz``).  The
price is lag: the filter's delay (≈ 64 ms at 5 Hz) is not predicted (a lead would raise the loop's gain at
the higher modes again), and the estimate follows the load only well below its bandwidth.  With
``model_error=None, command_filter_hz=None`` the model is taken as exact (the bandwidth as asked).

**Internal model of a periodic load** (``internal_model``, default on; :mod:`controller.periodic`).  The
controller does not know the load's profile or frequency.  Until it has one, it runs as above; meanwhile
:class:`controller.periodic.PeriodEstimator` fits F̂ by a constant, a trend and a sinusoid and accepts a
frequency once a whole fitted period is recorded, the fit leaves ≤ 5 % of the amplitude and an extremum lies
inside the record (a step, a ramp or a hold is refused).  Then the observer gets the load's oscillator at that
frequency (:meth:`controller.observer.LoadObserver.set_harmonic`), started from the fit: the fitted
oscillation of F̂ divided by the observer's own response at that frequency (its lag) is the harmonic, the
rest stays in the walk.  The harmonic's lengths are Re(K_h ẑ), ẑ the observer's phasor and

    K_h = −P_l(iω)⁺ P_F(iω) e^{iωτ} / N_c(iω),

P_l, P_F the modal model's length- and load-to-tip responses at ω (modes plus residual flexibility: the exact
dynamic inverse at that frequency, not the static one), e^{iωτ} the lead time, N_c the command filter's
response (its lag and gain at ω undone; elsewhere the filter acts as before).  The harmonic's noise q_h
(``harmonic_noise``, 3e-5 N²/s) and the walk's are set so that the small-gain bound holds for the new loop:
the largest q_h of ``harmonic_noise`` × 10^−j for which a walk noise exists, the walk's lowered until the
bound holds (the bound binds in the first mode's band, 4.7–6.1 Hz, and at the second pair, 28–29 Hz, for the
`paper` actuator).  Afterwards the frequency follows the phasor: a load at ω + δ turns ẑ e^{−iωt} at δ; over
each period a drift above 0.3 % of ω moves the oscillator (its state kept, the bound rechecked).  A load
that is not periodic never gets an oscillator, and the loop is the one above.

**Safeguards, as LACC's**: the estimate is held within ``validity_force`` (its direction kept); tensions
predicted outside [T_min, T_max] (T₀ + ∂T/∂l δl + ∂T/∂F δF) scale the length change back along its
direction (the step is reported ``saturated``, ``reach_gap`` the tip the model then expects off the
target); commands are rate-limited to ``length_rate`` [m/s].  Anti-windup needs nothing more: the observer
is fed the lengths actually commanded, so F̂ follows the load whatever the motors could do, and no
integrator of the position error exists.  The pressure is held (as LACC).
"""

from __future__ import annotations

import math
import time
from typing import Optional

import numpy as np

from ancf import Model
from ancf.errors import InputError

from .base import Controller, StepReport
from .errors import number
from .lacc import G as GRAVITY, start_inputs
from .observer import LoadObserver, modal_model
from .periodic import PeriodEstimator

FEEDFORWARDS = ("static", "dynamic")


class DynamicLACC(Controller):
    """Dynamic LACC (module docstring), stepped once per loop period.

    Parameters (SI)
    ----------
    model, pressure : the controller's model and the held pressure p [Pa]
    period : loop period h [s] (1e-3: 1 kHz);  latency : time from a measurement to the motors acting on its
        command [s]
    bandwidth_hz : the observer's bandwidth [Hz];  tip_noise_std : tracker noise σ the filter assumes [m]
    damping_ratio : the model's first-mode damping ratio [-] (mass-proportional, as the simulated rig's)
    modes : locked modes in the reduced model;  feedforward : "dynamic" (static + dynamic compliance) | "static"
    length_rate : motor speed limit [m/s] the commands respect (None: none)
    relinearise_force : ‖F̂ − F₀‖ [N] beyond which the linearisation point moves
    command_filter_hz : corner [Hz] of the two first-order low-passes on the commands (None: unfiltered)
    validity_force : ‖F̂‖ [N] the commands may use (1.962 N = 200 g)
    model_error : bound ε of the plant's modal frequencies' error (relative, all modes alike) the loop must
        stay stable for: the observer's bandwidth is lowered below
        ``bandwidth_hz`` until the small-gain bound holds with ``gain_margin`` (module docstring,
        robustness; None: the model taken as exact, the bandwidth as asked)
    internal_model : learn a periodic load's frequency online and add its oscillator to the observer (module
        docstring, internal model);  harmonic_noise : its largest noise intensity q_h [N²/s]
    """

    name = "dynamic LACC"

    def __init__(self, model: Model, pressure: float, *, period: float = 1e-3, latency: float = 1e-3,
                 bandwidth_hz: float = 12.0, tip_noise_std: float = 5e-5, damping_ratio: float = 0.05,
                 modes: int = 4, feedforward: str = "dynamic", length_rate: Optional[float] = None,
                 relinearise_force: float = 0.1, validity_force: float = 0.2 * GRAVITY, tolerance: float = 2e-4,
                 model_error: Optional[float] = 0.12, gain_margin: float = 1.5,
                 command_filter_hz: Optional[float] = 5.0, internal_model: bool = True,
                 harmonic_noise: float = 3e-5):
        super().__init__(model, pressure, tolerance=tolerance)
        if not isinstance(internal_model, bool):
            raise InputError(f"internal_model must be True or False, got {internal_model!r}")
        self.internal_model = internal_model
        self.harmonic_noise = number("harmonic_noise [N²/s]", harmonic_noise, strict=True)
        self.harmonic_hz: Optional[float] = None
        self.period = number("period [s]", period, strict=True)
        if self.period > 0.1:
            raise InputError(f"period must be at most 0.1 s for a dynamic observer, got {self.period:g} s")
        self.latency = number("latency [s]", latency)
        if self.latency > 30 * self.period:
            raise InputError(f"latency must be at most 30 periods ({30 * self.period:g} s), got {self.latency:g} s")
        self.bandwidth_hz = number("bandwidth_hz", bandwidth_hz, strict=True)
        self.tip_noise_std = number("tip_noise_std [m]", tip_noise_std, strict=True)
        self.damping_ratio = number("damping_ratio", damping_ratio)
        if isinstance(modes, bool) or not isinstance(modes, (int, np.integer)) or not 1 <= modes <= 12:
            raise InputError(f"modes must be an integer 1…12, got {modes!r}")
        self.n_modes = int(modes)
        if feedforward not in FEEDFORWARDS:
            raise InputError(f"feedforward must be one of {FEEDFORWARDS}, got {feedforward!r}")
        self.feedforward = feedforward
        self.length_rate = None if length_rate is None else number("length_rate [m/s]", length_rate, strict=True)
        self.relinearise_force = number("relinearise_force [N]", relinearise_force, strict=True)
        self.validity_force = number("validity_force [N]", validity_force, strict=True)
        self.model_error = None if model_error is None else number("model_error", model_error, strict=True)
        if self.model_error is not None and not self.model_error < 0.5:
            raise InputError(f"model_error must be in (0, 0.5) (a relative frequency error), "
                             f"got {self.model_error:g}")
        self.gain_margin = number("gain_margin", gain_margin, strict=True)
        if not self.gain_margin >= 1:
            raise InputError(f"gain_margin must be at least 1, got {self.gain_margin:g}")
        self.command_filter_hz = None if command_filter_hz is None else number("command_filter_hz",
                                                                                command_filter_hz, strict=True)
        self.observer: Optional[LoadObserver] = None
        self.relinearisations = 0

    # ------------------------------------------------------------------------------ state
    @property
    def estimate(self) -> np.ndarray:
        """F̂ [N] (3,): the observer's tip load estimate (zeros before start)."""
        return np.zeros(3) if self.observer is None else self.observer.load

    def _linearise(self, F: np.ndarray, near=None) -> tuple:
        """IK state for the target under F (or the nearest reachable one) and its modal model: (eq, mm, note)."""
        eq, saturated, note = self._reach(self.target, F)
        mm = modal_model(self.model, eq.tendon_lengths, self.pressure, F, count=self.n_modes,
                         damping_ratio=self.damping_ratio, near=eq)
        self.state = eq
        self._G = -np.linalg.pinv(mm.J_l) @ mm.C                          # (m, 3) lengths per load at the target
        self._Jl_pinv = np.linalg.pinv(mm.J_l)
        self._C = mm.C
        w = (mm.omega ** 2)[:, None] * (mm.g @ self._G) + mm.tip_shapes   # (k, 3) modal force per load
        self._dyn = [(mm.tip_shapes[i], w[i], 2 * mm.zeta[i] * mm.omega[i], mm.omega[i] ** 4)
                     for i in range(len(mm.omega))]
        return eq, mm, note if saturated else ""

    def start(self, target, initial_load=(0.0, 0.0, 0.0)) -> np.ndarray:
        """IK for the target under ``initial_load`` (from the stored droop state, as LACC), the modal model
        there and the observer at rest; returns the tendon lengths (m,) [m]."""
        pd, F0 = start_inputs(target, initial_load, self.validity_force)
        droop = self._warm_start()
        eq = self.model.ik(pd, self.pressure, F0, q0=droop.q, tensions0=droop.tensions)   # may raise Infeasible
        self.target, self.state = pd, eq
        _, mm, _ = self._linearise(F0)
        self.observer = LoadObserver(mm, self.period, tip_noise_std=self.tip_noise_std,
                                     bandwidth_hz=self.bandwidth_hz, model_error=self.model_error,
                                     gain_margin=self.gain_margin, loop_factor=self.loop_factor)
        self.observer.reset(F0)
        self._k = 0
        self._commands = [(-math.inf, mm.lengths.copy())]              # (time it acts [s], lengths) in order
        self._last = mm.lengths.copy()
        self._rate_prev = np.zeros(3)
        self._Fdd = np.zeros(3)
        self._lp = [mm.lengths.copy(), mm.lengths.copy()]
        self.relinearisations = 0
        self.harmonic_hz, self._Kh = None, None
        f1 = float(mm.frequencies_hz[0])
        self.periods = PeriodEstimator(f_max=0.5 * f1) if self.internal_model else None
        return mm.lengths.copy()

    @property
    def bandwidth_used_hz(self) -> float:
        """The observer's bandwidth [Hz] as built (below ``bandwidth_hz`` where the model error bound needs it)."""
        if self.observer is None:
            raise InputError("the dynamic LACC has no observer before start()")
        return self.observer.bandwidth_Hz()

    def loop_factor(self, freqs_hz) -> np.ndarray:
        """N(f) (len(f),) complex: the gain between F̂ and the length command relative to the static inverse G, along
        the most compliant direction — the latency prediction (1 + iωτ) times, with ``feedforward="dynamic"``,
        1 − d(iω)/(uᵀC u), d = Σ_k (u·t_k)(w_k·u)((iω)²/(1 + iω/ω_b) + 2ζ_kω_k iω)/ω_k⁴, times the command
        filter's ((1 − a)/(1 − a e^{−iωh}))² (module docstring)."""
        w = 2 * math.pi * np.asarray(freqs_hz, float)
        s = 1j * w
        out = 1.0 + s * self.lead_time
        if self.feedforward == "dynamic":
            C = self._C
            u = np.linalg.svd(0.5 * (C + C.T))[0][:, 0]
            wb = 2 * math.pi * self.bandwidth_hz
            d = sum((u @ t) * (wk @ u) * (s ** 2 / (1 + s / wb) + c * s) / w4 for t, wk, c, w4 in self._dyn)
            out = out * (1.0 - d / (u @ C @ u))
        if self.command_filter_hz is not None:
            a = math.exp(-2 * math.pi * self.command_filter_hz * self.period)
            out = out * ((1 - a) / (1 - a * np.exp(-s * self.period))) ** 2
        return out

    def command_filter(self, freqs_hz) -> np.ndarray:
        """The command filter's response (len(f),) complex: ((1 − a)/(1 − a e^{−iωh}))² (1 without a filter)."""
        s = 2j * math.pi * np.asarray(freqs_hz, float)
        if self.command_filter_hz is None:
            return np.ones_like(s)
        a = math.exp(-2 * math.pi * self.command_filter_hz * self.period)
        return ((1 - a) / (1 - a * np.exp(-s * self.period))) ** 2

    def _harmonic_command(self, freq_hz: float) -> None:
        """K_h (m, 3) complex: the lengths per harmonic load phasor at ``freq_hz`` (module docstring, internal
        model) — the model's dynamic inverse −P_l(iω)⁺ P_F(iω) about the linearisation point, advanced by the
        lead time and divided by the command filter's response; and the observer's map of it for the bound."""
        mm = self.observer.modal
        w = 2 * math.pi * freq_hz
        H = mm.omega ** 2 / (mm.omega ** 2 - w ** 2 + 2j * mm.zeta * mm.omega * w)          # (k,)
        P_F = mm.D_F + np.einsum("ki,kj,k->ij", mm.tip_shapes, mm.tip_shapes, H / mm.omega ** 2)
        P_l = mm.D_l + np.einsum("ki,km,k->im", mm.tip_shapes, mm.g, H)
        lead = np.exp(1j * w * self.lead_time) / self.command_filter([freq_hz])[0]
        self._Kh = -np.linalg.pinv(P_l) @ P_F * lead
        U = self.observer.U
        Mh = np.hstack([(self._Kh @ U).real, (self._Kh @ U).imag])                       # (m, 2r)
        self.observer.harmonic_map = lambda fs: self.command_filter(fs)[:, None, None] * Mh[None]

    def _set_harmonic(self, freq_hz: float) -> None:
        """The observer's oscillator at ``freq_hz`` [Hz] (module docstring, internal model), its state carried
        over when it moves: its noise the largest of q_h × 10^−j (q_h: ``harmonic_noise``, or the present one)
        for which some walk noise keeps the small-gain bound with ``model_error`` (the walk's noise lowered
        until it holds, so that the two share it; with the model as exact: as asked).  Without such a noise the
        oscillator is left out (``harmonic_hz`` None)."""
        obs = self.observer
        if obs.harmonic is None:
            self._q_walk = obs.q
        q_walk = obs.q
        qh = self.harmonic_noise if obs.harmonic is None else obs.harmonic[1]
        for _ in range(8):
            obs.q = q_walk
            obs.set_harmonic(freq_hz, qh)
            self._harmonic_command(freq_hz)
            if self.model_error is None or obs.stability_gain() <= 1.0 / self.gain_margin:
                self.harmonic_hz = float(freq_hz)
                return
            start = int(math.floor(math.log10(q_walk))) - 6
            lo, hi = obs._tune(obs.stability_gain, 1.0 / self.gain_margin, "a stable loop", first=start)
            if lo < hi:
                obs.q = 10.0 ** lo
                obs._build()
                self.harmonic_hz = float(freq_hz)
                return
            qh *= 0.1
        obs.q = self._q_walk
        obs.set_harmonic(None)
        self.harmonic_hz, self._Kh = None, None

    def _track(self, t: float) -> None:
        """The internal model's frequency (module docstring): until the first lock from the period estimator's
        fits of F̂; then from the drift of the oscillator's phase, every period: a load at ω + δ leaves the
        phasor ẑ e^{−iωt} turning at δ, which moves the oscillator when |δ| exceeds 0.3 % of ω over two periods."""
        obs, est = self.observer, self.periods
        if self.harmonic_hz is None:
            if est.add(t, obs.load):
                self._lock(t)
            return
        w = 2 * math.pi * self.harmonic_hz
        if t < self._drift[0] + 1.0 / self.harmonic_hz - 1e-9:
            return
        z = complex(np.vdot(self._drift[2], obs.phasor) * np.exp(-1j * w * t))
        if abs(z) < est.min_amplitude:
            self._drift = (t, None, self._drift[2], 0)
            return
        t_prev, z_prev, u, n = self._drift
        self._drift = (t, z, u, n + 1)
        if z_prev is None or n < 1:
            return
        delta = np.angle(z / z_prev) / (t - t_prev)                       # [rad/s]
        if abs(delta) > 0.003 * w:
            self._set_harmonic(self.harmonic_hz + delta / (2 * math.pi))
            self._drift = (t, None, u, 0)

    def _lock(self, t: float) -> None:
        """The internal model at the estimator's frequency (module docstring).  On the first lock it starts from
        the fit: the fitted oscillation of F̂ at t [s], divided by the observer's own response at that frequency
        (its lag), is the oscillator's load; the walk keeps F̂ without the fitted oscillation."""
        obs, est = self.observer, self.periods
        f = est.frequency_hz
        first = self.harmonic_hz is None
        if first:
            U = obs.U
            T = U.T @ obs.response(f) @ U                                # (r, r): true load → F̂ at f
            lagged = est.phasor(t)
            true = U @ np.linalg.solve(T, U.T @ lagged)
            walk = (obs.load - lagged.real, obs.load_rate - (2j * math.pi * f * lagged).real)
        self._set_harmonic(f)
        if first and self.harmonic_hz is not None:
            obs.seed_harmonic(true, *walk)
            self._drift = (t, None, est.fit[1], 0)

    def _harmonic_lengths(self) -> np.ndarray:
        """δl_h (m,) [m]: Re(K_h ẑ), ẑ the observer's harmonic load phasor (zeros without the oscillator)."""
        if self._Kh is None:
            return np.zeros(len(self._last))
        return (self._Kh @ self.observer.phasor).real

    def _applied(self, t: float) -> np.ndarray:
        """The lengths the motors act on at controller time t [s] (the last command whose time has come)."""
        cur = self._commands[0][1]
        for ta, lengths in self._commands:
            if ta <= t + 1e-12:
                cur = lengths
            else:
                break
        return cur

    # ------------------------------------------------------------------------------ one period
    def _desired(self, F: np.ndarray, Fdot: np.ndarray) -> np.ndarray:
        """δl (m,) [m] from the linearisation point for the predicted load (module docstring)."""
        mm = self.observer.modal
        dl = self._G @ (F - mm.load)
        if self.feedforward == "dynamic":
            e = sum(t * (w @ (self._Fdd + c * Fdot)) / w4 for t, w, c, w4 in self._dyn)
            dl = dl + self._Jl_pinv @ e
        return dl

    @property
    def lead_time(self) -> float:
        """τ [s] of the load prediction F̂ + τ dF̂/dt: the latency and half a period (the command filter's delay
        is not predicted: the lead would raise the loop's gain at the higher modes, module docstring)."""
        return self.latency + 0.5 * self.period

    def _smooth(self, lengths: np.ndarray) -> np.ndarray:
        """The command through two first-order low-passes at ``command_filter_hz`` (module docstring: the
        commands must not excite the higher locked modes, which the model knows least)."""
        if self.command_filter_hz is None:
            return lengths
        a = math.exp(-2 * math.pi * self.command_filter_hz * self.period)
        self._lp[0] = a * self._lp[0] + (1 - a) * lengths
        self._lp[1] = a * self._lp[1] + (1 - a) * self._lp[0]
        return self._lp[1].copy()

    def _limit_tensions(self, dl: np.ndarray, dF: np.ndarray) -> tuple:
        """(δl scaled back so that the predicted tensions stay within their limits, scale s ∈ [0, 1])."""
        mm, p = self.observer.modal, self.model.params
        T0 = mm.tensions
        dT = mm.dT_dl @ dl + mm.dT_dF @ dF
        s = 1.0
        for T, d in zip(T0, dT):
            if T + d > p.tension_max and d > 0:
                s = min(s, max(0.0, (p.tension_max - T) / d))
            if T + d < p.tension_min and d < 0 and T > p.tension_min:
                s = min(s, max(0.0, (p.tension_min - T) / d))
        return dl * s, s

    def step(self, measured_tip) -> StepReport:
        """One loop period: observe, predict the load at the command's time, command (module docstring)."""
        self._check_started()
        pm = self._measured(measured_tip)
        t0 = time.perf_counter()
        h, t = self.period, self._k * self.period
        notes: list = []
        obs = self.observer
        obs.update(pm, self._applied(t), 0.5 * (self._applied(t - h) + self._applied(t)))
        if self.periods is not None:
            before = self.harmonic_hz
            self._track(t)
            if self.harmonic_hz != before:
                notes.append("periodic load: internal model " + ("off" if self.harmonic_hz is None else
                                                                  f"at {self.harmonic_hz:.4g} Hz"))
        F, Fdot = obs.walk
        a = math.exp(-2 * math.pi * self.bandwidth_hz * h)
        self._Fdd = a * self._Fdd + (1 - a) * (Fdot - self._rate_prev) / h
        self._rate_prev = Fdot
        if np.linalg.norm(F - obs.modal.load) > self.relinearise_force and np.linalg.norm(F) <= self.validity_force:
            _, mm, note = self._linearise(F)
            obs.relinearise(mm, self._applied(t))
            if self.harmonic_hz is not None:
                self._harmonic_command(self.harmonic_hz)
            self.relinearisations += 1
            if note:
                notes.append(note)
        Fp = F + self.lead_time * Fdot
        if np.linalg.norm(Fp) > self.validity_force:
            notes.append(f"estimate {np.linalg.norm(Fp):.3g} N beyond the validity range: held at "
                         f"{self.validity_force:.3g} N")
            Fp = Fp * self.validity_force / np.linalg.norm(Fp)
        mm = obs.modal
        dl, s = self._limit_tensions(self._desired(Fp, Fdot) + self._harmonic_lengths(), Fp - mm.load)
        saturated = s < 1.0
        gap = float(np.linalg.norm(mm.J_l @ dl + mm.C @ (Fp - mm.load))) if saturated else 0.0
        if saturated:
            notes.append(f"tension limits: the length change scaled to {s:.2f}; {gap * 1e3:.2f} mm off the target")
        cmd = self._smooth(mm.lengths + dl)
        if self.length_rate is not None:
            cmd = self._last + np.clip(cmd - self._last, -self.length_rate * h, self.length_rate * h)
        self._commands.append((t + self.latency, cmd.copy()))
        if len(self._commands) > 64:
            del self._commands[:-32]
        self._last = cmd
        self._k += 1
        e = pm - self.target
        return StepReport(e, float(np.linalg.norm(e)), False, cmd.copy(), obs.load, "dynamic-lacc",
                          time.perf_counter() - t0, compliance=mm.C, active=tuple(self.state.active or ()),
                          notes=notes, saturated=saturated, reach_gap=gap)
