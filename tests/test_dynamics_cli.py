"""``bellows modes`` and ``bellows simulate``: results written and equal to the Python API's, outputs not
overwritten without --force, errors as one ``error:`` line with exit status 2."""

import csv
import json
import subprocess
import sys

import numpy as np
import pytest

from ancf import Model, presets


def run(*args, cwd):
    return subprocess.run([sys.executable, "-m", "validation.commands.main", *args], cwd=cwd, capture_output=True,
                          text=True, timeout=300)


def test_modes_command_writes_the_api_frequencies(tmp_path):
    r = run("modes", "--tensions-n", "2,0,0", "--pressure-kpa", "30", "--count", "4", "--out", "m", "--json",
            cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    printed = json.loads(r.stdout)
    saved = json.loads((tmp_path / "m" / "modes.json").read_text())
    assert printed == saved
    model = Model(presets.paper())
    f = model.modes(model.fk((2, 0, 0), 30e3), 4).frequencies_hz
    assert np.allclose([row["frequency_Hz"] for row in saved["modes"]], f, rtol=1e-9)
    assert (tmp_path / "m" / "modes.png").stat().st_size > 10_000
    again = run("modes", "--tensions-n", "2,0,0", "--out", "m", cwd=tmp_path)
    assert again.returncode == 2 and again.stderr.count("error:") == 1 and "--force" in again.stderr
    locked = run("modes", "--tensions-n", "2,1,1", "--pressure-kpa", "30", "--locked", "--json", cwd=tmp_path)
    held = run("modes", "--tensions-n", "2,1,1", "--pressure-kpa", "30", "--json", cwd=tmp_path)
    fl = json.loads(locked.stdout)["modes"][0]["frequency_Hz"]
    fh = json.loads(held.stdout)["modes"][0]["frequency_Hz"]
    assert fl > 1.5 * fh                                            # locking stiffens the first mode


def test_simulate_command_writes_the_run(tmp_path):
    r = run("simulate", "--tensions-n", "2,0,0", "--pressure-kpa", "30", "--t-end-s", "0.3", "--dt-ms", "5",
            "--damping-ratio", "0.1", "--out", "s", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    rows = list(csv.DictReader(open(tmp_path / "s" / "simulation.csv")))
    assert len(rows) == 61 and float(rows[-1]["t_s"]) == pytest.approx(0.3)
    summary = json.loads((tmp_path / "s" / "simulation.json").read_text())
    model = Model(presets.paper())
    from ancf.dynamics import rayleigh_about
    settled = model.fk((2, 0, 0), 30e3)
    sim = model.simulate(0.3, 5e-3, q0=model.fk((0, 0, 0), 30e3).q, tensions=(2, 0, 0), pressure=30e3,
                         damping=rayleigh_about(model, settled, 0.1))      # the ratio about the settled state
    assert np.allclose([float(rows[-1][f"tip_{c}_mm"]) for c in "xyz"], sim.tip[-1] * 1e3, atol=1e-5)
    assert np.allclose(summary["tip_end_mm"], sim.tip[-1] * 1e3, atol=1e-9)
    assert summary["static_tip_mm"] == pytest.approx(model.fk((2, 0, 0), 30e3).tip * 1e3, abs=1e-6)
    assert (tmp_path / "s" / "simulation.png").stat().st_size > 10_000


@pytest.mark.parametrize("args, text", [
    (("simulate", "--tensions-n", "2,0", "--t-end-s", "0.1"), "expected 3 values"),
    (("simulate", "--tensions-n", "2,0,0", "--dt-ms", "0"), "'--dt-ms': must be a finite number > 0"),
    (("simulate", "--tensions-n", "9,0,0", "--t-end-s", "0.1"), "--no-limits"),
    (("modes", "--count", "0"), "count"),
])
def test_bad_options_are_one_error_line(tmp_path, args, text):
    r = run(*args, "--out", "x", cwd=tmp_path) if args[0] == "simulate" else run(*args, cwd=tmp_path)
    assert r.returncode == 2 and r.stderr.count("error:") == 1 and text in r.stderr, r.stderr
    assert "Traceback" not in r.stderr


def test_modes_rows_label_kind_by_strain_energy_and_give_the_tip_direction(tmp_path):
    """modes.json: each row's kind follows the axial share of its strain energy (the bent state's 35.8 Hz mode
    is axial), the tip's motion is a unit vector named tip_direction (no millimetres), and an actuator
    without damping is said to be one (stderr warning, damping_source "none")."""
    r = run("modes", "--tensions-n", "2,0,0", "--pressure-kpa", "30", "--count", "6", "--json", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    data = json.loads(r.stdout)
    rows = data["modes"]
    assert all("tip_shape_mm" not in row for row in rows)
    assert all(np.linalg.norm(row["tip_direction"]) == pytest.approx(1.0, abs=1e-12) for row in rows)
    model = Model(presets.paper())
    api = model.modes(model.fk((2, 0, 0), 30e3), 6)
    assert [row["kind"] for row in rows] == list(api.kinds)
    assert [row["axial_energy_share"] for row in rows] == pytest.approx(api.axial_share, abs=1e-12)
    axial = [row for row in rows if row["kind"] == "axial"]
    assert len(axial) == 1 and axial[0]["frequency_Hz"] == pytest.approx(35.8, abs=0.05)
    assert data["damping_source"] == "none" and "states no damping" in data["damping_warning"]
    assert "warning:" in r.stderr and "states no damping" in r.stderr and "error:" not in r.stderr
    table = run("modes", "--tensions-n", "2,0,0", "--pressure-kpa", "30", "--count", "6", cwd=tmp_path)
    assert "tip direction [-]" in table.stdout and "axial share [-]" in table.stdout
    given = run("modes", "--count", "2", "--damping-ratio", "0.05", "--json", cwd=tmp_path)
    assert json.loads(given.stdout)["damping_source"] == "given" and "warning:" not in given.stderr


def test_simulate_warns_when_the_actuator_states_no_damping(tmp_path):
    r = run("simulate", "--tensions-n", "2,0,0", "--pressure-kpa", "30", "--t-end-s", "0.02", "--dt-ms", "5",
            "--out", "u", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "warning:" in r.stderr and "states no damping" in r.stderr and "UNDAMPED" in r.stdout
    assert "UndampedWarning" not in r.stderr                          # said once, as a CLI line
    summary = json.loads((tmp_path / "u" / "simulation.json").read_text())
    assert summary["damping_source"] == "none" and "will not settle" in summary["damping_warning"]
    d = run("simulate", "--tensions-n", "2,0,0", "--pressure-kpa", "30", "--t-end-s", "0.02", "--dt-ms", "5",
            "--damping-ratio", "0.05", "--out", "d", cwd=tmp_path)
    assert d.returncode == 0 and "warning:" not in d.stderr and "UNDAMPED" not in d.stdout
    summary = json.loads((tmp_path / "d" / "simulation.json").read_text())
    assert summary["damping_source"] == "given" and "damping_warning" not in summary
