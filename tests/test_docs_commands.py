"""Every ``bellows …`` command shown in README.md and docs/*.md runs and exits 0 on the default preset.

The commands are read from the documents' fenced code blocks (so the test follows the docs; nothing is
copied here): backslash continuations are joined, ``# comments`` and optional ``[...]`` parts dropped,
``pip install … && bellows …`` keeps its ``bellows`` part.  Each command runs as a subprocess in a fresh
temporary folder holding the input files it names, made by the documented command that writes them
(``bellows log show run.h5`` gets the log of the documented ``control … --log run.h5``): exit status 0 and
no traceback; where a document says what a command reports, ``SAYS`` checks its output holds it (and
``SAYS_NOT`` that it holds none of what a document says it does not report).

What the test changes, and only this (docs/README.md says so too):

* a command shown in several documents runs once, and a command whose outputs a later command reads runs once
  too (its own case's outputs are that command's inputs);
* ``SHORTER``: long runs get a documented short option (fewer workspace samples, a duration for a run that
  otherwise holds until Ctrl-C, the simulated rig as fast as it computes);
* ``FILES``: input files a document names but no command of it writes (a design file) are made from the
  format's own example (or the walkthrough's), with the files they name (a design's profile table, made by the
  documented command that writes it);
* commands that drive real hardware (``--rig FILE.toml``) run in tests/test_hardware/test_doc_rig_command.py
  against fake devices;
* commands that run FEM sweeps (``report``, ``identify``/``validate`` on the FEM, ``calibrate``; ~4–25 min
  each on 2 cores) are marked ``slow`` (``pytest -m slow``), and so are the commands whose input files one of
  them makes (a walkthrough's later steps); the default run checks that the options of the sweeps exist in the
  command's help — see ``test_fem_sweep_commands_parse``.
"""

from __future__ import annotations

import pathlib
import re
import shlex
import shutil
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]

# long runs: (pattern, replacement) applied to the command line, in order
SHORTER = [
    (r"--samples \d+", "--samples 200"),                                        # workspace Monte Carlo
    (r"^(bellows paper (all|workspace))(?!.*--samples)", r"\1 --samples 200"),
    (r"^(bellows paper compare)(?!.*--samples)", r"\1 --samples 200 --seeds 0 --presets paper --no-control"),
    (r"^(bellows control --rig sim)(?!.*--duration-s)(?!.*--max-iterations)", r"\1 --duration-s 6"),
    (r"^(bellows control --rig sim)(?!.*--fast)", r"\1 --fast"),
    (r"^(bellows paper dynamic)(?!.*--frequencies-hz)", r"\1 --frequencies-hz 2"),  # one load frequency
    (r"^(bellows paper dynamic)(?!.*--cycles)", r"\1 --cycles 2"),              # the fewest cycles (one judged)
    # one model form instead of all nine (~30 s instead of 3–8 min on 2 cores; each form goes through the same
    # fit, and tests/test_identification/ fits several forms to measured states)
    (r"^(bellows identify --measurements\b(?!.*--forms).*)$", r"\1 --forms paper"),
]
# what the docs say a command reports: (pattern of the command, words its output must hold)
SAYS = [
    # README: the 20 s control log (one pressure, one tip point) identifies nothing, and the command says why
    (r"^bellows identify --measurements run\.h5", ("one point", "one pressure", "refused")),
    # the walkthrough: the identified lab model, checked for a misfit (and, where a document says so, that
    # there was none): SAYS_NOT
]
# what the docs say a command does not report: (pattern of the command, words its output must not hold)
SAYS_NOT = [
    # the walkthrough: the lab model fits the simulated rig's states within their stated noise — no warning
    (r"^bellows identify --measurements lab_exp\.h5", ("warning:", "does not fit")),
]
# FEM sweeps: slow
FEM_SWEEP = re.compile(r"^bellows (report|validate|calibrate)(?![-\w])|^bellows identify(?![-\w])(?!.*--measurements)")
# real hardware: tests/test_hardware/test_doc_rig_command.py
HARDWARE = re.compile(r"--rig\s+\S+\.toml")


def _design_example() -> str:
    """The design-file example of docs/data-formats.md (the format's documentation: the `paper` design)."""
    text = (ROOT / "docs" / "data-formats.md").read_text()
    section = text.split("## FEM bellows designs", 1)[1]
    return re.search(r"```toml\n(.*?)```", section, re.S).group(1)


def _walkthrough_design() -> str:
    """The design file of docs/walkthrough.md (its first TOML block), which names the profile table of step 1."""
    return re.search(r"```toml\n(.*?)```", (ROOT / "docs" / "walkthrough.md").read_text(), re.S).group(1)


FILES = {"my_bellows.toml": _design_example, "lab_bellows.toml": _walkthrough_design}
#: a file that a FILES entry names inside it (a design's profile table) is provided beside it
COMPANION = re.compile(r'^profile_file\s*=\s*"([^"]+)"', re.M)


def doc_commands(path: pathlib.Path) -> list[str]:
    """The ``bellows`` command lines of a markdown file's fenced code blocks, cleaned as the module says."""
    out = []
    for block in re.findall(r"^```[a-z]*\n(.*?)^```", path.read_text(), re.S | re.M):
        text = block.replace("\\\n", " ")
        for line in text.splitlines():
            line = line.split(" #", 1)[0].strip()
            if "bellows " not in line or line.startswith(("from ", "import ", "#", ">>>")):
                continue
            line = line[line.index("bellows "):] if "&& bellows " in line else line
            if not line.startswith("bellows "):
                continue
            line = re.sub(r"\s*\[[^\]]*\]", "", line)
            out.append(" ".join(line.split()))
    return out


def shortened(cmd: str) -> str:
    for pattern, repl in SHORTER:
        cmd = re.sub(pattern, repl, cmd)
    return cmd


def needs_fem_sweep(cmd: str, writers: dict, seen: frozenset = frozenset()) -> bool:
    """A FEM sweep, or a command whose inputs are made by one (a walkthrough's later steps): ``slow``."""
    if FEM_SWEEP.search(cmd):
        return True
    tops = {name.split("/", 1)[0] for name in inputs_of(cmd)}
    return any(writers[t] not in seen and needs_fem_sweep(writers[t], writers, seen | {cmd})
               for t in tops if t in writers and writers[t] != cmd)


def _cases():
    seen = set()
    writers = producers()
    for path in DOCS:
        for k, cmd in enumerate(doc_commands(path)):
            if cmd in seen:             # the same command in two documents runs once
                continue
            seen.add(cmd)
            marks = [pytest.mark.slow] if needs_fem_sweep(cmd, writers) else []
            if HARDWARE.search(cmd):
                marks = [pytest.mark.skip(reason="real hardware: runs in test_doc_rig_command.py on fake devices")]
            yield pytest.param(path.name, k, cmd, marks=marks, id=f"{path.name}:{k}:{cmd[:60]}")



def run_bellows(cmd: str, cwd: pathlib.Path, timeout: float = 900) -> subprocess.CompletedProcess:
    argv = shlex.split(shortened(cmd))
    assert argv[0] == "bellows"
    return subprocess.run([sys.executable, "-m", "validation.commands.main", *argv[1:]], cwd=cwd, capture_output=True,
                          text=True, timeout=timeout, env=_env(cwd))


def _env(cwd: pathlib.Path) -> dict:
    import os
    env = dict(os.environ)
    env["BELLOWS_TRACEBACK_DIR"] = str(cwd / "tracebacks")
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), env.get("PYTHONPATH", "")])
    return env


OUTPUT_OPTIONS = ("--out", "--log", "--csv", "--vtu", "--export")


def outputs_of(cmd: str) -> list[str]:
    """The files/folders a command writes (values of its output options)."""
    argv = shlex.split(cmd)
    return [argv[i + 1] for i, a in enumerate(argv[:-1]) if a in OUTPUT_OPTIONS]


def inputs_of(cmd: str) -> list[str]:
    """Arguments that name input files (a .h5/.toml/.csv path, or a file inside a folder) — not outputs."""
    argv = shlex.split(cmd)
    outs = set(outputs_of(cmd))
    return [a for a in argv[1:] if not a.startswith("-") and a not in outs and re.search(r"\.(h5|toml|csv)$", a)]


def producers() -> dict[str, str]:
    """Which documented command writes each file or folder the docs name (the first one shown)."""
    out: dict[str, str] = {}
    for path in DOCS:
        for cmd in doc_commands(path):
            for o in outputs_of(cmd):
                out.setdefault(o.rstrip("/"), cmd)
    return out


CASES = list(_cases())


@pytest.fixture(scope="module")
def artifacts(tmp_path_factory):
    """``provide(name, dest)``: puts the input file ``name`` into folder ``dest`` — from FILES, or made once by
    the documented command that writes it (run in a folder of its own, its own inputs provided the same way)."""
    made: dict[str, pathlib.Path] = {}
    writers = producers()

    def provide(name: str, dest: pathlib.Path) -> None:
        target = dest / name
        if target.exists():
            return
        target.parent.mkdir(parents=True, exist_ok=True)
        if name in FILES:
            target.write_text(FILES[name]())
            for companion in COMPANION.findall(target.read_text()):
                provide(companion, dest)
            return
        top = name.split("/", 1)[0] if "/" in name else name
        if top not in writers:
            return                                   # not made by any command: the command itself will say so
        if top not in made:
            d = tmp_path_factory.mktemp("made")
            cmd = writers[top]
            for need in inputs_of(cmd):
                provide(need, d)
            res = run_bellows(cmd, d)
            assert res.returncode == 0, f"making {top} with {cmd!r} failed:\n{res.stdout[-2000:]}\n{res.stderr[-2000:]}"
            made[top] = d / top
        src = made[top] if top == name else made[top] / name.split("/", 1)[1]
        shutil.copy2(src, target) if src.is_file() else shutil.copytree(src, target)
    provide.made = made          # also filled by test_doc_command_runs: a documented command runs only once
    return provide


def test_the_docs_show_commands():
    """The extraction finds the README's main command and the commands of every section that has some."""
    readme = doc_commands(ROOT / "README.md")
    assert readme[0] == "bellows report --quick"
    assert any(c.startswith("bellows control --rig sim") for c in readme)
    assert any(c.startswith("bellows report --quick") for c in readme)
    assert "bellows fk --tensions-n 2,0,0 --pressure-kpa 30 --tip-force-n 0,0,-0.49" in readme  # [...] dropped
    assert len(CASES) >= 20


def test_ci_runs_the_readme_commands():
    """.ci/run runs the README's two commands: the main job with its own install, and the tests."""
    blocks = re.findall(r"^```bash\n(.*?)^```", (ROOT / "README.md").read_text(), re.S | re.M)
    main, tests = blocks[0].strip(), blocks[1].strip()
    assert main == 'pip install -e ".[pardiso]" && bellows report --quick'
    assert tests == "pip install -e .[test] && pytest"
    ci = (ROOT / ".ci" / "run").read_text()
    assert 'pip install --quiet -e "$repo[pardiso]" && bellows report --quick' in ci
    assert "\npip install -e .[test] && pytest\n" in ci


def test_the_test_install_has_the_plugins_the_default_run_uses():
    """pyproject's addopts run the suite on pytest-xdist (``-n``/``--dist``): the ``[test]`` extra installs it, so
    that the README's ``pip install -e .[test] && pytest`` works in a clean environment."""
    import tomllib
    cfg = tomllib.loads((ROOT / "pyproject.toml").read_text())
    addopts = shlex.split(cfg["tool"]["pytest"]["ini_options"]["addopts"])
    extra = {re.split(r"[<>=!~\[; ]", req, maxsplit=1)[0].lower()
             for req in cfg["project"]["optional-dependencies"]["test"]}
    if "-n" in addopts or any(a.startswith(("--dist", "--numprocesses")) for a in addopts):
        assert "pytest-xdist" in extra, "addopts use pytest-xdist but the [test] extra does not install it"
    assert "pytest" in extra


@pytest.mark.parametrize("doc, index, cmd", CASES)
def test_doc_command_runs(artifacts, tmp_path, doc, index, cmd):
    """Each command in a fresh folder holding only the inputs it names."""
    cwd = tmp_path
    for name in inputs_of(cmd):
        artifacts(name, cwd)
    res = run_bellows(cmd, cwd)
    assert res.returncode == 0, f"{shortened(cmd)}\nexit {res.returncode}\n{res.stdout[-3000:]}\n{res.stderr[-3000:]}"
    assert "Traceback" not in res.stderr + res.stdout
    for pattern, words in SAYS_NOT:
        if re.search(pattern, cmd):
            assert not any(w in res.stdout + res.stderr for w in words), f"{cmd}: the docs say it prints none of {words}"
    for pattern, words in SAYS:
        if re.search(pattern, cmd):
            assert all(w in res.stdout + res.stderr for w in words), f"{cmd}: the docs say it prints {words}"
    keep_outputs(artifacts.made, cmd, cwd)


def keep_outputs(made: dict, cmd: str, cwd: pathlib.Path) -> None:
    """The files a documented command wrote in ``cwd`` serve later commands as their inputs (``made``), where it
    is the command the docs make them with: it does not run a second time to make them."""
    writers = producers()
    for out in outputs_of(cmd):
        top = out.rstrip("/")
        if writers.get(top) == cmd and (cwd / top).exists():
            made.setdefault(top, cwd / top)


@pytest.mark.parametrize("cmd", sorted({c.values[2] for c in CASES if FEM_SWEEP.search(c.values[2])}))
def test_fem_sweep_commands_parse(cmd):
    """The FEM-sweep commands of the docs name real options and values (their full runs are ``slow``)."""
    from typer.testing import CliRunner

    from validation.commands.main import app
    argv = shlex.split(cmd)[1:]
    res = CliRunner().invoke(app, [*argv, "--help"])
    assert res.exit_code == 0, res.output
    # every option the doc gives exists in the subcommand's help
    for opt in (a for a in argv if a.startswith("--")):
        assert opt in res.output, f"{cmd}: {opt} is not an option of 'bellows {argv[0]}'"


def test_what_counts_as_a_fem_sweep():
    """Sweeps and the steps that need their outputs are slow; a command named like a sweep but not one is not."""
    writers = {"lab": "bellows report --quick --out lab", "decay": "bellows simulate --out decay"}
    assert needs_fem_sweep("bellows report --quick --out lab", writers)
    assert needs_fem_sweep("bellows control --rig sim --actuator lab/actuator.toml --log run.h5", writers)
    assert not needs_fem_sweep("bellows identify-damping decay/simulation.csv", writers)
    assert not needs_fem_sweep("bellows identify --measurements run.h5", writers)
    assert needs_fem_sweep("bellows identify --design paper", writers)


def test_a_documented_commands_outputs_serve_the_later_commands(tmp_path):
    """The file a documented command wrote in its own case is kept as the input of the later ones (it does not
    run again to make it); a command that is not the one the docs make the file with leaves it alone."""
    writer = producers()["run.h5"]
    (tmp_path / "run.h5").write_bytes(b"")
    made: dict = {}
    keep_outputs(made, "bellows control --rig sim --target-mm 1,2,3 --log run.h5", tmp_path / "elsewhere")
    assert made == {}
    keep_outputs(made, writer, tmp_path / "missing")             # wrote nothing there: nothing kept
    assert made == {}
    keep_outputs(made, writer, tmp_path)
    assert made == {"run.h5": tmp_path / "run.h5"}
