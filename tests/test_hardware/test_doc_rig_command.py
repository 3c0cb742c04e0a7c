"""The documented real-hardware command runs: every ``bellows control --rig <file>.toml ...`` line in the bash
blocks of README.md and docs/rig.md is run in-process against fake devices and must exit 0 and write its log.

How: the command is taken from the docs (backslash continuations joined, ``# comments`` and optional
``[...]`` parts dropped); the rig file is the documented example of docs/rig.md ("Rig files (TOML)"),
written under the name the command uses with one drive and force sensor per tendon and its devices
pointing at the fakes of :mod:`fakes.bench`: CiA 402 drives on python-can's virtual bus, pseudo-terminal
instruments and a NatNet stream whose tip (and tensions) follow the model's locked equilibrium for the
drives' positions.  The only substitution: ``--duration-s 60`` becomes ``--duration-s 2`` (DURATION_S).
The run must exit 0 genuinely: the controller converges on the tip the fakes report and holds it.
(The doc test that runs every other ``bellows`` command skips ``--rig *.toml`` commands and relies on this.)
"""

import json

import numpy as np
import pytest

pytest.importorskip("canopen")
pytest.importorskip("serial")

from fakes.doc_commands import ROOT, DocumentedCspRun, documented_rig_file, rig_toml_commands  # noqa: E402
from fakes.fixtures import quiet_canopen  # noqa: E402,F401  (fixture)

DOCS = ("README.md", "docs/rig.md")
DURATION_S = "2"


def test_the_extraction_finds_what_it_should():
    text = "```bash\nbellows control --rig a.toml --target-mm 1,2,3 \\\n    --pressure-kpa 60 [--force]  # note\n" \
           "bellows control --rig sim --target-mm 1,2,3\nbellows log show run.h5\n```\n```toml\nx = 1\n```\n"
    assert rig_toml_commands(text) == [["bellows", "control", "--rig", "a.toml", "--target-mm", "1,2,3",
                                        "--pressure-kpa", "60"]]
    for doc in DOCS:                                   # the docs do hold the command this test runs
        assert rig_toml_commands((ROOT / doc).read_text()), f"{doc}: no 'bellows control --rig *.toml' command"


def _cases():
    return [pytest.param(doc, cmd, id=f"{doc}:{i}") for doc in DOCS
            for i, cmd in enumerate(rig_toml_commands((ROOT / doc).read_text()))]


@pytest.mark.parametrize("doc, words", _cases())
def test_documented_hardware_command_runs_on_the_fake_bench(doc, words, tmp_path, monkeypatch, capsys, quiet_canopen):
    import tomllib
    from ancf import Model, presets
    from fakes.bench import ModelBench
    from hardware.runlog import read_run_log
    from validation.commands.main import main

    args = list(words[1:])
    if "--duration-s" in args:                          # the one documented substitution
        args[args.index("--duration-s") + 1] = DURATION_S
    args.append("--json")
    opt = lambda name: args[args.index(name) + 1]      # noqa: E731
    rig_name, log_name = opt("--rig"), opt("--log")
    target = np.array([float(x) for x in opt("--target-mm").split(",")]) * 1e-3
    pressure = float(opt("--pressure-kpa")) * 1e3

    doc_rig = documented_rig_file()
    cfg = tomllib.loads(doc_rig)
    assert cfg["backend"] == "hardware"
    params = presets.get(cfg["actuator"])
    l_ik = Model(params).ik(target, pressure).tendon_lengths
    drive, sensor = cfg["drives"][0], cfg["force_sensors"][0]
    with ModelBench(params, counts_per_mm=drive["counts_per_mm"], zero_length_mm=drive["zero_length_mm"],
                    initial_lengths=l_ik + 1e-3, force_scale_N_per_count=sensor["scale_N_per_count"],
                    rotation=cfg["tracker"].get("rotation"), offset_mm=cfg["tracker"].get("offset_mm", (0, 0, 0))
                    ) as bench:
        (tmp_path / rig_name).write_text(bench.rig_file(doc_rig))
        bench.start(pressure)                          # the tip where the drives stand (1 mm off the IK lengths)
        monkeypatch.chdir(tmp_path)
        with pytest.raises(SystemExit) as info:
            main(args)
        updates, errors = bench.updates, list(bench.errors)
    out, err = capsys.readouterr()
    assert info.value.code == 0, f"{doc}: bellows {' '.join(args)}\n{out}\n{err}"
    assert not errors and updates > 10
    res = json.loads(out.strip().splitlines()[-1])
    assert res["status"] == "held" and res["exit_status"] == 0
    sm = res["summary"]
    assert sm["met_tolerance"] and sm["periods_judged"] == 1 and not sm["load_changes_known"]
    assert sm["faults"] == []
    log = read_run_log(tmp_path / log_name)
    assert log.rows == res["samples"] > 5 and log.ended == "held" and log.summary["met_tolerance"]
    assert not log.attrs["rig"]["simulated"] and log.attrs["rig"]["drives"] == ["Epos4ProfileDrive"] * 3
    # the drives moved: from 1 mm off to the IK lengths, and the fake tip followed them to the target
    np.testing.assert_allclose(log.samples["position"][-1], l_ik, atol=2e-6)
    assert np.linalg.norm(log.samples["tip"][-1] - target) < 2e-4


def test_documented_hardware_command_in_csp_keeps_the_step_limit_beside_a_cpu_heavy_job(tmp_path, monkeypatch,
                                                                                         capsys, quiet_canopen):
    """The docs/rig.md command on the documented rig file with its drives in cyclic synchronous position, the
    drives in another process with their own SYNC clock (fakes.bench.ProcessModelBench), and a CPU-heavy job
    beside the loop (a busy thread, and this process's GIL held for 100 ms at a time, as a compiled kernel
    does): the run holds the target, and no SYNC moved a drive's demand by more than speed · sync period."""
    import threading
    import time
    from fakes.fixtures import hold_the_gil
    from validation.commands.main import main

    run = DocumentedCspRun(duration_s=3, extra=["--on-drive-fault", "stop"])
    drive = run.drive
    step = run.step
    stop = threading.Event()

    def cpu_heavy():
        while not stop.is_set():
            sum(i * i for i in range(50_000))
            hold_the_gil(0.1)                            # as a compiled kernel does
            time.sleep(0.2)
    with run.bench(tmp_path, monkeypatch) as bench:
        job = threading.Thread(target=cpu_heavy, daemon=True)
        job.start()
        try:
            with pytest.raises(SystemExit) as info:
                main(run.args)
        finally:
            stop.set()
            job.join(5.0)
        records = {n: bench.proc.records(n) for n in bench.nodes}
        errors = list(bench.errors)
    out, err = capsys.readouterr()
    assert info.value.code == 0, f"bellows {' '.join(run.args)}\n{out}\n{err}"
    assert not errors
    res = json.loads(out.strip().splitlines()[-1])
    assert res["status"] == "held" and res["summary"]["faults"] == []
    for n, recs in records.items():
        steps = [abs(r["step"]) for r in recs if r["state"] == "OPERATION ENABLED"]
        assert len(steps) > 100, n                        # SYNCs kept coming while the host was busy
        assert max(steps) <= step, (n, max(steps), step)
        moved_mm = abs(recs[-1]["demand"] - recs[0]["demand"]) / drive["counts_per_mm"]
        assert moved_mm > 0.5, n                          # it did move (from 1 mm off the IK lengths)
