r"""ParaView output of the rod model: one ``.vtu`` per state with the mechanics as point data, and ``.pvd``
collections (time series of ``.vtu`` frames) for transient runs and animated mode shapes.

A state's ``.vtu`` holds polylines (VTK unstructured grid, line cells): the centreline (cell data
``curve`` = 0) and each tendon path (``curve`` = i for tendon i), sampled at ``per_element`` + 1 points per
element.  Point data (units in the names; docs/data-formats.md, "Opening results in ParaView"):

* ``radius_m`` — the section radius r = √(A(λ)/π) = (D_eff/2) √(1 + β (λ − 1)) of the effective pressure
  section A(λ) the model uses (:meth:`ancf.ActuatorParams.pressure_area`), not the outer radius of the
  convolutions; on the tendon lines a thin display radius D_eff/40 (not a physical size).  ParaView's
  Tube filter with "Vary Radius: By Absolute Scalar" on ``radius_m`` draws the bellows.
* ``stretch`` — λ = |r_x| (1: the undeformed length).
* ``curvature_per_m`` — κ = |r_x × r_xx| / λ³, the curvature per deformed arc length (1/R of the osculating
  circle), the κ of the bending energy (:mod:`ancf.forces.bending`).
* ``bending_stiffness_Nm2`` — EI(λ, p) of the model's stiffness law at the state's pressure
  (:meth:`ancf.StiffnessLaw.EI`).
* ``bending_moment_Nm`` — the constitutive bending moment of the model.  The bending energy is
  U_b = ½ ∫ EI(λ, p) κ² dx over the *undeformed* arc length x, and the section turns by dθ/dx = λ κ per
  unit of x, so the moment work-conjugate to the rotation is

      M = ∂(½ EI κ²)/∂(λ κ) |_λ = EI(λ, p) κ / λ,

  equal to EI κ at λ = 1.  (A rod bent by one tendon of tension T at distance d, without gravity or tip
  load, carries M = T d along its whole length: a closed form the tests check.)
* ``axial_force_N`` — N = W'(λ) = ½ EA(λ, p)(λ³ − λ), the constitutive axial force of the axial energy
  (:mod:`ancf.stiffness`; tension positive).  Pressure and tendons add their own loads: in a straight
  state under an axial tip force F at pressure p (β = 0), N = F + p A_eff − Σ T_i.
* ``tension_N`` — the tendon's tension on its line, 0 on the centreline.
* ``undeformed_arc_length_m`` — x ∈ [0, L] of the section.

The section values (``stretch``, ``curvature_per_m``, ``bending_*``, ``axial_force_N``,
``undeformed_arc_length_m``) are also written on the tendon points of the same section.  At an element
boundary r_xx jumps (the Hermite elements are C¹), so κ there is the mean of the two elements' values.

A ``.pvd`` is the VTK collection format ParaView opens as one time series::

    <VTKFile type="Collection" version="0.1" byte_order="LittleEndian">
      <Collection>
        <DataSet timestep="0.001" group="" part="0" file="simulation/simulation_000001.vtu"/> ...

``NAME.pvd`` keeps its frames in the folder ``NAME/`` next to it (``NAME_000000.vtu``, …), file names
relative to the ``.pvd``.
"""

from __future__ import annotations

import math
import os
import pathlib
import xml.etree.ElementTree as ET
from typing import Iterable, Optional

import numpy as np

from . import kinematics as kin
from .errors import InputError, OutputExistsError

#: Display radius of the tendon lines as a fraction of D_eff (not a physical size).
TENDON_DISPLAY_RADIUS = 1.0 / 40.0
#: Frames per period of an animated mode shape.
MODE_FRAMES = 24
#: Tip amplitude of an animated mode shape, as a fraction of the undeformed length (the modes.png scale).
MODE_TIP_AMPLITUDE = 0.12


# ============================================================================ one state
def section_fields(model, q, pressure: float, per_element: int = 10) -> dict:
    """Section quantities at the centreline points of :meth:`ancf.Model.centreline` (``per_element`` + 1
    points per element, shared nodes once): arrays (k,) ``undeformed_arc_length_m``, ``stretch``,
    ``curvature_per_m``, ``bending_stiffness_Nm2``, ``bending_moment_Nm``, ``axial_force_N``, ``radius_m``
    (module docstring).  ``q`` (ndof,) full coordinates, ``pressure`` [Pa]."""
    q = model._q(q)
    k = model._per_element(per_element)
    p = model.params
    l0 = p.length / p.n_elements
    H = kin.hermite(np.linspace(0.0, 1.0, k + 1), l0)          # (3, 4, k+1)
    qn = q.reshape(-1, 6)
    lam, kap = [], []
    for e in range(p.n_elements):
        blocks = np.array([qn[e, :3], qn[e, 3:], qn[e + 1, :3], qn[e + 1, 3:]])
        a, b = H[1].T @ blocks, H[2].T @ blocks                # r_x, r_xx (k+1, 3)
        la = np.linalg.norm(a, axis=1)
        ka = np.linalg.norm(np.cross(a, b), axis=1) / la ** 3
        if e == 0:
            lam.append(la), kap.append(ka)
        else:
            kap[-1][-1] = 0.5 * (kap[-1][-1] + ka[0])          # C¹ elements: r_xx jumps at a node
            lam.append(la[1:]), kap.append(ka[1:])
    lam, kap = np.concatenate(lam), np.concatenate(kap)
    law = p.stiffness
    EI = np.asarray(law.EI(lam, pressure), float)
    EA = np.asarray(law.EA(lam, pressure), float)
    return {"undeformed_arc_length_m": np.linspace(0.0, p.length, len(lam)), "stretch": lam,
            "curvature_per_m": kap, "bending_stiffness_Nm2": EI, "bending_moment_Nm": EI * kap / lam,
            "axial_force_N": 0.5 * EA * (lam ** 3 - lam),
            "radius_m": np.sqrt(np.asarray(p.pressure_area(lam), float) / math.pi)}


def rod_mesh(model, q, tensions, pressure: float, per_element: int = 10, point_data: Optional[dict] = None):
    """A :class:`meshio.Mesh` of the state ``q`` (ndof,) at ``tensions`` (m,) [N] and ``pressure`` [Pa]:
    centreline and tendon polylines with the point data of the module docstring, plus ``point_data``
    ({name: array (points, …)} over the same points: centreline first, then each tendon)."""
    import meshio

    c = model.centreline(q, per_element)
    tendons = model.tendon_paths(q, per_element)
    T = np.asarray(tensions, float).reshape(model.m)
    sec = section_fields(model, q, pressure, per_element)
    n, m = len(c), len(tendons)
    data = {name: np.tile(v, m + 1) for name, v in sec.items()}
    data["radius_m"][n:] = model.params.D_eff * TENDON_DISPLAY_RADIUS
    data["tension_N"] = np.concatenate([np.zeros(n)] + [np.full(n, T[i]) for i in range(m)])
    for name, v in (point_data or {}).items():
        v = np.asarray(v, float)
        if v.shape[0] != n * (m + 1):
            raise InputError(f"point data {name!r} has {v.shape[0]} rows for {n * (m + 1)} points")
        data[name] = v
    lines = [np.column_stack([np.arange(i * n, (i + 1) * n - 1), np.arange(i * n + 1, (i + 1) * n)])
             for i in range(m + 1)]
    return meshio.Mesh(np.vstack([c, *tendons]), [("line", ln) for ln in lines], point_data=data,
                       cell_data={"curve": [np.full(n - 1, i) for i in range(m + 1)]})


def save_rod_vtu(path, model, q, tensions, pressure: float, per_element: int = 10) -> pathlib.Path:
    """Write :func:`rod_mesh` of one state to ``path`` (.vtu), creating the folder.  Returns the path."""
    path = pathlib.Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    rod_mesh(model, q, tensions, pressure, per_element).write(path)
    return path


# ============================================================================ collections
def frames_folder(pvd) -> pathlib.Path:
    """The folder of a ``.pvd``'s frames: ``NAME.pvd`` → ``NAME/``."""
    pvd = pathlib.Path(pvd)
    return pvd.with_suffix("")


def prepare_pvd(path, *, force: bool = False) -> pathlib.Path:
    """Check before any work that the collection ``path`` (.pvd) and its frames folder can be written: the
    suffix is .pvd, neither exists unless ``force`` (:class:`OutputExistsError`), the folder is writable.
    Returns the path."""
    from .outputs import prepare_output_dir, prepare_output_file
    p = prepare_output_file(path, force=force, suffixes=(".pvd",))
    d = frames_folder(p)
    if d.exists() and not d.is_dir():
        raise InputError(f"{d} exists and is not a folder: it would hold the frames of {p.name}")
    if d.is_dir() and any(d.iterdir()) and not force:
        raise OutputExistsError(f"{d} holds files (frames of an earlier {p.name}?); use --force to overwrite "
                                "them, or another name")
    prepare_output_dir(d, force=True)
    return p


def write_pvd(path, frames: Iterable[tuple[float, object]]) -> pathlib.Path:
    """Write the ``(time [s], meshio.Mesh)`` frames as ``NAME/NAME_000000.vtu``, … and the collection
    ``path`` (``NAME.pvd``) listing them with their times (increasing; InputError otherwise).  Frames of an
    earlier collection of the same name left in the folder are removed; the .pvd is written last (through
    a temporary file), so a collection never names a missing frame.  Check the path first with
    :func:`prepare_pvd`.  Returns the path."""
    path = pathlib.Path(path)
    d = frames_folder(path)
    d.mkdir(parents=True, exist_ok=True)
    for old in d.glob(f"{path.stem}_*.vtu"):
        old.unlink()
    root = ET.Element("VTKFile", type="Collection", version="0.1", byte_order="LittleEndian")
    coll = ET.SubElement(root, "Collection")
    last = -math.inf
    for k, (t, mesh) in enumerate(frames):
        t = float(t)
        if not t > last:
            raise InputError(f"{path.name}: frame times must increase, got {t!r} after {last!r}")
        last = t
        name = f"{path.stem}_{k:06d}.vtu"
        mesh.write(d / name)
        ET.SubElement(coll, "DataSet", timestep=repr(t), group="", part="0", file=f"{d.name}/{name}")
    if not len(coll):
        raise InputError(f"{path.name}: no frames to write")
    ET.indent(root)
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    ET.ElementTree(root).write(tmp, encoding="utf-8", xml_declaration=True)
    os.replace(tmp, path)
    return path


def read_pvd(path) -> list[tuple[float, pathlib.Path]]:
    """The ``(time [s], frame file)`` entries of a ``.pvd`` collection, in file order (paths resolved
    against the collection's folder)."""
    path = pathlib.Path(path)
    try:
        root = ET.parse(path).getroot()
    except (OSError, ET.ParseError) as exc:
        raise InputError(f"{path}: not a readable .pvd collection ({exc})") from None
    if root.get("type") != "Collection":
        raise InputError(f"{path}: not a VTK collection (type {root.get('type')!r})")
    return [(float(ds.get("timestep")), path.parent / ds.get("file")) for ds in root.iter("DataSet")]


# ============================================================================ transient runs and modes
def frame_indices(rows: int, max_frames: int) -> np.ndarray:
    """At most ``max_frames`` (≥ 2) row indices spread evenly over ``rows`` rows, the first and the last
    included, increasing."""
    if rows < 1:
        raise InputError("no rows to write as frames")
    if isinstance(max_frames, bool) or not isinstance(max_frames, (int, np.integer)) or max_frames < 2:
        raise InputError(f"the number of frames must be an integer >= 2, got {max_frames!r}")
    return np.unique(np.round(np.linspace(0, rows - 1, min(rows, int(max_frames)))).astype(int))


def simulation_frames(model, sim, max_frames: int = 100, per_element: int = 10):
    """``(t [s], mesh)`` frames of a :class:`ancf.dynamics.transient.Simulation` (at most ``max_frames`` of
    its output rows, :func:`frame_indices`), each a :func:`rod_mesh` at the row's tensions and pressure."""
    for i in frame_indices(len(sim.t), max_frames):
        yield float(sim.t[i]), rod_mesh(model, sim.q[i], sim.tensions[i], float(sim.pressure[i]), per_element)


def mode_amplitude(model, eq, shape: np.ndarray, tip_shape: np.ndarray, frames: int = MODE_FRAMES) -> float:
    """Scale [q units per unit shape] of an animated mode: the tool point moves ± ``MODE_TIP_AMPLITUDE`` × L
    (as in modes.png), halved (at most 8 times) until every frame is inside the model's domain."""
    amp = MODE_TIP_AMPLITUDE * model.params.length / max(float(np.linalg.norm(tip_shape)), 1e-300)
    s = np.sin(2 * np.pi * np.arange(frames) / frames)
    for _ in range(9):
        if all(model.inadmissibility(eq.q + amp * sk * shape) is None for sk in s):
            return amp
        amp /= 2
    raise InputError("the mode shape leaves the model's domain even at 1/256 of the display amplitude")


def mode_frames(model, eq, shape, frequency_hz: float, amplitude: float, frames: int = MODE_FRAMES,
                per_element: int = 10):
    """``(t [s], mesh)`` frames of one period 1/f of q(t) = q_eq + ``amplitude`` sin(2π f t) φ (the undamped
    oscillation in the mode shape φ; the last frame is one step before the period closes, so a looped
    animation is smooth).  Point data ``displacement_m`` (3 per point): the motion from the equilibrium."""
    base = rod_mesh(model, eq.q, eq.tensions, eq.pressure, per_element).points
    f = float(frequency_hz)
    if not f > 0:
        raise InputError(f"a mode needs a positive frequency, got {f!r} Hz")
    for k in range(frames):
        q = eq.q + amplitude * math.sin(2 * math.pi * k / frames) * np.asarray(shape, float)
        pts = np.vstack([model.centreline(q, per_element), *model.tendon_paths(q, per_element)])
        yield k / (frames * f), rod_mesh(model, q, eq.tensions, eq.pressure, per_element,
                                         {"displacement_m": pts - base})


def mode_pvd_names(count: int) -> list[str]:
    """The collections ``bellows modes --pvd`` writes, and their frame folders: mode_1.pvd, mode_1, …"""
    return [n for k in range(count) for n in (f"mode_{k + 1}.pvd", f"mode_{k + 1}")]


def write_mode_pvds(folder, model, eq, result) -> list[dict]:
    """``mode_k.pvd`` (k = 1 …) in ``folder``: each mode of ``result`` (:class:`ancf.dynamics.modes.ModalResult`)
    animated over one period.  Returns per mode {file, tip_amplitude_m, period_s}."""
    folder = pathlib.Path(folder)
    out = []
    for j, f in enumerate(result.frequencies_hz):
        amp = mode_amplitude(model, eq, result.shapes[j], result.tip_shapes[j])
        path = write_pvd(folder / f"mode_{j + 1}.pvd", mode_frames(model, eq, result.shapes[j], f, amp))
        out.append({"file": path.name, "tip_amplitude_m": amp * float(np.linalg.norm(result.tip_shapes[j])),
                    "period_s": 1.0 / float(f)})
    return out
