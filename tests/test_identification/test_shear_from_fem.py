"""The series shear compliance s(p) measured on the FEM's straight states and held in the shear form's fit
(docs/identification.md §4b): the law fitted to straight-state compliances, the rotation-free compliance of a
Timoshenko cantilever's cap compliance, the held parameters reported with their reason, and the FEM path
holding the measured law where the tips and markers would have fitted another one."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ancf.errors import InputError
from validation.identification import identify
from validation.identification.cap_compliance import fit_shear_law, lateral_shear
from validation.identification.fit import Observations, predict
from validation.identification.forms import get_form
from validation.reference.experiments import default_design

L = 0.2


def cantilever_C6(EI: float, s: float, length: float = L) -> np.ndarray:
    """6×6 cap compliance of a straight cantilever along e_x with bending stiffness EI [N m²] in both lateral
    planes and a rotation-free (shear) tip compliance s [m/N]: c_δF = L³/3EI + s, c_θF = c_δM = ±L²/2EI,
    c_θM = L/EI (closed form); the axial and torsional entries arbitrary."""
    C = np.diag([1e-4, 0.0, 0.0, 1e-2, 0.0, 0.0])
    a, b, c = length ** 3 / (3 * EI) + s, length ** 2 / (2 * EI), length / EI
    for u, w, sign in ((1, 5, 1.0), (2, 4, -1.0)):       # y bends about +z, z about −y
        C[u, u], C[w, w] = a, c
        C[u, w] = C[w, u] = sign * b
    return C


@settings(max_examples=40, deadline=None)
@given(EI=st.floats(0.01, 0.2), s=st.floats(0.0, 1e-2))
def test_lateral_shear_of_a_timoshenko_cantilever_is_its_shear_compliance(EI, s):
    assert lateral_shear(cantilever_C6(EI, s)) == pytest.approx(s, abs=1e-12 * L ** 3 / EI)


@settings(max_examples=40, deadline=None)
@given(s0=st.floats(0.0, 2e-3), s1=st.floats(0.0, 5e-3), s2=st.floats(0.0, 2e-3))
def test_shear_law_recovers_a_known_law(s0, s1, s2):
    """s(p) = s0 + s1 p̂ (+ s2 p̂²) sampled at the straight states' pressures → the coefficients back."""
    p = np.array([0.0, 25e3, 50e3, 75e3, 100e3])
    ph = p / 100e3
    np.testing.assert_allclose(fit_shear_law(p, s0 + s1 * ph), [s0, s1], atol=1e-12)
    np.testing.assert_allclose(fit_shear_law(p, s0 + s1 * ph + s2 * ph ** 2, degree=2), [s0, s1, s2], atol=1e-12)


def test_shear_law_is_the_least_squares_line_and_never_negative():
    """The FEM's straight-state values (0.51 / 2.35 / 3.79 mm/N at 0 / 50 / 100 kPa) → the least-squares line
    (closed form of the normal equations); a falling law is clipped at s1 = 0, not made negative."""
    p, s = np.array([0.0, 50e3, 100e3]), np.array([0.51e-3, 2.35e-3, 3.79e-3])
    x = p / 100e3
    s1 = np.sum((x - x.mean()) * (s - s.mean())) / np.sum((x - x.mean()) ** 2)
    np.testing.assert_allclose(fit_shear_law(p, s), [s.mean() - s1 * x.mean(), s1], rtol=1e-12)
    c = fit_shear_law(p, [3e-3, 2e-3, 1e-3])
    assert c[1] == 0.0 and c[0] == pytest.approx(2e-3)
    for bad in (dict(pressures=[0.0, 0.0], s=[1e-3, 2e-3]), dict(pressures=[0.0, 1e5], s=[1e-3, np.nan]),
                dict(pressures=[-1.0, 1e5], s=[1e-3, 2e-3]), dict(pressures=[0.0], s=[1e-3, 2e-3])):
        with pytest.raises(InputError):
            fit_shear_law(**bad)


BASE = __import__("ancf").presets.paper().replace(line_mass=0.0, tip_mass=0.0, gravity=(0.0, 0.0, 0.0))
TRUTH = np.array([700.0, 900.0, 0.09, 0.15, 0.55, 0.35, 0.024, 0.5e-3, 0.5e-3])   # s = 0.5 + 0.5 p̂ mm/N
MEASURED = (0.5e-3, 3.3e-3)                                                        # the FEM's straight states


def _synthetic(cases, theta, params=BASE):
    form = get_form("pressure_ei_shear")
    cases = list(cases)
    ms = np.array([0.25, 0.5, 0.75]) * params.length
    obs = Observations([c.tensions for c in cases], [c.pressure for c in cases], [c.tip_force for c in cases],
                       [bool(c.gravity) for c in cases], np.zeros((len(cases), 3)),
                       markers=np.zeros((len(cases), 3, 3)), marker_s=ms, labels=[c.label for c in cases])
    pred = predict(form.to_params(theta, params), obs)
    obs.tip, obs.markers = pred[:, :3], pred[:, 3:].reshape(len(cases), 3, 3)
    return obs


def test_measured_shear_is_held_with_its_reason_and_the_rest_refitted():
    """identify(measured=…): s0, s1 stay at the values given (not the data's 0.5 + 0.5 p̂), reported held with
    the reason in the fit, fit.json and the actuator file; s at 0 / 100 kPa carry their value."""
    design = default_design()
    train, held = _synthetic(design.training, TRUTH), _synthetic(design.heldout, TRUTH)
    why = identify.MEASURED_SHEAR
    res = identify.identify(train, BASE, heldout=held, forms=("pressure_ei_shear",),
                            measured={"s0": (MEASURED[0], why), "s1": (MEASURED[1], why)})
    f = res.fits["pressure_ei_shear"]
    assert res.params.shear_compliance == pytest.approx(MEASURED, rel=1e-12)
    assert f.held == pytest.approx({"s0": MEASURED[0], "s1": MEASURED[1]}, rel=1e-12)
    assert f.held_at == {"s0": why, "s1": why}
    assert res.values["s_100kPa"] == pytest.approx(sum(MEASURED), rel=1e-12)
    assert "s_100kPa" not in res.not_identifiable and "s_0kPa" not in res.not_identifiable
    assert res.to_dict()["fits"]["pressure_ei_shear"]["held"]["s1"]["held_at"] == why
    text = res.to_toml()
    assert "s1 held at the value measured on the FEM's straight states" in text
    assert f.rms_tip > 1e-6             # the data's own s is not the measured one: the others compensate


def test_measured_shear_with_the_data_s_recovers_the_rest():
    """Held at the data's own law, the refit recovers every other parameter exactly."""
    design = default_design()
    train = _synthetic(design.training, TRUTH)
    why = identify.MEASURED_SHEAR
    res = identify.identify(train, BASE, forms=("pressure_ei_shear",),
                            measured={"s0": (TRUTH[7], why), "s1": (TRUTH[8], why)})
    np.testing.assert_allclose(res.fits["pressure_ei_shear"].theta, TRUTH, rtol=1e-5)


def test_fem_path_holds_the_straight_state_shear(monkeypatch):
    """from_fem on a stand-in FEM (no FEM solve): its records are the reduced model's with s = 0.5 + 0.5 p̂
    mm/N, its straight states' cap compliances those of a cantilever with s = 0.5 + 3.3 p̂ mm/N.  The shear
    form's s on the FEM path is the straight-state law (within 1 %), not the one the tips would give."""
    from fem_reference import presets as fp
    from validation.reference import fem_sweep
    from validation.reference.fem_sweep import FemRecord
    geometry, material = fp.paper_bellows(), fp.paper_material()
    design = default_design(tension_max=5.0, pressure_max=100e3, tendon_distance=geometry.tendon_radius,
                            length=geometry.length, n_tendons=len(geometry.tendon_angles))
    rod = {"EA": 700.0, "EI": 0.09, "D_a": 0.03, "D_eff": 0.024, "EI_tip_force": 0.088,
           "cap_compliance": cantilever_C6(0.09, MEASURED[0], geometry.length).tolist()}
    base = identify.fem_base_params(geometry, material, tension_max=5.0, pressure_max=100e3, rod=rod,
                                    gravity=(0.0, 0.0, -9.81))

    def fake_cases(spec, cases, **kw):
        obs = _synthetic(cases, TRUTH, base)
        s_m = np.concatenate([[0.0], obs.marker_s, [base.length]])
        return [FemRecord(c, obs.tip[i], np.eye(3), np.vstack([[0.0, 0.0, 0.0], obs.markers[i], obs.tip[i]]), s_m,
                          np.array(c.tensions, float), np.zeros(len(c.tensions))) for i, c in enumerate(cases)]

    seen = []

    def fake_task(task):
        seen.append(task["case"].label)
        return lateral_shear(cantilever_C6(0.09, MEASURED[0] + MEASURED[1] * task["case"].pressure / 100e3,
                                           geometry.length))

    monkeypatch.setattr(fem_sweep, "run_rod", lambda spec, cache_dir=None: rod)
    monkeypatch.setattr(fem_sweep, "run_cases", fake_cases)
    monkeypatch.setattr(identify, "straight_shear_task", fake_task)
    res = identify.from_fem(geometry, material, design=design, forms=("pressure_ei_shear",), compliance=False,
                            progress=False, pressure_max=100e3)
    assert sorted(seen) == sorted(c.label for c in design.training if c.experiment == "pressure")
    sc = res.fits["pressure_ei_shear"].params.shear_compliance
    assert sc == pytest.approx(MEASURED, rel=0.01)
    assert res.meta["straight_shear"]["coeffs_m_per_N"] == pytest.approx(MEASURED, rel=1e-9)
    assert res.fits["pressure_ei_shear"].held_at["s1"] == identify.MEASURED_SHEAR
