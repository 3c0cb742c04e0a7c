r"""Compiled (numba) output rows of a transient run: the generalized-α step, its Newton iterations with the
exact iteration matrix, and the recorder's per-row quantities, without leaving compiled code between rows.

Why: at n = 6 one assembly costs ≈ 0.03 ms, while the Python around it (the plant's closures, the reductions
to free coordinates, the recorder's energy parts, the signals and their checks) cost ≈ 10× that per step; a
1 kHz control loop driving the dynamic plant needs a step well under 1 ms.

What is the same as the Python path (:mod:`.transient`, :mod:`.integrator`; tested against it to round-off,
``tests/test_dynamics_compiled.py``): the residual r = M z̈ + g(z, ż) with the tendons by tension or by length
(one-sided springs capped at the holding force, the tangent k ∇l ∇lᵀ of the taut ones), the pressure (held,
or the first-order supply's trapezoidal rule), the tip force, the Rayleigh matrix, the Kelvin–Voigt axial
damping, the tool-point inertia; the predictor (z̈_n or −ρ∞ z̈_n; with length springs the better of it and
the last state), Newton with the convergence tests, the
length springs' active-set update and the line search of :func:`.integrator.alpha_step`; the substeps
h / 2^base of a refined run and their energy bookkeeping (work of the loads, dissipation: trapezoidal sums); each
row's state, tool point, tensions, pressure, kinetic and potential energy and Newton iterations.

Loads: the caller samples every signal in Python on the substep grid the kernel will walk (the *load table*,
one row per substep end, row 0 the chunk's start: time, pressure — the signal's, or the supply's trapezoidal rule
—, tensions or motor lengths, tip force, and the pressure factors (f_A, f_I) of a pressure-dependent stiffness
law, EA(λ, p) = EA(λ) f_A(p)), with the same calls and arithmetic as the Python path, so time-varying signals
(ramps, sines, tables, a rig's motor lengths) and pressure-dependent laws give the same numbers; a substep whose
time is not the table's (a halved step) is never taken here.

What is not here — the kernel stops *before* the row instead and returns its index (:data:`FALLBACK`), and the
caller runs that row in Python, which halves the step, records the event or raises the typed error exactly as
before: a step whose Newton iteration fails for any reason (domain, singular matrix, no convergence, not
finite), and a load-table row the caller marked bad (a load outside the actuator's limits, a signal that raised).

Inputs come from :mod:`.transient`, which checks their shapes and dtypes (:func:`check_inputs`) before the
first call.  Layout of the scalar vector ``par`` (float64): the ``P_*`` indices below.  The array tuple
``arr``: (q_fix (ndof,), P (ndof, nz) or (1, 1), N (nq, 3, 4), wq (nq,), ea, ei, vc (polynomial
coefficients), mg (3,), E (3, 3), d, co, so (m,), M0 (ndof, ndof), Mz_const (nz, nz), C_R (nz, nz) (zeros
without Rayleigh damping), T (m,) [N] prescribed tensions, l0 (m,) [m] prescribed lengths, F_tot (3,) [N] tip
force plus tip weight, F_w (3,) [N] tip weight, F (3,) [N] tip force — the loads at t = 0; the steps read
theirs from the load table).  The previous row's point ``prev``: (E0 [J], V [m³], p_end (3,) [m], dissipated
power [W], pressure [Pa], t [s], U_A, U_B [J] the axial and bending energies of a pressure-dependent law at p = 0
(else 0), tendon lengths (m,) [m]).  The load table ``tab`` (k, L_VAR + 2m): the ``L_*`` columns below, then the
tensions (m,) [N] and the motor lengths (m,) [m].
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..assembly import assemble
from ..compiled_solvers import reduce_mat, reduce_rows, reduce_vec, tip_jacobian, tip_position, to_full
from .integrator import ACTIVE_SET_PASSES, ARMIJO, LINE_SEARCH_TRIES, RESIDUAL_FLOOR
from .mass import tool_point_inertia

#: kernel results: every row asked for done, or stopped before ``row`` (the caller runs it in Python)
DONE, FALLBACK = 0, 1

#: indices into ``par`` (the run's pressures are in the load table: the caller samples its supply and limits)
(P_N, P_USEP, P_HTOOL, P_CAX, P_HASCR, P_MTIP, P_TIPMOVES, P_FSCALE, P_LMODE, P_KPEN, P_FHOLD, P_SHOLD, P_RHO,
 P_AM, P_AF, P_GAMMA, P_BETA, P_H, P_HSUB, P_MAXIT, P_VARYING, P_BAND, P_PDEP) = range(23)
N_PAR = 23
#: length of ``prev`` before the tendon lengths
N_PREV = 10
#: columns of the load table: time [s], pressure [Pa], usable (1) or not (0), pressure factors f_A, f_I,
#: tip force (3,) [N], tip force plus tip weight (3,) [N]; then tensions (m,) and motor lengths (m,)
L_T, L_PR, L_OK, L_FA, L_FI, L_F, L_FTOT, L_VAR = 0, 1, 2, 3, 4, 5, 8, 11
#: Newton tolerances of a step (as :meth:`ancf.dynamics.transient._Stepper.advance` passes them)
RTOL, ATOL, VTOL = 1e-14, 0.0, 1e-7


def check_inputs(arr: tuple, par: np.ndarray, state: np.ndarray, prev: np.ndarray, nz: int, m: int) -> None:
    """TypeError / ValueError for an input the kernels cannot take (the boundary check before any call):
    float64 C-contiguous arrays of the shapes the module docstring lists."""
    ndof = arr[0].shape[0]
    shapes = [(ndof,), None, None, None, None, None, None, (3,), (3, 3), (m,), (m,), (m,), (ndof, ndof),
              (nz, nz), (nz, nz), (m,), (m,), (3,), (3,), (3,)]
    if len(arr) != len(shapes):
        raise ValueError(f"compiled_step: {len(arr)} arrays, expected {len(shapes)}")
    for k, (a, s) in enumerate(zip(arr, shapes)):
        if not (isinstance(a, np.ndarray) and a.dtype == np.float64 and a.flags.c_contiguous):
            raise TypeError(f"compiled_step: array {k} must be float64 and C-contiguous")
        if s is not None and a.shape != s:
            raise ValueError(f"compiled_step: array {k} has shape {a.shape}, expected {s}")
    for name, a, s in (("par", par, (N_PAR,)), ("state", state, (5, nz)), ("prev", prev, (N_PREV + m,))):
        if not (a.dtype == np.float64 and a.flags.c_contiguous and a.shape == s):
            raise ValueError(f"compiled_step: {name} must be float64 C-contiguous of shape {s}, got {a.shape}")
    if not np.all(np.isfinite(par)[[i for i in range(N_PAR) if i not in (P_FHOLD, P_SHOLD)]]):
        raise ValueError("compiled_step: par must be finite (the holding force may be inf)")


@njit(cache=True, nogil=True)
def axial_damping_c(q, v, n, N, wq, c_a, tangents):
    """:func:`ancf.dynamics.damping.axial_damping` in compiled form: (Q_d (ndof,), ∂Q_d/∂q, ∂Q_d/∂q̇ (ndof,
    ndof); the matrices zero unless ``tangents``)."""
    ndof = q.size
    Q = np.zeros(ndof)
    Dq = np.zeros((ndof, ndof))
    Dv = np.zeros((ndof, ndof))
    rx = np.empty(3)
    vx = np.empty(3)
    for e in range(n):
        o = 6 * e
        for k in range(wq.size):
            for c in range(3):
                rx[c] = 0.0
                vx[c] = 0.0
                for j in range(4):
                    rx[c] += N[k, 1, j] * q[o + 3 * j + c]
                    vx[c] += N[k, 1, j] * v[o + 3 * j + c]
            w = c_a * wq[k]
            ed = rx[0] * vx[0] + rx[1] * vx[1] + rx[2] * vx[2]
            for j in range(4):
                for c in range(3):
                    Q[o + 3 * j + c] += w * ed * N[k, 1, j] * rx[c]
            if tangents:
                for j in range(4):
                    for l in range(4):
                        ss = w * N[k, 1, j] * N[k, 1, l]
                        for c in range(3):
                            Dq[o + 3 * j + c, o + 3 * l + c] += ss * ed
                            for dd in range(3):
                                Dv[o + 3 * j + c, o + 3 * l + dd] += ss * rx[c] * rx[dd]
                                Dq[o + 3 * j + c, o + 3 * l + dd] += ss * rx[c] * vx[dd]
    return Q, Dq, Dv


@njit(cache=True, nogil=True)
def _values(q, arr, par):
    """(E0 [J] the energy without tendon and pressure loads, tendon lengths (m,) [m]) at q."""
    N, wq, ea, ei, vc, mg, E, d, co, so = arr[2:12]
    En, _, _, lc, _, _, _ = assemble(q, int(par[P_N]), N, wq, ea, ei, 0.0 * vc, mg, E, d, co, so,
                                     np.zeros(d.size), par[P_HTOOL], arr[18], False, 1)
    return En, lc


@njit(cache=True, nogil=True)
def _springs(lq, l0, par):
    """Tensions (m,) [N] of tendons held by length: k max(0, l − l0) capped at the holding force."""
    T = np.empty(lq.size)
    for i in range(lq.size):
        T[i] = min(par[P_KPEN] * max(lq[i] - l0[i], 0.0), par[P_FHOLD])
    return T


@njit(cache=True, nogil=True)
def _system(z1, v1, x, L, arr, par):
    """The integrator's system (:meth:`ancf.dynamics.transient._Plant.system`) under the loads of the load-table
    row L: (admissible, r (nz,) [N], M, K_t, C_t (nz, nz), force scale [N], Π [J] the potential under the step's
    loads, ∂Π/∂z (nz,), the length springs' stretches l − l0 (m,) [m] and gradients ∇l in z (m, nz): zeros for
    tendons by tension)."""
    q_fix, P, N, wq, ea, ei, vc, mg, E, d, co, so = arr[:12]
    Mz_c, C_R = arr[13], arr[14]
    m = d.size
    pr1, T_fix, l0, F_tot = L[L_PR], _tensions(L, m), _lengths(L, m), L[L_FTOT:L_FTOT + 3].copy()
    if par[P_PDEP] > 0:
        ea, ei = ea * L[L_FA], ei * L[L_FI]
    use_P, n = par[P_USEP] > 0, int(par[P_N])
    lmode = par[P_LMODE] > 0
    q = to_full(z1, q_fix, P, use_P)
    T1 = T_fix
    nz = z1.size
    stretch, G = np.zeros(m), np.zeros((m, nz))
    if lmode:
        lq = _values(q, arr, par)[1]
        stretch = lq - l0
        T1 = _springs(lq, l0, par)
    En, Q, K, _, Jl, _, _ = assemble(q, n, N, wq, ea, ei, pr1 * vc, mg, E, d, co, so, T1, par[P_HTOOL], F_tot,
                                     True, 2 if lmode else 0)
    if not np.isfinite(En):
        return False, np.zeros(nz), Mz_c, Mz_c, Mz_c, 0.0, En, np.zeros(nz), stretch, G
    Qr = reduce_vec(Q, P, use_P)
    r = Mz_c @ x + Qr
    Kt = reduce_mat(K, P, use_P)
    Mz = Mz_c
    Ct = C_R
    if par[P_HASCR] > 0:
        r += C_R @ v1
    if par[P_CAX] > 0:
        vq = to_full(v1, np.zeros(q.size), P, use_P)
        Qd, Dq, Dv = axial_damping_c(q, vq, n, N, wq, par[P_CAX], True)
        r += reduce_vec(Qd, P, use_P)
        Kt = Kt + reduce_mat(Dq, P, use_P)
        Ct = Ct + reduce_mat(Dv, P, use_P)
    if par[P_TIPMOVES] > 0:
        fi, Ds, Dvs, B = tool_point_inertia(q[-3:].copy(), v1[-3:].copy(), x[-6:-3].copy(), x[-3:].copy(),
                                            par[P_HTOOL], par[P_MTIP])
        r[-6:] += fi
        Mz = Mz_c.copy()
        Mz[-6:, -6:] += B
        Kt[-6:, -3:] += Ds
        Ct = Ct.copy()
        Ct[-6:, -3:] += Dvs
    if lmode:
        G = reduce_rows(Jl, P, use_P)
        for i in range(T1.size):
            if T1[i] > 0 and T1[i] < par[P_FHOLD]:
                g = G[i]
                Kt = Kt + par[P_KPEN] * np.outer(g, g)
    return True, r, Mz, Kt, Ct, par[P_FSCALE] + np.linalg.norm(Mz @ x), En, Qr, stretch, G


@njit(cache=True, nogil=True)
def _solve(J, r):
    """(ok, J⁻¹ r): LU with partial pivoting (LAPACK, as np.linalg.solve); not ok for a singular J."""
    try:
        return True, np.linalg.solve(J, r)
    except Exception:  # noqa: BLE001 — numba raises LinAlgError for an exactly singular pivot
        return False, r


@njit(cache=True, nogil=True)
def band_solve(A, b, kl, ku):
    """(ok, A⁻¹ b) for A (n, n) with at most kl sub- and ku super-diagonals: Gaussian elimination with partial
    pivoting inside the band (row exchanges widen the upper band to kl + ku); not ok for an exactly zero pivot
    (where LAPACK's gesv, i.e. np.linalg.solve, raises)."""
    n = A.shape[0]
    M = A.copy()
    x = b.copy()
    for k in range(n):
        last = min(n - 1, k + kl)
        cend = min(n - 1, k + kl + ku)
        p = k
        for i in range(k + 1, last + 1):
            if abs(M[i, k]) > abs(M[p, k]):
                p = i
        if M[p, k] == 0.0:
            return False, x
        if p != k:
            for j in range(k, cend + 1):
                M[k, j], M[p, j] = M[p, j], M[k, j]
            x[k], x[p] = x[p], x[k]
        for i in range(k + 1, last + 1):
            f = M[i, k] / M[k, k]
            if f != 0.0:
                for j in range(k + 1, cend + 1):
                    M[i, j] -= f * M[k, j]
                x[i] -= f * x[k]
    for i in range(n - 1, -1, -1):
        t = x[i]
        for j in range(i + 1, min(n, i + kl + ku + 1)):
            t -= M[i, j] * x[j]
        x[i] = t / M[i, i]
    return True, x


@njit(cache=True, nogil=True)
def _evaluate(x, k, a_const, z_pred, v_pred, h, L, arr, par):
    a1 = k * x + a_const
    z1 = z_pred + h * h * par[P_BETA] * a1
    v1 = v_pred + h * par[P_GAMMA] * a1
    ok, r, M, Kt, Ct, scale, En, Qr, st, G = _system(z1, v1, x, L, arr, par)
    return ok, a1, z1, v1, r, M, Kt, Ct, scale, En, Qr, st, G


@njit(cache=True, nogil=True)
def _branches(s, k, F_hold):
    """:func:`ancf.dynamics.integrator.spring_branches`: (branch (m,) 0 slack / 1 taut / 2 held, force (m,) [N])."""
    br = np.empty(s.size, dtype=np.int64)
    T = np.empty(s.size)
    for i in range(s.size):
        T[i] = min(k * max(s[i], 0.0), F_hold)
        br[i] = 0 if T[i] <= 0.0 else (2 if T[i] >= F_hold else 1)
    return br, T


@njit(cache=True, nogil=True)
def _branch_solve(J, r, s, G, bp, k, F_hold, cur, T, new):
    """:func:`ancf.dynamics.integrator.branch_solve`: (solved, the update with the springs on the branches new)."""
    JA, rA = J.copy(), r.copy()
    for i in range(s.size):
        if new[i] != cur[i]:
            g = G[i].copy()
            JA += (bp * k * ((1.0 if new[i] == 1 else 0.0) - (1.0 if cur[i] == 1 else 0.0))) * np.outer(g, g)
            fb = 0.0 if new[i] == 0 else (k * s[i] if new[i] == 1 else F_hold)
            rA += (fb - T[i]) * g
    return _solve(JA, rA)


@njit(cache=True, nogil=True)
def _active_set(J, r, dx, s, G, bp, par, passes):
    """:func:`ancf.dynamics.integrator.active_set_update` (the Newton update of the piecewise-linear length
    springs): the same ``passes``, the same search over all branches when they cycle, the same arithmetic."""
    k, F_hold, m = par[P_KPEN], par[P_FHOLD], s.size
    cur, T = _branches(s, k, F_hold)
    used = cur.copy()
    for _ in range(passes):
        new = _branches(s - bp * (G @ dx), k, F_hold)[0]
        if np.all(new == used):
            return dx
        solved, d = _branch_solve(J, r, s, G, bp, k, F_hold, cur, T, new)
        if not solved:
            return dx
        used, dx = new, d
    if np.all(_branches(s - bp * (G @ dx), k, F_hold)[0] == used):
        return dx
    n_br = 3 if F_hold < np.inf else 2
    new = np.empty(m, dtype=np.int64)
    for changes in range(1, m + 1):
        for code in range(n_br ** m):
            n_changed = 0
            for i in range(m):
                new[i] = (code // n_br ** i) % n_br
                if new[i] != cur[i]:
                    n_changed += 1
            if n_changed != changes:
                continue
            solved, d = _branch_solve(J, r, s, G, bp, k, F_hold, cur, T, new)
            if solved and np.all(_branches(s - bp * (G @ d), k, F_hold)[0] == new):
                return d
    return dx


@njit(cache=True, nogil=True)
def _next_lambda(lam, f0, ft):
    """:func:`ancf.dynamics.integrator.next_lambda`."""
    if not ft < np.inf:
        return 0.5 * lam
    curv = (ft - f0 * (1.0 - 2.0 * lam)) / (lam * lam)
    best = f0 / curv if curv > 0.0 else 0.5 * lam
    return min(0.5 * lam, max(0.1 * lam, best))


@njit(cache=True, nogil=True)
def alpha_step_c(z, v, acc, a, prev_acc, has_prev, h, L, arr, par):
    """:func:`ancf.dynamics.integrator.alpha_step` (rtol, atol, vtol = RTOL, ATOL, VTOL): (ok, z, v, z̈, a,
    Newton iterations, Π [J] at the new z) under the loads of the load-table row L; not ok where the Python step
    raises StepFailed.  Π is the potential under the step's loads (:func:`_system`), at the last evaluated state
    plus ∂Π/∂z · Δz when the last update moved z by Δz without a new evaluation (|Δz| ≤ h·VTOL: the neglected
    ½ Δzᵀ K Δz is far below round-off of Π); the linear system is solved in the band of ``par[P_BAND]`` diagonals
    when that is ≥ 0; the update is the active-set one of the length springs (:func:`_active_set`) and its length
    the line search's (:func:`.integrator.line_search`)."""
    rho, am, af, gam, beta = par[P_RHO], par[P_AM], par[P_AF], par[P_GAMMA], par[P_BETA]
    k = (1.0 - af) / (1.0 - am)
    bp, gp = h * h * beta * k, h * gam * k
    x = acc.copy()
    if has_prev and np.linalg.norm(acc + rho * prev_acc) < np.linalg.norm(acc - prev_acc):
        x = -rho * acc
    a_const = (af * acc - am * a) / (1.0 - am)
    z_pred = z + h * v + h * h * (0.5 - beta) * a
    v_pred = v + h * (1.0 - gam) * a
    x_hold = ((z - z_pred) / (h * h * beta) - a_const) / k
    ok, a1, z1, v1, r, M, Kt, Ct, scale, En, Qr, st, G = _evaluate(x, k, a_const, z_pred, v_pred, h, L, arr, par)
    if not ok:
        x = x_hold
        ok, a1, z1, v1, r, M, Kt, Ct, scale, En, Qr, st, G = _evaluate(x, k, a_const, z_pred, v_pred, h, L, arr,
                                                                       par)
        if not ok:
            return False, z, v, acc, a, 0, 0.0
    elif par[P_LMODE] > 0:                # :func:`.integrator._spring_start`: the start with the smaller residual
        okh, a1h, z1h, v1h, rh, Mh, Kth, Cth, sch, Enh, Qrh, sth, Gh = _evaluate(x_hold, k, a_const, z_pred, v_pred,
                                                                                 h, L, arr, par)
        if okh and np.linalg.norm(rh) < np.linalg.norm(r):
            x, a1, z1, v1, r, M, Kt, Ct = x_hold, a1h, z1h, v1h, rh, Mh, Kth, Cth
            scale, En, Qr, st, G = sch, Enh, Qrh, sth, Gh
    band = int(par[P_BAND])
    for it in range(1, int(par[P_MAXIT]) + 1):
        rn = np.linalg.norm(r)
        if not np.isfinite(rn):
            return False, z, v, acc, a, it, 0.0
        if rn <= ATOL + RTOL * scale:
            return True, z1, v1, x, a1, it, En
        J = np.empty_like(M)
        for i in range(M.shape[0]):
            for j in range(M.shape[1]):
                J[i, j] = (M[i, j] + gp * Ct[i, j]) + bp * Kt[i, j]
        if band >= 0:
            solved, dx = band_solve(J, r, band, band)
        else:
            solved, dx = _solve(J, r)
        if not solved:
            return False, z, v, acc, a, it, 0.0
        if par[P_LMODE] > 0:
            dx = _active_set(J, r, dx, st, G, bp, par, ACTIVE_SET_PASSES)
        if gp * np.abs(dx).max() <= VTOL:
            x = x - dx
            a1 = k * x + a_const
            zn = z_pred + h * h * beta * a1
            return True, zn, v_pred + h * gam * a1, x, a1, it, En + Qr @ (zn - z1)
        lam, f0, moved = 1.0, rn * rn, False
        for _ in range(LINE_SEARCH_TRIES):
            xt = x - lam * dx
            okt, a1n, z1n, v1n, rt_, Mn, Ktn, Ctn, scn, Enn, Qrn, stn, Gn = _evaluate(xt, k, a_const, z_pred, v_pred,
                                                                                     h, L, arr, par)
            if not okt:
                lam *= 0.5
                continue
            rt = np.linalg.norm(rt_)
            if rt <= (1.0 - ARMIJO * lam) * rn or rt <= RESIDUAL_FLOOR * scale:
                x = xt
                a1, z1, v1, r, M, Kt, Ct = a1n, z1n, v1n, rt_, Mn, Ktn, Ctn
                scale, En, Qr, st, G = scn, Enn, Qrn, stn, Gn
                moved = True
                break
            lam = _next_lambda(lam, f0, rt * rt)
        if not moved:
            return False, z, v, acc, a, it, 0.0
    return False, z, v, acc, a, int(par[P_MAXIT]), 0.0


@njit(cache=True, nogil=True)
def potential_known(par):
    """True when a row's potential is the step's own Π (:func:`alpha_step_c`): tensions prescribed and no load
    varying (then Π = E0 + T·l − p V − F·p_end under the row's loads, and no work of the loads is summed)."""
    return par[P_LMODE] == 0 and par[P_VARYING] == 0


@njit(cache=True, nogil=True)
def _tensions(L, m):
    """The prescribed tensions (m,) [N] of the load-table row L."""
    return L[L_VAR:L_VAR + m].copy()


@njit(cache=True, nogil=True)
def _lengths(L, m):
    """The motor lengths (m,) [m] of the load-table row L."""
    return L[L_VAR + m:L_VAR + 2 * m].copy()


@njit(cache=True, nogil=True)
def _law_energies(q, arr, par):
    """(U_A, U_B) [J]: the axial and the bending energy of the law at p = 0 (a pressure-dependent law's parts,
    :meth:`ancf.dynamics.transient._EnergyParts.parts`)."""
    N, wq, ea, ei, E, d, co, so = arr[2], arr[3], arr[4], arr[5], arr[8], arr[9], arr[10], arr[11]
    z1, z3, zm, n = np.zeros(1), np.zeros(3), np.zeros(d.size), int(par[P_N])
    UA = assemble(q, n, N, wq, ea, z1, z1, z3, E, d, co, so, zm, 0.0, z3, False, 0)[0]
    UB = assemble(q, n, N, wq, z1, ei, z1, z3, E, d, co, so, zm, 0.0, z3, False, 0)[0]
    return UA, UB


@njit(cache=True, nogil=True)
def _volume(q, arr, par):
    """The chamber volume V = ∫ Σ_c vc_c λ^(c+1) dx [m³] (per unit pressure: −∂Π/∂p)."""
    N, wq, vc = arr[2], arr[3], arr[6]
    V = 0.0
    for e in range(int(par[P_N])):
        o = 6 * e
        for kq in range(wq.size):
            s0 = s1 = s2 = 0.0
            for j in range(4):
                s0 += N[kq, 1, j] * q[o + 3 * j]
                s1 += N[kq, 1, j] * q[o + 3 * j + 1]
                s2 += N[kq, 1, j] * q[o + 3 * j + 2]
            lam = np.sqrt(s0 * s0 + s1 * s1 + s2 * s2)
            acc = 0.0
            for c in range(vc.size):
                acc += vc[c] * lam ** (c + 1)
            V += wq[kq] * acc
    return V


@njit(cache=True, nogil=True)
def _point(z, v, L, arr, par, out):
    """The row quantities of the state (z, v) under the loads of the load-table row L (time, pressure, motor
    lengths; the recorder's point): writes (E0, V, p_end, power, pr, t, U_A, U_B, lengths) to ``out`` (``prev``
    layout); returns (q, vq, T).  When :func:`potential_known` only p_end, the power and t are needed: E0, V,
    U_A, U_B and the lengths are left at 0."""
    q_fix, P, N, wq, C_R = arr[0], arr[1], arr[2], arr[3], arr[14]
    use_P, n, m = par[P_USEP] > 0, int(par[P_N]), arr[9].size
    q = to_full(z, q_fix, P, use_P)
    vq = to_full(v, np.zeros(q.size), P, use_P)
    known = potential_known(par)
    E0, V, UA, UB, lq = 0.0, 0.0, 0.0, 0.0, np.zeros(m)
    if not known:
        E0, lq = _values(q, arr, par)
        V = _volume(q, arr, par)
        if par[P_PDEP] > 0:
            UA, UB = _law_energies(q, arr, par)
    T = _springs(lq, _lengths(L, m), par) if par[P_LMODE] > 0 else _tensions(L, m)
    pw = 0.0
    if par[P_HASCR] > 0:
        pw += (v @ C_R) @ v
    if par[P_CAX] > 0:
        pw += vq @ axial_damping_c(q, vq, n, N, wq, par[P_CAX], False)[0]
    pe = tip_position(q, par[P_HTOOL])
    out[0], out[1], out[2:5], out[5], out[6], out[7], out[8], out[9] = E0, V, pe, pw, L[L_PR], L[L_T], UA, UB
    out[N_PREV:] = lq
    return q, vq, T


@njit(cache=True, nogil=True)
def potential(pt, L, arr, par):
    """Π [J] of the point ``pt`` (``prev`` layout) under the loads of the load-table row L: tensions [N] (or
    motor lengths [m]), pressure [Pa] and its law factors, tip force [N]
    (:meth:`ancf.dynamics.transient._EnergyParts.potential`)."""
    pr, F = L[L_PR], L[L_F:L_F + 3]
    Pi = pt[0] - pr * pt[1] - (F[0] * pt[2] + F[1] * pt[3] + F[2] * pt[4])
    if par[P_PDEP] > 0:
        Pi += (L[L_FA] - 1.0) * pt[8] + (L[L_FI] - 1.0) * pt[9]
    lq = pt[N_PREV:]
    m = lq.size
    if par[P_LMODE] > 0:
        s = 0.0
        for i in range(m):
            st = max(lq[i] - L[L_VAR + m + i], 0.0)
            sc = min(st, par[P_SHOLD])
            s += 0.5 * par[P_KPEN] * sc ** 2
            if np.isfinite(par[P_FHOLD]):
                s += par[P_FHOLD] * (st - sc)
        Pi += s
    else:
        Pi += _tensions(L, m) @ lq
    return Pi


@njit(cache=True, nogil=True)
def _increment(pa, pb, La, Lb, arr, par):
    """(work [J] of the time-varying loads, dissipation [J]) from point pa under the loads La to point pb under
    Lb (trapezoids)."""
    dW = 0.0
    if par[P_VARYING] > 0:
        dW = 0.5 * ((potential(pa, Lb, arr, par) - potential(pa, La, arr, par))
                    + (potential(pb, Lb, arr, par) - potential(pb, La, arr, par)))
    return dW, 0.5 * (pb[5] + pa[5]) * (pb[7] - pa[7])


@njit(cache=True, nogil=True)
def _kinetic(q, vq, M0, par):
    """K = ½ q̇ᵀ (M0 + m_tip J_pᵀ J_p) q̇ [J] as ½ q̇ᵀ M0 q̇ + ½ m_tip |J_p q̇|² (J_p: the tool point's Jacobian;
    no ndof × ndof matrix formed per row)."""
    K = 0.5 * ((vq @ M0) @ vq)
    if par[P_MTIP] > 0:
        vp = tip_jacobian(q, par[P_HTOOL]) @ vq
        K += 0.5 * par[P_MTIP] * (vp @ vp)
    return K


@njit(cache=True, nogil=True)
def run_rows(i0, i1, times, state, sc, prev, arr, par, tab, o_q, o_v, o_tip, o_T, o_p, o_kin, o_pot, o_work,
             o_diss, o_it):
    """Rows i0 … i1 − 1 of a run from the state (z, ż, z̈, a, previous z̈) = ``state`` (5, nz) at
    (has previous z̈, t [s], pressure [Pa]) = ``sc``, the last row's point ``prev``, the loads of every substep
    end in ``tab`` (row 0: the start's); writes the rows into the output arrays (the recorder's) and updates
    state, sc and prev in place.  Returns (DONE, i1) or (FALLBACK, i): row i not done, the state at row i − 1
    (module docstring)."""
    h, hsub = par[P_H], par[P_HSUB]
    M0 = arr[12]
    pb = np.empty(prev.size)
    ks = 0                                          # the load-table row of the current state
    for i in range(i0, i1):
        z, v, acc, a, pacc = state[0].copy(), state[1].copy(), state[2].copy(), state[3].copy(), state[4].copy()
        has_prev, tt = sc[0] > 0, sc[1]
        t_target = times[i]
        pa = prev.copy()
        ka, k = ks, ks
        dW = dD = Pi = 0.0
        n_it = 0
        while t_target - tt > 1e-12 * h:
            hh = min(hsub, t_target - tt)
            if t_target - tt - hh < 1e-9 * hh:
                hh = t_target - tt
            t1 = t_target if hh == t_target - tt else tt + hh
            k += 1
            if k >= tab.shape[0] or tab[k, L_T] != t1 or tab[k, L_OK] == 0:
                return FALLBACK, i
            ok, z1, v1, acc1, a1, n_k, Pi = alpha_step_c(z, v, acc, a, pacc, has_prev, hh, tab[k], arr, par)
            if not ok:
                return FALLBACK, i
            n_it += n_k
            pacc, z, v, acc, a, has_prev = acc, z1, v1, acc1, a1, True
            tt = t1
            if t1 != t_target:
                _point(z, v, tab[k], arr, par, pb)
                w, dd = _increment(pa, pb, tab[ka], tab[k], arr, par)
                dW, dD = dW + w, dD + dd
                pa[:] = pb
                ka = k
        q, vq, T = _point(z, v, tab[k], arr, par, pb)
        w, dd = _increment(pa, pb, tab[ka], tab[k], arr, par)
        dW, dD = dW + w, dD + dd
        o_q[i], o_v[i], o_tip[i], o_T[i], o_p[i] = q, vq, pb[2:5], T, tab[k, L_PR]
        o_kin[i] = _kinetic(q, vq, M0, par)
        o_pot[i] = Pi if potential_known(par) else potential(pb, tab[k], arr, par)
        o_it[i] = n_it
        o_work[i] = o_work[i - 1] + dW
        o_diss[i] = o_diss[i - 1] + dD
        prev[:] = pb
        ks = k
        state[0], state[1], state[2], state[3], state[4] = z, v, acc, a, pacc
        sc[0], sc[1], sc[2] = 1.0 if has_prev else 0.0, tt, tab[k, L_PR]
    return DONE, i1
