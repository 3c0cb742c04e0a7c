"""The compiled output rows of a transient run (ancf.dynamics.compiled_step) against the Python path they
replace: the same trajectories, tensions, energies, Newton iterations and events to round-off on several load
cases (tensions, locked and slackening length springs with a holding force, a pressure supply with its time
constant, a tip force with Rayleigh and axial damping, the tool-point inertia of the `paper` actuator, a refined
run's substeps, halved steps); errors raised where the Python path raises them; Ctrl-C still prompt; the
kernel's inputs checked at its boundary.  Each comparison also asserts that the compiled rows were used."""

import os
import signal
import threading
import time
import warnings

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from ancf import Model, presets
from ancf.dynamics import compiled_step as cs
from ancf.dynamics import transient as tr
from ancf.errors import BellowsError, LimitError

P30 = 30e3
_PAPER = Model(presets.paper())


@pytest.fixture(scope="module")
def paper():
    return Model(presets.paper())


@pytest.fixture(scope="module")
def springy():
    return Model(presets.paper().replace(tendon_stiffness=2000.0))


@pytest.fixture
def kernel_rows(monkeypatch):
    """Counts the rows the compiled kernel made (a comparison that never reached it would prove nothing)."""
    count = {"rows": 0}
    orig = tr._FastRows.run

    def spy(self, i, *a):
        j, st, pr = orig(self, i, *a)
        count["rows"] += j - i
        return j, st, pr
    monkeypatch.setattr(tr._FastRows, "run", spy)
    return count


def both_paths(monkeypatch, model, *args, **kw):
    """(the Python path's run, the compiled rows' run) of the same call."""
    out = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for flag in (False, True):
            monkeypatch.setattr(tr, "COMPILED_ROWS", flag)
            out.append(model.simulate(*args, **kw))
    return out


def assert_same_run(ref, fast):
    def rel(a, b):
        return float(np.abs(a - b).max()) / max(float(np.abs(a).max()), 1e-300)
    assert len(ref.t) == len(fast.t)
    for name in ("q", "v", "tip", "tensions", "pressure"):
        a, b = getattr(ref, name), getattr(fast, name)
        assert rel(a, b) <= 1e-10 or float(np.abs(a - b).max()) <= 1e-14, name
    # energies: round-off of sums of terms of the size of the potential
    scale = max(float(np.abs(ref.potential).max()), float(np.abs(ref.kinetic).max()), 1e-12)
    for name in ("energy", "kinetic", "potential", "work", "dissipated"):
        assert float(np.abs(getattr(ref, name) - getattr(fast, name)).max()) <= 1e-10 * scale, name
    assert np.array_equal(ref.newton_iterations, fast.newton_iterations)
    assert [(e["kind"], e["tendon"], e["t"]) for e in ref.events] == \
           [(e["kind"], e["tendon"], e["t"]) for e in fast.events]


def test_a_tension_step_with_the_tool_point_inertia(paper, monkeypatch, kernel_rows):
    start = paper.fk((0.0, 0.0, 0.0), P30)
    assert paper.params.tip_mass > 0 and paper.params.tool_offset > 0      # the tool point's inertia is in
    ref, fast = both_paths(monkeypatch, paper, 0.15, 1e-3, q0=start.q, tensions=(2, 0, 0), pressure=P30,
                           damping=0.05)
    assert_same_run(ref, fast)
    assert kernel_rows["rows"] == len(fast.t) - 1


def test_a_tip_force_with_rayleigh_and_axial_damping(paper, monkeypatch, kernel_rows):
    eq = paper.fk((2.0, 0.0, 0.0), P30)
    ref, fast = both_paths(monkeypatch, paper, 0.1, 1e-3, q0=eq.q, tensions=(2, 0, 0), pressure=P30,
                           tip_force=(0.0, 0.1, -0.3), damping={"alpha": 2.0, "beta": 1e-4, "axial": 0.05})
    assert_same_run(ref, fast)
    assert fast.dissipated[-1] > 0 and kernel_rows["rows"] == len(fast.t) - 1


def test_a_pressure_supply_with_its_time_constant(paper, monkeypatch, kernel_rows):
    eq = paper.fk((2.0, 0.0, 0.0), P30)
    ref, fast = both_paths(monkeypatch, paper, 0.1, 1e-3, q0=eq.q, tensions=(2, 0, 0), pressure=50e3,
                           pressure_tau=0.02, pressure0=P30, damping=0.05)
    assert_same_run(ref, fast)
    assert fast.pressure[-1] > 45e3 and abs(fast.work[-1]) > 0 and kernel_rows["rows"] == len(fast.t) - 1


def test_locked_length_springs_under_a_tip_force(springy, monkeypatch, kernel_rows):
    eq = springy.fk((2.0, 1.0, 1.0), P30)
    ref, fast = both_paths(monkeypatch, springy, 0.1, 2e-3, q0=eq.q, lengths=springy.rest_lengths(eq),
                           pressure=P30, tip_force=(0.0, 0.0, -0.4), damping=0.3)
    assert_same_run(ref, fast)
    assert kernel_rows["rows"] == len(fast.t) - 1


def test_a_slack_tendon_and_an_overpowered_motor_change_state(springy, monkeypatch, kernel_rows):
    eq = springy.fk((2.0, 1.0, 1.0), P30)
    l0 = springy.rest_lengths(eq) + np.array([3e-3, 0.0, -1.5e-3])
    ref, fast = both_paths(monkeypatch, springy, 0.1, 2e-3, q0=eq.q, lengths=l0, pressure=P30, damping=0.1,
                           holding_force=3.5)
    assert_same_run(ref, fast)
    kinds = {e["kind"] for e in fast.events}
    assert kinds & {"slack", "taut"} and kinds & {"overpowered", "holding"}
    assert kernel_rows["rows"] >= len(fast.t) - 1         # a refined run makes rows more than once


def test_a_refined_run_and_halved_steps(paper, monkeypatch, kernel_rows):
    """The energy check's refinement (substeps inside a row) and halvings (max_iter = 3 makes the first steps
    fail: those rows run in Python, the rest compiled)."""
    start = paper.fk((0.0, 0.0, 0.0), P30)
    ref, fast = both_paths(monkeypatch, paper, 0.1, 2e-2, q0=start.q, tensions=(2, 0, 0), pressure=P30,
                           damping=0.0)
    assert_same_run(ref, fast)
    assert [e["kind"] for e in fast.events].count("refined") >= 1 and kernel_rows["rows"] > 0
    kernel_rows["rows"] = 0
    ref, fast = both_paths(monkeypatch, paper, 0.1, 2e-3, q0=start.q, tensions=(2, 0, 0), pressure=P30,
                           damping=0.05, max_iter=3)
    assert_same_run(ref, fast)
    assert "subdivided" in {e["kind"] for e in fast.events}
    assert 0 < kernel_rows["rows"] < len(fast.t) - 1


def test_the_supply_overshooting_the_limits_raises_as_before(paper, monkeypatch):
    eq = paper.fk((2.0, 0.0, 0.0), P30)
    msgs = []
    for flag in (False, True):
        monkeypatch.setattr(tr, "COMPILED_ROWS", flag)
        with pytest.raises(LimitError) as exc, warnings.catch_warnings():
            warnings.simplefilter("ignore")
            paper.simulate(0.05, 0.01, q0=eq.q, tensions=(2, 0, 0), pressure=paper.params.pressure_max,
                           pressure_tau=1e-3, pressure0=0.0, damping=0.05)
        msgs.append(str(exc.value))
    assert msgs[0] == msgs[1] and "t = 0.01 s" in msgs[1]


def test_a_tension_ramp_and_a_sine_take_the_compiled_rows(paper, monkeypatch, kernel_rows):
    """Tensions as functions of time (a ramp on tendon 1, a sine on tendon 2) with a time-varying tip force: the
    signals sampled on the step grid give the Python path's run (work of the loads included)."""
    eq = paper.fk((2.0, 0.0, 0.0), P30)
    T = lambda t: (2.0 + 10.0 * min(t, 0.05), 0.5 + 0.5 * np.sin(2 * np.pi * 20.0 * t), 0.0)
    F = lambda t: (0.0, 0.0, -0.2 * min(t / 0.04, 1.0))
    ref, fast = both_paths(monkeypatch, paper, 0.08, 1e-3, q0=eq.q, tensions=T, pressure=P30, tip_force=F,
                           damping=0.05)
    assert_same_run(ref, fast)
    assert abs(fast.work[-1]) > 1e-4 and fast.tensions[-1, 0] == pytest.approx(2.5)
    assert kernel_rows["rows"] == len(fast.t) - 1


def test_a_tension_table_in_a_refined_run(paper, monkeypatch, kernel_rows):
    """A table signal (interpolated) sampled at the substeps of a run the energy check refines (substeps h/2^k
    inside each row: the load table holds every substep end)."""
    start = paper.fk((0.0, 0.0, 0.0), P30)
    table = ([0.0, 0.05, 0.1], [[2.0, 0.0, 0.0], [2.0, 0.0, 0.0], [2.0, 1.0, 0.0]])
    ref, fast = both_paths(monkeypatch, paper, 0.1, 2e-2, q0=start.q, tensions=table, pressure=P30, damping=0.0)
    assert_same_run(ref, fast)
    assert "refined" in {e["kind"] for e in fast.events} and kernel_rows["rows"] > 0


def test_motor_lengths_as_the_dynamic_rig_drives_them(springy, monkeypatch, kernel_rows):
    """Motor lengths moving linearly between records (as hardware.sim_dynamics passes them), a tip load
    function, the pressure supply, a holding force: the same run on both paths."""
    eq = springy.fk((2.0, 1.0, 1.0), P30)
    l0 = springy.rest_lengths(eq)
    lengths = lambda t: l0 + np.array([-4e-3, 1e-3, 2e-3]) * min(t / 0.03, 1.0)
    ref, fast = both_paths(monkeypatch, springy, 0.06, 1e-3, q0=eq.q, lengths=lengths, pressure=40e3,
                           pressure_tau=0.01, pressure0=P30, tip_force=lambda t: (0.0, 0.0, -0.3 * (t > 0.02)),
                           damping={"alpha": 5.0}, holding_force=6.0, rho_inf=0.6)
    assert_same_run(ref, fast)
    assert kernel_rows["rows"] == len(fast.t) - 1 and fast.pressure[-1] > 38e3


def test_a_pressure_ramp_with_a_pressure_dependent_law(monkeypatch, kernel_rows):
    """EA, EI scaled by f(p) while the pressure command ramps through the supply (τ): the law's factors on the
    load table, the potential's p-dependent parts in the rows (work of the loads)."""
    law = presets.paper().stiffness.with_pressure(EA=(0.3,), EI=(0.9,))
    m = Model(presets.paper().replace(stiffness=law))
    eq = m.fk((2.0, 0.0, 0.0), 0.0)
    ref, fast = both_paths(monkeypatch, m, 0.08, 1e-3, q0=eq.q, tensions=(2.0, 0.0, 0.0),
                           pressure=lambda t: 60e3 * min(t / 0.04, 1.0), pressure_tau=0.01, pressure0=0.0,
                           damping={"alpha": 20.0})
    assert_same_run(ref, fast)
    assert abs(fast.work[-1]) > 1e-4 and kernel_rows["rows"] == len(fast.t) - 1
    held = both_paths(monkeypatch, m, 0.03, 1e-3, q0=eq.q, tensions=(2.0, 0.0, 0.0), pressure=50e3,
                      damping={"alpha": 20.0})
    assert_same_run(*held)


def test_a_signal_failing_between_output_rows_raises_as_before(paper, monkeypatch):
    """Signals that are bad only between two output rows (0.04 s < t < 0.06 s at dt = 20 ms: the grid's check
    up front passes) in a run the energy check refines (substeps between the rows): a negative tension, a NaN, a
    pressure over the actuator's limit — the same typed error naming the same time (a substep's) on both paths."""
    start = paper.fk((0.0, 0.0, 0.0), P30)
    bad = lambda t: 0.041 < t < 0.059
    cases = ({"tensions": lambda t: (-1.0 if bad(t) else 2.0, 0.0, 0.0), "pressure": P30},
             {"tensions": lambda t: (np.nan if bad(t) else 2.0, 0.0, 0.0), "pressure": P30},
             {"tensions": (2, 0, 0), "pressure": lambda t: 1e6 if bad(t) else P30})
    for kw in cases:
        msgs = []
        for flag in (False, True):
            monkeypatch.setattr(tr, "COMPILED_ROWS", flag)
            with pytest.raises(BellowsError) as exc, warnings.catch_warnings():
                warnings.simplefilter("ignore")
                paper.simulate(0.1, 2e-2, q0=start.q, damping=0.0, **kw)
            msgs.append((type(exc.value), str(exc.value)))
        assert msgs[0] == msgs[1]
        assert 0.04 < float(msgs[1][1].split("t = ")[1].split(" s")[0]) < 0.06        # a substep off the grid


def test_progress_is_reported_for_every_row_in_order(paper):
    eq = paper.fk((2.0, 0.0, 0.0), P30)
    seen = []
    sim = paper.simulate(0.05, 1e-3, q0=eq.q, tensions=(2, 0, 0), pressure=P30, damping=0.05,
                         progress=lambda t, t_end: seen.append(t))
    assert np.array_equal(np.array(seen), sim.t[1:])


@pytest.mark.skipif(os.name != "posix", reason="SIGINT to the own process")
def test_ctrl_c_ends_a_compiled_run_promptly(paper, python_sigint):
    """A long run (6·10⁴ steps, seconds even at 20× real time) interrupted after 0.3 s returns the rows done within
    0.2 s of the Ctrl-C."""
    if threading.current_thread() is not threading.main_thread():
        pytest.skip("signal handlers need the main thread")
    eq = paper.fk((2.0, 0.0, 0.0), P30)
    paper.simulate(0.01, 1e-3, q0=eq.q, tensions=(2, 0, 0), pressure=P30, damping=0.05)      # kernels loaded
    sent = {}

    def interrupt():
        sent["t"] = time.perf_counter()
        os.kill(os.getpid(), signal.SIGINT)
    timer = threading.Timer(0.3, interrupt)
    timer.start()
    try:
        sim = paper.simulate(60.0, 1e-3, q0=eq.q, tensions=(2, 0, 0), pressure=P30, damping=0.05)
    finally:
        timer.cancel()
    latency = time.perf_counter() - sent["t"]
    assert sim.interrupted and 1 < len(sim.t) < 60_001
    assert latency < 0.2, latency


def test_the_kernel_inputs_are_checked_at_its_boundary():
    m = 3
    nz, ndof = 36, 42
    arr = [np.zeros(ndof), np.zeros((1, 1)), np.zeros((5, 3, 4)), np.zeros(5), np.zeros(2), np.zeros(2),
           np.zeros(2), np.zeros(3), np.eye(3), np.zeros(m), np.zeros(m), np.zeros(m), np.zeros((ndof, ndof)),
           np.zeros((nz, nz)), np.zeros((nz, nz)), np.zeros(m), np.ones(m), np.zeros(3), np.zeros(3), np.zeros(3)]
    par, state, prev = np.zeros(cs.N_PAR), np.zeros((5, nz)), np.zeros(cs.N_PREV + m)
    cs.check_inputs(tuple(arr), par, state, prev, nz, m)
    bad = list(arr)
    bad[13] = np.zeros((nz, nz), dtype=np.float32)
    with pytest.raises(TypeError):
        cs.check_inputs(tuple(bad), par, state, prev, nz, m)
    bad = list(arr)
    bad[15] = np.zeros(m + 1)
    with pytest.raises(ValueError):
        cs.check_inputs(tuple(bad), par, state, prev, nz, m)
    with pytest.raises(ValueError):
        cs.check_inputs(tuple(arr), par, np.zeros((5, nz + 1)), prev, nz, m)
    par[cs.P_H] = np.nan
    with pytest.raises(ValueError):
        cs.check_inputs(tuple(arr), par, state, prev, nz, m)


def test_the_tool_point_inertia_kernel_is_the_mass_modules():
    """The kernels call ancf.dynamics.mass.tool_point_inertia itself (one allocation-free implementation); its
    complex-step derivatives ∂f/∂s, ∂f/∂v_s match central finite differences of its force, and its mass block is
    ∂f/∂(x_r, x_s) (f is linear in the accelerations)."""
    from ancf.dynamics.mass import tool_point_inertia
    assert cs.tool_point_inertia is tool_point_inertia
    rng = np.random.default_rng(3)
    h_fd = 1e-6
    for _ in range(5):
        s, vs, xr, xs = (rng.normal(size=3) for _ in range(4))
        f, Ds, Dv, B = tool_point_inertia(s, vs, xr, xs, 0.005, 0.01)
        for j in range(3):
            e = np.eye(3)[j] * h_fd
            fd_s = (tool_point_inertia(s + e, vs, xr, xs, 0.005, 0.01)[0]
                    - tool_point_inertia(s - e, vs, xr, xs, 0.005, 0.01)[0]) / (2 * h_fd)
            fd_v = (tool_point_inertia(s, vs + e, xr, xs, 0.005, 0.01)[0]
                    - tool_point_inertia(s, vs - e, xr, xs, 0.005, 0.01)[0]) / (2 * h_fd)
            assert np.allclose(Ds[:, j], fd_s, rtol=1e-6, atol=1e-9 * float(np.abs(Ds).max()))
            assert np.allclose(Dv[:, j], fd_v, rtol=1e-6, atol=1e-9 * float(np.abs(Dv).max()))
        dx = rng.normal(size=6)
        f2 = tool_point_inertia(s, vs, xr + dx[:3], xs + dx[3:], 0.005, 0.01)[0]
        assert np.allclose(f2 - f, B @ dx, rtol=1e-12, atol=1e-15 * float(np.abs(f2 - f).max()))


@pytest.mark.parametrize("n, kl", [(36, 11), (37, 12), (20, 3), (8, 7)])
def test_the_banded_solve_is_gaussian_elimination(n, kl):
    """band_solve against np.linalg.solve on banded matrices, with row exchanges (small diagonal) and a singular
    matrix refused."""
    rng = np.random.default_rng(n)
    A = rng.normal(size=(n, n))
    i, j = np.indices((n, n))
    A[np.abs(i - j) > kl] = 0.0
    A[np.diag_indices(n)] *= 1e-3                       # pivoting needed
    b = rng.normal(size=n)
    ok, x = cs.band_solve(A, b, kl, kl)
    assert ok and np.allclose(x, np.linalg.solve(A, b), rtol=1e-9, atol=1e-9 * np.abs(x).max())
    A[:, 2] = 0.0
    assert not cs.band_solve(A, b, kl, kl)[0]


def test_the_free_base_stretch_coordinates(monkeypatch, kernel_rows):
    """q = q_fix + P z with the base stretch free (a band one wider, the velocities mapped by P)."""
    m = Model(presets.paper().replace(free_base_stretch=True))
    eq = m.fk((2.0, 0.0, 0.0), P30)
    ref, fast = both_paths(monkeypatch, m, 0.05, 1e-3, q0=eq.q, tensions=(2.5, 0.0, 0.0), pressure=P30,
                           tip_force=(0.0, 0.0, -0.2), damping={"alpha": 1.0, "beta": 1e-4, "axial": 0.02})
    assert_same_run(ref, fast)
    assert kernel_rows["rows"] == len(fast.t) - 1


@settings(max_examples=6, deadline=None)
@given(T=st.tuples(*[st.floats(0.0, 3.0)] * 3), p_kpa=st.floats(0.0, 60.0), Fz=st.floats(-0.3, 0.3),
       zeta=st.sampled_from([0.0, 0.05, 0.3]))
def test_any_constant_load_step_gives_the_python_paths_run(T, p_kpa, Fz, zeta):
    """Random constant loads stepped from the unloaded equilibrium at the same pressure: the compiled rows and the
    Python path give the same run (or the same typed error)."""
    m = _PAPER
    start = m.fk((0.0, 0.0, 0.0), p_kpa * 1e3)
    runs = []
    for flag in (False, True):
        tr.COMPILED_ROWS = flag
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                runs.append(m.simulate(0.02, 1e-3, q0=start.q, tensions=T, pressure=p_kpa * 1e3,
                                       tip_force=(0.0, 0.0, Fz), damping=zeta))
        except BellowsError as exc:
            runs.append((type(exc), str(exc)))
        finally:
            tr.COMPILED_ROWS = True
    if isinstance(runs[0], tuple) or isinstance(runs[1], tuple):
        assert runs[0] == runs[1]
    else:
        assert_same_run(*runs)
