"""FEM fail-fast: loads outside the stated operating limits are rejected before any load step (with an
explicit override), a failing solve stops within a bounded number of load steps or a time bound, and
importing the FEM reference loads neither numba nor the ANCF model."""

import subprocess
import sys
import time

import numpy as np
import pytest

from ancf.errors import ConfigError, ConvergenceError, InputError, LimitError
from fem_reference import (
    BellowsGeometry,
    BellowsModel,
    Material,
    MeshLevel,
    OperatingLimits,
)


@pytest.fixture(scope="module")
def tiny():
    return BellowsModel(BellowsGeometry.straight_tube(0.08, 0.015, 0.004, n_segments=2),
                        Material.neo_hookean(0.8e6, 40e6), MeshLevel(2, 1, 12, 1))


@pytest.mark.parametrize("loads, what", [
    (dict(pressure=30e6), "pressure"),                       # 30 000 kPa: a unit slip
    (dict(pressure=-1e6), "pressure"),
    (dict(tensions=(200.0, 0, 0)), "tension"),
    (dict(tip_force=(0, 0, -50.0)), "tip force"),
    (dict(locked_lengths=(0.01, None, None)), "locked length"),
])
def test_loads_outside_the_limits_are_rejected_before_any_step(tiny, loads, what):
    t0 = time.perf_counter()
    with pytest.raises(LimitError, match=what) as info:
        tiny.solve(**loads)
    assert "check_limits=False" in str(info.value)
    assert time.perf_counter() - t0 < 1.0                      # no load step was tried


def test_limits_are_stated_and_can_be_overridden(tiny):
    lim = OperatingLimits()
    assert lim.pressure_max == 200e3 and lim.tension_max == 20.0 and lim.tip_force_max == 10.0
    res = tiny.solve(tensions=(25.0, 0, 0), check_limits=False, n_steps=1)   # beyond the limit, on purpose
    assert res.tensions[0] == 25.0
    strict = BellowsModel(tiny.geometry, tiny.material, tiny.bmesh, limits=OperatingLimits(tension_max=0.1))
    with pytest.raises(LimitError):
        strict.solve(tensions=(0.2, 0, 0))


def test_a_failing_solve_stops_within_its_step_and_time_bounds(tiny):
    # 1000 N on one tendon asks for hundreds of load steps (one per 3 N): stop after max_steps
    t0 = time.perf_counter()
    with pytest.raises(ConvergenceError, match="max_steps = 3"):
        tiny.solve(tensions=(1000.0, 0, 0), check_limits=False, max_steps=3)
    with pytest.raises(ConvergenceError, match="time_limit_s"):
        tiny.solve(tensions=(1000.0, 0, 0), check_limits=False, time_limit_s=1e-6)
    assert time.perf_counter() - t0 < 120


def test_bad_solver_options_and_inputs_are_typed_errors(tiny):
    for kw in (dict(max_steps=0), dict(rtol=0.0), dict(max_iter=2.5), dict(time_limit_s=-1.0),
               dict(pressure="30e3"), dict(tensions=(1.0, 2.0)), dict(tip_force=(0, np.nan, 0)),
               dict(locked_lengths=("a", None, None))):
        with pytest.raises(InputError):
            tiny.solve(**kw)
    with pytest.raises(ConfigError):
        Material.neo_hookean("0.8", 40e6)
    with pytest.raises(ConfigError):
        BellowsGeometry.straight_tube("0.08", 0.015, 0.004)
    with pytest.raises(InputError):
        BellowsModel("tube", Material.neo_hookean(0.8e6, 40e6))
    for fn in (tiny.tip_compliance, tiny.cap_compliance, tiny.equivalent_rod):
        with pytest.raises(InputError, match="same BellowsModel"):
            fn("not a result")


def test_importing_the_fem_reference_loads_no_numba_and_no_ancf_model():
    code = ("import sys, fem_reference, validation.commands.fem; "
            "bad = [m for m in sys.modules if m.split('.')[0] == 'numba' or m in ('ancf.model', 'ancf.assembly')]; "
            "print(bad)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "[]"
