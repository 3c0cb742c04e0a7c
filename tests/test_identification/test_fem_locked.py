"""The FEM's locked-tendon compliance used by the validation (all tendons locked, taut set by the same
complementarity rule as the reduced model's exact locked compliance) against a nonlinear locked solve.

With every cable locked at its current length and a small tip force ε u, the tip moves by C u ε + O(ε²)
(one-sided: a slack cable may become taut in one direction of the load and not in the other)."""

import numpy as np
import pytest

pytest.importorskip("skfem")

from fem_reference import BellowsModel, MeshLevel, presets  # noqa: E402
from validation.reference.fem_sweep import locked_compliance  # noqa: E402

TINY = MeshLevel(2, 1, 12, 1)


@pytest.fixture(scope="module")
def model():
    return BellowsModel(presets.paper_bellows(), presets.paper_material(), TINY)


@pytest.mark.parametrize("T1", [0.0, 1.0])
def test_locked_compliance_matches_a_locked_nonlinear_solve(model, T1):
    res = model.solve(tensions=(T1, 0.0, 0.0), pressure=20e3, gravity=True)
    u = np.array([0.0, 0.0, -1.0])
    C, active = locked_compliance(model, res, u)
    eps = 2e-3
    loaded = model.solve(tensions=(T1, 0.0, 0.0), pressure=20e3, gravity=True, tip_force=tuple(eps * u),
                         locked_lengths=[float(x) for x in res.tendon_lengths], initial=res, n_steps=1)
    fd = (loaded.tip_position - res.tip_position) / eps
    assert np.linalg.norm(fd - C @ u) < 2e-3 * np.linalg.norm(C @ u)
    # the locked tendons that took up load are exactly the active set
    taut = [i for i in range(3) if loaded.tensions[i] > 1e-9]
    assert sorted(taut) == sorted(active)
    # locking stiffens: never more compliant than with tensions held
    Ct = model.tip_compliance(res, "tension")
    assert u @ C @ u <= u @ Ct @ u * (1 + 1e-9)
