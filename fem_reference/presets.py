"""Presets: the paper's actuator as far as the paper states it, every guess flagged in ``GUESSED``.

Stated by the paper (Sec. II, V): length 160 mm, length-to-diameter ≈ 5.4 (≈ 30 mm diameter),
three tendons at routing distance 27.5 mm, θ = 0, 2π/3, 4π/3, DPI8400 silicone Shore 50A, rigid PLA
end caps.  Identified ANCF parameters (docs/design.md §2–3): EA ≈ 767 N, EI ≈ 0.084 N m², D_a = 29.59 mm,
D_eff = 26.05 mm.

**How the guessed dimensions were sized** (a sweep over n ∈ {6, 8}, t ∈ {3, 4, 5} mm, root/crest
radii on a 3-per-convolution mesh, μ = 0.8 MPa, κ = 50 μ; linear stiffness from the condensed cap
tangent at zero load, as :meth:`BellowsModel.equivalent_rod` computes it: ``EA = L / C_uxFx``,
``EI = L³/(3 C_uzFz)`` (tip-force cantilever), ``D_a = sqrt(8 EI/EA)``, ``D_eff`` from the
pressure-elongation rate ``A_eff = (du_x/dp)/C_uxFx``).  The "stiff" row was re-measured on the
``coarse`` mesh with ``equivalent_rod()``: EA 776 N, EI 0.084 N m² (0.089 from a pure moment),
D_a 30.3 mm, D_eff 12.0 mm.

============  ===  =====  ======  ======  =======  =========  ======  ======
variant        n   t/mm   r_root  r_crest  EA / N  EI / N m²  D_a/mm  D_eff/mm
============  ===  =====  ======  ======  =======  =========  ======  ======
"stiff"        8    4.0    12.0    18.0     ~790    ~0.085     ~29     ~12
"deep"         8    4.0    10.5    22.0     ~410    ~0.047     ~31     ~24.5
============  ===  =====  ======  ======  =======  =========  ======  ======

(``r_root`` = inner radius at a root, ``r_crest`` = outer radius at a crest.)  No sine bellows of the
sweep matches all three of EA, EI and D_eff with a Shore-50A modulus: a thick near-incompressible
wall matching EA and EI elongates little under pressure (Poisson coupling of the hoop stress cancels
most of the cap force), while the deep-convolution variant matches D_eff and D_a but needs
μ ≈ 1.5 MPa to reach EA ≈ 767 N.  ``paper_bellows()`` defaults to ``"stiff"`` (it reproduces the
tip-load behaviour: ≈ 8 mm sag under 50 g, as the ANCF preset); use ``variant="deep"`` for pressure
studies.  The numbers above are rough (coarse mesh, ±5 %) and are re-measured by
``validation`` identification.
"""

from __future__ import annotations

import numpy as np

from ancf.errors import ConfigError

from .geometry import BellowsGeometry
from .material import Material

__all__ = ["GUESSED", "STATED", "paper_bellows", "paper_material", "straight_tube_test"]

#: Values taken from the paper (SI).
STATED = {
    "length": (0.160, "m", "Sec. II: 160 mm"),
    "diameter": (0.0296, "m", "length-to-diameter ≈ 5.4:1 → ≈ 29.6 mm (equivalent D_a = 29.59 mm)"),
    "tendon_radius": (0.0275, "m", "Sec. V-C: d1 = 27.5 mm"),
    "tendon_angles": ((0.0, 2 * np.pi / 3, 4 * np.pi / 3), "rad", "docs/design.md §2"),
    "material": ("DPI8400 silicone, Shore 50A", "", "Sec. II"),
    "caps": ("rigid PLA, 3-D printed", "", "Sec. II"),
}

#: Every dimension/parameter that the paper does not state, in ONE place: (value, unit, reason).
GUESSED = {
    "n_convolutions": (8, "-", "sized with EA/EI (see module doc); paper figure not available"),
    "root_radius": ({"stiff": 0.012, "deep": 0.0105}, "m", "inner radius at a root; sized (module doc)"),
    "crest_radius": ({"stiff": 0.018, "deep": 0.022}, "m", "outer radius at a crest; sized (module doc)"),
    "wall_thickness": (0.004, "m", "thick wall needed for EA ≈ 767 N with Shore 50A"),
    "collar_length": (0.005, "m", "straight bonded length at each cap"),
    "profile": ("sine", "-", "only shape implemented"),
    "cap_mass": (0.018, "kg", "PLA disc Ø60 × 5 mm (must hold tendons at 27.5 mm), ρ = 1250 kg/m³"),
    "cap_com_offset": (0.0025, "m", "half the cap thickness"),
    "tip_offset": (0.0, "m", "tip point = centre of the distal cap face"),
    "mu": (0.8e6, "Pa", "Shore 50A: E ≈ 2.4 MPa (Gent's relation 2.46 MPa) → μ = E/3"),
    "kappa": (40e6, "Pa", "κ/μ = 50 (ν ≈ 0.49); real silicone ~1 GPa, practical FE choice"),
    "density": (1100.0, "kg/m³", "typical platinum-cure silicone"),
    "guides": ("one guide per interior root, on a virtual rigid flange of the root ring at radius d", "-",
               "tendon channels at 27.5 mm lie outside the wall; see loads/tendons.py"),
}


def paper_bellows(variant: str = "stiff") -> BellowsGeometry:
    """The paper's actuator (160 mm, tendons at 27.5 mm); guessed dimensions from :data:`GUESSED`."""
    if variant not in ("stiff", "deep"):
        raise ConfigError("variant must be 'stiff' or 'deep'")
    G = {k: v[0] for k, v in GUESSED.items()}
    return BellowsGeometry(
        length=STATED["length"][0],
        n_convolutions=G["n_convolutions"],
        root_radius=G["root_radius"][variant],
        crest_radius=G["crest_radius"][variant],
        wall_thickness=G["wall_thickness"],
        collar_length=G["collar_length"],
        profile=G["profile"],
        tendon_radius=STATED["tendon_radius"][0],
        tendon_angles=STATED["tendon_angles"][0],
        cap_mass=G["cap_mass"],
        cap_com_offset=G["cap_com_offset"],
        tip_offset=G["tip_offset"],
    )


def paper_material() -> Material:
    """Shore 50A silicone as decoupled neo-Hookean (μ, κ, ρ from :data:`GUESSED`)."""
    return Material.neo_hookean(mu=GUESSED["mu"][0], kappa=GUESSED["kappa"][0], density=GUESSED["density"][0])


def straight_tube_test() -> BellowsGeometry:
    """Straight tube used by the closed-form tests (L = 160 mm, R_mid = 15 mm, t = 4 mm)."""
    return BellowsGeometry.straight_tube(0.16, 0.015, 0.004, n_segments=8)
