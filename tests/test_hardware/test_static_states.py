"""The static-states file format: HDF5 and CSV round trips, units, and clear errors on malformed files."""

import numpy as np
import pytest

from ancf.errors import BellowsError, ConfigError, InputError
from hardware.static_states import (StaticStates, read_static_states, write_static_states,
                                    write_static_states_csv)


def _states(n=5, markers=True, seed=0):
    rng = np.random.default_rng(seed)
    kw = dict(tensions=rng.uniform(0, 5, (n, 3)), pressure=rng.uniform(0, 120e3, n),
              tip_position=rng.normal(0, 0.01, (n, 3)) + [0.16, 0, 0],
              tip_force=np.where(np.arange(n)[:, None] == 0, np.nan, rng.normal(0, 0.1, (n, 3))),
              tip_position_std=np.full((n, 3), 5e-5), label=[f"s{k}" for k in range(n)])
    if markers:
        kw.update(markers=rng.normal(0, 0.01, (n, 2, 3)), marker_arclength=[0.05, 0.1])
    return StaticStates(**kw)


def test_hdf5_round_trip_is_exact(tmp_path):
    s = _states()
    path = write_static_states(tmp_path / "s.h5", s)
    r = read_static_states(path)
    for name in ("tensions", "pressure", "tip_position", "markers", "marker_arclength", "tip_position_std"):
        np.testing.assert_array_equal(getattr(r, name), getattr(s, name))
    np.testing.assert_array_equal(np.isnan(r.tip_force), np.isnan(s.tip_force))
    assert r.label == s.label


def test_no_silent_overwrite(tmp_path):
    path = write_static_states(tmp_path / "s.h5", _states())
    with pytest.raises(InputError, match="exists"):
        write_static_states(path, _states())
    write_static_states(path, _states(seed=1), overwrite=True)


def test_csv_round_trip_and_unit_suffixes(tmp_path):
    s = _states(markers=False)
    path = write_static_states_csv(tmp_path / "s.csv", s)
    r = read_static_states(path)
    np.testing.assert_allclose(r.tensions, s.tensions, rtol=0, atol=0)
    np.testing.assert_allclose(r.tip_position, s.tip_position, rtol=0, atol=0)
    # mm / kPa columns are converted
    (tmp_path / "mm.csv").write_text("tension1_N,tension2_N,tension3_N,pressure_kPa,tip_x_mm,tip_y_mm,tip_z_mm\n"
                                     "1,0,0,30,160,0,-5\n")
    mm = read_static_states(tmp_path / "mm.csv")
    assert mm.pressure[0] == 30e3 and mm.tip_position[0, 0] == pytest.approx(0.16)


@pytest.mark.parametrize("text, match", [
    ("tension1_N,tension2_N,tension3_N,pressure,tip_x_m,tip_y_m,tip_z_m\n1,0,0,3,0.16,0,0\n", "unit suffix"),
    ("tension1_N,tension2_N,tension3_N,pressure_Pa,tip_x_m,tip_y_m\n1,0,0,3,0.16,0\n", "tip_z"),
    ("tension1_N,tension2_N,tension3_N,pressure_Pa,tip_x_m,tip_y_m,tip_z_m\n1,x,0,3,0.16,0,0\n", "not a number"),
    ("tension1_N,tension2_N,tension3_N,pressure_Pa,tip_x_m,tip_y_m,tip_z_m\n-1,0,0,3,0.16,0,0\n", ">= 0"),
    ("tension1_N\n", "at least one state"),
])
def test_malformed_csv_is_a_config_error(tmp_path, text, match):
    (tmp_path / "bad.csv").write_text(text)
    with pytest.raises(ConfigError, match=match):
        read_static_states(tmp_path / "bad.csv")


def test_malformed_hdf5_is_a_config_error(tmp_path):
    import h5py
    (tmp_path / "junk.h5").write_bytes(b"not hdf5")
    with pytest.raises(ConfigError, match="HDF5"):
        read_static_states(tmp_path / "junk.h5")
    with h5py.File(tmp_path / "empty.h5", "w"):
        pass
    with pytest.raises(ConfigError, match="no static states"):
        read_static_states(tmp_path / "empty.h5")
    path = write_static_states(tmp_path / "u.h5", _states())
    with h5py.File(path, "a") as f:
        f["static_states/pressure"].attrs["units"] = "kPa"
    with pytest.raises(ConfigError, match="units"):
        read_static_states(path)


def test_shape_errors_are_typed():
    with pytest.raises(InputError, match="tip_position"):
        StaticStates(tensions=np.zeros((2, 3)), pressure=[0, 0], tip_position=np.zeros((3, 3)))
    with pytest.raises(BellowsError):
        StaticStates(tensions=np.zeros((2, 3)), pressure=["a", 0], tip_position=np.zeros((2, 3)))
    with pytest.raises(InputError, match="marker_arclength"):
        StaticStates(tensions=np.zeros((1, 3)), pressure=[0], tip_position=np.zeros((1, 3)),
                     markers=np.zeros((1, 2, 3)))


def test_subset_keeps_everything():
    s = _states()
    sub = s.subset([0, 2])
    assert sub.n_states == 2 and sub.label == ["s0", "s2"]
    np.testing.assert_array_equal(sub.markers, s.markers[[0, 2]])
