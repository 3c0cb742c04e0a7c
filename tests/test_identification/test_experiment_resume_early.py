"""``bellows experiment --resume`` with options that differ from the log's is refused before any design or rig
work, naming the option and the value stored in the log."""

from __future__ import annotations

import pytest

import validation.identification.experiment as experiment_design

ARGV = ["experiment", "--rig", "sim", "--states", "5", "--form", "paper", "--loads-g", "0", "--samples", "2",
        "--settle-s", "0", "--log", "exp.h5"]


@pytest.fixture(scope="module")
def log_dir(tmp_path_factory):
    from validation.commands.main import main
    d = tmp_path_factory.mktemp("resume")
    import os
    cwd = os.getcwd()
    os.chdir(d)
    try:
        with pytest.raises(SystemExit) as e:
            main(ARGV)
        assert e.value.code == 0
    finally:
        os.chdir(cwd)
    return d


class _Designed(Exception):
    """Raised by the design when it is called."""


@pytest.fixture
def no_design(monkeypatch, log_dir):
    def refuse(*a, **k):
        raise _Designed("the design was computed")
    monkeypatch.setattr(experiment_design, "design_experiment", refuse)
    monkeypatch.chdir(log_dir)


@pytest.mark.parametrize("change, option, stored", [
    (["--samples", "3"], "--samples", "2 in the log"),
    (["--loads-g", "0,20"], "--loads-g", "[0.0] in the log"),
    (["--form", "separate"], "--form", "'paper' in the log"),
    (["--seed", "4"], "--seed", "None in the log"),
])
def test_a_conflicting_option_is_refused_before_the_design(no_design, capsys, change, option, stored):
    from validation.commands.main import main
    argv = list(ARGV) + ["--resume"]
    i = argv.index(change[0]) if change[0] in argv else None
    if i is None:
        argv += change
    else:
        argv[i + 1] = change[1]
    with pytest.raises(SystemExit) as e:
        main(argv)                           # the design raises _Designed if it is reached
    err = capsys.readouterr().err
    assert e.value.code == 2, err
    assert err.startswith("error:") and option in err and stored in err


def test_the_same_options_go_on_to_the_design(no_design, capsys):
    from validation.commands.main import main
    with pytest.raises(SystemExit):
        main(list(ARGV) + ["--resume"])
    assert "the design was computed" in capsys.readouterr().err
