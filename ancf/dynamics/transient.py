r"""Transient response of the reduced model: :meth:`ancf.Model.simulate`.

Equations of motion in the free coordinates z (q = q_fix + P z, docs/dynamics.md):

    Pᵀ M(q) P z̈ + Pᵀ [Q(q, T, p, F) + Q_d(q, q̇) + m J_pᵀ (∇²p_end[q̇, q̇])] + C_R ż = 0

* M: consistent ANCF mass (:mod:`.mass`) plus the tool-point mass m J_pᵀ J_p; Q = ∂Π/∂q, the static
  model's generalized force (axial, bending, tendons, pressure, gravity, tip force) with its exact tangent;
  Q_d the Kelvin–Voigt axial damping and C_R the Rayleigh matrix (:mod:`.damping`); the last term is the
  tool point's centripetal acceleration (d'Alembert force −m p̈, p̈ = J_p q̈ + ∇²p_end[q̇, q̇]; zero without a
  tool offset).
* Tendons: prescribed tensions T(t) ≥ 0 (slack is T = 0), or prescribed lengths l⁰(t) (motor positions,
  locked or moving) as a one-sided spring T_i = k max(0, l_i(q) − l⁰_i) — k the actuator's
  ``tendon_stiffness`` when it has one (then this *is* the tendon), else the penalty ``tendon_penalty`` —
  with the exact tangent k ∇l ∇lᵀ + T ∇²l; a tendon goes slack and taut again by itself (events).
* Pressure: a prescribed signal p(t), or a first-order supply p' = (p_cmd(t) − p)/τ (``pressure_tau``),
  integrated with the trapezoidal rule.
* Tip force F(t), a dead load at the tool point.

Integration: generalized-α (:mod:`.integrator`), fixed step h = t_end / ceil(t_end / dt) with automatic
halving (up to ``max_halvings`` times) of a step whose Newton iteration fails; a run that still fails
raises :class:`~ancf.errors.ConvergenceError` at the time it happened, a state leaving the model's domain
:class:`~ancf.errors.CollapsedStateError` — never a silent blow-up.

Energy bookkeeping (all [J]): kinetic K = ½ q̇ᵀ M q̇; potential Π(q; loads(t)) (elastic + gravity + the load
potentials Σ T_i l_i − p V − F·p_end + the length springs); the work of the time-varying loads
W = ∫ ∂Π/∂t dt; the dissipated energy D = ∫ q̇ᵀ(C_R q̇ + Q_d) dt.  ``energy`` = K + Π − W obeys
d(energy)/dt = −dD/dt exactly in time, so energy + dissipated is constant up to the integrator's error
(trapezoidal sums, second order).
"""

from __future__ import annotations

import math
import time as _time
from dataclasses import dataclass, field
from typing import Callable, Optional

import numpy as np

from ..assembly import assemble
from ..errors import CollapsedStateError, ConvergenceError, InputError, LimitError, check_finite, check_scalar
from .damping import axial_damping
from .integrator import AlphaCoefficients, StepFailed, StepState, alpha_step
from .mass import consistent_mass, tool_point_inertia
from .signals import Signal


@dataclass
class Simulation:
    """A transient run.  Rows are output times.

    t (N,) [s]; q, v (N, ndof) coordinates and velocities; tip (N, 3) tool point [m]; tensions (N, m) [N]
    (prescribed, or the length springs'); pressure (N,) [Pa]; energy, kinetic, potential, work, dissipated
    (N,) [J] (module docstring: energy + dissipated is conserved); events: list of dicts (t [s], kind,
    tendon, text) — tendons going slack/taut, steps subdivided; newton_iterations (N,) per output step;
    dt [s] the step used; damping: the coefficients used {alpha [1/s], beta [s], axial [N s]};
    rho_inf; wall_time [s]."""
    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    tip: np.ndarray
    tensions: np.ndarray
    pressure: np.ndarray
    energy: np.ndarray
    kinetic: np.ndarray
    potential: np.ndarray
    work: np.ndarray
    dissipated: np.ndarray
    newton_iterations: np.ndarray
    dt: float
    damping: dict
    rho_inf: float
    events: list = field(default_factory=list)
    wall_time: float = 0.0
    interrupted: bool = False

    @property
    def real_time_factor(self) -> float:
        """Simulated time per wall-clock second (> 1: faster than real time)."""
        return float(self.t[-1] - self.t[0]) / self.wall_time if self.wall_time > 0 else float("inf")


#: most time steps of one transient run (t_end / dt)
MAX_STEPS = 10_000_000


def resolve_damping(model, damping, K0: np.ndarray, Mz: np.ndarray) -> dict:
    """The damping coefficients {alpha [1/s], beta [s], axial [N s]} of a run (module docstring of
    :meth:`ancf.Model.simulate` for the accepted forms)."""
    p = model.params
    if damping is None:
        return {"alpha": p.rayleigh_alpha, "beta": p.rayleigh_beta, "axial": p.axial_damping}
    if isinstance(damping, dict):
        unknown = set(damping) - {"alpha", "beta", "axial", "stiffness"}
        if unknown:
            raise InputError(f"damping: unknown keys {sorted(unknown)}; use alpha [1/s], beta [s], axial [N s] "
                             "(and optionally stiffness: the (nz, nz) matrix β multiplies)")
        out = {"alpha": 0.0, "beta": 0.0, "axial": 0.0}
        for k, v in damping.items():
            if k == "stiffness":
                out[k] = check_finite("damping['stiffness']", v, (model.nz, model.nz))
            else:
                out[k] = check_scalar(f"damping[{k!r}]", v, low=0.0, high=1e6)
        return out
    zeta = check_scalar("damping", damping, low=0.0, high=1.0)
    if zeta == 0.0:
        return {"alpha": 0.0, "beta": 0.0, "axial": 0.0}
    import scipy.linalg as sla
    w2 = sla.eigh(K0, Mz, eigvals_only=True, subset_by_index=[0, 0])[0]
    if not w2 > 0:
        raise InputError("damping given as a ratio needs a stable start state (its lowest mode sets "
                         "β = 2ζ/ω₁); start from an equilibrium or give {'alpha', 'beta', 'axial'}")
    return {"alpha": 0.0, "beta": 2.0 * zeta / math.sqrt(w2), "axial": 0.0}


def rayleigh_about(model, eq, ratio: float) -> dict:
    """Stiffness-proportional damping with ratio ``ratio`` at the first mode about the equilibrium ``eq``
    (tensions held): ``{"alpha": 0, "beta": 2ζ/ω₁, "axial": 0, "stiffness": K}`` with K (nz, nz) the tangent
    at ``eq``, the matrix β multiplies for the whole run — e.g. the equilibrium a step response settles on,
    where a ratio given as a number would be taken about the (moving) start state."""
    zeta = check_scalar("ratio", ratio, low=0.0, high=1.0)
    ev = model.evaluate(eq.q, eq.tensions, eq.pressure, eq.tip_force)
    K = model.reduce_mat(ev.K)
    K = 0.5 * (K + K.T)
    M = consistent_mass(model.n, model._N, model._wq, model.params.line_mass)
    if model.params.tip_mass > 0:
        from .mass import tip_mass_matrix
        M = M + tip_mass_matrix(eq.q, model.params.tool_offset, model.params.tip_mass)
    out = resolve_damping(model, zeta, K, model.reduce_mat(M))
    out["stiffness"] = K
    return out


def simulate(model, t_end: float, dt: float, q0=None, v0=None, *, tensions=None, lengths=None,
             pressure=0.0, pressure_tau: Optional[float] = None, pressure0: Optional[float] = None,
             tip_force=(0.0, 0.0, 0.0), damping=None, rho_inf: float = 0.9,
             tendon_penalty: Optional[float] = None, holding_force: Optional[float] = None,
             check_limits: bool = True, max_halvings: int = 8,
             max_iter: int = 12, progress: Optional[Callable[[float, float], None]] = None) -> Simulation:
    """Integrate the model in time (module docstring); see :meth:`ancf.Model.simulate` for the arguments."""
    wall0 = _time.perf_counter()
    p = model.params
    t_end = check_scalar("t_end", t_end, low=0.0, high=1e6, unit="s")
    dt = check_scalar("dt", dt, low=0.0, high=t_end, unit="s")
    if not (t_end > 0 and dt > 0):
        raise InputError(f"t_end and dt must be > 0 s, got t_end = {t_end:g} s, dt = {dt:g} s")
    rho_inf = check_scalar("rho_inf", rho_inf, low=0.0, high=1.0)
    nsteps = int(math.ceil(t_end / dt - 1e-9))
    if nsteps > MAX_STEPS:
        raise InputError(f"t_end / dt = {nsteps} steps is more than 10⁷; use a larger dt")
    if isinstance(max_halvings, bool) or not isinstance(max_halvings, int) or not 0 <= max_halvings <= 20:
        raise InputError(f"max_halvings must be an integer 0…20, got {max_halvings!r}")
    if not p.line_mass > 0 and not p.tip_mass > 0:
        raise InputError("a transient run needs mass: the actuator has line_mass = 0 and tip_mass = 0")
    if not p.line_mass > 0:
        raise InputError("a transient run needs the actuator's line mass (line_mass > 0 kg/m): without it "
                         "the mass matrix is singular")
    if (tensions is None) == (lengths is None):
        raise InputError("give exactly one of tensions= (prescribed tension [N]) or lengths= (prescribed "
                         "tendon lengths [m], e.g. locked at eq.tendon_lengths)")
    h = t_end / nsteps
    times = np.linspace(0.0, t_end, nsteps + 1)
    m = model.m
    length_mode = lengths is not None
    if length_mode:
        l0_sig = Signal("lengths", lengths, (m,), "m")
        k_pen = p.tendon_stiffness if p.tendon_stiffness else (
            1e5 if tendon_penalty is None else check_scalar("tendon_penalty", tendon_penalty, low=1.0, high=1e12,
                                                            unit="N/m"))
        if p.tendon_stiffness and tendon_penalty is not None:
            raise InputError("tendon_penalty is for inextensible tendons; this actuator's tendons have "
                             f"tendon_stiffness = {p.tendon_stiffness:g} N/m, which is used")
    else:
        T_sig = Signal("tensions", tensions, (m,), "N")
        k_pen = 0.0
    if holding_force is not None:
        if not length_mode:
            raise InputError("holding_force is the motors' force limit for tendons held by length (lengths=)")
        holding_force = check_scalar("holding_force", holding_force, low=1e-6, high=1e5, unit="N")
    F_hold = math.inf if holding_force is None else holding_force
    s_hold = F_hold / k_pen if length_mode else math.inf         # the stretch at which a motor gives way
    pc_sig = Signal("pressure", pressure, (), "Pa")
    F_sig = Signal("tip_force", tip_force, (3,), "N")
    tau = None if pressure_tau is None else check_scalar("pressure_tau", pressure_tau, low=1e-6, high=1e4,
                                                          unit="s")

    def check_loads(t, T=None, pr=None, l0=None):
        if T is not None:
            if np.any(T < -1e-12):
                raise InputError(f"tensions at t = {t:.6g} s: a tendon cannot push (T = {T} N)")
            if check_limits and np.any(T > p.tension_max + 1e-12):
                raise LimitError(f"tensions at t = {t:.6g} s: {T} N above the actuator's tension_max "
                                 f"{p.tension_max:g} N (check_limits=False analyses it anyway)")
        if pr is not None and check_limits and not p.pressure_min - 1e-9 <= pr <= p.pressure_max + 1e-9:
            raise LimitError(f"pressure at t = {t:.6g} s: {pr / 1e3:g} kPa outside the actuator's limits "
                             f"[{p.pressure_min / 1e3:g}, {p.pressure_max / 1e3:g}] kPa (the Python API takes "
                             "pascals; check_limits=False analyses it anyway)")
        if l0 is not None and np.any(l0 <= 0):
            raise InputError(f"lengths at t = {t:.6g} s must be > 0 m, got {l0}")

    # fail fast: every signal on the output grid before integrating
    for t in times:
        check_loads(t, T=None if length_mode else T_sig(t), pr=float(pc_sig(t)),
                    l0=l0_sig(t) if length_mode else None)
        F_sig(t)

    # pressure state
    p_init = float(pc_sig(0.0)) if pressure0 is None else float(check_scalar("pressure0", pressure0, unit="Pa"))
    if pressure0 is not None and tau is None:
        raise InputError("pressure0 is the supply's initial pressure: it needs pressure_tau")
    check_loads(0.0, pr=p_init)

    def pressure_at(t_new, t_old, p_old):
        if tau is None:
            return float(pc_sig(t_new))
        c = (t_new - t_old) / (2 * tau)
        return (p_old * (1 - c) + c * (float(pc_sig(t_old)) + float(pc_sig(t_new)))) / (1 + c)

    # start state
    if q0 is None:
        if length_mode:
            raise InputError("lengths= needs q0 (e.g. the equilibrium whose tendon lengths you lock)")
        q0 = model.fk(T_sig(0.0), p_init, F_sig(0.0), check_limits=check_limits).q
    z = model._initial_z(q0)
    nz, ndof = model.nz, model.ndof
    P = model._P
    if v0 is None:
        vz = np.zeros(nz)
    else:
        v0 = model._q(v0, "v0")
        vz = model._to_free(v0)

    def full_v(vz_):
        if P is None:
            v = np.zeros(ndof)
            v[6:] = vz_
            return v
        return P @ vz_

    if v0 is not None and not np.allclose(full_v(vz), v0, rtol=0, atol=1e-12 * max(1.0, np.abs(v0).max())):
        raise InputError("v0 moves the clamped base node (its first 6 entries must be 0, or only the base "
                         "stretch along the base axis with free_base_stretch)")

    def red_v(x):
        return model._reduce_vec(x)

    def red_m(K):
        return model._reduce_mat(K)

    M0 = consistent_mass(model.n, model._N, model._wq, p.line_mass)
    hoff, mtip = p.tool_offset, p.tip_mass

    def mass_full(q):
        if mtip > 0:
            Jp = model._tip_jacobian(q)
            return M0 + mtip * Jp.T @ Jp, Jp
        return M0, None

    # tendon forces at a state
    def tendon_state(q, t, l0=None):
        if not length_mode:
            return T_sig(t), None
        lq = model._evaluate(q, None, 0.0, (0.0, 0.0, 0.0), False, 1.0, "values").lengths
        T = np.minimum(k_pen * np.maximum(lq - l0, 0.0), F_hold)
        return T, lq

    def springy(T):
        """Tendons whose tension follows their stretch (taut, below the motors' holding force)."""
        return (T > 0) & (T < F_hold)

    # Rayleigh stiffness at the start: the linearisation's stiffness under the start loads
    q_start = model._to_full(z)
    l0_start = l0_sig(0.0) if length_mode else None
    T_start, _ = tendon_state(q_start, 0.0, l0_start)
    ev0 = model._evaluate(q_start, T_start, p_init, F_sig(0.0), True, 1.0, True)
    if not np.isfinite(ev0.energy):
        raise InputError(f"q0 is outside the model's domain: {model.inadmissibility(q_start)}")
    K0 = red_m(ev0.K)
    if length_mode:
        taut = springy(T_start)
        if np.any(taut):
            JA = red_v(ev0.J_l)[taut]
            K0 = K0 + k_pen * JA.T @ JA
    K0 = 0.5 * (K0 + K0.T)
    Mz0 = red_m(mass_full(q_start)[0])
    coeffs = resolve_damping(model, damping, K0, Mz0)
    alpha_d, beta_d, c_ax = coeffs["alpha"], coeffs["beta"], coeffs["axial"]
    if "stiffness" in coeffs:                    # a fixed matrix for β (e.g. a plant's, across many runs)
        K0 = coeffs.pop("stiffness")
        K0 = 0.5 * (K0 + K0.T)
    if beta_d > 0:
        lam = np.linalg.eigvalsh(K0)[0]
        if lam < -1e-9 * max(np.abs(np.diag(K0)).max(), 1e-300):
            raise InputError("stiffness-proportional damping (beta) needs a stable start: the tangent at q0 "
                             f"has a negative eigenvalue ({lam:.3g}); start from an equilibrium or damp with "
                             "alpha / axial only")
    C_R = alpha_d * Mz0 + beta_d * K0 if (alpha_d or beta_d) else None
    # Newton tolerance [N]: 1e-7 of the force scale (EA(1)·1e-3 + the weight + |M z̈|); a residual r moves the
    # state by about β' J⁻¹ r — far below 1 nm at every step size
    force_scale = abs(float(p.stiffness.EA(1.0))) * 1e-3 + abs(float(p.line_mass)) * 9.81 * p.length

    # constant part of the reduced mass: the consistent mass, plus a tool-point mass without offset
    Mz_const = red_m(M0).copy()
    if mtip > 0 and hoff == 0:
        Mz_const[-6:-3, -6:-3] += mtip * np.eye(3)
    tip_moves_mass = mtip > 0 and hoff > 0
    Ct_const = np.zeros((nz, nz)) if C_R is None else C_R
    ev_lengths = bool(length_mode)

    def make_system(t1, T1_fixed, pr1, F1, l01):
        def system(z1, v1, x):
            q = model._to_full(z1)
            T1 = tendon_state(q, t1, l01)[0] if length_mode else T1_fixed
            ev = model._evaluate(q, T1, pr1, F1, True, 1.0, ev_lengths)
            if not np.isfinite(ev.energy):
                raise StepFailed(f"the state left the model's domain ({model.inadmissibility(q)})")
            r = Mz_const @ x + red_v(ev.Q)
            Kt = red_m(ev.K)
            Mz, Ct = Mz_const, Ct_const
            if C_R is not None:
                r += C_R @ v1
            if c_ax > 0:
                Qd, Dq, Dv = axial_damping(q, full_v(v1), model.n, model._N, model._wq, c_ax)
                r += red_v(Qd)
                Kt = Kt + red_m(Dq)
                Ct = Ct + red_m(Dv)
            if tip_moves_mass:
                # the tool point's inertia m J_pᵀ p̈ acts on the tip node's 6 coordinates, the last 6 of z
                fi, Ds, Dvs, B = tool_point_inertia(q[-3:], v1[-3:], x[-6:-3], x[-3:], hoff, mtip)
                r[-6:] += fi
                Mz = Mz_const.copy()
                Mz[-6:, -6:] += B
                Kt = Kt.copy()
                Kt[-6:, -3:] += Ds
                Ct = Ct.copy()
                Ct[-6:, -3:] += Dvs
            if length_mode:
                taut = springy(T1)
                if np.any(taut):
                    JA = red_v(ev.J_l)[taut]
                    Kt = Kt + k_pen * JA.T @ JA
            return r, Mz, Kt, Ct, force_scale + float(np.linalg.norm(Mz @ x))
        return system

    # energy parts of a state: Π(q; T, p, F) = E0 + T·l − p V − F·p_end + ½ k Σ max(0, l − l0)²
    s1 = model._N[:, 1, :]                                   # slope shape values (nq, 4)
    eidx = np.arange(model.n)[:, None] * 6 + np.arange(12)[None, :]
    vc = model._vc

    law = model.params.stiffness

    def parts(q):
        e0 = model._evaluate(q, None, 0.0, (0.0, 0.0, 0.0), False, 1.0, "values")
        lam = np.linalg.norm(np.einsum("kj,ejc->ekc", s1, q[eidx].reshape(model.n, 4, 3)), axis=-1)
        V = float(np.sum(model._wq * sum(c * lam ** (j + 1) for j, c in enumerate(vc))))   # ∫ A(λ) λ dx
        # a pressure-dependent law: the axial and bending energies at p = 0, scaled by their factors at p
        UA = UB = 0.0
        if law.pressure_dependent:
            z3, z1 = np.zeros(3), np.zeros(1)
            common = (model._E, model._d, model._co, model._so, np.zeros(model.m), 0.0, z3, False, 0)
            UA = assemble(q, model.n, model._N, model._wq, model._ea, z1, z1, z3, *common)[0]
            UB = assemble(q, model.n, model._N, model._wq, z1, model._ei, z1, z3, *common)[0]
        return e0.energy, e0.lengths, V, model._tip(q), UA, UB

    def potential(pt, T, pr, F, l0):
        E0, lq, V, pe, UA, UB = pt
        Pi = E0 - pr * V - float(F @ pe)
        if law.pressure_dependent:
            fA, fI = law.pressure_factors(pr)
            Pi += (fA - 1.0) * UA + (fI - 1.0) * UB
        if length_mode:
            st = np.maximum(lq - l0, 0.0)
            sc = np.minimum(st, s_hold)
            Pi += float(np.sum(0.5 * k_pen * sc ** 2 + F_hold * (st - sc) if math.isfinite(F_hold)
                               else 0.5 * k_pen * sc ** 2))
        else:
            Pi += float(T @ lq)
        return Pi

    def dissipation_power(q, vq, vz_):
        pw = 0.0
        if C_R is not None:
            pw += float(vz_ @ C_R @ vz_)
        if c_ax > 0:
            pw += float(vq @ axial_damping(q, vq, model.n, model._N, model._wq, c_ax)[0])
        return pw

    coeff = AlphaCoefficients.from_rho(rho_inf)
    tol_abs = max(model.default_tol, 1e-10)

    # initial acceleration: M z̈0 = −g(z0, v0, 0)
    F0 = F_sig(0.0)
    sys0 = make_system(0.0, None if length_mode else T_sig(0.0), p_init, F0, l0_start)
    try:
        r0, Mm, _, _, _ = sys0(z, vz, np.zeros(nz))
    except StepFailed as exc:
        raise InputError(f"q0: {exc.reason}") from None
    acc0 = -np.linalg.solve(Mm, r0)
    state = StepState(z.copy(), vz.copy(), acc0, acc0.copy())

    N1 = nsteps + 1
    out_q = np.empty((N1, ndof)); out_v = np.empty((N1, ndof)); out_tip = np.empty((N1, 3))
    out_T = np.empty((N1, m)); out_p = np.empty(N1); kin_ = np.empty(N1); pot = np.empty(N1)
    work = np.zeros(N1); diss = np.zeros(N1); iters = np.zeros(N1, dtype=int)
    events: list = []

    def record(i, st, t, pr, F, l0):
        q = model._to_full(st.z)
        vq = full_v(st.v)
        T, _ = tendon_state(q, t, l0)
        pt = parts(q)
        out_q[i], out_v[i], out_tip[i], out_T[i], out_p[i] = q, vq, pt[3], T, pr
        Mf, _ = mass_full(q)
        kin_[i] = 0.5 * float(vq @ Mf @ vq)
        pot[i] = potential(pt, T, pr, F, l0)
        return pt, T, dissipation_power(q, vq, st.v)

    pt_prev, T_prev, pw_prev = record(0, state, 0.0, p_init, F0, l0_start)
    pr_prev, F_prev, l0_prev, t_prev = p_init, F0, l0_start, 0.0
    interrupted = False
    level = good = 0
    try:
        for i in range(1, N1):
            t_target = times[i]
            n_it = 0
            st, tt, pr_s = state, t_prev, pr_prev
            # advance t_prev → t_target in substeps h / 2^level: a failed step halves them (up to
            # max_halvings times), four good ones in a row double them again
            while t_target - tt > 1e-12 * h:
                hh = min(h / 2 ** level, t_target - tt)
                if t_target - tt - hh < 1e-9 * hh:
                    hh = t_target - tt
                t1 = t_target if hh == t_target - tt else tt + hh
                pr1 = pressure_at(t1, tt, pr_s)
                F1 = F_sig(t1)
                l01 = l0_sig(t1) if length_mode else None
                T1 = None if length_mode else T_sig(t1)
                check_loads(t1, T=T1, pr=pr1, l0=l01)
                try:
                    st_new, k = alpha_step(st, hh, coeff, make_system(t1, T1, pr1, F1, l01), rtol=1e-14, atol=0.0, vtol=1e-7,
                                           max_iter=max_iter)
                except StepFailed as exc:
                    if level >= max_halvings:
                        why = exc.reason
                        if "domain" in why:
                            raise CollapsedStateError(f"simulate: at t = {t1:.6g} s {why}, even with the step "
                                                      f"halved {level} times", solver="simulate",
                                                      stretch=float("nan")) from None
                        raise ConvergenceError(f"at t = {t1:.6g} s the step did not converge even halved {level} "
                                               f"times (h = {hh:.3g} s): {why}", solver="simulate",
                                               iterations=exc.iterations, residual_norm=exc.residual,
                                               tolerance=tol_abs) from None
                    level += 1
                    good = 0
                    events.append({"t": float(tt), "kind": "subdivided", "tendon": None,
                                   "text": f"step halved to {h / 2 ** level:.3g} s ({exc.reason})"})
                    continue
                n_it += k
                st, tt, pr_s = st_new, t1, pr1
                good += 1
                if level and good >= 4:
                    level, good = level - 1, 0
            state = st
            pr_i, F_i, l0_i = pr_s, F_sig(t_target), (l0_sig(t_target) if length_mode else None)
            pt, T_i, pw = record(i, state, t_target, pr_i, F_i, l0_i)
            iters[i] = n_it
            # work of the time-varying loads (trapezoid of ∂Π/∂t), dissipation (trapezoid of the power)
            if length_mode or not (T_sig.constant and pc_sig.constant and F_sig.constant) or tau is not None:
                Tn = None if length_mode else T_sig(t_prev)
                Tn1 = None if length_mode else T_sig(t_target)
                dW = 0.5 * ((potential(pt_prev, Tn1, pr_i, F_i, l0_i) - potential(pt_prev, Tn, pr_prev, F_prev, l0_prev))
                            + (potential(pt, Tn1, pr_i, F_i, l0_i) - potential(pt, Tn, pr_prev, F_prev, l0_prev)))
                work[i] = work[i - 1] + dW
            else:
                work[i] = work[i - 1]
            diss[i] = diss[i - 1] + 0.5 * (pw + pw_prev) * (t_target - t_prev)
            if length_mode:
                for j in range(m):
                    if (T_prev[j] > 0) != (T_i[j] > 0):
                        kind = "taut" if T_i[j] > 0 else "slack"
                        events.append({"t": float(t_target), "kind": kind, "tendon": j,
                                       "text": f"tendon {j + 1} {kind} at t = {t_target:.6g} s"})
                    if (T_prev[j] >= F_hold) != (T_i[j] >= F_hold):
                        kind = "overpowered" if T_i[j] >= F_hold else "holding"
                        events.append({"t": float(t_target), "kind": kind, "tendon": j,
                                       "text": f"motor {j + 1} {'gives way at its holding force' if kind == 'overpowered' else 'holds again'}"
                                               f" ({F_hold:g} N) at t = {t_target:.6g} s"})
            pt_prev, T_prev, pw_prev = pt, T_i, pw
            pr_prev, F_prev, l0_prev, t_prev = pr_i, F_i, l0_i, t_target
            if progress is not None:
                progress(t_target, t_end)
    except KeyboardInterrupt:
        interrupted = True
        i -= 1
    n_out = i + 1 if interrupted else N1
    sl = slice(0, n_out)
    energy = kin_[sl] + pot[sl] - work[sl]
    return Simulation(t=times[sl].copy(), q=out_q[sl], v=out_v[sl], tip=out_tip[sl], tensions=out_T[sl],
                      pressure=out_p[sl], energy=energy, kinetic=kin_[sl], potential=pot[sl], work=work[sl],
                      dissipated=diss[sl], newton_iterations=iters[sl], dt=h, damping=coeffs, rho_inf=rho_inf,
                      events=events, wall_time=_time.perf_counter() - wall0, interrupted=interrupted)
