"""Saving equilibria: VTU (centreline and tendon polylines with the mechanics for ParaView, via meshio:
:mod:`ancf.paraview`), PNG (matplotlib), JSON."""

from __future__ import annotations

import json
import math
import pathlib
from typing import Any, Sequence

import numpy as np


def equilibrium_polylines(model, eq, per_element: int = 10):
    """Centreline (k, 3) and tendon paths (m, k, 3) [m] of an equilibrium."""
    return model.centreline(eq.q, per_element), model.tendon_paths(eq.q, per_element)


def save_vtu(path, model, eq, per_element: int = 10) -> pathlib.Path:
    """Write the centreline and tendons of ``eq`` as VTK polylines for ParaView (cell data ``curve``: 0 =
    centreline, i = tendon i; point data ``radius_m``, ``stretch``, ``curvature_per_m``,
    ``bending_stiffness_Nm2``, ``bending_moment_Nm``, ``axial_force_N``, ``tension_N``,
    ``undeformed_arc_length_m``: :mod:`ancf.paraview`)."""
    from .paraview import save_rod_vtu
    return save_rod_vtu(path, model, eq.q, eq.tensions, eq.pressure, per_element)


def save_png(path, model, cases: Sequence[tuple[str, object]], title: str = "") -> pathlib.Path:
    """3-D picture (plus side and top views) of several labelled equilibria: centreline thick, tendons thin."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(13, 4.6))
    ax3 = fig.add_subplot(1, 3, 1, projection="3d")
    axs = fig.add_subplot(1, 3, 2)
    axt = fig.add_subplot(1, 3, 3)
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for k, (label, eq) in enumerate(cases):
        c, tendons = equilibrium_polylines(model, eq)
        col = colors[k % len(colors)]
        ax3.plot(*(c * 1e3).T, color=col, lw=2.5, label=label)
        axs.plot(c[:, 0] * 1e3, c[:, 2] * 1e3, color=col, lw=2.5, label=label)
        axt.plot(c[:, 0] * 1e3, c[:, 1] * 1e3, color=col, lw=2.5, label=label)
        for t in tendons:
            ax3.plot(*(t * 1e3).T, color=col, lw=0.8, alpha=0.7)
            axs.plot(t[:, 0] * 1e3, t[:, 2] * 1e3, color=col, lw=0.8, alpha=0.6)
            axt.plot(t[:, 0] * 1e3, t[:, 1] * 1e3, color=col, lw=0.8, alpha=0.6)
        ax3.scatter(*(eq.tip * 1e3), color=col, s=15)
    ax3.set_xlabel("x [mm]"), ax3.set_ylabel("y [mm]"), ax3.set_zlabel("z [mm]")
    axs.set_xlabel("x [mm]"), axs.set_ylabel("z [mm]"), axs.set_title("side view (x–z)")
    axt.set_xlabel("x [mm]"), axt.set_ylabel("y [mm]"), axt.set_title("top view (x–y)")
    for a in (axs, axt):
        a.set_aspect("equal", adjustable="datalim")
        a.grid(alpha=0.3)
    fig.suptitle(title)
    fig.tight_layout(rect=(0, 0.12, 1, 1))
    handles, labels = axs.get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=2, fontsize=8, frameon=False)
    path = pathlib.Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def equilibrium_summary(eq, seconds: float | None = None) -> dict:
    """Flat JSON-friendly summary with units in the key names."""
    out = {
        "tip_m": eq.tip.tolist(),
        "tensions_N": eq.tensions.tolist(),
        "pressure_Pa": eq.pressure,
        "tip_force_N": eq.tip_force.tolist(),
        "tendon_lengths_m": eq.tendon_lengths.tolist(),
        "iterations": eq.iterations,
        "residual_norm": eq.residual_norm,
        "solver": eq.solver,
        "converged": eq.converged,
    }
    if eq.slack is not None:
        out["slack_m"] = eq.slack.tolist()
        out["active"] = list(eq.active)
    if seconds is not None:
        out["solve_time_s"] = seconds
    return out


def to_jsonable(x: Any) -> Any:
    """Nested dict/list/array → JSON types (arrays to lists, NaN/inf to None, paths to strings)."""
    if isinstance(x, dict):
        return {str(k): to_jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [to_jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return to_jsonable(x.tolist())
    if isinstance(x, (np.floating, float)):
        v = float(x)
        return v if math.isfinite(v) else None
    if isinstance(x, np.integer):
        return int(x)
    if isinstance(x, np.bool_):
        return bool(x)
    if isinstance(x, pathlib.Path):
        return str(x)
    return x


def write_json(path, data) -> pathlib.Path:
    """Write ``data`` (converted by :func:`to_jsonable`) as indented JSON, creating the folder."""
    path = pathlib.Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(to_jsonable(data), indent=2))
    return path
