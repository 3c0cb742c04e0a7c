"""No traceback reaches a user: an unexpected exception (a bug) is one ``error:`` line naming a file that holds
the traceback, exit status 1; the command line's wording of limit messages reads as a sentence."""

import subprocess
import sys

import pytest
import typer

from ancf import clitools


def _app_raising(exc: BaseException):
    app = typer.Typer(add_completion=False)

    @app.command()
    def boom(x: int = 1) -> None:
        raise exc

    @app.command()
    def ok() -> None:
        pass

    return app


@pytest.mark.parametrize("exc", [ZeroDivisionError("float division by zero"), KeyError("q"), RuntimeError("")])
def test_unexpected_exception_is_one_line_and_a_traceback_file(tmp_path, monkeypatch, capsys, exc):
    monkeypatch.setenv("BELLOWS_TRACEBACK_DIR", str(tmp_path / "tb"))
    with pytest.raises(SystemExit) as info:
        clitools.run(_app_raising(exc), ["boom", "--x", "3"])
    assert info.value.code == 1
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: unexpected " + type(exc).__name__), err
    assert "Traceback" not in err
    files = list((tmp_path / "tb").iterdir())
    assert len(files) == 1 and str(files[0]) in lines[0]
    text = files[0].read_text()
    assert "Traceback (most recent call last)" in text and type(exc).__name__ in text
    assert "bellows boom --x 3" in text                # the command that failed, to reproduce it


def test_unwritable_traceback_folder_still_one_line(tmp_path, monkeypatch, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    monkeypatch.setenv("BELLOWS_TRACEBACK_DIR", str(blocker / "sub"))
    with pytest.raises(SystemExit) as info:
        clitools.run(_app_raising(ValueError("bad")), ["boom"])
    assert info.value.code == 1
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "could not be written" in err


def test_handled_errors_keep_status_2_and_success_0(capsys):
    from ancf.errors import InputError
    with pytest.raises(SystemExit) as info:
        clitools.run(_app_raising(InputError("x must be > 0")), ["boom"])
    assert info.value.code == 2 and capsys.readouterr().err.strip() == "error: x must be > 0"
    with pytest.raises(SystemExit) as info:
        clitools.run(_app_raising(InputError("x")), ["ok"])
    assert info.value.code == 0


@pytest.mark.parametrize("api, cli", [
    ("pressure 300 kPa is outside the actuator's limits [0, 120] kPa (the Python API takes pascals: 30 kPa = 30e3; "
     "check_limits=False analyses it anyway)",
     "pressure 300 kPa is outside the actuator's limits [0, 120] kPa (use --no-limits to analyse it anyway)"),
    ("tension T1 = 9 N is above the FEM model's operating limit 20 N (check_limits=False analyses it anyway)",
     "tension T1 = 9 N is above the FEM model's operating limit 20 N (use --no-limits to analyse it anyway)"),
    ("results exist; pass force=True", "results exist; pass --force"),
])
def test_limit_messages_in_command_line_terms(api, cli):
    assert clitools.cli_message(Exception(api)) == cli


def test_pressure_limit_message_from_the_command(tmp_path):
    res = subprocess.run([sys.executable, "-m", "validation.commands.main", "fk", "--pressure-kpa", "300"],
                         capture_output=True, text=True, cwd=tmp_path)
    assert res.returncode == 2
    assert res.stderr.strip().endswith("kPa (use --no-limits to analyse it anyway)"), res.stderr


def test_every_product_error_survives_pickling_with_its_attributes():
    """Errors raised in a worker process reach the caller as themselves (several take required keyword
    arguments, which Exception's default pickling does not pass back)."""
    import pickle

    import numpy as np

    from ancf import errors as E
    made = [E.ConvergenceError("no", solver="fk", iterations=3, residual_norm=2.0, tolerance=1e-9, history=[3.0, 2.0]),
            E.UnstableEquilibriumError("saddle", solver="fk", min_eigenvalue=-1.5),
            E.InfeasibleTargetError("out of reach", target=[0.1, 0.0, 0.0], nearest=[0.09, 0.0, 0.0]),
            E.CollapsedStateError("collapsed", solver="fk", stretch=0.4), E.ConfigError("bad"), E.LimitError("too big")]
    for err in made:
        back = pickle.loads(pickle.dumps(err))
        assert type(back) is type(err) and str(back) == str(err)
        for k, v in vars(err).items():
            assert np.array_equal(np.asarray(getattr(back, k), dtype=object), np.asarray(v, dtype=object))
