"""The paper's studies: one module per study, one namespace for all, the paper's numbers, the documentation tables.

``workspace`` (Sec. IV-A), ``stiffness_vs_tension`` (Sec. V-C), ``convergence`` (element number),
``loads`` (locked drift, holding a payload, IK time) and ``compare`` (every headline number for several
presets) are re-exported here; ``table1``, ``compliance_ablation`` and ``loading`` forward to
:mod:`validation.paper.control`, imported lazily (:class:`StudyUnavailableError` when it is missing).
:func:`run_all` runs every study on one preset into one folder.  The studies run on any actuator preset.

========================  ===========================================================================
module                    study
========================  ===========================================================================
``workspace_volume``      Sec. IV-A, Fig. 4: TD vs TPHD workspace volume (Monte Carlo, convex hulls)
``stiffness``             Sec. V-C, Fig. 9: tip stiffness vs T1, locked vs constant tension
``convergence``           Sec. V-A: tip error vs the number of elements n
``loads``                 Sec. V-D/E: locked drift under a payload, holding a payload, IK time
``comparison``            every headline number for several presets beside the paper's
``criteria``              the one "reproduces the paper" criterion of the comparison's table and figure
``hulls``                 convex-hull volume and distance helpers
``states``                state diagnostics: stretch range, collapse of a stiffness law
``plots``/``tables``      figures and printed tables (no computation)
``control``               Table I, the compliance ablation and the cyclic loading with the controllers (Sec. V-D/E)
``dynamic``               the cyclic loading on the dynamic plant (docs/dynamics.md)
``segments``              one segment against two of the same length: workspace, directions, stiffness, obstacle
``numbers``               the paper's own numbers, the one place they are written
``doc_tables``            the number tables of README.md and docs/paper-readings.md, generated from the studies' JSON
========================  ===========================================================================

Every study returns a plain ``dict`` (SI units, the unit in each key name).  The paper's numbers live in
:mod:`validation.paper.numbers` only.
"""

from __future__ import annotations

import inspect
import pathlib
from typing import Any, Callable, Optional, Union

from ancf.errors import BellowsError
from ancf.export import write_json

from validation.paper.numbers import PAPER
from validation.paper.common import G, resolve_params  # noqa: F401
from validation.paper.convergence import element_convergence
from validation.paper.hulls import hull_distance, hull_volume
from validation.paper.loads import hold_payload, ik_time, locked_drift
from validation.paper.plots import plot_stiffness, plot_workspace
from validation.paper.stiffness import stiffness_vs_tension
from validation.paper.tables import print_control_study, print_stiffness, print_workspace
from validation.paper.workspace_volume import MODES, read_samples, workspace, workspace_inputs

__all__ = ["PAPER", "G", "MODES", "StudyUnavailableError", "workspace", "workspace_inputs", "read_samples",
           "hull_volume", "hull_distance", "stiffness_vs_tension", "element_convergence", "locked_drift",
           "hold_payload", "ik_time", "table1", "compliance_ablation", "loading", "run_all",
           "plot_workspace", "plot_stiffness", "print_workspace", "print_stiffness", "print_control_study",
           "CONTROL_STUDIES", "CONTROL_FILES", "study_files", "write_json"]


class StudyUnavailableError(BellowsError, ImportError):
    """A study's implementation module is not installed."""


def _control_studies():
    import importlib
    import importlib.util

    name = "validation.paper.control"
    if importlib.util.find_spec(name) is None:
        raise StudyUnavailableError(
            "the controller studies (Table I, compliance ablation, continuous/cyclic loading) live in "
            "validation/paper/control.py, which is not available in this installation")
    return importlib.import_module(name)  # errors inside that module propagate unchanged


def _call_study(name: str, kw: dict) -> dict:
    """Call ``validation.paper.control.<name>(**kw)``; ``out`` and ``params`` are passed only if that function
    takes them, every other keyword unchanged (a typo fails loudly there)."""
    fn: Callable = getattr(_control_studies(), name, None)
    if fn is None:
        raise StudyUnavailableError(f"validation.paper.control has no function {name}()")
    try:
        sig = inspect.signature(fn).parameters
        if not any(p.kind is p.VAR_KEYWORD for p in sig.values()):
            for opt in ("out", "params"):
                if opt in kw and opt not in sig:
                    if opt == "params" and kw[opt] is not None:
                        raise StudyUnavailableError(f"validation.paper.control.{name}() does not take a preset")
                    kw = {k: v for k, v in kw.items() if k != opt}
    except (TypeError, ValueError):
        pass
    return fn(**kw)


def table1(**kw) -> dict:
    """Table I (Sec. IV-B): VF-CC vs LACC residual errors after five iterations."""
    return _call_study("table1", kw)


def compliance_ablation(**kw) -> dict:
    """FK- vs IK-derived compliance in the LACC loop (paper: IK-derived converges ≈ 50 % faster)."""
    return _call_study("compliance_ablation", kw)


def loading(**kw) -> dict:
    """Continuous (0 → 110 g → 0 over 50 s) and cyclic (0.125 Hz) loading (Sec. V-E)."""
    return _call_study("loading", kw)


def trajectory_tracking(**kw) -> dict:
    """Open-loop IK trajectory tracking (Sec. V-B): 30 mm circle, 50 mm rose curve, "SJTU"; RMSE."""
    return _call_study("trajectory_tracking", kw)


def feedforward_loading(**kw) -> dict:
    """Open-loop tracking under tip loads (Fig. 8 protocol: 15 g + 25 + 25 + 50 g)."""
    return _call_study("feedforward_loading", kw)


CONTROL_STUDIES = {"table1": table1, "ablation": compliance_ablation, "loading": loading}
#: Rig-protocol studies run on their own command (not by ``run_all``: minutes each).
RIG_STUDIES = {"tracking": trajectory_tracking, "feedforward": feedforward_loading}
RIG_FILES = {"tracking": "trajectories.json", "feedforward": "feedforward_loading.json"}
#: JSON file of each controller study in the output folder (the names validation.paper.control itself writes).
CONTROL_FILES = {"table1": "table1.json", "ablation": "compliance_ablation.json", "loading": "loading.json"}


def study_files(name: str) -> tuple:
    """Every file the controller or rig-protocol study ``name`` writes into its output folder: its JSON and the
    figure of the same stem (``validation.paper.control`` writes ``<stem>.json`` and ``<stem>.png``).  Checked before
    the study runs, so that an existing result is not replaced without ``--force``."""
    json_name = {**CONTROL_FILES, **RIG_FILES}[name]
    return json_name, json_name[:-len(".json")] + ".png"


def run_all(out: Union[str, pathlib.Path] = "bellows_out/paper", *, samples: int = 10_000, seed: int = 0,
            workers: Optional[int] = None, scheduler=None, progress: bool = True, console=None,
            params=None, force: bool = False) -> dict:
    """Run every study on one preset into ``out``; unavailable controller studies are reported as skipped.
    Returns ``{study: result or {"skipped": reason}}`` and writes ``summary.json``."""
    from ancf.outputs import prepare_output_dir
    from rich.markup import escape

    from validation.paper import stiffness as _st, workspace_volume as _ws

    prm = resolve_params(params)
    files = list(_ws.FILES) + list(_st.FILES) + [f for n in CONTROL_FILES for f in study_files(n)] + ["summary.json"]
    out = prepare_output_dir(out, files, force=force)
    results: dict[str, Any] = {}
    ws = workspace(samples=samples, seed=seed, workers=workers, scheduler=scheduler, out=out, progress=progress,
                   params=prm, force=True)
    results["workspace"] = {k: v for k, v in ws.items() if k != "clouds"}
    if console is not None:
        print_workspace(ws, console)
    st = stiffness_vs_tension(out=out, params=prm, force=True)
    results["stiffness"] = st
    if console is not None:
        print_stiffness(st, console)
    for name, fn in CONTROL_STUDIES.items():
        try:
            r = fn(out=out, params=prm)
            results[name] = r
            write_json(out / CONTROL_FILES[name], r)
            if console is not None:
                print_control_study(name, r, console)
        except StudyUnavailableError as exc:
            results[name] = {"skipped": str(exc)}
            if console is not None:
                console.print(f"[yellow]{name}: skipped — {escape(str(exc))}[/yellow]")
    summary = {
        "preset": prm.name,
        "workspace": {k: results["workspace"][k] for k in ("volume_td_m3", "volume_tphd_m3", "ratio",
                                                            "increase_percent", "sampling_error", "failures",
                                                            "collapsed", "samples")},
        "stiffness": st["summary"],
        **{n: ("skipped" if isinstance(results[n], dict) and "skipped" in results[n] else "done")
           for n in CONTROL_STUDIES},
    }
    write_json(out / "summary.json", summary)
    results["summary"] = summary
    return results
