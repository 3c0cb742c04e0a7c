"""ParaView outputs (ancf/paraview.py, hardware/runlog_paraview.py): the rod's .vtu arrays against closed forms,
read back with meshio and pyvista; .pvd collections of bellows simulate / modes / log export."""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET

import meshio
import numpy as np
import pytest
from scipy.optimize import brentq

from ancf import Model, presets
from ancf.errors import InputError, OutputExistsError
from ancf.export import save_vtu
from ancf.paraview import frames_folder, prepare_pvd, read_pvd, rod_mesh, save_rod_vtu, write_pvd
from validation.commands.main import main

pv = pytest.importorskip("pyvista")

ARRAYS = {"radius_m", "stretch", "curvature_per_m", "bending_stiffness_Nm2", "bending_moment_Nm", "axial_force_N",
          "tension_N", "undeformed_arc_length_m"}


def law(params):
    """Closed forms of the paper's linear law (docs/design.md §3): EA = a λ + b, EI = D_a² λ (a λ + b) / 8."""
    s = params.stiffness
    assert s.kind == "linear" and not s.EI_pressure and not s.EA_pressure
    a, b, D = s.source["a"], s.source["b"], s.source["D_a"]
    return (lambda lam: a * lam + b), (lambda lam: D ** 2 * lam * (a * lam + b) / 8)


def arc_q(model, R: float, lam: float) -> np.ndarray:
    """Nodal coordinates of a uniform bend in the x–z plane: the centreline a circle of radius R [m],
    stretched uniformly by λ (deformed length λ L), r_x = λ t."""
    p = model.params
    s = np.linspace(0.0, lam * p.length, p.n_elements + 1)       # deformed arc length of each node
    phi = s / R
    r = np.column_stack([R * np.sin(phi), np.zeros_like(phi), R * (1 - np.cos(phi))])
    t = np.column_stack([np.cos(phi), np.zeros_like(phi), np.sin(phi)])
    return np.hstack([r, lam * t]).ravel()


def centreline(mesh, n: int) -> dict:
    return {k: np.asarray(v)[:n] for k, v in mesh.point_data.items()}


@pytest.mark.parametrize("lam", [1.0, 1.08])
def test_uniform_bend_curvature_and_moment(tmp_path, lam):
    """A circle of radius R: curvature 1/R along the whole body; moment EI(λ)/(R λ) (= EI/R at λ = 1);
    stretch λ; radius √(A_eff/π) (β = 0); read back with meshio and pyvista.  (The cubic Hermite elements
    interpolate a circle to O(φ²) in curvature, φ the angle per element: 48 elements, φ ≈ 0.03 rad.)"""
    model = Model(presets.paper().replace(n_elements=48))
    R = 0.12
    path = save_rod_vtu(tmp_path / "bend.vtu", model, arc_q(model, R, lam), (0.0, 0.0, 0.0), 0.0)
    EA, EI = law(model.params)
    n = 48 * 10 + 1
    for mesh in (meshio.read(path), pv.read(path)):
        d = centreline(mesh, n)
        assert ARRAYS <= set(d)
        assert np.allclose(d["curvature_per_m"], 1 / R, rtol=1e-4)
        assert np.allclose(d["stretch"], lam, rtol=1e-9)
        assert np.allclose(d["bending_stiffness_Nm2"], EI(lam), rtol=1e-12)
        assert np.allclose(d["bending_moment_Nm"], EI(lam) / (R * lam), rtol=1e-4)
        assert np.allclose(d["axial_force_N"], 0.5 * EA(lam) * (lam ** 3 - lam), rtol=1e-6, atol=1e-6)
        assert np.allclose(d["radius_m"], model.params.D_eff / 2, rtol=1e-12)
        assert np.allclose(d["undeformed_arc_length_m"], np.linspace(0, model.params.length, n))


def _no_gravity(**changes):
    return Model(presets.paper().replace(gravity=(0.0, 0.0, 0.0), **changes))


def test_tendon_bend_carries_T_times_d():
    """Without gravity or tip load (base stretch free: a uniform state) one tendon of tension T at distance d
    bends the rod with M = T d along its
    whole length (moment balance at any cut), whatever the stretch; and the curvature is uniform."""
    model = _no_gravity(free_base_stretch=True)
    T = 2.0
    eq = model.fk((T, 0.0, 0.0), 30e3)
    mesh = rod_mesh(model, eq.q, eq.tensions, eq.pressure)
    n = len(model.centreline(eq.q))
    d = centreline(mesh, n)
    Td = T * model.params.tendons[0].distance
    inner = slice(0, n)
    assert np.allclose(d["bending_moment_Nm"][inner], Td, rtol=2e-3)
    assert np.ptp(d["curvature_per_m"][inner]) < 5e-3 * d["curvature_per_m"].mean()
    assert np.all(d["stretch"] > 1.01)          # the pressure stretches it: M ≠ EI κ there
    assert not np.allclose(d["bending_stiffness_Nm2"] * d["curvature_per_m"], Td, rtol=5e-3)
    tension = np.asarray(mesh.point_data["tension_N"])
    assert np.all(tension[:n] == 0) and np.all(tension[n:2 * n] == T) and np.all(tension[2 * n:] == 0)


@pytest.mark.parametrize("F, p_kpa", [(5.0, 0.0), (-1.0, 0.0), (2.0, 40.0)])   # -1 N: below Euler buckling
def test_straight_stretch_is_the_closed_form(F, p_kpa):
    """A straight rod (free base stretch, no gravity) under an axial tip force F at pressure p: uniform
    stretch λ with ½ EA(λ)(λ³ − λ) = F + p A_eff (β = 0), axial force that value, curvature 0."""
    model = _no_gravity(free_base_stretch=True)
    EA, _ = law(model.params)
    N = F + p_kpa * 1e3 * model.params.A_eff
    lam = brentq(lambda x: 0.5 * EA(x) * (x ** 3 - x) - N, 0.6, 1.6)
    eq = model.fk((0.0, 0.0, 0.0), p_kpa * 1e3, (F, 0.0, 0.0))
    d = centreline(rod_mesh(model, eq.q, eq.tensions, eq.pressure), len(model.centreline(eq.q)))
    assert np.allclose(d["stretch"], lam, rtol=1e-7)
    assert np.allclose(d["axial_force_N"], N, rtol=1e-6, atol=1e-9)
    assert np.all(d["curvature_per_m"] < 1e-6) and np.all(np.abs(d["bending_moment_Nm"]) < 1e-8)


def test_vtu_layout_and_tube_recipe(tmp_path):
    """save_vtu (bellows fk/ik/locked --vtu, demo): point arrays of one length per point, cell data curve
    (0 centreline, i tendon i);
    the documented recipe (Extract Surface, Threshold curve = 0, Tube by absolute scalar radius_m) draws a
    tube of the section radius around a straight rod."""
    model = _no_gravity(free_base_stretch=True)
    eq = model.fk((0.0, 0.0, 0.0), 0.0)
    path = save_vtu(tmp_path / "s.vtu", model, eq)
    m = meshio.read(path)
    npts = len(m.points)
    assert npts == 4 * len(model.centreline(eq.q))
    for name in ARRAYS:
        assert m.point_data[name].shape == (npts,), name
    assert sorted(np.unique(np.concatenate(m.cell_data["curve"]))) == [0, 1, 2, 3]
    g = pv.read(path)
    body = g.threshold((0, 0), scalars="curve").extract_surface(algorithm="dataset_surface")
    tube = body.tube(scalars="radius_m", absolute=True, n_sides=64)
    r = model.params.D_eff / 2
    assert tube.bounds[3] == pytest.approx(r, rel=2e-3) and tube.bounds[5] == pytest.approx(r, rel=2e-3)


def test_pvd_collection_round_trip(tmp_path):
    """write_pvd: frames in NAME/, times increasing, relative paths; pyvista's PVD reader sees the times;
    decreasing times are refused; an existing collection is kept without force; stale frames go."""
    model = Model(presets.paper())
    eq = model.fk((1.0, 0.0, 0.0), 10e3)
    mesh = rod_mesh(model, eq.q, eq.tensions, eq.pressure)
    times = [0.0, 0.01, 0.025]
    path = write_pvd(prepare_pvd(tmp_path / "run.pvd"), ((t, mesh) for t in times))
    assert [t for t, _ in read_pvd(path)] == times
    assert all(f.parent == frames_folder(path) and f.exists() for _, f in read_pvd(path))
    assert pv.get_reader(str(path)).time_values == pytest.approx(times)
    with pytest.raises(OutputExistsError):
        prepare_pvd(path)
    write_pvd(prepare_pvd(path, force=True), ((t, mesh) for t in times[:2]))
    assert len(list(frames_folder(path).glob("*.vtu"))) == 2
    with pytest.raises(InputError, match="increase"):
        write_pvd(tmp_path / "bad.pvd", ((t, mesh) for t in (0.0, 0.0)))
    with pytest.raises(InputError, match=r"\.pvd"):
        prepare_pvd(tmp_path / "x.vtu")


def _frames(path):
    entries = read_pvd(path)
    times = [t for t, _ in entries]
    assert len(times) >= 2 and all(b > a for a, b in zip(times, times[1:]))
    root = ET.parse(path).getroot()
    assert root.get("type") == "Collection" and len(root.findall("Collection/DataSet")) == len(entries)
    return entries


def test_simulate_pvd(tmp_path, capsys):
    """bellows simulate --pvd: simulation.pvd with frames at the CSV's times (the first and the last), each
    opening in meshio and pyvista with the arrays; no overwrite without --force."""
    out = tmp_path / "sim"
    args = ["simulate", "--tensions-n", "2,0,0", "--pressure-kpa", "30", "--t-end-s", "0.05", "--dt-ms", "5",
            "--out", str(out), "--pvd", "--pvd-frames", "4"]
    with pytest.raises(SystemExit) as e:
        main(args)
    assert e.value.code in (0, None)
    entries = _frames(out / "simulation.pvd")
    csv_t = np.loadtxt(out / "simulation.csv", delimiter=",", skiprows=1, usecols=0)
    assert len(entries) == 4
    assert [t for t, _ in entries][0] == csv_t[0] and [t for t, _ in entries][-1] == pytest.approx(csv_t[-1])
    for _, f in entries:
        m, g = meshio.read(f), pv.read(f)
        assert ARRAYS <= set(m.point_data) and ARRAYS <= set(g.point_data)
        assert g.n_points == len(m.points) and m.point_data["tension_N"].max() == pytest.approx(2.0)
    (out / "simulation.pvd").write_text("keep")
    with pytest.raises(SystemExit) as e:
        main([a for a in args if a != "--pvd-frames" and a != "4"])
    assert e.value.code == 2 and (out / "simulation.pvd").read_text() == "keep"


def test_modes_pvd(tmp_path):
    """bellows modes --pvd: one collection per mode over one period 1/f; the frame a quarter period in is
    the equilibrium plus the shape at the stated amplitude (tool point 12 % of L), checked on the last
    node r_{n+1}, linear in q, against an independent Model.modes."""
    out = tmp_path / "modes"
    with pytest.raises(SystemExit) as e:
        main(["modes", "--tensions-n", "2,0,0", "--pressure-kpa", "30", "--count", "2", "--out", str(out), "--pvd"])
    assert e.value.code in (0, None)
    info = json.loads((out / "modes.json").read_text())
    model = Model(presets.paper())
    eq = model.fk((2.0, 0.0, 0.0), 30e3)
    r = model.modes(eq, 2)
    for j in range(2):
        entries = _frames(out / f"mode_{j + 1}.pvd")
        f = r.frequencies_hz[j]
        assert len(entries) == 24
        assert entries[-1][0] == pytest.approx(23 / 24 / f, rel=1e-6)
        amp = 0.12 * model.params.length / np.linalg.norm(r.tip_shapes[j])
        assert info["paraview"][j]["tip_amplitude_m"] == pytest.approx(0.12 * model.params.length)
        quarter = meshio.read(entries[6][1])
        n = len(model.centreline(eq.q))
        disp = quarter.point_data["displacement_m"][n - 1]
        assert np.allclose(np.abs(disp), np.abs(amp * r.shapes[j][-6:-3]), atol=1e-9)   # shape sign is free
        assert pv.read(entries[0][1]).point_data["displacement_m"] == pytest.approx(0.0, abs=1e-15)
    (out / "mode_2.pvd").write_text("keep")
    (out / "modes.json").unlink()
    with pytest.raises(SystemExit) as e:
        main(["modes", "--count", "2", "--out", str(out), "--pvd"])
    assert e.value.code == 2 and (out / "mode_2.pvd").read_text() == "keep"


def test_modes_pvd_needs_out(capsys):
    with pytest.raises(SystemExit) as e:
        main(["modes", "--pvd"])
    assert e.value.code == 2 and "--out" in capsys.readouterr().err


def _log(path, t, tips, true_tips=None):
    from hardware.runlog import RunLog
    with RunLog(path, n_tendons=3) as log:
        for k, (tk, tip) in enumerate(zip(t, tips)):
            log.sample(t=tk, tip=tip, tension=(1.0 + k, 0.0, 0.5), pressure=3e4, error_norm=0.001 * k,
                       true_tip=None if true_tips is None else true_tips[k])
    return path


def test_log_export_pvd_tip_trajectory(tmp_path, capsys):
    """bellows log export --pvd: frame k is the tip path up to sample k (a NaN tip left out), at the sample's
    time, with the sample's values as point data; the true tip of a simulated rig is curve 1."""
    t = [0.0, 0.1, 0.2, 0.3]
    tips = [(0.16, 0.0, 0.0), (0.161, 0.0, 0.001), (np.nan, np.nan, np.nan), (0.162, 0.001, 0.002)]
    true = [(0.16, 0.0, 0.0)] * 4
    log = _log(tmp_path / "run.h5", t, tips, true)
    with pytest.raises(SystemExit) as e:
        main(["log", "export", str(log), "--pvd", str(tmp_path / "run.pvd"), "--csv", str(tmp_path / "run.csv")])
    assert e.value.code in (0, None), capsys.readouterr().err
    entries = _frames(tmp_path / "run.pvd")
    assert [tk for tk, _ in entries] == [0.0, 0.1, 0.3]
    last = meshio.read(entries[-1][1])
    curve = np.concatenate(last.cell_data["curve"])
    assert set(curve) == {0, 1}
    assert np.allclose(last.points[:3], np.asarray(tips)[[0, 1, 3]])
    assert np.allclose(last.point_data["t_s"][:3], [0.0, 0.1, 0.3])
    assert np.allclose(last.point_data["tension1_N"][:3], [1.0, 2.0, 4.0])
    assert "error_norm_m" in pv.read(entries[-1][1]).point_data
    first = meshio.read(entries[0][1])
    assert len(first.points) == 2                    # one measured and one true sample: two points
    with pytest.raises(SystemExit) as e:
        main(["log", "export", str(log), "--pvd", str(tmp_path / "run.pvd")])
    assert e.value.code == 2


def test_log_export_needs_an_output(tmp_path, capsys):
    log = _log(tmp_path / "run.h5", [0.0], [(0.16, 0, 0)])
    with pytest.raises(SystemExit) as e:
        main(["log", "export", str(log)])
    assert e.value.code == 2 and "--pvd" in capsys.readouterr().err
    nan_log = _log(tmp_path / "nan.h5", [0.0], [(np.nan, np.nan, np.nan)])
    with pytest.raises(SystemExit) as e:
        main(["log", "export", str(nan_log), "--pvd", str(tmp_path / "n.pvd")])
    assert e.value.code == 2 and "tip" in capsys.readouterr().err
