"""Figures of the identification/validation report (matplotlib, Agg; each returns PNG bytes).

Every function takes plain result objects (:class:`validation.identification.identify.IdentificationResult`,
:class:`validation.checks.compare.ValidationResult`, the dict of :func:`validation.checks.compare.stiffness_vs_tension`)
and returns the PNG of one figure; :mod:`validation.report.build` embeds them (base64) and also writes them
next to the report.  Lengths are shown in mm, stiffnesses in N/mm, compliances in mm/N.
"""

from __future__ import annotations

import io

import numpy as np

__all__ = ["forms_figure", "correlation_figure", "residuals_figure", "shapes_figure", "ellipses_figure",
           "stiffness_figure"]

FEM_STYLE = {"color": "0.15", "lw": 2.0, "label": "FEM"}
ANCF_STYLE = {"color": "tab:red", "lw": 1.4, "ls": "--", "label": "reduced model"}


def _plt():
    import matplotlib
    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt
    return plt


def _png(fig) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110, bbox_inches="tight")
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


def residuals_figure(train_labels, train_err, heldout_labels=None, heldout_err=None) -> bytes:
    """Tip error per state [mm]: training residuals and held-out prediction errors."""
    plt = _plt()
    n_ax = 2 if heldout_err is not None and len(heldout_err) else 1
    fig, axes = plt.subplots(1, n_ax, figsize=(4.2 * n_ax + 1.5, 3.4), squeeze=False)
    for ax, labels, err, title, col in ((axes[0, 0], train_labels, train_err, "training residual", "0.5"),
                                        (axes[0, -1], heldout_labels, heldout_err, "held-out error", "tab:blue")):
        if err is None or (n_ax == 1 and title.startswith("held")):
            continue
        err = 1e3 * np.asarray(err, float)
        ax.barh(np.arange(err.size), err, color=col)
        ax.set_yticks(np.arange(err.size), [str(lb) for lb in labels], fontsize=6)
        ax.invert_yaxis()
        ax.set_xlabel("tip error [mm]")
        ax.set_title(title)
        ax.grid(axis="x", alpha=0.3)
    fig.tight_layout()
    return _png(fig)


def shapes_figure(rows: list, max_states: int = 8) -> bytes:
    """Centrelines of the held-out states, FEM vs the reduced (ANCF) model, projected on the x–z and x–y planes [mm]."""
    plt = _plt()
    rows = rows[:max_states]
    n = len(rows)
    fig, axes = plt.subplots(2, n, figsize=(2.1 * n + 0.6, 5.2), squeeze=False, sharex=True)
    for j, r in enumerate(rows):
        cf, ca = 1e3 * np.asarray(r["centreline_fem_m"]), 1e3 * np.asarray(r["centreline_ancf_m"])
        for i, (c, lab) in enumerate(((2, "z"), (1, "y"))):
            ax = axes[i, j]
            ax.plot(cf[:, 0], cf[:, c], **FEM_STYLE)
            ax.plot(ca[:, 0], ca[:, c], **ANCF_STYLE)
            ax.set_aspect("equal", adjustable="datalim")
            ax.grid(alpha=0.3)
            if j == 0:
                ax.set_ylabel(f"{lab} [mm]")
            if i == 1:
                ax.set_xlabel("x [mm]")
        axes[0, j].set_title(f"{r['label']}\n{r['shape_error_pct']:.2f} % L", fontsize=7)
    axes[0, 0].legend(frameon=False, fontsize=7)
    fig.tight_layout()
    return _png(fig)


def _ellipse(C, i, j, n=120):
    """Tip displacement [mm] under a unit force [N] rotating in the (i, j) plane: the compliance ellipse."""
    a = np.linspace(0, 2 * np.pi, n)
    f = np.zeros((3, n))
    f[i], f[j] = np.cos(a), np.sin(a)
    u = 1e3 * (np.asarray(C, float) @ f)
    return u[i], u[j]


def ellipses_figure(rows: list, max_states: int = 4) -> bytes:
    """Compliance ellipses (tip displacement under a unit force turning in a plane) of the held-out states,
    FEM vs ANCF, with tensions held (top) and tendons locked (bottom), x–z plane [mm/N]."""
    plt = _plt()
    rows = [r for r in rows if "C_tension_fem" in r][:max_states]
    if not rows:
        return b""
    n = len(rows)
    fig, axes = plt.subplots(2, n, figsize=(2.4 * n + 0.6, 5.0), squeeze=False)
    for j, r in enumerate(rows):
        for i, mode in enumerate(("tension", "locked")):
            ax = axes[i, j]
            for who, st in (("fem", FEM_STYLE), ("ancf", ANCF_STYLE)):
                x, z = _ellipse(r[f"C_{mode}_{who}"], 0, 2)
                ax.plot(x, z, **st)
            ax.set_aspect("equal", adjustable="datalim")
            ax.grid(alpha=0.3)
            ax.set_title(f"{r['label']} ({mode})\nerr {r[f'C_{mode}_error_pct']:.1f} %", fontsize=7)
            ax.set_xlabel("u_x [mm/N]", fontsize=7)
            if j == 0:
                ax.set_ylabel("u_z [mm/N]", fontsize=7)
    axes[0, 0].legend(frameon=False, fontsize=7)
    fig.tight_layout()
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
