"""``bellows modes | simulate``: the reduced model's dynamics on the command line (docs/dynamics.md).

``modes``: natural frequencies [Hz], damping ratios and mode shapes about an equilibrium (tensions held,
or tendons locked with ``--locked``), a table, ``modes.json`` and a figure of the shapes (``modes.png``).

``simulate``: the step response from the equilibrium of ``--start-tensions-n`` to ``--tensions-n`` (applied
as a step, or a linear ramp over ``--ramp-ms``) at ``--pressure-kpa``, with a progress bar; writes
``simulation.csv`` (one row per step, units in the header), ``simulation.json`` (summary) and
``simulation.png`` (tip motion and energy).  Ctrl-C stops between two steps, writes the rows done, says so and
exits with status 130.

``--pvd`` (both): ParaView time series of the rod (:mod:`ancf.paraview`): ``simulation.pvd`` with its frames in
``simulation/``; ``mode_k.pvd`` per mode, one period of the undamped oscillation in the shape.
"""

from __future__ import annotations

import csv
import json
import pathlib
import warnings
from typing import Optional

import numpy as np
import typer
from rich.markup import escape
from rich.table import Table

from .. import clitools
from ..cli import (FORCE_HELP, NO_LIMITS_HELP, PRESET_HELP, PRESSURE_HELP, _model, console, model_info, parse_vector,
                   warm_up)
from ..errors import InputError
from ..export import write_json
from .damping import UndampedWarning, states_damping, undamped_message
from .transient import MAX_STEPS, rayleigh_about
from ..outputs import prepare_output_dir
from .. import paraview

MODES_FILES = ("modes.png", "modes.json")
SIM_FILES = ("simulation.csv", "simulation.json", "simulation.png")
SIM_PVD = ("simulation.pvd", "simulation")            # --pvd: the collection and its frames folder

# option ranges (clitools.number_range: a given value outside is a usage error, exit status 2)
RATIO = clitools.number_range(0.0, 1.0)                                  # damping ratios, rho_inf
RAMP_MS = clitools.number_range(0.0, unit="ms")
T_END_S = clitools.number_range(0.0, 1e6, low_open=True, unit="s")      # ancf.dynamics.transient's range
DT_MS = clitools.number_range(0.0, low_open=True, unit="ms")


def modes(tensions_n: str = typer.Option("0,0,0", help="Tendon tensions [N] of the equilibrium."),
          pressure_kpa: float = typer.Option(0.0, help=PRESSURE_HELP, callback=clitools.FINITE),
          tip_force_n: str = typer.Option("0,0,0", help="Tip force [N] of the equilibrium (world frame)."),
          locked: bool = typer.Option(False, "--locked", help="Tendons locked at the equilibrium's lengths "
                                      "(motors holding position) instead of tensions held."),
          count: int = typer.Option(6, min=1, help="Number of modes (at most the model's free coordinates)."),
          damping_ratio: Optional[float] = typer.Option(None, callback=RATIO, help="Damping ratio of the first mode "
                                                        f"(stiffness-proportional), {RATIO.text}; default: the "
                                                        "actuator file's damping coefficients."),
          preset: str = typer.Option("paper", help=PRESET_HELP),
          out: Optional[pathlib.Path] = typer.Option(None, help="Folder for modes.png and modes.json."),
          pvd: bool = typer.Option(False, "--pvd", help="Also write each mode animated over one period as a ParaView "
                                   "time series, mode_1.pvd … in the --out folder (tool-point amplitude 12 % of the "
                                   "length; docs/data-formats.md)."),
          force: bool = typer.Option(False, "--force", help=FORCE_HELP),
          no_limits: bool = typer.Option(False, "--no-limits", help=NO_LIMITS_HELP),
          as_json: bool = typer.Option(False, "--json", help="Print JSON instead of a table.")):
    """Vibration modes about an equilibrium: frequencies [Hz], damping ratios and shapes."""
    if pvd and out is None:
        raise InputError("--pvd needs an --out folder to write the mode_k.pvd collections into")
    folder = None if out is None else prepare_output_dir(
        out, MODES_FILES + (tuple(paraview.mode_pvd_names(count)) if pvd else ()), force=force)
    model = _model(preset, None)
    T = parse_vector(tensions_n, model.m, "--tensions-n")
    F = parse_vector(tip_force_n, 3, "--tip-force-n")
    if count > model.nz:
        raise InputError(f"--count must be at most {model.nz} (the model's free coordinates), got {count}")
    warm_up()
    eq = model.fk(T, pressure_kpa * 1e3, F, check_limits=not no_limits)
    if locked:
        eq = model.fk_locked(eq.tendon_lengths, pressure_kpa * 1e3, F, q0=eq.q, tensions0=eq.tensions,
                             check_limits=not no_limits)
    r = model.modes(eq, count, damping=damping_ratio)   # None: the actuator file's coefficients
    rows = mode_rows(r)
    info = model_info(preset, model.params)
    summary = {"preset": model.params.name, "model": info, "tensions_N": T.tolist(), "pressure_kPa": pressure_kpa,
               "tip_force_N": F.tolist(), "tendons": "locked" if locked else "tensions held",
               "damping": r.damping, "damping_source": r.damping_source, "tip_mm": (eq.tip * 1e3).tolist(),
               "modes": rows}
    if r.damping_source == "none":
        summary["damping_warning"] = undamped_message(model.params, "the damping ratios ζ are 0 because no "
                                                      "damping is known, not because the actuator is undamped")
        warn(summary["damping_warning"])
    if folder is not None:
        folder.mkdir(parents=True, exist_ok=True)
        if pvd:
            summary["paraview"] = paraview.write_mode_pvds(folder, model, eq, r)
        write_json(folder / "modes.json", summary)
        save_modes_png(folder / "modes.png", model, eq, r,
                       f"modes of '{model.params.name}' at T = {tensions_n} N, p = {pressure_kpa:g} kPa "
                       f"({summary['tendons']})")
    if as_json:
        typer.echo(json.dumps(summary, indent=2))
        return
    console.print(modes_table(rows, f"modes at T = {tensions_n} N, p = {pressure_kpa:g} kPa — "
                                    f"{summary['tendons']} — {info['description']}"))
    if folder is not None:
        console.print(f"wrote {folder / 'modes.png'} and {folder / 'modes.json'}")
    if pvd:
        console.print(f"wrote mode_1.pvd … mode_{len(rows)}.pvd in {folder}/ (one period each; tool-point "
                      f"amplitude {paraview.MODE_TIP_AMPLITUDE * 100:g} % of the length, smaller where that "
                      "leaves the model's domain: modes.json)")


def mode_rows(r) -> list[dict]:
    """One dict per mode of the ModalResult r: frequency [Hz], damping ratio [-], kind (axial / bending by the
    axial share of its strain energy, ancf.dynamics.modes), that share [-], and the unit vector [-] along which
    the tool point moves (world frame; a direction, not a displacement: shapes have no amplitude)."""
    return [{"mode": k + 1, "frequency_Hz": float(r.frequencies_hz[k]), "damping_ratio": float(r.damping_ratios[k]),
             "kind": r.kinds[k], "axial_energy_share": float(r.axial_share[k]),
             "tip_direction": r.tip_directions[k].tolist()} for k in range(len(r.frequencies_hz))]


def modes_table(rows: list[dict], title: str) -> Table:
    """The printed table of :func:`mode_rows`."""
    t = Table(title=escape(title))
    for c in ("mode", "f [Hz]", "ζ [-]", "kind", "axial share [-]", "tip direction [-]"):
        t.add_column(escape(c), justify="right" if c != "kind" else "left")
    for row in rows:
        t.add_row(str(row["mode"]), f"{row['frequency_Hz']:.3f}", f"{row['damping_ratio']:.4f}", row["kind"],
                  f"{row['axial_energy_share']:.3f}", " ".join(f"{x:+.2f}" for x in row["tip_direction"]))
    return t


def warn(text: str) -> None:
    """A loud ``warning: …`` line on stderr (stdout stays the table or the JSON)."""
    typer.secho(f"warning: {text}", err=True, fg=typer.colors.YELLOW, bold=True)


def _finish(fig, title: str, path) -> pathlib.Path:
    """Title, layout, save at 100 dpi and close a figure."""
    import matplotlib.pyplot as plt
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    path = pathlib.Path(path)
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def save_modes_png(path, model, eq, r, title: str) -> pathlib.Path:
    """One panel per mode: the equilibrium's centreline (grey) and the shape at ± a visible amplitude
    (tip motion 12 % of the length), side (x–z) and top (x–y) views."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    k = len(r.frequencies_hz)
    fig, axes = plt.subplots(2, k, figsize=(2.6 * k + 1, 5.2), squeeze=False)
    c0 = model.centreline(eq.q) * 1e3
    for j in range(k):
        amp = 0.12 * model.params.length / max(np.linalg.norm(r.tip_shapes[j]), 1e-300)
        for row, (a, b, name) in enumerate(((0, 2, "x–z"), (0, 1, "x–y"))):
            ax = axes[row, j]
            ax.plot(c0[:, a], c0[:, b], color="0.6", lw=2)
            for sgn, col in ((1, "C0"), (-1, "C3")):
                try:
                    c = model.centreline(eq.q + sgn * amp * r.shapes[j]) * 1e3
                except InputError:
                    continue
                ax.plot(c[:, a], c[:, b], color=col, lw=1.5)
            ax.set_aspect("equal", adjustable="datalim")
            ax.grid(alpha=0.3)
            ax.set_xlabel("x [mm]", fontsize=8)
            ax.set_ylabel(f"{name[-1]} [mm]", fontsize=8)
            ax.tick_params(labelsize=7)
            if row == 0:
                ax.set_title(f"mode {j + 1}: {r.frequencies_hz[j]:.2f} Hz\n({r.kinds[j]})", fontsize=9)
    return _finish(fig, title, path)


def simulate(tensions_n: str = typer.Option(..., help="Tendon tensions [N] applied at t = 0."),
             start_tensions_n: str = typer.Option("0,0,0", help="Tensions [N] of the start equilibrium."),
             pressure_kpa: float = typer.Option(0.0, help="Chamber pressure [kPa] (constant; within the actuator's "
                                               "limits unless --no-limits).", callback=clitools.FINITE),
             tip_force_n: str = typer.Option("0,0,0", help="Tip force [N] (constant; also in the start state)."),
             ramp_ms: float = typer.Option(0.0, callback=RAMP_MS, help="Ramp the tensions linearly over this time, "
                                           f"{RAMP_MS.text}; 0: a step."),
             t_end_s: float = typer.Option(1.0, callback=T_END_S, help=f"Simulated time, {T_END_S.text}."),
             dt_ms: float = typer.Option(1.0, callback=DT_MS, help=f"Time step (the output interval), {DT_MS.text}; "
                                         "at most --t-end-s and at most 10^7 steps."),
             damping_ratio: Optional[float] = typer.Option(None, callback=RATIO, help="Damping ratio of the first "
                                                           "mode about the final equilibrium (stiffness-proportional), "
                                                           f"{RATIO.text}; default: the actuator file's coefficients."),
             rho_inf: float = typer.Option(0.9, callback=RATIO, help="Integrator's high-frequency spectral radius, "
                                           f"{RATIO.text} (1: none of its numerical dissipation)."),
             preset: str = typer.Option("paper", help=PRESET_HELP),
             out: pathlib.Path = typer.Option(pathlib.Path("bellows_sim"), help="Output folder."),
             pvd: bool = typer.Option(False, "--pvd", help="Also write the rod over time as a ParaView time series: "
                                      "simulation.pvd and its frames in simulation/ (docs/data-formats.md)."),
             pvd_frames: int = typer.Option(100, min=2, max=100_000, help="Most frames of --pvd (spread evenly "
                                            "over the output steps, the first and last included)."),
             force: bool = typer.Option(False, "--force", help=FORCE_HELP),
             no_limits: bool = typer.Option(False, "--no-limits", help=NO_LIMITS_HELP)):
    """Step response in time: from the start equilibrium to new tensions (tip motion, energy)."""
    from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

    if dt_ms * 1e-3 > t_end_s:
        raise InputError(f"--dt-ms must be at most --t-end-s, got {dt_ms:g} ms and {t_end_s:g} s")
    if t_end_s / (dt_ms * 1e-3) > MAX_STEPS:
        raise InputError(f"--t-end-s / --dt-ms is more than {MAX_STEPS:.0e} steps ({t_end_s:g} s in steps of "
                         f"{dt_ms:g} ms): use a larger --dt-ms")
    folder = prepare_output_dir(out, SIM_FILES + (SIM_PVD if pvd else ()), force=force)
    model = _model(preset, None)
    T1 = parse_vector(tensions_n, model.m, "--tensions-n")
    T0 = parse_vector(start_tensions_n, model.m, "--start-tensions-n")
    F = parse_vector(tip_force_n, 3, "--tip-force-n")
    warm_up()
    p = pressure_kpa * 1e3
    start = model.fk(T0, p, F, check_limits=not no_limits)
    friction = {}
    if model.params.tendon_friction > 0:      # at rest on the tendons' friction history, loaded from slack
        fstart = model.fk_history(T0, p, F, check_limits=not no_limits)
        start, friction = fstart.equilibrium, {"segment_tensions": fstart.segment_tensions}
    settled = model.fk(T1, p, F, q0=start.q, check_limits=not no_limits)
    # a ratio is the first mode's about the state the response settles on (not the start, which the step
    # leaves at once)
    damping = None if damping_ratio is None else rayleigh_about(model, settled, damping_ratio)
    undamped = damping is None and not states_damping(model.params)
    undamped_text = undamped_message(model.params, "this run is undamped apart from the integrator's numerical "
                                                   "dissipation (--rho-inf < 1) and will not settle")
    if undamped:                       # said here, before the run, and in simulation.json
        warn(undamped_text)
    ramp = ramp_ms * 1e-3
    tensions = (lambda t: T0 + (T1 - T0) * min(t / ramp, 1.0)) if ramp > 0 else T1
    with Progress(TextColumn("simulating"), BarColumn(), TextColumn("{task.fields[t]:.3f} / {task.total:.3f} s"),
                  TimeRemainingColumn(), console=console, transient=True) as bar:
        task = bar.add_task("sim", total=t_end_s, t=0.0)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UndampedWarning)             # warned above, once
            sim = model.simulate(t_end_s, dt_ms * 1e-3, q0=start.q, tensions=tensions, pressure=p, tip_force=F,
                                 damping=damping, rho_inf=rho_inf, check_limits=not no_limits,
                                 progress=lambda t, te: bar.update(task, completed=t, t=t), **friction)
    folder.mkdir(parents=True, exist_ok=True)
    write_simulation_csv(folder / "simulation.csv", sim)
    if pvd:
        paraview.write_pvd(folder / "simulation.pvd", paraview.simulation_frames(model, sim, pvd_frames))
    # with tendon friction the state a step settles on depends on its path: no static reference to report
    final = settled if model.params.tendon_friction == 0 else None
    info = model_info(preset, model.params)
    summary = {"preset": model.params.name, "model": info, "start_tensions_N": T0.tolist(), "tensions_N": T1.tolist(),
               "ramp_ms": ramp_ms, "pressure_kPa": pressure_kpa, "tip_force_N": F.tolist(),
               "t_end_s": float(sim.t[-1]), "dt_s": sim.dt, "steps": len(sim.t) - 1, "damping": sim.damping,
               "damping_source": sim.damping_source,
               **({"damping_warning": undamped_text} if undamped else {}),
               "rho_inf": sim.rho_inf, "interrupted": sim.interrupted, "wall_time_s": sim.wall_time,
               "real_time_factor": sim.real_time_factor,
               "tip_start_mm": (sim.tip[0] * 1e3).tolist(), "tip_end_mm": (sim.tip[-1] * 1e3).tolist(),
               "static_tip_mm": None if final is None else (final.tip * 1e3).tolist(),
               "overshoot_mm": None if final is None else _overshoot(sim, start.tip, final.tip) * 1e3,
               "energy_drift_J": float(sim.energy[-1] + sim.dissipated[-1] - sim.energy[0]),
               "events": sim.events[:50]}
    write_json(folder / "simulation.json", summary)
    save_simulation_png(folder / "simulation.png", sim, None if final is None else final.tip,
                        f"'{model.params.name}': T {start_tensions_n} → {tensions_n} N at {pressure_kpa:g} kPa")
    state = ("interrupted at" if sim.interrupted else "done:") + (" (UNDAMPED)" if undamped else "")
    console.print(escape(info["description"]))
    console.print(escape(f"{state} {sim.t[-1]:.3f} s simulated in {sim.wall_time:.2f} s "
                         f"({sim.real_time_factor:.1f}× real time, step {sim.dt * 1e3:g} ms)"))
    if final is not None:
        console.print(escape(f"tip {' '.join(f'{x:.2f}' for x in sim.tip[-1] * 1e3)} mm at the end; static "
                             f"equilibrium {' '.join(f'{x:.2f}' for x in final.tip * 1e3)} mm; overshoot "
                             f"{summary['overshoot_mm']:.2f} mm"))
    console.print(f"wrote {folder / 'simulation.csv'}, {folder / 'simulation.json'} and {folder / 'simulation.png'}"
                  + (f"; {folder / 'simulation.pvd'} (frames in {folder / 'simulation'}/)" if pvd else ""))
    if sim.interrupted:                  # Ctrl-C: the rows done are written; the shell's status for it
        typer.secho(f"interrupted at t = {sim.t[-1]:.6g} s: the {len(sim.t)} rows done are in "
                    f"{folder / 'simulation.csv'}", err=True, fg=typer.colors.YELLOW)
        raise typer.Exit(130)


def _overshoot(sim, tip0, tip1) -> float:
    """How far [m] the tip went beyond the final static position, along the start → final direction."""
    d = tip1 - tip0
    n = float(np.linalg.norm(d))
    if n == 0:
        return 0.0
    return max(0.0, float(((sim.tip - tip0) @ (d / n)).max()) - n)


def write_simulation_csv(path, sim) -> pathlib.Path:
    """One row per output time: t [s], tip [mm], tensions [N], pressure [kPa], energies [J]."""
    m = sim.tensions.shape[1]
    header = (["t_s", "tip_x_mm", "tip_y_mm", "tip_z_mm"] + [f"T{i + 1}_N" for i in range(m)]
              + ["pressure_kPa", "kinetic_J", "energy_J", "dissipated_J", "newton_iterations"])
    tmp = pathlib.Path(path).with_suffix(".csv.tmp")
    with open(tmp, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(header)
        for i in range(len(sim.t)):
            w.writerow([f"{sim.t[i]:.6g}", *(f"{x * 1e3:.6f}" for x in sim.tip[i]),
                        *(f"{x:.6g}" for x in sim.tensions[i]), f"{sim.pressure[i] / 1e3:.6g}",
                        f"{sim.kinetic[i]:.6e}", f"{sim.energy[i]:.9e}", f"{sim.dissipated[i]:.6e}",
                        int(sim.newton_iterations[i])])
    tmp.replace(path)
    return pathlib.Path(path)


def save_simulation_png(path, sim, static_tip, title: str) -> pathlib.Path:
    """Tip coordinates [mm] over time (dashed: the static equilibrium of the final loads), and the energy
    balance (kinetic, dissipated, energy + dissipated − its start)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4))
    for c, name in enumerate("xyz"):
        a1.plot(sim.t, sim.tip[:, c] * 1e3 - (0 if c else sim.tip[0, 0] * 1e3), label=f"{name}" + (" − x₀" if c == 0 else ""),
                color=f"C{c}")
        if static_tip is not None:
            a1.axhline(static_tip[c] * 1e3 - (0 if c else sim.tip[0, 0] * 1e3), color=f"C{c}", ls="--", lw=0.8)
    a1.set_xlabel("t [s]"), a1.set_ylabel("tip [mm]"), a1.grid(alpha=0.3), a1.legend(fontsize=8)
    a1.set_title("tip motion (dashed: static equilibrium)", fontsize=9)
    a2.plot(sim.t, sim.kinetic, label="kinetic")
    a2.plot(sim.t, sim.dissipated, label="dissipated")
    a2.plot(sim.t, sim.energy + sim.dissipated - sim.energy[0], label="energy + dissipated − start (the integrator's own loss)")
    a2.set_xlabel("t [s]"), a2.set_ylabel("energy [J]"), a2.grid(alpha=0.3), a2.legend(fontsize=8)
    a2.set_title("energy", fontsize=9)
    return _finish(fig, title, path)


SHORT_HELP = {
    "modes": "Vibration modes about an equilibrium: frequencies, damping, shapes.",
    "simulate": "Step response in time: tip motion and energy.",
}


def register(app: typer.Typer) -> None:
    """Attach ``modes`` and ``simulate`` to the root ``bellows`` app."""
    for fn in (modes, simulate):
        app.command(fn.__name__, short_help=SHORT_HELP[fn.__name__])(fn)
