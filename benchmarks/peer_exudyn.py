"""Benchmark peer: static solve of a clamped-free ANCF cable cantilever in Exudyn.

This module builds the same problem as our own ANCF statics solver in the compiled
multibody library Exudyn (https://github.com/jgerstmayr/EXUDYN) and times it, so that
both the answer and the cost can be compared.

Model (Exudyn item names)
-------------------------
* ``NodePointSlope1``       : 3-D ANCF node, coordinates (r, r_x) = 6 ODE2 coordinates.
* ``ObjectANCFCable``       : 3-D Bernoulli-Euler ANCF cable element (cubic Hermite),
                              bending in 3-D, no torsion. Default (full) Gauss integration:
                              order 9 for the axial term, order 5 for bending.
* ``NodePointGround`` + ``MarkerNodeCoordinate`` + ``CoordinateConstraint`` (x 6):
                              clamp of the first node in position AND slope (all 6
                              displacement coordinates of node 0 held at zero, i.e. the
                              reference values r = 0, r_x = base_axis).
* ``MarkerNodePosition`` + ``LoadForceVector``: tip force on the last node (global frame,
  dead load).
* ``MarkerBodyMass`` + ``LoadMassProportional`` (per element): uniform line load.
  The cable gets ``massPerLength = 1 kg/m`` and the "acceleration" vector is set to the
  line load q [N/m], so each element receives the consistent load  int rhoA*q*S dx  =
  int q*S dx (including the slope/moment components). Mass plays no role in statics.

Solver
------
``mbs.SolveStatic`` (= ``exudyn.SolveStatic``, i.e. ``MainSolverStatic``): full Newton,
sparse linear solver (``LinearSolverType.EigenSparse``; ``linear_solver="dense"`` selects
Exudyn's default ``EXUdense``, which is equally fast at n=6, slower from n=12 on and prints
a warning above 1000 unknowns), exact (automatic-differentiation) element Jacobians, one load step
(the static solver ramps the load factor 0 -> 1 and subdivides the step by itself only if
Newton fails).

Convergence test: Exudyn's default test is on the L2 norm of the force residual
(``|R|/|R_0| <= 1e-8`` or ``|R| <= 1e-10``). Its round-off floor grows roughly like n^3
(measured for L=0.16 m, EA=767.2 N, EI=0.0839 N m^2: ~2e-12 N at n=6, ~5e-12 N at n=12,
~3e-9 N at n=96, ~3e-8 N at n=192), so a residual tolerance tight enough for 1e-9 tip
accuracy makes Newton stall for fine meshes. We therefore switch Exudyn to its increment
criterion (``newton.residualMode = 1``: error = L2 norm of the Newton increment of all
ODE2 coordinates, positions [m] and slopes [-]) with ``relativeTolerance =
absoluteTolerance = newton_tol = 1e-10`` (Exudyn's docs ask for equal values in this
mode). The increment floor is ~1e-15..1e-13 for n=6..192; since full Newton converges
quadratically, the accepted iterate's error is ~ the next increment ~ C*newton_tol^2.
Checked over n=6..192, tip loads 1e-6..20 N, with/without line load: relative tip error
|tip - tip_ref| / |tip_ref - tip_0| <= 3e-11 (reference: newton_tol=1e-12). The test case
(0,0,-0.49) N needs 4 Newton iterations (Exudyn's default criterion: 3, rel. error 1.3e-10).

Cost profile (Exudyn's own CSolverTimer, n=12, 4 Newton iterations, ~1.5 ms): ~70 % element
Jacobians (automatic differentiation with 24 derivative slots per 12-coordinate element),
~25 % sparse factorisation, residuals ~3 %; one Newton iteration costs ~0.19 ms (n=6) /
~0.37 ms (n=12), fixed solver set-up ~0.05 ms.

Material law differences vs. our model (see ``CObjectANCFCable.cpp``)
---------------------------------------------------------------------
* axial strain: ``eps = |r_x| - 1`` (Biot/engineering strain), energy ``1/2 EA eps^2``
  (ours: Green strain ``1/2(|r_x|^2 - 1)``);
* curvature: vector ``kappa = (r_x x r_xx) / |r_x|^2`` ("material measure of curvature"),
  energy ``1/2 EI |kappa|^2`` (ours: ``|r_x x r_xx| / |r_x|^3``).
Both coincide with ours for an inextensible cable; the differences are O(eps), but with
these stiffnesses the curvature normalisation matters: bending makes ours prefer stretching
(dW/deps contains -EI*kappa^2), eps ~ EI kappa^2/EA. Measured with an independent energy
minimiser (same Hermite mesh): for n=12, tip (0,0,-0.49) N, Exudyn's law gives
tip = (0.159767622354, 0, -0.007954267270) m, our law (0.159772466477, 0, -0.007955730140) m,
i.e. |dtip|/|tip - tip_0| = 6.4e-4 (n=6: 6.2e-4); of this, Green vs Biot strain alone is
only 3.7e-8, the rest is |r_x|^-3 vs |r_x|^-2 in kappa.

Dynamics (``simulate_cantilever``): the same cable with its mass (``massPerLength`` = m'), gravity as a
mass-proportional load, released from the straight reference at rest, integrated by Exudyn's
generalized-α (``DynamicSolverType.GeneralizedAlpha``, Arnold–Brüls form like ours, fixed step, full Newton
with the increment criterion); the tip position is recorded by a ``SensorNode`` at every step.

Only ``available``, ``solve_cantilever``, ``time_solve``, ``simulate_cantilever`` are public. Nothing is printed,
rendered, or written to disk.
"""
from __future__ import annotations

import statistics
import time

import numpy as np

try:  # pragma: no cover - depends on environment
    import exudyn as _exu
    from exudyn.itemInterface import (
        CoordinateConstraint,
        LoadForceVector,
        LoadMassProportional,
        MarkerBodyMass,
        MarkerNodeCoordinate,
        MarkerNodePosition,
        NodePointGround,
        NodePointSlope1,
        ObjectANCFCable,
        SensorNode,
        VNodePointSlope1,
        VObjectANCFCable,
    )
except Exception:  # ImportError, or a broken binary wheel
    _exu = None

__all__ = ["available", "solve_cantilever", "time_solve", "simulate_cantilever"]

#: Newton tolerance on the L2 norm of the Newton increment (Exudyn residualMode=1).
DEFAULT_NEWTON_TOL = 1e-10


def available() -> bool:
    """True if exudyn could be imported."""
    return _exu is not None


def _require() -> None:
    if _exu is None:
        raise RuntimeError("exudyn is not importable; install with `pip install exudyn`")


def _settings(newton_tol: float, linear_solver: str = "sparse"):
    """Quiet static-solver settings: no console output, no files."""
    s = _exu.SimulationSettings()
    if linear_solver == "sparse":
        s.linearSolver.solverType = _exu.LinearSolverType.EigenSparse
    elif linear_solver == "dense":
        s.linearSolver.solverType = _exu.LinearSolverType.EXUdense
    else:
        raise ValueError("linear_solver must be 'sparse' or 'dense'")
    s.staticSolver.verboseMode = 0
    s.staticSolver.verboseModeFile = 0
    s.solution.file.write = False
    s.solution.sensors.active = False
    s.show.computationTime = False
    s.show.statistics = False
    s.staticSolver.numberOfLoadSteps = 1
    s.staticSolver.newton.useModifiedNewton = False
    s.staticSolver.newton.residualMode = 1  # error = norm of Newton increment
    s.staticSolver.newton.relativeTolerance = float(newton_tol)
    s.staticSolver.newton.absoluteTolerance = float(newton_tol)
    return s


def _build(n_elements, length, EA, EI, tip_force, line_load, base_axis, line_mass=1.0):
    """Create the Exudyn system (not yet assembled). Returns (SC, mbs, tip_node)."""
    n = int(n_elements)
    if n < 1 or n != n_elements:
        raise ValueError("n_elements must be a positive integer")
    if not length > 0:
        raise ValueError("length must be positive")
    e = np.asarray(base_axis, dtype=float).reshape(3)
    ne = float(np.linalg.norm(e))
    if ne == 0.0:
        raise ValueError("base_axis must be non-zero")
    e = e / ne
    h = float(length) / n
    slope = e.tolist()
    q = [float(v) for v in np.asarray(line_load, dtype=float).reshape(3)]
    f = [float(v) for v in np.asarray(tip_force, dtype=float).reshape(3)]
    has_q = any(v != 0.0 for v in q)

    SC = _exu.SystemContainer()
    mbs = SC.AddSystem()
    vnode = VNodePointSlope1(show=False)
    vcable = VObjectANCFCable(show=False)

    nodes = [mbs.AddNode(NodePointSlope1(referenceCoordinates=[0.0, 0.0, 0.0] + slope,
                                         visualization=vnode))]
    for i in range(n):
        p = ((i + 1) * h * e).tolist()
        nodes.append(mbs.AddNode(NodePointSlope1(referenceCoordinates=p + slope,
                                                 visualization=vnode)))
        obj = mbs.AddObject(ObjectANCFCable(length=h, massPerLength=float(line_mass),
                                            bendingStiffness=float(EI),
                                            axialStiffness=float(EA),
                                            nodeNumbers=[nodes[-2], nodes[-1]],
                                            visualization=vcable))
        if has_q:  # line load q [N/m] (statics, rhoA = 1 kg/m) or gravity [m/s^2] (dynamics, rhoA = m')
            mm = mbs.AddMarker(MarkerBodyMass(bodyNumber=obj))
            mbs.AddLoad(LoadMassProportional(markerNumber=mm, loadVector=q))

    # clamp: all 6 coordinates (position + slope) of node 0 fixed to the reference
    ng = mbs.AddNode(NodePointGround(referenceCoordinates=[0.0, 0.0, 0.0]))
    mg = mbs.AddMarker(MarkerNodeCoordinate(nodeNumber=ng, coordinate=0))
    for j in range(6):
        mj = mbs.AddMarker(MarkerNodeCoordinate(nodeNumber=nodes[0], coordinate=j))
        mbs.AddObject(CoordinateConstraint(markerNumbers=[mg, mj]))

    mt = mbs.AddMarker(MarkerNodePosition(nodeNumber=nodes[-1]))
    mbs.AddLoad(LoadForceVector(markerNumber=mt, loadVector=f))
    return SC, mbs, nodes[-1]


def solve_cantilever(n_elements: int, length: float, EA: float, EI: float,
                     tip_force: tuple[float, float, float],
                     line_load: tuple[float, float, float] = (0, 0, 0),
                     base_axis=(1, 0, 0), *,
                     newton_tol: float = DEFAULT_NEWTON_TOL,
                     linear_solver: str = "sparse") -> dict:
    """Clamped-free straight cable (SI units: m, N, N/m; line_load in N/m) along base_axis
    from the origin. Builds the Exudyn model, solves the static equilibrium (full Newton,
    increment tolerance ``newton_tol``, tight enough for 1e-9 relative tip accuracy) and returns
    {"tip": ndarray(3) [m], "build_s": float, "solve_s": float, "newton_iterations": int}.

    build_s: creation of SystemContainer/MainSystem, all nodes/objects/markers/loads and
             ``mbs.Assemble()``.
    solve_s: the single call ``mbs.SolveStatic(settings)`` (solver initialisation, Newton
             iterations with Jacobian assembly/factorisation). Creating the
             SimulationSettings object and reading the tip position are in neither.
    newton_iterations: total Newton steps over all load steps (``it.newtonStepsCount``).
    Raises exudyn.SolverError (after Exudyn prints a diagnostic) if Newton fails.
    """
    _require()
    settings = _settings(newton_tol, linear_solver)

    t0 = time.perf_counter()
    SC, mbs, tip_node = _build(n_elements, length, EA, EI, tip_force, line_load, base_axis)
    mbs.Assemble()
    t1 = time.perf_counter()
    mbs.SolveStatic(settings, storeSolver=True, autoAssemble=False)
    t2 = time.perf_counter()

    tip = np.array(mbs.GetNodeOutput(tip_node, _exu.OutputVariableType.Position), dtype=float)
    iters = None
    try:
        iters = int(mbs.sys["staticSolver"].it.newtonStepsCount)
    except Exception:  # pragma: no cover - API drift
        pass
    del SC  # keep the container alive until here (mbs belongs to it)
    return {"tip": tip, "build_s": t1 - t0, "solve_s": t2 - t1, "newton_iterations": iters}


def time_solve(n_elements: int, length: float, EA: float, EI: float,
               tip_force: tuple[float, float, float],
               line_load: tuple[float, float, float] = (0, 0, 0),
               base_axis=(1, 0, 0), repeats: int = 50, warmup: int = 1, **kw) -> dict:
    """Median build and solve times [s] over ``repeats`` fresh build+solve runs (after
    ``warmup`` untimed runs). Returns {"build_s", "solve_s" (medians), "build_s_min",
    "solve_s_min", "tip" (last run), "newton_iterations", "repeats"}."""
    _require()
    if repeats < 1:
        raise ValueError("repeats must be >= 1")
    args = (n_elements, length, EA, EI, tip_force, line_load, base_axis)
    for _ in range(max(0, int(warmup))):
        solve_cantilever(*args, **kw)
    builds, solves, res = [], [], None
    for _ in range(int(repeats)):
        res = solve_cantilever(*args, **kw)
        builds.append(res["build_s"])
        solves.append(res["solve_s"])
    return {"build_s": statistics.median(builds), "solve_s": statistics.median(solves),
            "build_s_min": min(builds), "solve_s_min": min(solves),
            "tip": res["tip"], "newton_iterations": res["newton_iterations"],
            "repeats": int(repeats)}


if __name__ == "__main__":  # pragma: no cover - manual benchmark
    if not available():
        raise SystemExit("exudyn not available")
    L, EA, EI = 0.16, 767.2, 0.0839
    for n in (6, 12):
        r = time_solve(n, L, EA, EI, (0.0, 0.0, -0.49), repeats=50)
        print(f"n={n:3d}  build median {r['build_s']*1e3:8.3f} ms  "
              f"solve median {r['solve_s']*1e3:8.3f} ms  newton={r['newton_iterations']}  "
              f"tip={np.array2string(r['tip'], precision=12)}")


def simulate_cantilever(n_elements: int, length: float, EA: float, EI: float, line_mass: float,
                        gravity=(0.0, 0.0, -9.81), *, t_end: float, dt: float, rho_inf: float = 0.9,
                        newton_tol: float = 1e-10, base_axis=(1, 0, 0)) -> dict:
    """The clamped-free cable (line mass m' [kg/m]) released from the straight reference at rest under
    ``gravity`` [m/s²], integrated with Exudyn's generalized-α (spectral radius ``rho_inf``) in fixed steps
    ``dt`` [s] to ``t_end`` [s].  Returns {"t" (N,) [s], "tip" (N, 3) [m], "build_s", "solve_s",
    "steps"}; solve_s is the single ``mbs.SolveDynamic`` call."""
    _require()
    nsteps = int(round(t_end / dt))
    s = _exu.SimulationSettings()
    s.linearSolver.solverType = _exu.LinearSolverType.EXUdense
    s.timeIntegration.verboseMode = 0
    s.timeIntegration.verboseModeFile = 0
    s.solution.file.write = False
    s.solution.sensors.writePeriod = dt
    s.show.computationTime = False
    s.timeIntegration.endTime = nsteps * dt
    s.timeIntegration.numberOfSteps = nsteps
    s.timeIntegration.generalizedAlpha.spectralRadius = float(rho_inf)
    s.timeIntegration.generalizedAlpha.computeInitialAccelerations = True
    s.timeIntegration.newton.useModifiedNewton = False
    s.timeIntegration.newton.relativeTolerance = float(newton_tol)
    s.timeIntegration.newton.absoluteTolerance = float(newton_tol)
    s.timeIntegration.adaptiveStep = False
    t0 = time.perf_counter()
    SC, mbs, tip_node = _build(n_elements, length, EA, EI, (0.0, 0.0, 0.0), gravity, base_axis,
                               line_mass=line_mass)
    sensor = mbs.AddSensor(SensorNode(nodeNumber=tip_node, storeInternal=True, writeToFile=False,
                                      outputVariableType=_exu.OutputVariableType.Position))
    mbs.Assemble()
    t1 = time.perf_counter()
    mbs.SolveDynamic(s, solverType=_exu.DynamicSolverType.GeneralizedAlpha)
    t2 = time.perf_counter()
    data = np.asarray(mbs.GetSensorStoredData(sensor), dtype=float)
    del SC
    return {"t": data[:, 0], "tip": data[:, 1:4], "build_s": t1 - t0, "solve_s": t2 - t1, "steps": nsteps}
