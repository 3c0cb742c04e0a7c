"""Headless rendering of results to PNG with pyvista (VTK).

System requirements (Debian/Ubuntu), measured with pyvista 0.49 / vtk 9.7 wheels (docs/fem.md §7):

- **EGL (default here)**: Mesa's ``libegl-mesa0`` and ``libgl1-mesa-dri`` (llvmpipe software OpenGL;
  no GPU, no X server).  This module sets ``VTK_DEFAULT_OPENGL_WINDOW=vtkEGLRenderWindow`` before
  importing pyvista (unless the variable is already set) to skip the X11 probe.
- **OSMesa** alternative: ``apt-get install libosmesa6`` and
  ``VTK_DEFAULT_OPENGL_WINDOW=vtkOSOpenGLRenderWindow``.
- **Xvfb** alternative: ``apt-get install xvfb`` and run under ``xvfb-run -a``.
  (``pyvista.start_xvfb`` no longer exists in pyvista 0.49.)

pyvista is an optional dependency (extra ``fem``); importing this module does not import it.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np

__all__ = ["render_result", "result_title", "to_pyvista"]


def _pv():
    os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    import pyvista as pv

    pv.OFF_SCREEN = True
    return pv


def to_pyvista(res, deformed: bool = True):
    """``pyvista.UnstructuredGrid`` (triquadratic hexahedra) of a result, with point data
    ``displacement`` [m] and ``|u| [mm]``; points are the deformed positions if ``deformed``."""
    pv = _pv()
    from skfem.io.meshio import to_meshio

    U = res.state.U
    mm = to_meshio(res.model.bmesh.mesh, point_data={"displacement": U.T.copy()})
    grid = pv.from_meshio(mm)
    if deformed:
        grid.points = grid.points + U.T
    grid.point_data["|u| [mm]"] = 1e3 * np.linalg.norm(U, axis=0)
    return grid


def render_result(res, path: str | Path, show_undeformed: bool = True, window_size=(1400, 700),
                  subdivision: int = 2) -> Path:
    """Render the deformed bellows (coloured by |u|), the tendon paths and optionally the undeformed
    outline to a PNG file; side view (x to the right, z up)."""
    pv = _pv()
    grid = to_pyvista(res, deformed=True)
    surf = grid.extract_surface(nonlinear_subdivision=subdivision, algorithm="dataset_surface") \
        if _accepts_algorithm(grid) else grid.extract_surface(nonlinear_subdivision=subdivision)
    pl = pv.Plotter(off_screen=True, window_size=list(window_size))
    pl.add_mesh(surf, scalars="|u| [mm]", cmap="viridis", smooth_shading=True)
    if show_undeformed:
        g0 = to_pyvista(res, deformed=False)
        pl.add_mesh(g0.extract_feature_edges(), color="grey", opacity=0.35)
    M = res.model
    x = M.bmesh.X + res.state.U
    for k, tp in enumerate(M.tendons):
        pts = tp.points(x, M.X_c + res.state.uc, res.state.R)
        T = res.state.T[k]
        pl.add_mesh(pv.lines_from_points(pts), color="red" if T > 0 else "orange", line_width=3)
    tip = res.tip_position
    pl.add_mesh(pv.Sphere(radius=0.002, center=tip), color="black")
    pl.camera_position = "xz"
    pl.camera.up = (0.0, 0.0, 1.0)
    pl.reset_camera()
    pl.camera.zoom(1.7)
    pl.add_text(result_title(res), font_size=10)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    pl.screenshot(str(path))
    pl.close()
    return path


def result_title(res) -> str:
    """Title of a rendered result: the loads and the tip, with units (no numpy repr)."""
    return (f"p = {_num(float(res.loadcase.pressure) * 1e-3)} kPa, T = {_vector(res.state.T, digits=2)} N, "
            f"tip = {_vector(res.tip_position, 1e3)} mm")


def _num(x: float, digits: int = 1) -> str:
    """``x`` with ``digits`` decimals, never ``-0.0`` (``nan``, ``inf``, ``-inf`` as words); the product's text
    rule (ancf.textfmt), kept here so that the FEM needs no other package."""
    x = float(x)
    if not math.isfinite(x):
        return "nan" if math.isnan(x) else ("inf" if x > 0 else "-inf")
    s = f"{x:.{digits}f}"
    return s.lstrip("-") if float(s) == 0 else s


def _vector(v, scale: float = 1.0, digits: int = 1) -> str:
    """``(x, y, z)`` with ``digits`` decimals after multiplying by ``scale`` (no unit, no numpy repr)."""
    return "(" + ", ".join(_num(float(x) * scale, digits) for x in v) + ")"


def _accepts_algorithm(grid) -> bool:
    import inspect

    try:
        return "algorithm" in inspect.signature(grid.extract_surface).parameters
    except (TypeError, ValueError):  # pragma: no cover
        return False
