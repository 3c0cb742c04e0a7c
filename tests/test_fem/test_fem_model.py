"""Bellows model: Newton convergence order, tip compliance vs FD of the nonlinear solve (tension and
locked), tendon slack, errors, result API."""

import json

import numpy as np
import pytest

from ancf.errors import ConvergenceError, InputError
from fem_reference import BellowsModel, MeshLevel, presets

TINY = MeshLevel(2, 1, 12, 1)


@pytest.fixture(scope="module")
def model():
    return BellowsModel(presets.paper_bellows(), presets.paper_material(), TINY)


@pytest.fixture(scope="module")
def loaded(model):
    return model.solve(tensions=(2.0, 0.0, 0.0), pressure=20e3, tip_force=(0.0, 0.0, -0.49), gravity=True)


def _orders(h):
    """Observed convergence orders log(r_{k+1}/r_k) / log(r_k/r_{k-1}) on the asymptotic tail."""
    h = np.asarray(h)
    return [np.log(h[k + 1] / h[k]) / np.log(h[k] / h[k - 1]) for k in range(1, len(h) - 1)]


def test_newton_converges_quadratically(model, loaded, monkeypatch):
    """Observed order of the Newton corrections ‖Δq_k‖ on the tail of a load step is ≈ 2.  With plain updates:
    the ring rotations of fem_reference.corotation reach the round-off floor an iteration earlier here, which
    leaves too few corrections above it to measure an order (their tail is plain Newton too, below MIN_ANGLE)."""
    import fem_reference.model as fm
    monkeypatch.setattr(fm, "RING_UPDATE", False)
    res = model.solve(tensions=loaded.tensions, pressure=20e3, tip_force=(0.0, 0.1, -0.49), gravity=True,
                      initial=loaded, n_steps=1)
    step = res.stats.steps[-1]
    h, s = step["residuals"], step["step_norms"]
    assert h[-1] < 1e-9 * max(h)
    assert len(s) >= 3
    order = _orders(s[-3:])[0]
    assert order > 1.8, (s, order)
    # a linearly convergent iteration with the same first contraction would be far slower:
    assert s[-1] < (s[-2] / s[-3]) ** 1.8 * s[-2]


def test_loaded_state_is_plausible(model, loaded):
    r = loaded
    assert r.iterations >= len(r.stats.steps)
    # top tendon (θ = 0, +z) at 2 N bends the tip up against 50 g; result stays symmetric in y
    assert abs(r.tip_position[1]) < 1e-8
    c = r.centreline
    assert c.shape == (2 * model.bmesh.shape[0] + 1, 3)
    assert np.allclose(c[0], 0.0, atol=1e-12) and np.allclose(c[-1], r.cap_centre, atol=1e-9)
    L = r.tendon_lengths
    assert L[1] == pytest.approx(L[2], rel=1e-10)  # mirror symmetry about the x–z plane
    # the top tendon is on the outside of the bend when the tip goes down, inside when it goes up
    assert np.sign(L[0] - L[1]) == -np.sign(r.tip_position[2])
    R = r.cap_rotation
    assert np.allclose(R.T @ R, np.eye(3), atol=1e-12)
    json.dumps(r.summary())


def test_pressure_only_is_axisymmetric_extension(model):
    r = model.solve(pressure=30e3)
    assert r.tip_position[0] > model.geometry.length
    assert np.abs(r.tip_position[1:]).max() < 1e-9
    assert np.linalg.norm(r.cap_rotation_vector) < 1e-9
    assert np.allclose(r.tendon_lengths, r.tip_position[0], rtol=1e-9)


def test_single_tendon_matches_cap_compliance_in_the_linear_limit(model):
    """A tiny tension T on tendon θ = 0 equals force −T e_x and moment (d e_z)×(−T e_x) on the cap."""
    T = 1e-3
    r0 = model.solve()
    C6 = model.cap_compliance(r0)
    r = model.solve(tensions=(T, 0.0, 0.0))
    d = model.geometry.tendon_radius
    load = np.concatenate([[-T, 0, 0], np.cross([0, 0, d], [-T, 0, 0])])
    pred = C6 @ load
    got = np.concatenate([r.state.uc, r.cap_rotation_vector])
    assert np.allclose(got, pred, rtol=2e-3, atol=2e-3 * np.abs(pred).max())


@pytest.mark.parametrize("mode", ["tension", "locked"])
def test_tip_compliance_matches_fd_of_nonlinear_solve(model, loaded, mode):
    C = model.tip_compliance(loaded, mode=mode)
    h = 2e-3  # N
    F0 = np.asarray(loaded.loadcase.tip_force)
    locked = [float(loaded.tendon_lengths[0]), None, None] if mode == "locked" else None
    Cfd = np.zeros((3, 3))
    for j in range(3):
        pos = []
        for s in (1, -1):
            F = F0.copy()
            F[j] += s * h
            r = model.solve(tensions=loaded.tensions, pressure=20e3, tip_force=F, gravity=True,
                            initial=loaded, locked_lengths=locked, n_steps=1)
            if mode == "locked":
                assert abs(r.tendon_lengths[0] - locked[0]) < 1e-10
            pos.append(r.tip_position)
        Cfd[:, j] = (pos[0] - pos[1]) / (2 * h)
    assert np.abs(C - Cfd).max() < 1e-4 * np.abs(C).max(), (C, Cfd)
    if mode == "locked":
        Ct = model.tip_compliance(loaded, mode="tension")
        assert Ct[2, 2] > 1.2 * C[2, 2]  # locking the loaded tendon stiffens the tip vertically


def test_locked_tendon_goes_slack_instead_of_pushing(model, loaded):
    L0 = float(loaded.tendon_lengths[0])
    # push the tip upwards hard: the top tendon's path shortens, so the locked cable must go slack
    r = model.solve(locked_lengths=[L0, None, None], pressure=20e3, tip_force=(0.0, 0.0, 1.5), gravity=True,
                    initial=loaded)
    assert r.tensions[0] == 0.0
    assert r.tendon_lengths[0] < L0
    # and a downward load keeps it taut with a larger tension (the multiplier)
    r2 = model.solve(locked_lengths=[L0, None, None], pressure=20e3, tip_force=(0.0, 0.0, -1.0), gravity=True,
                     initial=loaded)
    assert r2.tensions[0] > loaded.tensions[0]
    assert abs(r2.tendon_lengths[0] - L0) < 1e-10


def test_errors(model):
    with pytest.raises(InputError, match="push"):
        model.solve(tensions=(-1.0, 0.0, 0.0))
    with pytest.raises(InputError):
        model.solve(tip_force=(0.0, np.nan, 0.0))
    with pytest.raises(ConvergenceError) as ei:
        model.solve(tensions=(5.0, 0.0, 0.0), pressure=60e3, n_steps=1, max_iter=2, max_cuts=0)
    e = ei.value
    assert e.solver == "fem_newton" and len(e.history) == 3 and e.residual_norm > e.tolerance


def test_save_vtu_round_trip(model, loaded, tmp_path):
    import meshio

    p = loaded.save_vtu(tmp_path / "out.vtu")
    m = meshio.read(p)
    assert m.points.shape[0] == model.bmesh.n_nodes
    u = m.point_data["displacement"]
    assert np.allclose(np.sort(np.linalg.norm(u, axis=1)), np.sort(np.linalg.norm(loaded.displacement.T, axis=1)))


def test_cap_reduction_equals_the_sparse_triple_product(model, loaded):
    """RigidCapReduction.reduce (index maps, no sparse products) against PᵀKP by sparse products, on a loaded
    state with a rotated cap and the follower pressure's non-symmetric tangent; extra 6×6 terms land on the cap
    block."""
    st = loaded.state
    assert np.linalg.norm(st.R - np.eye(3)) > 0.05
    f, K, _ = model.asm.assemble(st.U)
    fp, Kp = model.press.assemble(st.U, 20e3)
    K.data -= Kp.data
    r = f - fp
    extra = np.arange(36.0).reshape(6, 6)
    rq, Kq = model.caps.reduce(K, r, st.R, extra_cc=extra)
    rq_ref, Kq_ref = model.caps.reduce_reference(K, r, st.R)
    s = model.caps.n_free
    Kq_ref = Kq_ref.tolil()
    Kq_ref[s:, s:] = Kq_ref[s:, s:].toarray() + extra
    assert np.abs(rq - rq_ref).max() <= 1e-13 * np.abs(rq_ref).max()
    assert abs(Kq - Kq_ref.tocsr()).max() <= 1e-13 * abs(Kq_ref).max()
    assert model.caps.reduce(None, r, st.R)[1] is None


def test_step_control_does_not_change_the_answer(model, monkeypatch):
    """Intermediate load steps converged loosely (STEP_RTOL) and failing steps cut after STALL_ITERATIONS give
    the equilibrium of tight steps without the stall rule, to the solve's tolerance; a failed step is abandoned
    after at most STALL_ITERATIONS + 1 residuals when it stalls."""
    import fem_reference.model as fm
    kw = dict(tensions=(4.0, 0.0, 0.0), pressure=60e3, n_steps=1)
    fast = model.solve(**kw)
    assert all(len(f["residuals"]) <= fm.STALL_ITERATIONS + 1 for f in fast.stats.failed_steps
               if f["reason"].startswith("not converging"))
    monkeypatch.setattr(fm, "STEP_RTOL", 1e-12)
    monkeypatch.setattr(fm, "STALL_ITERATIONS", 10 ** 6)
    tight = model.solve(**kw)
    L = model.geometry.length
    assert np.abs(fast.tip_position - tight.tip_position).max() < 1e-8 * L
    assert np.abs(fast.state.U - tight.state.U).max() < 1e-8 * L
    # the loose steps do less work: fewer Newton iterations for the same path
    assert fast.stats.n_iterations < tight.stats.n_iterations


def test_tangent_assembled_only_for_newton_steps(model, loaded, monkeypatch):
    """Every tangent assembly of a solve serves a factorisation: the line search's trial states and a load step's
    start under its new loads need residuals only (each tangent costs about as much as a factorisation), and the
    answer is the same as with tangents everywhere (same iterates: the residuals are unchanged)."""
    from fem_reference.model import BellowsModel as BM
    calls = {True: 0, False: 0}
    plain = BM.evaluate

    def counting(self, st, lc, tangent=True, stats=None):
        calls[bool(tangent)] += 1
        return plain(self, st, lc, tangent=tangent, stats=stats)

    monkeypatch.setattr(BM, "evaluate", counting)
    res = model.solve(tensions=(2.0, 0.5, 0.0), pressure=30e3, tip_force=(0.0, 0.1, 0.0), n_steps=3,
                      check_stability=False)
    assert len(res.stats.steps) >= 3
    assert calls[True] == res.stats.n_factorizations, calls
    assert calls[False] >= res.stats.n_iterations

    def always_tangent(self, st, lc, tangent=True, stats=None):
        return plain(self, st, lc, tangent=True, stats=stats)

    monkeypatch.setattr(BM, "evaluate", always_tangent)
    ref = model.solve(tensions=(2.0, 0.5, 0.0), pressure=30e3, tip_force=(0.0, 0.1, 0.0), n_steps=3,
                      check_stability=False)
    assert ref.stats.n_factorizations == res.stats.n_factorizations
    assert np.abs(ref.state.U - res.state.U).max() <= 1e-12 * model.geometry.length
