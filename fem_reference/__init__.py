"""fem_reference — scikit-fem 3-D hyperelastic reference model of the tendon-pneumatic bellows.

An independent, higher-fidelity model that the reduced ANCF model is identified from and validated
against.  SI units everywhere (m, N, Pa, kg).  World frame: base cap at the origin, undeformed axis
along ``+x``, gravity ``(0, 0, -9.81)``, tendon angle θ about ``+x`` from ``+z``.

Quick start::

    from fem_reference import BellowsGeometry, Material, BellowsModel, presets

    geo = presets.paper_bellows()                       # GUESSED dimensions: presets.GUESSED
    mat = presets.paper_material()                      # Material.neo_hookean(mu=0.8e6, kappa=40e6)
    model = BellowsModel(geo, mat, mesh="coarse")       # "coarse" (tests, seconds) | "reference"
    res = model.solve(tensions=(2, 0, 0), pressure=30e3, tip_force=(0, 0, -0.49), gravity=True)
    res.tip_position, res.cap_rotation, res.centreline, res.tendon_lengths, res.iterations
    res.save_vtu("out.vtu")
    C = model.tip_compliance(res, mode="tension")       # 3×3 [m/N]; mode="locked" too
    rod = model.equivalent_rod()                        # EA, EI, D_a, D_eff (identification)
    locked = model.solve(locked_lengths=res.tendon_lengths[:1].tolist() + [None, None],
                         pressure=50e3, tip_force=(0, 0, -0.49), gravity=True, initial=res)

Command line (the product's, :mod:`validation.commands.fem`)::

    bellows fem solve --pressure-kpa 30 --tensions-n 2,0,0 --tip-force-n 0,0,-0.49 \\
        --gravity --mesh coarse --out out/ --png

What is modelled (details and derivations in the module docstrings):

- :mod:`.geometry` — parametric sine-profile bellows / straight tube, exact normal offset of the wall.
- :mod:`.mesh` — structured, exactly curved 27-node hexahedra (revolved lattice), signed-Jacobian
  check, meshio save/load.  Levels ``coarse``, ``medium``, ``reference``.
- :mod:`.material` — decoupled (default) or ex43 compressible neo-Hookean, decoupled Mooney–Rivlin;
  ``P`` and ``∂P/∂F`` (checked against finite differences).  Near incompressibility (κ/μ = 50,
  ν ≈ 0.49) with the mixed u–p wall element (27-node hexahedra with a discontinuous linear pressure,
  condensed per element; ``BellowsModel(element="mixed")``, the default): locking-free in bending of the
  thin curved wall, where full-integration Hex27 alone (``element="displacement"``) is ~30 % too stiff at
  one layer and κ/μ = 50 (docs/fem.md §3a).
- :mod:`.verification` — closed-form problems (uniaxial block, Rivlin ring, tube beam theory, a thin curved
  wall in bending).
- :mod:`.assembly` — internal force/tangent of both wall elements (compiled and numpy) and the
  follower-pressure (Nanson) load + load stiffness.
- :mod:`.loads` — rigid caps (clamped base, 6-DOF distal cap), cap pressure force, tendons
  (sliding cables, tension or locked length, slack allowed), gravity, tip force.
- :mod:`.model` — Newton with exact tangent, backtracking line search, adaptive load stepping,
  ``ConvergenceError`` with residual history; tip compliance from the condensed tangent.
- :mod:`.stack` — N bellows in series joined by rigid intermediate caps (one chamber each, tendons anchored
  per segment and routed through the segments below): ``StackModel``, ``StackResult``.
- :mod:`.symmetry` — Newton steps in the subspace invariant under the mesh's symmetries that keep the loads.
- :mod:`.corotation` — each ring of nodes turned by a finite rotation in a Newton update.
- :mod:`.transfer` — a solved state carried to a finer mesh of the same bellows (its solve's start).
- :mod:`.sparse_keys` — the fixed sparsity patterns, from sorted entry keys.
- :mod:`.fields` — per-element Cauchy stress, von Mises, pressure and principal stretches (the VTU's cell data).
- :mod:`.render` — headless PNG rendering with pyvista (EGL; see that module for system packages).
- :mod:`.errors` — its errors: the product's exception tree (:mod:`ancf.errors`), or the same names standing
  alone when ``ancf`` is not installed; the FEM needs no other package of the product.
"""

from . import presets
from .geometry import BellowsGeometry
from .material import Material
from .mesh import MESH_LEVELS, BellowsMesh, MeshLevel, build_mesh
from .model import BellowsModel, OperatingLimits
from .results import BellowsResult
from .stack import StackModel, StackResult

__all__ = [
           "MESH_LEVELS",
           "BellowsGeometry",
           "BellowsMesh",
           "BellowsModel",
           "BellowsResult",
           "Material",
           "MeshLevel",
           "OperatingLimits",
           "StackModel",
           "StackResult",
           "build_mesh",
           "presets",
]
