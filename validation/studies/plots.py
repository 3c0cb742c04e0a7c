"""Figures of the paper's studies (no computation): Fig. 4 and Fig. 9 look-alikes and the comparison."""

from __future__ import annotations

import pathlib
from typing import Union

import numpy as np

from ..paper_numbers import WORKSPACE as PAPER_WORKSPACE
from .common import pyplot as _pyplot, save_figure as _save_figure


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


def plot_comparison(res: dict, out: Union[str, pathlib.Path]) -> list[pathlib.Path]:
    """Ours / paper for every numeric headline with a paper value, one marker per preset (log scale);
    the shaded band is where the verdict counts a number as reproduced."""
    plt = _pyplot()
    paper = res["paper"]
    keys = [k for k, v in paper.items() if isinstance(v, (int, float)) and v
            and any(isinstance(p["numbers"].get(k), (int, float)) for p in res["presets"])]
    fig, ax = plt.subplots(figsize=(9, 0.38 * len(keys) + 1.6))
    y = np.arange(len(keys))[::-1]
    markers = "osD^v<>ph"
    for j, p in enumerate(res["presets"]):
        vals = [p["numbers"].get(k) for k in keys]
        r = np.array([v / paper[k] if isinstance(v, (int, float)) and np.isfinite(v) else np.nan
                      for k, v in zip(keys, vals)], float)
        ax.scatter(np.clip(r, 1e-3, 1e3), y + 0.12 * (j - (len(res["presets"]) - 1) / 2), marker=markers[j % 9],
                   label=f"{p['preset']} ({p['reproduced']}/{p['judged']} reproduced)", zorder=3)
    for i, k in enumerate(keys):
        lo, hi = res.get("criteria", {}).get(k, [None, None])
        if lo is not None or hi is not None:
            a = (lo if lo is not None else 1e-3) / paper[k]
            b = (hi if hi is not None else 1e3 * paper[k]) / paper[k]
            ax.fill_betweenx([y[i] - 0.4, y[i] + 0.4], a, b, color="tab:green", alpha=0.12, lw=0)
    ax.axvline(1.0, color="k", lw=0.8)
    ax.set_xscale("log")
    ax.set_xlim(1e-3, 1e3)
    ax.set_yticks(y, [res["labels"][k] for k in keys], fontsize=8)
    ax.set_xlabel("ours / paper  (green: counted as reproduced)")
    ax.grid(alpha=0.3, axis="x")
    ax.legend(fontsize=7, loc="lower right")
    s = res["settings"]
    ax.set_title(f"Headline numbers vs the paper (workspace: {s['samples_per_mode_per_seed']} samples per mode, "
                 f"seeds {', '.join(str(x) for x in s['seeds'])})", fontsize=9)
    fig.tight_layout()
    return _save_figure(fig, pathlib.Path(out), "compare")
