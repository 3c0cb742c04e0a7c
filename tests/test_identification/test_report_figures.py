"""The validation report's figures that locate the model's error, built from synthetic validation rows.

Every figure is valid PNG; the data a figure plots come from pure helpers (:func:`error_points`,
:func:`training_points`, :func:`shape_difference`, the compliance ellipse) checked against the rows they were
given and against closed forms (the ellipse of a diagonal compliance has the compliances as semi-axes); a row
without a FEM error gives no bar and no crash; no rows at all is an InputError, rows without the data of a
figure give no figure."""

import math
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import example, given, settings, strategies as st

from ancf.errors import InputError
from validation.checks.compare import COMPLIANCE_TARGET_PCT, SHAPE_TARGET_PCT
from validation.report import figures as figs
from validation.report.build import report_figures

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
L = 0.16
S = np.linspace(0.0, L, 17)


def _centreline(curvature: float, plane: int = 2) -> np.ndarray:
    """A circular arc of the given curvature [1/m] in the x–(plane) plane, at the arc lengths S (17, 3) [m]."""
    c = np.zeros((S.size, 3))
    if curvature == 0:
        c[:, 0] = S
    else:
        c[:, 0] = np.sin(curvature * S) / curvature
        c[:, plane] = (1 - np.cos(curvature * S)) / curvature
    return c


def _row(label, T, p_kpa, *, tip=0.5, shape=0.8, ct=3.0, cl=7.0, offset=(0.0, 0.0, 1e-3), compliance=True,
         experiment="heldout", curvature=3.0):
    fem = _centreline(curvature)
    ancf = fem + np.outer(S / L, offset)                    # the difference grows linearly to `offset` at the tip
    r = {"label": label, "experiment": experiment, "tensions_N": list(T), "pressure_Pa": 1e3 * p_kpa,
         "tip_force_N": [0.0, 0.0, 0.0], "gravity": True, "tip_error_pct": tip, "shape_error_pct": shape,
         "tip_error_m": tip * L / 100, "shape_error_m": shape * L / 100, "shape_s_m": S,
         "centreline_fem_m": fem, "centreline_ancf_m": ancf}
    if compliance:
        Cf = np.diag([1e-5, 6e-2, 6e-2])
        r.update(C_tension_fem=Cf, C_tension_ancf=0.95 * Cf, C_locked_fem=0.3 * Cf, C_locked_ancf=0.27 * Cf,
                 C_tension_error_pct=ct, C_locked_error_pct=cl)
    return r


ROWS = [_row("A", (1, 0, 0), 25, tip=0.4, shape=0.6, ct=2.0, cl=6.0),
        _row("B", (2, 2, 0), 50, tip=1.1, shape=1.7, ct=6.5, cl=12.0, offset=(0.0, 2e-3, -1e-3)),
        _row("C", (0, 0, 3), 100, tip=0.7, shape=0.9, ct=4.0, cl=16.0, curvature=0.0),
        _row("X", (5, 5, 5), 120, tip=2.0, shape=2.2, ct=9.0, cl=20.0, experiment="extrapolation")]
FEM_ERROR = {"rows": [{"label": "A", "fem_tip_error_pct": 0.1, "fem_C_tension_error_pct": 0.5,
                       "fem_C_locked_error_pct": None, "measured": True},
                      {"label": "B", "fem_tip_error_pct": None, "fem_C_tension_error_pct": None,
                       "fem_C_locked_error_pct": None},
                      {"label": "C", "fem_tip_error_pct": 0.3, "fem_C_tension_error_pct": 1.0,
                       "fem_C_locked_error_pct": 2.0, "measured": False}]}


def _png(b: bytes) -> bool:
    return isinstance(b, bytes) and b.startswith(PNG_MAGIC) and len(b) > 1000


# ------------------------------------------------------------------------------------------ error against loads
def test_error_points_are_placed_from_the_rows():
    p = figs.error_points(ROWS, FEM_ERROR, against="pressure")
    assert p["label"] == ["A", "B", "C", "X"]
    np.testing.assert_allclose(p["x"], [25, 50, 100, 120])                          # kPa
    np.testing.assert_allclose(p["tip"], [0.4, 1.1, 0.7, 2.0])
    np.testing.assert_allclose(p["C_tension"], [2.0, 6.5, 4.0, 9.0])
    np.testing.assert_allclose(p["C_locked"], [6.0, 12.0, 16.0, 20.0])
    np.testing.assert_allclose(p["fem_tip"], [0.1, np.nan, 0.3, np.nan])             # None / no FEM row: no bar
    np.testing.assert_allclose(p["fem_C_locked"], [np.nan, np.nan, 2.0, np.nan])
    assert p["extrapolation"].tolist() == [False, False, False, True]
    assert p["fem_measured"].tolist() == [True, True, False, True]
    t = figs.error_points(ROWS, None, against="tension")
    np.testing.assert_allclose(t["x"], [1, 4, 3, 15])                                # ΣT [N]
    assert np.isnan(t["fem_tip"]).all()


@settings(max_examples=30, deadline=None)
@given(st.lists(st.tuples(st.floats(0, 5), st.floats(0, 5), st.floats(0, 5), st.floats(0, 2e5),
                          st.floats(0, 10), st.one_of(st.none(), st.floats(0, 3))), min_size=1, max_size=12))
def test_error_points_match_any_rows(data):
    rows = [{"label": f"s{i}", "tensions_N": [a, b, c], "pressure_Pa": p, "tip_error_pct": e}
            for i, (a, b, c, p, e, _) in enumerate(data)]
    fem = {"rows": [{"label": f"s{i}", "fem_tip_error_pct": f} for i, (*_, f) in enumerate(data)]}
    pp = figs.error_points(rows, fem, against="pressure")
    tt = figs.error_points(rows, fem, against="tension")
    np.testing.assert_allclose(pp["x"], [d[3] / 1e3 for d in data])
    np.testing.assert_allclose(tt["x"], [d[0] + d[1] + d[2] for d in data])
    np.testing.assert_allclose(pp["tip"], [d[4] for d in data])
    np.testing.assert_allclose(pp["fem_tip"], [np.nan if d[5] is None else d[5] for d in data])
    assert np.isnan(pp["C_tension"]).all()                          # no compliances in these rows: no points


def test_error_points_reject_empty_and_malformed_input():
    with pytest.raises(InputError, match="no compared states"):
        figs.error_points([], None)
    with pytest.raises(InputError, match="against"):
        figs.error_points(ROWS, None, against="force")
    with pytest.raises(InputError, match="pressure_Pa"):
        figs.error_points([{"label": "a", "tensions_N": [0], "tip_error_pct": 1.0}], None)
    with pytest.raises(InputError, match="no compared states"):
        figs.error_map_figure([])


def test_training_points_from_the_observations():
    train = SimpleNamespace(pressure=np.array([0.0, 50e3]), tensions=np.array([[1.0, 2.0, 0.0], [0.0, 0.0, 4.0]]))
    e = np.array([0.8e-3, 1.6e-3])
    p = figs.training_points(train, e, L, against="pressure")
    np.testing.assert_allclose(p["x"], [0.0, 50.0])
    np.testing.assert_allclose(p["tip"], [0.5, 1.0])                      # 100 e / L
    np.testing.assert_allclose(figs.training_points(train, e, L, against="tension")["x"], [3.0, 4.0])
    with pytest.raises(InputError, match="training states"):
        figs.training_points(train, e[:1], L)
    with pytest.raises(InputError, match="length_m"):
        figs.training_points(train, e, 0.0)


def test_error_map_is_a_png_with_and_without_fem_errors_and_compliances():
    train = {a: figs.training_points(SimpleNamespace(pressure=np.array([0.0, 50e3]), tensions=np.zeros((2, 3))),
                                     [1e-3, 2e-3], L, against=a) for a in figs.AGAINST}
    assert _png(figs.error_map_figure(ROWS, FEM_ERROR, train=train, targets={"tip": 2.5, "compliance": 5.0}))
    assert _png(figs.error_map_figure(ROWS, None))
    assert _png(figs.error_map_figure(ROWS, {"rows": None}))
    no_c = [_row("n", (1, 0, 0), 10, compliance=False)]
    assert _png(figs.error_map_figure(no_c, {"rows": [{"label": "n", "fem_tip_error_pct": None}]}))


# ---------------------------------------------------------------------------------------------------- shapes
def test_shape_difference_is_rod_minus_fem_in_mm_along_s():
    s, d = figs.shape_difference(ROWS[1])
    np.testing.assert_allclose(s, 1e3 * S)
    np.testing.assert_allclose(d, np.outer(S / L, [0.0, 2.0, -1.0]), atol=1e-12)    # the offset field, mm
    bad = dict(ROWS[0], centreline_ancf_m=ROWS[0]["centreline_ancf_m"][:5])
    with pytest.raises(InputError, match="do not match"):
        figs.shape_difference(bad)
    with pytest.raises(InputError, match="lacks"):
        figs.shape_difference({k: v for k, v in ROWS[0].items() if k != "shape_s_m"})


def test_worst_rows_orders_by_the_key_and_skips_missing():
    rows = [{"k": 1.0}, {"k": float("nan")}, {"k": 3.0}, {}, {"k": 2.0}]
    assert [r["k"] for r in figs.worst_rows(rows, "k", 2)] == [3.0, 2.0]
    assert figs.worst_rows(rows, "k", 0) == []


def test_shape_figures_are_pngs_and_empty_input_is_rejected():
    assert _png(figs.shapes_figure(ROWS))
    assert _png(figs.view3d_figure(ROWS))
    bare = [{k: v for k, v in r.items() if not k.startswith("centreline")} for r in ROWS]
    assert figs.shapes_figure(bare) == b"" and figs.view3d_figure(bare) == b""
    for f in (figs.shapes_figure, figs.view3d_figure, figs.ellipses_figure):
        with pytest.raises(InputError, match="no compared states"):
            f([])


@settings(max_examples=50, deadline=None)
@given(st.floats(1e-4, 50.0), st.floats(10.0, 500.0))
@example(1.0000000000000002e-4, 10.0)              # share·span/d = 9999.999…, whose log10 rounds up to 4.0
def test_magnification_is_round_and_shows_the_difference_at_about_a_tenth(d, span):
    k = figs.magnification(np.array([[d, 0.0, 0.0]]), span)
    mant = k / 10 ** math.floor(math.log10(k))
    assert k >= 1 and any(math.isclose(mant, m) for m in (1, 2, 5))
    if d >= 0.1 * span:
        assert k == 1
    else:
        assert k * d <= 0.1 * span * (1 + 1e-9) and k * d > 0.1 * span / 2.5 - 1e-9


def test_view_faces_the_bending_plane():
    assert figs.view_angles(1e3 * _centreline(0.0)) == (20.0, -60.0)                 # straight: default
    elev, azim = figs.view_angles(1e3 * _centreline(3.0, plane=2))                   # bends in x–z: seen from −y
    assert elev == 20.0 and math.isclose(azim, -60.0)
    elev, azim = figs.view_angles(1e3 * _centreline(3.0, plane=1))                   # bends in x–y: from above
    assert elev == 55.0 and azim == -60.0


# ------------------------------------------------------------------------------------------------- compliance
def test_ellipse_of_a_diagonal_compliance_has_the_compliances_as_semi_axes():
    C = np.diag([2e-3, 5e-3, 7e-3])                                                 # m/N
    for (i, j, _) in figs.PLANES:
        u, v = figs._ellipse(C, i, j, n=721)
        assert math.isclose(u.max(), 1e3 * C[i, i], rel_tol=1e-9) and math.isclose(v.max(), 1e3 * C[j, j],
                                                                                     rel_tol=1e-5)
        np.testing.assert_allclose((u / (1e3 * C[i, i])) ** 2 + (v / (1e3 * C[j, j])) ** 2, 1.0, rtol=1e-9)


def test_ellipses_in_three_planes_and_no_figure_without_compliances():
    assert _png(figs.ellipses_figure(ROWS))
    assert figs.ellipses_figure([_row("n", (1, 0, 0), 10, compliance=False)]) == b""


# ---------------------------------------------------------------------------------------------------- residuals
def test_residuals_share_one_scale_and_draw_the_target():
    assert _png(figs.residuals_figure(["a", "b"], [1e-3, 2e-3], ["c"], [3e-3], target_m=4e-3))
    assert _png(figs.residuals_figure(["a", "b"], [1e-3, 2e-3]))


# ------------------------------------------------------------------------------------------------ in the report
def test_report_figures_carries_every_validation_figure():
    fit = SimpleNamespace(names=["EA", "EI"], correlation=np.array([[1.0, 0.2], [0.2, 1.0]]),
                          tip_errors=lambda: np.array([1e-3, 2e-3]))
    ident = SimpleNamespace(
        comparison=[{"form": "paper", "chosen": True, "train_rms_tip_m": 1e-3, "heldout_rms_tip_m": 2e-3,
                     "heldout_max_tip_m": 3e-3}],
        fit=fit, heldout_errors=np.array([2e-3, 3e-3, 1e-3]), params=SimpleNamespace(length=L),
        train=SimpleNamespace(labels=["t1", "t2"], pressure=np.array([0.0, 50e3]), tensions=np.zeros((2, 3))),
        heldout=SimpleNamespace(labels=["A", "B", "C"]))
    val = SimpleNamespace(rows=ROWS, fem_error=FEM_ERROR,
                          targets={"shape_pct": {"target": SHAPE_TARGET_PCT},
                                   "compliance_pct": {"target": COMPLIANCE_TARGET_PCT}})
    out = report_figures(ident, val)
    assert {"forms", "correlation", "residuals", "error_map", "shapes", "ellipses", "shapes_3d"} <= set(out)
    assert all(_png(v) for v in out.values())
    out = report_figures(ident, SimpleNamespace(rows=[], fem_error={}, targets={}))
    assert set(out) == {"forms", "correlation", "residuals"}


def test_extrapolation_states_stay_out_of_the_shape_and_compliance_figures():
    only_x = [ROWS[-1]]
    assert figs.shapes_figure(only_x) == b"" and figs.ellipses_figure(only_x) == b""
    assert figs.view3d_figure(only_x) == b""
    assert _png(figs.error_map_figure(only_x))                            # the error map marks them apart
