"""The command line's rules, each tested through the real entry point ``validation.commands.main.main``:

* a given option is used or rejected, never silently replaced (``--mu-mpa 0``);
* outputs are validated before any work, and existing results are not overwritten without ``--force``;
* the actuator's limits apply to every mode (fk, ik, locked, FEM), with ``--no-limits`` as the override;
* every handled error exits 2 with exactly one ``error:`` line, in the command line's terms.
"""

import json

import pytest

from ancf import cli as ancf_cli
from validation.commands.main import main


def run(capsys, *args):
    with pytest.raises(SystemExit) as info:
        main(list(args))
    out = capsys.readouterr()
    return info.value.code, out.out, out.err


def one_error_line(err: str) -> str:
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: "), err
    assert "Traceback" not in err
    return lines[0]


@pytest.mark.parametrize("args, message", [
    (["fk", "--pressure-kpa", "abc"], "--pressure-kpa"),                  # not a number (usage error)
    (["fk", "--no-such-option"], "No such option"),
    (["ik"], "--target-mm"),                                              # missing required option
    (["fk", "--tensions-n", "1,2"], "expected 3 values"),
    (["fk", "--tensions-n", "9,0,0"], "--no-limits"),                     # CLI terms, not check_limits=False
    (["fk", "--pressure-kpa", "500"], "kPa"),
    (["fk", "--n-elements", "0"], "--n-elements"),
    (["fk", "--preset", "/nonexistent/file.toml"], "cannot read"),
    (["locked", "--lengths-mm", "150,150,150", "--preset", "paper_unscaled"], "outside the actuator's limits"),
    (["locked", "--lengths-mm", "160,160,160", "--method", "newton"], "--method"),
    (["ik", "--target-mm", "158,0,12", "--pressure-kpa", "30"], "not reachable"),
    (["fem", "solve", "--mu-mpa", "0"], "--mu-mpa"),                      # 0 is not "not given"
    (["fem", "solve", "--kappa-mpa", "-1"], "--kappa-mpa"),
    (["fem", "solve", "--pressure-kpa", "30000"], "--no-limits"),         # before meshing
    (["fem", "solve", "--tensions-n", "50,0,0"], "operating limit"),
    (["fem", "solve", "--png"], "--out"),
    (["fem", "solve", "--solver", "bogus"], "not available"),              # before meshing
    (["fem", "solve", "--locked-lengths-mm", "a,,"], "--locked-lengths-mm"),
])
def test_every_handled_error_is_one_line_with_status_2(capsys, args, message):
    code, _, err = run(capsys, *args)
    line = one_error_line(err)
    assert code == 2 and message in line
    for api_term in ("check_limits", "force=True", "SI pascals", "30e3"):
        assert api_term not in line


def test_the_same_limits_apply_to_locked_mode_with_an_explicit_override(capsys):
    code, out, err = run(capsys, "locked", "--lengths-mm", "150,150,150", "--no-limits", "--json",
                         "--preset", "paper_unscaled")
    assert code == 0, err
    data = json.loads(out)["locked"]
    assert max(data["tensions_N"]) > 5 and data["limit_violations"] and data["stable"] is True


def test_outputs_are_checked_before_any_work(capsys, tmp_path, monkeypatch):
    def must_not_run(*a, **k):
        raise AssertionError("computed before the output was checked")

    (tmp_path / "demo.json").write_text("{}")
    monkeypatch.setattr(ancf_cli, "run_demo", must_not_run)
    monkeypatch.setattr(ancf_cli, "_model", must_not_run)
    code, _, err = run(capsys, "demo", "--out", str(tmp_path))
    assert code == 2 and "--force" in one_error_line(err)
    assert (tmp_path / "demo.json").read_text() == "{}"                     # not overwritten
    (tmp_path / "s.vtu").write_text("keep")
    for args in (["fk", "--vtu", str(tmp_path / "s.vtu")], ["ik", "--target-mm", "1,2,3", "--vtu", str(tmp_path / "s.vtu")],
                 ["fk", "--vtu", str(tmp_path / "s.txt")], ["params", "--out", str(tmp_path / "p.json")],
                 ["fem", "solve", "--out", str(tmp_path / "s.vtu")]):
        code, _, err = run(capsys, *args)
        assert code == 2, args
        one_error_line(err)
    assert (tmp_path / "s.vtu").read_text() == "keep"


def test_force_overwrites_and_fresh_names_work(capsys, tmp_path):
    target = tmp_path / "s.vtu"
    target.write_text("old")
    code, _, err = run(capsys, "fk", "--tensions-n", "1,0,0", "--vtu", str(target), "--force", "--json")
    assert code == 0, err and target.read_text() != "old"
    code, _, err = run(capsys, "params", "--preset", "four_tendon", "--out", str(tmp_path / "a.toml"))
    assert code == 0, err
    code, _, err = run(capsys, "params", "--preset", "paper", "--out", str(tmp_path / "a.toml"))
    assert code == 2 and "exists" in one_error_line(err)


def test_help_is_plain_text_with_whole_summaries(capsys):
    code, out, _ = run(capsys, "--help")
    assert code == 0
    commands = out.split("Commands:")[1].splitlines()
    assert "``" not in out and not any(ln.rstrip().endswith("...") for ln in commands), out
    for cmd in ("demo", "fk", "ik", "locked", "compliance", "params", "fem", "fem solve"):
        code, out, _ = run(capsys, *cmd.split(), "--help")
        assert code == 0 and "``" not in out
        if "Commands:" in out:            # command groups: whole summaries of their commands too
            assert not any(ln.rstrip().endswith("...") for ln in out.split("Commands:")[1].splitlines()), out


def test_table_columns_state_units(capsys):
    code, out, err = run(capsys, "fk", "--tensions-n", "1,0,0")
    assert code == 0, err
    for col in ("T [N]", "p [kPa]", "F [N]", "tip x,y,z [mm]", "slack [mm]", "time [ms]"):
        assert col in out, col


def test_ctrl_c_is_one_line_with_status_130(capsys, monkeypatch):
    def interrupted(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(ancf_cli, "warm_up", interrupted)
    code, _, err = run(capsys, "fk", "--tensions-n", "1,0,0")
    assert code == 130 and one_error_line(err) == "error: interrupted"


def test_an_interrupted_run_error_is_reported_like_every_product_error(capsys, monkeypatch, tmp_path):
    from validation.infra.runner import RunInterrupted

    def stopped(*a, **k):
        raise RunInterrupted("interrupted", completed={0: 1, 1: 2, 2: 3}, total=10, saved_to="x.h5")

    monkeypatch.setattr(ancf_cli, "run_demo", stopped)
    code, _, err = run(capsys, "demo", "--out", str(tmp_path / "d"))
    assert code == 2 and "3 of 10 tasks finished; finished results saved to x.h5" in one_error_line(err)
