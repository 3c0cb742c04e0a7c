"""Frictionless penalty contact between facing outer flanks (fem_reference.loads.contact, BellowsModel(contact=True)).

Fast: the pair gap against fem_reference.contact.flank_gaps (an independent measure) on the unloaded wall and its
invariance under rigid motions; energy, gradient and Hessian against finite differences of the energy; a hand-made
pair pressed together by a known force settles at the penetration F / (k_c A); the model's scatter of the pair
blocks into its reduced residual and Newton matrix against the node-space Hessian; with every gap open the model
evaluates bit for bit as without contact; bad options refused.  Slow: solves on the tiny and the medium mesh
where the contact-free FEM lets the flanks pass through each other.
"""

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import given, settings
from hypothesis import strategies as hst

from ancf.errors import InputError
from fem_reference import BellowsModel, MeshLevel
from fem_reference.contact import flank_gaps
from fem_reference.loads.contact import (
    FlankPairs,
    contact_terms,
    default_stiffness,
    flank_pairs,
    global_terms,
    pair_gaps,
)
from fem_reference.mesh import build_mesh
from fem_reference.model import LoadCase
from fem_reference.presets import paper_bellows, paper_material

TINY = MeshLevel(2, 1, 12, 1)


@pytest.fixture(scope="module")
def geo():
    return paper_bellows()


@pytest.fixture(scope="module")
def coarse(geo):
    return build_mesh(geo, "coarse")


@pytest.fixture(scope="module")
def tiny_contact(geo):
    return BellowsModel(geo, paper_material(), TINY, contact=True)


def _closed(bm, pairs, groove: int, factor: float, level: int | None = None) -> np.ndarray:
    """Positions with flank B of ``groove`` (at ``level`` only, or every level) moved axially towards flank A by
    ``factor`` × its reference gap."""
    x = bm.X.copy()
    sel = (pairs.groove == groove) & ((pairs.level == level) if level is not None else True)
    g0 = pair_gaps(pairs, bm.X)
    x[0, pairs.nodes[sel, 1]] -= factor * g0[sel]
    return x


def test_pair_gaps_on_the_unloaded_wall_are_the_flank_gaps(coarse, geo):
    pairs = flank_pairs(coarse)
    fg = flank_gaps(coarse, coarse.X, "outer")
    g = pair_gaps(pairs, coarse.X)
    assert pairs.n_pairs == fg.gaps.size                               # every groove, level and meridian once
    np.testing.assert_allclose(g, fg.gaps[pairs.groove, pairs.level - 1, pairs.angle], rtol=0, atol=1e-12)
    assert np.all(np.abs(pairs.sign) == 1)
    # tributary area: the node's meridian step (half the arc to its ↑ and ↓ neighbours) × its circumferential
    # step ρ sin Δθ (the chord of its ± neighbours over 2), from the positions directly (the area's chord of the
    # curved meridian is up to 3 % shorter than the two arcs)
    X = coarse.X
    up, down, plus = (X[:, pairs.nodes[:, k]] for k in (2, 3, 4))
    a = X[:, pairs.nodes[:, 0]]
    ds = 0.5 * (np.linalg.norm(up - a, axis=0) + np.linalg.norm(a - down, axis=0))
    rho = np.hypot(a[1], a[2])
    np.testing.assert_allclose(pairs.area, ds * rho * np.sin(np.pi / coarse.shape[2]), rtol=0.04)


@settings(max_examples=15, deadline=None)
@given(rv=hst.lists(hst.floats(-3, 3), min_size=3, max_size=3),
       shift=hst.lists(hst.floats(-0.1, 0.1), min_size=3, max_size=3))
def test_pair_gaps_are_invariant_under_rigid_motions(coarse, rv, shift):
    from scipy.spatial.transform import Rotation

    pairs = flank_pairs(coarse)
    x = _closed(coarse, pairs, 2, 1.3)
    Q = Rotation.from_rotvec(rv).as_matrix()
    np.testing.assert_allclose(pair_gaps(pairs, Q @ x + np.asarray(shift)[:, None]), pair_gaps(pairs, x),
                               rtol=0, atol=1e-12)


@pytest.mark.parametrize("level", [1, 2])
def test_penetration_is_measured_along_the_axis(coarse, level):
    pairs = flank_pairs(coarse)
    g0 = pair_gaps(pairs, coarse.X)
    g = pair_gaps(pairs, _closed(coarse, pairs, 2, 1.25, level))
    sel = (pairs.groove == 2) & (pairs.level == level)
    # the b nodes of one level moved together along the axis: their pairs' normals (from the unmoved ↑/↓ and the
    # equally moved ± neighbours) stay the axis, so the gap is −¼ of the reference one; other grooves unchanged
    np.testing.assert_allclose(g[sel], -0.25 * g0[sel], rtol=1e-9)
    np.testing.assert_array_equal(g[pairs.groove != 2], g0[pairs.groove != 2])


@pytest.mark.parametrize("factor", [1.3, 2.0])
def test_energy_gradient_and_hessian_match_finite_differences(coarse, factor):
    pairs = flank_pairs(coarse)
    rng = np.random.default_rng(3)
    x = _closed(coarse, pairs, 3, factor) + 2e-4 * rng.standard_normal(coarse.X.shape)
    k = 1e9
    E, grad, H = global_terms(pairs, x, k)
    assert contact_terms(pairs, x, k).active.size > 20 and E > 0
    for _ in range(3):
        v = rng.standard_normal(x.size)
        eps = 1e-7
        xp, xm = ((x.T.ravel() + s * eps * v).reshape(-1, 3).T for s in (1, -1))
        (Ep, gp, _), (Em, gm, _) = global_terms(pairs, xp, k), global_terms(pairs, xm, k)
        assert (Ep - Em) / (2 * eps) == pytest.approx(grad @ v, rel=1e-6)
        Hv = H @ v
        assert np.linalg.norm((gp - gm) / (2 * eps) - Hv) <= 1e-6 * np.linalg.norm(Hv)
    assert abs(H - H.T).max() <= 1e-9 * abs(H).max()


def test_no_force_while_every_gap_is_open(coarse):
    pairs = flank_pairs(coarse)
    x = _closed(coarse, pairs, 3, 0.99)
    t = contact_terms(pairs, x, 1e12)
    assert t.energy == 0.0 and t.active.size == 0 and np.all(t.gaps > 0)


def _hand_pair(tilt: float):
    """Ten nodes: a at the origin, b at (δ, 0, 0), flank neighbours in planes whose normals turn by ±tilt about z
    (their bisector stays +x)."""
    def flank(centre, t):
        n = np.array([np.cos(t), np.sin(t), 0.0])
        u = np.array([-np.sin(t), np.cos(t), 0.0])               # ↑ along the flank
        e = np.array([0.0, 0.0, 1.0])                            # ± around
        h = 1e-3
        return [centre + h * u, centre - h * u, centre + h * e, centre - h * e], n
    delta = 2e-3
    A, _ = flank(np.zeros(3), tilt)
    B, _ = flank(np.array([delta, 0, 0]), -tilt)
    B = [B[1], B[0], B[3], B[2]]                                 # mirror: ↑ of b is −u, + of b is −e
    X = np.array([np.zeros(3), [delta, 0, 0]] + A + B).T
    nodes = np.arange(10)[None]
    pairs = FlankPairs(nodes, np.array([1.0]), np.array([1e-6]), *(np.zeros(1, int),) * 3)
    s = np.sign(pair_gaps(pairs, X))
    return FlankPairs(nodes, s, np.array([1e-6]), *(np.zeros(1, int),) * 3), X


@pytest.mark.parametrize("tilt", [0.0, 0.4])
@pytest.mark.parametrize("F", [0.5, 3.0])
def test_a_pair_pressed_by_a_known_force_penetrates_by_F_over_k_A(tilt, F):
    pairs, X = _hand_pair(tilt)
    k = 2e9
    assert pair_gaps(pairs, X)[0] == pytest.approx(2e-3)
    # node b free, every other node held; force F on b towards a (−x): minimise Π_c + F x_b
    x = X.copy()
    for _ in range(30):
        t = contact_terms(pairs, x, k)
        r = (t.grad[0, 3:6] if t.active.size else np.zeros(3)) + np.array([F, 0, 0])
        if np.linalg.norm(r) < 1e-12:
            break
        Kb = t.hess[0, 3:6, 3:6] if t.active.size else np.eye(3) * 1e-9
        step = np.linalg.lstsq(Kb, -r, rcond=None)[0]
        x[:, 1] += step if t.active.size else np.array([-2.1e-3, 0, 0])
    g = pair_gaps(pairs, x)[0]
    assert -g == pytest.approx(F / (k * 1e-6), rel=1e-9)


def test_model_scatters_the_pair_blocks_into_its_reduced_system(tiny_contact):
    m = tiny_contact
    bm, pairs = m.bmesh, m.contact_pairs
    lc = LoadCase(np.zeros(m.m), 0.0, np.zeros(3), 0.0, np.full(m.m, np.nan))
    m.evaluate(m.zero_state(), lc)                                  # the model-wide pattern
    st = m.zero_state()
    st.U[:] = _closed(bm, pairs, 4, 1.5) - bm.X
    ct = m.contact_forces(st, hessian=True)
    assert ct.active.size > 0
    m._ensure_contact_pattern()
    pat = m._pattern
    Kq = sp.csr_matrix((np.zeros(pat[2].size), pat[1], pat[0]), shape=(m.n_dofs, m.n_dofs))
    r = np.zeros(m.n_dofs)
    m._add_contact(ct, r, Kq)
    E, grad, H = global_terms(pairs, bm.X + st.U, m.contact_stiffness)
    fd = m.caps.free_dofs
    nf = m.caps.n_free
    np.testing.assert_allclose(r[:nf], grad[fd], rtol=0, atol=1e-12 * np.abs(grad).max())
    assert np.all(r[nf:] == 0)
    D = Kq[:nf, :nf] - H[fd][:, fd]
    assert abs(D).max() <= 1e-12 * abs(H).max()
    assert abs(Kq[nf:]).max() == 0


def test_open_gaps_evaluate_bit_for_bit_as_without_contact(geo):
    m0, m1 = (BellowsModel(geo, paper_material(), TINY, contact=c) for c in (False, True))
    st = m0.zero_state()
    st.U[:] = 2e-3 * m0.bmesh.X                                      # a uniform stretch: every gap opens
    lc = LoadCase(np.array([2.0, 1.0, 0.0]), 20e3, np.zeros(3), 0.0, np.full(3, np.nan))
    for tangent in (True, False, True):
        e0, e1 = m0.evaluate(st, lc, tangent=tangent), m1.evaluate(st, lc, tangent=tangent)
        assert e1["contact"].active.size == 0 and e1["contact"].gaps.min() > 0
        np.testing.assert_array_equal(e0["r"], e1["r"])
        if tangent:
            np.testing.assert_array_equal(e0["K"].indptr, e1["K"].indptr)
            np.testing.assert_array_equal(e0["K"].indices, e1["K"].indices)
            np.testing.assert_array_equal(e0["K"].data, e1["K"].data)


def test_bad_contact_options_are_refused(geo):
    mat = paper_material()
    with pytest.raises(InputError, match="contact must be"):
        BellowsModel(geo, mat, TINY, contact="yes")
    for bad in (0.0, -1e9, float("nan")):
        with pytest.raises(InputError):
            BellowsModel(geo, mat, TINY, contact=True, contact_stiffness=bad)
    m = BellowsModel(geo, mat, TINY)
    assert m.contact_pairs is None and m.contact_forces(m.zero_state()) is None
    assert default_stiffness(mat, geo) == pytest.approx(10 * 3 * mat.mu / geo.wall_thickness)


@pytest.mark.slow
def test_medium_mesh_two_tendons_keep_the_flanks_apart_with_contact():
    """Medium mesh, tendons 1 and 2 at equal tension, no pressure: without contact the outer flanks next to the
    grooves' bottom pass through each other near 4.5 N (docs/fem.md §5a); with contact the solve reaches 5 N, the
    gaps stay above −(a few µm) and the contact carries a positive normal force (≈ 10 min on 2 cores)."""
    from validation.reference.designs import load_design

    geo, mat = load_design("paper")
    m = BellowsModel(geo, mat, mesh="medium", contact=True)
    prev, seen, tips = None, {}, {}
    for T in (2.5, 3.5, 4.0, 4.5, 5.0):
        prev = m.solve(tensions=[T, T, 0.0], initial=prev, n_steps=6, max_steps=120)
        ct = m.contact_forces(prev.state)
        gaps = flank_gaps(m.bmesh, m.bmesh.X + prev.state.U)
        seen[T] = (ct.active.size, ct.gaps.min(), ct.normal_force.sum(), gaps.minimum)
        tips[T] = prev.tip_position
        assert prev.stable
    assert seen[4.0][0] == 0 and seen[4.0][1] > 0.1e-3            # open at 4 N: the contact-free equilibrium
    for T in (4.5, 5.0):
        n_act, g_min, N, fg_min = seen[T]
        assert n_act > 0 and N > 0
        assert g_min > -0.06e-3 and fg_min > -0.06e-3             # penetration ≤ 60 µm of a 0.88 mm groove
    assert seen[5.0][2] > seen[4.5][2]
    rows = _docs_contact_rows()                                     # docs/fem.md §5a's table is this run's output
    for T, label in ((4.5, "4.5 N"), (5.0, "5 N")):
        tip_mm, force_n = rows[label]
        assert np.allclose(tips[T] * 1e3, tip_mm, atol=0.01)
        assert seen[T][2] == pytest.approx(force_n, abs=0.05)


def _docs_contact_rows() -> dict:
    """{"4.5 N" | "5 N": (tip [mm], total normal force [N])} of the default-k_c rows of docs/fem.md §5a's table."""
    import pathlib
    import re
    text = (pathlib.Path(__file__).resolve().parents[2] / "docs" / "fem.md").read_text()
    out = {}
    for m in re.finditer(r"^\| (4\.5 N|5 N) \| default \| \(([^)]*)\) \|[^|]*\|[^|]*\| ([0-9.]+)", text, re.M):
        out[m.group(1)] = (np.array([float(v.replace("−", "-")) for v in m.group(2).split(",")]), float(m.group(3)))
    assert set(out) == {"4.5 N", "5 N"}, out
    return out
