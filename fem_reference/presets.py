"""Presets: the paper's actuator as far as the paper states it, every guess flagged in ``GUESSED``.

Stated by the paper (Sec. II, V): length 160 mm, length-to-diameter ≈ 5.4 (≈ 30 mm diameter),
three tendons at routing distance 27.5 mm, θ = 0, 2π/3, 4π/3, DPI8400 silicone Shore 50A, rigid PLA
end caps.  Identified ANCF parameters (docs/design.md §2–3): EA ≈ 767 N, EI ≈ 0.084 N m², D_a = 29.59 mm,
D_eff = 26.05 mm.

**Variants.**  ``"soft"`` (the default) is calibrated to the product's ``paper`` reading of the
stiffness law (docs/paper-readings.md "FEM calibration targets"; ``bellows calibrate``, docs/identification.md
§6): EA(1) 122.8 N, EI(1) 0.01343 N m², D_a 29.59 mm, D_eff 26.05 mm.  On the converged FEM (the mixed wall
element, two elements through the wall; docs/fem.md §3a) a Shore-50A wall (μ = 0.8 MPa) of 3.7 mm with
convolutions from an 8.5 mm root to a 21.3 mm crest has (default mesh, condensed cap tangent at zero load,
:meth:`BellowsModel.equivalent_rod`): EA 119 N, EI 0.0134 N m², D_a 30.0 mm, blocked-force D_eff 26.3 mm; the
secant D_eff under 60 kPa (free elongation λ = 1.19 read through the reduced model's axial law) is 25.1 mm
(calibration mismatch −3.0 %, +0.1 %, −3.8 %).  It is a soft, extensible bellows: 60 kPa lengthens it by
19 %.  (The former soft design, a 2.6 mm wall from a 10.5 mm root to a 20 mm crest, was calibrated on the
displacement element, whose locking made it 39 % too stiff: EA 131 N there, 94.5 N converged.)

``"stiff"`` reads the law literally (EA = k(λ) ≈ 767 N, EI ≈ 0.084 N m²); a 4 mm wall is needed for that
with Shore 50A, and such a wall elongates little under pressure (Poisson coupling of the hoop stress
cancels most of the cap force): D_eff ≈ 13 mm.  ``"deep"`` has deeper convolutions with a 4 mm wall.

============  ===  =====  ======  =======  =======  =========  ======  ========
variant        n   t/mm   r_root  r_crest  EA / N  EI / N m²  D_a/mm  D_eff/mm
============  ===  =====  ======  =======  =======  =========  ======  ========
"soft"         8    3.7     8.5    21.3      119    0.01345     30.0   26.3
"stiff"        8    4.0    12.0    18.0      742    0.08528     30.3   13.2
"deep"         8    4.0    10.5    22.0      211    0.02876     33.0   27.7
============  ===  =====  ======  =======  =======  =========  ======  ========

(``r_root`` = inner radius at a root, ``r_crest`` = outer radius at a crest; default mesh, mixed element,
blocked-force D_eff; ``tests/test_fem/test_fem_presets.py`` checks the table.)  The identification
(``bellows identify``) re-measures all of them with the reduced model in the loop.
"""

from __future__ import annotations

import numpy as np

from .errors import ConfigError

from .geometry import BellowsGeometry
from .material import Material

__all__ = ["GUESSED", "STATED", "VARIANTS", "paper_bellows", "paper_material", "straight_tube_test"]

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
    "root_radius": ({"soft": 0.0085, "stiff": 0.012, "deep": 0.0105}, "m",
                    "inner radius at a root; calibrated/sized (module doc)"),
    "crest_radius": ({"soft": 0.0213, "stiff": 0.018, "deep": 0.022}, "m",
                     "outer radius at a crest; calibrated/sized (module doc)"),
    "wall_thickness": ({"soft": 0.0037, "stiff": 0.004, "deep": 0.004}, "m",
                       "soft: calibrated to the length-scaled reading on the converged FEM; stiff: EA ≈ 767 N "
                       "with Shore 50A"),
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


#: Geometry variants of :func:`paper_bellows` (module docstring); the first is the default.
VARIANTS = ("soft", "stiff", "deep")


def paper_bellows(variant: str = "soft") -> BellowsGeometry:
    """The paper's actuator (160 mm, tendons at 27.5 mm); guessed dimensions from :data:`GUESSED`.
    ``variant``: one of :data:`VARIANTS` (module docstring)."""
    if variant not in VARIANTS:
        raise ConfigError(f"variant must be one of {', '.join(VARIANTS)}; got {variant!r}")
    G = {k: v[0] for k, v in GUESSED.items()}
    return BellowsGeometry(
        length=STATED["length"][0],
        n_convolutions=G["n_convolutions"],
        root_radius=G["root_radius"][variant],
        crest_radius=G["crest_radius"][variant],
        wall_thickness=G["wall_thickness"][variant],
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
