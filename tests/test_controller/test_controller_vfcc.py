"""VF-CC baseline: its residual follows its control law, e* = (I + C_L χ)⁻¹ C_L F."""

import numpy as np
import pytest

from ancf import compliance as cp
from controller import VFCC, SimulatedPlant, run_iterations
from hardware.errors import LimitError

P = 60e3
TENSIONS = (2.5, 2.2, 2.2)


@pytest.fixture(scope="module")
def target(paper_model):
    return paper_model.fk(TENSIONS, P, (0, 0, 0)).tip


@pytest.mark.parametrize("chi", [10.0, 100.0])
def test_proportional_residual_matches_fixed_point(paper_model, target, chi):
    m = paper_model
    F = np.array([0.0, 0.0, -0.2])                       # ≈ 20 g: small, so the law is nearly linear
    ctrl = VFCC(m, P, chi=chi, tolerance=0.0)
    res = run_iterations(ctrl, SimulatedPlant(m, P, load=F), target, iterations=25)
    eq = m.ik(target, P, ctrl.estimate, q0=ctrl.state.q, tensions0=ctrl.state.tensions)
    lk = m.fk_locked(eq.tendon_lengths, P, F, q0=eq.q, tensions0=eq.tensions)
    CL = cp.locked(m, lk, method="exact", load_direction=F).C_p
    e_pred = np.linalg.solve(np.eye(3) + CL * chi, CL @ F)
    assert np.linalg.norm(e_pred) > 2e-4
    assert res.final_error == pytest.approx(np.linalg.norm(e_pred), rel=0.05)
    # the larger gain leaves the smaller residual, but never removes it
    assert res.final_error > 0.2 * res.errors[0] / (1 + chi * np.max(np.diag(CL)))


def test_residual_scales_with_the_load(paper_model, target):
    m = paper_model
    out = []
    for F in (np.array([0, 0, -0.15]), np.array([0, 0, -0.3])):
        res = run_iterations(VFCC(m, P, tolerance=0.0), SimulatedPlant(m, P, load=F), target, iterations=6)
        out.append(res.final_error)
    assert out[1] / out[0] == pytest.approx(2.0, rel=0.1)


def test_integral_variant_converges_slowly_and_chi_in_N_per_mm_is_unstable(paper_model, target):
    m = paper_model
    F = np.array([0, 0, -0.3])
    res = run_iterations(VFCC(m, P, law="integral", tolerance=0.0), SimulatedPlant(m, P, load=F), target,
                         iterations=4)
    assert res.errors[-1] < res.errors[0]
    assert res.errors[-1] > 0.5 * res.errors[0]              # loop gain C_L χ ≈ 0.05 per step
    # χ = 10 N/mm = 1e4 N/m: |1 − C_L χ| > 1, the error grows — or the virtual force saturates the tensions
    # and the nearest reachable state is a jump the rig's step limit refuses (a typed LimitError)
    try:
        res = run_iterations(VFCC(m, P, chi=1e4, tolerance=0.0), SimulatedPlant(m, P, load=F), target,
                             iterations=2)
        assert res.errors[-1] > res.errors[0]
    except LimitError as exc:
        assert "largest step" in str(exc)
