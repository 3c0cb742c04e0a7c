"""Default tolerances scale with the problem size: every element count (1…200) and quadrature order (4…20)
the parameter validator accepts solves a standard case with default settings, and every shipped preset runs
the demo (including the locked case warm-started from the IK state)."""

import numpy as np
import pytest

from ancf import Model, presets
from ancf.cli import run_demo

STANDARD = dict(T=(2.0, 0.5, 1.0), p=30e3, F=(0.0, 0.0, -0.3))


def solve_standard(n, nq, full=True):
    m = Model(presets.paper().replace(n_elements=n, quadrature_points=nq))
    ref = m.fk(STANDARD["T"], STANDARD["p"], STANDARD["F"])
    assert ref.residual_norm < m.default_tol and ref.stable
    if full:
        ik = m.ik(ref.tip, STANDARD["p"], STANDARD["F"])
        assert np.allclose(ik.tensions, STANDARD["T"], atol=1e-5)
        lk = m.fk_locked(ref.tendon_lengths, STANDARD["p"], (0.0, 0.0, -0.5), q0=ref.q, tensions0=ref.tensions)
        assert lk.stable and np.all(lk.tensions >= 0)
    return m, ref


@pytest.mark.parametrize("n, nq, full", [(1, 4, True), (1, 20, True), (3, 13, True), (17, 7, True),
                                         (60, 5, True), (200, 4, False)])
def test_every_accepted_size_solves_the_standard_case(n, nq, full):
    solve_standard(n, nq, full)


@pytest.mark.slow
@pytest.mark.parametrize("n, nq", [(120, 20), (200, 4), (200, 20)])
def test_largest_sizes_solve_all_modes(n, nq):
    solve_standard(n, nq, True)


def test_default_tolerance_grows_with_the_element_count_above_the_round_off_floor():
    tols = [Model(presets.paper().replace(n_elements=n)).default_tol for n in (1, 6, 50, 200)]
    assert tols == sorted(tols) and tols[1] < 1.2e-9 and tols[3] > 100 * tols[1]
    # the tip converges with the mesh at these tolerances (no noise from a loose tolerance)
    tips = [solve_standard(n, 5, False)[1].tip for n in (20, 40, 80)]
    assert np.linalg.norm(tips[2] - tips[1]) < np.linalg.norm(tips[1] - tips[0]) + 1e-9


@pytest.mark.parametrize("name", ["paper", "paper_constant", "four_tendon"])
def test_every_shipped_preset_runs_the_demo(name):
    model = Model(presets.get(name))
    rows = run_demo(model)
    assert [r["case"] for r in rows] == ["droop", "bend", "ik", "locked"]
    locked = rows[-1]["eq"]
    assert locked.stable and np.all(locked.tensions >= 0) and np.all(locked.slack >= 0)
    # the locked state under the extra load keeps the IK state's tendon lengths where taut
    for i in locked.active:
        assert abs(locked.tendon_lengths[i] - rows[2]["eq"].tendon_lengths[i]) < 1e-9
