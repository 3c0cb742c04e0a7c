"""Is a reading physically plausible?  The FEM of a Shore-50A silicone bellows of the paper's size as judge.

:func:`fem_equivalent_rods` sweeps the FEM reference's bellows (``fem_reference.presets.paper_bellows``,
variants ``"stiff"`` — shallow convolutions — and ``"deep"``) over wall thicknesses and returns the
equivalent-rod parameters (EA, EI, D_a, D_eff from the condensed cap tangent at zero load,
:meth:`fem_reference.BellowsModel.equivalent_rod`) beside the readings' EA(1), EI(1).  Coarse mesh:
a few seconds per case on 2 cores.  Measured (coarse mesh, μ = 0.8 MPa, κ = 50 μ):

=======  ======  =======  ==========  ======  =======
variant  t [mm]  EA [N]   EI [N m²]   D_a     D_eff
=======  ======  =======  ==========  ======  =======
deep     1.5     22.7     0.00282     31.5    30.1
deep     2.0     44.8     0.00571     31.9    29.5
deep     2.5     82.3     0.01065     32.2    28.8
deep     3.0     139.7    0.01828     32.4    27.9
deep     4.0     327.1    0.04339     32.6    25.7
stiff    1.5     79.8     0.00893     29.9    24.6
stiff    2.0     154.4    0.01752     30.1    22.8
stiff    2.5     268.1    0.03060     30.2    20.5
stiff    4.0     776.2    0.08896     30.3    12.0
=======  ======  =======  ==========  ======  =======

The length-scaled readings (EA(1) = 123–153 N, EI(1) = 0.013–0.017 N m², D_a 29.6 mm, D_eff 26 mm) are
met by a 2–3 mm wall with D_eff 23–28 mm; the unscaled reading's EA = 767 N needs a 4 mm wall with
shallow convolutions, whose effective pressure diameter is then 12 mm (paper: 26 mm).
"""

from __future__ import annotations

from typing import Sequence

from validation.paper.common import resolve_params

DEFAULT_CASES = (("deep", 0.002), ("deep", 0.003), ("stiff", 0.002), ("stiff", 0.004))


def fem_equivalent_rods(cases: Sequence[tuple[str, float]] = DEFAULT_CASES, mesh: str = "coarse") -> list[dict]:
    """``[{variant, wall_thickness_m, EA_N, EI_N_m2, D_a_m, D_eff_m}]`` for (variant, wall thickness [m])."""
    from fem_reference import BellowsModel, presets as fem_presets

    rows = []
    for variant, t in cases:
        g = fem_presets.paper_bellows(variant).replace(wall_thickness=float(t))
        r = BellowsModel(g, fem_presets.paper_material(), mesh=mesh).equivalent_rod()
        rows.append({"variant": variant, "wall_thickness_m": float(t), "EA_N": float(r["EA"]),
                     "EI_N_m2": float(r["EI"]), "D_a_m": float(r["D_a"]), "D_eff_m": float(r["D_eff"])})
    return rows


def reading_targets(presets_: Sequence[str] = ("paper_unscaled", "paper_scaled", "paper_scaled_020")) -> dict:
    """EA(1) [N] and EI(1) [N m²] of each reading, for comparison with :func:`fem_equivalent_rods`."""
    out = {}
    for name in presets_:
        p = resolve_params(name)
        out[name] = {"EA_N": float(p.stiffness.EA(1.0)), "EI_N_m2": float(p.stiffness.EI(1.0)),
                     "D_a_m": float(p.stiffness.source.get("D_a", float("nan"))), "D_eff_m": p.D_eff}
    return out
