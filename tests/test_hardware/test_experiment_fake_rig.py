"""The identification experiment on the hardware path: the documented rig file (docs/rig.md) with its devices
pointing at the fakes (fakes.bench.ProcessModelBench: drives in cyclic synchronous position in another process,
which record every per-SYNC demand step; load cells, valves and tracker following the model's locked
equilibrium).  A small plan of 4 states: the log holds them with their standard errors, no drive saw a set-point
step above its limit, and a Ctrl-C while the rig settles keeps the states done — ``resume`` finishes the rest."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("canopen")
pytest.importorskip("serial")

from fakes.fixtures import quiet_canopen  # noqa: E402,F401  (fixture)

P = 40e3
TENSIONS = [(1.0, 1.0, 1.0), (2.0, 0.6, 0.6), (0.6, 2.0, 0.6), (0.6, 0.6, 2.0)]


def _plan(params):
    from validation.identification.experiment import ExperimentPlan, ExperimentState
    states = tuple(ExperimentState(t, P, 0.0, (0.0, 0.0, 0.0), f"state {i}") for i, t in enumerate(TENSIONS))
    return ExperimentPlan(states, "paper", 0.0, len(states), (0.0,), params.to_toml())


def test_an_experiment_on_the_fake_bench_is_bounded_and_resumes(tmp_path, monkeypatch, quiet_canopen):
    import tomllib
    from ancf import Model, presets
    from fakes.bench import ProcessModelBench
    from fakes.doc_commands import documented_rig_file
    from hardware.build import build_rig
    from hardware.config import RigConfig
    from hardware.errors import RunAborted
    from hardware.static_states import read_static_states
    import validation.identification.experiment_run as er

    doc = documented_rig_file()
    cfg = tomllib.loads(doc)
    params = presets.get(cfg["actuator"])
    drive, sensor, tracker = cfg["drives"][0], cfg["force_sensors"][0], cfg["tracker"]
    sync_ms = 5.0
    step_limit = cfg["speed_mm_per_s"] * drive["counts_per_mm"] * sync_ms * 1e-3        # counts per SYNC
    l0 = Model(params).fk(TENSIONS[0], P, (0.0, 0.0, 0.0)).tendon_lengths + 1e-3
    plan, log = _plan(params), tmp_path / "exp.h5"
    opts = er.ExperimentOptions(samples=3, settle_s=0.05, sample_period_s=0.02, tension_tolerance=0.05)
    loads = []                                   # the operator's answers: the tip is free (mass 0)

    reach = er._reach
    calls = {"n": 0}

    def ctrl_c_on_the_third(rig, model, st, o):
        calls["n"] += 1
        if calls["n"] == 3:
            raise KeyboardInterrupt              # Ctrl-C while the rig moves to and settles at state 2
        return reach(rig, model, st, o)

    with ProcessModelBench(params, counts_per_mm=drive["counts_per_mm"], zero_length_mm=drive["zero_length_mm"],
                           initial_lengths=l0, force_scale_N_per_count=sensor["scale_N_per_count"],
                           rotation=tracker.get("rotation"), offset_mm=tracker.get("offset_mm", (0, 0, 0)),
                           sync_period_ms=sync_ms) as bench:
        rig_file = tmp_path / "rig.toml"
        rig_file.write_text(bench.rig_file(doc))
        bench.start(P)
        rcfg = RigConfig.from_toml(rig_file)

        def tolerant(rig):
            # a host stalled by other jobs on a shared machine is not what this test is about (the drives'
            # silence and move supervision are tested in test_epos4_cyclic.py / test_rig_recovery.py)
            for d in rig.drives:
                d.pdo_timeout = 2.0
            rig.move_timeout = max(rig.move_timeout, 10.0)
            return rig
        monkeypatch.setattr(er, "_reach", ctrl_c_on_the_third)
        with pytest.raises(RunAborted, match="--resume"):
            with tolerant(build_rig(rcfg)) as rig:
                er.run_experiment(plan, rig, params, log, options=opts,
                                  change_load=lambda m, f: loads.append(m))
        assert read_static_states(log).label == ["state 0", "state 1"]
        monkeypatch.setattr(er, "_reach", reach)
        with tolerant(build_rig(rcfg)) as rig:
            res = er.run_experiment(plan, rig, params, log, options=opts, resume=True,
                                    change_load=lambda m, f: loads.append(m))
        records = {n: bench.proc.records(n) for n in bench.nodes}
        events = {n: bench.proc.events(n) for n in bench.nodes}
    assert res.status == "completed" and res.recorded == 2 and res.done == 4
    st = read_static_states(log)
    assert st.label == [f"state {i}" for i in range(4)]
    for name in ("tensions_std", "pressure_std", "tip_position_std"):
        v = np.asarray(getattr(st, name), float)
        assert np.all(np.isfinite(v)) and np.all(v >= er.SE_FLOOR[name]), (name, v)
    assert np.allclose(st.pressure, P, rtol=0.05)
    assert np.all(np.abs(st.tensions - np.array(TENSIONS)) <= 0.2), st.tensions
    assert loads == [0.0, 0.0]                                    # asked once per run: the tip free
    for n, recs in records.items():                               # bounded set-points on every drive
        steps = [abs(r["step"]) for r in recs if r["state"] == "OPERATION ENABLED"]
        assert steps and max(steps) <= step_limit, (n, max(steps), events[n])
