"""Readable results in a console and in Jupyter: one-line reprs with units (never the coordinate vector) and small
HTML tables (``_repr_html_``) that parse and carry the values."""

import re
from html.parser import HTMLParser

import numpy as np
import pytest

from ancf import Model, presets


class _Table(HTMLParser):
    """Cell texts of an HTML fragment; fails on an end tag that does not close the open element."""

    def __init__(self):
        super().__init__()
        self.stack, self.cells, self.caption = [], [], ""

    def handle_starttag(self, tag, attrs):
        self.stack.append(tag)

    def handle_endtag(self, tag):
        assert self.stack and self.stack[-1] == tag, f"</{tag}> closes <{self.stack[-1] if self.stack else None}>"
        self.stack.pop()

    def handle_data(self, data):
        if self.stack and self.stack[-1] in ("td", "th"):
            self.cells.append(data)
        elif self.stack and self.stack[-1] == "caption":
            self.caption += data


def parse(html: str) -> _Table:
    t = _Table()
    t.feed(html)
    t.close()
    assert t.stack == [], f"unclosed elements {t.stack}"
    assert html.startswith("<table>")
    return t


def _numbers(text: str) -> np.ndarray:
    return np.array([float(x) for x in text.split(",")])


@pytest.fixture(scope="module")
def model():
    return Model(presets.get("paper"))


def test_model_repr_names_the_actuator(model):
    p = model.params
    r = repr(model)
    assert "\n" not in r and r.startswith("Model('paper'")
    assert f"{p.n_elements} elements" in r and f"L={1e3 * p.length:.1f} mm" in r and f"{p.n_tendons} tendons" in r
    assert f"pressure ≤ {p.pressure_max / 1e3:.1f} kPa" in r


def test_equilibrium_repr_is_one_short_line_with_the_tip_in_mm(model):
    eq = model.fk((2.0, 0.0, 0.5), 30e3)
    r = repr(eq)
    assert "\n" not in r and len(r) < 200
    assert "q=" not in r and "array" not in r
    tip = _numbers(re.search(r"tip=\(([^)]*)\) mm", r).group(1))
    np.testing.assert_allclose(tip, 1e3 * eq.tip, atol=5e-4)
    np.testing.assert_allclose(_numbers(re.search(r"tensions=\(([^)]*)\) N", r).group(1)), eq.tensions, atol=5e-4)
    assert "pressure=30.00 kPa" in r and "stable=True" in r and "converged=True" in r and "solver='fk'" in r
    assert "slack" not in r                   # FK: no slack to show


def test_locked_equilibrium_repr_shows_the_slack_in_mm(model):
    held = model.fk((2.0, 0.0, 0.0), 20e3)
    eq = model.fk_locked(held.tendon_lengths + np.array([0.0, 1e-3, 2e-3]), 20e3, q0=held.q, tensions0=held.tensions)
    r = repr(eq)
    assert len(r) < 200 and "solver='fk_locked'" in r
    slack = _numbers(re.search(r"slack=\(([^)]*)\) mm", r).group(1))
    np.testing.assert_allclose(slack, 1e3 * eq.slack, atol=5e-4)
    assert slack[2] > 0.5                     # a 2 mm longer tendon stays slack (its length is not reached)


def test_equilibrium_html_is_a_table_of_its_values(model):
    eq = model.fk((1.0, 0.0, 0.0), 40e3, tip_force=(0.0, 0.0, -0.5))
    t = parse(eq._repr_html_())
    cells = dict(zip(t.cells[2::2], t.cells[3::2]))          # after the header row
    np.testing.assert_allclose(_numbers(cells["tip"].removesuffix(" mm").strip("()")), 1e3 * eq.tip, atol=5e-4)
    assert cells["pressure"] == "40.00 kPa" and cells["tip force"] == "(0.000, 0.000, -0.500) N"
    assert cells["stable"] == "True" and cells["converged"] == "True"


def test_validation_result_repr_and_html_carry_the_errors():
    from validation.checks.compare import ValidationResult
    val = ValidationResult(rows=[{"label": "a"}, {"label": "b"}], length=0.16, params=presets.get("paper"),
                           tip_error_pct={"mean": 0.41, "max": 1.23}, shape_error_pct={"mean": 0.5, "max": 1.9},
                           compliance_error_pct={"tension": {"mean": 3.0, "max": 4.5},
                                                 "locked": {"mean": 6.0, "max": 9.25}},
                           targets={"shape_pct": {"target": 2.5, "value": 1.9, "status": "met", "met": True}},
                           failures=[{"label": "c", "model": "FEM", "error": "diverged"}])
    r = repr(val)
    assert "\n" not in r and len(r) < 200
    assert "2 states" in r and "0.41/1.23 % L" in r and "0.50/1.90 % L" in r and "shape_pct: met" in r
    assert "1 not compared" in r
    t = parse(val._repr_html_())
    cells = dict(zip(t.cells[2::2], t.cells[3::2]))
    assert cells["tip error [% L]"] == "mean 0.41 %, max 1.23 %"
    assert cells["compliance error, tendons locked [%]"] == "mean 6.00 %, max 9.25 %"
    assert cells["not compared"] == "c (FEM)" and "L = 160.0 mm" in t.caption
