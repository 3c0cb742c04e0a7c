"""Stacked bellows (fem_reference.stack): one segment is BellowsModel; the tangent is the derivative of the
residual; the series laws of pressure and of a distal tendon against single bellows solved alone; the force
balance of a tendon's anchor against the walls' internal forces; errors; the VTU."""

import meshio
import numpy as np
import pytest

from ancf.errors import ConfigError, InputError, LimitError
from fem_reference import BellowsModel, MeshLevel, StackModel, presets
from fem_reference.loads.caps import log_so3
from fem_reference.model import LoadCase
from fem_reference.stack import StackLoadCase, StackState

LEVEL = MeshLevel(2, 1, 6, 1)          # coarsest mesh with guides at every root and nodes every 30°
H_CAP = 0.01                           # intermediate cap length [m]


def _half(**kw):
    """The `paper` bellows at half length (80 mm, 4 convolutions of the same pitch)."""
    return presets.paper_bellows().replace(length=0.08, n_convolutions=4, collar_length=0.0025, **kw)


@pytest.fixture(scope="module")
def mat():
    return presets.paper_material()


@pytest.fixture(scope="module")
def two(mat):
    """Two different segments (the second shorter, its tendons at 60/180/300°), a 10 mm cap."""
    lower = _half(cap_mass=0.01)
    upper = presets.paper_bellows().replace(length=0.0625, n_convolutions=3, collar_length=0.0025,
                                            tendon_angles=(np.pi / 3, np.pi, 5 * np.pi / 3))
    return StackModel([lower, upper], mat, LEVEL, cap_lengths=[H_CAP])


def _perturbed(model, seed, scale=1e-5):
    rng = np.random.default_rng(seed)
    dq = scale * rng.standard_normal(model.n_dofs)
    dq[-6 * getattr(model, "N", 1):] *= 10
    return model._apply(model.zero_state(), dq, rings=False), rng


def test_one_segment_stack_has_the_bellows_models_residual_and_tangent(mat):
    geo = _half()
    single, stack = BellowsModel(geo, mat, LEVEL), StackModel([geo], mat, LEVEL)
    assert stack.n_dofs == single.n_dofs
    st, _ = _perturbed(single, 1)
    st.T[:] = [1.0, 0.5, 0.0]
    lc = LoadCase(st.T.copy(), 20e3, np.array([0.1, 0.0, -0.3]), 1.0, np.full(3, np.nan))
    a = single.evaluate(st, lc)
    b = stack.evaluate(StackState([st.U.copy()], st.uc[None].copy(), st.R[None].copy(), st.T.copy(), st.slack.copy()),
                       StackLoadCase(lc.tensions, np.array([20e3]), lc.tip_force, 1.0, np.full(3, np.nan)))
    assert np.abs(a["r"] - b["r"]).max() <= 1e-13 * np.abs(a["r"]).max()
    assert abs(a["K"] - b["K"]).max() <= 1e-13 * abs(a["K"]).max()
    assert np.array_equal(a["L"], b["L"]) and np.allclose(a["g"], b["g"], rtol=0, atol=1e-15)
    assert b["f_ref"] == pytest.approx(a["f_ref"], rel=1e-13)


def test_one_segment_stack_solves_as_the_bellows_model(mat):
    geo = _half()
    single, stack = BellowsModel(geo, mat, LEVEL), StackModel([geo], mat, LEVEL)
    loads = dict(tip_force=(0.0, 0.05, -0.2), gravity=True)
    a = single.solve([1.0, 0.5, 0.0], 20e3, **loads)
    b = stack.solve([1.0, 0.5, 0.0], [20e3], **loads)
    assert np.abs(a.tip_position - b.tip_position).max() < 1e-9
    assert np.abs(a.cap_rotation_vector - b.cap_rotation_vectors[0]).max() < 1e-8
    assert np.abs(a.tendon_lengths - b.tendon_lengths).max() < 1e-9
    assert np.abs(a.centreline - b.centreline).max() < 1e-9
    assert b.stable and a.stable


@pytest.mark.parametrize("cap_length", [H_CAP, 0.0])
def test_stack_tangent_is_the_derivative_of_its_residual(mat, two, cap_length):
    """Central differences of the residual along random and single-cap directions (rotations by the exact update
    R ← exp(εθ)R): every new term — the base ring tied to cap 1, both chambers on cap 1, a tendon of segment 2
    through segment 1 and the cap's channel — with pressures, gravity and a tip force."""
    model = two if cap_length else StackModel([two.segments[0].geometry, two.segments[1].geometry], mat, LEVEL,
                                              cap_lengths=[0.0])
    st, rng = _perturbed(model, 2)
    T = np.array([0.5, 0.0, 0.3, 1.0, 0.0, 0.4])
    st.T[:] = T
    lc = StackLoadCase(T, np.array([20e3, 10e3]), np.array([0.1, 0.0, -0.2]), 1.0, np.full(6, np.nan))
    ev = model.evaluate(st, lc)
    dirs = [rng.standard_normal(model.n_dofs) for _ in range(2)] + [np.eye(model.n_dofs)[model.n_free + i]
                                                                       for i in range(12)]
    eps = 1e-7
    for v in dirs:
        rp = model.evaluate(model._apply(st, eps * v, rings=False), lc, tangent=False)["r"]
        rm = model.evaluate(model._apply(st, -eps * v, rings=False), lc, tangent=False)["r"]
        Kv = ev["K"] @ v
        assert np.linalg.norm((rp - rm) / (2 * eps) - Kv) < 1e-7 * np.linalg.norm(Kv)
        Lp, Lm = (model.tendon_lengths(model._apply(st, s * eps * v, rings=False)) for s in (1, -1))
        assert np.allclose((Lp - Lm) / (2 * eps), ev["g"].T @ v, rtol=1e-6, atol=1e-9)


def test_series_law_of_the_chamber_pressures(mat, two):
    """No tendons, no gravity, p1 ≠ p2: segment k carries only its own chamber's end load (at cap 1 the chamber
    above pushes down by p2·A, segment 2's wall pulls up by as much), so the stack's elongation is the sum of each
    segment's elongation solved alone with its own pressure."""
    p = np.array([30e3, 10e3])
    res = two.solve(None, p)
    alone = [BellowsModel(s.geometry, mat, LEVEL).solve(None, pk) for s, pk in zip(two.segments, p)]
    ext = [a.tip_position[0] - s.geometry.length for a, s in zip(alone, two.segments)]
    assert ext[0] > 5e-3 and abs(ext[0] - ext[1]) > 3e-3           # the law is tested on different elongations
    cap1 = res.cap_centres[0, 0] - two.X_c[0, 0]
    tip = res.tip_position[0] - two.X_c[1, 0]
    assert cap1 == pytest.approx(ext[0], abs=1e-10)
    assert tip == pytest.approx(ext[0] + ext[1], abs=1e-10)
    assert np.abs(res.tip_position[1:]).max() < 1e-10 and np.abs(res.cap_rotation_vectors).max() < 1e-9
    assert np.abs(res.centreline[:, 1:]).max() < 1e-10


TENDON_4 = [0.0, 0.0, 0.0, 0.3, 0.0, 0.0]      # segment 2's first tendon (at 60°) at 0.3 N


@pytest.fixture(scope="module")
def bent(two):
    """Tendon 4 alone: no pressure, no gravity."""
    return two.solve(TENDON_4, [0.0, 0.0])


@pytest.fixture(scope="module")
def bent_p(two, bent):
    """Tendon 4 with the chambers at 20 and 10 kPa."""
    return two.solve(TENDON_4, [20e3, 10e3], initial=bent)


def _composed(mat, two, res, ps):
    """Segment 1 alone with one tendon at 60° anchored at its cap, segment 2 alone with its first tendon (both at
    0.3 N, each at its own chamber's pressure ``ps``); the deviations of the stack's cap 1 rotation, cap 1 centre,
    tip rotation and tip from theirs composed, and the rotation angles of both caps and of segment 2 alone."""
    g1, g2 = two.segments[0].geometry, two.segments[1].geometry
    one = BellowsModel(g1.replace(tendon_angles=(np.pi / 3,), cap_mass=0.0), mat, LEVEL).solve([0.3], ps[0])
    top = BellowsModel(g2, mat, LEVEL).solve([0.3, 0.0, 0.0], ps[1])
    R1, R2 = res.cap_rotations
    tip = res.cap_centres[0] + R1 @ (np.array([H_CAP, 0.0, 0.0]) + top.tip_position)
    dev = [np.abs(R1 - one.cap_rotation).max(), np.abs(res.cap_centres[0] - one.cap_centre).max(),
           np.abs(R2 - R1 @ top.cap_rotation).max(), np.abs(res.tip_position - tip).max()]
    return dev, [np.linalg.norm(log_so3(R)) for R in (R1, R2, top.cap_rotation)]


def test_a_tendon_of_segment_2_loads_segment_1_as_if_anchored_at_cap_1(mat, two, bent):
    """Segment 2, its tendon above cap 1 and cap 2 are in equilibrium, so what they put on cap 1 is the tendon's
    pull at the channel entry: segment 1 deforms as a bellows alone with that tendon anchored at its cap, and
    segment 2 as alone on top of cap 1 (its pose composed with cap 1's, the cap length along cap 1's axis).  So the
    intermediate cap turns and the tip turns more than segment 2 alone would."""
    dev, (a1, a2, alone) = _composed(mat, two, bent, (0.0, 0.0))
    assert a1 > 0.02 and a2 > 1.5 * alone                           # cap 1 turns; the tip more than segment 2's
    assert max(dev[0], dev[2]) < 1e-8 and max(dev[1], dev[3]) < 1e-9
    # the guides in segment 1 carry the tendon's force: T (e_k − e_{k−1}) at each, sideways
    pts = bent.tendon_points(3)
    e = np.diff(pts, axis=0) / np.linalg.norm(np.diff(pts, axis=0), axis=1)[:, None]
    n_guides = len(two.segments[0].geometry.root_positions()) - 2
    assert np.linalg.norm(0.3 * (e[1:n_guides + 1] - e[:n_guides]).sum(0)) > 0.02 * 0.3


def test_with_pressures_the_composition_holds_to_the_discrete_cavitys_closure(mat, two, bent_p):
    """With pressures the same argument needs chamber 2 to be closed: its discs (π r_i², as in BellowsModel) and
    the mesh's quadratic end rings enclose areas 0.24 % apart at 6 elements around, and when cap 2 tilts against
    cap 1 the difference, p₂ ΔA (R₂ − R₁) e_x, goes to cap 1 in the stack but to the ground for segment 2 alone."""
    dev, (a1, a2, alone) = _composed(mat, two, bent_p, (20e3, 10e3))
    assert a1 > 0.02 and a2 > 1.5 * alone
    assert dev[0] < 5e-3 * a1 and dev[2] < 5e-3 * a2 and max(dev[1], dev[3]) < 5e-3 * a2 * 0.08


def test_anchor_force_balances_the_walls_reaction(two, bent_p):
    """At the tip cap: the walls' pull from the FEM's internal (and pressure) forces on the tied ring, plus the
    chamber's push p2·A along the cap axis, plus the tendon's −T e at the anchor (e: the cable's last direction)
    vanish, force and moment, to the solver's tolerance; the same for cap 1 with the tendon's pulls at the
    channel's entry and exit."""
    bent = bent_p
    T, p = 0.3, bent.loadcase.pressures
    W = two.wall_forces_on_caps(bent)
    pts = bent.tendon_points(3)
    e = np.diff(pts, axis=0) / np.linalg.norm(np.diff(pts, axis=0), axis=1)[:, None]
    R1, R2 = bent.cap_rotations
    c1, c2 = bent.cap_centres
    F2 = -T * e[-1] + p[1] * two.A_distal[1] * R2[:, 0]
    assert np.linalg.norm(W[1, :3] + F2) < 1e-8 * T
    assert np.linalg.norm(W[1, 3:] + np.cross(pts[-1] - c2, -T * e[-1])) < 1e-9 * T
    n1 = len(two.segments[0].geometry.root_positions()) - 2          # pts[n1 + 1], pts[n1 + 2]: entry, exit of cap 1
    F_in, F_out = -T * e[n1], T * e[n1 + 2]
    F1 = F_in + F_out + (p[0] * two.A_distal[0] - p[1] * two.A_base[1]) * R1[:, 0]
    assert np.linalg.norm(W[0, :3] + F1) < 1e-8 * T
    M1 = np.cross(pts[n1 + 1] - c1, F_in) + np.cross(pts[n1 + 2] - c1, F_out)
    assert np.linalg.norm(W[0, 3:] + M1) < 1e-9 * T
    assert np.linalg.norm(W[1, 3:]) > 0.5 * T * 0.0275                # the tip cap's wall carries ≈ T d


def test_results_and_vtu(two, bent_p, tmp_path):
    bent = bent_p
    s = bent.summary()
    assert len(s["cap_centres_m"]) == 2 and len(s["pressures_Pa"]) == 2 and len(s["tensions_N"]) == 6
    assert bent.centreline.shape == (sum(2 * seg.bmesh.shape[0] + 1 for seg in two.segments), 3)
    assert np.allclose(bent.centreline[0], 0.0, atol=1e-12)
    assert np.allclose(bent.segment_centreline(1)[-1], bent.cap_centres[1], atol=1e-9)
    assert np.allclose(bent.tendon_lengths, two.tendon_lengths(bent.state))
    m = meshio.read(bent.save_vtu(tmp_path / "stack.vtu"))
    n1, n2 = (seg.bmesh.n_nodes for seg in two.segments)
    assert m.points.shape[0] == n1 + n2
    assert set(np.unique(m.point_data["segment"])) == {1, 2}
    assert np.unique(m.point_data["chamber_pressure_Pa"]).tolist() == [0.0, 10e3, 20e3]
    x = m.points + m.point_data["displacement"]
    assert np.allclose(x[n1:].T, two.nodes(bent.state, 1))


def test_inputs_are_checked(mat, two):
    with pytest.raises(InputError, match="pressures"):
        two.solve(None, [10e3])
    with pytest.raises(InputError, match="tensions"):
        two.solve([0, 0, 0, -1, 0, 0], [0, 0])
    with pytest.raises(LimitError, match="chamber 2"):
        two.solve(None, [0.0, 500e3])
    with pytest.raises(LimitError, match=r"T4 \(segment 2\)"):
        two.solve([0, 0, 0, 50, 0, 0], [0, 0])
    g = _half()
    with pytest.raises(ConfigError, match="coincide"):
        StackModel([g, g], mat, LEVEL)
    with pytest.raises(ConfigError, match="cap_lengths"):
        StackModel([g, g.replace(tendon_angles=(1.0,))], mat, LEVEL, cap_lengths=[-0.01])
    with pytest.raises(InputError, match="cap_lengths"):
        StackModel([g, g.replace(tendon_angles=(1.0,))], mat, LEVEL, cap_lengths=[0.01, 0.01])
    with pytest.raises(InputError, match="segments"):
        StackModel([], mat, LEVEL)
    with pytest.raises(InputError, match="this same StackModel"):
        two.wall_forces_on_caps(object())


@pytest.mark.slow
def test_two_segment_stack_on_the_default_mesh(mat):
    """The `two_segment` layout (two half-length `paper` bellows, 10 mm cap, tendons at 0/120/240° and
    60/180/300°) on the default mesh: a segment-2 tendon composed as above, and the pressure series law."""
    lower = _half()
    upper = _half(tendon_angles=(np.pi / 3, np.pi, 5 * np.pi / 3))
    stack = StackModel([lower, upper], mat, "coarse", cap_lengths=[H_CAP])
    T, p = 1.0, np.array([0.0, 0.0])
    res = stack.solve([0.0, 0.0, 0.0, T, 0.0, 0.0], p)
    one = BellowsModel(lower.replace(tendon_angles=(np.pi / 3,), cap_mass=0.0), mat, "coarse").solve([T], p[0])
    top = BellowsModel(upper, mat, "coarse").solve([T, 0.0, 0.0], p[1])
    R1, R2 = res.cap_rotations
    assert np.abs(R1 - one.cap_rotation).max() < 1e-8
    assert np.abs(R2 - R1 @ top.cap_rotation).max() < 1e-8
    tip = res.cap_centres[0] + R1 @ (np.array([H_CAP, 0.0, 0.0]) + top.tip_position)
    assert np.abs(res.tip_position - tip).max() < 1e-9
    p = np.array([30e3, 10e3])
    res = stack.solve(None, p)
    ext = [BellowsModel(g, mat, "coarse").solve(None, pk).tip_position[0] - g.length for g, pk in zip((lower, upper), p)]
    assert res.tip_position[0] - stack.X_c[1, 0] == pytest.approx(sum(ext), abs=1e-10)
