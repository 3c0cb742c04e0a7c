"""CLI (typer app mounted as ``bellows fem``, validation/commands/fem.py) and headless rendering."""

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from validation.commands.fem import app


def test_cli_solve_json_and_files(tmp_path):
    r = CliRunner().invoke(app, ["solve", "--preset", "straight_tube", "--tensions-n", "0.2,0,0", "--tip-force-n",
                                 "0,0,-0.05", "--no-gravity", "--json", "--out", str(tmp_path)])
    assert r.exit_code == 0, r.output
    line = [ln for ln in r.stdout.splitlines() if ln.startswith("{")][-1]
    d = json.loads(line)
    assert len(d["tip_position_m"]) == 3 and d["iterations"] >= 1
    assert d["tensions_N"] == [0.2, 0.0, 0.0]
    import meshio
    vtu = meshio.read(tmp_path / "result.vtu")         # the fields ParaView users expect (tests/test_fem/test_fem_fields.py)
    assert {"displacement", "chamber_pressure_Pa"} <= set(vtu.point_data)
    assert {"cauchy_stress_Pa", "von_mises_Pa", "pressure_Pa", "principal_stretches"} <= set(vtu.cell_data)
    assert json.loads((tmp_path / "result.json").read_text())["pressure_Pa"] == 0.0
    # not a terminal: progress as plain lines, one per load step (never only at the end, never a bar)
    steps = [ln for ln in r.stderr.splitlines() if ln.startswith("load λ = ")]
    assert len(steps) == d["load_steps"] and steps[-1].startswith("load λ = 1.000"), r.stderr


def test_cli_rejects_bad_input(capsys):
    from validation.commands.main import main

    for args, message in ((["--tensions-n", "1,2"], "expected 3"),
                          (["--preset", "straight_tube", "--tensions-n", "-1,0,0"], "push")):
        with pytest.raises(SystemExit) as info:
            main(["fem", "solve", *args])
        err = capsys.readouterr().err
        lines = err.strip().splitlines()
        assert info.value.code == 2 and len(lines) == 1 and lines[0].startswith("error:") and message in err


def test_cli_info():
    r = CliRunner().invoke(app, ["info"])
    assert r.exit_code == 0 and "wall_thickness" in r.output


def test_render_png_headless(tmp_path):
    pytest.importorskip("pyvista")
    from fem_reference import BellowsGeometry, BellowsModel, Material, MeshLevel
    from fem_reference.render import render_result

    M = BellowsModel(BellowsGeometry.straight_tube(0.08, 0.015, 0.004, n_segments=2),
                     Material.neo_hookean(0.8e6, 40e6), MeshLevel(2, 1, 12, 1))
    res = M.solve(tensions=(0.5, 0, 0))
    p = render_result(res, tmp_path / "r.png", window_size=(400, 300))
    import matplotlib.image as mpimg

    img = mpimg.imread(p)
    assert img.shape[:2] == (300, 400)
    assert np.std(img[..., :3]) > 0.01  # not a blank frame
