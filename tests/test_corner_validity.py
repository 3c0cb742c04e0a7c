"""Where the identified rod fails: two tendons near T_max without pressure (docs/identification.md, section
"Where the identified rod fails: two tendons near T_max without pressure").

The rod identified by ``bellows report --quick`` on the ``paper`` design (form ``pressure_ei_shear``; its
actuator file is reproduced in ``IDENTIFIED`` below) has, at p = 0,

    EA(λ) = b + a λ,  W'(λ) = ½ EA(λ)(λ³ − λ),   EI(λ) = c₀ + c₁ λ  (c₀ < 0: EI = 0 at λ = −c₀/c₁ ≈ 0.724).

For a uniform bend under T on tendons 1 and 2 (120° apart: their resultant arm is d) the potential per unit
reference length is, with κ the curvature per unit arc length (the ANCF bending energy ½ EI(λ) κ² dx and the
tendon length density λ(1 − d κ cos φᵢ)),

    π(λ, κ) = W(λ) + ½ EI(λ) κ² + T λ (2 − d κ),

whose equilibria are EI κ = T d λ and W' + ½ EI' κ² + T (2 − d κ) = 0, and whose Hessian determinant is

    det = EI W'' − (EI' κ − T d)² = EI W'' − (c₀ κ / λ)²      (on the equilibrium path).

The path T(λ) has its maximum (a fold) where det = 0.  These closed forms are checked here against the ANCF
model (free base stretch: the uniform arc is then the continuum solution), and the FEM's measured
corner states (saved numbers, below) are placed against them.
"""

from __future__ import annotations

import numpy as np
import pytest

import ancf
from ancf.errors import ConvergenceError

IDENTIFIED = """
name = "paper-identified"
length_m = 0.16
n_elements = 6
quadrature_points = 5
D_eff_m = 0.026613567856542113
pressure_area_slope = 0.0
line_mass_kg_per_m = 0.5316047294840275
tip_mass_kg = 0.018
tool_offset_m = 0.0
base_axis = [1.0, 0.0, 0.0]
reference_direction = [0.0, 0.0, 1.0]
gravity_m_per_s2 = [0.0, 0.0, -9.81]
tension_min_N = 0.0
tension_max_N = 5.0
pressure_min_Pa = 0.0
pressure_max_Pa = 100000.0
free_base_stretch = false
shear_compliance_coeffs_m_per_N_per_100kPa = [0.0006280643777147248, 0.0032422394618026973]

[stiffness]
law = "polynomial"
EA_coeffs_N = [114.05808852595659, 9.547553381918144]
EI_coeffs_N_m2 = [-0.03523371144106183, 0.0486850592184846]
EI_pressure_coeffs_per_100kPa = [0.7317586021315973, 0.49188203516124873]

[[tendons]]
distance_m = 0.0275
angle_rad = 0.0

[[tendons]]
distance_m = 0.0275
angle_rad = 2.0943951023931953

[[tendons]]
distance_m = 0.0275
angle_rad = 4.1887902047863905
"""

EA = np.array([114.05808852595659, 9.547553381918144])      # EA = EA[0] + EA[1] λ [N]
EI = np.array([-0.03523371144106183, 0.0486850592184846])   # EI = EI[0] + EI[1] λ [N m²]
D = 0.0275                                                   # tendon distance [m]

#: Saved FEM reference (not computed here): the `paper` design's FEM, BellowsModel(mesh="coarse"), gravity
#: off, contact off, T1 = T2 = T, T3 = 0, p = 0, warm-started along 2.5 → 5 N; every state stable.  Mid-body
#: stretch and curvature: mean over the six interior convolutions of (arc length of the ring-centroid
#: centreline / its reference length) and (angle between the centreline tangents at the convolution's two
#: roots / arc length).  T [N]: (λ, κ [1/m]).
FEM_CORNER = {2.5: (0.9485, 6.558), 3.5: (0.9220, 10.378), 4.0: (0.9065, 12.759), 4.4: (0.8925, 14.984),
              5.0: (0.8682, 19.068)}


def _ei(lam):
    return EI[0] + EI[1] * lam


def _w1(lam):
    return 0.5 * (EA[0] + EA[1] * lam) * (lam ** 3 - lam)


def _w2(lam):
    return 0.5 * EA[1] * (lam ** 3 - lam) + 0.5 * (EA[0] + EA[1] * lam) * (3 * lam ** 2 - 1)


def _uniform_path(lam):
    """T(λ) [N] and κ(λ) [1/m] of the uniform bend (module doc): the positive root of A T² + 2 T + W' = 0,
    A = ½ EI' (d λ/EI)² − d² λ/EI."""
    A = 0.5 * EI[1] * (D * lam / _ei(lam)) ** 2 - D * D * lam / _ei(lam)
    T = (-2.0 + np.sqrt(4.0 - 4.0 * A * _w1(lam))) / (2.0 * A)
    return T, T * D * lam / _ei(lam)


def _closed_form_fold():
    lam = np.linspace(0.999, 0.80, 40001)
    T, kap = _uniform_path(lam)
    i = int(np.argmax(T))
    return T[i], lam[i], kap[i]


def _params(**changes):
    return ancf.ActuatorParams.from_toml_string(IDENTIFIED).replace(**changes)


def _continue_to(model, T_end, step=0.25):
    """fk along T1 = T2 from 0 to ``T_end`` [N], warm-started; returns the last equilibrium."""
    q = None
    for T in np.append(np.arange(step, T_end, step), T_end):
        eq = model.fk((T, T, 0.0), q0=q)
        q = eq.q
    return eq


def test_closed_form_fold_has_zero_determinant():
    T, lam, kap = _closed_form_fold()
    det = _ei(lam) * _w2(lam) - (EI[0] * kap / lam) ** 2
    assert det == pytest.approx(0.0, abs=2e-3 * _ei(lam) * _w2(lam))
    assert 4.5 < T < 4.7 and 0.84 < lam < 0.87


def test_rod_follows_the_uniform_closed_form_and_folds_where_it_does():
    """Free base stretch: the ANCF model's mid-body (λ, κ) is the closed form's, and its path ends at the
    closed-form fold T* (within 0.5 %); with the base stretch clamped it ends earlier (base boundary layer)."""
    T_star, _, _ = _closed_form_fold()
    model = ancf.Model(_params(gravity=(0.0, 0.0, 0.0), free_base_stretch=True))
    eq = _continue_to(model, 4.0)
    lam_grid = np.linspace(0.999, 0.85, 30001)
    T_grid, _ = _uniform_path(lam_grid)
    j = int(np.argmin(abs(T_grid[: int(np.argmax(T_grid))] - 4.0)))
    lam_rod = np.median(model.stretches(eq.q))
    assert lam_rod == pytest.approx(lam_grid[j], abs=2e-3)
    near = model.fk((0.995 * T_star,) * 2 + (0.0,), q0=_continue_to(model, 0.98 * T_star, 0.2).q)
    assert near.stable
    with pytest.raises(ConvergenceError, match="limit point"):
        model.fk((1.005 * T_star,) * 2 + (0.0,), q0=near.q)
    clamped = ancf.Model(_params(gravity=(0.0, 0.0, 0.0)))
    with pytest.raises(ConvergenceError):
        clamped.fk((0.97 * T_star,) * 2 + (0.0,), q0=_continue_to(clamped, 4.4, 0.2).q)


def test_fem_secant_bending_stiffness_tracks_the_law_but_its_5N_state_is_past_the_laws_fold():
    """The law's EI(λ) is not what collapses: the FEM's secant EI = λ T d/κ along the corner path is 0.88–0.91
    × the law's at the FEM's own stretch (the rod is, if anything, too stiff in bending there).  But the FEM's stable 5 N state has κ above the largest curvature at
    which the law's energy density is convex at that stretch, κ_c(λ) = λ √(EI W'')/|c₀|: no rod of this form
    and these values can hold it."""
    for T, (lam, kap) in FEM_CORNER.items():
        ratio = lam * T * D / kap / _ei(lam)
        assert 0.85 < ratio < 0.95, (T, ratio)
    lam5, kap5 = FEM_CORNER[5.0]
    kappa_c = lam5 * np.sqrt(_ei(lam5) * _w2(lam5)) / abs(EI[0])
    assert kap5 > 1.03 * kappa_c
    lam4, kap4 = FEM_CORNER[4.0]
    assert kap4 < 0.8 * lam4 * np.sqrt(_ei(lam4) * _w2(lam4)) / abs(EI[0])


def test_fk_with_gravity_does_not_depend_on_earlier_calls():
    """Model.fk keeps no warm start between calls: T = (4, 4, 0) N with gravity gives bit-identical
    coordinates on a fresh model and after other solves on the same model; explicit warm starts from
    equilibria of other loads reach the same (single) equilibrium."""
    params = _params()
    fresh = ancf.Model(params).fk((4.0, 4.0, 0.0))
    model = ancf.Model(params)
    for T in ((5.0, 0.0, 0.0), (0.0, 5.0, 0.0), (2.0, 2.0, 0.0), (3.0, 3.0, 0.0), (0.0, 0.0, 5.0)):
        model.fk(T)
    model.droop()
    again = model.fk((4.0, 4.0, 0.0))
    assert np.array_equal(fresh.q, again.q)
    for T in ((0.0, 0.0, 0.0), (5.0, 0.0, 0.0), (0.0, 5.0, 0.0), (2.5, 2.5, 2.5), (4.5, 4.5, 0.0)):
        warm = model.fk((4.0, 4.0, 0.0), q0=model.fk(T).q)
        assert np.allclose(warm.q, fresh.q, atol=1e-8), T
    assert fresh.stable


def _doc_table():
    """Rows of the table in docs/identification.md §4c: T → (FEM λ, rod λ, FEM κ, rod κ, ratio) (None for —)."""
    import pathlib
    text = (pathlib.Path(__file__).parents[1] / "docs" / "identification.md").read_text(encoding="utf-8")
    section = text.split("## 4c. Where the identified rod fails")[1].split("\n## ")[0]
    rows = {}
    for line in section.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) == 6 and cells[0].replace(".", "").isdigit():
            rows[float(cells[0])] = [None if c == "—" else float(c) for c in cells[1:]]
    return rows


def test_doc_table_matches_the_saved_fem_the_closed_form_and_the_rod():
    rows = _doc_table()
    assert set(rows) == {2.5, 4.0, 4.4, 5.0}
    model = ancf.Model(_params(gravity=(0.0, 0.0, 0.0)))
    lam_grid = np.linspace(0.999, 0.86, 30001)
    T_grid, k_grid = _uniform_path(lam_grid)
    q = None
    for T, (fem_lam, rod_lam, fem_kap, rod_kap, ratio) in sorted(rows.items()):
        assert (fem_lam, fem_kap) == pytest.approx(FEM_CORNER[T], abs=0.006)
        assert ratio == pytest.approx(fem_lam * T * D / fem_kap / _ei(fem_lam), abs=0.006)
        if rod_lam is None:
            continue
        j = int(np.argmin(abs(T_grid - T)))
        assert (rod_lam, rod_kap) == pytest.approx((lam_grid[j], k_grid[j]), abs=0.006)
        q = _continue_to(model, T, 0.5).q if q is None else model.fk((T, T, 0.0), q0=q).q
        assert np.median(model.stretches(q)) == pytest.approx(rod_lam, abs=2e-3)
