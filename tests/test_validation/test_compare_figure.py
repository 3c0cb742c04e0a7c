"""compare.png and the comparison table judge with ONE criterion: the green band of the figure is exactly the
interval in which the table puts a ✓, and values off the axis are drawn as off-scale, never pinned to it."""

import math

import numpy as np
import pytest

from validation.paper import comparison, plots
from validation.paper.criteria import ratio_band, within

JUDGED = [k for k, h in comparison.HEADLINES.items() if (h[3] is not None or h[4] is not None) and h[1]]


@pytest.mark.parametrize("key", JUDGED)
def test_band_and_verdict_agree_at_the_band_edges(key):
    _, paper, _, lo, hi = comparison.HEADLINES[key]
    a, b = ratio_band(lo, hi, paper)
    edges = [e for e in (lo, hi) if e is not None]
    probes = [e * f for e in edges for f in (1 - 1e-9, 1.0, 1 + 1e-9)] + [paper, 0.0, 1e-6 * paper, 1e6 * paper]
    for v in probes:
        in_band = bool(a <= v / paper <= b)
        assert comparison.verdict(key, v) is in_band, (key, v, a, b)


def test_ratio_band_of_open_and_negative_criteria():
    assert ratio_band(None, 0.03, 0.01) == (-math.inf, pytest.approx(3.0))
    assert ratio_band(10.0, None, 10.0) == (1.0, math.inf)
    for lo, hi in ((1.0, 2.0), (None, 2.0), (1.0, None)):
        a, b = ratio_band(lo, hi, -1.0)
        for v in np.linspace(-5, 5, 41):
            assert bool(a <= v / -1.0 <= b) is within(float(v), lo, hi), (lo, hi, v)


def _result(values: dict) -> dict:
    keys = list(values)
    numbers = {k: v for k, v in values.items()}
    return {"paper": {k: comparison.HEADLINES[k][1] for k in keys},
            "labels": {k: comparison.HEADLINES[k][0] for k in keys},
            "criteria": {k: [comparison.HEADLINES[k][3], comparison.HEADLINES[k][4]] for k in keys},
            "settings": {"samples_per_mode_per_seed": 10, "seeds": [0]},
            "presets": [{"preset": "p", "numbers": numbers,
                         "verdicts": {k: comparison.verdict(k, v) for k, v in numbers.items()},
                         "reproduced": 0, "judged": len(keys)}]}


def test_figure_bands_are_the_verdicts_interval_and_tiny_ratios_are_not_pinned(monkeypatch, tmp_path):
    # a LACC error of 1e-5 mm is a ratio of ~1e-3 of the paper's and reproduces (≤ 0.03 mm): the old figure pinned
    # ratios to the axis at 1e-3 and started that band at 0.1, so the band disagreed with the table's ✓
    values = {"table1_upward_lacc_mm": 1e-5, "convergence_n6_mm": 0.6 * (1 + 1e-9), "locked_drift_110g_mm": 10.0,
              "workspace_increase_percent": 0.0}
    res = _result(values)
    lay = plots.comparison_layout(res)
    x0, x1 = lay["limits"]
    for k in values:                       # every band is the criterion's interval, clipped to the axis
        a, b = ratio_band(*res["criteria"][k], res["paper"][k])
        assert lay["bands"][k] == (pytest.approx(max(a, x0)), pytest.approx(min(b, x1)))
    for q in lay["points"]:                # the marker's fill is the table's verdict; on-scale points are in place
        assert q["reproduced"] is comparison.verdict(q["key"], q["value"]) is res["presets"][0]["verdicts"][q["key"]]
        if q["edge"] is None:
            a, b = lay["bands"][q["key"]]
            assert bool(a <= q["x"] <= b) is q["reproduced"] and q["x"] == q["ratio"]
    tiny = next(q for q in lay["points"] if q["key"] == "table1_upward_lacc_mm")
    assert tiny["edge"] is None and tiny["reproduced"] and x0 < tiny["ratio"]     # on the axis, inside its band
    zero = next(q for q in lay["points"] if q["key"] == "workspace_increase_percent")
    assert zero["edge"] == "left" and zero["reproduced"] is False                  # 0 cannot be drawn on a log axis
    # the drawn figure marks the off-scale value in words, and draws one band per criterion
    figs = []
    monkeypatch.setattr(plots, "_save_figure", lambda fig, out, stem: figs.append(fig) or [])
    plots.plot_comparison(res, tmp_path)
    ax = figs[0].axes[0]
    assert ax.get_xlim() == pytest.approx((x0, x1))
    assert [t.get_text() for t in ax.texts] == ["0× (off scale)"]


def test_limits_are_whole_decades_around_the_data():
    assert plots.comparison_limits([0.5, 2.0], [(0.8, 1.2)]) == (0.1, 10.0)
    x0, x1 = plots.comparison_limits([1e-5, 3.0], [(-math.inf, 3.0)])
    assert x0 <= 1e-5 / 1.5 and x1 >= 4.5
    assert plots.comparison_limits([1e-12, 1e12], []) == (1e-6, 1e6)
