"""FEM virtual experiments as a sweep: each load case solved independently, in parallel, cached on disk.

:func:`run_cases` hands the load cases of a :class:`validation.reference.experiments.Design` to
:func:`validation.infra.runner.run_tasks` — local processes by default, a dask cluster with ``scheduler`` — with
a progress bar.  Each case is cached (with ``cache_dir``) under a hash of everything that determines its
result: the geometry, the material, the mesh level, the load case, what is asked (compliance or not) and
a fingerprint of the code that computes it (:func:`fem_fingerprint`: the ``fem_reference`` sources but its
presentation modules, and this module and :mod:`validation.reference.experiments`, which build the records); so a
re-run computes only what changed and an interrupted sweep resumes where it stopped.

A worker builds its :class:`fem_reference.BellowsModel` once per (geometry, material, mesh) and keeps it
for the following cases.  The result of one case is a small :class:`FemRecord` (tip pose, centreline,
tendon data, optionally the 3×3 tip compliances), never the model.

Warm starts.  The cases are grouped into short *chains* (:func:`plan_chains`): each chain starts at the
case with the smallest load and visits its nearest remaining neighbour next, in the load space scaled by
the operating range; every solve of a chain starts from the previous equilibrium and ramps the loads from
there (the FEM's own load stepping), which takes far fewer Newton iterations than solving every case from
the unloaded state.  A chain is the unit of parallel work and of caching.  The equilibrium of a stable
state does not depend on the path to it, so warm and cold solves agree to the solver's tolerance.
Axisymmetric cases are chained apart from the others, so that the FEM solves them in its symmetric subspace.
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass, field, replace
from typing import Optional, Sequence

import numpy as np

from ancf.errors import BellowsError, ConfigError, InputError, LimitError

from validation.reference.experiments import LoadCase
from validation.infra.runner import ResultCache, RunInterrupted, run_tasks, source_fingerprint

#: fem_reference modules that cannot change a cached result (command line, rendering, text formatting, the
#: closed-form verification problems): editing them keeps the cache
FEM_PRESENTATION = ("cli.py", "render.py", "verification.py")


def fem_fingerprint() -> str:
    """Cache version of FEM results: a hash of every module that computes them (see the module docstring)."""
    return "fem-" + source_fingerprint("fem_reference", exclude=FEM_PRESENTATION,
                                       files=("validation.reference.fem_sweep", "validation.reference.experiments"))


__all__ = ["FemRecord", "FemSpec", "run_cases", "run_rod", "run_modes", "fem_model", "solve_task", "plan_chains",
           "tip_compliances", "mesh_level", "describe_level",
           "axisymmetric",
           "locked_compliance", "modes_chain", "classify_fem_modes"]


@dataclass(frozen=True)
class FemSpec:
    """What defines an FEM model: geometry, material, mesh level and wall element (``"mixed"``, the locking-free
    default, or ``"displacement"``; fem_reference.assembly.ELEMENTS) — all picklable, hashable inputs."""
    geometry: object
    material: object
    mesh: str = "coarse"
    element: str = "mixed"
    #: gravity vector (3,) [m/s²] of the gravity load cases (the design's mounting,
    #: validation.reference.designs.MOUNTINGS; default horizontal: −z with the axis along +x)
    gravity: tuple = (0.0, 0.0, -9.81)

    def __post_init__(self):
        from fem_reference.assembly import check_element
        from fem_reference.mesh import MESH_LEVELS, MeshLevel
        if not (isinstance(self.mesh, MeshLevel) or (isinstance(self.mesh, str) and self.mesh in MESH_LEVELS)):
            raise ConfigError(f"unknown mesh level {self.mesh!r}; choose from {sorted(MESH_LEVELS)}")
        check_element(self.element, self.material)
        g = np.asarray(self.gravity, float)
        if g.shape != (3,) or not np.all(np.isfinite(g)):
            raise ConfigError(f"FemSpec.gravity must be 3 finite numbers [m/s²], got {self.gravity!r}")
        object.__setattr__(self, "gravity", tuple(float(v) for v in g))

    def key(self) -> dict:
        k = {"geometry": self.geometry, "material": self.material, "mesh": self.mesh, "element": self.element}
        if self.gravity != (0.0, 0.0, -9.81):   # the horizontal default keeps the cache keys it always had
            k["gravity"] = self.gravity
        return k


@dataclass
class FemRecord:
    """The FEM's answer for one load case (SI units).

    tip_position (3,) [m]; cap_rotation (3, 3); centreline (k, 3) [m] with centreline_s (k,) the
    undeformed arc length of each point from the base [m]; tensions (m,) [N]; tendon_lengths (m,) [m];
    compliance_tension / compliance_locked (3, 3) [m/N] (tip compliance with tensions held / tendons
    locked, if asked) and locked_active (indices of the tendons locked); with a slack tendon also
    ``extra["compliance_locked_opposite"]`` / ``extra["locked_active_opposite"]``: the same for the opposite
    load direction (+z by default), whose taut set can differ; iterations, seconds; error: the
    failure message if the solve failed (then the arrays are NaN).
    """
    case: LoadCase
    tip_position: np.ndarray
    cap_rotation: np.ndarray
    centreline: np.ndarray
    centreline_s: np.ndarray
    tensions: np.ndarray
    tendon_lengths: np.ndarray
    compliance_tension: Optional[np.ndarray] = None
    compliance_locked: Optional[np.ndarray] = None
    iterations: int = 0
    seconds: float = 0.0
    error: str = ""
    extra: dict = field(default_factory=dict)
    state: Optional[object] = field(default=None, repr=False, compare=False)

    @property
    def ok(self) -> bool:
        return not self.error

    def centreline_at(self, s) -> np.ndarray:
        """Centreline points at undeformed arc lengths ``s`` (k,) [m], linear interpolation → (k, 3) [m]."""
        s = np.atleast_1d(np.asarray(s, float))
        return np.column_stack([np.interp(s, self.centreline_s, self.centreline[:, c]) for c in range(3)])

    def to_dict(self) -> dict:
        d = asdict(replace(self, state=None))
        d.pop("state")
        d["case"] = self.case.to_dict()
        return d


_MODELS: dict = {}


def fem_model(spec: FemSpec):
    """The :class:`fem_reference.BellowsModel` of ``spec``, built once per process."""
    from fem_reference import BellowsModel
    from validation.infra.runner import task_key
    k = task_key(spec.key())
    if k not in _MODELS:
        _MODELS.clear()                       # one model per worker at a time (memory)
        _MODELS[k] = BellowsModel(spec.geometry, spec.material, mesh=spec.mesh, element=spec.element,
                                  gravity_vector=spec.gravity)
    return _MODELS[k]


def _centreline_s(model) -> np.ndarray:
    """Undeformed arc length of each centreline row (reference axial coordinate of each ring) [m]."""
    bm = model.bmesh
    n_s, n_t, _ = bm.shape
    sel = bm.lattice[1] == n_t
    i_s = bm.lattice[0, sel]
    cnt = np.bincount(i_s, minlength=2 * n_s + 1)
    return np.bincount(i_s, weights=bm.X[0, sel], minlength=2 * n_s + 1) / cnt


def solve_task(task: dict):
    """Worker entry point: ``task["kind"]`` is ``"chain"`` (:func:`solve_chain`), ``"case"``
    (:func:`solve_case`), ``"rod"`` (:func:`rod_estimate`) or ``"modes"`` (:func:`modes_chain`)."""
    kind = task.get("kind")
    if kind == "rod":
        return rod_estimate(task)
    if kind == "modes":
        return modes_chain(task)
    if kind == "chain":
        return solve_chain(task)
    return solve_case(task)


def rod_estimate(task: dict) -> dict:
    """Worker: closed-form equivalent-rod values (EA, EI, D_a, D_eff, …) from the condensed cap tangent of the
    unloaded FEM (:meth:`fem_reference.BellowsModel.equivalent_rod`), plus the wall and cap masses."""
    spec: FemSpec = task["spec"]
    model = fem_model(spec)
    rod = model.equivalent_rod()
    rod = {k: (np.asarray(v).tolist() if isinstance(v, np.ndarray) else float(v)) for k, v in rod.items()}
    rod["wall_mass_kg"] = float(spec.geometry.wall_volume() * spec.material.density)
    rod["cap_mass_kg"] = float(spec.geometry.cap_mass)
    return rod


def solve_case(task: dict) -> FemRecord:
    """Worker: solve one load case on the FEM (``task``: spec, case, compliance) → :class:`FemRecord`."""
    return solve_chain({**task, "kind": "chain", "cases": [task["case"]],
                        "compliance": [bool(task.get("compliance"))]})[0]


def solve_chain(task: dict) -> list:
    """Worker: solve the load cases ``task["cases"]`` in order, each warm-started from the previous
    equilibrium (``task``: spec, cases, compliance — one flag per case; optional ``starts`` — one
    :class:`fem_reference.transfer.StateSnapshot` or None per case, the same case solved on another mesh of
    the design, tried first: :func:`start_solve`) → list of :class:`FemRecord`.

    A solve that fails (a :class:`~ancf.errors.BellowsError`) is retried from the unloaded state; if that
    fails too, its record carries ``error`` (arrays NaN), so that one hard case does not lose the sweep;
    the caller decides what a failed case means."""
    from fem_reference.transfer import snapshot
    spec: FemSpec = task["spec"]
    model = fem_model(spec)
    m = model.m
    out, prev = [], None
    starts = task.get("starts") or [None] * len(task["cases"])
    for case, want_c, start in zip(task["cases"], task["compliance"], starts):
        t0 = time.perf_counter()
        if len(case.tensions) != m:
            raise InputError(f"load case has {len(case.tensions)} tensions; the FEM model has {m} tendons")
        loads = dict(tensions=case.tensions, pressure=case.pressure, tip_force=case.tip_force, gravity=case.gravity)
        res, err = None, ""
        if start is not None:
            res, err = start_solve(model, start, loads)
            started = res is not None
        for initial in (() if res is not None else (prev, None) if prev is not None else (None,)):
            try:
                res = model.solve(**loads, initial=initial)
                break
            except BellowsError as exc:
                err = f"{type(exc).__name__}: {exc}"
        if res is None:
            s = _centreline_s(model)
            out.append(FemRecord(case, np.full(3, np.nan), np.full((3, 3), np.nan), np.full((len(s), 3), np.nan), s,
                                 np.full(m, np.nan), np.full(m, np.nan), seconds=time.perf_counter() - t0, error=err))
            continue
        prev = res
        rec = FemRecord(case, res.tip_position.copy(), res.cap_rotation.copy(), res.centreline.copy(),
                        _centreline_s(model), res.tensions.copy(), np.asarray(res.tendon_lengths, float).copy(),
                        iterations=res.iterations, state=snapshot(res))
        if start is not None:   # how the solve went, for people: the equilibrium is the same either way
            rec.extra["started_from_other_mesh"] = started
        if want_c:       # both compliances from one factorisation of the tangent
            u = np.asarray(task.get("locked_direction", (0.0, 0.0, -1.0)), float)
            slack = bool(np.any(res.state.T <= 1e-12))      # then the taut set depends on the load's sign
            rec.compliance_tension, both = tip_compliances(model, res, (u, -u) if slack else (u,))
            rec.compliance_locked, rec.extra["locked_active"] = both[0]
            if slack:
                rec.extra["compliance_locked_opposite"], rec.extra["locked_active_opposite"] = both[1]
        rec.seconds = time.perf_counter() - t0
        out.append(rec)
    return out


def start_solve(model, start, loads: dict) -> tuple:
    """Solve ``loads`` on ``model`` from ``start``, the same loads' equilibrium on another mesh of the design
    (:func:`fem_reference.transfer.start_from`: interpolated, the added nodes relaxed), in one load step at
    full load → (result, "") or (None, the failure) — the caller then solves from the unloaded state.  A
    snapshot with other loads is refused (InputError): it would be a start for a different problem."""
    from fem_reference.transfer import start_from
    if not (np.allclose(start.T, loads["tensions"], rtol=0, atol=1e-12) and start.pressure == loads["pressure"]
            and np.allclose(start.tip_force, loads["tip_force"], rtol=0, atol=1e-12)
            and float(start.gravity) == float(loads["gravity"])):
        raise InputError("start_solve: the start was solved under other loads")
    try:
        return model.solve(**loads, initial=start_from(start, model), max_cuts=0), ""
    except BellowsError as exc:
        return None, f"{type(exc).__name__}: {exc}"


def _load_vector(case: LoadCase, scale: np.ndarray) -> np.ndarray:
    return np.concatenate([case.tensions, [case.pressure], case.tip_force, [float(case.gravity)]]) / scale


def axisymmetric(case: LoadCase) -> bool:
    """Whether a load case keeps the actuator's rotational symmetry: equal tensions, pressure, no tip force, no
    gravity (the FEM then solves it in its symmetric subspace, :mod:`fem_reference.symmetry`)."""
    T = np.asarray(case.tensions, float)
    return (T.size == 0 or bool(np.ptp(T) <= 1e-12 * max(1.0, float(np.abs(T).max())))) \
        and not np.any(np.asarray(case.tip_force, float)) and not float(case.gravity)


def plan_chains(cases: Sequence[LoadCase], max_length: int = 4) -> list[list[int]]:
    """Group case indices into warm-start chains of at most ``max_length`` cases (see the module docstring):
    each chain starts at the smallest remaining load and goes to the nearest remaining case next, in the load
    space scaled by the largest value of each load component over the cases.

    A chain ends where the nearest remaining case is farther from its last case than from the unloaded state
    (measured: a lateral tip force at 0 kPa reached from a 5 N single-tendon bend took 155 Newton iterations,
    from the unloaded state 15).  Axisymmetric cases (:func:`axisymmetric`) are chained apart from the others: a warm start from a bent
    state would keep the FEM from solving them in its 6-fold symmetric subspace (measured 1.3–2× per solve,
    docs/fem.md §4).  Their chains come last: they are the cheap ones, so the parallel workers finish together.
    Cases with gravity are chained apart from those without: the self-weight of the whole wall is not a small
    step from a weightless state (measured: 3 N on one tendon at 50 kPa with gravity, warm-started from the same
    tendon without gravity, took 57 Newton iterations and 43 s; from the unloaded state 21 and 14 s)."""
    if max_length < 1:
        raise InputError("max_length must be >= 1")
    n = len(cases)
    if n == 0:
        return []
    raw = np.array([_load_vector(c, 1.0) for c in cases])
    scale = np.maximum(np.abs(raw).max(axis=0), 1e-12)
    X = raw / scale
    cls = [(axisymmetric(c), bool(c.gravity)) for c in cases]
    return [ch for key in ((False, False), (False, True), (True, False))
            for ch in _nearest_chains(X, [i for i in range(n) if cls[i] == key], max_length)]


def _nearest_chains(X: np.ndarray, indices: list, max_length: int) -> list[list[int]]:
    left = set(indices)
    chains = []
    while left:
        start = min(left, key=lambda i: (np.linalg.norm(X[i]), i))
        chain = [start]
        left.discard(start)
        while left and len(chain) < max_length:
            nxt = min(left, key=lambda i: (np.linalg.norm(X[i] - X[chain[-1]]), i))
            if np.linalg.norm(X[nxt] - X[chain[-1]]) > np.linalg.norm(X[nxt]):
                break               # nearer to the unloaded state than to this one: a cold start is shorter
            chain.append(nxt)
            left.discard(nxt)
        chains.append(chain)
    return chains


def locked_compliance(model, res, direction):
    """FEM tip compliance (3, 3) [m/N] with *all* tendons locked at their current lengths, and the taut tendons
    (list of indices), chosen by the complementarity rule of the reduced model's exact locked compliance
    (:func:`ancf.compliance.active_set`, ``rule="exact"``), so that both models run the same experiment: tendons
    carrying tension stay taut; a slack one is taut iff a small tip load along ``direction`` (3,) would stretch it
    and its tension increment is ≥ 0.  ``direction`` may also be a tuple of directions (one factorisation):
    then a list of (compliance, taut) pairs, one per direction — with a slack tendon the locked response is
    piecewise linear, and ±u can make different tendons taut."""
    return tip_compliances(model, res, direction)[1]


def tip_compliances(model, res, direction) -> tuple:
    """``(C_tension, locked)`` from one assembly and factorisation of the tangent at ``res``: the tip compliance
    with the tensions held, ``J_p K⁻¹ J_pᵀ`` (3, 3) [m/N] (:meth:`fem_reference.BellowsModel.tip_compliance`,
    ``mode="tension"``), and what :func:`locked_compliance` returns for ``direction``."""
    from fem_reference.solver import factorize
    st = res.state
    ev = model.evaluate(st, res.loadcase, tangent=True)
    fac = factorize(ev["K"], model.linear_solver)
    Jp = model.tip_jacobian(st).toarray()
    Y = fac.solve(Jp.T)                              # K⁻¹ J_pᵀ
    g_all = ev["g"]                                   # (n_dofs, m): ∂L_i/∂q
    Z_all = fac.solve(g_all)                          # K⁻¹ g
    taut = {i for i in range(g_all.shape[1]) if st.T[i] > 1e-12}
    if isinstance(direction, tuple) and len(direction) and np.ndim(direction[0]) == 1:
        return Jp @ Y, [_locked_along(Jp, Y, g_all, Z_all, taut, d) for d in direction]
    return Jp @ Y, _locked_along(Jp, Y, g_all, Z_all, taut, direction)


def _locked_along(Jp, Y, g_all, Z_all, taut: set, direction) -> tuple[np.ndarray, list]:
    """The active-set loop of :func:`locked_compliance` for one load direction (3,)."""
    u = np.asarray(direction, float)
    u = u / np.linalg.norm(u)
    m = g_all.shape[1]

    def response(A):
        if not A:
            return Y, np.zeros((0, 3))
        g, Z = g_all[:, A], Z_all[:, A]
        dT = np.linalg.solve(g.T @ Z, g.T @ Y)          # tension increments per unit tip force (len(A), 3)
        return Y - Z @ dT, dT

    dl0 = g_all.T @ (Y @ u)
    A = sorted(taut | {i for i in range(m) if dl0[i] > 0})
    seen = set()
    while tuple(A) not in seen:
        seen.add(tuple(A))
        dq, dT = response(A)
        dTu = dict(zip(A, dT @ u))
        dl = g_all.T @ (dq @ u)
        drop = [i for i in A if i not in taut and dTu[i] < -1e-12 * max(1.0, abs(dTu[i]))]
        add = [i for i in range(m) if i not in A and dl[i] > 1e-14]
        if not drop and not add:
            return Jp @ dq, A
        if drop:
            A.remove(min(drop, key=lambda i: dTu[i]))
        else:
            A = sorted(A + [max(add, key=lambda i: dl[i])])
    raise InputError("the active set of the FEM locked compliance cycled (degenerate state)")


def check_cases(spec: FemSpec, cases: Sequence[LoadCase]) -> None:
    """Fail fast, before any FEM work: every case must have one tension per tendon of the design and loads
    inside the FEM's operating limits (:class:`fem_reference.OperatingLimits`; the solve would refuse them
    one by one and a fit would run on what is left).  :class:`~ancf.errors.LimitError` names the first
    offending case, the load and the FEM's bound."""
    from fem_reference import OperatingLimits
    m = len(spec.geometry.tendon_angles)
    limits = OperatingLimits()
    for c in cases:
        if len(c.tensions) != m:
            raise InputError(f"load case {c.label or c.experiment} has {len(c.tensions)} tensions; the FEM design "
                             f"has {m} tendons")
        try:
            limits.check_loads(c.tensions, c.pressure, c.tip_force)
        except LimitError as exc:
            why = str(exc).split(" (check_limits")[0]
            raise LimitError(f"load case {c.label or c.experiment}: {why}. "
                             "The operating range asked for (the design's [limits] table or --tension-max-n / "
                             "--pressure-max-kpa) exceeds what the FEM reference accepts (tension ≤ "
                             f"{limits.tension_max:g} N, pressure ≤ {limits.pressure_max / 1e3:g} kPa, |tip force| ≤ "
                             f"{limits.tip_force_max:g} N); lower it") from None


def run_cases(spec: FemSpec, cases: Sequence[LoadCase], *, compliance=False, workers: Optional[int] = None,
              scheduler=None, cache_dir=None, progress: bool = True, on_result=None,
              chain_length: int = 4, starts: Optional[Sequence] = None,
              specs: Optional[Sequence[FemSpec]] = None) -> list[FemRecord]:
    """Solve every load case on the FEM of ``spec``; returns one :class:`FemRecord` per case, in order.

    compliance : also compute the tip compliances (tension held, all tendons locked) of each state (a bool,
        or a function of the load case);  workers, scheduler : see :func:`validation.infra.runner.run_tasks`;
    cache_dir : folder of the on-disk cache (None: no cache);  on_result(i, records) : called as each chain
    finishes;  chain_length : cases per warm-start chain (1: every case solved from the unloaded state);
    starts : one :class:`fem_reference.transfer.StateSnapshot` or None per case — the case's equilibrium on
        another mesh of the design (a :class:`FemRecord`'s ``state``), from which it is solved first
        (:func:`start_solve`).  The cache key does not include it: the equilibrium does not depend on the start;
    specs : one :class:`FemSpec` per case instead of ``spec`` (e.g. the same design on several refined meshes), so
        that cases on different meshes share one pool of workers; chains never pass between specs.
    Raises :class:`validation.infra.runner.RunInterrupted` on Ctrl-C (finished chains are in the cache)."""
    cases = list(cases)
    if not cases:
        raise InputError("run_cases: no load cases")
    per_case = [spec] * len(cases) if specs is None else list(specs)
    if len(per_case) != len(cases) or not all(isinstance(sp, FemSpec) for sp in per_case):
        raise InputError(f"run_cases: specs must be one FemSpec per case ({len(cases)})")
    distinct = []                                   # the specs, each once, in order of first use
    for sp in per_case:
        if not any(sp == d for d in distinct):
            distinct.append(sp)
    for sp in distinct:
        check_cases(sp, [c for c, s2 in zip(cases, per_case) if s2 == sp])
    want = compliance if callable(compliance) else (lambda c, v=bool(compliance): v)
    if starts is not None and len(starts) != len(cases):
        raise InputError(f"run_cases: {len(starts)} starts for {len(cases)} cases")
    chains, chain_specs = [], []
    for sp in distinct:
        idx = [i for i, s2 in enumerate(per_case) if s2 == sp]
        for ch in plan_chains([cases[i] for i in idx], chain_length):
            chains.append([idx[j] for j in ch])
            chain_specs.append(sp)
    tasks = [{"kind": "chain", "spec": sp, "cases": [cases[i] for i in ch],
              "compliance": [bool(want(cases[i])) for i in ch]} for ch, sp in zip(chains, chain_specs)]
    if starts is not None:
        for t, ch in zip(tasks, chains):
            t["starts"] = [starts[i] for i in ch]
    cache = None
    if cache_dir is not None:
        cache = ResultCache(cache_dir, version=fem_fingerprint())

    def key_inputs(task):
        return {**task["spec"].key(), "cases": task["cases"], "compliance": task["compliance"],
                "locked_direction": task.get("locked_direction", (0.0, 0.0, -1.0))}

    try:
        out = run_tasks(solve_task, tasks, workers=workers, scheduler=scheduler, progress=progress,
                        description=f"FEM ({_meshes_text(distinct)}, {len(cases)} cases)", cache=cache,
                        key_inputs=key_inputs,
                        on_result=on_result, weights=[len(t["cases"]) for t in tasks])
    except RunInterrupted as exc:
        done = sum(len(tasks[i]["cases"]) for i in exc.completed)
        where = (f"they are cached in {cache_dir}: run the same command again to resume" if cache is not None
                 else "without a cache folder they are not kept (use --cache)")
        raise RunInterrupted(f"interrupted: {done} of {len(cases)} FEM cases were finished; {where}",
                             completed=exc.completed, total=exc.total, saved_to=cache_dir) from None
    records: list = [None] * len(cases)
    for ch, recs in zip(chains, out.results):
        for i, r in zip(ch, recs):
            records[i] = r
    return records


def mesh_level(mesh):
    """A mesh level name or :class:`fem_reference.MeshLevel` → the MeshLevel."""
    from fem_reference.mesh import MESH_LEVELS, MeshLevel
    if isinstance(mesh, MeshLevel):
        return mesh
    if isinstance(mesh, str) and mesh in MESH_LEVELS:
        return MESH_LEVELS[mesh]
    raise InputError(f"unknown mesh level {mesh!r}; choose from {sorted(MESH_LEVELS)} or give a MeshLevel")


def describe_level(mesh) -> str:
    """A mesh level in words: "'coarse' (4 per convolution × 2 through the wall × 12 around, 1 per collar)"."""
    lvl = mesh_level(mesh)
    name = f"'{mesh}' " if isinstance(mesh, str) else ""
    return (f"{name}({lvl.n_per_conv} per convolution × {lvl.n_thick} through the wall × {lvl.n_theta} around, "
            f"{lvl.n_collar} per collar)")


def _meshes_text(specs: Sequence[FemSpec]) -> str:
    """The meshes of ``specs`` for a progress line: a level's name, or its element counts (:func:`describe_level`)."""
    names = [sp.mesh if isinstance(sp.mesh, str) else describe_level(sp.mesh) for sp in specs]
    return f"{names[0]} mesh" if len(names) == 1 else f"meshes {' | '.join(names)}"


def run_rod(spec: FemSpec, *, cache_dir=None) -> dict:
    """:func:`rod_estimate` of ``spec`` in this process (cached like the load cases)."""
    cache = None if cache_dir is None else ResultCache(cache_dir, version=fem_fingerprint())
    task = {"kind": "rod", "spec": spec}
    return run_tasks(solve_task, [task], workers=1, progress=False, cache=cache,
                     key_inputs=lambda t: {**t["spec"].key(), "kind": "rod"}).results[0]


#: modes asked of the FEM per state: enough to hold the first bending pair, the second, the first axial and
#: the first torsion mode of a bellows
FEM_MODE_COUNT = 8


def classify_fem_modes(frequencies_hz, cap_shapes, axis, length: float) -> dict:
    """The first bending and first axial frequency [Hz] among FEM modes, from the rigid cap's motion in each
    shape (``cap_shapes`` (k, 6): translation [m], rotation [rad]; ``axis``: the actuator's axis at the state):
    a shape whose cap translation is not small beside its rotation times ``length`` (torsion has none) is
    *axial* when ≥ 90 % of the translation lies along the axis and *bending* when ≥ 90 % lies across it.
    None where no mode of the kind is among those computed."""
    shapes = np.asarray(cap_shapes, float)
    translating = [np.linalg.norm(s[:3]) > 0.1 * length * np.linalg.norm(s[3:]) for s in shapes]
    return first_bending_and_axial(np.asarray(frequencies_hz)[translating], shapes[translating, :3], axis)


def first_bending_and_axial(frequencies_hz, translations, axis) -> dict:
    """The first frequency [Hz] whose point translation (``translations`` (k, 3)) lies ≥ 90 % along ``axis``
    (axial) and the first whose translation lies ≥ 90 % across it (bending); None where there is none."""
    e = np.asarray(axis, float) / np.linalg.norm(axis)
    out = {"bending_hz": None, "axial_hz": None}
    for f, u in zip(frequencies_hz, np.asarray(translations, float)):
        nu = np.linalg.norm(u)
        if not nu > 0:
            continue
        along = abs(float(u @ e))
        across = float(np.linalg.norm(u - (u @ e) * e))
        if out["axial_hz"] is None and along > 0.9 * nu:
            out["axial_hz"] = float(f)
        elif out["bending_hz"] is None and across > 0.9 * nu:
            out["bending_hz"] = float(f)
    return out


def modes_chain(task: dict) -> list:
    """Worker: the FEM's first bending and axial modes (tensions held, :meth:`fem_reference.BellowsModel.modes`)
    at each pressure of ``task["pressures"]`` [Pa] with the tensions ``task["tensions"]`` [N], no gravity; each
    state warm-started from the previous one.  One dict per pressure: pressure_Pa, bending_hz, axial_hz,
    frequencies_hz (every mode computed), total_mass_kg, seconds, error (the failure text, '' if none; then
    the frequencies are None)."""
    spec: FemSpec = task["spec"]
    model = fem_model(spec)
    length = float(spec.geometry.length)
    out, prev = [], None
    for p in task["pressures"]:
        t0 = time.perf_counter()
        row = {"pressure_Pa": float(p), "bending_hz": None, "axial_hz": None, "frequencies_hz": None,
               "total_mass_kg": None, "seconds": 0.0, "error": ""}
        res, err = None, ""
        for initial in ((prev, None) if prev is not None else (None,)):
            try:
                res = model.solve(tensions=task["tensions"], pressure=float(p), initial=initial)
                break
            except BellowsError as exc:
                err = f"{type(exc).__name__}: {exc}"
        if res is not None:
            prev = res
            try:
                md = model.modes(res, FEM_MODE_COUNT, tendons="held")
            except BellowsError as exc:
                err = f"{type(exc).__name__}: {exc}"
            else:
                err = ""
                axis = np.asarray(res.tip_position, float)
                row.update(classify_fem_modes(md.frequencies_hz, md.cap_shapes, axis, length))
                row["frequencies_hz"] = [float(f) for f in md.frequencies_hz]
                row["total_mass_kg"] = float(md.total_mass)
        row["error"] = err
        row["seconds"] = time.perf_counter() - t0
        out.append(row)
    return out


def run_modes(spec: FemSpec, pressures: Sequence[float], tensions: Sequence[float], *, cache_dir=None,
              progress: bool = False) -> list:
    """:func:`modes_chain` of ``spec`` in this process, cached like the load cases (one entry per design,
    mesh, pressures and tensions).  Loads outside the FEM's operating limits are refused first
    (:class:`~ancf.errors.LimitError`)."""
    from fem_reference import OperatingLimits
    pressures = [float(p) for p in pressures]
    tensions = [float(t) for t in tensions]
    if not pressures:
        raise InputError("run_modes: no pressures")
    if len(tensions) != len(spec.geometry.tendon_angles):
        raise InputError(f"run_modes: {len(tensions)} tensions for a design with "
                         f"{len(spec.geometry.tendon_angles)} tendons")
    for p in pressures:
        OperatingLimits().check_loads(tensions, p, (0.0, 0.0, 0.0))
    cache = None if cache_dir is None else ResultCache(cache_dir, version=fem_fingerprint())
    task = {"kind": "modes", "spec": spec, "pressures": pressures, "tensions": tensions}
    return run_tasks(solve_task, [task], workers=1, progress=progress, description=f"FEM modes ({spec.mesh} mesh)",
                     cache=cache, key_inputs=lambda t: {**t["spec"].key(), "kind": "modes",
                                                        "pressures": t["pressures"], "tensions": t["tensions"],
                                                        "count": FEM_MODE_COUNT}).results[0]
