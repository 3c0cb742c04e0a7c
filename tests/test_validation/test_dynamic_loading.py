"""The quasi-static-vs-dynamic loading study (validation.dynamic_studies): on a slow loop (the paper's:
5 mm/s motors, 100 ms settle) the dynamic plant changes LACC's error little; on a fast loop (50 mm/s,
20 ms settle) quasi-static LACC corrects on the ringing of the locked first mode and does worse than on the
static plant — the measurement docs/dynamics.md reports.  Also the dynamic plant's uncontrolled motion is
amplified near resonance as a damped oscillator's is."""

import math

import pytest

from ancf.errors import InputError
from validation.dynamic_studies import dynamic_loading


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


@pytest.mark.slow
def test_the_documented_table_is_the_programs_output():
    """docs/dynamics.md's table (both loops, 0.125 … 2 Hz) rerun: the study is deterministic (fixed compute
    time, no noise), so every number must come back to its two decimals (~4 min)."""
    import pathlib
    import re
    text = (pathlib.Path(__file__).parents[2] / "docs" / "dynamics.md").read_text()
    rows = re.findall(r"^\| (slow|fast) \| ([\d.]+) \| ([\d.]+) \| ([\d.]+) \| ([\d.]+) \| ([\d.]+) \|$", text, re.M)
    assert len(rows) == 10
    runs = {"slow": dynamic_loading(),
            "fast": dynamic_loading(motor_rate=0.05, settle_time=0.02, compute_time=0.002, actuation_latency=0.005)}
    for loop, f, *vals in rows:
        row = next(r for r in runs[loop]["rows"] if r["frequency_Hz"] == float(f))
        got = [row["static_max_mm"], row["dynamic_max_mm"], row["uncontrolled_static_mm"], row["uncontrolled_dynamic_mm"]]
        assert [float(v) for v in vals] == pytest.approx(got, abs=0.006), (loop, f)
