"""Tendon friction in the FEM reference: the capstan law at the guide points with stick/slip history
(fem_reference.loads.tendon_friction; docs/fem.md "Tendon friction")."""

import numpy as np
import pytest

from ancf.errors import InputError
from fem_reference import BellowsModel, MeshLevel, presets
from fem_reference.loads.tendon_friction import (
    SLIP_IN,
    SLIP_OUT,
    STICK,
    FrictionLaw,
    FrictionProfile,
    tension_profile,
    wrap_angles,
)

TINY = MeshLevel(2, 1, 12, 1)
E_IN = np.array([1.0, 0.0, 0.0])


@pytest.fixture(scope="module")
def model():
    return BellowsModel(presets.paper_bellows(), presets.paper_material(), TINY)


@pytest.fixture(scope="module")
def bent(model):
    return model.solve(tensions=(3.0, 0.0, 1.0), pressure=1e4)


def _angles_by_arccos(pts: np.ndarray) -> np.ndarray:
    """Turning angles at points 0 … n−1 of a polyline (motor side of point 0 along +x), by arccos of the unit
    directions' dot products (an evaluation independent of wrap_angles' atan2 form)."""
    d = np.vstack([E_IN[None], np.diff(pts, axis=0)])
    u = d / np.linalg.norm(d, axis=1)[:, None]
    return np.arccos(np.clip(np.einsum("kc,kc->k", u[:-1], u[1:]), -1.0, 1.0))


def test_wrap_angle_gradients_match_finite_differences():
    rng = np.random.default_rng(2)
    x = np.cumsum(np.vstack([np.zeros(3), [0.02, 0.0, 0.0] + 3e-3 * rng.standard_normal((6, 3))]), axis=0)
    a, da = wrap_angles(x, E_IN)
    assert np.allclose(a, _angles_by_arccos(x), atol=1e-12)
    h = 1e-7
    for j in range(x.shape[0]):
        for c in range(3):
            xp, xm = x.copy(), x.copy()
            xp[j, c] += h
            xm[j, c] -= h
            fd = (wrap_angles(xp, E_IN)[0] - wrap_angles(xm, E_IN)[0]) / (2 * h)
            assert np.allclose(fd, da[:, j, c], rtol=1e-6, atol=1e-6)


def test_profile_cone_stick_and_slip():
    """Every segment inside the cone of its predecessor; slipping ones on its edge, stuck ones at the held
    tension; loading from slack slips everywhere: T_k = T exp(−μ Σ_{j≤k} α_j)."""
    alpha = np.array([0.1, 0.2, 0.05, 0.3])
    mu = 0.25
    T, code, _ = tension_profile(2.0, np.zeros(4), alpha, mu)
    assert np.all(code == SLIP_IN)
    assert np.allclose(T, 2.0 * np.exp(-mu * np.cumsum(alpha)), rtol=1e-14)
    held = np.array([2.03, 1.0, 3.0, 2.0])
    T, code, _ = tension_profile(2.0, held, alpha, mu)
    prev = np.concatenate([[2.0], T[:-1]])
    assert np.all(T >= prev * np.exp(-mu * alpha) - 1e-14) and np.all(T <= prev * np.exp(mu * alpha) + 1e-14)
    assert list(code) == [STICK, SLIP_IN, SLIP_OUT, STICK]
    assert T[0] == 2.03 and T[3] == 2.0


def test_mu_zero_is_todays_fem_exactly(model):
    """friction=0 takes the frictionless path: the same tip and the same iteration counts; and the friction
    terms evaluated with μ = 0 (any history) are the frictionless residual and tangent to round-off."""
    a = model.solve(tensions=(2.0, 0.0, 0.5), pressure=1e4)
    b = model.solve(tensions=(2.0, 0.0, 0.5), pressure=1e4, friction=0.0)
    assert np.allclose(a.tip_position, b.tip_position, rtol=1e-12, atol=0)
    assert [s["iterations"] for s in a.stats.steps] == [s["iterations"] for s in b.stats.steps]
    assert a.iterations == b.iterations
    st = a.state
    lc = model._loadcase(st.T, 1e4, (0.0, 0.0, 0.0), False, None)
    ev0 = model.evaluate(st, lc)
    held = np.random.default_rng(1).uniform(0, 3, (model.m, len(model.tendons[0].guide_nodes) + 1))
    lc.friction = FrictionLaw(0.0, held, E_IN)
    ev1 = model.evaluate(st, lc)
    assert np.linalg.norm(ev1["r"] - ev0["r"]) <= 1e-12 * np.linalg.norm(model.evaluate(
        st, model._loadcase(np.zeros(3), 1e4, (0, 0, 0), False, None), tangent=False)["r"] - ev0["r"])
    assert abs(ev1["K"] - ev0["K"]).max() <= 1e-12 * abs(ev0["K"]).max()
    assert np.allclose(ev1["g"], ev0["g"], rtol=0, atol=1e-15)


def test_tangent_matches_finite_differences_with_slip_in_stick_and_slip_out(model, bent):
    """The full non-symmetric Newton matrix with friction equals the central difference of the residual at a
    perturbed state whose tendons slip toward the motor, stick and slip back out."""
    rng = np.random.default_rng(5)
    st = model._apply(bent.state, 2e-5 * rng.standard_normal(model.n_dofs))
    st.T[:] = [2.0, 0.0, 1.0]
    alpha0 = model.friction_profile(bent).wrap_angles[0]
    n = alpha0.size
    held = np.zeros((model.m, n))
    held[0] = 2.0 * np.exp(-0.3 * np.cumsum(alpha0)) * np.linspace(0.9, 1.1, n)
    held[2] = 3.0
    lc = model._loadcase(st.T, 2e4, (0.3, -0.2, -0.5), True, None)
    lc.friction = FrictionLaw(0.3, held, E_IN)
    codes = set()
    for k in (0, 2):
        pts = model.tendons[k].points(model.bmesh.X + st.U, model.X_c + st.uc, st.R)
        codes |= set(tension_profile(st.T[k], held[k], wrap_angles(pts, E_IN)[0], 0.3)[1].tolist())
    assert codes == {SLIP_IN, STICK, SLIP_OUT}
    K = model.evaluate(st, lc)["K"]
    assert abs(K - K.T).max() > 1e-6 * abs(K).max()          # friction is not conservative
    h = 1e-7
    for _ in range(2):
        d = rng.standard_normal(model.n_dofs)
        d[model.caps.n_free + 3:] *= 10.0
        rp = model.evaluate(model._apply(st, d, h), lc, tangent=False)["r"]
        rm = model.evaluate(model._apply(st, d, -h), lc, tangent=False)["r"]
        fd, an = (rp - rm) / (2 * h), K @ d
        assert np.linalg.norm(fd - an) < 1e-6 * np.linalg.norm(an)


def test_capstan_ratio_when_every_guide_slips(model):
    """Loading from slack: every guide slips toward the motor and the anchor segment's tension is the motor's
    times exp(−μ Σα) over the guides' angles (measured on the converged polyline); the loaded equilibrium bends
    less than the frictionless one (the tendon pulls with less than the motor tension past the first guide)."""
    mu = 0.3
    res = model.solve(tensions=(2.0, 0.0, 0.0), friction=mu)
    prof = model.friction_profile(res)
    assert np.all(prof.sliding[0] == SLIP_IN)
    pts = model.tendons[0].points(model.bmesh.X + res.state.U, model.X_c + res.state.uc, res.state.R)
    alpha = _angles_by_arccos(pts)
    assert alpha.sum() > 0.1
    assert prof.segment_tensions[0, -1] / 2.0 == pytest.approx(np.exp(-mu * alpha.sum()), rel=1e-10)
    free = model.solve(tensions=(2.0, 0.0, 0.0))
    assert 0 < res.tip_position[2] < free.tip_position[2]


def test_friction_inputs_are_checked(model, bent):
    for bad in (-0.1, 1.5, float("nan")):
        with pytest.raises(InputError):
            model.solve(tensions=(1.0, 0.0, 0.0), friction=bad)
    with pytest.raises(InputError, match="locked"):
        model.solve(locked_lengths=(0.16, None, None), friction=0.2)
    with pytest.raises(InputError, match="μ"):
        model.solve(tensions=(1.0, 0.0, 0.0), friction=0.2, friction_state=model.friction_profile(bent))
    with pytest.raises(InputError, match="friction > 0"):
        model.solve(tensions=(1.0, 0.0, 0.0), friction_state=FrictionProfile(0.2, np.zeros((3, 8)),
                                                                            np.zeros((3, 8)), np.zeros((3, 8))))
    with pytest.raises(InputError, match="FrictionProfile"):
        model.solve(tensions=(1.0, 0.0, 0.0), friction=0.2, friction_state="slack")


@pytest.mark.slow
def test_cycle_loop_opens_and_grows_with_mu(model):
    """A cycle 0 → 2 N → 0 in 3 steps per branch: the loop closes at 0 N, its area is > 0 and grows with μ;
    the unloading branch lies above the loading one at the mid tension (the tendon holds the bend)."""
    areas = {}
    for mu in (0.1, 0.3):
        cyc = model.tension_cycle([2.0, 0.0, 0.0], 0.0, steps=3, friction=mu)
        up, down = cyc.branches()
        assert np.allclose(up[0], down[0], atol=1e-8)
        assert down[1][2] > up[1][2]
        areas[mu] = cyc.loop_area
    assert 0 < areas[0.1] < areas[0.3]
