"""Tendon friction with hysteresis (ancf.forces.tendon_friction, ancf.friction, Model.fk_history / tension_cycle):
μ = 0 is the frictionless model; the capstan law against its closed form on a circular arc; every derivative
against finite differences; the hysteresis loop of a tension cycle."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ancf import ActuatorParams, ConfigError, InputError, Model, compliance, presets
from ancf import friction as fr
from ancf.forces import tendon_friction as tf

P, F = 20e3, np.array([0.0, 0.0, 0.2])


@pytest.fixture(scope="module")
def model():
    return Model(presets.paper().replace(tendon_friction=0.3))


@pytest.fixture(scope="module")
def cycles():
    out = {}
    for mu in (0.0, 0.01, 0.1, 0.3):
        out[mu] = Model(presets.paper().replace(tendon_friction=mu)).tension_cycle([4.0, 0.0, 0.0], P, steps=8)
    return out


# ------------------------------------------------------------------------------------------------ parameters
def test_the_friction_coefficient_is_a_checked_parameter_in_the_file():
    p = presets.paper()
    assert p.tendon_friction == 0.0 and "tendon_friction" not in p.to_toml()     # files without it unchanged
    q = p.replace(tendon_friction=0.2)
    assert "tendon_friction = 0.2" in q.to_toml()
    assert ActuatorParams.from_toml_string(q.to_toml()) == q
    for bad in (-0.01, 1.5, float("nan"), "0.1", True):
        with pytest.raises(ConfigError, match="tendon_friction"):
            p.replace(tendon_friction=bad)
    with pytest.raises(ConfigError, match="tendon_friction"):
        ActuatorParams.from_toml_string(q.to_toml().replace("tendon_friction = 0.2", "tendon_friction = 2.0"))


# ------------------------------------------------------------------------------------------------ μ = 0
def test_without_friction_fk_history_is_fk_bit_for_bit():
    m = Model(presets.paper())
    s = m.fk_history([3.0, 1.0, 0.0], P, F)
    eq = m.fk([3.0, 1.0, 0.0], P, F)
    assert np.array_equal(s.q, eq.q) and np.array_equal(s.tip, eq.tip)
    s2 = m.fk_history([2.0, 1.5, 0.5], P, F, s)
    assert np.array_equal(s2.q, m.fk([2.0, 1.5, 0.5], P, F, s.q).q)
    assert np.array_equal(s2.segment_tensions, np.repeat([[2.0], [1.5], [0.5]], m.n, axis=1))


def test_one_tension_on_every_segment_gives_the_frictionless_forces(model):
    q = model.fk([3.0, 1.0, 0.5], P, F).q
    T = np.array([3.0, 1.0, 0.5])
    ok, G, H, lseg, J = tf.segment_forces(q, model.n, model._N, model._wq, model._E, model._d, model._co,
                                          model._so, np.repeat(T[:, None], model.n, axis=1), True)
    ev, ev0 = model.evaluate(q, T, P, F), model.evaluate(q, np.zeros(3), P, F)
    assert ok
    assert np.allclose(G, ev.Q - ev0.Q, rtol=0, atol=1e-12 * np.abs(ev.Q - ev0.Q).max())
    assert np.allclose(H, ev.K - ev0.K, rtol=0, atol=1e-12 * np.abs(ev.K).max())
    assert np.allclose(lseg.sum(axis=1), ev.lengths, rtol=1e-14) and np.allclose(J.sum(axis=1), ev.J_l, atol=1e-15)
    # the whole residual at μ = 0 (any history) is the model's
    parts = fr._parts(model, q, T, np.full((3, model.n), 7.0), 0.0, P, F, True)
    assert np.allclose(parts["Q"], ev.Q, rtol=0, atol=1e-12 * np.abs(ev.Q).max())


# ------------------------------------------------------------------------------------------------ geometry
def test_guide_points_are_the_tendon_paths_at_the_nodes(model):
    q = model.fk([3.0, 1.0, 0.5], P, F).q
    ok, Pg, _G = tf.guide_points(q, model.n, model._E, model._d, model._co, model._so)
    assert ok and np.allclose(Pg, model.tendon_paths(q, per_element=1), rtol=0, atol=1e-15)


def _fd(fun, q, v, h):
    """Fourth-order central difference of fun along v."""
    return (8 * (fun(q + h * v) - fun(q - h * v)) - (fun(q + 2 * h * v) - fun(q - 2 * h * v))) / (12 * h)


def test_wrap_angle_and_guide_point_gradients_match_finite_differences(model):
    q = model.fk([3.0, 1.0, 0.5], P, F).q
    rng = np.random.default_rng(3)

    def parts(x):
        _ok, Pg, G = tf.guide_points(x, model.n, model._E, model._d, model._co, model._so)
        return Pg, G, *tf.wrap_angles(Pg, G, model._e1, model.ndof)
    _Pg, G, _alpha, dalpha = parts(q)
    for _ in range(3):
        v = rng.standard_normal(model.ndof)
        v[:6] = 0.0
        fd = _fd(lambda x: parts(x)[2], q, v, 1e-5)
        assert np.allclose(dalpha @ v, fd, rtol=0, atol=1e-7 * np.abs(fd).max())
        slope = np.zeros(model.ndof)
        slope[21:24] = v[21:24]                                       # node 3's slope only
        fdP = _fd(lambda x: parts(x)[0], q, slope, 1e-5)
        assert np.allclose(np.einsum("irc,c->ir", G[:, 3], v[21:24]), fdP[:, 3], rtol=0, atol=1e-9)


def _arc(n: int, theta: float, length: float = 0.16) -> np.ndarray:
    """Full coordinates of a planar circular arc of total turning theta bending towards +z (the θ = 0 tendon's
    side), nodes and slopes exact."""
    R = length / theta
    s = np.linspace(0.0, length, n + 1)
    q = np.zeros((n + 1, 6))
    q[:, 0], q[:, 2] = R * np.sin(s / R), R * (1 - np.cos(s / R))
    q[:, 3], q[:, 5] = np.cos(s / R), np.sin(s / R)
    return q.ravel()


@pytest.mark.parametrize("n", [6, 24])
def test_capstan_closed_form_on_a_circular_arc(n):
    m = Model(presets.paper().replace(n_elements=n))
    theta, mu = 1.2, 0.25
    q = _arc(n, theta)
    _ok, Pg, G = tf.guide_points(q, n, m._E, m._d, m._co, m._so)
    alpha, _ = tf.wrap_angles(Pg, G, m._e1, m.ndof)
    expect = np.full(n, theta / n)
    expect[0] = theta / (2 * n)
    for i in range(3):                        # every tendon, inner or outer, wraps its offset arc alike
        assert np.allclose(alpha[i], expect, rtol=0, atol=1e-12)
    wrap = theta * (1 - 1 / (2 * n))          # the guides' total wrap (the last half segment ends at the anchor)
    motor = np.array([2.0, 1.0, 3.0])
    T_in, code, _, _ = tf.tension_profile(motor, np.zeros((3, n)), alpha, mu)     # pulled in: loading
    assert np.all(code == tf.SLIP_IN)
    assert np.allclose(T_in[:, -1] / motor, math.exp(-mu * wrap), rtol=1e-13)
    T_out, code, _, _ = tf.tension_profile(motor, np.full((3, n), 1e3), alpha, mu)   # pulled out
    assert np.all(code == tf.SLIP_OUT)
    assert np.allclose(T_out[:, -1] / motor, math.exp(mu * wrap), rtol=1e-13)
    # the continuous capstan T_out/T_in = exp(μ Θ) as the guides get denser: an error of exactly μΘ/(2n)
    assert math.log(motor[0] / T_in[0, -1]) == pytest.approx(mu * theta - mu * theta / (2 * n), rel=1e-12)


# ------------------------------------------------------------------------------------------------ the law
@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(0.0, 5.0), min_size=4, max_size=4), st.lists(st.floats(0.0, 0.6), min_size=4, max_size=4),
       st.floats(0.0, 5.0), st.floats(0.0, 0.5))
def test_every_segment_ends_inside_the_friction_cone(held, alpha, motor, mu):
    held, alpha = np.array([held]), np.array([alpha])
    T, code, _, dTm = tf.tension_profile(np.array([motor]), held, alpha, mu)
    prev = np.concatenate([[motor], T[0, :-1]])
    f = np.exp(mu * alpha[0])
    assert np.all(T[0] >= prev / f * (1 - 1e-12)) and np.all(T[0] <= prev * f * (1 + 1e-12))
    assert np.all(T[0][code[0] == tf.STICK] == held[0][code[0] == tf.STICK])       # stuck: held
    h = 1e-6 * max(motor, 1.0)                                                    # ∂T/∂T_motor where smooth
    Tp, cp, _, _ = tf.tension_profile(np.array([motor + h]), held, alpha, mu)
    if motor > 0 and np.array_equal(cp, code):
        assert np.allclose((Tp - T) / h, dTm, rtol=1e-5, atol=1e-9)


def _held(model, q, motor, mu):
    """Held tensions that give the pattern slip in, slip in, stick, slip out, stick, stick on every tendon at q."""
    alpha = fr._alpha(model, q)
    held = np.zeros(alpha.shape)
    for i in range(alpha.shape[0]):
        t = motor[i]
        for k in range(alpha.shape[1]):
            f = math.exp(mu * alpha[i, k])
            held[i, k], t = ((0.0, t / f) if k < 2 else (1e3, t * f) if k == 3 else (t, t))
    return held


@pytest.mark.parametrize("pattern", ["in", "mixed", "out"])
def test_the_tangent_with_friction_matches_finite_differences(model, pattern):
    q = model.fk([3.0, 1.0, 0.5], P, F).q
    motor = np.array([2.5, 1.2, 0.3])
    held = {"in": np.zeros((3, model.n)), "out": np.full((3, model.n), 1e3),
            "mixed": _held(model, q, motor, 0.3)}[pattern]
    base = fr._parts(model, q, motor, held, 0.3, P, F, True)
    rng = np.random.default_rng(7)
    for _ in range(3):
        v = rng.standard_normal(model.ndof) * 1e-3
        v[:6] = 0.0
        h = 1e-4
        for s in (-2, -1, 1, 2):
            assert np.array_equal(fr._parts(model, q + s * h * v, motor, held, 0.3, P, F, False)["code"], base["code"])
        fd = _fd(lambda x: fr._parts(model, x, motor, held, 0.3, P, F, False)["Q"], q, v, h)
        assert np.allclose(base["K"] @ v, fd, rtol=0, atol=1e-7 * np.abs(fd).max())
    assert not np.allclose(base["K"], base["K"].T)          # friction is not conservative


# ------------------------------------------------------------------------------------------------ history
def test_loading_from_slack_is_the_capstan_profile_at_the_solution(model):
    s = model.fk_history([3.0, 1.0, 0.0], P, F)
    alpha = fr._alpha(model, s.q)
    assert np.allclose(s.wrap_angles, alpha, rtol=0, atol=1e-15)
    expect = np.array([3.0, 1.0, 0.0])[:, None] * np.exp(-0.3 * np.cumsum(alpha, axis=1))
    assert np.allclose(s.segment_tensions, expect, rtol=1e-14, atol=0)
    assert np.all(s.sliding[:2] == tf.SLIP_IN)
    # the equilibrium: Q_el + Σ T_ik ∇l_ik = 0 at the state, by the frictionless forces of each element's tension
    assert s.equilibrium.residual_norm < model.default_tol


def test_compliance_with_friction_matches_finite_differences(model):
    s0 = model.fk_history([2.0, 0.5, 0.0], P)
    s1 = model.fk_history([3.0, 1.0, 0.0], P, (0, 0, 0), s0)
    C = fr.compliance(model, s1).C_p
    h, Cfd = 1e-3, np.zeros((3, 3))
    for j in range(3):
        dF = np.zeros(3)
        dF[j] = h
        a = model.fk_history([3.0, 1.0, 0.0], P, dF, s0)
        b = model.fk_history([3.0, 1.0, 0.0], P, -dF, s0)
        assert np.array_equal(a.sliding, s1.sliding) and np.array_equal(b.sliding, s1.sliding)
        Cfd[:, j] = (a.tip - b.tip) / (2 * h)
    assert np.allclose(C, Cfd, rtol=0, atol=1e-5 * np.abs(C).max())
    m0 = Model(presets.paper())
    C0 = compliance.tension(m0, m0.fk([3.0, 1.0, 0.0], P)).C_p
    assert np.abs(C - C0).max() > 0.01 * np.abs(C0).max()          # friction changes the compliance
    with pytest.raises(InputError, match="friction"):
        compliance.tension(model, s1.equilibrium)               # the frictionless form refuses a friction state


def test_loop_area_grows_with_friction_and_vanishes_without(cycles):
    area = {mu: c.loop_area for mu, c in cycles.items()}
    energy = {mu: c.dissipated_energy for mu, c in cycles.items()}
    assert area[0.0] < 1e-9 and abs(energy[0.0]) < 1e-9
    assert 0 < area[0.01] < area[0.1] / 5 < area[0.3] / 5
    assert 0 < energy[0.01] < energy[0.1] < energy[0.3]
    for c in cycles.values():                                   # the cycle closes: 0 N is slack everywhere
        assert np.all(c.states[-1].segment_tensions == 0.0)
        assert np.allclose(c.tip[-1], c.tip[0], rtol=0, atol=1e-9)


@pytest.mark.parametrize("mu", [0.1, 0.3])
def test_loading_and_unloading_branches_bracket_the_frictionless_curve(cycles, mu):
    c = cycles[mu]
    load, unload = c.branches()
    free = c.frictionless_tip
    d = (free[-1] - free[0]) / np.linalg.norm(free[-1] - free[0])
    s = len(free) - 1
    states_unload = c.states[s:][::-1]
    for k in range(1, s + 1):
        st_l, st_u = c.states[k], states_unload[k]
        Tm = st_l.motor_tensions[0]
        assert np.all(st_l.segment_tensions[0] <= Tm * (1 + 1e-12))           # loading: below the motor
        assert (load[k] - free[k]) @ d < 0
        if np.all(st_u.segment_tensions[0] >= Tm):                           # away from the reversal zone
            assert (unload[k] - free[k]) @ d > 0
    assert all(np.all(x.segment_tensions[0] >= x.motor_tensions[0]) for x in states_unload[1:s // 2 + 1])


def test_bad_friction_inputs_are_refused(model):
    s = model.fk_history([1.0, 0.0, 0.0], P)
    with pytest.raises(InputError, match="another actuator"):
        Model(presets.paper().replace(tendon_friction=0.3, n_elements=8)).fk_history([1.0, 0.0, 0.0], P, state=s)
    with pytest.raises(InputError, match="μ"):
        Model(presets.paper().replace(tendon_friction=0.1)).fk_history([1.0, 0.0, 0.0], P, state=s)
    with pytest.raises(InputError, match="FrictionState"):
        model.fk_history([1.0, 0.0, 0.0], P, state=s.equilibrium)
    with pytest.raises(InputError, match="steps"):
        model.tension_cycle([1.0, 0.0, 0.0], P, steps=1)
    with pytest.raises(InputError, match="peak_tensions"):
        model.tension_cycle([-1.0, 0.0, 0.0], P)
    with pytest.raises(InputError):
        model.fk_history([1.0, 0.0], P)


def test_the_documented_cycle_numbers_are_the_programs(cycles):
    import pathlib
    import re
    doc = (pathlib.Path(__file__).parents[1] / "docs" / "friction.md").read_text(encoding="utf-8")
    rows = {float(r[0]): r[1:] for r in re.findall(r"^\| ([0-9.]+) \| (\S+) \| (\S+) \| (\S+) \| (\S+) \|$", doc, re.MULTILINE)}
    assert set(rows) == {0.01, 0.1, 0.3}
    for mu, row in rows.items():
        c = cycles[mu]
        load, unload = c.branches()
        free = c.frictionless_tip
        d = (free[-1] - free[0]) / np.linalg.norm(free[-1] - free[0])
        got = (c.loop_area * 1e3, c.dissipated_energy * 1e3, (load[-1] - free[-1]) @ d * 1e3, (unload[4] - load[4]) @ d * 1e3)
        for value, text in zip(got, row):                  # equal to the printed digits
            assert abs(value - float(text)) <= 0.5 * 10.0 ** -len(text.split(".")[1]) + 1e-9, (mu, got, row)


# ------------------------------------------------------------------------------------------------ locked
@pytest.fixture(scope="module")
def locked_start(model):
    """A loaded friction state (tendon 3 slack at 0 N) and its lock under an extra tip load."""
    s = model.fk_history([3.0, 1.0, 0.0], P)
    return s, fr.fk_locked_history(model, s, None, P, (0.0, 0.0, 0.1))


@pytest.mark.parametrize("Fz", [0.1, -0.3])
def test_locked_without_friction_is_fk_locked(Fz):
    m = Model(presets.paper())
    s = m.fk_history([3.0, 1.0, 0.0], P)
    got = fr.fk_locked_history(m, s, None, P, (0.0, 0.0, Fz))
    eq = m.fk_locked(m.rest_lengths(s.equilibrium), P, (0.0, 0.0, Fz))
    assert got.equilibrium.active == eq.active
    assert np.allclose(got.q, eq.q, rtol=0, atol=1e-11) and np.allclose(got.tip, eq.tip, rtol=0, atol=1e-12)
    assert np.allclose(got.motor_tensions, eq.tensions, rtol=0, atol=1e-9)
    assert np.allclose(got.equilibrium.slack, eq.slack, rtol=0, atol=1e-12)
    moved = eq.tendon_lengths - [1e-3, 0.0, -2e-3]             # the motors move: still the same equations
    got2 = fr.fk_locked_history(m, got, moved, P)
    assert np.allclose(got2.q, m.fk_locked(moved, P, (0, 0, 0), eq.q, eq.tensions).q, rtol=0, atol=1e-11)
    for u in ([0.0, 0.0, -1.0], [0.0, 1.0, 0.0]):
        C = fr.locked_compliance(m, got, u)
        Cx = compliance.locked(m, eq, "exact", load_direction=u)
        assert C.active == Cx.active
        assert np.allclose(C.C_p, Cx.C_p, rtol=0, atol=1e-9 * np.abs(Cx.C_p).max())
        assert np.allclose(C.dT_dF, Cx.dT_dF, rtol=0, atol=1e-9 * np.abs(Cx.dT_dF).max())


def test_the_locked_law_holds_at_the_solution(model, locked_start):
    s, L = locked_start
    ref = fr._reference(model, s, None)
    lseg = fr._reference(model, L, None).lseg
    T, code, a = L.segment_tensions, L.sliding, L.wrap_angles
    for i in L.equilibrium.active:
        prev = np.concatenate([[L.motor_tensions[i]], T[i, :-1]])
        f = np.exp(0.3 * a[i])
        assert np.all(T[i] >= prev / f * (1 - 1e-9)) and np.all(T[i] <= prev * f * (1 + 1e-9))      # in the cone
        slip = code[i] != tf.STICK
        assert np.allclose(T[i][slip & (code[i] > 0)], (prev / f)[slip & (code[i] > 0)], rtol=1e-9)  # on its edge
        assert np.allclose(T[i][slip & (code[i] < 0)], (prev * f)[slip & (code[i] < 0)], rtol=1e-9)
        cuts = list(np.flatnonzero(~slip)) + [model.n]
        for a0, b0 in zip(cuts[:-1], cuts[1:]):                  # each stuck span keeps its length
            assert abs(lseg[i, a0:b0].sum() - ref.lseg[i, a0:b0].sum()) < 1e-9
        assert abs(lseg[i].sum() - ref.l0[i]) < 1e-9            # and the motor the whole tendon's
    assert np.any(L.sliding[0] == tf.STICK) or np.any(L.sliding[0] != L.sliding[0, 0])   # a real pattern


@pytest.mark.parametrize("direction", [[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 1.0]])
def test_locked_compliance_with_friction_matches_finite_differences(model, locked_start, direction):
    _s, L = locked_start
    C = fr.locked_compliance(model, L, direction)
    u = np.asarray(direction) / np.linalg.norm(direction)
    probe = fr.fk_locked_history(model, L, None, P, L.equilibrium.tip_force + 1e-3 * u)
    h, tips = 2e-3, []
    for k in (1, 2):                                          # one-sided: stick/slip depends on the load's sign
        x = fr.fk_locked_history(model, L, None, P, L.equilibrium.tip_force + k * h * u)
        assert np.array_equal(x.sliding, probe.sliding) and x.equilibrium.active == probe.equilibrium.active
        tips.append(x.tip)
    fd = (-3 * L.tip + 4 * tips[0] - tips[1]) / (2 * h)
    assert np.allclose(C.C_p @ u, fd, rtol=0, atol=1e-5 * np.abs(fd).max())
    m0 = Model(presets.paper())
    C0 = compliance.locked(m0, m0.fk_locked(L.equilibrium.tendon_lengths, P, L.equilibrium.tip_force), "exact",
                           load_direction=u)
    assert np.abs(C.C_p - C0.C_p).max() > 0.05 * np.abs(C0.C_p).max()              # friction changes it


def test_bad_locked_inputs_are_refused(model, locked_start):
    s, _L = locked_start
    with pytest.raises(InputError, match="FrictionState"):
        fr.fk_locked_history(model, s.equilibrium)
    with pytest.raises(InputError, match="tendon_lengths"):
        fr.fk_locked_history(model, s, [0.1, -0.1, 0.1], P)
    with pytest.raises(InputError, match="another actuator"):
        fr.fk_locked_history(Model(presets.paper().replace(tendon_friction=0.3, n_elements=8)), s)
    with pytest.raises(InputError, match="load_direction"):
        fr.locked_compliance(model, s, [0.0, 0.0, 0.0])
