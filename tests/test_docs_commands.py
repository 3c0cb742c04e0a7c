"""Every ``bellows …`` command shown in README.md and docs/*.md runs and exits 0 on the default preset.

The commands are read from the documents' fenced code blocks (so the test follows the docs; nothing is
copied here): backslash continuations are joined, ``# comments`` and optional ``[...]`` parts dropped,
``pip install … && bellows …`` keeps its ``bellows`` part.  Each document's commands run in its own
temporary folder, in the order the document shows them (``bellows log show run.h5`` reads the log the
``control`` line above it wrote), each as a subprocess: exit status 0 and no traceback.

What the test changes, and only this (docs/README.md says so too):

* ``SHORTER``: long runs get a documented short option (fewer workspace samples, a duration for a run that
  otherwise holds until Ctrl-C, the simulated rig as fast as it computes);
* ``FILES``: input files a document names but no command of it writes (a design file) are made from the
  format's own example;
* commands that drive real hardware (``--rig FILE.toml``) run in tests/test_hardware/test_doc_rig_command.py
  against fake devices;
* commands that run FEM sweeps (``report``, ``identify``/``validate`` on the FEM, ``calibrate``; ~4–25 min
  each on 2 cores) are marked ``slow`` (``pytest -m slow``); the default run checks that they parse and pass
  their up-front checks with ``--help`` replaced by nothing else — see ``test_fem_sweep_commands_parse``.
"""

from __future__ import annotations

import pathlib
import re
import shlex
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
]
# FEM sweeps: slow
FEM_SWEEP = re.compile(r"^bellows (report|validate|calibrate)\b|^bellows identify\b(?!.*--measurements)")
# real hardware: tests/test_hardware/test_doc_rig_command.py
HARDWARE = re.compile(r"--rig\s+\S+\.toml")


def _design_example() -> str:
    """The design-file example of validation/designs.py's docstring (the format's documentation)."""
    import validation.designs as designs
    doc = designs.__doc__
    block = doc.split("::", 1)[1].split("\n\n", 2)
    return "\n".join(line[4:] for line in "\n\n".join(block[:2]).splitlines() if line.startswith("    ") or not line)


FILES = {"my_bellows.toml": _design_example}


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


def _cases():
    for path in DOCS:
        for k, cmd in enumerate(doc_commands(path)):
            marks = [pytest.mark.slow] if FEM_SWEEP.search(cmd) else []
            if HARDWARE.search(cmd):
                marks = [pytest.mark.skip(reason="real hardware: runs in test_doc_rig_command.py on fake devices")]
            yield pytest.param(path.name, k, cmd, marks=marks, id=f"{path.name}:{k}:{cmd[:60]}")


CASES = list(_cases())


def run_bellows(cmd: str, cwd: pathlib.Path, timeout: float = 900) -> subprocess.CompletedProcess:
    argv = shlex.split(shortened(cmd))
    assert argv[0] == "bellows"
    return subprocess.run([sys.executable, "-m", "validation.cli", *argv[1:]], cwd=cwd, capture_output=True,
                          text=True, timeout=timeout, env=_env(cwd))


def _env(cwd: pathlib.Path) -> dict:
    import os
    env = dict(os.environ)
    env["BELLOWS_TRACEBACK_DIR"] = str(cwd / "tracebacks")
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), env.get("PYTHONPATH", "")])
    return env


@pytest.fixture(scope="module")
def workdirs(tmp_path_factory):
    """One folder per document; the commands before a command (in document order) have run in it."""
    state: dict[str, tuple[pathlib.Path, int]] = {}

    def get(doc: str, upto: int) -> pathlib.Path:
        if doc not in state:
            d = tmp_path_factory.mktemp(doc.replace(".", "_"))
            for name, make in FILES.items():
                (d / name).write_text(make())
            state[doc] = (d, 0)
        d, done = state[doc]
        state[doc] = (d, max(done, upto + 1))
        return d
    return get


def test_the_docs_show_commands():
    """The extraction finds the README's main command and the commands of every section that has some."""
    readme = doc_commands(ROOT / "README.md")
    assert readme[0] == "bellows demo"
    assert any(c.startswith("bellows control --rig sim") for c in readme)
    assert any(c.startswith("bellows report --quick") for c in readme)
    assert "bellows fk --tensions-n 2,0,0 --pressure-kpa 30 --tip-force-n 0,0,-0.49" in readme  # [...] dropped
    assert len(CASES) >= 30


@pytest.mark.parametrize("doc, index, cmd", CASES)
def test_doc_command_runs(workdirs, doc, index, cmd):
    cwd = workdirs(doc, index)
    res = run_bellows(cmd, cwd)
    assert res.returncode == 0, f"{shortened(cmd)}\nexit {res.returncode}\n{res.stdout[-3000:]}\n{res.stderr[-3000:]}"
    assert "Traceback" not in res.stderr + res.stdout


@pytest.mark.parametrize("cmd", sorted({c.values[2] for c in CASES if FEM_SWEEP.search(c.values[2])}))
def test_fem_sweep_commands_parse(cmd):
    """The FEM-sweep commands of the docs name real options and values (their full runs are ``slow``)."""
    from typer.testing import CliRunner

    from validation.cli import app
    argv = shlex.split(cmd)[1:]
    res = CliRunner().invoke(app, [*argv, "--help"])
    assert res.exit_code == 0, res.output
    sub = app
    # every option the doc gives exists in the subcommand's help
    for opt in (a for a in argv if a.startswith("--")):
        assert opt in res.output, f"{cmd}: {opt} is not an option of 'bellows {argv[0]}'"
    assert sub is app
