"""Inadmissible states (ancf/assembly.py, module docstring): the assembly answers them with an infinite
energy — never a division by zero — and the solvers and the public API turn them into typed errors.

Regression of "No traceback reaches a user": ``report --quick`` died with a raw ZeroDivisionError from the
Rodrigues frame's 1/(1 + t·e1) in the tendon kernel, reached by a line-search trial state with a section
pointing back along −e1; ``Model.fk(q0=zeros)`` reached the same division.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from ancf import Model, assembly, presets
from ancf.assembly import assemble, state_status
from ancf.errors import BellowsError, CollapsedStateError, InputError
from ancf.forces.tendon import tendon_density, tendon_length_density, tendon_length_gradient

SETTINGS = dict(deadline=None, suppress_health_check=[HealthCheck.too_slow], derandomize=True)
M = Model(presets.paper())
M4 = Model(presets.four_tendon())


def _assemble(m, q, T, want_H=True, need=0):
    return assemble(np.ascontiguousarray(q, float), m.n, m._N, m._wq, m._ea, m._ei, 1e4 * m._vc, m._mg, m._E,
                    m._d, m._co, m._so, np.ascontiguousarray(T, float), m.params.tool_offset,
                    m.total_tip_load(np.zeros(3)), want_H, need)


def _status(m, q):
    return state_status(np.ascontiguousarray(q, float), m.n, m._N, m._E, m._d, m._co, m._so)


def _clamped_zero(m):
    """The state the solvers build from q0 = 0: base node clamped, every other coordinate zero.  In element
    1 the slope r_x = s₂'(ξ) e1 turns negative for ξ > 1/3: sections pointing exactly along −e1."""
    return m.to_full(np.zeros(m.nz))


# ---------------------------------------------------------------------------------------- kernels
@pytest.mark.parametrize("want_H", [True, False])
@pytest.mark.parametrize("need", [0, 1, 2])
def test_section_along_minus_e1_is_inadmissible_not_a_division_by_zero(want_H, need):
    q = _clamped_zero(M)
    E, *_ = _assemble(M, q, [2.0, 0.0, 0.0], want_H, need)
    assert E == np.inf
    code, e, k, i, v = _status(M, q)
    assert code == assembly.REVERSED and e == 0 and v == pytest.approx(0.0)


def test_tendon_kernels_return_nan_where_the_frame_or_the_path_is_undefined():
    E = M._E
    minus_e1 = -E[:, 0]
    b = 0.3 * E[:, 1]
    for a in (minus_e1, np.zeros(3)):
        w, g, H = tendon_density(a, b, E, 0.0275, 1.0, 0.0)
        assert np.isnan(w) and np.all(np.isnan(g)) and np.all(np.isnan(H))
        w, g = tendon_length_gradient(a, b, E, 0.0275, 1.0, 0.0)
        assert np.isnan(w) and np.all(np.isnan(g))
        assert np.isnan(tendon_length_density(a, b, E, 0.0275, 1.0, 0.0))
    # folded path: planar arc of curvature 1/d bending towards the tendon → |r_c,x| = 1 − κ d = 0
    d = 0.0275
    a, b = E[:, 0], E[:, 1] / d
    assert tendon_length_density(a, b, E, d, 1.0, 0.0) == pytest.approx(0.0, abs=1e-12)
    w, g, H = tendon_density(a, b, E, d, 1.0, 0.0)
    assert np.isnan(w) or (w > 0 and np.all(np.isfinite(g)))        # never a division by zero


@settings(max_examples=60, **SETTINGS)
@given(st.floats(0.0, 2.9), st.floats(0.3, 2.0), st.floats(-30.0, 30.0), st.sampled_from([0, 1, 2]))
def test_tendon_length_density_closed_form_on_a_planar_arc(phi, lam, kappa, tendon):
    """Closed form: a planar arc in the (e1, e2) plane, tangent angle φ, stretch λ, curvature κ
    per unit arc length (a = λ t, b = λ² κ n); tendon i at angle θ_i (offset d cos θ_i along n in the bending
    plane, d sin θ_i out of it, both carried rigidly by the Rodrigues frame of a planar bend):
    r_c,x = λ (1 − κ d cos θ_i) t, so |r_c,x| = λ |1 − κ d cos θ_i|."""
    E, d = M._E, M._d[tendon]
    t = np.cos(phi) * E[:, 0] + np.sin(phi) * E[:, 1]
    n = -np.sin(phi) * E[:, 0] + np.cos(phi) * E[:, 1]
    a, b = lam * t, lam ** 2 * kappa * n
    expect = lam * abs(1.0 - kappa * d * M._co[tendon])
    assert tendon_length_density(a, b, E, d, M._co[tendon], M._so[tendon]) == pytest.approx(expect, rel=1e-9, abs=1e-12)


def test_folded_tendon_path_is_inadmissible():
    """Uniform planar arc towards tendon 1 with curvature radius close to d: the assembly answers inf and
    the model names the folded tendon; slightly less curvature is admissible."""
    short = Model(presets.paper().replace(n_elements=8, length=0.04))    # bend below 172° at κ ≤ 0.9/d
    d, E = short._d[0], short._E

    def arc_s(kappa):
        s = np.linspace(0.0, short.params.length, short.n + 1)
        q = np.zeros(short.ndof)
        for j, sj in enumerate(s):
            q[6 * j:6 * j + 3] = np.sin(kappa * sj) / kappa * E[:, 0] + (1 - np.cos(kappa * sj)) / kappa * E[:, 1]
            q[6 * j + 3:6 * j + 6] = np.cos(kappa * sj) * E[:, 0] + np.sin(kappa * sj) * E[:, 1]
        return q
    good, bad = arc_s(0.7 / d), arc_s(0.9 / d)          # w ≈ 0.3 and 0.1 on tendon 1
    assert _status(short, good)[0] == assembly.OK
    assert np.isfinite(_assemble(short, good, [1.0, 0.0, 0.0])[0])
    code, e, k, i, v = _status(short, bad)
    assert code == assembly.FOLDED and i == 0 and v < assembly.TENDON_MIN
    for T in ([1.0, 0.0, 0.0], [0.0, 0.0, 0.0]):          # the rule does not depend on the tensions
        assert _assemble(short, bad, T)[0] == np.inf
    assert "tendon 1's path folds" in short.inadmissibility(bad)
    with pytest.raises(CollapsedStateError, match="tendon 1's path folds"):
        short.evaluate(bad)


@settings(max_examples=80, **SETTINGS)
@given(hnp.arrays(np.float64, M.ndof, elements=st.floats(-3.0, 3.0)), st.floats(0.0, 6.0), st.booleans())
def test_assembly_is_total_and_agrees_with_the_rules(q, T1, want_H):
    """Any finite q: the assembly returns (never raises); a finite energy with finite derivatives exactly
    when state_status calls the state admissible, inf otherwise."""
    q = q.copy()
    q[:6] = M.q_ref[:6]
    E, G, H, *_ = _assemble(M, q, [T1, 0.5, 0.0], want_H, 2)
    ok = _status(M, q)[0] == assembly.OK
    event("admissible" if ok else "inadmissible")
    if ok:
        assert np.isfinite(E) and np.all(np.isfinite(G)) and (not want_H or np.all(np.isfinite(H)))
    else:
        assert E == np.inf


def test_non_finite_q_is_inadmissible_in_the_kernel():
    q = M.q_ref.copy()
    q[10] = np.nan
    assert _assemble(M, q, [1.0, 0.0, 0.0])[0] == np.inf
    assert _status(M, q)[0] == assembly.NONFINITE


# ---------------------------------------------------------------------------------------- public API
@pytest.mark.parametrize("bad, match", [
    (lambda m: np.zeros(m.ndof), "points back along the base axis|collapsed section"),
    (lambda m: np.r_[m.q_ref[:-3], 0.0, 0.0, 0.0], "collapsed section at element"),
    (lambda m: -m.q_ref, "points back along the base axis"),
    (lambda m: np.zeros(m.ndof + 6), "q0 has 48 coordinates; this model"),
    (lambda m: M4.q_ref[:30], "q0 has 30 coordinates"),
    (lambda m: np.full(m.ndof, np.nan), "q0 contains NaN or inf"),
    (lambda m: np.zeros((2, m.ndof)), "q0 must have shape"),
])
def test_inadmissible_q0_is_an_input_error_before_any_solve(bad, match):
    q0 = bad(M)
    with pytest.raises(InputError, match=match):
        M.fk((2.0, 0.0, 0.0), 0.0, (0, 0, 0), q0=q0)
    with pytest.raises(InputError, match=match):
        M.ik(M.droop(0.0).tip + [0.0, 0.01, 0.0], 0.0, q0=q0)
    with pytest.raises(InputError, match=match):
        M.fk_locked(M.tendon_lengths(M.q_ref), 0.0, q0=q0)


def _verified(m, eq, T):
    Q = m.reduce_vec(m.residual(eq.q, T, eq.pressure, eq.tip_force))
    assert np.linalg.norm(Q) < 10 * m.default_tol
    assert m.inadmissibility(eq.q) is None
    assert eq.stable and np.all(np.isfinite(eq.tip))


q0_vectors = st.one_of(
    hnp.arrays(np.float64, M.ndof, elements=st.floats(allow_nan=True, allow_infinity=True, width=64)),
    hnp.arrays(np.float64, M.ndof, elements=st.floats(-1.0, 1.0)),
    st.tuples(st.floats(0.0, 2.0), st.integers(0, 2 ** 31)).map(
        lambda s: M.q_ref + s[0] * np.random.default_rng(s[1]).standard_normal(M.ndof)),
    st.tuples(st.integers(1, M.n), st.floats(-1.0, 1.0)).map(
        lambda s: np.concatenate([M.q_ref[:6 * s[0] + 3], s[1] * M.q_ref[6 * s[0] + 3:6 * s[0] + 6],
                                  M.q_ref[6 * s[0] + 6:]])),
    st.integers(1, 80).map(lambda k: np.ones(k)),
)


@settings(max_examples=40, **SETTINGS)
@given(q0_vectors, st.floats(0.0, 5.0), st.floats(0.0, 100e3))
def test_fk_from_any_q0_is_verified_or_a_bellows_error(q0, T1, p):
    T = np.array([T1, 0.3 * T1, 0.0])
    try:
        eq = M.fk(T, p, (0.0, 0.0, 0.0), q0=q0)
    except BellowsError as exc:
        event(type(exc).__name__)
        return
    event("verified")
    _verified(M, eq, T)


@settings(max_examples=15, **SETTINGS)
@given(q0_vectors)
def test_ik_and_locked_from_any_q0_are_verified_or_a_bellows_error(q0):
    try:
        eq = M.ik(M.droop(0.0).tip + np.array([0.0, 0.01, 0.0]), 0.0, q0=q0)
        _verified(M, eq, eq.tensions)
    except BellowsError as exc:
        event(type(exc).__name__)
    try:
        eq = M.fk_locked(0.98 * M.tendon_lengths(M.q_ref), 0.0, q0=q0)
        assert np.linalg.norm(M.reduce_vec(M.residual(eq.q, eq.tensions, 0.0, (0, 0, 0)))) < 10 * M.default_tol
    except BellowsError as exc:
        event(type(exc).__name__)


def test_every_public_evaluation_names_an_inadmissible_state():
    """No partial vector from an assembly that stopped early: evaluate-based accessors and dQ_dp raise."""
    q = _clamped_zero(M)
    for call in (M.residual, M.tangent, M.dQ_dT, M.dQ_dp, M.tendon_lengths, M.tendon_jacobian):
        with pytest.raises(CollapsedStateError, match="points back along the base axis"):
            call(q)
    assert np.all(np.isfinite(M.dQ_dp(M.q_ref)))


def test_tip_frame_and_tendon_paths_refuse_an_undefined_frame():
    q = M.q_ref.copy()
    q[-3:] = -M._E[:, 0]                          # tip slope along −e1: Rodrigues divides by 1 + c = 0
    for call in (M.tip_rotation, M.tip_angular_jacobian):
        with pytest.raises(InputError, match="points back along the base axis"):
            call(q)
    with pytest.raises(CollapsedStateError):
        M.tendon_paths(q)
    assert np.all(np.isfinite(M.tip_rotation(M.q_ref))) and np.all(np.isfinite(M.tendon_paths(M.q_ref)))


# The exact state of the issue: a line-search trial state of 'report --quick' (fit of the 'paper' form,
# trial law EA = 596.3 λ − 380.1 N, EI = −0.02886 λ + 0.04529 λ² N m², equal tensions 5 N, no gravity):
# the first element folds back (node 2 at x = −9 mm), its slope at quadrature points 2–4 is −e1 plus
# ~1e-16 transverse round-off, so 1 + t·e1 rounds to exactly 0 in the tendon kernel's 1/(1 + c).
ISSUE_Q = np.array([
    0.0, 0.0, 0.0,
    1.0, 0.0, 0.0,
    -0.009167304455308944, 2.6625402377430262e-18, -1.212915626397985e-18,
    0.8852721446321039, -8.774710277588424e-17, -7.020535639003335e-17,
    0.023138358958833618, -1.493057328509053e-18, -3.1888208734375577e-18,
    0.8639575197411937, -1.6332438817877858e-16, -1.112089477584164e-16,
    0.054382393074767256, -7.82618844952036e-18, -6.953918086136471e-18,
    0.8600483429090411, -2.3777102843803325e-16, -1.6451872401865592e-16,
    0.08431548422243963, -1.6361643140134582e-17, -1.238063518051372e-17,
    0.8593276239567736, -3.042668144871951e-16, -2.0718639403065233e-16,
    0.11201504174498565, -2.693096741231303e-17, -1.9221438176103594e-17,
    0.8591875074054477, -3.9422514405218045e-16, -2.5737306904163223e-16,
    0.13673988181006497, -3.895823711481743e-17, -2.7213681018668532e-17,
    0.8591638780996499, -4.603998919485677e-16, -3.1415506228233805e-16,
])


@pytest.mark.parametrize("need", [0, 1, 2])
def test_issue_state_from_report_quick_is_inadmissible(need):
    ea = np.array([-380.0594650617952, 596.3196477827864])
    ei = np.array([0.0, -0.028862711009693114, 0.04528607558966618])
    out = assemble(ISSUE_Q, M.n, M._N, M._wq, ea, ei, np.zeros(1), np.zeros(3), M._E, M._d, M._co, M._so,
                   np.full(3, 5.0), 0.0, np.zeros(3), True, need)
    assert out[0] == np.inf
    code, e, k, i, v = _status(M, ISSUE_Q)
    assert (code, e, k) == (assembly.REVERSED, 0, 1) and v == 0.0
    assert "element 1, quadrature point 2 points back along the base axis" in M.inadmissibility(ISSUE_Q)


# ------------------------------------------------------------------ the slack tendons' rule, skipped by a bound
@settings(max_examples=300, **SETTINGS)
@given(hnp.arrays(np.float64, 3, elements=st.floats(-1.0, 1.0)), st.floats(0.2, 3.0),
       hnp.arrays(np.float64, 3, elements=st.floats(-1.0, 1.0)), st.floats(-2.0, 2.0),
       st.floats(0.0, 2 * np.pi), st.floats(1e-3, 0.1))
def test_density_lower_bound_is_below_every_tendons_density(t, lam, bdir, log_b, theta, d):
    """forces.tendon.density_lower_bound(a, b, d) ≤ |r_c,x| of a tendon at any angle and any distance ≤ d
    (the exact kernel), wherever the frame is defined — the assembly skips the slack tendons' rule on it."""
    from ancf.forces.tendon import density_lower_bound
    E = M._E
    if np.linalg.norm(t) < 1e-3 or np.linalg.norm(bdir) < 1e-3:
        return
    t = t / np.linalg.norm(t)
    if 1 + t @ E[:, 0] < assembly.FRAME_MIN:
        return
    a, b = lam * t, 10 ** log_b * bdir / np.linalg.norm(bdir)
    lb = density_lower_bound(a, b, d)
    for dd in (d, 0.5 * d):
        w = tendon_length_density(a, b, E, dd, np.cos(theta), np.sin(theta))
        assert lb <= w + 1e-12 * max(1.0, abs(w))


@pytest.mark.parametrize("phi", [0.0, 0.4, 1.2, 2.5])
@pytest.mark.parametrize("psi", [0.0, 1.0, 4.0])
def test_density_lower_bound_is_attained_by_a_bend_towards_the_tendon(phi, psi):
    """A section turned by φ from e1 in the plane of e1 and o_ψ = cos ψ e2 + sin ψ e3, bending further in that
    plane (b = λ²κ n plus a tangential part), the tendon at θ = ψ: |r_c,x| equals the bound exactly
    (λ |1 − κ d|).  A bound that was too optimistic would exceed the density here, one with a needless factor
    (a bend-angle-dependent frame-rate bound, say) would fall below it."""
    from ancf.forces.tendon import density_lower_bound
    E, d, lam = M._E, 0.0275, 1.1
    o = np.cos(psi) * E[:, 1] + np.sin(psi) * E[:, 2]
    t = np.cos(phi) * E[:, 0] + np.sin(phi) * o
    n = -np.sin(phi) * E[:, 0] + np.cos(phi) * o
    for kappa in (0.0, 5.0, 25.0):
        a, b = lam * t, lam ** 2 * kappa * n + 0.7 * t
        w = tendon_length_density(a, b, E, d, np.cos(psi), np.sin(psi))
        assert w == pytest.approx(lam * abs(1 - kappa * d), rel=1e-12, abs=1e-13)
        assert density_lower_bound(a, b, d) == pytest.approx(w, rel=1e-12, abs=1e-13)


@pytest.mark.parametrize("model", ["paper", "four_tendon"])
@pytest.mark.parametrize("plane_deg", [0.0, 20.0, 40.0])
def test_slack_rule_with_the_bound_agrees_with_the_rules_near_folding(model, plane_deg):
    """All tendons slack, no lengths wanted (need_lengths 0: the rule may be skipped where the bound holds):
    planar arcs whose curvature sweeps across the folding limit of the tendon nearest the bending side — the
    assembly is finite exactly where state_status (the exact rule, no bound) calls the state admissible."""
    base = presets.paper() if model == "paper" else presets.four_tendon()
    short = Model(base.replace(n_elements=8, length=0.04))
    E, d = short._E, float(np.max(short._d))
    ph = np.radians(plane_deg)
    nrm = np.cos(ph) * E[:, 1] + np.sin(ph) * E[:, 2]
    s = np.linspace(0.0, short.params.length, short.n + 1)
    seen = set()
    for kappa in np.linspace(0.2 / d, 1.5 / d, 53):
        q = np.zeros(short.ndof)
        for j, sj in enumerate(s):
            q[6 * j:6 * j + 3] = np.sin(kappa * sj) / kappa * E[:, 0] + (1 - np.cos(kappa * sj)) / kappa * nrm
            q[6 * j + 3:6 * j + 6] = np.cos(kappa * sj) * E[:, 0] + np.sin(kappa * sj) * nrm
        ok = _status(short, q)[0] == assembly.OK
        seen.add(ok)
        for want_H in (True, False):
            assert np.isfinite(_assemble(short, q, np.zeros(short.m), want_H, 0)[0]) == ok
    assert seen == {True, False}                   # the sweep crossed the limit


def test_tendon_lengths_kernel_equals_the_assembly_and_refuses_folded_paths():
    """assembly.tendon_lengths (the lengths a Newton loop computes once, at its solution) against the
    assembly's own lengths, and NaN on an inadmissible state."""
    from ancf.assembly import tendon_lengths
    rng = np.random.default_rng(3)
    for m in (M, M4):
        for _ in range(4):
            eq = m.fk(rng.uniform(0, 4, m.m), rng.uniform(0, 100e3), rng.normal(0, 0.3, 3))
            for T in (eq.tensions, np.zeros(m.m)):
                ref = _assemble(m, eq.q, T, False, 2)[3]
                got = tendon_lengths(eq.q, m.n, m._N, m._wq, m._E, m._d, m._co, m._so)
                np.testing.assert_allclose(got, ref, rtol=1e-14, atol=0)
    assert np.all(np.isnan(tendon_lengths(_clamped_zero(M), M.n, M._N, M._wq, M._E, M._d, M._co, M._so)))
