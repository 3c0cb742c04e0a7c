"""Figures of the paper's studies (no computation): Fig. 4 and Fig. 9 look-alikes, the element convergence
and the comparison."""

from __future__ import annotations

import pathlib
from typing import Union

import numpy as np

from validation.paper.numbers import WORKSPACE as PAPER_WORKSPACE
from validation.paper.common import pyplot as _pyplot, save_figure as _save_figure
from validation.paper.criteria import ratio_band, within


def plot_workspace(res: dict, out: Union[str, pathlib.Path]) -> list[pathlib.Path]:
    """Fig. 4 look-alike: TD (blue) and TPHD (red) tip clouds in 3-D with their hulls, plus side (x–z)
    and front (y–z) views.  Writes workspace.png and workspace.svg (scatter rasterised)."""
    from scipy.spatial import ConvexHull

    plt = _pyplot()
    fig = plt.figure(figsize=(14, 4.8))
    ax3 = fig.add_subplot(1, 3, 1, projection="3d")
    axs = fig.add_subplot(1, 3, 2)
    axf = fig.add_subplot(1, 3, 3)
    style = {"TPHD": ("tab:red", 0.25), "TD": ("tab:blue", 0.5)}
    for mode in ("TPHD", "TD"):
        c = res["clouds"][mode]
        P = c["tips"][c["ok"]] * 1e3
        col, alpha = style[mode]
        v = res["modes"][mode]["volume_cm3"]
        lab = f"{mode}: {v:.1f} cm³ ({len(P)} tips)"
        ax3.scatter(*P.T, s=1, color=col, alpha=alpha, label=lab, rasterized=True, depthshade=False)
        if len(P) >= 4 and res["modes"][mode]["volume_m3"] > 0:
            H = ConvexHull(P)
            ax3.plot_trisurf(P[:, 0], P[:, 1], P[:, 2], triangles=H.simplices, color=col, alpha=0.08,
                             linewidth=0)
            for ax, (i, j) in ((axs, (0, 2)), (axf, (1, 2))):
                H2 = ConvexHull(P[:, [i, j]])
                loop = np.append(H2.vertices, H2.vertices[0])
                ax.plot(P[loop, i], P[loop, j], color=col, lw=1.2)
        axs.scatter(P[:, 0], P[:, 2], s=1, color=col, alpha=alpha, label=lab, rasterized=True)
        axf.scatter(P[:, 1], P[:, 2], s=1, color=col, alpha=alpha, rasterized=True)
    for axis, name in zip("xyz", ("set_xlabel", "set_ylabel", "set_zlabel")):
        getattr(ax3, name)(f"{axis} [mm]")
    for a, (h, v, view) in ((axs, ("x", "z", "side")), (axf, ("y", "z", "front"))):
        a.set(xlabel=f"{h} [mm]", ylabel=f"{v} [mm]", title=f"{view} view ({h}–{v})")
        a.set_aspect("equal", adjustable="datalim")
        a.grid(alpha=0.3)
    axs.legend(loc="best", fontsize=8, markerscale=6)
    fig.suptitle(f"Workspace, {res['samples']} samples per mode: TPHD {res['increase_percent']:+.1f} % vs TD "
                 f"(paper {PAPER_WORKSPACE['increase_percent']:+.1f} %)")
    fig.tight_layout()
    return _save_figure(fig, pathlib.Path(out), "workspace")



def plot_stiffness(res: dict, out: Union[str, pathlib.Path]) -> list[pathlib.Path]:
    """Fig. 9 look-alike: one panel per pressure, k vs T1, constant tension vs locked."""
    plt = _pyplot()
    P = res["pressures_Pa"]
    T = np.asarray(res["tensions_N"])
    cv = res["curves_N_per_m"]
    fig, axes = plt.subplots(1, len(P), figsize=(4.6 * len(P), 4.0), sharey=True, squeeze=False)
    style = {"locked_linear_exact": ("tab:red", "-", "locked, linear (exact KKT)"),
             "locked_linear_paper": ("tab:orange", "--", "locked, linear (paper eq. 13)"),
             "locked_linear_ik": ("tab:purple", ":", "locked, linear (IK eq. 15)"),
             "constant_linear": ("tab:blue", "-", "constant tension, linear")}
    for i, p in enumerate(P):
        ax = axes[0, i]
        for name, (col, ls, lab) in style.items():
            if name in cv:
                ax.plot(T, cv[name][i], color=col, ls=ls, lw=1.6, label=lab)
        ax.plot(T, cv["locked_nonlinear"][i], "o", color="tab:red", mfc="none", label="locked, nonlinear FK")
        ax.plot(T, cv["constant_nonlinear"][i], "s", color="tab:blue", mfc="none",
                label="constant tension, nonlinear FK")
        ax.set_title(f"p = {p / 1e3:g} kPa")
        ax.set_xlabel(f"T{res['tendon'] + 1} [N]")
        ax.grid(alpha=0.3)
    axes[0, 0].set_ylabel("k_equivalent = m g / (z_unload − z_load) [N/m]")
    axes[0, 0].set_ylim(bottom=0)
    axes[0, -1].legend(fontsize=7, loc="best")
    fig.suptitle(f"Tip stiffness along z, {res['mass_kg'] * 1e3:g} g payload: locked / constant = "
                 f"{res['summary']['mean_ratio_nonlinear']:.2f} (paper: about 2)")
    fig.tight_layout()
    return _save_figure(fig, pathlib.Path(out), "stiffness")


def comparison_limits(ratios, bands, floor: float = 1e-6, ceil: float = 1e6) -> tuple[float, float]:
    """x limits of compare.png (log axis of ours / paper): whole decades around every positive finite ratio,
    the finite band edges and 1, within [floor, ceil]; values outside are drawn as off-scale markers."""
    vals = [min(max(v, floor), ceil) for v in list(ratios) + [e for b in bands for e in b] + [1.0]
            if np.isfinite(v) and v > 0]
    lo = 10.0 ** np.floor(np.log10(min(vals) / 1.5))
    hi = 10.0 ** np.ceil(np.log10(max(vals) * 1.5))
    return float(max(lo, floor)), float(min(hi, ceil))


def comparison_layout(res: dict) -> dict:
    """What compare.png shows, computed without drawing: ``keys`` (headlines, top to bottom), ``limits`` (x0, x1)
    of the log axis of ours / paper, ``bands`` {key: (a, b)} — the interval of
    :func:`~validation.paper.criteria.ratio_band`, clipped to the axis — and ``points``, one per preset and
    headline: {preset (index), key, value, ratio, x (where drawn), edge (None, "left", "right": off scale),
    reproduced (the verdict of :func:`~validation.paper.criteria.within`, the table's ✓/✗)}."""
    paper = res["paper"]
    crit = {k: tuple(v) for k, v in res.get("criteria", {}).items()}
    keys = [k for k, v in paper.items() if _number(v) and v
            and any(_number(p["numbers"].get(k)) for p in res["presets"])]
    full = {k: ratio_band(*crit[k], paper[k]) for k in keys if crit.get(k, (None, None)) != (None, None)}
    points = [{"preset": j, "key": k, "value": p["numbers"][k], "ratio": p["numbers"][k] / paper[k],
               "reproduced": within(p["numbers"][k], *crit.get(k, (None, None)))}
              for j, p in enumerate(res["presets"]) for k in keys if _number(p["numbers"].get(k))]
    x0, x1 = comparison_limits([q["ratio"] for q in points], full.values())
    for q in points:
        r = q["ratio"]
        q["edge"] = None if x0 <= r <= x1 else ("right" if r > x1 else "left")
        q["x"] = r if q["edge"] is None else (x0 * 1.15 if q["edge"] == "left" else x1 / 1.15)
    bands = {k: (max(a, x0), min(b, x1)) for k, (a, b) in full.items() if max(a, x0) < min(b, x1)}
    return {"keys": keys, "limits": (x0, x1), "bands": bands, "points": points}


def plot_comparison(res: dict, out: Union[str, pathlib.Path]) -> list[pathlib.Path]:
    """Ours / paper for every numeric headline with a paper value, one marker per preset (log scale).

    The green band is where :func:`validation.paper.criteria.within` — the criterion of the table's ✓ —
    counts a number as reproduced; a filled marker is a reproduced value, a hollow one a missed value.  Ratios
    off the axis (≤ 0, or beyond its limits) are drawn at the edge as ◀ / ▶ with their ratio written beside
    them, never pinned silently (:func:`comparison_layout`)."""
    plt = _pyplot()
    lay = comparison_layout(res)
    keys, (x0, x1) = lay["keys"], lay["limits"]
    fig, ax = plt.subplots(figsize=(9, 0.38 * len(keys) + 1.6))
    y = dict(zip(keys, np.arange(len(keys))[::-1]))
    for k, (a, b) in lay["bands"].items():
        ax.fill_betweenx([y[k] - 0.4, y[k] + 0.4], a, b, color="tab:green", alpha=0.12, lw=0)
    markers = "osD^v<>ph"
    n = len(res["presets"])
    labelled = set()
    for q in lay["points"]:
        j = q["preset"]
        p = res["presets"][j]
        colour = f"C{j % 10}"
        yq = y[q["key"]] + 0.12 * (j - (n - 1) / 2)
        label = None if j in labelled else f"{p['preset']} ({p['reproduced']}/{p['judged']} reproduced)"
        labelled.add(j)
        marker = markers[j % 9] if q["edge"] is None else ("<" if q["edge"] == "left" else ">")
        ax.scatter([q["x"]], [yq], marker=marker, color=colour, label=label, zorder=3,
                   facecolors="none" if q["reproduced"] is False else colour)
        if q["edge"] is not None:                   # off the axis: the arrow at the edge and the ratio beside it
            left = q["edge"] == "left"
            ax.annotate(f"{q['ratio']:.2g}× (off scale)", (q["x"], yq), xytext=(6 if left else -6, 0),
                        textcoords="offset points", ha="left" if left else "right", va="center", fontsize=6,
                        color=colour)
    ax.axvline(1.0, color="k", lw=0.8)
    ax.set_xscale("log")
    ax.set_xlim(x0, x1)
    ax.set_yticks(list(y.values()), [res["labels"][k] for k in keys], fontsize=8)
    ax.set_xlabel("ours / paper  (green: counted as reproduced; filled: reproduced, hollow: missed)")
    ax.grid(alpha=0.3, axis="x")
    ax.legend(fontsize=7, loc="lower right")
    s = res["settings"]
    ax.set_title(f"Headline numbers vs the paper (workspace: {s['samples_per_mode_per_seed']} samples per mode, "
                 f"seeds {', '.join(str(x) for x in s['seeds'])})", fontsize=9)
    fig.tight_layout()
    return _save_figure(fig, pathlib.Path(out), "compare")


def _number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and bool(np.isfinite(v))


def plot_convergence(res: dict, out: Union[str, pathlib.Path]) -> list[pathlib.Path]:
    """Tip error [mm] vs the number of elements n on log-log axes (``element_convergence``'s result): the error
    per n (open markers where some state failed: a lower bound), the fitted slope −rate through the n it was
    fitted on, and the paper's two points.  Writes convergence.png and convergence.svg."""
    plt = _pyplot()
    n = np.asarray(res["n"], float)
    e = np.asarray(res["tip_error_m"], float) * 1e3
    ok = np.asarray(res["complete"], bool) & np.isfinite(e) & (e > 0)
    part = ~np.asarray(res["complete"], bool) & np.isfinite(e) & (e > 0)
    fig, ax = plt.subplots(figsize=(5.5, 4.2))
    ax.loglog(n[ok], e[ok], "o", color="C0", label=f"max over the states (reference n = {res['n_ref']})")
    if part.any():
        ax.loglog(n[part], e[part], "o", mfc="none", color="C0", label="some state failed (lower bound)")
    fit_n = np.asarray(res["rate_n"], float)
    if fit_n.size >= 2 and np.isfinite(res["rate"]):
        fit_e = e[np.isin(n, fit_n)]
        c = np.exp(np.mean(np.log(fit_e) + res["rate"] * np.log(fit_n)))     # least-squares intercept at the slope
        xs = np.array([fit_n.min(), fit_n.max()])
        ax.loglog(xs, c * xs ** -res["rate"], "-", color="C1", label=f"fit: slope −{res['rate']:.2f}")
    pp = res["paper"]
    ax.loglog(pp["n"], pp["tip_error_mm"], "k^", label="paper (Sec. V-A)")
    from matplotlib.ticker import FixedLocator, NullFormatter, ScalarFormatter
    ax.xaxis.set_major_locator(FixedLocator(sorted(set(n) | set(pp["n"]))))
    ax.xaxis.set_major_formatter(ScalarFormatter())
    ax.xaxis.set_minor_formatter(NullFormatter())
    ax.set_xlabel("number of elements n")
    ax.set_ylabel("tip error [mm]")
    ax.set_title(f"{res['preset']}: tip error vs n")
    ax.legend(fontsize=8)
    fig.tight_layout()
    return _save_figure(fig, out, "convergence")
