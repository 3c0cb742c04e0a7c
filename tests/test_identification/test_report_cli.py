"""The HTML report and the identification commands, on synthetic measurements from the reduced model.

The report must be self-contained (every image embedded and decodable, no external URL), show the numbers
of the result it reports, and show a non-identifiable parameter as such, never as a number.  The commands
must check their outputs before any work, never overwrite without ``--force``, and turn every handled
error into one ``error:`` line with exit status 2.
"""

import base64
import json
import os
import pathlib
import re
import subprocess
import sys
from html.parser import HTMLParser

import numpy as np
import pytest

from ancf import ActuatorParams
from hardware.static_states import StaticStates, write_static_states
from validation.identification import identify
from validation.reference.experiments import default_design
from validation.identification.forms import get_form
from validation.report.build import build_report, write_report

from test_fit import BASE, MARKERS, TRUE, synthetic

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


class _Collector(HTMLParser):
    def __init__(self):
        super().__init__()
        self.srcs, self.hrefs, self.text = [], [], []

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if "src" in a:
            self.srcs.append(a["src"])
        if "href" in a:
            self.hrefs.append(a["href"])

    def handle_data(self, data):
        self.text.append(data)


def _states(design, noise=2e-5, seed=4) -> StaticStates:
    obs = synthetic(get_form("paper"), np.array(TRUE["paper"]), design.cases, noise=noise, seed=seed)
    return StaticStates(tensions=obs.tensions, pressure=obs.pressure, tip_position=obs.tip, tip_force=obs.tip_force,
                        tip_position_std=obs.tip_std, markers=obs.markers, marker_arclength=MARKERS,
                        markers_std=obs.markers_std,
                        label=[("heldout " if c.role == "heldout" else "") + c.label for c in design.cases])


@pytest.fixture(scope="module")
def no_pressure_result():
    """A design without any pressure: D_eff cannot be identified."""
    design = default_design()
    design = type(design)(tuple(c for c in design.cases if c.pressure == 0.0))
    return identify.from_measurements(_states(design), BASE, forms=("paper",), gravity=False)


def _parse(html: str) -> _Collector:
    c = _Collector()
    c.feed(html)
    return c


def test_report_is_self_contained_and_shows_the_result(no_pressure_result, tmp_path):
    res = no_pressure_result
    path = write_report(tmp_path / "r.html", res, figures_dir=tmp_path / "fig")
    html = path.read_text()
    doc = _parse(html)
    assert len(doc.srcs) >= 3
    for src in doc.srcs:
        assert src.startswith("data:image/png;base64,")
        assert base64.b64decode(src.split(",", 1)[1]).startswith(PNG_MAGIC)
    assert not re.search(r"""(src|href)\s*=\s*["']?(https?:)?//""", html)
    assert "<script" not in html.lower()
    text = " ".join(doc.text)
    # the identified values appear as the report formats them, the non-identifiable one does not
    assert f"{res.values['EA']:.4g}" in text and f"{1e3 * res.values['D_a']:.4g}" in text
    assert res.values["D_eff"] is None and "D_eff" in res.not_identifiable
    row = re.search(r"<td class=\"l\">D_eff</td>\s*<td class=\"l\">[^<]*</td>\s*"      # name, meaning
                    r"<td class=\"na\" colspan=\"2\">not identifiable</td>", html)
    assert row, "D_eff must be shown as not identifiable"
    assert {p.name for p in (tmp_path / "fig").iterdir()} >= {"forms.png", "correlation.png", "residuals.png"}
    with pytest.raises(Exception, match="exists"):
        write_report(tmp_path / "r.html", res)


def test_report_needs_an_identification_result():
    from ancf.errors import InputError
    with pytest.raises(InputError):
        build_report({"EA": 1.0})


ROOT = pathlib.Path(__file__).resolve().parents[2]


def _bellows(*args, cwd):
    # the checkout under test first on the path: an editable install of another checkout must not answer
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT)] + [p for p in [os.environ.get("PYTHONPATH")] if p]))
    return subprocess.run([sys.executable, "-m", "validation.commands.main", *map(str, args)], cwd=cwd, capture_output=True,
                          text=True, timeout=600, env=env)


@pytest.fixture(scope="module")
def measured_files(tmp_path_factory):
    d = tmp_path_factory.mktemp("cli")
    states = write_static_states(d / "states.h5", _states(default_design()))
    base = d / "base.toml"
    base.write_text(BASE.to_toml())
    # an actuator of another length / tendon count than the FEM design, and a design beyond the FEM's limits
    (d / "long.toml").write_text(BASE.replace(length=0.2).to_toml())
    t = BASE.tendons[0]
    four = tuple(t.model_copy(update={"angle": float(a)}) for a in np.arange(4) * np.pi / 2)
    (d / "four.toml").write_text(BASE.replace(tendons=four).to_toml())
    from validation.reference.designs import design_to_toml, load_design
    (d / "wide.toml").write_text(design_to_toml(*load_design("paper"), "wide",
                                                limits={"tension_max": 30.0, "pressure_max": 100e3}))
    return d, states, base


def test_cli_identify_and_report_from_measurements(measured_files):
    d, states, base = measured_files
    r = _bellows("report", "--measurements", states, "--base", base, "--forms", "paper,constant",
                 "--out", d / "rep", cwd=d)
    assert r.returncode == 0, r.stderr
    out = d / "rep"
    p = ActuatorParams.from_toml(out / "actuator.toml")
    fit = json.loads((out / "fit.json").read_text())
    assert fit["form"] == "paper" and p.stiffness.EA(1.0) == pytest.approx(fit["values"]["EA"], rel=1e-9)
    assert fit["values"]["EA"] == pytest.approx(767.2, rel=0.01)
    assert "git_revision" in fit["provenance"] and fit["provenance"]["versions"]
    html = (out / "report.html").read_text()
    assert "paper" in html and "data:image/png;base64," in html
    # a second run into the same folder is refused before any work, one error line, exit 2
    again = _bellows("identify", "--measurements", states, "--base", base, "--out", out, cwd=d)
    assert again.returncode == 2
    lines = [ln for ln in again.stderr.strip().splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error:") and "--force" in lines[0]
    assert "Traceback" not in again.stderr


@pytest.mark.parametrize("args, message", [
    (("identify", "--design", "paper", "--measurements", "states.h5"), "not both"),
    (("identify", "--measurements", "nope.h5"), "no such file"),
    (("identify", "--measurements", "states.h5", "--forms", "bogus"), "unknown form"),
    (("identify", "--measurements", "states.h5"), "--base"),
    (("report", "--measurements", "states.h5", "--quick"), "--base"),
    (("report", "--design", "nope.toml"), "nope.toml"),
    (("calibrate", "--design", "paper"), "at least one"),
    (("identify", "--design", "paper", "--pressure-max-kpa", "0"), "--pressure-max-kpa"),
    (("validate", "--params", "no_such_preset"), "unknown preset"),
    (("validate", "--params", "long.toml"), "200 mm long and the FEM design 160 mm"),
    (("validate", "--params", "four.toml"), "has 4 tendons and the FEM design 3"),
    (("identify", "--design", "wide.toml"), "exceeds what the FEM reference accepts (tension ≤ 20 N"),
    (("identify", "--design", "paper", "--pressure-max-kpa", "300"), "pressure 225 kPa is outside"),
    (("report", "--design", "paper", "--quick", "--cases", "optimal"), "--cases must be"),
])
def test_cli_bad_inputs_exit_2_with_one_line(measured_files, args, message):
    d, *_ = measured_files
    r = _bellows(*args, "--out", d / "bad_out" / "x.toml" if args[0] == "calibrate" else d / "bad_out", cwd=d)
    lines = [ln for ln in r.stderr.strip().splitlines() if ln.strip()]
    assert r.returncode == 2 and len(lines) == 1 and lines[0].startswith("error:"), r.stderr
    assert message in lines[0]
    assert not (d / "bad_out").exists() or not any((d / "bad_out").iterdir())
