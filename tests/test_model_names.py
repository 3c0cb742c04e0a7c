"""Every command that prints a tip says which model and which parameter set produced it — the ANCF rod with an
actuator preset or file, or the FEM reference with a bellows design — in its table title / first line and in its
JSON (a ``model`` field): `bellows fk` on `paper` and `bellows fem solve` on `paper` are different models."""

import json
from types import SimpleNamespace

import numpy as np
import pytest

from ancf import presets
from validation.commands.main import main

ROD_PAPER = "ANCF rod model, actuator preset 'paper' (the paper's stiffness law)"
FEM_PAPER = "FEM reference (3-D hyperelastic), bellows design 'paper' (wall geometry and material)"


def run(capsys, *args):
    with pytest.raises(SystemExit) as info:
        main([str(a) for a in args])
    out = capsys.readouterr()
    assert info.value.code == 0, out.out + out.err
    return out.out, out.err


def test_fk_names_the_rod_model_and_preset(capsys):
    out, _ = run(capsys, "fk", "--tensions-n", "2,0,0", "--pressure-kpa", "30", "--tip-force-n", "0,0,-0.49")
    assert f"FK — {ROD_PAPER}" in out
    out, _ = run(capsys, "fk", "--tensions-n", "2,0,0", "--pressure-kpa", "30", "--tip-force-n", "0,0,-0.49", "--json")
    m = json.loads(out)["fk"]["model"]
    assert m == {"kind": "ANCF rod", "parameters": "paper", "source": "preset", "path": None, "description": ROD_PAPER}


@pytest.mark.parametrize("cmd, key", [(["ik", "--target-mm", "175.04,0,-34.23", "--pressure-kpa", "30",
                                        "--tip-force-n", "0,0,-0.49"], "ik"),
                                      (["locked", "--lengths-mm", "177.2,172.0,172.0", "--pressure-kpa", "30"],
                                       "locked"),
                                      (["compliance", "--tensions-n", "1,0,0", "--pressure-kpa", "20"], None),
                                      (["modes", "--tensions-n", "1,0,0", "--pressure-kpa", "20", "--count", "2"],
                                       None)])
def test_other_rod_commands_carry_the_model(capsys, cmd, key):
    out, _ = run(capsys, *cmd, "--json")
    data = json.loads(out)
    assert (data[key] if key else data)["model"]["description"] == ROD_PAPER


def test_an_actuator_file_is_named_with_its_path(capsys, tmp_path):
    f = tmp_path / "lab.toml"
    f.write_text(presets.paper().replace(name="lab", description="").to_toml())
    out, _ = run(capsys, "fk", "--tensions-n", "1,0,0", "--preset", f, "--json")
    m = json.loads(out)["fk"]["model"]
    assert m["source"] == "file" and m["path"] == str(f.resolve()) and m["parameters"] == "lab"
    assert m["description"] == f"ANCF rod model, actuator file {f.resolve()} (name 'lab')"


class _FakeFem:
    """Stands in for the FEM model (a solve takes a minute): the command's output is what is tested."""

    def __init__(self, *a, **k):
        self.n_dofs, self.bmesh = 10, SimpleNamespace(n_elements=2)

    def solve(self, **k):
        stats = SimpleNamespace(steps=[1], t_total=1.0, t_linear=0.5, t_assembly=0.3)
        return SimpleNamespace(tip_position=np.array([0.1701, 0.0, -0.0424]), cap_rotation_vector=np.zeros(3),
                               tensions=np.array([2.0, 0.0, 0.0]), tendon_lengths=np.full(3, 0.16), iterations=3,
                               stats=stats, summary=lambda: {"tip_position_m": [0.1701, 0.0, -0.0424]})


def test_fem_solve_names_the_fem_reference_and_design(capsys, monkeypatch):
    monkeypatch.setattr("fem_reference.model.BellowsModel", _FakeFem)
    args = ("fem", "solve", "--tensions-n", "2,0,0", "--pressure-kpa", "30", "--tip-force-n", "0,0,-0.49")
    _, err = run(capsys, *args)
    lines = err.splitlines()
    i = lines.index(FEM_PAPER)
    assert lines[i + 1] == "tip position: (170.10, 0.00, -42.40) mm"
    out, _ = run(capsys, *args, "--json")
    m = json.loads(out)["model"]
    assert m["kind"] == "FEM reference" and m["parameters"] == "paper" and m["description"] == FEM_PAPER
    out, _ = run(capsys, *args, "--mu-mpa", "0.5", "--json")
    m = json.loads(out)["model"]
    assert m["material"] == {"mu_MPa": 0.5, "kappa_MPa": None}
    assert m["description"].endswith("(wall geometry and material, shear modulus = 0.5 MPa given)")


def test_simulate_names_the_model(capsys, tmp_path):
    out, err = run(capsys, "simulate", "--tensions-n", "1,0,0", "--t-end-s", "0.01", "--dt-ms", "1",
                   "--damping-ratio", "0.05", "--out", tmp_path / "sim")
    assert ROD_PAPER in out + err
    data = json.loads((tmp_path / "sim" / "simulation.json").read_text())
    assert data["model"]["description"] == ROD_PAPER
