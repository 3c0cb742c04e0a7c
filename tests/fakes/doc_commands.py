"""The documented ``bellows control --rig <file>.toml`` commands and rig file, read from README.md and docs/rig.md,
and a run of the command on a bench of fakes (used by tests/test_hardware/test_doc_rig_command.py and
test_rig_recovery.py)."""

import contextlib
import pathlib
import re
import shlex

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[2]


def bash_commands(text: str) -> list:
    """The command lines of the ```bash blocks of a Markdown text: continuations joined, comments and
    optional [...] parts dropped."""
    out = []
    for block in re.findall(r"```bash\n(.*?)```", text, flags=re.S):
        joined = re.sub(r"\\\n\s*", " ", block)
        for line in joined.splitlines():
            line = re.sub(r"\s\[[^\]]*\]", "", line)                   # optional parts: [--force]
            words = shlex.split(line, comments=True)
            if words:
                out.append(words)
    return out


def rig_toml_commands(text: str) -> list:
    cmds = []
    for w in bash_commands(text):
        if w[:2] == ["bellows", "control"] and "--rig" in w and w[w.index("--rig") + 1].endswith(".toml"):
            cmds.append(w)
    return cmds


def documented_rig_file() -> str:
    """The example rig file of docs/rig.md (the ```toml block of "Rig files (TOML)")."""
    text = (ROOT / "docs/rig.md").read_text()
    section = text[text.index("## Rig files (TOML)"):]
    return re.search(r"```toml\n(.*?)```", section, flags=re.S).group(1)


class DocumentedCspRun:
    """The docs/rig.md ``bellows control --rig`` command (``--duration-s`` set, ``--json`` and ``extra`` added) on
    the documented rig file, its drives in cyclic synchronous position at ``sync_period_ms`` in another process
    (:class:`fakes.bench.ProcessModelBench`), started 1 mm off the IK lengths.  ``step``: the largest demand step
    per SYNC the rig file's speed allows [counts]."""

    def __init__(self, duration_s: float, extra=(), sync_period_ms: float = 5.0):
        import tomllib
        from ancf import Model, presets
        words = rig_toml_commands((ROOT / "docs/rig.md").read_text())[0]
        self.args = list(words[1:])
        self.args[self.args.index("--duration-s") + 1] = str(duration_s)
        self.args += ["--json", *extra]
        self.target = np.array([float(x) for x in self.opt("--target-mm").split(",")]) * 1e-3
        self.pressure = float(self.opt("--pressure-kpa")) * 1e3
        self.doc_rig = documented_rig_file()
        self.cfg = tomllib.loads(self.doc_rig)
        self.params = presets.get(self.cfg["actuator"])
        self.l_ik = Model(self.params).ik(self.target, self.pressure).tendon_lengths
        self.drive, self.sensor = self.cfg["drives"][0], self.cfg["force_sensors"][0]
        self.sync_period_ms = sync_period_ms
        self.step = self.cfg["speed_mm_per_s"] * self.drive["counts_per_mm"] * sync_period_ms * 1e-3

    def opt(self, name: str) -> str:
        return self.args[self.args.index(name) + 1]

    @contextlib.contextmanager
    def bench(self, tmp_path, monkeypatch):
        """The running bench, its rig file written under the command's name in ``tmp_path`` (the working folder)."""
        from fakes.bench import ProcessModelBench
        tracker = self.cfg["tracker"]
        with ProcessModelBench(self.params, counts_per_mm=self.drive["counts_per_mm"],
                               zero_length_mm=self.drive["zero_length_mm"], initial_lengths=self.l_ik + 1e-3,
                               force_scale_N_per_count=self.sensor["scale_N_per_count"],
                               rotation=tracker.get("rotation"), offset_mm=tracker.get("offset_mm", (0, 0, 0)),
                               sync_period_ms=self.sync_period_ms) as bench:
            (tmp_path / self.opt("--rig")).write_text(bench.rig_file(self.doc_rig))
            bench.start(self.pressure)
            monkeypatch.chdir(tmp_path)
            yield bench
