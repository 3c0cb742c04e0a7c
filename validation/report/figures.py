"""Figures of the identification/validation report (matplotlib, Agg; each returns PNG bytes).

Every function takes plain result objects (:class:`validation.identification.identify.IdentificationResult`,
:class:`validation.checks.compare.ValidationResult`, the dict of :func:`validation.checks.compare.stiffness_vs_tension`)
and returns the PNG of one figure; :mod:`validation.report.build` embeds them (base64) and also writes them
next to the report.  Lengths are shown in mm, stiffnesses in N/mm, compliances in mm/N.

The validation figures locate the model's error rather than restate it:

* :func:`error_map_figure`: the tip error [% of L] and the compliance errors (tensions held, tendons locked) [%]
  of every compared state against its pressure [kPa] and its total tendon tension ΣT [N], with the targets, the
  FEM's own discretisation error as a ± bar where it was measured (``ValidationResult.fem_error["rows"]``) and the
  training states' tip errors beside the held-out ones; its data come from the pure :func:`error_points`;
* :func:`shapes_figure`: the difference field Δr(s) = r_rod(s) − r_FEM(s) [mm] of the centrelines at the same
  undeformed arc length s [mm] (x, y, z and |Δr|; :func:`shape_difference`), on one scale for every state,
  with the full-scale x–z overlay below it;
* :func:`ellipses_figure`: the compliance ellipses of the worst states in the x–y, x–z and y–z planes: the tip
  displacement per unit force turning in the plane, u = C f with |f| = 1 N, projected on the plane [mm/N];
* :func:`view3d_figure`: the two centrelines of the worst states in 3-D, on equal axis scales [mm].

States outside the training hull (experiment ``"extrapolation"``) are marked apart in the error map and left
out of the shape and compliance figures, as the validation's summary leaves them out.

No rows at all is the caller's mistake (:class:`~ancf.errors.InputError`); rows that lack what a figure shows
(no compliance matrices, no centrelines) give no figure (``b""``), which the report leaves out.
"""

from __future__ import annotations

import io
import math
from typing import Optional

import numpy as np

from ancf.errors import InputError

from validation.checks.compare import COMPLIANCE_TARGET_PCT, SHAPE_TARGET_PCT
from validation.reference.experiments import EXTRAPOLATION

__all__ = ["forms_figure", "correlation_figure", "residuals_figure", "shapes_figure", "ellipses_figure",
           "stiffness_figure", "error_map_figure", "error_points", "training_points", "shape_difference",
           "view3d_figure", "worst_rows", "magnification", "view_angles", "friction_figure"]

FEM_STYLE = {"color": "0.15", "lw": 2.0, "label": "FEM"}
ANCF_STYLE = {"color": "tab:red", "lw": 1.4, "ls": "--", "label": "reduced model"}


def _plt():
    import matplotlib
    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt
    return plt


def _png(fig, tight: bool = True) -> bytes:
    """The figure as PNG bytes (110 dpi); ``tight=False`` for a figure that sets its own margins (saves the
    second drawing the tight bounding box costs)."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110, bbox_inches="tight" if tight else None)
    _plt().close(fig)
    return buf.getvalue()


def forms_figure(comparison: list) -> bytes:
    """Training and held-out RMS / max tip error per model form [mm]; the chosen form is marked."""
    plt = _plt()
    rows = [r for r in comparison if "train_rms_tip_m" in r]
    names = [r["form"] + (" *" if r.get("chosen") else "") for r in rows]
    x = np.arange(len(rows))
    fig, ax = plt.subplots(figsize=(7.0, 3.6))
    bars = [("train RMS", "train_rms_tip_m", "0.7"), ("held-out RMS", "heldout_rms_tip_m", "tab:blue"),
            ("held-out max", "heldout_max_tip_m", "tab:orange")]
    w = 0.8 / len(bars)
    for i, (lab, key, col) in enumerate(bars):
        vals = [1e3 * r.get(key, np.nan) for r in rows]
        ax.bar(x + (i - 1) * w, vals, w, label=lab, color=col)
    ax.set_xticks(x, names, rotation=30, ha="right")      # eight form names side by side overlap
    ax.set_ylabel("tip error [mm]")
    ax.set_title("Model forms (* = chosen)")
    ax.legend(frameon=False, fontsize=8)
    ax.grid(axis="y", alpha=0.3)
    fig.tight_layout()
    return _png(fig)


def correlation_figure(names, corr) -> bytes:
    """Parameter correlation matrix of the chosen form's fit."""
    plt = _plt()
    corr = np.asarray(corr, float)
    fig, ax = plt.subplots(figsize=(1.0 + 0.7 * len(names), 0.8 + 0.6 * len(names)))
    im = ax.imshow(corr, vmin=-1, vmax=1, cmap="RdBu_r")
    ax.set_xticks(range(len(names)), names, rotation=45, ha="right")
    ax.set_yticks(range(len(names)), names)
    for i in range(len(names)):
        for j in range(len(names)):
            if np.isfinite(corr[i, j]):
                ax.text(j, i, f"{corr[i, j]:.2f}", ha="center", va="center", fontsize=7,
                        color="white" if abs(corr[i, j]) > 0.6 else "black")
    fig.colorbar(im, ax=ax, shrink=0.8)
    ax.set_title("Parameter correlation")
    return _png(fig)


def residuals_figure(train_labels, train_err, heldout_labels=None, heldout_err=None,
                     target_m: Optional[float] = None, target_note: str = "") -> bytes:
    """Tip error per state [mm]: training residuals and held-out prediction errors, side by side on one
    x-scale, with the target ``target_m`` [m] (e.g. the shape target, 2.5 % of L) as a dotted line, its legend
    entry followed by ``target_note`` (e.g. " (2.5 % L)")."""
    plt = _plt()
    panels = [("training residual", train_labels, train_err, "0.5")]
    if heldout_err is not None and len(heldout_err):
        panels.append(("held-out error", heldout_labels, heldout_err, "tab:blue"))
    errs = [1e3 * np.asarray(p[2], float) for p in panels]
    n_max = max(e.size for e in errs)
    fig, axes = plt.subplots(1, len(panels), figsize=(4.2 * len(panels) + 1.5, 1.2 + 0.16 * max(n_max, 8)),
                             squeeze=False, sharex=True)
    for ax, (title, labels, _, col), err in zip(axes[0], panels, errs):
        ax.barh(np.arange(err.size), err, color=col)
        ax.set_yticks(np.arange(err.size), [str(lb) for lb in labels], fontsize=6)
        ax.set_ylim(err.size - 0.5, -0.5)
        ax.set_xlabel("tip error [mm]")
        ax.set_title(title)
        ax.grid(axis="x", alpha=0.3)
        if target_m is not None:                 # labelled along the line: a legend box would cover bars
            ax.axvline(1e3 * target_m, **_target_style("target"))
            ax.text(1e3 * target_m, 0.5, f"target {1e3 * target_m:.1f} mm{target_note} ", rotation=90, ha="right",
                    va="center", fontsize=7, color="tab:red", transform=ax.get_xaxis_transform())
    axes[0, 0].set_xlim(left=0)
    fig.tight_layout()
    return _png(fig)


def _target_style(label: str) -> dict:
    return {"color": "tab:red", "ls": ":", "lw": 1.3, "label": label}


# ----------------------------------------------------------------------------------- error against the loads
#: the error map's x axes: name → (axis label, row → value)
AGAINST = {"pressure": ("pressure [kPa]", lambda r: float(r["pressure_Pa"]) / 1e3),
           "tension": ("total tendon tension ΣT [N]", lambda r: float(np.sum(r["tensions_N"])))}
#: the error map's quantities: name, row key, FEM-error key (in ``fem_error["rows"]``), axis label
QUANTITIES = (("tip", "tip_error_pct", "fem_tip_error_pct", "tip error [% L]"),
              ("C_tension", "C_tension_error_pct", "fem_C_tension_error_pct", "compliance error,\ntensions held [%]"),
              ("C_locked", "C_locked_error_pct", "fem_C_locked_error_pct", "compliance error,\ntendons locked [%]"))


def _num(v) -> float:
    """A float, NaN for None / missing / not finite (no point, no bar)."""
    try:
        v = float(v)
    except (TypeError, ValueError):
        return math.nan
    return v if math.isfinite(v) else math.nan


def _fem_by_label(fem_error: Optional[dict]) -> dict:
    rows = (fem_error or {}).get("rows") or []
    return {r["label"]: r for r in rows if isinstance(r, dict) and "label" in r}


def error_points(rows: list, fem_error: Optional[dict] = None, *, against: str = "pressure") -> dict:
    """The points of :func:`error_map_figure` from the validation rows (no computation beyond units).

    rows : ``ValidationResult.rows``; fem_error : ``ValidationResult.fem_error`` (its ``rows`` carry
    ``fem_tip_error_pct``, ``fem_C_tension_error_pct``, ``fem_C_locked_error_pct`` per label; None or absent
    values give no bar); against : ``"pressure"`` (x = p [kPa]) or ``"tension"`` (x = ΣT [N]).
    Returns {"label": [str] (N,), "x": (N,), "extrapolation": bool (N,), and per quantity q in ``tip``,
    ``C_tension``, ``C_locked``: q (N,) the model-vs-FEM error [% L or %], ``fem_`` + q (N,) the FEM's error
    [same unit], NaN where unknown; "fem_measured": bool (N,), False where the FEM error is an estimate (its
    row's ``measured`` False)}."""
    if against not in AGAINST:
        raise InputError(f"against must be one of {', '.join(AGAINST)}, got {against!r}")
    rows = list(rows or [])
    if not rows:
        raise InputError("no compared states: the error map needs at least one validation row")
    missing = [k for k in ("label", "pressure_Pa", "tensions_N", "tip_error_pct") if any(k not in r for r in rows)]
    if missing:
        raise InputError(f"validation rows lack {', '.join(missing)} (rows of validation.checks.compare.compare_records)")
    fem = _fem_by_label(fem_error)
    xf = AGAINST[against][1]
    out = {"label": [str(r["label"]) for r in rows], "x": np.array([xf(r) for r in rows], float),
           "extrapolation": np.array([r.get("experiment") == EXTRAPOLATION for r in rows], bool),
           "fem_measured": np.array([bool(fem.get(r["label"], {}).get("measured", True)) for r in rows], bool)}
    for name, key, fkey, _ in QUANTITIES:
        out[name] = np.array([_num(r.get(key)) for r in rows])
        out[f"fem_{name}"] = np.array([_num(fem.get(r["label"], {}).get(fkey)) for r in rows])
    return out


def training_points(train, tip_errors_m, length_m: float, *, against: str = "pressure") -> dict:
    """The training states of an identification as error-map points: {"x": (N,), "tip": (N,) [% L]}.

    train : :class:`validation.identification.fit.Observations` (its ``pressure`` [Pa], ``tensions`` [N]);
    tip_errors_m : (N,) the fit's tip residuals [m]; length_m : L [m] (> 0)."""
    if against not in AGAINST:
        raise InputError(f"against must be one of {', '.join(AGAINST)}, got {against!r}")
    if not (length_m > 0):
        raise InputError(f"length_m must be > 0, got {length_m!r}")
    e = np.asarray(tip_errors_m, float).ravel()
    p, T = np.asarray(train.pressure, float).ravel(), np.atleast_2d(np.asarray(train.tensions, float))
    if not (e.size == p.size == T.shape[0]):
        raise InputError(f"{e.size} tip errors for {p.size} training states")
    x = p / 1e3 if against == "pressure" else T.sum(axis=1)
    return {"x": x, "tip": 100 * e / length_m}


def _error_panel(ax, pts: dict, name: str, target: float, train: Optional[dict]) -> None:
    """One error-map panel: held-out (and extrapolation) points, FEM bars, training points, target."""
    x, y, fe, ex = pts["x"], pts[name], pts[f"fem_{name}"], pts["extrapolation"]
    if train is not None:
        ax.plot(train["x"], train["tip"], "x", color="0.55", ms=5, label="training state")
    for sel, col, what in ((pts["fem_measured"], "0.2", "measured"), (~pts["fem_measured"], "0.65", "estimated")):
        bar = sel & np.isfinite(fe) & np.isfinite(y)
        if bar.any():
            ax.errorbar(x[bar], y[bar], yerr=fe[bar], fmt="none", ecolor=col, elinewidth=1.2, capsize=3,
                        label=f"± FEM discretisation error, {what}", zorder=3)
    ax.plot(x[~ex], y[~ex], "o", color="tab:blue", ms=5, label="held-out state", zorder=4)
    if ex.any():
        ax.plot(x[ex], y[ex], "^", color="tab:orange", mfc="none", ms=6, label="extrapolation state", zorder=4)
    ax.axhline(target, **_target_style(f"target {target:g} %" + (" L" if name == "tip" else "")))
    tops = [target] + [v for v in np.concatenate([y + np.nan_to_num(fe), train["tip"] if train else []])
                       if np.isfinite(v)]
    ax.set_ylim(0, 1.12 * max(tops))
    ax.grid(alpha=0.3)


def error_map_figure(rows: list, fem_error: Optional[dict] = None, *, targets: Optional[dict] = None,
                     train: Optional[dict] = None) -> bytes:
    """The model's errors against the loads: tip error [% L] and, when the rows carry compliances, the
    compliance errors (tensions held, tendons locked) [%] against pressure [kPa] (top) and total tension
    ΣT [N] (bottom); targets dotted (``targets``: {"tip": %, "compliance": %}, default the paper's
    2.5 % of L and 5 %); the FEM's discretisation error as ± bars where measured; ``train``: {"pressure":
    :func:`training_points` (against pressure), "tension": … (against tension)} adds the training states'
    tip errors."""
    pts = {a: error_points(rows, fem_error, against=a) for a in AGAINST}
    t = {"tip": SHAPE_TARGET_PCT, "compliance": COMPLIANCE_TARGET_PCT} | dict(targets or {})
    names = [q for q in QUANTITIES if q[0] == "tip" or np.isfinite(pts["pressure"][q[0]]).any()]
    plt = _plt()
    fig, axes = plt.subplots(2, len(names), figsize=(3.5 * len(names) + 0.6, 5.6), squeeze=False, sharex="row")
    for i, (a, (xlabel, _)) in enumerate(AGAINST.items()):
        for j, (name, _, _, ylabel) in enumerate(names):
            ax = axes[i, j]
            tr = (train or {}).get(a) if name == "tip" else None
            _error_panel(ax, pts[a], name, t["tip" if name == "tip" else "compliance"], tr)
            ax.set_xlabel(xlabel)
            ax.set_ylabel(ylabel)
    handles = {}
    for ax in axes.ravel():
        for h, lab in zip(*ax.get_legend_handles_labels()):
            handles.setdefault(lab, h)
    fig.tight_layout(rect=(0, 0.07, 1, 1))
    fig.legend(handles.values(), handles.keys(), loc="lower center", ncol=min(len(handles), 4), frameon=False,
               fontsize=8)
    return _png(fig)


# ----------------------------------------------------------------------------------------------- shapes
def _in_hull(rows: list) -> list:
    """The rows that judge the model: extrapolation states (outside the training hull) are reported apart."""
    return [r for r in rows if r.get("experiment") != EXTRAPOLATION]


def worst_rows(rows: list, key: str, n: int) -> list:
    """The ``n`` rows with the largest finite ``row[key]``, worst first (rows without it left out)."""
    have = [r for r in rows if np.isfinite(_num(r.get(key)))]
    return sorted(have, key=lambda r: -float(r[key]))[:max(int(n), 0)]


def shape_difference(row: dict) -> tuple:
    """(s [mm] (k,), Δr = rod − FEM centreline [mm] (k, 3)) of one compared state, at the same undeformed
    arc length s (``shape_s_m``, ``centreline_ancf_m``, ``centreline_fem_m`` of a validation row)."""
    try:
        s = 1e3 * np.asarray(row["shape_s_m"], float).ravel()
        ca, cf = np.asarray(row["centreline_ancf_m"], float), np.asarray(row["centreline_fem_m"], float)
    except KeyError as exc:
        raise InputError(f"validation row {row.get('label', '?')!r} lacks {exc.args[0]}") from None
    if ca.shape != cf.shape or ca.shape != (s.size, 3):
        raise InputError(f"centrelines {ca.shape} and {cf.shape} do not match the {s.size} arc-length points")
    return s, 1e3 * (ca - cf)


_COMPONENTS = (("Δx", "tab:blue"), ("Δy", "tab:green"), ("Δz", "tab:purple"))


def _difference_panel(ax, s, d) -> None:
    for k, (lab, col) in enumerate(_COMPONENTS):
        ax.plot(s, d[:, k], color=col, lw=1.1, label=lab)
    ax.plot(s, np.linalg.norm(d, axis=1), color="k", lw=2.0, label="|Δr|")
    ax.axhline(0, color="0.6", lw=0.6)
    ax.grid(alpha=0.3)


def _overlay_panel(ax, row) -> None:
    """Full-scale overlay in the x–y or x–z plane, whichever holds the larger lateral deflection of the FEM."""
    cf, ca = 1e3 * np.asarray(row["centreline_fem_m"]), 1e3 * np.asarray(row["centreline_ancf_m"])
    c = 1 if np.ptp(cf[:, 1]) > np.ptp(cf[:, 2]) else 2
    ax.plot(cf[:, 0], cf[:, c], **FEM_STYLE)
    ax.plot(ca[:, 0], ca[:, c], **ANCF_STYLE)
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(alpha=0.3)
    ax.tick_params(labelsize=7)
    ax.set_xlabel("x [mm]", fontsize=8, labelpad=1)
    ax.set_ylabel(f"{'xyz'[c]} [mm]", fontsize=8, labelpad=1)


def shapes_figure(rows: list, max_states: int = 8, ncols: int = 4) -> bytes:
    """Where along the body the shapes differ: Δr = rod − FEM centreline [mm] (x, y, z, |Δr|) against the
    undeformed arc length s [mm] for the ``max_states`` states of largest shape error (worst first), all on
    one y-scale; below each, the full-scale x–z overlay [mm]."""
    if not rows:
        raise InputError("no compared states: the shape figure needs at least one validation row")
    have = [r for r in _in_hull(rows) if r.get("centreline_fem_m") is not None]
    rows = worst_rows(have, "shape_error_pct", max_states)
    if not rows:
        return b""
    plt = _plt()
    n = len(rows)
    nc = min(n, ncols)
    nr = -(-n // nc)
    diff = [shape_difference(r) for r in rows]
    lo = min(float(d.min()) for _, d in diff)
    hi = max(float(np.linalg.norm(d, axis=1).max()) for _, d in diff)
    pad = 0.06 * (hi - lo) or 1.0
    height = 3.7 * nr + 0.7
    fig = plt.figure(figsize=(2.7 * nc + 0.6, height))
    gs = fig.add_gridspec(3 * nr, nc, height_ratios=[2.4, 1.15, 0.3] * nr, left=0.07, right=0.99,
                          top=1 - 0.7 / height, bottom=0.65 / height, wspace=0.34, hspace=0.5)
    for j, (r, (s, d)) in enumerate(zip(rows, diff)):
        i, c = divmod(j, nc)
        ax = fig.add_subplot(gs[3 * i, c])
        _difference_panel(ax, s, d)
        ax.set_ylim(lo - pad, hi + pad)
        ax.set_title(f"{r['label']}\nshape error {r['shape_error_pct']:.2f} % L", fontsize=8)
        ax.set_xlabel("arc length s [mm]", fontsize=8, labelpad=1)
        ax.tick_params(labelsize=8)
        ax.set_ylabel("rod − FEM [mm]" if c == 0 else "", fontsize=8)
        ov = fig.add_subplot(gs[3 * i + 1, c])
        _overlay_panel(ov, r)
        if j == 0:
            ov.legend(frameon=False, fontsize=7, loc="best")
    h, lab = fig.axes[0].get_legend_handles_labels()
    fig.legend(h, lab, loc="lower center", ncol=len(h), frameon=False, fontsize=9,
               title="reduced model − FEM at the same arc length", title_fontsize=8)
    if len(have) > n:
        fig.text(0.01, 1 - 0.1 / height, f"the {n} of {len(have)} states with the largest shape error", fontsize=8,
                 va="top", color="0.3")
    return _png(fig, tight=False)


def _ellipse(C, i, j, n=120):
    """Tip displacement [mm] under a unit force [N] rotating in the (i, j) plane: the compliance ellipse."""
    a = np.linspace(0, 2 * np.pi, n)
    f = np.zeros((3, n))
    f[i], f[j] = np.cos(a), np.sin(a)
    u = 1e3 * (np.asarray(C, float) @ f)
    return u[i], u[j]


PLANES = ((0, 1, "x–y"), (0, 2, "x–z"), (1, 2, "y–z"))
_ELLIPSE_STYLES = (("tension", "fem", {"color": "0.15", "lw": 2.0, "label": "FEM, tensions held"}),
                   ("tension", "ancf", {"color": "tab:red", "lw": 1.4, "ls": "--", "label": "reduced model, tensions held"}),
                   ("locked", "fem", {"color": "0.55", "lw": 1.6, "label": "FEM, tendons locked"}),
                   ("locked", "ancf", {"color": "tab:orange", "lw": 1.4, "ls": ":", "label": "reduced model, tendons locked"}))


def _c_error(r: dict) -> float:
    return max(_num(r.get("C_tension_error_pct")), _num(r.get("C_locked_error_pct")))


def ellipses_figure(rows: list, max_states: int = 3) -> bytes:
    """Compliance ellipses of the ``max_states`` states of largest compliance error (worst first): tip
    displacement under a 1 N force turning in the x–y, x–z and y–z planes, projected on the plane [mm/N],
    FEM vs the reduced model, tensions held and tendons locked."""
    if not rows:
        raise InputError("no compared states: the ellipse figure needs at least one validation row")
    have = [dict(r, _c_err=_c_error(r)) for r in _in_hull(rows) if r.get("C_tension_fem") is not None]
    rows = worst_rows(have, "_c_err", max_states) or have[:max_states]
    if not rows:
        return b""
    plt = _plt()
    n = len(rows)
    fig, axes = plt.subplots(n, 3, figsize=(9.6, 3.1 * n + 0.4), squeeze=False,
                             gridspec_kw=dict(left=0.08, right=0.99, top=1 - 0.4 / (3.1 * n + 0.4),
                                              bottom=0.75 / (3.1 * n + 0.4), hspace=0.5, wspace=0.3))
    for i, r in enumerate(rows):
        curves = [(j, st, _ellipse(r[f"C_{mode}_{who}"], a, b)) for j, (a, b, _) in enumerate(PLANES)
                  for mode, who, st in _ELLIPSE_STYLES]
        h = 1.08 * max(float(np.abs(np.concatenate(u)).max()) for _, _, u in curves) or 1.0
        for j, st, u in curves:
            axes[i, j].plot(*u, **st)
        for j, (a, b, plane) in enumerate(PLANES):
            ax = axes[i, j]
            ax.set(xlim=(-h, h), ylim=(-h, h), aspect="equal")
            ax.grid(alpha=0.3)
            ax.tick_params(labelsize=7)
            ax.set_xlabel(f"u_{'xyz'[a]} [mm/N]", fontsize=8, labelpad=1)
            ax.set_ylabel(f"u_{'xyz'[b]} [mm/N]", fontsize=8, labelpad=1)
            ax.text(0.03, 0.97, f"{plane} plane", transform=ax.transAxes, va="top", fontsize=8,
                    bbox=dict(fc="white", ec="none", alpha=0.8, pad=1))
        axes[i, 0].set_title(f"{r['label']}: compliance error, tensions held {_num(r.get('C_tension_error_pct')):.1f} %,"
                             f" tendons locked {_num(r.get('C_locked_error_pct')):.1f} %", fontsize=8, loc="left")
    handles = dict(zip(*axes[0, 0].get_legend_handles_labels()[::-1]))
    fig.legend(handles.values(), handles.keys(), loc="lower center", ncol=4, frameon=False, fontsize=8)
    return _png(fig, tight=False)


def _equal_3d(ax, pts: np.ndarray) -> None:
    """Equal scales on the three axes of a 3-D plot around the points (N, 3)."""
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    c, h = (lo + hi) / 2, max(float((hi - lo).max()) / 2, 1e-9) * 1.05
    ax.set_xlim(c[0] - h, c[0] + h)
    ax.set_ylim(c[1] - h, c[1] + h)
    ax.set_zlim(c[2] - h, c[2] + h)
    ax.set_box_aspect((1, 1, 1))


def magnification(diff_mm: np.ndarray, span_mm: float, share: float = 0.1) -> float:
    """A round factor k (1, 2 or 5 × 10ⁿ, ≥ 1) that shows the largest difference |Δr| [mm] as about ``share`` of
    the span [mm] (1 when it is already that large)."""
    d = float(np.max(np.linalg.norm(np.atleast_2d(diff_mm), axis=1), initial=0.0))
    if not (d > 0) or not np.isfinite(d) or d >= share * span_mm:
        return 1.0
    raw = share * span_mm / d
    e = 10.0 ** math.floor(math.log10(raw))
    if e > raw:                               # log10 rounded up just below a power of ten (9999.999… → 4.0)
        e /= 10.0
    return float(max(m * e for m in (1, 2, 5) if m * e <= raw))


def view_angles(centreline_mm: np.ndarray) -> tuple:
    """(elevation, azimuth) [deg] of a 3-D view that faces the bending plane of a centreline (k, 3) [mm]: the
    camera looks along ±(x × n), n the lateral direction of the tip (the sign that looks from above), turned
    30° towards +x; the elevation is kept within 20°–55° and a camera looking nearly straight down keeps
    the default azimuth −60°.  A straight centreline gets the default view (20°, −60°)."""
    c = np.asarray(centreline_mm, float)
    lat = (c[-1] - c[0]) * np.array([0.0, 1.0, 1.0])
    if np.linalg.norm(lat) < 1e-6 * max(float(np.ptp(c, axis=0).max()), 1e-12):
        return 20.0, -60.0
    v = np.cross([1.0, 0.0, 0.0], lat / np.linalg.norm(lat))
    if v[2] < 0 or (v[2] == 0 and v[1] > 0):
        v = -v
    cam = np.cos(np.radians(30)) * v + np.sin(np.radians(30)) * np.array([1.0, 0.0, 0.0])
    azim = float(np.degrees(np.arctan2(cam[1], cam[0]))) if np.hypot(v[0], v[1]) > 0.5 else -60.0
    elev = float(np.clip(np.degrees(np.arcsin(np.clip(cam[2], -1, 1))), 20.0, 55.0))
    return elev, azim


def view3d_figure(rows: list, max_states: int = 3) -> bytes:
    """The FEM and the rod centrelines of the ``max_states`` states of largest shape error in 3-D, equal axis
    scales [mm], with the difference magnified: FEM + k Δr (k from :func:`magnification`, stated)."""
    if not rows:
        raise InputError("no compared states: the 3-D figure needs at least one validation row")
    rows = worst_rows([r for r in _in_hull(rows) if r.get("centreline_fem_m") is not None], "shape_error_pct",
                      max_states)
    if not rows:
        return b""
    plt = _plt()
    fig = plt.figure(figsize=(3.6 * len(rows) + 0.4, 3.9))
    for j, r in enumerate(rows):
        ax = fig.add_subplot(1, len(rows), j + 1, projection="3d")
        cf, ca = 1e3 * np.asarray(r["centreline_fem_m"]), 1e3 * np.asarray(r["centreline_ancf_m"])
        k = magnification(ca - cf, float(np.ptp(cf, axis=0).max()))
        ax.plot(*cf.T, **FEM_STYLE)
        ax.plot(*ca.T, **ANCF_STYLE)
        if k > 1:
            cm = cf + k * (ca - cf)
            ax.plot(*cm.T, color="tab:orange", lw=1.2, ls=":", label=f"FEM + {k:g} × (rod − FEM)")
            for a, b in zip(cf, cm):
                ax.plot(*np.stack([a, b]).T, color="tab:orange", lw=0.5, alpha=0.6)
        ax.scatter(*cf[0], color="k", s=12)
        ax.legend(frameon=False, fontsize=7, loc="upper left")
        _equal_3d(ax, np.vstack([cf, ca] + ([cm] if k > 1 else [])))
        ax.view_init(*view_angles(cf))
        for k, lab in enumerate("xyz"):
            getattr(ax, f"set_{lab}label")(f"{lab} [mm]", fontsize=8, labelpad=-1)
        ax.tick_params(labelsize=7, pad=0)
        ax.set_title(f"{r['label']}\nshape error {r['shape_error_pct']:.2f} % L", fontsize=8, pad=14)
    fig.subplots_adjust(left=0.02, right=0.98, wspace=0.15)
    return _png(fig)


def stiffness_figure(stiff: dict) -> bytes:
    """Vertical tip stiffness [N/mm] vs T1 [N] per pressure, tensions held and tendons locked, ANCF vs FEM
    (the Fig. 9 protocol)."""
    plt = _plt()
    curves = stiff["curves"]
    fig, axes = plt.subplots(1, len(curves), figsize=(3.4 * len(curves), 3.2), squeeze=False, sharey=True)
    for ax, (name, c) in zip(axes[0], curves.items()):
        T = np.asarray(c["T1_N"], float)
        for mode, mk in (("tension", "o"), ("locked", "s")):
            ax.plot(T, 1e-3 * np.asarray(c[f"k_{mode}_fem_N_per_m"]), marker=mk, color="0.15",
                    label=f"FEM, {mode}")
            ax.plot(T, 1e-3 * np.asarray(c[f"k_{mode}_ancf_N_per_m"]), marker=mk, color="tab:red", ls="--",
                    mfc="none", label=f"reduced model, {mode}")
        ax.set_title(name)
        ax.set_xlabel("T1 [N]")
        ax.grid(alpha=0.3)
    axes[0, 0].set_ylabel("vertical tip stiffness [N/mm]")
    axes[0, 0].legend(frameon=False, fontsize=7)
    fig.tight_layout()
    return _png(fig)


def _branch_plot(ax, T, u, s: int, color: str, who: str, dashed: bool) -> None:
    """Loading (filled ▲, solid or dashed) and unloading (open ▽, dotted) of one model's cycle; ``s`` steps per
    branch."""
    ls = "--" if dashed else "-"
    ax.plot(T[:s + 1], u[:s + 1], color=color, ls=ls, marker="^", ms=5, lw=1.6, label=f"{who}, loading")
    ax.plot(T[s:], u[s:], color=color, ls=":", marker="v", ms=5, mfc="white", lw=1.6, label=f"{who}, unloading")


def _branch_gap(T: np.ndarray, u: np.ndarray, s: int) -> tuple[np.ndarray, np.ndarray]:
    """(tensions (s + 1,) [N] ascending, unloading − loading u at each [mm]) of one cycle (both branches share the
    tensions: the unloading branch visits the loading one's in reverse)."""
    return T[:s + 1], u[s:][::-1] - u[:s + 1]


def friction_figure(friction: dict) -> bytes:
    """Per tension cycle of the friction check (:func:`validation.checks.hysteresis.friction_check`), one column per
    pressure: top, the tip displacement u [mm] against the tension of tendon 1 [N], the FEM and the reduced model,
    loading (▲, solid or dashed) and unloading (▽, dotted) apart, u along the FEM's loading direction from the
    FEM's start; bottom, the gap between the branches (unloading − loading u at each tension [mm]), the hysteresis
    itself.  Empty bytes when no cycle was compared."""
    rows = [r for r in friction.get("rows", []) if not r.get("error")]
    if not rows:
        return b""
    plt = _plt()
    fig, axes = plt.subplots(2, len(rows), figsize=(3.6 * len(rows) + 0.6, 5.6), squeeze=False,
                             gridspec_kw={"height_ratios": [3, 2]}, sharex="col")
    for j, r in enumerate(rows):
        T = np.asarray(r["tension_N"], float)
        s = (len(T) - 1) // 2
        ax, gap = axes[0, j], axes[1, j]
        for key, style, who, dashed in (("u_fem_mm", FEM_STYLE, "FEM", False),
                                        ("u_rod_mm", ANCF_STYLE, "reduced model", True)):
            u = np.asarray(r[key], float)
            _branch_plot(ax, T, u, s, style["color"], who, dashed)
            gap.plot(*_branch_gap(T, u, s), color=style["color"], ls="--" if dashed else "-", marker="o", ms=4,
                     label=who)
        ax.set_title(f"{r['pressure_kPa']:g} kPa ({r['role']}): loop ratio {r['loop_ratio']:.2f}", fontsize=9)
        gap.axhline(0.0, color="0.6", lw=0.8)
        gap.set_xlabel("tension of tendon 1 [N]")
        for a in (ax, gap):
            a.grid(alpha=0.3)
    axes[0, 0].set_ylabel("tip displacement u [mm]")
    axes[1, 0].set_ylabel("unloading − loading u [mm]")
    axes[0, 0].legend(frameon=False, fontsize=7)
    axes[1, 0].legend(frameon=False, fontsize=7)
    fig.tight_layout()
    return _png(fig)
