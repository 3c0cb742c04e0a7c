"""The locked-compliance gap between the FEM and the reduced model on a straight tube, decomposed.

On a straight tube the FEM and the reduced model agree on the tension-held compliance but not on the locked
one (docs/identification.md, "The locked-compliance gap").  This module measures why, with the theory of
:mod:`validation.identification.cap_compliance` (the locked compliance as a function of the 6×6 cap
compliance; the rotation-free lateral compliance ``s`` that a locked tendon cannot hold): the FEM's cap
compliance and guided tendon paths against straight chords (:func:`fem_decomposition`), a rod matched to the
FEM's tension-held compliance (:func:`matched_rod`, :func:`rod_ratios`), and the table over a few states
(:func:`measure`, :func:`format_table`; ``benchmarks/locked_gap.py``).

Units: SI throughout (m, N, Pa, N m²); compliances [m/N], rotations per moment [1/(N m)].
"""

from __future__ import annotations

from typing import Optional, Sequence

import numpy as np

from ancf.errors import InputError
from validation.identification.cap_compliance import (  # noqa: F401  (re-exported: their old home)
    locked_from_cap, point_jacobian, ratio_with_shear, remove_shear, shear_compliance)

__all__ = ["locked_from_cap", "shear_compliance", "remove_shear", "ideal_line_gradients", "fem_decomposition",
           "matched_rod", "rod_ratios", "ratio_with_shear", "STATES", "measure", "format_table"]


# --------------------------------------------------------------------------- FEM side

def ideal_line_gradients(model, st) -> np.ndarray:
    """(n_q, m) gradients of the straight exit→anchor chord length of every tendon of an FEM model
    (``fem_reference.BellowsModel``) at state ``st``: nonzero on the six cap unknowns only."""
    g = np.zeros((model.n_dofs, model.m))
    sl = model.caps.cap_slice
    for k, tp in enumerate(model.tendons):
        anchor = model.X_c + st.uc + st.R @ tp.anchor
        e = anchor - tp.exit_point
        e = e / np.linalg.norm(e)
        g[sl, k] = point_jacobian(st.R @ tp.anchor).T @ e
    return g


def fem_decomposition(model, res, direction=(0.0, 0.0, -1.0)) -> dict:
    """Decompose the FEM's locked compliance about the equilibrium ``res`` of ``model``.

    Returns (SI) ``length`` (tip x [m]), ``C_tension``, ``C_locked`` (3×3 [m/N], the latter by
    :func:`validation.reference.fem_sweep.locked_compliance`, as the validation uses), ``active`` (locked taut
    tendons), ``C6`` (6×6 cap compliance), ``g_deviation`` (largest ‖g − g_line‖/‖g‖ over the tendons: the
    guided path's length gradient against the straight chord's), ``C_locked_line`` (from ``C6`` and the
    straight chords, :func:`locked_from_cap`), ``EI_moment`` = ℓ/c_θM, ``EI_tip_force`` = ℓ³/(3 c_δF) [N m²]
    along z (ℓ the current length), ``shear_z``, ``shear_y`` [m/N] (:func:`shear_compliance`), ``share_z`` =
    s/c_δF, ``C_locked_no_shear`` (locked compliance of ``C6`` without s) and the z stiffness ratios
    ``ratio`` (exact), ``ratio_line``, ``ratio_no_shear``."""
    from fem_reference.solver import factorize
    from validation.reference.fem_sweep import locked_compliance
    st = res.state
    ev = model.evaluate(st, res.loadcase, tangent=True)
    fac = factorize(ev["K"], model.linear_solver)
    E = np.zeros((model.n_dofs, 6))
    E[model.caps.cap_slice, :] = np.eye(6)
    C6 = E.T @ fac.solve(E)
    g, gl = ev["g"], ideal_line_gradients(model, st)
    dev = float(max(np.linalg.norm(g[:, k] - gl[:, k]) / np.linalg.norm(g[:, k]) for k in range(model.m)))
    Ct = model.tip_compliance(res, mode="tension")
    Cl, active = locked_compliance(model, res, direction)
    tip_off = st.R @ model.a_tip
    anchors = [st.R @ model.tendons[i].anchor for i in active]
    chords = []
    for i in active:
        a = model.X_c + st.uc + st.R @ model.tendons[i].anchor - model.tendons[i].exit_point
        chords.append(a / np.linalg.norm(a))
    C_line = locked_from_cap(C6, tip_off, np.reshape(anchors, (-1, 3)), np.reshape(chords, (-1, 3)))
    sz, sy = shear_compliance(C6, (0, 0, 1)), shear_compliance(C6, (0, 1, 0))
    C6n = remove_shear(C6, {(0.0, 0.0, 1.0): sz, (0.0, 1.0, 0.0): sy})
    C_ns = locked_from_cap(C6n, tip_off, np.reshape(anchors, (-1, 3)), np.reshape(chords, (-1, 3)))
    Ct_ns = locked_from_cap(C6n, tip_off, np.zeros((0, 3)))
    ell = float(res.tip_position[0])
    w = np.array([0.0, -1.0, 0.0])
    return {"length": ell, "pressure": float(res.loadcase.pressure), "tensions": np.asarray(st.T, float).copy(),
            "C_tension": Ct, "C_locked": Cl, "active": list(active), "C6": C6, "g_deviation": dev,
            "C_locked_line": C_line, "EI_moment": ell / float(w @ C6[3:, 3:] @ w),
            "EI_tip_force": ell ** 3 / (3 * Ct[2, 2]), "shear_z": sz, "shear_y": sy, "share_z": sz / Ct[2, 2],
            "C_locked_no_shear": C_ns, "ratio": Ct[2, 2] / Cl[2, 2], "ratio_line": Ct[2, 2] / C_line[2, 2],
            "ratio_no_shear": Ct_ns[2, 2] / C_ns[2, 2]}


# --------------------------------------------------------------------------- reduced-model side

def matched_rod(base, length: float, tensions, pressure: float, c_axial: float, c_lateral: float, *,
                iterations: int = 30, rtol: float = 1e-9):
    """The reduced model (constant EA, EI) that, straight under ``tensions`` [N] and ``pressure`` [Pa]
    without gravity, has the tip position x = ``length`` [m], the tension-held axial compliance ``c_axial``
    and lateral (z) compliance ``c_lateral`` [m/N] — the rod an identification makes of that FEM state.

    ``base`` : :class:`ancf.ActuatorParams` giving L, the tendons, n, the tool offset and the rest (gravity is
    switched off).  Returns (params, eq).
    With W'(λ) = ½ EA (λ³ − λ) the axial compliance L / (½ EA (3λ² − 1)) gives EA, the section force at the
    stretch λ = length/L gives the pressure area (p A_eff − ΣT = W'(λ)), and EI follows from a multiplicative
    fixed point on the lateral compliance."""
    from ancf import Model, StiffnessLaw
    from ancf import compliance as cp
    L = base.length
    lam = length / L
    T = np.asarray(tensions, float)
    EA = 2 * L / (c_axial * (3 * lam ** 2 - 1))            # first guesses: the closed forms above
    A = (0.5 * EA * (lam ** 3 - lam) + T.sum()) / pressure if pressure > 0 else base.A_eff
    if A <= 0:
        raise InputError(f"no positive pressure area reaches the stretch {lam:.4f} under these loads")
    EI = length ** 3 / (3 * c_lateral)
    params = eq = None
    for _ in range(iterations):
        params = base.replace(stiffness=StiffnessLaw.constant(EA, EI), D_eff=float(np.sqrt(4 * A / np.pi)),
                              gravity=(0.0, 0.0, 0.0))
        model = Model(params)
        eq = model.fk(tuple(T), pressure, check_limits=False)
        C = cp.tension(model, eq).C_p
        err = (C[0, 0] / c_axial - 1, C[2, 2] / c_lateral - 1, (eq.tip[0] - length) / length if pressure > 0 else 0.0)
        if max(abs(x) for x in err) < rtol:
            break
        EA *= C[0, 0] / c_axial
        EI *= C[2, 2] / c_lateral
        if pressure > 0:
            A += (length - eq.tip[0]) / (pressure * C[0, 0])  # Newton on the length: ∂x/∂A = p c_xx
    return params, eq


def rod_ratios(params, eq, direction=(0.0, 0.0, -1.0), shear: float = 0.0) -> dict:
    """Locked/held z stiffness ratio of the reduced model at ``eq`` (exact locked compliance, same taut-set
    rule as the validation), and with a series rotation-free compliance ``shear`` [m/N] added along z to
    both compliances (what a shear-flexible rod would give).  Returns ``ratio``, ``ratio_shear``,
    ``C_tension``, ``C_locked``, ``active``."""
    from ancf import Model
    from ancf import compliance as cp
    model = Model(params)
    Ct = cp.tension(model, eq).C_p
    cl = cp.locked(model, eq, method="exact", load_direction=direction)
    Cl = cl.C_p
    return {"ratio": Ct[2, 2] / Cl[2, 2], "ratio_shear": (Ct[2, 2] + shear) / (Cl[2, 2] + shear),
            "C_tension": Ct, "C_locked": Cl, "active": list(cl.active)}


#: The straight states measured: (pressure as a fraction of the design's p_max, equal tension [N]).
STATES = ((0.0, 0.0), (0.5, 0.0), (1.0, 0.0), (0.0, 2.5), (0.5, 2.5), (1.0, 2.5))


def measure(design="paper", mesh: str = "coarse", states: Sequence = STATES, *, pressure_max: Optional[float] = None,
            cache: Optional[str] = None, log=None) -> list[dict]:
    """Solve the straight ``states`` on the FEM of ``design`` (warm-started in order), decompose each
    (:func:`fem_decomposition`) and put the matched reduced model beside it (:func:`matched_rod`,
    :func:`rod_ratios`, with EI matched to the held compliance — the reduced model — and the same with the
    reduced model's series shear compliance ``shear_compliance`` = max(s, 0) (:mod:`ancf.shear`), EI matched to
    the held compliance with s included — the shear rod).  ``cache``: an ``.npz`` path per
    state is written/read under this directory.  Returns one dict per state (SI)."""
    import pathlib
    from validation.reference.designs import design_limits, load_design
    from validation.identification.identify import fem_base_params
    geo, mat = load_design(design)
    p_max = design_limits(design)["pressure_max"] if pressure_max is None else float(pressure_max)
    base = fem_base_params(geo, mat, pressure_max=p_max).replace(gravity=(0.0, 0.0, 0.0))
    model, prev, rows = None, None, []
    for frac, T in states:
        p = frac * p_max
        tens = (T,) * len(geo.tendon_angles)
        path = None if cache is None else pathlib.Path(cache) / f"{design}_{mesh}_p{p:.0f}_T{T:g}.npz"
        if path is not None and path.exists():
            z = np.load(path, allow_pickle=True)
            fem = z["fem"].item()
        else:
            if model is None:
                from fem_reference import BellowsModel
                model = BellowsModel(geo, mat, mesh=mesh)
            res = model.solve(tensions=tens, pressure=p, initial=prev)
            prev = res
            fem = fem_decomposition(model, res)
            if path is not None:
                path.parent.mkdir(parents=True, exist_ok=True)
                np.savez(path, fem=np.array(fem, dtype=object))
        Ct = fem["C_tension"]
        params, eq = matched_rod(base, fem["length"], tens, p, Ct[0, 0], Ct[2, 2])
        rod = rod_ratios(params, eq)
        # the shear rod: the reduced model with its own series shear compliance (ancf.shear) s = the FEM's
        # rotation-free compliance at this state (≥ 0: a negative measured s is taken as none), EI matched to
        # the held compliance with s included — its compliances carry s P⊥ themselves
        s_rod = max(float(fem["shear_z"]), 0.0)
        params_b, eq_b = matched_rod(base.replace(shear_compliance=(s_rod,)), fem["length"], tens, p, Ct[0, 0],
                                     Ct[2, 2])
        rod_b = rod_ratios(params_b, eq_b)
        row = {"pressure_Pa": p, "tension_N": T, "fem": fem, "rod_ratio": rod["ratio"],
               "rod_active": rod["active"], "rod_C_tension": rod["C_tension"], "rod_C_locked": rod["C_locked"],
               "shear_rod_ratio": rod_b["ratio"], "shear_rod_s": s_rod,
               "shear_rod_C_locked_zz": rod_b["C_locked"][2, 2],
               "locked_error_pct": 100 * (rod["C_locked"][2, 2] / fem["C_locked"][2, 2] - 1),
               "shear_locked_error_pct": 100 * (rod_b["C_locked"][2, 2] / fem["C_locked"][2, 2] - 1)}
        rows.append(row)
        if log is not None:
            log(format_table([row], header=not rows[:-1]))
    return rows


def format_table(rows, header: bool = True) -> str:
    """The measurement as a Markdown table (one line per state)."""
    out = []
    if header:
        out += ["| p [kPa] | T [N] | taut | FEM ratio | FEM, straight-line tendon | max ‖g − g_line‖/‖g‖ | "
                "EI moment / tip force [N m²] | rotation-free share of c_zz [%] | FEM ratio without it | "
                "reduced model ratio | locked c_zz, model vs FEM [%] | shear rod ratio | locked c_zz, shear rod vs FEM [%] |",
                "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        f = r["fem"]
        out.append(f"| {r['pressure_Pa'] / 1e3:.0f} | {r['tension_N']:g} | {len(f['active'])} | {f['ratio']:.3f} | "
                   f"{f['ratio_line']:.3f} | {f['g_deviation']:.0e} | {f['EI_moment']:.4f} / {f['EI_tip_force']:.4f} | "
                   f"{100 * f['share_z']:.1f} | {f['ratio_no_shear']:.3f} | {r['rod_ratio']:.3f} | "
                   f"{r['locked_error_pct']:+.1f} | {r['shear_rod_ratio']:.3f} | {r['shear_locked_error_pct']:+.1f} |")
    return "\n".join(out)
