"""'bellows control --actuator/--plant': the controller's model and the simulated plant are the actuators given
(a preset or a file), the result and the run log say which (names, paths, hashes), and contradictions are refused
before a run log exists."""

import hashlib
import json
import pathlib

import numpy as np
import pytest
from typer.testing import CliRunner

from ancf import ActuatorParams, Model, presets
from hardware.runlog import read_run_log
from validation.commands.main import app

runner = CliRunner()
TARGET = np.array([0.174, 0.0, -0.002])     # reachable on `paper` and on the stiffer file at 30 kPa
P = 30e3


@pytest.fixture(scope="module")
def stiff(tmp_path_factory) -> "pathlib.Path":
    """`bellows params --out` edited by hand: a stiffer actuator (a 30 % larger stiffness law) named 'stiff'."""
    d = tmp_path_factory.mktemp("actuators")
    res = runner.invoke(app, ["params", "--out", str(d / "a.toml")])
    assert res.exit_code == 0, res.output
    text = (d / "a.toml").read_text()
    assert 'name = "paper"' in text and "a_N = 213.76\n" in text
    path = d / "stiff.toml"
    path.write_text(text.replace('name = "paper"', 'name = "stiff"').replace("a_N = 213.76\n", "a_N = 277.888\n"))
    return path


def _control(tmp_path, name, *extra):
    log = tmp_path / f"{name}.h5"
    res = runner.invoke(app, ["control", "--rig", "sim", "--target-mm", ",".join(f"{x * 1e3:g}" for x in TARGET),
                              "--pressure-kpa", "30", "--fast", "--max-iterations", "10", "--log", str(log),
                              "--json", *extra])
    return res, log


def _out(res) -> dict:
    return json.loads(res.stdout.strip().splitlines()[-1])


def test_actuator_file_is_the_model_and_the_plant(tmp_path, stiff):
    res, log = _control(tmp_path, "stiff", "--actuator", str(stiff))
    assert res.exit_code == 0, res.output
    out = _out(res)
    sha = hashlib.sha256(stiff.read_bytes()).hexdigest()
    assert out["actuator"]["name"] == "stiff" and out["actuator"]["path"] == str(stiff.resolve())
    assert out["actuator"]["file_sha256"] == sha and out["plant"]["file_sha256"] == sha
    assert out["plant"]["mismatch"] is False
    # the controller's model is the plant: the first IK lands on the target, no correction
    assert out["iterations"] == 0 and out["errors_m"][0] < 1e-6
    d = read_run_log(log)
    assert ActuatorParams.from_toml_string(_actuator_toml(log)) == ActuatorParams.from_toml(stiff)
    assert d.attrs["run"]["actuator"]["file_sha256"] == sha


def _actuator_toml(log) -> str:
    import h5py
    with h5py.File(log, "r") as f:
        v = f["static_states"].attrs["actuator_toml"]
    return v.decode() if isinstance(v, bytes) else v


def test_plant_other_than_the_model_shows_the_mismatch(tmp_path, stiff):
    """--actuator paper --plant stiff.toml: the first command is paper's IK; the stiff plant, its tendons locked
    at those lengths, puts the tip where the ANCF model of the stiff actuator says (computed here directly),
    millimetres from the target; LACC then corrects it."""
    res, log = _control(tmp_path, "mixed", "--actuator", "paper", "--plant", str(stiff))
    assert res.exit_code == 0, res.output
    out = _out(res)
    assert out["actuator"]["name"] == "paper" and out["actuator"]["source"] == "preset"
    assert out["plant"]["name"] == "stiff" and out["plant"]["path"] == str(stiff.resolve())
    assert out["actuator"]["parameters_sha256"] != out["plant"]["parameters_sha256"]
    ik = Model(presets.paper()).ik(TARGET, P)
    truth = Model(ActuatorParams.from_toml(stiff)).fk_locked(ik.tendon_lengths, P, q0=ik.q, tensions0=ik.tensions)
    expected = float(np.linalg.norm(truth.tip - TARGET))
    assert expected > 1e-3                                             # the two actuators differ by millimetres
    d = read_run_log(log)
    assert float(np.linalg.norm(d.samples["true_tip"][0] - TARGET)) == pytest.approx(expected, abs=2e-6)
    assert out["errors_m"][0] == pytest.approx(expected, abs=2e-6)     # no tracker noise without --mismatch
    assert out["status"] == "converged" and out["iterations"] >= 1
    run = d.attrs["run"]
    assert run["actuator"]["name"] == "paper" and run["plant"]["name"] == "stiff"
    assert run["plant"]["file_sha256"] == hashlib.sha256(stiff.read_bytes()).hexdigest()
    from hardware.runlog import summary                                # what `bellows log show` prints
    text = summary(log)
    assert "controller's model: actuator 'paper' (preset)" in text
    sha = run["plant"]["file_sha256"][:12]
    assert f"simulated plant: actuator 'stiff' (file {stiff.resolve()}, sha256 {sha}…)" in text


def test_mismatch_perturbs_the_given_plant(tmp_path, stiff):
    res, log = _control(tmp_path, "mm", "--plant", str(stiff), "--mismatch", "--seed", "1")
    assert res.exit_code in (0, 1), res.output
    out = _out(res)
    assert out["plant"]["name"] == "stiff" and out["plant"]["mismatch"] is True
    plant = ActuatorParams.from_toml_string(read_run_log(log).attrs["rig"]["plant_options"]["params"])
    base = ActuatorParams.from_toml(stiff)
    # PlantOptions.mismatched scales the stiffness law by 0.95: around the stiff file, not around paper
    assert float(plant.stiffness.EA(1.0)) == pytest.approx(0.95 * float(base.stiffness.EA(1.0)), rel=1e-9)
    from hardware.runlog import summary
    assert "simulated plant: actuator 'stiff'" in summary(log) and "perturbed by --mismatch" in summary(log)


def test_text_output_names_model_and_plant(tmp_path, stiff):
    res = runner.invoke(app, ["control", "--rig", "sim", "--target-mm", "174,0,-2", "--pressure-kpa", "30",
                              "--fast", "--max-iterations", "3", "--plant", str(stiff)])
    assert res.exit_code == 0, res.output
    line = next(x for x in res.stdout.splitlines() if x.startswith("controller's model"))
    assert "preset 'paper'" in line and "'stiff' from" in line and str(stiff.resolve()) in line


def _refused(monkeypatch, capsys, rig, log, *extra) -> str:
    """Run the command as the console script does (its error handler: one ``error:`` line, exit status 2)."""
    from validation.commands.main import main
    monkeypatch.setattr("sys.argv", ["bellows", "control", "--rig", str(rig), "--target-mm", "174,0,-2",
                                     "--pressure-kpa", "30", "--max-iterations", "1", "--log", str(log),
                                     *extra])
    with pytest.raises(SystemExit) as info:
        main()
    err = capsys.readouterr().err
    assert info.value.code == 2 and err.startswith("error: "), err
    assert not log.exists()
    return err


@pytest.mark.parametrize("extra, msg", [
    (["--actuator", "four_tendon", "--plant", "paper"], "has 3 tendons, the controller's model 'four_tendon' 4"),
    (["--plant", "four_tendon"], "has 4 tendons, the controller's model 'paper' 3"),
    (["--actuator", "/nonexistent/a.toml"], "--actuator: cannot read actuator file"),
    (["--plant", "no_such_preset"], "--plant: unknown preset"),
])
def test_contradictions_are_refused_before_the_log(monkeypatch, capsys, tmp_path, extra, msg):
    assert msg in _refused(monkeypatch, capsys, "sim", tmp_path / "run.h5", *extra)


def test_plant_on_a_hardware_rig_is_refused(monkeypatch, capsys, tmp_path, stiff):
    rig = tmp_path / "rig.toml"
    rig.write_text('backend = "hardware"\n'
                   + "".join(f'[[drives]]\nbackend="epos4"\nnode_id={i}\nchannel="can0"\ncounts_per_mm=100\n'
                             f'counts_per_turn=4096\nzero_length_mm=160\n[[force_sensors]]\nbackend="serial"\n'
                             f'port="/dev/null"\nchannel={i}\n' for i in (1, 2, 3))
                   + '[pressure]\nbackend="serial"\nport="/dev/zero"\n[tracker]\nbackend="natnet"\n')
    assert "--plant: only for a simulated rig" in _refused(monkeypatch, capsys, rig, tmp_path / "hw.h5",
                                                           "--plant", str(stiff))
    err = _refused(monkeypatch, capsys, rig, tmp_path / "hw.h5", "--actuator", "four_tendon")
    assert "4 tendons, the rig file has 3 [[drives]]" in err
