"""Equilibrium results: tip pose, centreline, tendon data, VTU export."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .loads.caps import log_so3

__all__ = ["BellowsResult"]


@dataclass
class BellowsResult:
    """One converged equilibrium of a :class:`fem_reference.BellowsModel` (SI units).

    Attributes
    ----------
    model : BellowsModel
    state : State — nodal displacements ``U (3, n_nodes)`` [m], cap ``uc (3,)`` [m], ``R (3, 3)``, ``T (m,)`` [N]
    loadcase : LoadCase — the loads that were reached (tensions hold the final tensions/multipliers)
    stats : NewtonStats — timings [s], iterations, per-step residual histories
    tendon_lengths : ndarray (m,) — cable path lengths [m]
    stable : bool or None — the reduced tangent is positive definite (on the tangent space of the taut
        locked tendons): a minimum of the potential; None if not checked or inconclusive
    negative_directions : int or None — number of negative eigenvalues of that reduced tangent
    """

    model: object
    state: object
    loadcase: object
    stats: object
    tendon_lengths: np.ndarray
    stable: bool | None = None
    negative_directions: int | None = None

    @property
    def tip_position(self) -> np.ndarray:
        """Tip point (cap centre + ``tip_offset`` along the cap axis), world frame [m], shape (3,)."""
        return self.model.tip_position(self.state)

    @property
    def cap_rotation(self) -> np.ndarray:
        """Rotation matrix of the distal cap (3, 3); its first column is the deformed tip axis."""
        return self.state.R.copy()

    @property
    def cap_rotation_vector(self) -> np.ndarray:
        """Rotation vector of the distal cap [rad], shape (3,)."""
        return log_so3(self.state.R)

    @property
    def cap_centre(self) -> np.ndarray:
        return self.model.X_c + self.state.uc

    @property
    def tensions(self) -> np.ndarray:
        """Tendon tensions [N] (prescribed, or the multipliers of locked tendons), shape (m,)."""
        return self.state.T.copy()

    @property
    def iterations(self) -> int:
        """Total Newton iterations over all load steps."""
        return int(self.stats.n_iterations)

    @property
    def displacement(self) -> np.ndarray:
        """Nodal displacements [m], shape (3, n_nodes)."""
        return self.state.U

    @property
    def centreline(self) -> np.ndarray:
        """Deformed centreline, shape (2 n_s + 1, 3) [m]: mean of each ring of mid-wall nodes.

        Row 0 is the base centre, the last row the distal cap centre; rows follow the fine mesh
        lattice along the axis (vertices and mid-nodes).
        """
        bm = self.model.bmesh
        n_s, n_t, n_th = bm.shape
        x = bm.X + self.state.U
        sel = bm.lattice[1] == n_t
        i_s = bm.lattice[0, sel]
        cnt = np.bincount(i_s, minlength=2 * n_s + 1)
        return np.stack([np.bincount(i_s, weights=x[k, sel], minlength=2 * n_s + 1) / cnt for k in range(3)], 1)

    def summary(self) -> dict:
        """JSON-friendly summary (SI units)."""
        lc = self.loadcase
        return dict(
            tip_position_m=self.tip_position.tolist(),
            cap_rotation_vector_rad=self.cap_rotation_vector.tolist(),
            tensions_N=self.tensions.tolist(),
            tendon_lengths_m=np.asarray(self.tendon_lengths).tolist(),
            pressure_Pa=float(lc.pressure),
            tip_force_N=np.asarray(lc.tip_force).tolist(),
            gravity=float(lc.gravity),
            iterations=self.iterations,
            load_steps=len(self.stats.steps),
            symmetry_order=int(getattr(self.stats, "symmetry_order", 1)),
            timings_s=self.stats.as_dict(),
            n_dofs=int(self.model.n_dofs),
            stable=self.stable,
        )

    def save_vtu(self, path: str | Path) -> Path:
        """Write the deformed state's fields on the reference mesh (hex27 VTU, via meshio) for ParaView.

        Point data (per node):

        - ``displacement`` (n_nodes, 3) [m]: open with "Warp By Vector";
        - ``chamber_pressure_Pa`` (n_nodes,): the applied cavity pressure on the nodes of the loaded inner
          surface, 0 elsewhere.

        Cell data (per element: averages over the deformed element, :func:`fem_reference.fields.cell_fields`):
        ``cauchy_stress_Pa`` (9 components, row-major: a tensor in ParaView), ``von_mises_Pa``, ``pressure_Pa``
        (hydrostatic, ``−tr σ / 3``, positive in compression: the mixed element's pressure field),
        ``principal_stretches`` (3, largest first) and ``volume_ratio``.  ParaView's "Cell Data to Point Data"
        averages them to the nodes.
        """
        import meshio
        from skfem.io.meshio import to_meshio

        from .fields import cell_fields

        model = self.model
        cells = cell_fields(model.asm, self.state.U)
        cells["cauchy_stress_Pa"] = cells["cauchy_stress_Pa"].reshape(-1, 9)
        mm = to_meshio(model.bmesh.mesh, point_data={"displacement": self.state.U.T.copy(),
                                                     "chamber_pressure_Pa": self.chamber_pressure()},
                       cell_data={k: [np.ascontiguousarray(v)] for k, v in cells.items()})
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        meshio.write(path, mm)
        return path

    def chamber_pressure(self) -> np.ndarray:
        """Applied cavity pressure [Pa] on each node of the loaded inner surface (every node of its facets), 0 on
        the others; shape (n_nodes,)."""
        model = self.model
        nodes = model.asm.basis.get_dofs(facets=model.bmesh.inner_facets()).flatten()
        out = np.zeros(model.bmesh.n_nodes)
        out[nodes] = float(self.loadcase.pressure)
        return out
