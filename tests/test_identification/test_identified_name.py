"""An identified actuator file carries its own name (not the base actuator's) and a [provenance] table — the
source (measurement file and the SHA-256 of its bytes, or the FEM design), the form, the date, the package
version — that the actuator loader accepts; `bellows params` reads it back to the same parameters."""

import hashlib
import tomllib

import numpy as np
import pytest
from typer.testing import CliRunner

from ancf import ActuatorParams, presets
from ancf.errors import ConfigError, InputError
from hardware.static_states import StaticStates, write_static_states
from validation.commands.main import app
from validation.identification import identify
from validation.identification.fit import Observations, predict
from validation.identification.forms import get_form
from validation.reference.experiments import default_design

BASE = presets.paper().replace(line_mass=0.0, tip_mass=0.0, gravity=(0.0, 0.0, 0.0))
MARKERS = np.array([0.04, 0.08, 0.12])


@pytest.fixture(scope="module")
def identified(tmp_path_factory):
    """States of the `paper` form's own model (no noise) as a static-states file, identified with that form."""
    # the default design without the states the paper preset buckles under (high tensions without pressure)
    form = get_form("paper")
    cases = [c for c in default_design().cases if c.pressure > 0 or max(c.tensions) < 3]
    obs = Observations([c.tensions for c in cases], [c.pressure for c in cases], [c.tip_force for c in cases],
                       [False] * len(cases), np.zeros((len(cases), 3)), markers=np.zeros((len(cases), 3, 3)),
                       marker_s=MARKERS, labels=[c.label for c in cases])
    pred = predict(form.to_params(np.array([767.2, 1336.0, 0.02959, 0.02605]), BASE), obs)
    states = StaticStates(tensions=obs.tensions, pressure=obs.pressure, tip_position=pred[:, :3],
                          tip_force=obs.tip_force, markers=pred[:, 3:].reshape(len(cases), 3, 3),
                          marker_arclength=MARKERS,
                          label=[("heldout " if c.role == "heldout" else "") + c.label for c in cases])
    path = write_static_states(tmp_path_factory.mktemp("states") / "states.h5", states)
    return identify.from_measurements(path, BASE, forms=("paper",), gravity=False), path


def test_name_and_provenance_round_trip(identified, tmp_path):
    res, states = identified
    out = tmp_path / "actuator.toml"
    res.to_toml(out)
    raw = tomllib.loads(out.read_text())
    assert raw["name"] == "paper-identified" != BASE.name
    prov = raw["provenance"]
    assert prov["source"] == "measurements" and prov["form"] == "paper" and prov["base_actuator"] == "paper"
    assert prov["measurements"] == str(states.resolve())
    assert prov["measurements_sha256"] == hashlib.sha256(states.read_bytes()).hexdigest()
    assert prov["created"][:4].isdigit() and prov["bellows_version"] not in ("", "unknown")
    back = ActuatorParams.from_toml(out)                         # the loader accepts the table
    assert back.name == "paper-identified" and back == res.params.replace(name="paper-identified")
    # `bellows params` (the presets' loader) reads it back, without the table, to the same parameters
    r = CliRunner().invoke(app, ["params", "--preset", str(out)])
    assert r.exit_code == 0, r.output
    assert ActuatorParams.from_toml_string(r.stdout) == back and "[provenance]" not in r.stdout


def test_a_given_name(identified, tmp_path):
    res, _ = identified
    text = res.to_toml(tmp_path / "a.toml", name='lab "A" bellows')
    assert ActuatorParams.from_toml(tmp_path / "a.toml").name == 'lab "A" bellows'
    assert tomllib.loads(text)["provenance"]["source"] == "measurements"
    for bad in ("", "   ", 3):
        with pytest.raises(InputError, match="name"):
            res.to_toml(name=bad)


def test_fem_default_name_is_the_design_s():
    res = identify.IdentificationResult.__new__(identify.IdentificationResult)
    res.source, res.meta, res.params = "fem", {"design_name": "designs/lab_bellows.toml"}, BASE
    assert res.default_name() == "lab_bellows-identified"
    res.meta = {"design_name": "paper"}
    assert res.default_name() == "paper-identified"


def test_provenance_must_be_a_table():
    text = presets.paper().to_toml()
    with pytest.raises(ConfigError, match="provenance"):
        ActuatorParams.from_toml_string('provenance = "FEM"\n' + text)
    assert ActuatorParams.from_toml_string(text + '\n[provenance]\nsource = "fem"\n') == presets.paper()


def test_cli_identify_writes_the_given_name(identified, tmp_path):
    _, states = identified
    base = tmp_path / "base.toml"
    base.write_text(BASE.replace(name="lab").to_toml())
    r = CliRunner().invoke(app, ["identify", "--measurements", str(states), "--base", str(base), "--no-gravity",
                                 "--forms", "paper", "--out", str(tmp_path / "id"), "--name", "lab A"])
    assert r.exit_code == 0, r.output
    raw = tomllib.loads((tmp_path / "id" / "actuator.toml").read_text())
    assert raw["name"] == "lab A" and raw["provenance"]["base_actuator"] == "lab"
    r = CliRunner().invoke(app, ["identify", "--measurements", str(states), "--base", str(base), "--no-gravity",
                                 "--forms", "paper", "--out", str(tmp_path / "id2")])
    assert r.exit_code == 0, r.output
    assert tomllib.loads((tmp_path / "id2" / "actuator.toml").read_text())["name"] == "lab-identified"
