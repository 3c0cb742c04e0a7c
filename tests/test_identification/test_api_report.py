"""``validation.run_report`` (``bellows report`` as one call) and the identification result's display, on
synthetic measurements made by the reduced model with known parameters (tests/test_identification/test_fit.py)."""

import json
import re
from html.parser import HTMLParser

import numpy as np
import pytest
from typer.testing import CliRunner

import validation
from ancf import ActuatorParams
from ancf.errors import InputError, OutputExistsError
from hardware.static_states import StaticStates, write_static_states
from validation.identification.forms import get_form
from validation.reference.experiments import default_design

from test_fit import BASE, MARKERS, TRUE, synthetic

EA_TRUE = TRUE["paper"][0]                    # EA(1) = k(1) of the parameters that made the data [N]


def _states() -> StaticStates:
    design = default_design()
    obs = synthetic(get_form("paper"), np.array(TRUE["paper"]), design.cases, noise=2e-5, seed=4)
    return StaticStates(tensions=obs.tensions, pressure=obs.pressure, tip_position=obs.tip, tip_force=obs.tip_force,
                        tip_position_std=obs.tip_std, markers=obs.markers, marker_arclength=MARKERS,
                        markers_std=obs.markers_std,
                        label=[("heldout " if c.role == "heldout" else "") + c.label for c in design.cases])


@pytest.fixture(scope="module")
def states_file(tmp_path_factory):
    return write_static_states(tmp_path_factory.mktemp("api") / "states.h5", _states())


@pytest.fixture(scope="module")
def run(states_file):
    return validation.run_report(states_file.parent / "rep", measurements=states_file, base=BASE, forms=("paper",))


def test_run_report_from_measurements_writes_the_folder_and_recovers_the_truth(run):
    d = run.out
    assert {p.name for p in d.iterdir()} == {"report.html", "actuator.toml", "fit.json", "figures"}
    assert {p.name for p in run.files} == {"report.html", "actuator.toml", "fit.json", "figures"}
    assert run.validation is None and run.stiffness is None          # no FEM behind measurements
    assert run.identification.form == "paper" and run.modes is not None
    p = ActuatorParams.from_toml(d / "actuator.toml")
    assert p.stiffness.EA(1.0) == pytest.approx(EA_TRUE, rel=0.01)
    assert json.loads((d / "fit.json").read_text())["values"]["EA"] == pytest.approx(EA_TRUE, rel=0.01)
    assert "data:image/png;base64," in run.report.read_text()
    r = repr(run)
    assert "\n" not in r and "form='paper'" in r and str(run.report) in r


def test_run_report_never_overwrites_and_checks_inputs_before_any_work(run, states_file, tmp_path):
    with pytest.raises(OutputExistsError):
        validation.run_report(run.out, measurements=states_file, base=BASE, forms=("paper",))
    out = tmp_path / "never"
    for kw, message in (({"design": "paper", "measurements": states_file, "base": BASE}, "not both"),
                        ({"measurements": states_file}, "base="),
                        ({"design": "paper", "base": BASE}, "only with measurements"),
                        ({"measurements": tmp_path / "nope.h5", "base": BASE}, "no such file"),
                        ({"measurements": states_file, "base": BASE, "forms": ("bogus",)}, "unknown form"),
                        ({"design": "paper", "cases": "optimal"}, "cases must be"),
                        ({"design": "paper", "pressure_max": 0.0}, "pressure_max must be a number > 0"),
                        ({"design": "paper", "tension_max": "5"}, "tension_max must be a number > 0")):
        with pytest.raises(InputError, match=message):
            validation.run_report(out, **kw)
        assert not out.exists()


def test_the_report_command_is_run_report_with_si_units(run, monkeypatch, tmp_path):
    """``bellows report`` hands its options to run_report (kPa → Pa) and prints what it returns."""
    from validation.commands.main import app
    from validation.report import pipeline
    calls = []

    def fake(out, **kw):
        calls.append((out, kw))
        return run
    monkeypatch.setattr(pipeline, "run_report", fake)
    r = CliRunner().invoke(app, ["report", "--design", "paper", "--quick", "--pressure-max-kpa", "80",
                                 "--tension-max-n", "4", "--out", str(tmp_path / "r")])
    assert r.exit_code == 0, r.output
    (out, kw), = calls
    assert out == tmp_path / "r" and kw["design"] == "paper" and kw["quick"] is True
    assert kw["pressure_max"] == pytest.approx(80e3) and kw["tension_max"] == pytest.approx(4.0)
    assert kw["forms"] == pipeline.QUICK_FORMS and kw["command"].startswith("bellows ")
    assert f"wrote {run.report}" in r.output.replace("\n", "")


def test_identification_result_repr_and_html(run):
    res = run.identification
    r = repr(res)
    assert "\n" not in r and len(r) < 250 and "Observations" not in r
    ea = float(re.search(r"EA=([\d.]+) N", r).group(1))
    assert ea == pytest.approx(EA_TRUE, rel=0.01)
    assert f"D_a={1e3 * res.values['D_a']:.4g} mm" in r and "form='paper'" in r and "source='measurements'" in r

    class Cells(HTMLParser):
        def __init__(self):
            super().__init__()
            self.cells, self.open = [], []

        def handle_starttag(self, tag, attrs):
            self.open.append(tag)

        def handle_endtag(self, tag):
            assert self.open.pop() == tag

        def handle_data(self, data):
            if self.open and self.open[-1] in ("td", "th"):
                self.cells.append(data)
    c = Cells()
    c.feed(res._repr_html_())
    assert c.open == []
    row = c.cells.index("EA")
    assert float(c.cells[row + 1].split()[0]) == pytest.approx(EA_TRUE, rel=0.01)
    lo, hi = (float(x) for x in c.cells[row + 2].split(" … "))
    assert lo < res.values["EA"] < hi


def test_a_validations_fem_error_reaches_the_report(run):
    """for_validation sets the ValidationResult's own ``fem_error`` and build_report shows it."""
    from validation.checks.compare import ValidationResult
    from validation.checks.fem_error import for_validation
    val = ValidationResult(rows=[], length=BASE.length, params=run.identification.params)
    fe = for_validation(val, None, [], 2)          # no compared state: nothing to measure, said so
    assert fe is val.fem_error and fe["estimated"] is False
    html = validation.build_report(run.identification, val, figures={})
    assert "not estimated (no held-out state was compared)" in html
