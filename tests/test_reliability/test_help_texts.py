"""--help tells the truth: every list of choices in a help text is exactly what the program accepts.

The lists are built from the code's registries; these tests read them back from the real command tree
(``bellows ... --help``) and compare them with the registries, so that a choice added, renamed or removed
in the code cannot leave a stale help text behind.
"""

import re

import pytest

from ancf import presets
from ancf.compliance import METHODS
from ancf.cli import LOCKED_METHODS
from fem_reference.mesh import MESH_LEVELS
from fem_reference.model import LINEAR_SOLVERS
from validation.commands.control import CONTROLLERS
from hardware.loads import PROFILES
from validation.identification.calibrate import GEOMETRY_PARAMETERS, MATERIAL_PARAMETERS
from validation.commands.main import main
from validation.reference.designs import PRESETS as DESIGNS
from validation.identification.forms import FORMS
from cli_commands import commands  # noqa: E402


COMMANDS = commands()


def _option(command: str, opt: str):
    for p in COMMANDS[command].params:
        if opt in getattr(p, "opts", []):
            return p
    raise AssertionError(f"{command} has no option {opt}")


def _listed(help_text: str) -> list:
    m = re.findall(r"\{([^{}]*)\}", help_text)
    assert len(m) == 1, f"expected one {{a | b}} list of choices in {help_text!r}"
    return m[0].split(" | ")


PRESET_COMMANDS = ["ik", "demo"] + [
    f"paper {c}" for c in ("workspace", "stiffness", "table1", "ablation", "loading", "tracking", "feedforward",
                           "all", "convergence", "loads")]

LISTS = [(c, "--preset", list(presets.NAMES)) for c in PRESET_COMMANDS] + [
    *[(c, "--preset", [*presets.NAMES, *presets.CHAIN_NAMES]) for c in ("params", "fk", "locked", "compliance")],
    ("locked", "--method", list(LOCKED_METHODS)),
    *[(c, "--design", list(DESIGNS)) for c in ("identify", "validate", "report", "calibrate")],
    *[(c, "--mesh", list(MESH_LEVELS)) for c in ("identify", "validate", "report", "calibrate")],
    *[(c, "--forms", list(FORMS)) for c in ("identify", "report")],
    ("calibrate", "--free", list(GEOMETRY_PARAMETERS + MATERIAL_PARAMETERS)),
    ("fem solve", "--solver", list(LINEAR_SOLVERS)),
    ("control", "--controller", list(CONTROLLERS)),
    ("control", "--compliance", list(METHODS)),
    ("control", "--load-profile", list(PROFILES)),
]


@pytest.mark.parametrize("command, opt, registry", LISTS, ids=[f"{c} {o}" for c, o, _ in LISTS])
def test_help_lists_exactly_the_accepted_values(command, opt, registry):
    assert _listed(_option(command, opt).help) == registry


@pytest.mark.parametrize("command, opt, registry", [("fem solve", "--mesh", list(MESH_LEVELS)),
                                                    ("fem solve", "--preset", list(DESIGNS)),
                                                    ("fem info", "--preset", list(DESIGNS))])
def test_fem_choices_are_the_registries(command, opt, registry):
    import click
    shown = _option(command, opt).get_help_record(click.Context(COMMANDS[command]))[0]   # "--mesh <a|b|c>"
    m = re.search(r"[<\[]([^<>\[\]]*\|[^<>\[\]]*)[>\]]", shown)
    assert m and m.group(1).split("|") == registry, shown


def test_report_quick_help_states_the_real_cost(capsys):
    with pytest.raises(SystemExit):
        main(["report", "--help"])
    out = " ".join(capsys.readouterr().out.split())
    # a measured cold time in minutes, and what a cached re-run costs (the old text promised "a few minutes")
    assert "few minutes" not in out and re.search(r"\d+(\.\d+)? min measured", out) and "seconds" in out
    assert "fine" not in out                          # the mesh levels are coarse, medium, reference
    assert "{" + " | ".join(MESH_LEVELS) + "}" in out


@pytest.mark.parametrize("args", [["calibrate", "--target-ea-n", "700", "--free", "kappa"],
                                  ["control", "--target-mm", "150,0,20", "--pressure-kpa", "30", "--compliance", "x"],
                                  ["locked", "--lengths-mm", "160,160,160", "--method", "newton"]])
def test_a_value_outside_the_listed_choices_is_rejected(capsys, tmp_path, args):
    with pytest.raises(SystemExit) as info:
        main(args + (["--out", str(tmp_path / "c.toml")] if args[0] == "calibrate" else []))
    assert info.value.code == 2 and capsys.readouterr().err.startswith("error: ")
