"""No result is overwritten without ``--force`` — for EVERY ``bellows`` command that writes files.

Each case pre-creates one of the command's outputs, replaces the command's first expensive step by a function
that fails the test, and checks: exit status 2, one ``error:`` line naming ``--force``, the file untouched.
The commands check their outputs before any work, so every case runs in well under a second.
"""

import pytest

from validation.commands.main import main


def _must_not_run(*a, **k):
    raise AssertionError("computed before the outputs were checked")


def run(capsys, args):
    with pytest.raises(SystemExit) as info:
        main([str(a) for a in args])
    out = capsys.readouterr()
    return info.value.code, out.err


# (command line with {d} for the output folder, the output file to pre-create (relative to {d}),
#  the expensive step that must not run: "module:attribute")
CASES = {
    "fk --vtu": (["fk", "--vtu", "{d}/s.vtu"], "s.vtu", "ancf.cli:warm_up"),
    "ik --vtu": (["ik", "--target-mm", "150,0,20", "--vtu", "{d}/s.vtu"], "s.vtu", "ancf.cli:warm_up"),
    "locked --vtu": (["locked", "--lengths-mm", "160,160,160", "--vtu", "{d}/s.vtu"], "s.vtu", "ancf.cli:warm_up"),
    "fk --vtu (chain)": (["fk", "--preset", "two_segment", "--vtu", "{d}/s.vtu"], "s.vtu", "ancf.cli:warm_up"),
    "locked --vtu (chain)": (["locked", "--preset", "two_segment", "--lengths-mm", "80,80,80,170,170,170", "--vtu",
                              "{d}/s.vtu"], "s.vtu", "ancf.cli:warm_up"),
    "demo": (["demo", "--out", "{d}"], "demo.png", "ancf.cli:run_demo"),
    "params --out": (["params", "--out", "{d}/a.toml"], "a.toml", "ancf.presets:get"),
    "fem solve --out": (["fem", "solve", "--out", "{d}"], "result.json", "fem_reference.model:BellowsModel"),
    "fem solve --png": (["fem", "solve", "--out", "{d}", "--png"], "result.png", "fem_reference.model:BellowsModel"),
    "paper workspace": (["paper", "workspace", "--samples", "10", "--out", "{d}"], "workspace.png",
                        "validation.paper.workspace_volume:run_tasks"),
    "paper stiffness": (["paper", "stiffness", "--out", "{d}"], "stiffness.json", "validation.paper.stiffness:Model"),
    "paper table1": (["paper", "table1", "--out", "{d}"], "table1.json", "validation.paper:_call_study"),
    "paper table1 figure": (["paper", "table1", "--out", "{d}"], "table1.png", "validation.paper:_call_study"),
    "paper ablation": (["paper", "ablation", "--out", "{d}"], "compliance_ablation.png",
                       "validation.paper:_call_study"),
    "paper loading": (["paper", "loading", "--out", "{d}"], "loading.json", "validation.paper:_call_study"),
    "paper tracking": (["paper", "tracking", "--out", "{d}"], "trajectories.json", "validation.paper:_call_study"),
    "paper feedforward": (["paper", "feedforward", "--out", "{d}"], "feedforward_loading.json",
                          "validation.paper:_call_study"),
    "paper all": (["paper", "all", "--samples", "10", "--out", "{d}"], "table1.png", "validation.paper:workspace"),
    "paper compare": (["paper", "compare", "--presets", "paper", "--out", "{d}"], "compare.png",
                      "validation.paper.comparison:run_preset"),
    "identify": (["identify", "--design", "straight_tube", "--out", "{d}"], "fit.json", "validation.identification.identify:from_fem"),
    "validate": (["validate", "--params", "paper", "--design", "straight_tube", "--out", "{d}"], "validation.json",
                 "validation.checks.compare:validate"),
    "report": (["report", "--design", "straight_tube", "--out", "{d}"], "report.html", "validation.identification.identify:from_fem"),
    "report figures": (["report", "--design", "straight_tube", "--out", "{d}"], "figures",
                       "validation.identification.identify:from_fem"),
    "calibrate": (["calibrate", "--target-ea-n", "700", "--out", "{d}/c.toml"], "c.toml",
                  "validation.identification.calibrate:calibrate"),
    "control --log": (["control", "--target-mm", "150,0,20", "--pressure-kpa", "30", "--log", "{d}/run.h5"], "run.h5",
                      "hardware.build:build_rig"),
    "experiment --log": (["experiment", "--states", "5", "--log", "{d}/exp.h5"], "exp.h5",
                         "validation.identification.experiment:design_experiment"),
    "fem profile --export": (["fem", "profile", "--export", "{d}/wall.csv"], "wall.csv",
                             "fem_reference.profile_export:export_profile"),
    "log export --csv": (["log", "export", "{d}/no_such_run.h5", "--csv", "{d}/s.csv"], "s.csv",
                         "hardware.runlog:read_run_log"),
    "modes": (["modes", "--out", "{d}"], "modes.png", "ancf.dynamics.cli:warm_up"),
    "simulate": (["simulate", "--tensions-n", "1,0,0", "--out", "{d}"], "simulation.csv", "ancf.dynamics.cli:warm_up"),
    "paper dynamic": (["paper", "dynamic", "--out", "{d}"], "dynamic_loading.json",
                      "validation.paper.dynamic:dynamic_loading"),
    "paper convergence": (["paper", "convergence", "--out", "{d}"], "convergence.svg",
                          "validation.paper.convergence:element_convergence"),
    "paper loads": (["paper", "loads", "--out", "{d}"], "loads.json", "validation.paper.loads:locked_drift"),
    "paper segments": (["paper", "segments", "--quick", "--out", "{d}"], "segments_obstacle.png",
                       "validation.paper.segments:run_tasks"),
}


@pytest.mark.parametrize("name", list(CASES))
def test_an_existing_output_is_kept_without_force(name, capsys, tmp_path, monkeypatch):
    args, existing, expensive = CASES[name]
    module, attr = expensive.split(":")
    monkeypatch.setattr(f"{module}.{attr}", _must_not_run)
    target = tmp_path / existing
    if existing == "figures":
        target.mkdir()
        (target / "forms.png").write_text("keep")
        target = target / "forms.png"
    else:
        target.write_text("keep")
    code, err = run(capsys, [a.format(d=tmp_path) for a in args])
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert code == 2 and len(lines) == 1 and lines[0].startswith("error: "), err
    assert "--force" in lines[0] and "Traceback" not in err
    assert target.read_text() == "keep"


def test_every_output_writing_command_is_covered():
    """A command that gains an output option must join CASES: every command with --force (or --out) is listed."""
    import typer

    from validation.commands.main import app

    def walk(cmd, prefix=()):
        if hasattr(cmd, "commands"):        # a group (typer may vendor its own click)
            for n, c in cmd.commands.items():
                yield from walk(c, prefix + (n,))
        else:
            yield " ".join(prefix), {o for p in cmd.params for o in getattr(p, "opts", [])}

    covered = {k.split(" --")[0].replace(" figures", "").replace(" figure", "") for k in CASES}
    writers = {name for name, opts in walk(typer.main.get_command(app)) if "--force" in opts}
    assert writers <= covered, sorted(writers - covered)
    assert {"paper table1", "paper tracking", "paper feedforward", "log export", "fk", "control"} <= writers
