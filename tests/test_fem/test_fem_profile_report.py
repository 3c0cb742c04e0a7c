"""A design whose wall is a profile table goes through the whole quick report (FEM experiments, identification,
validation, the report): ``bellows report --quick --design <table design>`` end to end (slow: the FEM sweep of
25 load cases: 190 s measured).  The table is the paper design exported exactly (fem_reference.profile_export),
so its headline numbers are the built-in design's (measured: held-out tip error mean 0.62 %, max 1.61 % of L on
both, the same to 1e-9)."""

import json
import subprocess
import sys

import pytest

from fem_reference import presets
from fem_reference.profile import write_profile_csv
from fem_reference.profile_export import export_profile

DESIGN = """name = "paper, wall as a table"
profile_file = "wall.csv"
n_convolutions = 8
collar_length_mm = 5
tendon_radius_mm = 27.5
tendon_angles_deg = [0, 120, 240]
cap_mass_g = 18
cap_com_offset_mm = 2.5

[material]
mu_MPa = 0.8
kappa_MPa = 40

[limits]
tension_max_N = 5
pressure_max_kPa = 100
"""


@pytest.mark.slow
def test_quick_report_of_a_table_design(tmp_path):
    write_profile_csv(export_profile(presets.paper_bellows(), ("coarse",), spacing=2e-4), tmp_path / "wall.csv")
    (tmp_path / "design.toml").write_text(DESIGN)
    out = tmp_path / "report"
    run = subprocess.run([sys.executable, "-m", "validation.commands.main", "report", "--quick", "--design",
                          str(tmp_path / "design.toml"), "--out", str(out), "--cache", str(tmp_path / "cache")],
                         capture_output=True, text=True, timeout=3600, check=False)
    assert run.returncode == 0, run.stderr[-3000:]
    assert "Traceback" not in run.stderr
    for name in ("report.html", "actuator.toml", "validation.json"):
        assert (out / name).is_file(), name
    assert json.loads((out / "validation.json").read_text())
