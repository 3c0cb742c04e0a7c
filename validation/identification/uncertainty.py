r"""What an identification's intervals contain: the stated noise of every input, propagated, and the misfit
the model cannot explain.

**Errors in variables.**  A measured static state i has inputs u_i = (T_1 … T_m [N], p [Pa], F_x, F_y, F_z [N])
that are themselves measured, with stated standard deviations (the ``tensions_std``, ``pressure_std`` and
``tip_force_std`` of the static-states format, :mod:`hardware.static_states`).  The model is evaluated at the
*recorded* inputs, so an input error δu moves the prediction by G_i δu, G_i = ∂x̂_i/∂u the model's own input
sensitivity at the equilibrium.  At an equilibrium Q(q, u) = 0, so K δq + (∂Q/∂u) δu = 0 and

    ∂x/∂u = −J_x K⁻¹ ∂Q/∂u + ∂x/∂u|_q,      ∂Q/∂T = (∂l_c/∂q)ᵀ,  ∂Q/∂p = Model.dQ_dp,  ∂Q/∂F = −(∂p_end/∂q)ᵀ

(reduced coordinates, K the tangent; J_x the tool point's or a marker's Jacobian; the direct term is the series
shear offset s(p) P⊥F of a shear form, linear in F and in s).  To first order the residual of state i then has
the covariance

    C_i = diag(σ_x,i²) + G_i diag(σ_u,i²) G_iᵀ                        (d × d, d = 3 + 3k: tip and markers)

and the fit minimises Σ_i r_iᵀ C_i⁻¹ r_i, i.e. the residuals whitened by L_i⁻¹ with C_i = L_i L_iᵀ (the
*effective variance* method of errors in variables).  G_i depends on θ, so the whitening is recomputed at the
optimum and the fit repeated from there until θ moves by less than 1 % of its standard deviation
(:data:`WEIGHT_RTOL`, at most :data:`WEIGHT_ITERATIONS` refits); the parameter
covariance (J_wᵀ J_w)⁻¹ then carries the input noise.  Without stated input noise C_i is the diagonal of the tip
and marker σ's and nothing changes.

**Model-form error.**  With stated noise the reduced χ² = RSS_w/(n − k) should be ≈ 1 ± √(2/(n − k)); a value
above 1 says the residuals exceed every stated noise: the model is not exact (or the noise is understated).
Then the covariance is scaled by χ²/dof (never shrunk below the stated noise: the scale is max(1, χ²/dof)) and
the quantile is Student's t with n − k degrees of freedom (:func:`variance_scale`).  The interval then contains
the stated noise of the tip, the markers and the inputs, and the misfit beyond it spread evenly over the
states; it does not contain a model error that the parameters absorb without leaving a residual (an error
along the directions the parameters move the predictions).  ``FitResult.interval_basis`` says which applies.

**A misfit is loud** (:func:`misfit`).  With stated noise, χ²/dof above max(:data:`MISFIT_FACTOR`,
χ²₀.₉₉₉(dof)/dof) says the model does not describe the data: the quantile keeps noise alone from raising it
(1 in 1000 fits of an exact model; it governs below ≈ 6 degrees of freedom), and the factor 4 — the residual
RMS twice the stated noise, three quarters of the residual variance unexplained by it — keeps a small,
common model-form error (whose intervals the χ² scaling covers) from raising it.  Above it the parameters are
the best compromise of a model that cannot reach the data — e.g. a mass or a friction left out — and their
intervals, scaled or not, describe that compromise, not the actuator: the fit's result, fit.json, the report
and the command line say so (``FitResult.misfit``).
"""

from __future__ import annotations

from typing import Optional

import numpy as np
import scipy.stats as st

__all__ = ["input_jacobian", "state_covariance", "whitening", "whiten", "diagonal_whitening", "variance_scale",
           "misfit", "misfit_threshold", "WEIGHT_ITERATIONS", "WEIGHT_RTOL", "MISFIT_FACTOR", "MISFIT_QUANTILE"]

#: Refits with the whitening recomputed at the optimum (errors in variables; the module docstring).
WEIGHT_ITERATIONS = 4
#: … stopped when no free parameter moved by more than this × its standard deviation.
WEIGHT_RTOL = 0.01
#: A misfit is reported when χ²/dof (stated noise) exceeds this factor … (module docstring)
MISFIT_FACTOR = 4.0
#: … and the χ²/dof this quantile of χ²(dof)/dof gives (noise alone exceeds it in 1 fit of 1000).
MISFIT_QUANTILE = 0.999


def input_jacobian(model, q: np.ndarray, tensions, pressure: float, tip_force, S: Optional[np.ndarray] = None
                   ) -> np.ndarray:
    """∂(tool point, markers)/∂u (3 + 3k, m + 4) at the equilibrium ``q`` of ``model`` (full coordinates) under
    ``tensions`` (m,) [N], ``pressure`` [Pa], ``tip_force`` (3,) [N]; u = (T_1 … T_m, p, F_x, F_y, F_z).
    Columns: [m/N] for tensions and forces, [m/Pa] for the pressure.  ``S`` (3k, ndof): the markers' position
    matrix (:func:`validation.identification.forms.position_matrix`) or None.  One linear solve with the
    equilibrium's tangent (module docstring)."""
    T = np.asarray(tensions, float)
    F = np.asarray(tip_force, float)
    p = float(pressure)
    ev = model.evaluate(q, T, p, F)
    H = model.reduce_mat(ev.K)
    dQ = np.column_stack([model.dQ_dT(q), model.dQ_dp(q, p), model.dQ_dF(q)])         # (ndof, m + 4)
    dz = -np.linalg.solve(H, model.reduce_vec(dQ.T).T)                                 # (nz, m + 4)
    k = 0 if S is None else S.shape[0] // 3
    G = np.zeros((3 + 3 * k, dQ.shape[1]))
    G[:3] = model.reduce_vec(model.tool_jacobian(q, p, F)) @ dz
    if model.params.shear_compliance:        # the shear offset s(p) P⊥F_tot at fixed q: linear in F and in s
        m = T.size
        u0 = model.shear_offset(q, p, F)
        hp = max(1.0, 1e-6 * abs(p))
        G[:3, m] += (model.shear_offset(q, p + hp, F) - u0) / hp
        for j in range(3):
            e = np.zeros(3)
            e[j] = 1.0
            G[:3, m + 1 + j] += model.shear_offset(q, p, F + e) - u0
    if k:
        G[3:] = model.reduce_vec(S) @ dz
    return G


def state_covariance(G: np.ndarray, output_sd: np.ndarray, input_sd: np.ndarray) -> np.ndarray:
    """C = diag(output_sd²) + G diag(input_sd²) Gᵀ (d, d) [m²]: the residual covariance of one state with
    output (tip, markers) standard deviations ``output_sd`` (d,) [m] and input standard deviations ``input_sd``
    (m + 4,) [N, Pa, N] propagated through ``G`` (d, m + 4) (:func:`input_jacobian`)."""
    Gs = G * np.asarray(input_sd, float)[None, :]
    return np.diag(np.asarray(output_sd, float) ** 2) + Gs @ Gs.T


def whitening(C: np.ndarray) -> np.ndarray:
    """L⁻¹ (d, d) with C = L Lᵀ (Cholesky): ``whitening(C) @ r`` has unit covariance when r has covariance C."""
    L = np.linalg.cholesky(C)
    return np.linalg.solve(L, np.eye(C.shape[0]))


def diagonal_whitening(w: np.ndarray) -> np.ndarray:
    """Blocks (N, d, d) with the weights 1/σ ``w`` (N, d) on their diagonals: the whitening of independent
    outputs without input noise."""
    N, d = w.shape
    W = np.zeros((N, d, d))
    W[:, np.arange(d), np.arange(d)] = w
    return W


def whiten(W: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Apply the per-state whitening blocks ``W`` (N, d, d) to residuals (N·d,) or Jacobian rows (N·d, n)
    stacked state by state; returns the same shape."""
    N, d = W.shape[:2]
    xr = np.asarray(x, float).reshape(N, d, -1)
    return np.einsum("nij,njk->nik", W, xr).reshape(np.shape(x))


def variance_scale(rss: float, dof: int, absolute: bool) -> tuple:
    """(s², quantile, basis) of the intervals θ ± quantile · √(s² (JᵀJ)⁻¹)_jj: with stated noise
    (``absolute``) s² = max(1, χ²/dof) (χ² = ``rss``, the whitened residual sum) and the normal quantile while
    χ²/dof ≤ 1, Student's t(dof) above; without stated noise s² = χ²/dof and t(dof).  ``basis`` says in words
    what the intervals contain (module docstring)."""
    dof = max(int(dof), 1)
    chi2 = float(rss) / dof
    if not absolute:
        return chi2, float(st.t.ppf(0.975, dof)), "the residual scatter (no noise stated; s² = χ²/dof)"
    if chi2 <= 1.0:
        return 1.0, float(st.norm.ppf(0.975)), (f"the stated noise (χ²/dof = {chi2:.3g} ≤ 1: the residuals are "
                                                "within it)")
    return chi2, float(st.t.ppf(0.975, dof)), (f"the stated noise scaled by χ²/dof = {chi2:.3g}: the residuals "
                                               "exceed it (model-form error or understated noise)")


def misfit_threshold(dof: int) -> float:
    """χ²/dof above which a fit with stated noise does not fit its data: max(:data:`MISFIT_FACTOR`,
    χ²_q(dof)/dof), q = :data:`MISFIT_QUANTILE` (module docstring)."""
    dof = max(int(dof), 1)
    return max(MISFIT_FACTOR, float(st.chi2.ppf(MISFIT_QUANTILE, dof)) / dof)


def misfit(rss: float, dof: int, absolute: bool) -> str:
    """The warning of a fit whose reduced χ² (``rss``/``dof``, whitened by the stated noise) is above
    :func:`misfit_threshold`; "" when it is not, or when no noise is stated (``absolute`` False: χ² then has no
    scale)."""
    if not absolute:
        return ""
    chi2 = float(rss) / max(int(dof), 1)
    limit = misfit_threshold(dof)
    if not chi2 > limit:
        return ""
    return (f"the model does not fit these data within their stated noise: χ²/dof = {chi2:.3g} (> {limit:.3g}, "
            f"{dof} degrees of freedom); parameters and intervals describe the best compromise, not the actuator")
