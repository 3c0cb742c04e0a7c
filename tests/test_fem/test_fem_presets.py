"""The geometry presets' table in fem_reference/presets.py is the program's output (default mesh, mixed element)."""

import re

import pytest

import fem_reference.presets as presets
from fem_reference import BellowsModel


@pytest.mark.slow
def test_the_documented_variant_table_is_the_programs_output():
    rows = re.findall(r'^"(\w+)"\s+(\d+)\s+([\d.]+)\s+([\d.]+)\s+([\d.]+)\s+(\d+)\s+([\d.]+)\s+([\d.]+)\s+([\d.]+)$',
                      presets.__doc__, re.M)
    assert [r[0] for r in rows] == list(presets.VARIANTS)
    for name, n, t, r_root, r_crest, ea, ei, d_a, d_eff in rows:
        geo = presets.paper_bellows(name)
        assert (geo.n_convolutions, geo.wall_thickness, geo.root_radius, geo.crest_radius) == pytest.approx(
            (int(n), float(t) * 1e-3, float(r_root) * 1e-3, float(r_crest) * 1e-3))
        rod = BellowsModel(geo, presets.paper_material(), "coarse").equivalent_rod()
        assert rod["EA"] == pytest.approx(float(ea), abs=0.5)
        assert rod["EI"] == pytest.approx(float(ei), abs=6e-6)
        assert rod["D_a"] * 1e3 == pytest.approx(float(d_a), abs=0.05)
        assert rod["D_eff"] * 1e3 == pytest.approx(float(d_eff), abs=0.05)
