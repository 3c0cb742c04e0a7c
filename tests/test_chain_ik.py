"""The chain's IK with redundant tendons (ancf.chain_ik; docs/multisegment.md, "Inverse problem").

Every check is against an independent computation: the FK of the returned tensions (a cold solve), finite
differences of the tip and of the compliance through FK solves, ancf.Model.ik for one segment, and the tensions
that generated a target (feasible, so no better than the optimum)."""

import time

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from ancf import ChainIKEquilibrium, ChainModel, Model, presets
from ancf.chain_ik import _Problem, _target
from ancf.errors import InfeasibleTargetError, InputError, LimitError

PR = np.array([30e3, 60e3])
T_GEN = np.array([1.0, 0.4, 0.2, 1.5, 0.3, 0.6])
T_GEN2 = np.array([0.5, 1.4, 0.8, 0.2, 1.0, 0.1])
UZ = np.array([0.0, 0.0, 1.0])


@pytest.fixture(scope="module")
def chain():
    return ChainModel(presets.two_segment())


@pytest.fixture(scope="module")
def targets(chain):
    return {k: chain.fk(T, PR) for k, T in (("a", T_GEN), ("b", T_GEN2))}


def _tip_jacobian_fd(model, T, pr, z0, d=1e-5):
    """∂p_end/∂T (3, m) by central differences of FK solves."""
    J = np.zeros((3, model.m))
    for j in range(model.m):
        e = np.zeros(model.m)
        e[j] = d
        J[:, j] = (model.fk(T + e, pr, z0=z0, check_limits=False).tip
                   - model.fk(T - e, pr, z0=z0, check_limits=False).tip) / (2 * d)
    return J


def _project(model, T, free, target, pr, z0):
    """Back onto p_end(T) = target by Newton steps over the tensions ``free`` (finite-difference Jacobian)."""
    T = T.copy()
    for _ in range(6):
        eq = model.fk(T, pr, z0=z0, check_limits=False)
        r = eq.tip - target
        if np.linalg.norm(r) < 1e-11:
            break
        J = _tip_jacobian_fd(model, T, pr, eq.z)
        T[free] -= np.linalg.lstsq(J[:, free], r, rcond=None)[0]
    assert np.linalg.norm(model.fk(T, pr, z0=z0, check_limits=False).tip - target) < 1e-10
    return T


def _feasible_directions(model, r, lo, hi):
    """Directions d (m,) with ∂p/∂T d = 0 that keep the bounds: a basis of the null space over the free tensions
    (both signs), and for each tension at a bound the direction that moves it inward, the other bounds held."""
    T = r.tensions
    active = np.array([j in r.kkt["active"] for j in range(model.m)])
    free = ~active
    J = _tip_jacobian_fd(model, T, PR, r.z)
    dirs = []
    if free.sum() > 3:
        _, _, Vt = np.linalg.svd(J[:, free])
        for v in Vt[3:]:
            for sgn in (1.0, -1.0):
                d = np.zeros(model.m)
                d[free] = sgn * v
                dirs.append(d)
    for i in np.nonzero(active)[0]:
        d = np.zeros(model.m)
        d[i] = 1.0 if T[i] <= lo[i] else -1.0
        d[free] = -np.linalg.lstsq(J[:, free], J[:, i] * d[i], rcond=None)[0]
        dirs.append(d)
    return dirs, free


def _check_no_descent(model, r, f, target, eps=0.05):
    """f does not fall along any feasible direction on the constraint (moved ε, projected back)."""
    lo, hi = np.zeros(model.m), np.full(model.m, 5.0)
    dirs, free = _feasible_directions(model, r, lo, hi)
    assert dirs
    f0 = f(r.tensions)
    for d in dirs:
        d = d / np.linalg.norm(d)
        T1 = np.clip(r.tensions + eps * d, lo, hi)
        moved = free | (np.abs(d) > 0)
        T1 = _project(model, T1, moved & (T1 > 0), target, PR, r.z)
        assert np.all(T1 >= lo - 1e-12) and np.all(T1 <= hi + 1e-12)
        assert f(T1) >= f0 - 1e-9 * abs(f0), (d, f(T1) - f0)


def _reached(model, r, target, pr=PR):
    cold = model.fk(r.tensions, pr)                  # an independent FK from the straight chain
    assert np.linalg.norm(cold.tip - target) < 1e-8
    assert np.linalg.norm(r.tip - target) < 1e-8


# ----------------------------------------------------------------------------- one segment
@pytest.mark.parametrize("T, pr", [((1.5, 0.8, 0.2), 30e3), ((2.0, 0.0, 0.5), 0.0), ((0.3, 1.2, 2.2), 90e3)])
def test_one_segment_chain_ik_is_model_ik(T, pr):
    params = presets.paper()
    model, one = Model(params), ChainModel(params)
    eq = model.fk(T, pr)
    a = model.ik(eq.tip, pr, tol_position=1e-12)
    for objective, u in (("least_tension", None), ("compliance", UZ)):
        b = one.ik(eq.tip, pr, objective=objective, compliance_direction=u, tol_position=1e-12)
        assert np.max(np.abs(a.tensions - b.tensions)) < 1e-8
        assert np.linalg.norm(a.tip - b.tip) < 1e-11
        np.testing.assert_allclose(b.q, a.q, atol=1e-10)


def test_one_segment_unreachable_as_model():
    params = presets.paper()
    with pytest.raises(InfeasibleTargetError) as a:
        Model(params).ik([0.1, 0.0, -0.15], 30e3)
    with pytest.raises(InfeasibleTargetError) as b:
        ChainModel(params).ik([0.1, 0.0, -0.15], 30e3)
    assert np.linalg.norm(a.value.nearest - b.value.nearest) < 1e-6
    assert "T1 >= 0 N" in b.value.violated


# ----------------------------------------------------------------------------- least tension
@pytest.mark.parametrize("key, T_gen", [("a", T_GEN), ("b", T_GEN2)])
def test_least_tension_reaches_target_inside_bounds(chain, targets, key, T_gen):
    target = targets[key].tip
    r = chain.ik(target, PR)
    assert isinstance(r, ChainIKEquilibrium) and r.solver == "ik"
    _reached(chain, r, target)
    assert np.all(r.tensions >= 0) and np.all(r.tensions <= 5)
    # the generating tensions reach the target too: the optimum has no more Σ T²
    assert r.tensions @ r.tensions <= T_gen @ T_gen + 1e-9
    assert r.objective_value == pytest.approx(0.5 * r.tensions @ r.tensions)
    assert r.kkt["stationarity"] < 1e-6 and r.kkt["multiplier_min"] >= -1e-8 and r.kkt["bounds_N"] == 0.0
    assert r.kkt["primal_m"] < 1e-8


@pytest.mark.parametrize("key", ["a", "b"])
def test_least_tension_no_feasible_descent(chain, targets, key):
    target = targets[key].tip
    r = chain.ik(target, PR)
    _check_no_descent(chain, r, lambda T: 0.5 * T @ T, target)


# ----------------------------------------------------------------------------- compliance
def _compliance(chain, z0):
    def f(T):
        return UZ @ chain.compliance(chain.fk(T, PR, z0=z0, check_limits=False)) @ UZ
    return f


def test_compliance_gradient_against_fk_differences(chain, targets):
    eq = targets["b"]
    prob = _Problem(chain, _target(chain, eq.tip, None), PR, np.zeros(3), UZ, chain.default_tol, eq.z)
    f = _compliance(chain, eq.z)
    d = 1e-4
    fd = np.array([(f(T_GEN2 + d * e) - f(T_GEN2 - d * e)) / (2 * d) for e in np.eye(6)])
    np.testing.assert_allclose(prob.grad(T_GEN2), fd, rtol=1e-6, atol=1e-9 * np.max(np.abs(fd)))
    assert prob.f(T_GEN2) == pytest.approx(f(T_GEN2), rel=1e-12)


@pytest.mark.parametrize("key", ["a", "b"])
def test_stiff_along_z_differs_from_least_tension(chain, targets, key):
    target = targets[key].tip
    lt = chain.ik(target, PR)
    st_ = chain.ik(target, PR, objective="compliance", compliance_direction=UZ)
    _reached(chain, st_, target)
    assert np.all(st_.tensions >= 0) and np.all(st_.tensions <= 5)
    assert np.max(np.abs(st_.tensions - lt.tensions)) > 0.1
    c_lt = UZ @ chain.compliance(chain.fk(lt.tensions, PR)) @ UZ
    c_st = UZ @ chain.compliance(chain.fk(st_.tensions, PR)) @ UZ
    assert c_st < c_lt - 1e-4 * c_lt                     # stiffer along z …
    assert st_.tensions @ st_.tensions > lt.tensions @ lt.tensions   # … for more tension
    assert st_.objective_value == pytest.approx(c_st, rel=1e-9)
    assert st_.kkt["stationarity"] < 1e-6 and st_.kkt["multiplier_min"] >= -1e-8


def test_stiff_along_z_no_feasible_descent(chain, targets):
    target = targets["b"].tip
    r = chain.ik(target, PR, objective="compliance", compliance_direction=UZ)
    _check_no_descent(chain, r, _compliance(chain, r.z), target, eps=0.02)


# ----------------------------------------------------------------------------- pose, errors
def test_pose_reaches_position_and_direction(chain, targets):
    eq = targets["a"]
    d = eq.tip_rotation[:, 0]
    r = chain.ik(eq.tip, PR, tip_direction=2.0 * d)
    _reached(chain, r, eq.tip)
    t = chain.fk(r.tensions, PR).tip_rotation[:, 0]
    assert np.linalg.norm(t - d) < 1e-8
    assert r.multipliers.shape == (5,)
    assert r.tensions @ r.tensions <= T_GEN @ T_GEN + 1e-9


def test_unreachable_target_refused_quickly(chain):
    t = time.perf_counter()
    with pytest.raises(InfeasibleTargetError) as exc:
        chain.ik([0.1, 0.1, 0.1], PR)
    assert time.perf_counter() - t < 20.0
    e = exc.value
    assert np.linalg.norm(e.nearest - e.target) > 1e-3
    assert np.all(e.tensions >= 0) and np.all(e.tensions <= 5)
    np.testing.assert_allclose(chain.fk(e.tensions, PR).tip, e.nearest, atol=1e-9)


@pytest.mark.parametrize("kwargs, error", [
    ({"target": [np.nan, 0, 0]}, InputError),
    ({"target": [0.1, 0.0]}, InputError),
    ({"tip_direction": [0, 0, 0]}, InputError),
    ({"objective": "stiffest"}, InputError),
    ({"objective": "compliance"}, InputError),
    ({"compliance_direction": UZ}, InputError),
    ({"objective": "compliance", "compliance_direction": [0, 0, 0]}, InputError),
    ({"pressures": [30e3, 200e3]}, LimitError),
    ({"pressures": [30e3]}, InputError),
    ({"tensions0": [1.0, 2.0]}, InputError),
    ({"tol_position": 0.0}, InputError),
])
def test_bad_inputs_are_typed_errors(chain, kwargs, error):
    args = {"target": [0.17, -0.05, 0.01], "pressures": PR, **kwargs}
    with pytest.raises(error):
        chain.ik(args.pop("target"), args.pop("pressures"), **args)


def test_pose_needs_five_tendons():
    with pytest.raises(InputError, match="at least 5 tendons"):
        ChainModel(presets.paper()).ik([0.16, 0, 0], 0.0, tip_direction=[1, 0, 0])


@settings(max_examples=4, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.lists(st.floats(0.05, 2.5), min_size=6, max_size=6))
def test_least_tension_property(chain, T):
    """For any target made by tensions inside the bounds: reached, inside the bounds, no more Σ T²."""
    T = np.array(T)
    target = chain.fk(T, PR).tip
    r = chain.ik(target, PR)
    _reached(chain, r, target)
    assert np.all(r.tensions >= 0) and np.all(r.tensions <= 5)
    assert r.tensions @ r.tensions <= T @ T + 1e-9


def test_documented_example(chain, targets):
    """The numbers of docs/multisegment.md, "Inverse problem" (two objectives on one target)."""
    target = targets["b"].tip
    lt = chain.ik(target, PR)
    cz = chain.ik(target, PR, objective="compliance", compliance_direction=UZ)
    np.testing.assert_allclose(lt.tensions, [0.22, 0.46, 0.26, 0.40, 1.41, 0.0], atol=0.006)
    np.testing.assert_allclose(cz.tensions, [0.0005, 0.0, 0.0, 0.55, 1.59, 0.0], atol=0.006)
    assert round(lt.objective_value, 2) == 1.24 and round(0.5 * cz.tensions @ cz.tensions, 2) == 1.42
    assert round(UZ @ chain.compliance(lt) @ UZ, 4) == 0.1029 and round(cz.objective_value, 4) == 0.1025
    for p, c in ((0.0, 0.118), (120e3, 0.159)):
        eq = chain.fk([1, 0, 0, 2, 0, 0], [p, p])
        assert round(UZ @ chain.compliance(eq) @ UZ, 3) == c


# ----------------------------------------------------------------------------- obstacles
def _centreline(model, q, per_element=4):
    """Body points by kin.interpolate of each segment's node chain (independent of ancf.chain_ik.Body)."""
    from ancf import kinematics as kin
    return np.vstack([kin.interpolate(model.sys.segment_q(q, k), s.params.n_elements, s.params.length, per_element)
                      for k, s in enumerate(model.sys.segments)])


@pytest.fixture(scope="module")
def blocked(chain, targets):
    """A sphere (radius 15 mm, margin 10 mm) whose centre is 20 mm outside the least-tension shape's middle: that
    shape crosses it by 5 mm."""
    tg = targets["b"].tip
    free = chain.ik(tg, PR)
    x = _centreline(chain, free.q)
    mid = x[len(x) // 2]
    n = mid - 0.5 * (x[0] + x[-1])
    centre = mid + 0.020 * n / np.linalg.norm(n)
    return tg, free, centre


def test_obstacle_kept_out_and_target_reached(chain, blocked):
    tg, free, centre = blocked
    R, margin = 0.015, 0.010
    assert np.linalg.norm(_centreline(chain, free.q) - centre, axis=1).min() < R + margin - 4e-3
    r = chain.ik(tg, PR, obstacles=[(centre, R)], obstacle_margin=margin)
    eq = chain.fk(r.tensions, PR)                          # cold
    assert np.linalg.norm(eq.tip - tg) < 1e-8
    assert np.linalg.norm(_centreline(chain, eq.q) - centre, axis=1).min() >= R + margin - 1e-8
    assert r.kkt["clearance_m"] >= -1e-8 and r.kkt["stationarity"] < 1e-5 and r.kkt["multiplier_min"] > -1e-5
    assert r.kkt["obstacle_active"] and np.all(r.kkt["obstacle_multipliers"] > 0)    # the sphere binds
    assert r.objective_value > free.objective_value         # keeping out costs tension


def test_obstacle_gradient_against_fk_differences(chain, blocked):
    """∂g/∂T (through the FK's tangent) against central differences of FK solves."""
    from ancf.chain_ik import _obstacles
    tg, free, centre = blocked
    obs = _obstacles(chain, [(centre, 0.015)], 0.01, 4)
    prob = _Problem(chain, _target(chain, tg, None), free.pressures, free.tip_force, None, chain.default_tol, free.z,
                    obs)
    T = free.tensions + 0.3
    G = prob.g_jac(T)
    h = 1e-5
    for j in range(chain.m):
        e = np.zeros(chain.m)
        e[j] = h
        gp = obs.g(chain.fk(T + e, PR, z0=free.z).z)
        gm = obs.g(chain.fk(T - e, PR, z0=free.z).z)
        np.testing.assert_allclose(G[:, j], (gp - gm) / (2 * h), atol=1e-7 * max(1.0, np.abs(G).max()))


def test_one_segment_crossing_an_obstacle_is_refused():
    """One segment: the target fixes the shape; a sphere across it is an InfeasibleTargetError naming it."""
    one = ChainModel(presets.paper())
    eq = one.fk([1.0, 3.0, 3.0], [90e3])
    x = _centreline(one, eq.q)
    with pytest.raises(InfeasibleTargetError, match="inside obstacle 1"):
        one.ik(eq.tip, [90e3], obstacles=[(x[len(x) // 2], 0.01)])
    clear = one.ik(eq.tip, [90e3], obstacles=[(x[len(x) // 2] + [0, 0, 0.2], 0.01)])
    assert np.allclose(clear.tensions, eq.tensions, atol=1e-6) and clear.kkt["clearance_m"] > 0.15


@pytest.mark.parametrize("obstacles, kw", [
    (5.0, {}), ([(0, 0, 0)], {}), ([((0, 0), 0.01)], {}), ([((0, 0, 0), -0.01)], {}),
    ([((0, 0, np.nan), 0.01)], {}), ([((0, 0, 1), 0.01)], {"obstacle_margin": -1e-3}),
    ([((0, 0, 1), 0.01)], {"obstacle_samples": 0}), ([((0, 0, 1), 0.01)], {"obstacle_samples": 2.5})])
def test_obstacle_inputs_checked(chain, targets, obstacles, kw):
    with pytest.raises(InputError):
        chain.ik(targets["a"].tip, PR, obstacles=obstacles, **kw)
