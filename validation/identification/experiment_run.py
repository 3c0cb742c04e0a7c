r"""Drive a rig through a designed identification experiment (:mod:`validation.identification.experiment`) and
record what it measured in a run log's ``/static_states``.

Per state (SI):

1. **Load.**  When the hung mass changes (and before the first state) ``change_load(mass [kg], force (3,) [N])``
   is called: on hardware a person hangs the mass (``bellows experiment`` asks and waits for Enter; a mass of 0:
   the tip is confirmed free); on a simulated rig the default applies the force to the plant.
2. **Designed lengths.**  The model (the base actuator) gives the tendon lengths l(T_d, p, F) of the designed
   tensions T_d; a tendon designed slack gets ``slack_margin`` more length, so that it stays slack on a plant
   that differs from the model.  Tensions rise with pressure at fixed lengths, so the lengths are sent before a
   rise of pressure and after a fall; a move larger than 90 % of the rig's largest step per command is sent in
   steps.
3. **Corrections.**  The drives hold positions, not tensions: with T_m the measured tensions of the taut
   tendons A, l_A ← l_A + S (T_d − T_m)_A, S = ∂l_A/∂T_A the model's tension–length sensitivity (a forward
   difference of its FK, step ``FD_STEP`` [N]), until max |T_d − T_m| ≤ ``tension_tolerance`` or after
   ``max_corrections``.  A state not reached within the tolerance is recorded anyway (an event says so): the
   record is what was measured.
4. **Samples.**  After ``settle_s``, ``samples`` readings ``sample_period_s`` apart (tensions, pressure — the
   health check —, tip); recorded: their means and standard errors s/√K (``tensions_std``, ``pressure_std``,
   ``tip_position_std``; s pooled over the states measured so far, :class:`NoisePool`), each at least its floor
   (:data:`SE_FLOOR`: a noise-free simulated rig gives 0, which a fit cannot weight), the known tip force (m g; 0
   when no mass hangs) and the state's label.  A tendon designed slack that reads within the tolerance of 0 is
   recorded as 0 N: it carries nothing, and the mean of its sensor's noise clipped at 0 would be a pull that is
   not there.

The log (``static_std=True`` run log) stores the plan and the options in its ``run`` attribute
(``run["experiment"]``).  ``resume=True`` reads an existing log, refuses other options or another plan, copies
what it holds (samples, events, static states) into a fresh log that then replaces it (``os.replace``: at every
moment the path holds one complete log) and runs the states whose labels it does not hold.  Ctrl-C makes the
rig safe (drives holding, pressure held or vented as configured), closes the log as ``interrupted`` with the
states done and raises :class:`hardware.errors.RunAborted`; a fault does the same and re-raises the fault with
``.log_path``.
"""

from __future__ import annotations

import math
import os
import pathlib
import time
from dataclasses import asdict, dataclass, field
from typing import Callable, Optional

import numpy as np

from ancf import ActuatorParams, Model
from ancf.errors import BellowsError, InputError

from validation.identification.experiment import SLACK_MARGIN, ExperimentPlan, ExperimentState

__all__ = ["ExperimentOptions", "ExperimentResult", "run_experiment", "read_plan", "check_resume", "SE_FLOOR",
           "FD_STEP"]

#: smallest recorded standard error of each mean (tensions [N], pressure [Pa], tip [m]): below the resolution
#: of any force sensor, pressure sensor and tracker the product drives
SE_FLOOR = {"tensions_std": 1e-4, "pressure_std": 1.0, "tip_position_std": 1e-6}
#: tension step of the tension–length sensitivity [N]
FD_STEP = 0.05


@dataclass(frozen=True)
class ExperimentOptions:
    """How the states are reached and measured (SI; checked at construction).

    samples : readings per state, an integer in 2 … 10000;  settle_s : wait before the readings [s], 0 … 600;
    sample_period_s : between readings [s], 0 … 60;  tension_tolerance : reached when every taut tendon is
    within this of its designed tension [N], (0, 10];  max_corrections : 0 … 50;  slack_margin : extra length of
    a tendon designed slack [m], 0 … 0.02."""
    samples: int = 5
    settle_s: float = 0.5
    sample_period_s: float = 0.05
    tension_tolerance: float = 0.02
    max_corrections: int = 5
    slack_margin: float = SLACK_MARGIN

    def __post_init__(self):
        for name, lo, hi in (("samples", 2, 10000), ("max_corrections", 0, 50)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or not lo <= v <= hi:
                raise InputError(f"{name} must be an integer in {lo} … {hi}, got {v!r}")
        for name, lo, hi, open_lo in (("settle_s", 0, 600, False), ("sample_period_s", 0, 60, False),
                                      ("tension_tolerance", 0, 10, True), ("slack_margin", 0, 0.02, False)):
            v = getattr(self, name)
            if isinstance(v, (bool, str)) or not (math.isfinite(v) and (v > lo if open_lo else v >= lo) and v <= hi):
                raise InputError(f"{name} must be in {'(' if open_lo else '['}{lo:g}, {hi:g}], got {v!r}")


@dataclass
class ExperimentResult:
    """Outcome of :func:`run_experiment`: ``status`` completed | interrupted | fault, the states recorded in the
    log (``done``, of ``total``; ``recorded``: by this call), the log path, wall time [s], per state recorded
    by this call {label, corrections, reached, designed/measured tensions [N]}."""
    status: str
    done: int
    total: int
    recorded: int
    log_path: pathlib.Path
    wall_s: float = 0.0
    states: list = field(default_factory=list)


def read_plan(path) -> tuple:
    """(plan dict, options dict, labels of the states recorded) of an experiment log; :class:`InputError` when
    ``path`` is no experiment log."""
    from hardware.runlog import read_run_log
    from ancf.errors import ConfigError
    data = read_run_log(path)
    exp = data.attrs.get("run", {}).get("experiment")
    if not isinstance(exp, dict) or "plan" not in exp or "options" not in exp:
        raise InputError(f"{path} is not an identification-experiment log (no run['experiment'] plan)")
    try:
        labels = list(data.static_states().label or [])
    except (ConfigError, InputError):
        labels = []
    return exp["plan"], exp["options"], labels


def _differences(stored: dict, now: dict, names: Optional[dict] = None) -> list:
    """'samples: 3 in the log, 5 now' for every entry that differs (``names``: how to call each key, e.g. its
    command-line option)."""
    names = names or {}
    return [f"{names.get(k, k)}: {stored.get(k)!r} in the log, {now.get(k)!r} now"
            for k in sorted(set(stored) | set(now)) if stored.get(k) != now.get(k)]


def check_resume(path, info: dict, names: Optional[dict] = None) -> tuple:
    """Whether the experiment log at ``path`` can be resumed with the options ``info`` (the ``run_info`` of
    :func:`run_experiment` merged with its options, as stored in the log): (stored plan dict, labels recorded);
    :class:`InputError` naming every option that differs, with the value stored in the log (``names``: the
    option's name to show for each key).  Needs no design: ``bellows experiment --resume`` calls it before any
    design or rig work."""
    path = pathlib.Path(path)
    if not path.is_file():
        raise InputError(f"--resume: no experiment log {path}")
    old_plan, old_opts, labels = read_plan(path)
    diff = _differences(old_opts, info, names)
    if diff:
        raise InputError(f"--resume: {path} was started with other options ({'; '.join(diff)}); resume with the "
                         "same options, or start again with --force")
    return old_plan, labels


# ------------------------------------------------------------------------------------------------ the log
def _open_log(path, rig, params: ActuatorParams, plan: ExperimentPlan, info: dict, *, force: bool, resume: bool):
    """(the open run log, labels already recorded).  ``resume``: copy the old log into a new one that replaces it."""
    from hardware.runlog import RunLog
    path = pathlib.Path(path)
    run = {"experiment": {"plan": plan.to_dict(), "options": info}}
    kw = dict(n_tendons=rig.m, rig=rig.describe(), controller={"name": "identification experiment"}, run=run,
              actuator_toml=params.to_toml(), static_std=True, flush_rows=10)
    if not resume:
        return RunLog(path, force=force, **kw), set()
    if force:
        raise InputError("give --resume (continue the log) or --force (start it again), not both")
    old_plan, labels = check_resume(path, info)
    if old_plan != plan.to_dict():
        raise InputError(f"--resume: {path} was started with other options (the designed states differ); resume "
                         "with the same options, or start again with --force")
    tmp = path.with_name(f".{path.name}.resume.h5")
    log = RunLog(tmp, force=True, **kw)
    try:
        _copy_log(path, log)
        os.replace(tmp, path)
    except BaseException:
        log.close("aborted", "resume failed")
        tmp.unlink(missing_ok=True)
        raise
    log.path = path
    return log, set(labels)


def _copy_log(path, log) -> None:
    """The samples, events and static states of the log at ``path`` into the open ``log``."""
    from hardware.runlog import read_run_log
    from hardware.static_states import read_static_states
    data = read_run_log(path)
    names = [k for k in data.samples if k in log.fields]
    for i in range(data.rows):
        log.sample(**{k: data.samples[k][i] for k in names})
    for t, kind, msg in data.events:
        if kind != "end":
            log.event(t, kind if kind not in ("fault", "limit", "error") else f"earlier {kind}", msg)
    try:
        st = read_static_states(path)
    except BellowsError:
        return
    for i in range(st.n_states):
        std = {"tensions_std": st.tensions_std[i], "pressure_std": st.pressure_std[i],
               "tip_position_std": st.tip_position_std[i]}
        log.static_state(time=st.time[i], tensions=st.tensions[i], pressure=st.pressure[i], tip=st.tip_position[i],
                         tip_force=st.tip_force[i], label=st.label[i], std=std)
    log.event(float(st.time[-1]) if st.n_states else 0.0, "resumed", f"resumed with {st.n_states} states done")
    log.flush()


# ------------------------------------------------------------------------------------------------ moves
def _move(rig, target: np.ndarray, expected=None) -> None:
    """Send ``target`` (m,) [m] in steps of at most 90 % of the rig's largest step; wait until reached."""
    cur = np.asarray(rig.commanded if rig.commanded is not None else rig.positions(), float)
    if not np.all(np.isfinite(cur)):                 # nothing commanded yet (a simulated rig): rig the tendons
        rig.command(target, expected_tensions=expected)
        rig.advance(None)
        return
    n = max(1, int(math.ceil(float(np.max(np.abs(target - cur))) / (0.9 * rig.limits.max_step))))
    for i in range(1, n + 1):
        rig.command(cur + (target - cur) * i / n, expected_tensions=expected if i == n else None)
        rig.advance(None)


def _designed(model: Model, st: ExperimentState, margin: float) -> tuple:
    """(lengths (m,) [m] to command, the equilibrium, taut tendons (bool m,), S = ∂l_A/∂T_A)."""
    T = np.asarray(st.tensions, float)
    eq = model.fk(T, st.pressure, st.tip_force)      # from the straight reference, as the design's solve
    taut = T > 0
    lengths = np.asarray(eq.tendon_lengths, float) + np.where(taut, 0.0, margin)
    idx = np.flatnonzero(taut)
    S = np.zeros((idx.size, idx.size))
    for c, j in enumerate(idx):
        dT = np.zeros_like(T)
        dT[j] = FD_STEP if T[j] + FD_STEP <= model.params.tension_max else -FD_STEP
        e2 = model.fk(T + dT, st.pressure, st.tip_force, q0=eq.q)
        S[:, c] = (np.asarray(e2.tendon_lengths)[idx] - np.asarray(eq.tendon_lengths)[idx]) / dT[j]
    return lengths, eq, taut, S


def _slack_within_travel(rig, lengths: np.ndarray, taut: np.ndarray) -> np.ndarray:
    """A slack tendon's length [m] at most the rig's travel (its margin is what keeps it slack, not a target: a
    path longer than the travel leaves it taut, and the state is recorded as measured)."""
    return np.where(taut, lengths, np.minimum(lengths, rig.limits.length_max))


def _reach(rig, model: Model, st: ExperimentState, o: "ExperimentOptions") -> tuple:
    """Move to the designed state and correct on the measured tensions.  Returns (the model's equilibrium,
    corrections made, reached within the tolerance, last measured tensions (m,) [N])."""
    lengths, eq, taut, S = _designed(model, st, o.slack_margin)
    T_d = np.asarray(st.tensions, float)
    lengths = _slack_within_travel(rig, lengths, taut)
    if st.pressure > rig.read_pressure():          # tensions rise with pressure: lengths first
        _move(rig, lengths, T_d)
        rig.set_pressure(st.pressure)
    else:
        rig.set_pressure(st.pressure)
        _move(rig, lengths, T_d)
    rig.advance(o.settle_s)
    k = 0
    while True:
        T_m = np.asarray(rig.check_health()["tensions"], float)
        err = T_d - T_m
        slack_pulled = ~taut & (T_m > o.tension_tolerance)
        ok = np.all(np.abs(err[taut]) <= o.tension_tolerance) and not slack_pulled.any()
        if ok or k >= o.max_corrections:
            return eq, k, bool(ok), T_m
        lengths = lengths.copy()
        lengths[taut] += S @ err[taut]
        lengths[slack_pulled] += o.slack_margin
        lengths = _slack_within_travel(rig, lengths, taut)
        _move(rig, lengths, T_d)
        rig.advance(o.settle_s)
        k += 1


def _measure(rig, st: ExperimentState, o: "ExperimentOptions", runlog, index: int) -> dict:
    """``samples`` readings (each one a row of the log's samples); their means and standard errors."""
    T, P, X = [], [], []
    for k in range(o.samples):
        if k:
            rig.advance(o.sample_period_s)
        r = rig.check_health()
        tip = rig.measure()
        T.append(r["tensions"]), P.append(r["pressure"]), X.append(tip)
        runlog.sample(t=rig.clock.now(), iteration=index, tip=tip, tension=r["tensions"], pressure=r["pressure"],
                      position=r["positions"], command=rig.commanded)
    T, P, X = np.array(T), np.array(P), np.array(X)
    mean_T = np.maximum(T.mean(axis=0), 0.0)
    # a tendon designed slack and left slack (the reach step checked it reads within the tolerance of 0) carries
    # nothing: its sensor reads noise about 0, whose mean clipped at 0 would record a small pull that is not there
    # (measured: EI biased by −0.13 %, its interval holding the truth in 58–80 % of seeds; recorded as 0: 92 %)
    slack = (np.asarray(st.tensions, float) <= 0.0) & (mean_T <= o.tension_tolerance)
    mean_T[slack] = 0.0
    var = {"tensions_std": T.var(axis=0, ddof=1), "pressure_std": P.var(ddof=1), "tip_position_std": X.var(axis=0, ddof=1)}
    return {"tensions": mean_T, "pressure": float(P.mean()), "tip": X.mean(axis=0), "var": var,
            "samples": o.samples}


class NoisePool:
    """Each instrument channel's noise, pooled over the states measured so far.

    A standard deviation from K = 3…5 readings of one state is itself uncertain by 1/√(2(K−1)) ≈ 35–70 %; as a
    weight it would give a few states most of the fit and intervals too narrow (measured: 3 seeds of the
    simulated mismatched rig, the 95 % intervals of EI and D_eff held the truth in 1 of 3, with widths half the
    pooled ones').  The sensors' noise is one number per channel, so the state's standard error is
    s_pooled/√K with s_pooled² = Σ_states s²_state / n_states (equal K: the pooled variance), over every state
    recorded so far (the first state: its own readings), never below :data:`SE_FLOOR`."""

    def __init__(self):
        self.sums: dict = {}
        self.count = 0

    def add(self, var: dict) -> None:
        for k, v in var.items():
            self.sums[k] = self.sums.get(k, 0.0) + np.asarray(v, float)
        self.count += 1

    def standard_errors(self, samples: int) -> dict:
        return {k: np.maximum(np.sqrt(v / self.count / samples), SE_FLOOR[k]) for k, v in self.sums.items()}


# ------------------------------------------------------------------------------------------------ the run
def _default_change_load(rig) -> Optional[Callable]:
    if getattr(rig, "simulated", False):
        return lambda mass, force: rig.set_load(np.asarray(force, float))
    return None


def run_experiment(plan: ExperimentPlan, rig, params: ActuatorParams, log, *,
                   options: Optional[ExperimentOptions] = None, force: bool = False, resume: bool = False,
                   change_load: Optional[Callable[[float, np.ndarray], None]] = None,
                   progress: Optional[Callable[[dict], None]] = None, run_info: Optional[dict] = None) -> ExperimentResult:
    """Run ``plan`` on ``rig`` (simulated or real, opened) with the model ``params`` (the base actuator), writing
    the run log ``log`` (module docstring).  ``run_info``: JSON-friendly entries that must match on ``resume``
    (with the options).  ``change_load(mass [kg], force (3,) [N])``: required on hardware (a person hangs the
    mass); ``progress(dict)`` after each state recorded.  Returns an :class:`ExperimentResult`; Ctrl-C raises
    :class:`hardware.errors.RunAborted` (``.log_path``, ``.result``) after the rig is made safe."""
    from hardware.errors import DriveFault, RunAborted
    o = options or ExperimentOptions()
    if not isinstance(o, ExperimentOptions):
        raise InputError(f"options must be ExperimentOptions, got {type(o).__name__}")
    if not isinstance(params, ActuatorParams) or params.n_tendons != rig.m or \
            any(len(s.tensions) != rig.m for s in plan.states):
        raise InputError(f"the plan, the actuator and the rig must have the same tendons ({rig.m} on the rig)")
    change_load = change_load or _default_change_load(rig)
    if change_load is None:
        raise InputError("a hardware rig needs change_load(mass, force): a person hangs (or removes) the masses")
    info = {**asdict(o), **(run_info or {})}
    runlog, done = _open_log(log, rig, params, plan, info, force=force, resume=resume)
    res = ExperimentResult("running", len(done), len(plan.states), 0, pathlib.Path(log))
    t0, model, mass, pool = time.monotonic(), Model(params), None, NoisePool()
    try:
        for i, st in enumerate(plan.states):
            if st.label in done:
                continue
            if st.mass != mass:
                change_load(st.mass, np.asarray(st.tip_force, float))
                mass = st.mass
                runlog.event(rig.clock.now(), "load", f"{st.mass * 1e3:g} g at the tip")
            _one_state(rig, model, st, o, runlog, i, res, progress, pool)
        res.status = "completed"
    except KeyboardInterrupt:
        rig.safe_stop("experiment interrupted (Ctrl-C)")
        res.status = "interrupted"
        _close(runlog, res, t0, "interrupted", "Ctrl-C", rig)
        exc = RunAborted(f"experiment interrupted by Ctrl-C after {res.done} of {res.total} states; rig made safe; "
                         f"log: {res.log_path} (continue with --resume)")
        exc.log_path, exc.result = res.log_path, res
        raise exc from None
    except BaseException as exc:
        rig.safe_stop(f"experiment stopped: {type(exc).__name__}: {exc}", quick=isinstance(exc, DriveFault))
        res.status = "fault"
        _close(runlog, res, t0, "fault", f"{type(exc).__name__}: {exc}", rig)
        if isinstance(exc, BellowsError):
            exc.log_path, exc.result = res.log_path, res
        raise
    rig.safe_stop("experiment completed", quiet=True)
    _close(runlog, res, t0, "completed", f"{res.done} of {res.total} states", rig)
    return res


def _one_state(rig, model, st, o, runlog, i, res, progress, pool: NoisePool) -> None:
    """Reach, measure and record one state (a row of ``/static_states``, its standard errors from ``pool``;
    ``progress`` told)."""
    eq, k, ok, _ = _reach(rig, model, st, o)
    m = _measure(rig, st, o, runlog, i)
    pool.add(m["var"])
    runlog.static_state(time=rig.clock.now(), tensions=m["tensions"], pressure=m["pressure"], tip=m["tip"],
                        tip_force=np.asarray(st.tip_force, float), label=st.label,
                        std=pool.standard_errors(m["samples"]))
    if not ok:
        runlog.event(rig.clock.now(), "warning", f"{st.label}: tensions {np.round(m['tensions'], 3).tolist()} N "
                                                 f"not within {o.tension_tolerance:g} N of the design after {k} "
                                                 "corrections (recorded as measured)")
    runlog.flush()
    res.done += 1
    res.recorded += 1
    rec = {"label": st.label, "index": i, "done": res.done, "total": res.total, "corrections": k, "reached": ok,
           "designed_N": list(st.tensions), "measured_N": m["tensions"].tolist(), "pressure_Pa": m["pressure"],
           "mass_kg": st.mass, "tip_m": m["tip"].tolist()}
    res.states.append(rec)
    if progress is not None:
        progress(rec)


def _close(runlog, res: ExperimentResult, t0: float, status: str, reason: str, rig) -> None:
    """Close the log with the run's status (the caller closes the rig)."""
    res.wall_s = time.monotonic() - t0
    runlog.close(status, reason, t=rig.clock.now())
