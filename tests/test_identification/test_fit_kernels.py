"""compile_fit_kernels, run in the background while the FEM sweep runs, must compile every numba signature
the fits use: otherwise the first run of a fresh install waits for the compiler after the sweep."""

from kernel_signatures import grown, run_fresh

CHECK = """
    from ancf import presets
    from validation.reference.experiments import default_design
    from validation.identification.fit import Observations, _Evaluator, predict
    from validation.identification.forms import get_form
    from validation.identification.identify import compile_fit_kernels

    compile_fit_kernels()
    before = signatures()
    form = get_form("pressure_ei")
    base = presets.paper().replace(gravity=(0.0, 0.0, 0.0))
    cases = default_design().training[::4]
    obs = Observations([c.tensions for c in cases], [c.pressure for c in cases], [c.tip_force for c in cases],
                       [False] * len(cases), np.zeros((len(cases), 3)), labels=[c.label for c in cases])
    theta = np.array([700.0, 900.0, 0.09, 0.15, 0.8, 0.3, 0.024])
    obs.tip = predict(form.to_params(theta, base), obs)[:, :3]
    _Evaluator(form, obs, base).evaluate(theta * 1.01, jacobian=True)
    after = signatures()
    print(json.dumps({"before": before, "after": after}))
"""


def test_the_background_compile_covers_every_kernel_signature_of_a_fit():
    """In a fresh interpreter: after compile_fit_kernels, one fit evaluation (FK from cold and warm starts, the
    exact Jacobian, the pressure sensitivity) adds no signature to any ancf kernel."""
    out = run_fresh(CHECK)
    before, after = out["before"], out["after"]
    assert before.get("ancf.compiled_solvers.fk_newton") == 1          # it did compile (or load) the FK loop
    new = grown(before, after)
    assert not new, f"kernels compiled by the fit but not by compile_fit_kernels: {new}"
