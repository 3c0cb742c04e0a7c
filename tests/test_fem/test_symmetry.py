"""Newton in the symmetric subspace (fem_reference.symmetry): group detection, load subgroups, the basis and the
fast reduced tangent against explicit products, and symmetric solves against the full solve."""

import numpy as np
import pytest
import scipy.sparse as sp

from ancf.errors import InputError
from fem_reference import BellowsModel
from fem_reference import symmetry as S
from fem_reference.mesh import MeshLevel
from fem_reference.presets import paper_bellows, paper_material

SMALL = MeshLevel(n_per_conv=2, n_thick=1, n_theta=6)


@pytest.fixture(scope="module")
def small():
    return BellowsModel(paper_bellows(), paper_material(), mesh=SMALL)


def _order(model, **loads):
    lc = model._loadcase(loads.get("tensions"), loads.get("pressure", 0.0), loads.get("tip_force", (0.0, 0.0, 0.0)),
                         loads.get("gravity", False), loads.get("locked_lengths"))
    return len(S.load_subgroup(model, [lc], [model.zero_state()]))


def _action(model, g):
    """Π_g on reduced vectors, built independently of the module: (Π v) at node perm[i] = Q v at node i; u_c with
    Q, θ with det(Q) Q."""
    c = model.caps
    n_q = c.n_q
    rows, cols, vals = [], [], []
    qn = c.q_of_node
    src = c.free_nodes
    dst = g.perm[src]
    assert np.all(qn[dst] >= 0)
    for a in range(3):
        for b in range(3):
            rows.append(qn[dst] + a)
            cols.append(qn[src] + b)
            vals.append(np.full(src.size, g.Q[a, b]))
    s = c.n_free
    det = np.linalg.det(g.Q)
    for a in range(3):
        for b in range(3):
            rows += [np.array([s + a]), np.array([s + 3 + a])]
            cols += [np.array([s + b]), np.array([s + 3 + b])]
            vals += [np.array([g.Q[a, b]]), np.array([det * g.Q[a, b]])]
    r, cc, v = map(np.concatenate, (rows, cols, vals))
    return sp.csr_matrix((v, (r, cc)), shape=(n_q, n_q))


def test_default_mesh_group():
    m = BellowsModel(paper_bellows(), paper_material())
    G = S.mesh_group(m)
    rot = sorted(round(np.degrees(g.angle)) for g in G if g.kind == "rotation")
    mir = sorted(round(np.degrees(g.angle)) for g in G if g.kind == "mirror")
    # n_theta = 12 elements around: rotations by 30° (not the 15° node spacing: vertices would land on mid-nodes)
    assert rot == list(range(0, 360, 30))
    assert mir == list(range(0, 180, 15))
    X = m.bmesh.X
    for g in G:
        assert np.abs(g.Q @ X - X[:, g.perm]).max() < 1e-12
        assert np.allclose(g.Q @ g.Q.T, np.eye(3))
    # equal tensions: C3v (rotations by 120°, mirrors through the tendons)
    H = S.load_subgroup(m, [m._loadcase([1, 1, 1], 1e4, (0, 0, 0), False, None)])
    assert sorted((g.kind, round(np.degrees(g.angle))) for g, _ in H) == \
        [("mirror", 0), ("mirror", 60), ("mirror", 120), ("rotation", 0), ("rotation", 120), ("rotation", 240)]


def test_mesh_group_n_theta_not_multiple_of_3():
    m = BellowsModel(paper_bellows(), paper_material(), mesh=MeshLevel(n_per_conv=2, n_thick=1, n_theta=4))
    G = S.mesh_group(m)
    assert len(G) == 8  # D4
    # 120° is not a mesh rotation; the mirror through tendon 1 (θ = 0) maps tendon 2 (120°) onto tendon 3 (240°)
    H = S.load_subgroup(m, [m._loadcase([1, 1, 1], 0.0, (0, 0, 0), False, None)])
    assert [(g.kind, g.angle) for g, _ in H] == [("rotation", 0.0), ("mirror", 0.0)]
    assert list(H[1][1]) == [0, 2, 1]


@pytest.mark.parametrize("loads, order", [
    (dict(tensions=[3, 3, 3], pressure=50e3), 6),
    (dict(tensions=[2, 0, 0]), 2),
    (dict(tensions=[5, 5, 0]), 2),
    (dict(tensions=[0, 2, 4]), 1),
    (dict(tensions=[0, 2, 4], pressure=37.5e3), 1),
    (dict(tip_force=(0.0, 0.0, -0.5)), 2),          # lateral, in the mirror plane through tendon 1
    (dict(tip_force=(0.0, 0.3, -0.5)), 1),          # lateral, in no mirror plane
    (dict(tip_force=(0.7, 0.0, 0.0), pressure=1e4), 12),  # axial, no tension: the whole mesh group (D6)
    (dict(tip_force=(0.7, 0.0, 0.0), tensions=[0, 0, 1]), 2),  # the mirror through tendon 3 (240°)
    (dict(tip_force=(0.0, 0.5, 0.0)), 2),           # lateral, in the plane at 90°: no tendon there, none loaded
    (dict(tip_force=(0.0, 0.5, 0.0), tensions=[1, 0, 0]), 1),
    (dict(gravity=True), 2),                        # g = (0, 0, -9.81): lateral, in the plane through tendon 1
    (dict(tensions=[1, 1, 1], gravity=0.0), 6),
    (dict(locked_lengths=[0.1, 0.1, None]), 2),
    (dict(locked_lengths=[0.1, 0.1, 0.1]), 6),
])
def test_load_subgroup(small, loads, order):
    assert _order(small, **loads) == order


def test_start_state_limits_the_group(small):
    lc = small._loadcase([1, 1, 1], 0.0, (0, 0, 0), False, None)
    st = small.zero_state()
    assert len(S.load_subgroup(small, [lc], [st])) == 6
    st.T[:] = [1.0, 2.0, 2.0]
    assert len(S.load_subgroup(small, [lc], [st])) == 2
    st = small.zero_state()
    node = small.caps.free_nodes[5]
    st.U[:, node] = 1e-4
    assert len(S.load_subgroup(small, [lc], [st])) == 1


@pytest.fixture(scope="module")
def c3v_solution(small):
    return small.solve(tensions=[3, 3, 3], pressure=50e3, symmetry=False)


def test_basis_invariant_and_fast_tangent(small, c3v_solution):
    res = c3v_solution
    sub = S.subspace_for(small, [res.loadcase], [res.state])
    assert sub is not None and sub.order == 6
    T = sub.T
    for g in sub.elements:
        Pi = _action(small, g)
        assert abs(Pi @ T - T).max() < 1e-12
    # dimension of the fixed space = (1/|H|) Σ tr(Π_g) (character formula), independent of the construction
    dim = np.mean([_action(small, g).diagonal().sum() for g in sub.elements])
    assert sub.n_s == round(dim)
    assert np.linalg.matrix_rank(T.toarray()) == sub.n_s
    TtT = (sub.Tt @ T).toarray()
    assert np.allclose(TtT, np.diag(np.diag(TtT)), atol=1e-12)
    assert 5.0 < small.n_dofs / sub.n_s < 6.5
    K = small.evaluate(res.state, res.loadcase)["K"]
    fast, ref = sub.reduce_matrix(K), sub.reduce_matrix_reference(K)
    assert abs(fast - ref).max() <= 1e-10 * abs(ref).max()
    # and the tangent really is equivariant at this state (what the fast map relies on)
    for g in sub.elements[1:3]:
        Pi = _action(small, g)
        assert abs(Pi @ K @ Pi.T - K).max() <= 1e-9 * abs(K).max()


def test_fast_tangent_mirror_state(small):
    res = small.solve(tensions=[2, 0, 0], pressure=1e4, symmetry=False, check_stability=False)
    sub = S.subspace_for(small, [res.loadcase], [res.state])
    assert sub.order == 2
    K = small.evaluate(res.state, res.loadcase)["K"]
    fast, ref = sub.reduce_matrix(K), sub.reduce_matrix_reference(K)
    assert abs(fast - ref).max() <= 1e-10 * abs(ref).max()


def _agree(a, b, tip=1e-9):
    assert np.abs(a.tip_position - b.tip_position).max() < tip
    assert np.abs(a.cap_rotation - b.cap_rotation).max() < 1e-8
    assert np.allclose(a.tensions, b.tensions, rtol=1e-7, atol=1e-9)


@pytest.mark.parametrize("loads, order", [
    (dict(tensions=[3, 3, 3], pressure=50e3), 6),
    (dict(tensions=[2, 0, 0]), 2),
    (dict(tensions=[0, 2, 2], pressure=20e3), 2),
    (dict(pressure=30e3), 12),
])
def test_symmetric_solve_equals_full(small, c3v_solution, loads, order):
    full = c3v_solution if order == 6 else small.solve(**loads, symmetry=False)
    if order == 12:
        assert np.abs(full.tip_position[1:]).max() < 1e-12
    sym = small.solve(**loads)
    assert sym.stats.symmetry_order == order and full.stats.symmetry_order == 1
    assert sym.stats.n_symmetric_steps > 0 and full.stats.n_symmetric_steps == 0
    assert sym.summary()["symmetry_order"] == order and full.summary()["symmetry_order"] == 1
    _agree(sym, full)
    if order == 2:  # a bend: the tip moves laterally
        assert np.abs(sym.tip_position[1:]).max() > 1e-3


def test_locked_symmetric_lengths(small):
    L0 = small.tendon_lengths(small.zero_state())
    kw = dict(pressure=40e3, locked_lengths=list(0.99 * L0))
    sym = small.solve(**kw)
    full = small.solve(**kw, symmetry=False)
    assert sym.stats.symmetry_order == 6
    assert np.all(full.tensions > 0.1)
    _agree(sym, full)
    assert np.abs(sym.tendon_lengths - 0.99 * L0).max() < 1e-10


def test_warm_start_lower_symmetry(small):
    a = small.solve(tensions=[1, 0, 0], pressure=10e3)      # mirror-symmetric state
    b = small.solve(tensions=[0, 0.5, 1], pressure=10e3)    # no symmetry
    assert a.stats.symmetry_order == 2 and b.stats.symmetry_order == 1
    sym = small.solve(tensions=[1, 1, 1], pressure=10e3, initial=a)
    full = small.solve(tensions=[1, 1, 1], pressure=10e3, initial=a, symmetry=False)
    assert sym.stats.symmetry_order == 2                    # the start state's mirror, not C3v
    _agree(sym, full)
    sym = small.solve(tensions=[1, 1, 1], pressure=10e3, initial=b)
    full = small.solve(tensions=[1, 1, 1], pressure=10e3, initial=b, symmetry=False)
    assert sym.stats.symmetry_order == 1
    _agree(sym, full)


def test_tip_compliance_at_symmetric_solve(small, c3v_solution):
    sym = small.solve(tensions=[3, 3, 3], pressure=50e3)
    C1, C2 = small.tip_compliance(sym), small.tip_compliance(c3v_solution)
    assert np.abs(C1 - C2).max() < 1e-7 * np.abs(C2).max()
    C1, C2 = small.tip_compliance(sym, "locked"), small.tip_compliance(c3v_solution, "locked")
    assert np.abs(C1 - C2).max() < 1e-7 * np.abs(C2).max()


def test_symmetry_flag_typed(small):
    with pytest.raises(InputError):
        small.solve(tensions=[1, 1, 1], symmetry="yes")
    with pytest.raises(InputError):
        small.solve(tensions=[1, 1, 1], symmetry=1)


def test_nearly_symmetric_start_uses_full_steps_where_needed(small, c3v_solution):
    """A start state asymmetric below the state tolerance (1e-9 L) is taken as symmetric; the residual's part
    outside the subspace is then above the Newton tolerance, so those steps use the full system and the answer is
    the full solve's."""
    import copy
    res = copy.copy(c3v_solution)
    res.state = c3v_solution.state.copy()
    node = small.caps.free_nodes[7]
    res.state.U[:, node] += 2e-11
    kw = dict(tensions=[3.0, 3.0, 3.0], pressure=51e3, initial=res)
    sym = small.solve(**kw)
    full = small.solve(**kw, symmetry=False)
    assert sym.stats.symmetry_order == 6
    assert sym.stats.n_symmetric_steps < sym.stats.n_factorizations  # some steps fell back to the full system
    _agree(sym, full)
