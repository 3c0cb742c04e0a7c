"""``bellows control`` compiles the loop's kernels before the rig moves (validation.commands.control.compile_loop_kernels):
a live run must never stop for the numba compiler — on a fresh install the first saturation would otherwise
compile the bounded IK mid-run (tens of seconds with the load changing, and a Ctrl-C waiting for it)."""

import pytest

from kernel_signatures import grown, run_fresh

CHECK = """
    from ancf import Model, presets
    from controller import LACC, VFCC, RunOptions, run_on_rig
    from hardware import SimulatedRig
    from validation.commands.control import compile_loop_kernels

    which = sys.argv[1]
    compile_loop_kernels(controller=which)
    before = signatures()
    P = 30e3
    model = Model(presets.paper())
    target = model.fk((2.0, 1.0, 0.6), P).tip
    # 0.5 N along +y from 2 s to 4 s: the target is out of reach meanwhile (tests/test_controller/test_saturation.py)
    load = lambda t: np.array([0.0, 0.5, 0.0]) if 2.0 <= t < 4.0 else np.zeros(3)
    ctrl = LACC(model, P) if which == "lacc" else VFCC(model, P, law="integral")
    res = run_on_rig(ctrl, SimulatedRig(model, load=load), target, RunOptions(duration=5.0, idle_period=0.05,
                     sim_compute_time=0.0, log=sys.argv[2]))
    saturated = sum("reach" in s for s in res.saturation)
    print(json.dumps({"before": before, "after": signatures(), "saturated": saturated,
                      "corrections": res.iterations}))
"""


@pytest.mark.parametrize("controller", ["lacc", "vfcc"])
def test_a_run_after_the_warm_up_compiles_nothing(tmp_path, controller):
    """In a fresh interpreter: after compile_loop_kernels, a control run on the simulated rig with corrections and
    a saturated stretch (the bounded IK) adds no signature to any ancf kernel."""
    out = run_fresh(CHECK, controller, str(tmp_path / "run.h5"))
    assert out["saturated"] > 0 and out["corrections"] > 0           # the run did exercise both paths
    before, after = out["before"], out["after"]
    assert before.get("ancf.compiled_solvers.fk_newton", 0) >= 1     # the warm-up did compile (or load) them
    new = grown(before, after)
    assert not new, f"kernels compiled by the control run but not by the warm-up: {new}"


@pytest.mark.parametrize("which", ["four_tendon", "weak", "free_base_stretch"])
def test_the_warm_up_runs_on_any_actuator_inside_its_limits(which):
    """Its loads scale with the actuator's limits: it completes on four tendons, on an actuator with a tenth of the
    paper's pressure and a fifth of its tension range, and with the free base stretch (another reduced map)."""
    from ancf import presets
    from validation.commands.control import compile_loop_kernels
    params = {"four_tendon": presets.get("four_tendon"),
              "weak": presets.paper().replace(pressure_max=12e3, tension_max=1.0),
              "free_base_stretch": presets.paper().replace(free_base_stretch=True)}[which]
    assert compile_loop_kernels(params) is True
    assert compile_loop_kernels(params, controller="vfcc") is True


@pytest.mark.parametrize("kw", [dict(controller="pid"), dict(controller="vfcc", compliance="exact"),
                                dict(compliance="magic"), dict(params={"name": "paper"})])
def test_the_warm_up_refuses_bad_arguments_with_a_typed_error(kw):
    from ancf.errors import InputError
    from validation.commands.control import compile_loop_kernels
    with pytest.raises(InputError):
        compile_loop_kernels(**kw)
