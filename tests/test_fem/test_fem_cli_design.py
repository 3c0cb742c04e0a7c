"""``bellows fem solve --design``: one's own bellows design file in the FEM's command, the same model as the preset
it describes (to round-off: the threaded sparse solver itself differs from run to run in the 16th digit), and a
clear error for a wrong combination or file."""

import json

import numpy as np

import pytest

from fem_reference import presets
from validation.reference.designs import design_to_toml


def _solve(args, capsys):
    from validation.commands.main import main
    with pytest.raises(SystemExit) as info:
        main(["fem", "solve", "--tensions-n", "0.5,0,0", "--no-gravity", "--json", *args])
    out, err = capsys.readouterr()
    return info.value.code, out, err


def test_a_design_file_solves_as_the_preset_it_writes_down(tmp_path, capsys):
    design = tmp_path / "my_tube.toml"
    design.write_text(design_to_toml(presets.straight_tube_test(), presets.paper_material(), name="my tube"))
    code_p, out_p, err_p = _solve(["--preset", "straight_tube"], capsys)
    code_d, out_d, err_d = _solve(["--design", str(design)], capsys)
    assert code_p == 0 and code_d == 0, err_p + err_d
    preset, own = json.loads(out_p.splitlines()[-1]), json.loads(out_d.splitlines()[-1])
    assert np.allclose(own["tip_position_m"], preset["tip_position_m"], rtol=1e-12, atol=1e-15)   # one model
    assert own["model"]["parameters"] == "my_tube.toml" and "design file" in own["model"]["description"]
    assert preset["model"]["source"] == "design preset"


@pytest.mark.parametrize("args, says", [
    (["--design", "missing.toml"], "cannot read design file"),
    (["--design", "paper", "--preset", "paper"], "not both"),
    (["--design", "wall.csv"], "neither a preset"),
])
def test_a_wrong_design_is_one_error_line(args, says, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    code, out, err = _solve(args, capsys)
    errors = [line for line in err.splitlines() if line.startswith("error:")]
    assert code == 2 and len(errors) == 1 and says in errors[0], err
