"""``bellows control`` compiles the loop's kernels before the rig moves (validation.control_cli.compile_loop_kernels):
a live run must never stop for the numba compiler — on a fresh install the first saturation would otherwise
compile the bounded IK mid-run (tens of seconds with the load changing, and a Ctrl-C waiting for it)."""

import json
import os
import subprocess
import sys
import textwrap

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

CHECK = textwrap.dedent("""
    import json, sys, numpy as np
    from numba.core.registry import CPUDispatcher
    from ancf import Model, presets
    from controller import LACC, VFCC, run_on_rig
    from hardware import SimulatedRig
    from validation.control_cli import compile_loop_kernels

    def signatures():
        out = {}
        for name, mod in list(sys.modules.items()):
            if name.split(".")[0] != "ancf":
                continue
            for attr, obj in list(vars(mod).items()):
                if isinstance(obj, CPUDispatcher):
                    out[f"{name}.{attr}"] = len(obj.signatures)
        return out

    which = sys.argv[1]
    compile_loop_kernels(controller=which)
    before = signatures()
    P = 30e3
    model = Model(presets.paper())
    target = model.fk((2.0, 1.0, 0.6), P).tip
    # 0.5 N along +y from 2 s to 4 s: the target is out of reach meanwhile (tests/test_controller/test_saturation.py)
    load = lambda t: np.array([0.0, 0.5, 0.0]) if 2.0 <= t < 4.0 else np.zeros(3)
    ctrl = LACC(model, P) if which == "lacc" else VFCC(model, P, law="integral")
    res = run_on_rig(ctrl, SimulatedRig(model, load=load), target, duration=5.0, idle_period=0.05,
                     sim_compute_time=0.0, log=sys.argv[2])
    saturated = sum("reach" in s for s in res.saturation)
    print(json.dumps({"before": before, "after": signatures(), "saturated": saturated,
                      "corrections": res.iterations}))
""")


@pytest.mark.parametrize("controller", ["lacc", "vfcc"])
def test_a_run_after_the_warm_up_compiles_nothing(tmp_path, controller):
    """In a fresh interpreter: after compile_loop_kernels, a control run on the simulated rig with corrections and
    a saturated stretch (the bounded IK) adds no signature to any ancf kernel."""
    run = subprocess.run([sys.executable, "-c", CHECK, controller, str(tmp_path / "run.h5")], cwd=ROOT,
                         env={**os.environ, "PYTHONPATH": ROOT}, capture_output=True, text=True, timeout=600,
                         check=False)
    assert run.returncode == 0, run.stderr[-2000:]
    out = json.loads(run.stdout.strip().splitlines()[-1])
    assert out["saturated"] > 0 and out["corrections"] > 0           # the run did exercise both paths
    before, after = out["before"], out["after"]
    assert before.get("ancf.compiled_solvers.fk_newton", 0) >= 1     # the warm-up did compile (or load) them
    grown = {k: (before.get(k, 0), n) for k, n in after.items() if n > before.get(k, 0)}
    assert not grown, f"kernels compiled by the control run but not by the warm-up: {grown}"
