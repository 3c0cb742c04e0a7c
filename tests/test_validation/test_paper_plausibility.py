"""The FEM of a Shore-50A bellows as judge of the readings (slow: runs the FEM reference)."""

import pytest

pytest.importorskip("skfem")

from validation.paper.plausibility import fem_equivalent_rods, reading_targets  # noqa: E402


@pytest.mark.slow
def test_thin_walled_bellows_meets_the_scaled_reading_not_the_unscaled():
    rows = {(r["variant"], r["wall_thickness_m"]): r for r in fem_equivalent_rods()}
    tgt = reading_targets()
    scaled_lo, scaled_hi = tgt["paper_scaled"]["EA_N"], tgt["paper_scaled_020"]["EA_N"]
    # a 2–3 mm wall brackets the length-scaled EA(1) with a pressure diameter near the paper's 26 mm
    thin = [rows[("deep", 0.003)], rows[("stiff", 0.002)]]
    assert all(0.8 * scaled_lo < r["EA_N"] < 1.2 * scaled_hi for r in thin)
    assert all(r["D_eff_m"] > 0.022 for r in thin)
    # the unscaled EA needs the 4 mm shallow bellows, whose D_eff is less than half the paper's
    thick = rows[("stiff", 0.004)]
    assert thick["EA_N"] == pytest.approx(tgt["paper_unscaled"]["EA_N"], rel=0.1)
    assert thick["D_eff_m"] < 0.5 * tgt["paper_unscaled"]["D_eff_m"]
    # EA grows steeply with the wall: thinner walls are softer
    assert rows[("deep", 0.002)]["EA_N"] < rows[("deep", 0.003)]["EA_N"]
