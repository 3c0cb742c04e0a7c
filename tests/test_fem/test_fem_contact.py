"""Flank gaps and routing radii of a deformed wall (fem_reference.contact) against closed forms: the unloaded
sine wall, rigid motions, a uniform bend of known radius, a flank pushed through its neighbour; and the docs'
margin table against the function."""

import re
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ancf.errors import InputError
from fem_reference import BellowsModel, MeshLevel
from fem_reference.contact import flank_gaps, groove_rows, tendon_radii
from fem_reference.mesh import build_mesh
from fem_reference.presets import paper_bellows, paper_material

TINY = MeshLevel(2, 1, 12, 1)
DOCS = Path(__file__).resolve().parents[2] / "docs" / "fem.md"


@pytest.fixture(scope="module")
def geo():
    return paper_bellows()


@pytest.fixture(scope="module")
def tiny(geo):
    return build_mesh(geo, TINY)


def _sine_gap(geo, dzeta):
    """Closed form of the unloaded groove width at axial offset ``dzeta`` from a root: twice the axial offset
    of the outer surface point, ζ + (t/2) n_z with n_z = −r'/√(1 + r'²), r' = a k sin(k Δζ)."""
    a = 0.5 * (geo.r_crest_mid - geo.r_root_mid)
    k = 2 * np.pi / geo.pitch
    rp = a * k * np.sin(k * dzeta)
    return 2 * (dzeta - 0.5 * geo.wall_thickness * rp / np.sqrt(1 + rp * rp))


def _bend(X, R):
    """Uniform bend of radius R [m] towards +z: the axis onto the arc, every cross-section into its normal plane."""
    phi = X[0] / R
    return np.array([(R - X[2]) * np.sin(phi), X[1], R - (R - X[2]) * np.cos(phi)])


def _outer_nodes(bm, rows):
    sel = (bm.lattice[1] == 2 * bm.shape[1]) & np.isin(bm.lattice[0], rows)
    return np.flatnonzero(sel)


def test_unloaded_sine_wall_gap_is_the_closed_form(geo, tiny):
    coarse = build_mesh(geo, "coarse")
    for bm in (tiny, coarse):
        _rows, h = groove_rows(bm, "outer")
        dz = np.arange(1, h) * geo.pitch / (2 * h)
        for surface in ("outer", "inner"):
            fg = flank_gaps(bm, bm.X, surface)
            assert fg.gaps.shape == (geo.n_convolutions - (surface == "outer"), h - 1, 2 * bm.shape[2])
            np.testing.assert_allclose(fg.gaps, np.broadcast_to(_sine_gap(geo, dz)[None, :, None], fg.gaps.shape),
                                       rtol=1e-12, atol=1e-15)
    assert fg.minimum == pytest.approx(_sine_gap(geo, geo.pitch / 8), rel=1e-12)


@settings(max_examples=15, deadline=None)
@given(rv=st.lists(st.floats(-3, 3), min_size=3, max_size=3), shift=st.lists(st.floats(-1, 1), min_size=3, max_size=3))
def test_rigid_motion_keeps_every_gap(tiny, rv, shift):
    from scipy.spatial.transform import Rotation

    Q = Rotation.from_rotvec(rv).as_matrix()
    x = Q @ tiny.X + np.array(shift)[:, None]
    for surface in ("outer", "inner"):
        np.testing.assert_allclose(flank_gaps(tiny, x, surface).gaps, flank_gaps(tiny, tiny.X, surface).gaps,
                                   rtol=1e-9, atol=1e-13)


@pytest.mark.parametrize("R", [0.05, 0.1, 0.4])
def test_uniform_bend_closes_the_concave_grooves_as_the_closed_form(geo, tiny, R):
    rows, h = groove_rows(tiny, "outer")
    fg = flank_gaps(tiny, _bend(tiny.X, R), "outer")
    theta = np.pi * np.arange(2 * tiny.shape[2]) / tiny.shape[2]
    for k, r in enumerate(rows):
        for j in range(1, h):
            node = _outer_nodes(tiny, [r + j])
            node = node[np.argsort(tiny.lattice[2, node])]
            delta = tiny.X[0, node] - tiny.zeta[r]                       # axial offset of B's nodes
            rho0 = np.hypot(tiny.X[1, node], tiny.X[2, node])
            expect = 2 * (R - rho0 * np.cos(theta)) * np.sin(delta / R)
            np.testing.assert_allclose(fg.gaps[k, j - 1], expect, rtol=1e-9)
    assert fg.argmin()[2] == 0                                       # θ = 0: the concave side (+z)
    assert fg.minimum < flank_gaps(tiny, tiny.X).minimum


def test_a_flank_pushed_through_its_neighbour_gives_a_negative_gap(geo, tiny):
    rows, h = groove_rows(tiny, "outer")
    g0 = flank_gaps(tiny, tiny.X).gaps
    delta = g0[2, 0, 0] + 1e-3                                       # 1 mm past contact
    x = tiny.X.copy()
    x[0, _outer_nodes(tiny, rows[2] + np.arange(1, h + 1))] -= delta  # flank B of groove 2 moved towards A
    fg = flank_gaps(tiny, x)
    np.testing.assert_allclose(fg.gaps[2], g0[2] - delta, rtol=1e-12)
    np.testing.assert_allclose(np.delete(fg.gaps, 2, axis=0), np.delete(g0, 2, axis=0), rtol=1e-12)
    assert fg.minimum == pytest.approx(-1e-3, rel=1e-9) and fg.per_groove[2] < 0 < np.delete(fg.per_groove, 2).min()


def test_bad_inputs_are_refused(geo, tiny):
    with pytest.raises(InputError, match="outer"):
        flank_gaps(tiny, tiny.X, "middle")
    with pytest.raises(InputError, match="shape"):
        flank_gaps(tiny, tiny.X[:, :-1])
    with pytest.raises(InputError, match="finite"):
        flank_gaps(tiny, np.full_like(tiny.X, np.nan))
    with pytest.raises(InputError, match="2 elements per convolution"):
        flank_gaps(build_mesh(geo, MeshLevel(1, 1, 12, 1)), build_mesh(geo, MeshLevel(1, 1, 12, 1)).X)


@pytest.fixture(scope="module")
def tiny_model(geo):
    return BellowsModel(geo, paper_material(), TINY)


def _polylines(model, x):
    return [tp.points(x, model.X_c, np.eye(3)) for tp in model.tendons]


def test_routing_radius_unloaded_and_in_a_uniform_bend(geo, tiny_model):
    bm = tiny_model.bmesh
    d = geo.tendon_radius
    tr = tendon_radii(bm, bm.X, _polylines(tiny_model, bm.X))
    np.testing.assert_allclose(tr.guides, d, rtol=1e-12)
    np.testing.assert_allclose(tr.spans, d, rtol=1e-12)
    np.testing.assert_allclose(tr.spans_smooth, d, rtol=1e-12)
    R = 0.08
    x = _bend(bm.X, R)
    tr = tendon_radii(bm, x, _polylines(tiny_model, x))
    np.testing.assert_allclose(tr.guides, d, rtol=1e-12)             # every guide stays in its normal plane
    half = geo.pitch / (2 * R)
    for k, th in enumerate(geo.tendon_angles):
        expect = np.hypot(R - (R - d * np.cos(th)) * np.cos(half), d * np.sin(th))
        np.testing.assert_allclose(tr.spans[k], expect, rtol=1e-9)
    np.testing.assert_allclose(tr.spans_smooth, tr.spans, rtol=1e-4)   # the Hermite midpoint is near the arc's
    assert tr.spans[0].min() > d                                     # the inside tendon's chord: a longer arm


# ---------------------------------------------------------------- the docs table against the function
def _docs_rows():
    text = DOCS.read_text()
    sec = text.split("Self-contact and routing radius over the operating range, measured")[1].split("\n## ")[0]
    rows = {}
    table = sec.split("| state | outer min gap [mm]")[1].split("\n\n")[0]   # the flank-gap table
    for line in table.splitlines():
        m = re.match(r"\|\s*([^|]+?)\s*\|\s*(-?\d+\.\d+)\s*\|", line)
        if m:
            rows[m.group(1)] = float(m.group(2))
    return rows


def test_docs_table_unloaded_row_matches_the_function(geo):
    bm = build_mesh(geo, "coarse")
    assert _docs_rows()["unloaded"] == pytest.approx(flank_gaps(bm, bm.X).minimum * 1e3, abs=0.0051)


@pytest.mark.slow
def test_docs_table_row_of_a_solved_state_matches_the_function(geo):
    model = BellowsModel(geo, paper_material(), "coarse")
    res = model.solve(tensions=[2.5, 0.0, 0.0])
    gap = flank_gaps(model.bmesh, model.bmesh.X + res.state.U).minimum
    assert _docs_rows()["T1 2.5 N"] == pytest.approx(gap * 1e3, abs=0.0051)


def test_cap_gaps_unloaded_closed_form_and_rigid_motion(geo, tiny):
    from scipy.spatial.transform import Rotation

    from fem_reference.contact import cap_gaps

    _, h = groove_rows(tiny, "outer")
    Xc = np.array([geo.length, 0.0, 0.0])
    expect = geo.collar_length + _sine_gap(geo, geo.pitch / (2 * h)) / 2      # level 1 of the end flanks
    g0 = cap_gaps(tiny, tiny.X, Xc, np.eye(3))
    np.testing.assert_allclose(g0, expect, rtol=1e-12)
    Q = Rotation.from_rotvec([0.3, -0.2, 0.5]).as_matrix()
    x = Q @ tiny.X + np.array([[0.01], [0.0], [0.0]])      # the wall moves rigidly off the base cap: a larger gap
    g = cap_gaps(tiny, x, Q @ Xc + [0.01, 0, 0], Q)
    assert g[1] == pytest.approx(expect, rel=1e-12) and g[0] != pytest.approx(expect)
