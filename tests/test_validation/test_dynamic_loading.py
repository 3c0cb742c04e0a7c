"""The quasi-static-vs-dynamic loading study (validation.paper.dynamic): on a slow loop (the paper's:
5 mm/s motors, 100 ms settle) the dynamic plant changes LACC's error little; on a fast loop (50 mm/s,
20 ms settle) quasi-static LACC corrects on the ringing of the locked first mode and does worse than on the
static plant — the measurement docs/dynamics.md reports.  Also the dynamic plant's uncontrolled motion is
amplified near resonance as a damped oscillator's is."""

import math

import pytest

from ancf.errors import InputError
from validation.paper.dynamic import dynamic_loading


@pytest.fixture(scope="module")
def slow():
    return dynamic_loading(frequencies=(2.0,), cycles=3)["rows"][0]


@pytest.fixture(scope="module")
def fast():
    return dynamic_loading(frequencies=(2.0,), cycles=3, motor_rate=0.05, settle_time=0.02, compute_time=0.002,
                           actuation_latency=0.005)


def test_the_slow_loop_sees_little_of_the_inertia(slow):
    assert slow["dynamic_max_mm"] < 1.5 * slow["static_max_mm"]


def test_the_fast_loop_corrects_on_the_ringing(fast):
    row = fast["rows"][0]
    assert row["static_max_mm"] < 10.0                         # quasi-static LACC tracks on the static plant
    assert row["dynamic_max_mm"] > 1.5 * row["static_max_mm"]  # and not on the dynamic one


def test_the_free_dynamic_response_is_amplified_like_an_oscillator(fast):
    """Uncontrolled: the static plant follows the load m/2 (1 − cos ωt) (peak: the full amplitude A); the
    dynamic one passes the constant half unchanged and amplifies the cosine half by the first mode's
    G = 1/√((1 − r²)² + (2ζr)²), r = f/f₁: its peak is A (1 + G)/2 (the small shape nonlinearity aside)."""
    row, f1 = fast["rows"][0], fast["first_mode_Hz"]
    ratio = row["uncontrolled_dynamic_mm"] / row["uncontrolled_static_mm"]
    r = 2.0 / f1
    G = 1 / math.sqrt((1 - r * r) ** 2 + (2 * 0.1 * r) ** 2)
    assert ratio > 1.0
    assert ratio == pytest.approx((1 + G) / 2, rel=0.02)


def test_bad_study_inputs():
    with pytest.raises(InputError, match="frequencies"):
        dynamic_loading(frequencies=(0.0,))
    with pytest.raises(InputError, match="cycles"):
        dynamic_loading(frequencies=(1.0,), cycles=1)
    with pytest.raises(InputError, match="cyclic_mass"):
        dynamic_loading(frequencies=(1.0,), cyclic_mass=-0.1)
    # the dynamic LACC's options are refused before any run starts
    for kw, what in ((dict(model_error=0.7), "model_error"), (dict(observer_bandwidth_hz=0.0), "bandwidth"),
                     (dict(loop_latency=0.5), "latency"), (dict(internal_model=1), "internal_model")):
        with pytest.raises(InputError, match=what):
            dynamic_loading(frequencies=(1.0,), dynamic_lacc=True, **kw)


@pytest.mark.slow
def test_the_documented_controller_table_is_the_programs_output():
    """docs/dynamics.md's controller table (LACC, ZV-shaped LACC and the dynamic LACC without its internal model
    on the fast loop,
    0.5 … 4 Hz, the plant as the model and mismatched) rerun: deterministic (fixed compute time, seeded tracker
    noise), so the page's lines must come back as they are (~40 min on 2 cores)."""
    import pathlib
    from validation.paper.dynamic import CONTROLLER_TABLE_PLANTS, FAST_LOOP, controller_table
    text = (pathlib.Path(__file__).parents[2] / "docs" / "dynamics.md").read_text()
    runs = {label: dynamic_loading(frequencies=(0.5, 1.0, 2.0, 4.0), cycles=2, shaping=True, dynamic_lacc=True,
                                   mismatch=mismatch, internal_model=False, **FAST_LOOP)
            for label, mismatch in CONTROLLER_TABLE_PLANTS}
    for line in controller_table(runs):
        assert line in text, line


@pytest.mark.slow
def test_the_documented_internal_model_table_is_the_programs_output():
    """docs/dynamics.md's internal-model table (the dynamic LACC learning the load's frequency, on the
    mismatched dynamic plant: 1 Hz over 4 cycles, 2 Hz over 6) rerun: deterministic (seeded tracker noise), so
    the page's lines must come back as they are (~30 min on the shared 2 cores)."""
    import pathlib
    from validation.paper.dynamic import INTERNAL_MODEL_ROWS, internal_model_row, internal_model_table
    text = (pathlib.Path(__file__).parents[2] / "docs" / "dynamics.md").read_text()
    for line in internal_model_table([internal_model_row(f, c) for f, c in INTERNAL_MODEL_ROWS]):
        assert line in text, line


def test_internal_model_row_refuses_bad_inputs():
    from validation.paper.dynamic import internal_model_row
    with pytest.raises(InputError):
        internal_model_row(0.0, 3)
    with pytest.raises(InputError):
        internal_model_row(1.0, 1)


@pytest.mark.slow
def test_the_documented_table_is_the_programs_output():
    """docs/dynamics.md's table (both loops, 0.125 … 2 Hz) rerun: the study is deterministic (fixed compute
    time, no noise), so every number must come back to its two decimals (~6 min)."""
    import pathlib
    import re
    text = (pathlib.Path(__file__).parents[2] / "docs" / "dynamics.md").read_text()
    rows = re.findall(r"^\| (slow|fast) \| ([\d.]+) \| ([\d.]+) \| ([\d.]+) \| ([\d.]+|–) \| ([\d.]+) \| ([\d.]+) \|$",
                      text, re.M)
    assert len(rows) == 10
    runs = {"slow": dynamic_loading(),
            "fast": dynamic_loading(motor_rate=0.05, settle_time=0.02, compute_time=0.002, actuation_latency=0.005,
                                    shaping=True)}
    for loop, f, st, dy, zv, fs, fd in rows:
        row = next(r for r in runs[loop]["rows"] if r["frequency_Hz"] == float(f))
        assert [float(st), float(dy), float(fs), float(fd)] == pytest.approx(
            [row["static_max_mm"], row["dynamic_max_mm"], row["uncontrolled_static_mm"], row["uncontrolled_dynamic_mm"]],
            abs=0.006), (loop, f)
        assert (zv == "–") == (loop == "slow")
        if zv != "–":
            assert float(zv) == pytest.approx(row["shaped_max_mm"], abs=0.006), (loop, f)


def test_the_zv_shaper_leaves_a_damped_oscillator_at_rest():
    """Two steps A₁ (t = 0) and A₂ = 1 − A₁ (t = T_d/2) into x'' + 2ζωx' + ω²x = ω²u: no vibration after
    the second (closed form of the step response), while a single step keeps ringing."""
    from controller import zv_shaper
    f, z = 5.47, 0.1
    a1, delay = zv_shaper(f, z)
    w = 2 * math.pi * f
    wd = w * math.sqrt(1 - z * z)

    def step(t):                       # response to a unit step at t = 0 (zero for t < 0)
        t = max(t, 0.0)
        return 1 - math.exp(-z * w * t) * (math.cos(wd * t) + z * w / wd * math.sin(wd * t))

    times = [delay + k * 0.01 for k in range(1, 60)]
    shaped = [a1 * step(t) + (1 - a1) * step(t - delay) - 1 for t in times]
    single = [step(t) - 1 for t in times]
    assert max(abs(x) for x in shaped) < 1e-12
    assert max(abs(x) for x in single) > 0.1
    with pytest.raises(InputError):
        zv_shaper(5.0, 1.0)


def test_shaped_moves_restore_the_fast_loop_on_the_dynamic_plant():
    """The fast loop at 0.5 Hz: unshaped moves excite the first mode (worse than no control); ZV-shaped
    moves bring the error back within a few times the static plant's (measured 4.9 vs 38.7 vs 1.2 mm)."""
    row = dynamic_loading(frequencies=(0.5,), cycles=2, motor_rate=0.05, settle_time=0.02, compute_time=0.002,
                          actuation_latency=0.005, shaping=True)["rows"][0]
    assert row["dynamic_max_mm"] > row["uncontrolled_dynamic_mm"]
    assert row["shaped_max_mm"] < 0.3 * row["dynamic_max_mm"]
    assert row["shaped_max_mm"] < 6 * row["static_max_mm"]


def test_waiting_for_a_still_tip_settles_on_the_dynamic_plant():
    """settle_time='still': after each move the loop waits until the tip rings by less than the tolerance;
    under a constant hidden load LACC then converges in a few corrections."""
    from ancf import Model, presets
    from controller import LACC, run_timed
    from hardware import PlantOptions, SimulatedRig
    model = Model(presets.paper())
    target = model.fk((2.0, 1.0, 0.5), 30e3).tip
    rig = SimulatedRig(model, 30e3, load=(0, 0, -0.2), dynamics=True,
                       options=PlantOptions(damping=0.1, length_rate=0.05))
    r = run_timed(LACC(model, 30e3), rig, target, duration=3.0, compute_time=0.002, settle_time="still",
                  idle_period=0.1, sample_dt=0.02)
    assert r.corrections <= 4
    assert r.error_norm[-1] < 0.2e-3
    assert all(c[3] > 0.1 for c in r.cycle_times)             # it waited (a period is 0.18 s)
    with pytest.raises(InputError, match="settle_time"):
        run_timed(LACC(model, 30e3), rig, target, duration=1.0, settle_time="soon")
