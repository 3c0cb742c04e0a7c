"""The report's tables name what they show: the chosen form's own parameters with their units (the names of
the correlation plot), every column headed plainly, and the FEM design described as what it is (a straight
tube is a tube, not an "8-convolution bellows").  Built cheaply from synthetic measurements, figures skipped."""

import dataclasses
import re
from html.parser import HTMLParser

import numpy as np
import pytest

from fem_reference import presets as fem_presets
from validation.identification import identify
from validation.checks.compare import ValidationResult
from validation.reference.experiments import default_design
from validation.identification.forms import FORMS, MEANINGS, REPORTED, get_form
from validation.report.build import build_report, param_rows

from test_fit import BASE
from test_report_cli import _states


class _Tables(HTMLParser):
    """Header cells and rows (cell texts) of every table."""

    def __init__(self):
        super().__init__()
        self.tables, self._cell = [], None

    def handle_starttag(self, tag, attrs):
        if tag == "table":
            self.tables.append({"head": [], "rows": []})
        elif tag == "tr" and self.tables:
            self.tables[-1]["rows"].append([])
        elif tag in ("th", "td"):
            self._cell = (tag, [])

    def handle_endtag(self, tag):
        if tag in ("th", "td") and self._cell:
            kind, text = self._cell
            t = " ".join("".join(text).split())
            (self.tables[-1]["head"] if kind == "th" else self.tables[-1]["rows"][-1]).append(t)
            self._cell = None

    def handle_data(self, data):
        if self._cell:
            self._cell[1].append(data)


def _tables(html):
    p = _Tables()
    p.feed(html)
    return p.tables


@pytest.fixture(scope="module")
def separate_result():
    design = default_design()
    return identify.from_measurements(_states(design), BASE, forms=("separate",), gravity=False)


def _validation(params) -> ValidationResult:
    row = {"label": "h1", "tensions_N": [1.0, 0.0, 0.0], "pressure_Pa": 20e3, "tip_force_N": [0.0, 0.0, 0.0],
           "gravity": True, "tip_error_m": 1e-4, "tip_error_pct": 0.1, "shape_error_pct": 0.2,
           "C_tension_error_pct": 3.0, "C_locked_error_pct": 4.0, "ratio_z_fem": 2.1, "ratio_z_ancf": 1.9}
    return ValidationResult(rows=[row], length=0.16, params=params)


def test_parameter_table_uses_the_forms_own_names_and_units(separate_result):
    res = separate_result
    assert res.form == "separate"
    html = build_report(res, _validation(res.params), figures={})
    tables = _tables(html)
    params = tables[0]
    names = [r[0] for r in params["rows"] if r]
    assert names == list(res.fit.names) == ["EA1", "sA", "EI1", "sI", "D_eff"]   # = the correlation plot's names
    units = {r[0]: r[-2] for r in params["rows"] if r}                 # cells: ..., unit, first estimate
    assert units == {"EA1": "N", "sA": "N", "EI1": "N m²", "sI": "N m²", "D_eff": "mm"}
    assert "a" not in names and "b" not in names
    # values shown are the fit's own (D_eff in mm)
    rows = {r["name"]: r for r in param_rows(res)}
    assert rows["EA1"]["value"] == f"{res.fit.theta[0]:.4g}"
    assert rows["D_eff"]["value"] == f"{1e3 * res.fit.theta[4]:.4g}"
    # the derived values are a table of their own, headed as such, with units
    derived = tables[1]
    assert [r[0] for r in derived["rows"] if r] == list(res.values)
    assert all(r[-1] for r in derived["rows"] if r)


def test_every_form_parameter_has_a_unit_and_a_meaning():
    for name in FORMS:
        for fd in (False, True):
            f = get_form(name, fit_distance=fd)
            assert len(f.units) == len(f.names)
            assert all(n in MEANINGS for n in f.names), (name, f.names)
    assert all(k in MEANINGS for k in REPORTED)


def test_every_column_is_headed_plainly(separate_result):
    res = separate_result
    html = build_report(res, _validation(res.params), figures={})
    heads = [h for t in _tables(html) for h in t["head"]]
    assert heads and all(h and not h.startswith("…") for h in heads), heads
    assert not any(re.search(r"\bANCF\b", h) for h in heads), heads
    assert "k_z locked / tensions held, reduced model [–]" in heads


def test_a_straight_tube_is_described_as_a_tube(separate_result):
    tube = fem_presets.straight_tube_test()
    bellows = fem_presets.paper_bellows()
    mat = fem_presets.paper_material()
    assert identify.describe_geometry(tube) == "straight tube"
    assert identify.describe_geometry(bellows) == f"{bellows.n_convolutions}-convolution bellows"
    p = identify.fem_base_params(tube, mat)
    assert "straight tube" in p.description and "convolution" not in p.description
    fem = dataclasses.replace(separate_result, source="fem")
    fem.meta = {"mesh": "coarse", "design": identify.describe_geometry(tube), "geometry": {"name": "tube"}}
    html = build_report(fem, figures={})
    text = " ".join(re.sub(r"<[^>]+>", " ", html).split())
    assert "3-D FEM of the straight tube" in text and "convolution" not in text
    assert np.isfinite(fem.fit.theta).all()


def test_the_ratio_table_shows_fem_and_model_per_state(separate_result):
    """Section 3b: one row per state with the FEM's and the reduced model's locked/held ratio and their
    difference, from ValidationResult.ratio_per_state."""
    from validation.checks.compare import ratio_row
    res = separate_result
    val = _validation(res.params)
    val.rows[0]["locked_active_fem"], val.rows[0]["locked_active_ancf"] = [0], [0, 1]
    val.ratio_per_state = [ratio_row(r) for r in val.rows]
    html = build_report(res, val, figures={})
    table = next(t for t in _tables(html) if "difference, reduced vs FEM [%]" in t["head"])
    rows = [r for r in table["rows"] if r]
    assert len(rows) == 1
    cells = dict(zip(table["head"], rows[0]))
    assert cells["ratio, FEM [–]"] == "2.1" and cells["ratio, reduced model [–]"] == "1.9"
    assert cells["difference, reduced vs FEM [%]"] == f"{100 * (1.9 / 2.1 - 1):+.1f}"
    assert cells["taut, FEM"] == "1" and cells["taut, reduced model"] == "1, 2"


def test_shear_diagnostic_names_the_chosen_forms_term():
    """The report's shear sentences say whether the chosen reduced model carries a series shear compliance
    (ancf.shear) and, if so, its s at 0 and 100 kPa."""
    from ancf import presets
    from validation.report.build import _shear_note
    assert "has no shear compliance" in _shear_note(presets.paper())
    text = _shear_note(presets.paper().replace(shear_compliance=(0.5e-3, 3.3e-3)))
    assert "s = 0.50 / 3.80 mm/N at 0 / 100 kPa" in text
