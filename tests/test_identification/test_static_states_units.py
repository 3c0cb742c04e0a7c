"""Static-state CSV columns: every unit suffix must be a unit of the column's quantity, and every column must
be known — a wrong-dimension or unknown unit, or an unknown column, is a ConfigError naming the column and
the accepted units, never a silently scaled or dropped value."""

import pytest

from ancf.errors import ConfigError
from hardware.static_states import read_static_states

REQ = "tension1_N,tension2_N,tension3_N,pressure_kPa,tip_x_mm,tip_y_mm,tip_z_mm"
ROW = "1,0,0,30,160,0,-5"


def _read(tmp_path, header, row):
    p = tmp_path / "s.csv"
    p.write_text(header + "\n" + row + "\n")
    return read_static_states(p)


@pytest.mark.parametrize("header, row, column, accepted", [
    # a length unit on a tension column: was read as 1 mm = 1e-3 N
    ("tension1_mm,tension2_N,tension3_N,pressure_kPa,tip_x_mm,tip_y_mm,tip_z_mm", ROW, "tension1_mm", "N"),
    # a force unit on a pressure column, a pressure unit on a tip column
    ("tension1_N,tension2_N,tension3_N,pressure_N,tip_x_mm,tip_y_mm,tip_z_mm", ROW, "pressure_N", "kPa"),
    ("tension1_N,tension2_N,tension3_N,pressure_kPa,tip_x_kPa,tip_y_mm,tip_z_mm", ROW, "tip_x_kPa", "mm"),
    ("tension1_N,tension2_N,tension3_N,pressure_kPa,tip_x_mm,tip_y_mm,tip_z_mm,tip_std_N", ROW + ",0.1",
     "tip_std_N", "mm"),
    ("tension1_N,tension2_N,tension3_N,pressure_kPa,tip_x_mm,tip_y_mm,tip_z_mm,force_x_mm", ROW + ",0.1",
     "force_x_mm", "N"),
    # an unknown unit on an optional column: was silently dropped (no tip load / no σ)
    (REQ + ",force_z_lbf", ROW + ",1", "force_z_lbf", "N"),
    (REQ + ",tip_std_um", ROW + ",50", "tip_std_um", "mm"),
    (REQ + ",pressure_std_inH2O", ROW + ",1", "pressure_std_inH2O", "kPa"),
])
def test_a_unit_of_the_wrong_dimension_or_an_unknown_unit_is_an_error(tmp_path, header, row, column, accepted):
    with pytest.raises(ConfigError, match=column) as exc:
        _read(tmp_path, header, row)
    assert accepted in str(exc.value) and "accepted" in str(exc.value)


@pytest.mark.parametrize("extra", ["temperature_C", "tip_w_mm", "forcex_N", "tension4"])
def test_an_unknown_column_is_an_error(tmp_path, extra):
    with pytest.raises(ConfigError, match=extra):
        _read(tmp_path, REQ + "," + extra, ROW + ",1")


def test_a_gap_in_the_tendon_numbering_is_an_error(tmp_path):
    with pytest.raises(ConfigError, match="tension3_N"):
        _read(tmp_path, "tension1_N,tension3_N,pressure_kPa,tip_x_mm,tip_y_mm,tip_z_mm", "1,0,30,160,0,-5")


def test_accepted_units_are_scaled(tmp_path):
    s = _read(tmp_path, "tension1_N,tension2_N,tension3_N,pressure_bar,tip_x_m,tip_y_mm,tip_z_mm,force_z_N,"
                        "tip_std_mm,pressure_std_kPa,tension_std_N,time_s,label",
              "1,0,0,0.3,0.16,0,-5,-0.1,0.05,0.2,0.01,12.5,a")
    assert s.pressure[0] == pytest.approx(30e3) and s.tip_position[0, 0] == pytest.approx(0.16)
    assert s.tip_force[0, 2] == pytest.approx(-0.1) and s.tip_position_std[0, 0] == pytest.approx(5e-5)
    assert s.pressure_std[0] == pytest.approx(200.0) and s.time[0] == 12.5 and s.label == ["a"]
