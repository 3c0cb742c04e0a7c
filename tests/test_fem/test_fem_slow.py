"""Heavier FEM checks (run with ``pytest -m slow``)."""

import numpy as np
import pytest

from fem_reference import BellowsModel, MeshLevel, presets

pytestmark = pytest.mark.slow


def test_tip_compliance_mesh_convergence_rate():
    """Vertical tip compliance of the paper bellows under refinement along the profile and around:
    successive differences shrink with an observed order > 1.5 (log-log fit of |C_h - C_{h/2}|)."""
    geo = presets.paper_bellows()
    vals = []
    ns = [2, 4, 8]
    for n in ns:
        M = BellowsModel(geo, presets.paper_material(), MeshLevel(n, 1, 6 * n, 1))
        vals.append(M.tip_compliance(M.solve())[2, 2])
    d = np.abs(np.diff(vals))
    rate = np.log(d[0] / d[1]) / np.log(2.0)
    assert rate > 1.5, (vals, rate)


def test_examples_run(tmp_path):
    import importlib.util
    import pathlib

    root = pathlib.Path(__file__).resolve().parents[2] / "examples"
    for name, argv in (("fem_quickstart.py", ["--mesh", "coarse", "--out", str(tmp_path / "fem")]),
                       ("fem_locked_stiffness.py", ["--quick"])):
        spec = importlib.util.spec_from_file_location(name[:-3], root / name)
        mod = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(mod)
        out = mod.main(argv)
        assert out is not None
