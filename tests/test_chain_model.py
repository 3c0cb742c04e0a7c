"""Statics of a multi-segment actuator (ancf.chain_model, docs/multisegment.md): one segment is ancf.Model to
round-off; two identical segments joined by a zero-length cap are one rod of double length; a distal tendon bends
the proximal segment by the moment balance κ = T d λ / EI; the compliances are the finite differences of the FK;
the cap map's derivatives are those of finite differences."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ancf import Model, StiffnessLaw, Tendon, compliance, presets
from ancf import kinematics as kin
from ancf.chain import Cap, ChainParams
from ancf.chain_model import ChainModel
from ancf.errors import ConvergenceError, InputError, LimitError, UnstableEquilibriumError

PAPER = presets.paper()
MODEL = Model(PAPER)
ONE = ChainModel(PAPER)
TWO = ChainModel(presets.two_segment())


def _tendons(degrees, d=0.0275):
    return tuple(Tendon(distance=d, angle=math.radians(a)) for a in degrees)


def _pair(base, n, junction="free", cap=None, first=(60, 180, 300), second=(0, 120, 240)):
    """Two segments of ``base`` at half length, n elements each; segment 2 owns the tip mass and tool."""
    s1 = base.replace(length=base.length / 2, n_elements=n, tip_mass=0.0, tool_offset=0.0, tendons=_tendons(first))
    s2 = base.replace(length=base.length / 2, n_elements=n, tendons=_tendons(second))
    return ChainModel(ChainParams(segments=(s1, s2), caps=(cap or Cap(),), junction_stretch=junction))


# ------------------------------------------------------------------------------------------ one segment = Model
@settings(max_examples=20, deadline=None)
@given(T=st.lists(st.floats(0.0, 5.0), min_size=3, max_size=3), p_kPa=st.floats(0.0, 120.0),
       F=st.lists(st.floats(-0.3, 0.3), min_size=3, max_size=3))
def test_one_segment_fk_is_model_fk(T, p_kPa, F):
    try:
        ref = MODEL.fk(T, p_kPa * 1e3, F)
    except ConvergenceError:                # beyond the actuator's limit point (e.g. 2 × 5 N at 0 kPa): the chain too
        with pytest.raises(ConvergenceError):
            ONE.fk(T, [p_kPa * 1e3], F)
        return
    eq = ONE.fk(T, [p_kPa * 1e3], F)
    np.testing.assert_allclose(eq.q, ref.q, rtol=0, atol=1e-12)
    np.testing.assert_allclose(eq.tip, ref.tip, rtol=0, atol=1e-12)
    np.testing.assert_allclose(eq.tip_rotation, ref.tip_rotation, rtol=0, atol=1e-12)
    np.testing.assert_allclose(eq.tendon_lengths, ref.tendon_lengths, rtol=0, atol=1e-12)
    assert eq.energy == pytest.approx(ref.energy, rel=1e-12, abs=1e-15)
    # both compliances: the tensions held, and the lengths of the taut tendons held (exact KKT)
    np.testing.assert_allclose(ONE.compliance(eq), compliance.tension(MODEL, ref).C_p, rtol=1e-8, atol=1e-12)
    A = tuple(int(i) for i in np.nonzero(ref.tensions > 0)[0])
    np.testing.assert_allclose(ONE.locked_compliance(eq, A), compliance.locked(MODEL, ref, "exact", A).C_p,
                               rtol=1e-7, atol=1e-12)


@pytest.mark.parametrize("params", [PAPER.replace(free_base_stretch=True),
                                    PAPER.replace(stiffness=PAPER.stiffness.with_pressure(EA=(0.2,), EI=(0.55, 0.35)),
                                                  pressure_area_slope=0.3)],
                         ids=["free_base_stretch", "pressure_factors"])
def test_one_segment_variants_are_model(params):
    model, chain = Model(params), ChainModel(params)
    ref, eq = model.fk((2.0, 0.0, 1.0), 80e3, (0.1, 0.0, -0.2)), chain.fk((2.0, 0.0, 1.0), [80e3], (0.1, 0.0, -0.2))
    np.testing.assert_allclose(eq.q, ref.q, rtol=0, atol=1e-12)
    np.testing.assert_allclose(chain.compliance(eq), compliance.tension(model, ref).C_p, rtol=1e-8, atol=1e-12)


@pytest.mark.parametrize("T, p", [((3.0, 0.0, 1.0), 50e3), ((0.0, 4.0, 0.0), 100e3)])
def test_one_segment_locked_fk_is_model_locked_fk(T, p):
    lengths = MODEL.fk(T, p).tendon_lengths - np.array([0.0, 0.0, 1e-3])       # the third tendon shortened
    ref = MODEL.fk_locked(lengths, p, (0.0, 0.0, -0.2))
    eq = ONE.fk_locked(lengths, [p], (0.0, 0.0, -0.2))
    assert eq.active == ref.active
    np.testing.assert_allclose(eq.q, ref.q, rtol=0, atol=1e-10)
    np.testing.assert_allclose(eq.tensions, ref.tensions, rtol=0, atol=1e-8)
    np.testing.assert_allclose(eq.slack, ref.slack, rtol=0, atol=1e-12)


# ------------------------------------------------------------------------------------------ two segments
@pytest.mark.parametrize("n", [3, 6])
def test_identical_segments_with_a_zero_cap_are_one_rod_of_double_length(n):
    """Continuous junction: the same node chain as one rod of 2n elements — equal to round-off.  Free junction
    (one more coordinate, the base stretch of segment 2): the same limit, within the discretisation error."""
    rod = Model(PAPER.replace(n_elements=2 * n, tendons=_tendons((0, 120, 240))))
    T, p, F = np.array([2.0, 0.5, 0.0]), 60e3, np.array([0.1, 0.2, -0.1])
    ref = rod.fk(T, p, F)
    eq = _pair(PAPER, n, "continuous").fk(np.r_[0.0, 0.0, 0.0, T], [p, p], F)
    np.testing.assert_allclose(eq.tip, ref.tip, rtol=0, atol=1e-12)
    np.testing.assert_allclose(eq.tendon_lengths[3:], ref.tendon_lengths, rtol=0, atol=1e-12)
    free = _pair(PAPER, n, "free").fk(np.r_[0.0, 0.0, 0.0, T], [p, p], F)
    assert np.abs(free.tip - ref.tip).max() < (1e-6 if n == 3 else 1e-9)


def _curvature(q, n, length):
    a = kin.interpolate(q, n, length, 8, 1)
    b = kin.interpolate(q, n, length, 8, 2)
    lam = np.linalg.norm(a, axis=1)
    return np.linalg.norm(np.cross(a, b), axis=1) / lam ** 3, lam


def test_distal_tendon_bends_the_proximal_segment_by_the_moment_balance():
    """No gravity, no pressure, constant EI: a tendon of segment 2 at distance d and tension T runs through
    segment 1's routing.  Cutting the body and the tendon anywhere leaves the moment T d, so both segments bend
    with κ = T d λ / EI (κ per deformed length; the energy ½ EI κ² per reference length makes the moment
    conjugate to the rotation per reference length κλ equal EI κ/λ).  Checked away from the clamped base's
    first element, where |r_x| = 1 is imposed."""
    EI, T, d, n = 0.0134, 2.0, 0.0275, 8
    base = PAPER.replace(stiffness=StiffnessLaw.constant(EA=120.0, EI=EI), gravity=(0.0, 0.0, 0.0), line_mass=0.0,
                         tip_mass=0.0, tool_offset=0.0)
    model = _pair(base, n, cap=Cap(mass=0.0, length=0.01))
    eq = model.fk([0.0, 0.0, 0.0, T, 0.0, 0.0], [0.0, 0.0])
    assert np.all(eq.tensions[:3] == 0.0)                 # segment 1's own tendons are slack
    L = base.length / 2
    for k, part in ((0, slice(8 * n // 2, None)), (1, slice(None))):
        kappa, lam = _curvature(model.sys.segment_q(eq.q, k), n, L)
        np.testing.assert_allclose(kappa[part], T * d * lam[part] / EI, rtol=1e-3)
    assert eq.segment_ends[0][2] > 0.005                 # the proximal segment lifts (tendon on top, +z)


def test_each_chamber_has_its_own_pressure():
    """Pressure in chamber 2 only: segment 1 stays at its unpressurised shape (no gravity, no tendons)."""
    base = PAPER.replace(gravity=(0.0, 0.0, 0.0))
    model = _pair(base, 3, cap=Cap(length=0.01))
    eq = model.fk(np.zeros(6), [0.0, 80e3])
    np.testing.assert_allclose(eq.segment_ends[0], [0.08, 0.0, 0.0], atol=1e-12)
    assert eq.tip[0] > base.length + 0.01 + base.tool_offset + 0.005        # segment 2 stretched


def test_cap_weight_and_length_enter():
    """The cap's length moves the tip by that length along the axis (no gravity); its weight droops the chain."""
    base = PAPER.replace(gravity=(0.0, 0.0, 0.0))
    a = _pair(base, 3, cap=Cap(length=0.0)).fk(np.zeros(6), [0.0, 0.0])
    b = _pair(base, 3, cap=Cap(length=0.02)).fk(np.zeros(6), [0.0, 0.0])
    np.testing.assert_allclose(b.tip - a.tip, [0.02, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(b.tendon_lengths - a.tendon_lengths, [0.0] * 3 + [0.02] * 3, atol=1e-12)
    light = _pair(PAPER, 3, cap=Cap(mass=0.0, length=0.01)).fk(np.zeros(6), [0.0, 0.0])
    heavy = _pair(PAPER, 3, cap=Cap(mass=0.05, length=0.01)).fk(np.zeros(6), [0.0, 0.0])
    assert heavy.tip[2] < light.tip[2] - 1e-3


# ------------------------------------------------------------------------------------------ compliances
def test_compliance_is_the_finite_difference_of_fk():
    T, p = np.array([1.0, 0.0, 0.5, 0.0, 2.0, 0.0]), np.array([40e3, 20e3])
    eq = TWO.fk(T, p)
    C = TWO.compliance(eq)
    h = 1e-3
    for i in range(3):
        dF = np.zeros(3)
        dF[i] = h
        fd = (TWO.fk(T, p, dF, z0=eq.z).tip - TWO.fk(T, p, -dF, z0=eq.z).tip) / (2 * h)
        np.testing.assert_allclose(C[:, i], fd, rtol=1e-5, atol=1e-9)


def test_locked_fk_holds_lengths_and_its_compliance_is_the_finite_difference():
    T, p = np.array([1.0, 0.0, 0.5, 0.0, 2.0, 0.0]), np.array([40e3, 20e3])
    eq = TWO.fk(T, p)
    l0 = eq.tendon_lengths + np.where(T > 0, 0.0, 1e-3)   # the unloaded tendons 1 mm slack
    locked = TWO.fk_locked(l0, p, z0=eq.z)
    assert locked.active == (0, 2, 4)                     # the tendons under tension lock, the others stay slack
    np.testing.assert_allclose(locked.slack, np.where(T > 0, 0.0, 1e-3), atol=1e-12)
    np.testing.assert_allclose(locked.tensions, T, atol=1e-7)
    np.testing.assert_allclose(locked.tip, eq.tip, atol=1e-10)
    C = TWO.locked_compliance(locked)
    assert np.linalg.norm(C) < np.linalg.norm(TWO.compliance(eq))       # locking stiffens
    h = 5e-3
    for i in range(3):
        dF = np.zeros(3)
        dF[i] = h
        tips = [TWO.fk_locked(l0, p, s * dF, z0=eq.z).tip for s in (1, -1)]
        np.testing.assert_allclose(C[:, i], (tips[0] - tips[1]) / (2 * h), rtol=1e-4, atol=1e-8)


# ------------------------------------------------------------------------------------------ derivatives, errors
@pytest.mark.parametrize("junction", ["free", "continuous"])
def test_chain_gradient_hessian_and_length_jacobian_are_finite_differences(junction):
    model = _pair(PAPER, 3, junction, cap=Cap(mass=0.02, length=0.01))
    z = model.sys.z_ref + 1e-3 * np.random.default_rng(1).standard_normal(model.nz)
    T, p, F = np.array([1.0, 0.0, 2.0, 0.5, 3.0, 0.0]), np.array([30e3, 80e3]), np.array([0.1, -0.2, 0.3])
    _, g, H, _, Jl = model.sys.evaluate(z, T, p, F, hessian=True, lengths=2)
    h = 1e-7
    for i in range(model.nz):
        zp, zm = z.copy(), z.copy()
        zp[i] += h
        zm[i] -= h
        Ep, gp, _, lp, _ = model.sys.evaluate(zp, T, p, F, hessian=False, lengths=1)
        Em, gm, _, lm, _ = model.sys.evaluate(zm, T, p, F, hessian=False, lengths=1)
        assert g[i] == pytest.approx((Ep - Em) / (2 * h), rel=1e-5, abs=1e-7)
        np.testing.assert_allclose(H[:, i], (gp - gm) / (2 * h), rtol=1e-5, atol=1e-6 * np.abs(H).max())
        np.testing.assert_allclose(Jl[:, i], (lp - lm) / (2 * h), atol=1e-8)


def test_inputs_are_checked_per_tendon_and_chamber():
    with pytest.raises(InputError, match="6 values"):
        TWO.fk([1.0, 0.0, 0.0], [0.0, 0.0])
    with pytest.raises(InputError, match="2 values"):
        TWO.fk(np.zeros(6), 50e3)
    with pytest.raises(LimitError, match="chamber 2"):
        TWO.fk(np.zeros(6), [0.0, 150e3])
    with pytest.raises(LimitError, match="T5"):
        TWO.fk([0, 0, 0, 0, 6.0, 0], [0.0, 0.0])
    with pytest.raises(InputError, match="NaN"):
        TWO.fk([0, 0, 0, 0, np.nan, 0], [0.0, 0.0])
    with pytest.raises(InputError, match="equilibrium of this chain"):
        TWO.compliance(MODEL.fk())


def test_a_saddle_is_refused_unless_asked():
    """The straight chain under a large compressive tip load along its axis is a saddle (buckling)."""
    base = PAPER.replace(gravity=(0.0, 0.0, 0.0), tool_offset=0.0)
    model = _pair(base, 3)
    z = model.sys.z_ref
    with pytest.raises(UnstableEquilibriumError):
        model.fk(np.zeros(6), [0.0, 0.0], (-3.0, 0.0, 0.0), z0=z)
    eq = model.fk(np.zeros(6), [0.0, 0.0], (-3.0, 0.0, 0.0), z0=z, check_stability=False)
    assert not eq.stable


def test_what_the_chain_model_does_not_take_yet_is_refused_clearly():
    with pytest.raises(InputError, match="shear compliance"):
        ChainModel(PAPER.replace(shear_compliance=(0.001,)))
    elastic = ChainModel(PAPER.replace(tendon_stiffness=2e3))
    with pytest.raises(InputError, match="inextensible"):
        elastic.fk_locked(MODEL.fk().tendon_lengths, [0.0])
    with pytest.raises(InputError, match="ChainParams or ActuatorParams"):
        ChainModel("paper")
    z = TWO.sys.z_ref.copy()
    z[-3:] = 0.0                                            # a collapsed tip slope
    with pytest.raises(InputError, match="admissible"):
        TWO.fk(np.zeros(6), [0.0, 0.0], z0=z)
    with pytest.raises(InputError, match="active tendons"):
        TWO.locked_compliance(TWO.fk(np.zeros(6), [0.0, 0.0]), active=(7,))


@settings(max_examples=8, deadline=None)
@given(T=st.lists(st.floats(0.0, 1.5), min_size=6, max_size=6), p=st.lists(st.floats(30.0, 100.0), min_size=2,
                                                                             max_size=2))
def test_turning_the_tension_pattern_by_120_degrees_turns_the_tip(T, p):
    """Without gravity the chain is symmetric under a turn of 120° about its axis (both segments' tendons are 120°
    apart): tensions moved one tendon on in each segment give the tip turned by 120° about the base axis."""
    model = _pair(PAPER.replace(gravity=(0.0, 0.0, 0.0)), 3, cap=Cap(mass=0.01, length=0.01))
    T = np.asarray(T)
    pr = np.asarray(p) * 1e3
    turned = T[[2, 0, 1, 5, 3, 4]]
    a, b = model.fk(T, pr).tip, model.fk(turned, pr).tip
    c, s = math.cos(2 * math.pi / 3), math.sin(2 * math.pi / 3)
    # θ turns from e_ref = z towards e1 × e_ref = −y: R z = cos 120° z − sin 120° y
    R = np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])
    np.testing.assert_allclose(b, R @ a, atol=1e-9)


def test_equilibrium_repr_and_dict():
    eq = TWO.fk([0, 0, 0, 2.0, 0, 0], [30e3, 0.0])
    text = repr(eq)
    assert "\n" not in text and "mm" in text and "kPa" in text and "q=" not in text
    d = eq.to_dict()
    assert d["pressures"] == [30e3, 0.0] and len(d["tip"]) == 3 and d["solver"] == "fk"
