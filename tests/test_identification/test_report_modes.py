"""The report's Dynamics section: the identified rod's first bending and axial modes per pressure beside the
FEM's.  Default-run tests use synthetic measurements (a fit in seconds), stand-in FEM rows where the FEM
is not the subject, and a small straight-tube mesh where it is; the real `paper` numbers are a slow test."""

import json
import re

import numpy as np
import pytest

from ancf import Model
from validation.reference import fem_sweep
from validation.identification import identify
from validation.commands import identify as cli
from validation.reference.experiments import default_design
from validation.checks.modes_compare import (MEASURED_NOTE, NO_MASS_NOTE, QUICK_NOTE, compare_modes, report_pressures,
                                      rod_modes)
from validation.report.build import build_report

from test_fit import BASE
from test_report_cli import _states
from test_report_tables import _tables

MASSES = dict(line_mass=0.3, tip_mass=0.01)


@pytest.fixture(scope="module")
def result():
    return identify.from_measurements(_states(default_design()), BASE.replace(**MASSES), forms=("separate",),
                                      gravity=False)


def _fake_fem(pressures, bending=3.0, axial=25.0):
    """FEM rows as run_modes returns them: bending rising 10 % per step, axial constant."""
    return [{"pressure_Pa": p, "bending_hz": bending * 1.1 ** k, "axial_hz": axial, "frequencies_hz": [1.0],
             "total_mass_kg": 0.06, "seconds": 0.0, "error": ""} for k, p in enumerate(pressures)]


def _dynamics_table(html):
    return next(t for t in _tables(html) if any("bending f₁" in h for h in t["head"]))


def test_rod_frequencies_are_model_modes_of_the_fitted_parameters(result):
    """The rod's columns are Model.modes of the report's fitted parameters (gravity off beside the FEM): its
    lowest mode (bending, twice) and the first mode whose tool point moves along the axis."""
    p = result.params.replace(gravity=(0.0, 0.0, -9.81))           # an actuator file under gravity
    pressures = report_pressures(p.pressure_max)
    assert pressures == [0.0, 0.5 * p.pressure_max, p.pressure_max]
    m = compare_modes(p, pressures, [0.0] * 3, fem=_fake_fem(pressures))
    model = Model(p.replace(gravity=(0.0, 0.0, 0.0)))
    for row, pr in zip(m["rows"], pressures):
        eq = model.fk((0.0, 0.0, 0.0), pr)
        md = model.modes(eq, 8)
        axis = eq.tip / np.linalg.norm(eq.tip)
        axial = [f for f, u in zip(md.frequencies_hz, md.tip_shapes) if abs(u @ axis) > 0.9 * np.linalg.norm(u)]
        assert row["rod_bending_frequency_hz"] == pytest.approx(md.frequencies_hz[0], rel=1e-12)
        assert md.frequencies_hz[1] == pytest.approx(md.frequencies_hz[0], rel=1e-6)      # the pair
        assert row["rod_axial_frequency_hz"] == pytest.approx(axial[0], rel=1e-12)
        assert row["rod_axial_frequency_hz"] > 2 * row["rod_bending_frequency_hz"]
        assert row["bending_difference_pct"] == pytest.approx(
            100 * (row["rod_bending_frequency_hz"] / row["fem_bending_frequency_hz"] - 1), rel=1e-12)
        assert row["axial_difference_pct"] == pytest.approx(
            100 * (row["rod_axial_frequency_hz"] / row["fem_axial_frequency_hz"] - 1), rel=1e-12)
        assert "rod_first_mode_damping_ratio" not in row                # undamped actuator: no column
    # gravity changes the state and so the rod's modes: the comparison with the FEM has none
    with_g = rod_modes(p, 0.0, (0, 0, 0), gravity=True)["bending_hz"]
    assert with_g != pytest.approx(m["rows"][0]["rod_bending_frequency_hz"], rel=1e-6)


def test_the_report_shows_the_section_and_fit_json_carries_it(result, tmp_path):
    p = result.params
    pressures = report_pressures(p.pressure_max)
    m = compare_modes(p, pressures, [0.0] * 3, fem=_fake_fem(pressures))
    html = build_report(result, modes=m, figures={})
    assert re.search(r"<h2 id=\"sec-dynamics\">\d\. Dynamics: first modes per pressure</h2>", html)
    t = _dynamics_table(html)
    assert t["head"][:4] == ["pressure [kPa]", "FEM bending f₁ [Hz]", "rod bending f₁ [Hz]", "bending difference [%]"]
    rows = [r for r in t["rows"] if r]
    assert [r[0] for r in rows] == [f"{x / 1e3:g}" for x in pressures]
    for r, d in zip(rows, m["rows"]):
        assert r[2] == f"{d['rod_bending_frequency_hz']:.3f}" and r[3] == f"{d['bending_difference_pct']:+.1f}"
    assert "pressure dependence of EI" in html
    assert re.search(r"FEM(&#39;|')s first bending frequency changes by \+21 %", html)       # 1.1² − 1 of the stand-in
    assert '<h2 id="sec-diagnostics">4. Diagnostics</h2>' in html                     # numbering follows
    assert "Dynamics" not in build_report(result, figures={})                         # no data, no section
    result.modes = m
    try:
        d = json.loads(result.save(tmp_path / "fit.json").read_text())
    finally:
        result.modes = None
    assert d["modes"]["rows"][0]["rod_bending_frequency_hz"] == m["rows"][0]["rod_bending_frequency_hz"]
    assert {"pressure_kPa", "fem_bending_frequency_hz", "rod_axial_frequency_hz", "axial_difference_pct"} <= \
        set(d["modes"]["rows"][0])
    assert "modes" not in json.loads(result.save(tmp_path / "fit2.json").read_text())   # only when computed


def test_damping_of_the_actuator_file_gives_the_first_mode_ratio(result):
    """Rayleigh α gives ζ₁ = α / (2 ω₁) exactly: the report's ratio column."""
    p = result.params.replace(rayleigh_alpha=2.0)
    m = compare_modes(p, [0.0, 60e3], [0.0] * 3, fem_note=QUICK_NOTE)
    for row in m["rows"]:
        w = 2 * np.pi * row["rod_bending_frequency_hz"]
        assert row["rod_first_mode_damping_ratio"] == pytest.approx(2.0 / (2 * w), rel=1e-9)
    assert m["damping"]["rayleigh_alpha_per_s"] == 2.0
    html = build_report(result, modes=m, figures={})
    t = _dynamics_table(html)
    assert t["head"][-1] == "rod damping ratio, first mode [–]"
    assert t["rows"][1][-1] == f"{m['rows'][0]['rod_first_mode_damping_ratio']:.4f}"
    assert QUICK_NOTE in html


def test_a_massless_actuator_says_so_once():
    m = compare_modes(BASE.replace(line_mass=0.0), [0.0, 1e4], [0.0] * 3, fem_note=MEASURED_NOTE, gravity=True)
    assert m["rod"] == NO_MASS_NOTE and all(r["rod_bending_frequency_hz"] is None and not r["rod_error"]
                                            for r in m["rows"])


def test_quick_report_skips_the_fem_modes_and_the_full_one_asks_for_them(result, monkeypatch, tmp_path):
    """--quick never calls the FEM modes; the full report asks for 0, 50, 100 % of the design's largest
    pressure with the tendons slack, through the cache folder, and shows what it gets."""
    from validation.reference.designs import load_design
    geo, mat = load_design("paper")
    fem = ("paper", geo, mat, {"tension_max": 5.0, "pressure_max": 100e3})
    calls = []

    def fake(spec, pressures, tensions, *, cache_dir=None, progress=False):
        calls.append((spec.mesh, list(pressures), list(tensions), cache_dir))
        return _fake_fem(pressures)
    monkeypatch.setattr(fem_sweep, "run_modes", fake)
    q = cli._report_modes(result, fem, "coarse", tmp_path, quick=True)
    assert not calls and q["fem"] == QUICK_NOTE and q["rows"][0]["fem_bending_frequency_hz"] is None
    assert q["rows"][2]["rod_bending_frequency_hz"] is not None
    full = cli._report_modes(result, fem, "coarse", tmp_path, quick=False)
    assert calls == [("coarse", [0.0, 50e3, 100e3], [0.0, 0.0, 0.0], tmp_path)]
    assert full["fem"] == "computed" and full["rows"][1]["fem_bending_frequency_hz"] == pytest.approx(3.3)
    meas = cli._report_modes(result, None, "coarse", tmp_path, quick=False)
    assert meas["fem"] == MEASURED_NOTE and meas["gravity"] and len(calls) == 1


def test_cli_report_from_measurements_has_the_section(tmp_path):
    from hardware.static_states import write_static_states
    from test_report_cli import _bellows
    states = write_static_states(tmp_path / "states.h5", _states(default_design()))
    (tmp_path / "base.toml").write_text(BASE.replace(**MASSES, rayleigh_beta=1e-3).to_toml())
    r = _bellows("report", "--measurements", states, "--base", "base.toml", "--forms", "separate", "--out", "rep",
                 cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    fit = json.loads((tmp_path / "rep" / "fit.json").read_text())
    m = fit["modes"]
    assert m["fem"] == MEASURED_NOTE and m["damping"]["rayleigh_beta_s"] == 1e-3
    assert [row["pressure_kPa"] for row in m["rows"]] == [0.0, 60.0, 120.0]
    assert all(row["rod_first_mode_damping_ratio"] > 0 for row in m["rows"])
    assert "Dynamics: first modes per pressure" in (tmp_path / "rep" / "report.html").read_text()
    assert "rayleigh_beta_s = 0.001" in (tmp_path / "rep" / "actuator.toml").read_text()   # kept from --base


# ------------------------------------------------------------------------------------ the FEM side (small mesh)
@pytest.fixture(scope="module")
def tube_spec():
    from fem_reference import BellowsGeometry, Material
    from fem_reference.mesh import MeshLevel
    return fem_sweep.FemSpec(BellowsGeometry.straight_tube(0.16, 0.015, 0.004, n_segments=8),
                             Material.neo_hookean(0.8e6, 40e6), MeshLevel(2, 1, 12, 1))


def test_fem_modes_are_classified_and_cached(tube_spec, tmp_path, monkeypatch):
    """The worker finds the tube's first bending and axial modes (the clamped-free beam and rod of its own
    equivalent rod, like tests/test_fem/test_fem_modes.py); a second call is served from the cache."""
    rows = fem_sweep.run_modes(tube_spec, [0.0], [0.0] * 3, cache_dir=tmp_path)
    model = fem_sweep.fem_model(tube_spec)
    res = model.solve()
    rod = model.equivalent_rod(res)
    mp = (rows[0]["total_mass_kg"] - tube_spec.geometry.cap_mass) / 0.16
    f_bend = 1.87510407 ** 2 / (2 * np.pi * 0.16 ** 2) * np.sqrt(rod["EI_tip_force"] / mp)
    assert rows[0]["bending_hz"] == pytest.approx(f_bend, rel=0.05) and not rows[0]["error"]
    assert rows[0]["axial_hz"] is not None and rows[0]["axial_hz"] > 2 * rows[0]["bending_hz"]
    assert rows[0]["bending_hz"] == pytest.approx(rows[0]["frequencies_hz"][0], rel=1e-12)

    def boom(task):
        raise AssertionError("recomputed despite the cache")
    monkeypatch.setattr(fem_sweep, "modes_chain", boom)
    assert fem_sweep.run_modes(tube_spec, [0.0], [0.0] * 3, cache_dir=tmp_path) == rows


def test_fem_modes_refuse_loads_beyond_the_fem_limits(tube_spec):
    from ancf.errors import InputError, LimitError
    with pytest.raises(LimitError):
        fem_sweep.run_modes(tube_spec, [500e3], [0.0] * 3)
    with pytest.raises(InputError, match="tensions"):
        fem_sweep.run_modes(tube_spec, [0.0], [0.0] * 2)


def test_fem_mode_classification_ignores_torsion():
    axis = np.array([1.0, 0, 0])
    shapes = np.array([[0, 0, 0, 1.0, 0, 0],            # torsion: no translation
                       [0, 1e-3, 0, 0, 0, 0.01],         # bending in y
                       [1e-3, 0, 0, 1e-9, 0, 0]])        # axial
    out = fem_sweep.classify_fem_modes([1.0, 2.0, 3.0], shapes, axis, 0.16)
    assert out == {"bending_hz": 2.0, "axial_hz": 3.0}


# ------------------------------------------------------------------------------------ the documented numbers
@pytest.mark.slow
def test_the_documented_report_modes_are_the_programs_output(tmp_path_factory):
    """docs/identification.md's Dynamics table is the full report's on the `paper` design: the identification
    of every form and the FEM modes rerun (coarse mesh; ~15–20 min on 2 shared cores with an empty cache,
    seconds with the FEM cache of a report run in $BELLOWS_FEM_CACHE)."""
    import os
    import pathlib
    from validation.identification.forms import FORMS
    text = (pathlib.Path(__file__).parents[2] / "docs" / "identification.md").read_text()
    rows = re.findall(r"^\| (\d+) \| ([\d.]+) \| ([\d.]+) \| ([+−-][\d.]+) \| ([\d.]+) \| ([\d.]+) \| ([+−-][\d.]+) \|$",
                      text, re.M)
    assert len(rows) == 3
    cache = pathlib.Path(os.environ.get("BELLOWS_FEM_CACHE") or tmp_path_factory.mktemp("fem_cache"))
    fem = cli._fem_design("paper", None, None)
    res = cli._identify_fem(fem, "coarse", 2, None, cache, FORMS, False)
    m = cli._report_modes(res, fem, "coarse", cache, quick=False)
    for doc, row in zip(rows, m["rows"]):
        got = (f"{row['pressure_kPa']:g}", f"{row['fem_bending_frequency_hz']:.3f}",
               f"{row['rod_bending_frequency_hz']:.3f}", f"{row['bending_difference_pct']:+.1f}",
               f"{row['fem_axial_frequency_hz']:.2f}", f"{row['rod_axial_frequency_hz']:.2f}",
               f"{row['axial_difference_pct']:+.1f}")
        assert tuple(x.replace("−", "-") for x in doc) == got
