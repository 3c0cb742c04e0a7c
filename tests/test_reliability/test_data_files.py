"""Data files that are not what their name says — binary content in a .csv, a folder given as a file, a value that
is not a finite number in one row, a truncated HDF5 file — end, through every command that reads them, in one
`error:` line naming the file (and for tabular data its row and column), exit status 2, before any fit."""

import numpy as np
import pytest

from ancf import clitools
from ancf.errors import ConfigError
from hardware.static_states import StaticStates, read_static_states, write_static_states
from validation.commands.main import app

STATES_HEADER = "tension1_N,tension2_N,tension3_N,pressure_kPa,tip_x_mm,tip_y_mm,tip_z_mm"
DECAY_HEADER = "t_s,tip_x_mm,tip_y_mm,tip_z_mm"

COMMANDS = {"identify": lambda f: ["identify", "--measurements", f, "--base", "paper"],
            "identify-damping": lambda f: ["identify-damping", f],
            "log show": lambda f: ["log", "show", f]}


def _cli(args, capsys):
    with pytest.raises(SystemExit) as info:
        clitools.run(app, [str(a) for a in args])
    err = capsys.readouterr().err.strip()
    return info.value.code, err


def _binary(path):
    path.write_bytes(bytes(range(256)) * 8)            # NUL bytes and bytes that are not UTF-8
    return path


def _binary_no_nul(path):
    path.write_bytes(bytes(range(128, 256)) * 8)       # no NUL: caught as not UTF-8 text
    return path


def _folder(path):
    path.mkdir()
    return path


def _truncated(path):
    full = path.with_name("full.h5")
    write_static_states(full, StaticStates(tensions=np.ones((5, 3)), pressure=np.full(5, 3e4),
                                           tip_position=np.tile([0.16, 0.0, 0.0], (5, 1))))
    path.write_bytes(full.read_bytes()[:1500])
    return path


CASES = {"binary.csv": (_binary, "not a text"), "latin.csv": (_binary_no_nul, "not UTF-8 text"),
         "folder.csv": (_folder, "folder"), "folder.h5": (_folder, "folder"), "cut.h5": (_truncated, "truncated")}


@pytest.mark.parametrize("command", list(COMMANDS))
@pytest.mark.parametrize("name", list(CASES))
def test_a_file_that_is_not_what_its_name_says_is_one_error_line(tmp_path, capsys, command, name):
    make, match = CASES[name]
    path = make(tmp_path / name)
    code, err = _cli(COMMANDS[command](path), capsys)
    assert code == 2, err
    assert err.startswith("error:") and err.count("\n") == 0 and "unexpected" not in err and "Traceback" not in err
    assert name in err
    if not (command == "log show" and name.endswith(".csv") and make is not _folder):
        assert match in err                       # (a .csv given to `log show` is "not a readable HDF5 file")


@pytest.mark.parametrize("bad", ["nan", "inf", "-inf", "abc"])
def test_a_value_that_is_not_a_finite_number_names_file_row_and_column(tmp_path, capsys, bad):
    states = tmp_path / "states.csv"
    states.write_text(f"# comment line\n{STATES_HEADER}\n1,0,0,30,160,0,1\n1,0,0,{bad},160,0,1\n")
    code, err = _cli(COMMANDS["identify"](states), capsys)
    assert code == 2 and err.count("\n") == 0
    assert "states.csv" in err and "row 4" in err and "column pressure_kPa" in err
    decay = tmp_path / "decay.csv"
    rows = [f"{0.002 * i:.3f},0,0,{np.cos(i / 5):.6f}" for i in range(100)]
    rows[40] = f"0.080,0,{bad},0.5"
    decay.write_text(DECAY_HEADER + "\n" + "\n".join(rows) + "\n")
    code, err = _cli(COMMANDS["identify-damping"](decay), capsys)
    assert code == 2 and err.count("\n") == 0
    assert "decay.csv" in err and "row 42" in err and "column tip_y_mm" in err


def test_an_empty_required_cell_and_a_negative_tension_name_row_and_column(tmp_path):
    p = tmp_path / "s.csv"
    p.write_text(f"{STATES_HEADER}\n1,0,0,30,160,0,1\n1,0,0,,160,0,1\n")
    with pytest.raises(ConfigError, match=r"row 3, column pressure_kPa: empty cell"):
        read_static_states(p)
    p.write_text(f"{STATES_HEADER}\n1,0,0,30,160,0,1\n1,-0.5,0,30,160,0,1\n")
    with pytest.raises(ConfigError, match=r"row 3, column tension2_N: a tension must be >= 0"):
        read_static_states(p)


def test_a_non_finite_value_in_an_hdf5_file_names_the_state_and_dataset(tmp_path):
    import h5py
    p = tmp_path / "s.h5"
    write_static_states(p, StaticStates(tensions=np.ones((5, 3)), pressure=np.full(5, 3e4),
                                        tip_position=np.tile([0.16, 0.0, 0.0], (5, 1))))
    with h5py.File(p, "a") as f:
        f["static_states/tip_position"][2, 1] = np.inf
    with pytest.raises(ConfigError, match=r"s\.h5: .*tip_position contains NaN or inf \(state 2 .*column 1"):
        read_static_states(p)


def test_an_unknown_load_stays_allowed(tmp_path):
    p = tmp_path / "s.csv"
    p.write_text(f"{STATES_HEADER},force_z_N\n1,0,0,30,160,0,1,\n1,0,0,30,160,0,1,nan\n1,0,0,30,160,0,1,-0.1\n")
    s = read_static_states(p)
    assert np.isnan(s.tip_force[:2, 2]).all() and s.tip_force[2, 2] == -0.1
    p.write_text(f"{STATES_HEADER},force_z_N\n1,0,0,30,160,0,1,inf\n")
    with pytest.raises(ConfigError, match="row 2, column force_z_N"):
        read_static_states(p)
