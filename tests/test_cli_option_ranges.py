"""Every numeric option (and every comma list of numbers) of every ``bellows`` subcommand refuses a value outside
its range at the command-line boundary: exit status 2 and exactly one ``error:`` line that names the option — a
usage error, never a library's own check surfacing as an "unexpected" bug (exit 1, a traceback file) or a run
that starts and computes nonsense (``bellows paper workspace --samples 0``, a negative ``--seed``, a NaN payload).

The cases are a table, ``RANGES``: (command, option, bad values[, what the line names, extra arguments]).  A new
option gets a row there; ``test_every_numeric_option_has_a_row`` walks the whole typer command tree and fails on
a numeric (int/float) or number-list option without one, so that a new option without a range check is caught.

Only refused inputs run, in-process under the console entry point's error contract (:func:`ancf.clitools.run`,
what :func:`validation.commands.main.main` calls; the command tree is built once, not per case, to keep this file fast —
``test_the_entry_point_gives_the_same_lines`` checks ``main`` itself on a sample): no study, solve, FEM or rig
starts — the ``no_work`` fixture turns each command's first expensive call into an immediate failure, so that a
check that regresses fails here at once instead of running for minutes.
"""

from __future__ import annotations

import re

import pytest
import typer

from ancf import clitools
from validation.commands.main import app, main
from cli_commands import commands  # noqa: E402

#: valid values of required options, so that a row tests only its own option
BASE = {
    "ik": ["--target-mm", "150,0,10"],
    "locked": ["--lengths-mm", "160,160,160"],
    "simulate": ["--tensions-n", "1,0,0"],
    "identify-damping": ["no_such_decay.csv"],      # the ranges are checked before the file is read
    "validate": ["--params", "paper"],
    "calibrate": ["--target-ea-n", "700"],
    "control": ["--target-mm", "176,-12,3", "--pressure-kpa", "30"],
    "experiment": ["--log", "exp.h5"],
    "fem profile": ["--export", "wall.csv"],
}

NAN_INF = ["nan", "inf"]
RATIO = ["-0.1", "1.5", *NAN_INF]                   # a ratio in [0, 1]
POSITIVE = ["0", "-1", *NAN_INF]                    # a finite number > 0
NON_NEGATIVE = ["-1", *NAN_INF]                     # a finite number >= 0
WORKERS = ["0", "-1", "1025"]
SEED = ["-1", str(2**32), "99999999999999999999999"]
SAMPLES = ["0", "-1", "10000001", "99999999999999999999999"]
N_ELEMENTS = ["0", "-1", "201"]
VECTOR3 = ["", "1,2", "1,x", "1,,2,3", "inf,0,0"]             # a 3-vector of finite numbers
NUMBERS = ["", ",", "1,x", "1,,2", "nan", "inf"]               # a non-empty list of finite numbers
CHAIN = ["--preset", "two_segment"]                            # a two-segment actuator (6 tendons, 2 chambers)

#: (command, option, bad values, text the error line names (default: the option), extra arguments)
RANGES = [
    # the model: ancf/cli.py, ancf/dynamics/cli.py
    *[(c, "--pressure-kpa", NAN_INF) for c in ("fk", "ik", "locked", "compliance", "modes", "simulate")],
    ("fk", "--n-elements", N_ELEMENTS),
    ("ik", "--n-elements", N_ELEMENTS),
    ("fk", "--tensions-n", VECTOR3),
    ("compliance", "--tensions-n", VECTOR3),
    ("modes", "--tensions-n", VECTOR3),
    ("simulate", "--tensions-n", VECTOR3),
    ("simulate", "--start-tensions-n", VECTOR3),
    *[(c, "--tip-force-n", VECTOR3) for c in ("fk", "ik", "locked", "compliance", "modes", "simulate")],
    ("ik", "--target-mm", VECTOR3),
    ("locked", "--lengths-mm", [*VECTOR3, "0,160,160", "-1,160,160"]),
    ("compliance", "--load-direction", [*VECTOR3, "0,0,0"]),
    # a multi-segment actuator: one tension and one locked length per tendon, one pressure per chamber
    *[(c, "--pressure-kpa", ["30,10"]) for c in ("fk", "locked", "compliance")],
    *[(c, "--pressure-kpa", ["30", "30,10,5", "nan,0", "30,"], "--pressure-kpa", CHAIN) for c in ("fk", "compliance")],
    *[(c, "--tensions-n", ["1,0,0", "1,0,0,0,0,0,0", *NUMBERS], "--tensions-n", CHAIN) for c in ("fk", "compliance")],
    ("locked", "--lengths-mm", ["160,160,160", "0,80,80,160,160,160", "-1,80,80,160,160,160", *NUMBERS],
     "--lengths-mm", CHAIN),
    ("modes", "--count", ["0", "-1", "1000", "99999999999999999999999"]),
    ("modes", "--damping-ratio", RATIO),
    ("simulate", "--ramp-ms", NON_NEGATIVE),
    ("simulate", "--t-end-s", [*POSITIVE, "1e7"]),
    ("simulate", "--dt-ms", [*POSITIVE, "2000"]),                 # 2 s > the default --t-end-s 1
    ("simulate", "--dt-ms", ["1e-5"], "--dt-ms", ["--t-end-s", "1000"]),   # 10^11 steps
    ("simulate", "--damping-ratio", RATIO),
    ("simulate", "--rho-inf", RATIO),
    ("simulate", "--pvd-frames", ["1", "0", "-1", "100001", "99999999999999999999999"]),
    # identification: validation/commands/identify.py
    ("identify-damping", "--start-s", NON_NEGATIVE),
    ("identify-damping", "--end-s", POSITIVE),
    ("identify-damping", "--end-s", ["0.2", "0.3"], "--end-s", ["--start-s", "0.3"]),
    ("identify", "--heldout-fraction", ["-0.1", "1", "1.5", *NAN_INF]),
    *[(c, "--tension-max-n", POSITIVE) for c in ("identify", "report")],      # the upper limit: with the cases
    *[(c, "--pressure-max-kpa", POSITIVE) for c in ("identify", "report")],
    ("report", "--tendon-friction", RATIO),
    *[(c, "--workers", WORKERS) for c in ("identify", "validate", "report", "calibrate")],
    *[(c, "--forms", ["", ",", "no_such_form"]) for c in ("identify", "report")],
    ("calibrate", "--target-ea-n", POSITIVE),
    ("calibrate", "--target-ei-n-m2", POSITIVE),
    ("calibrate", "--target-d-eff-mm", POSITIVE),
    ("calibrate", "--range-factor", ["1", "0.5", "-1", "11", *NAN_INF]),
    ("calibrate", "--pressure-kpa", [*POSITIVE, "201"]),
    ("calibrate", "--free", ["", ",", "no_such_parameter"]),
    # the controller on a rig: validation/commands/control.py
    ("control", "--target-mm", VECTOR3),
    ("control", "--pressure-kpa", ["-1", *NAN_INF]),
    ("control", "--tolerance-mm", ["-1", *NAN_INF]),
    ("control", "--load-mass-g", ["-1", "1001", *NAN_INF], "--load-mass-g", ["--load-profile", "step"]),
    ("control", "--seed", SEED),
    ("control", "--duration-s", POSITIVE),
    ("control", "--max-iterations", ["-1"]),
    ("control", "--plant-damping-ratio", RATIO, "--plant-damping-ratio", ["--dynamics"]),
    ("control", "--shaping-damping-ratio", ["-0.1", "1", *NAN_INF]),
    # the identification experiment on a rig: validation/commands/experiment.py
    ("experiment", "--states", ["2", "-1", "1001"]),
    ("experiment", "--samples", ["1", "0", "10001"]),
    ("experiment", "--loads-g", [*NUMBERS, "-1", "1001"]),
    ("experiment", "--settle-s", ["-1", "601", *NAN_INF]),
    ("experiment", "--tension-tolerance-n", ["0", "-1", "11", *NAN_INF]),
    ("experiment", "--corrections", ["-1", "51"]),
    ("experiment", "--seed", SEED),
    # the paper's studies: validation/commands/paper.py
    *[(f"paper {c}", "--samples", SAMPLES) for c in ("workspace", "all", "compare")],
    *[(f"paper {c}", "--seed", SEED) for c in ("workspace", "all")],
    *[(f"paper {c}", "--workers", WORKERS) for c in ("workspace", "all", "compare")],
    ("paper workspace", "--chunk-size", SAMPLES),
    ("paper stiffness", "--pressures-kpa", [*NUMBERS, "-1", "0,-25"]),
    ("paper stiffness", "--tensions-n", [*NUMBERS, "-1"]),
    ("paper stiffness", "--mass-kg", [*POSITIVE, "1.5"]),
    ("paper dynamic", "--frequencies-hz", [*NUMBERS, "0", "-1", "0.001", "21"]),
    ("paper dynamic", "--cycles", ["0", "1", "-1", "51", "99999999999999999999999"]),
    ("paper dynamic", "--mass-g", [*POSITIVE, "1001"]),
    ("paper dynamic", "--motor-rate-mm-s", POSITIVE),
    *[("paper dynamic", o, [*NON_NEGATIVE, "10001"]) for o in ("--settle-ms", "--compute-ms", "--latency-ms")],
    ("paper dynamic", "--damping-ratio", RATIO),
    ("paper dynamic", "--observer-bandwidth-hz", [*POSITIVE, "125", "1000"]),
    ("paper dynamic", "--loop-latency-ms", [*NON_NEGATIVE, "31"]),
    ("paper dynamic", "--model-error-pct", [*NON_NEGATIVE, "50", "101"]),
    ("paper table1", "--plant-friction", [*NUMBERS, "-0.1", "1.5", "0,2"]),
    ("paper loading", "--plant-friction", [*NUMBERS, "-0.1", "1.5", "0,2"]),
    ("paper loading", "--aware-compute-ms", [*NON_NEGATIVE, "10001"]),
    ("paper convergence", "--n-values", [*NUMBERS, "0", "1.5", "201"]),
    ("paper convergence", "--n-ref", N_ELEMENTS),
    ("paper loads", "--mass-kg", [*POSITIVE, "1.5"]),
    ("paper loads", "--hold-mass-kg", [*POSITIVE, "1.5"]),
    ("paper compare", "--seeds", [*NUMBERS, "-1", "0.5", str(2**32)]),
    ("paper compare", "--presets", ["", ","]),
    ("paper segments", "--samples", SAMPLES),
    ("paper segments", "--seed", SEED),
    ("paper segments", "--workers", WORKERS),
    ("paper segments", "--rays", ["1", "0", "-1", "65", "2.5"]),
    ("paper segments", "--bisections", ["-1", "11", "1.5"]),
    ("paper segments", "--points", ["0", "4", "-1"]),
    ("paper segments", "--single-length-mm", [*NAN_INF, "0", "-170", "49", "501"]),
    # the FEM: validation/commands/fem.py
    ("fem solve", "--pressure-kpa", [*NAN_INF, "-inf"]),
    ("fem solve", "--tensions-n", [*VECTOR3, "-1,0,0"]),
    ("fem solve", "--tip-force-n", VECTOR3),
    ("fem solve", "--locked-lengths-mm", ["1,2", "a,,", "0,,", "-1,,", "nan,,"]),
    ("fem solve", "--mu-mpa", [*POSITIVE, "1e7"]),
    ("fem solve", "--kappa-mpa", [*POSITIVE, "1e7"]),
    ("fem solve", "--kappa-mpa", ["1"], "--kappa-mpa", ["--mu-mpa", "10"]),   # Poisson ratio < 0
    ("fem solve", "--max-time-s", POSITIVE),
    ("fem profile", "--spacing-mm", [*POSITIVE, "10.5"]),
    ("fem profile", "--mesh", ["", ",", "fine", "coarse,x"]),
    # paths the commands read: the line names the path
    ("log show", "path", ["no_such_log.h5"], "no_such_log.h5"),
    ("log export", "path", ["no_such_log.h5"], "no_such_log.h5", ["--csv", "out.csv"]),
    ("log export", "--max-frames", ["1", "0", "-1", "100001"], "--max-frames", ["run.h5", "--pvd", "out.pvd"]),
    ("identify-damping", "record", ["no_such_decay.csv"], "no_such_decay.csv"),
    ("identify", "--measurements", ["no_such_states.csv"], "--measurements", ["--base", "paper"]),
    ("control", "--rig", ["no_such_rig.toml"], "no_such_rig.toml"),
]


def _cases():
    for row in RANGES:
        command, option, values = row[:3]
        names = row[3] if len(row) > 3 else option
        extra = row[4] if len(row) > 4 else []
        for value in values:
            yield pytest.param(command, option, value, names, extra, id=f"{command} {option}={value!r}"
                               + (f" {' '.join(extra)}" if extra else ""))


def _argv(command: str, option: str, value: str, extra: list) -> list:
    base = [a for a in BASE.get(command, []) if not (command == "identify-damping" and option == "record")]
    if not option.startswith("--"):                       # a positional argument
        return [*command.split(), value, *base, *extra]
    return [*command.split(), *base, *extra, f"{option}={value}"]   # "=": values such as "-1" stay values


@pytest.fixture
def no_work(monkeypatch, tmp_path):
    """Each command's first expensive step fails at once (exit 1, an "unexpected" error): a refused option never
    gets there, and a check that regresses fails this test in milliseconds instead of starting a long run."""
    monkeypatch.chdir(tmp_path)                                          # default output folders land here
    monkeypatch.setenv("BELLOWS_TRACEBACK_DIR", str(tmp_path / "tracebacks"))

    def work(*args, **kwargs):
        raise AssertionError("the command started its work: the option was not refused first")

    for target in ("ancf.cli.warm_up", "ancf.dynamics.cli.warm_up",           # fk, ik, locked / modes, simulate
                   "validation.paper.workspace", "validation.paper.run_all", "validation.paper.stiffness_vs_tension",
                   "validation.paper.dynamic.dynamic_loading", "validation.paper.convergence.element_convergence",
                   "validation.paper.loads.locked_drift", "validation.paper.loads.hold_payload",
                   "validation.paper.comparison.compare", "validation.infra.runner.run_tasks",
                   "validation.paper.segments.segments_study",
                   "validation.commands.identify._identify_fem", "validation.commands.identify._identify_measured",
                   "validation.reference.fem_sweep.run_cases", "validation.identification.calibrate.calibrate",
                   "validation.identification.damping.fit_free_decay", "fem_reference.model.BellowsModel",
                   "validation.commands.control.compile_loop_kernels", "hardware.build.build_rig"):
        monkeypatch.setattr(target, work)


#: the ``bellows`` command tree, built once (``main`` builds it on every call: ≈ 50 ms)
COMMAND = typer.main.get_command(app)


def _run(capsys, argv: list, entry=None) -> tuple:
    with pytest.raises(SystemExit) as info:
        entry(argv) if entry else clitools.run(COMMAND, argv)
    out = capsys.readouterr()
    return info.value.code, out.err


@pytest.mark.parametrize("command, option, value, names, extra", list(_cases()))
def test_a_value_out_of_range_is_one_error_line_with_status_2(no_work, capsys, command, option, value, names, extra):
    code, err = _run(capsys, _argv(command, option, value, extra))
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert code == 2, f"exit status {code}, expected 2: {err}"
    assert len(lines) == 1 and lines[0].startswith("error: "), f"expected one 'error:' line, got: {err!r}"
    assert names in lines[0], f"the line does not name {names}: {lines[0]}"
    assert "Traceback" not in err and "unexpected" not in lines[0]


@pytest.mark.parametrize("argv", [["paper", "workspace", "--samples", "0"], ["paper", "workspace", "--seed", "-1"],
                                  ["simulate", "--tensions-n", "1,0,0", "--dt-ms", "nan"],
                                  [*BASE["control"], "--seed", "-1"], ["paper", "compare", "--seeds", "0,-1"]],
                         ids=lambda a: " ".join(a))
def test_the_entry_point_gives_the_same_lines(no_work, capsys, argv):
    argv = ["control", *argv] if argv[0] == "--target-mm" else argv
    assert _run(capsys, argv, entry=main) == _run(capsys, argv)


# ---- the table covers every option ------------------------------------------------------------------------------

def _annotation(param):
    """The option's Python type: typer >= 0.26 keeps it on the parameter; older typer has click types."""
    desc = getattr(param, "type_descriptor", None)
    if desc is not None:
        return desc.annotation
    return {"integer": int, "integer range": int, "float": float, "float range": float,
            "text": str}.get(getattr(getattr(param, "type", None), "name", None))


#: a default that is a list of numbers ("0,0,0"), or a help text that says the value is one
_NUMBER_LIST_DEFAULT = re.compile(r"^\s*-?[\d.]+(\s*,\s*-?[\d.]*)+\s*$")
_NUMBER_LIST_HELP = re.compile(r"comma|'x,y,z'|X,Y,Z", re.IGNORECASE)


def _needs_a_row(param) -> bool:
    kind = _annotation(param)
    if kind in (int, float):
        return True
    if kind is str and param.opts and param.opts[0].startswith("--"):
        return bool(_NUMBER_LIST_DEFAULT.match(str(param.default or ""))
                    or _NUMBER_LIST_HELP.search(param.help or ""))
    return False


def test_every_numeric_option_has_a_row():
    covered = {(c, o) for c, o, *_ in RANGES}
    missing = [f"{name} {p.opts[0]}" for name, cmd in commands().items() for p in cmd.params
               if _needs_a_row(p) and (name, p.opts[0]) not in covered]
    assert not missing, ("numeric or number-list options without a row in RANGES (add their refused values, and a "
                         f"range check if they have none): {', '.join(missing)}")


def test_every_row_names_an_existing_option():
    every = commands()
    for command, option, *_ in RANGES:
        assert command in every, f"no command {command!r}"
        params = every[command].params
        names = {o for p in params for o in (p.opts or [])} | {p.name for p in params}
        assert option in names, f"{command} has no option {option}"


def test_help_texts_state_the_ranges(capsys):
    """The help of a ranged option says its range: typer's own "[x>=1]" for integers, the range in words for
    floats (ancf.clitools.number_range)."""
    for command in ("paper workspace", "paper dynamic", "simulate", "fem solve"):
        with pytest.raises(SystemExit):
            main([*command.split(), "--help"])
    out = " ".join(capsys.readouterr().out.split())
    for text in ("1<=x<=10000000", "0<=x<=4294967295", "2<=x<=50", "in (0, 1000] g", "a finite number > 0 ms",
                 "in (0, 1e+06] s", "in (0, 1e+06] MPa", "a finite number > 0 s"):
        assert text in out, text
