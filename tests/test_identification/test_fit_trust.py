"""What the fit may claim: identifiability is a property of the data (not of the fitted value), a fit without
spare degrees of freedom claims nothing, and intervals after freezing a parameter still cover the truth."""

import numpy as np
import pytest

from validation.experiments import default_design
from validation.fit import fit
from validation.forms import get_form

from test_fit import BASE, TRUE, synthetic

CASES = default_design().training[::2]


@pytest.mark.parametrize("name, param", [("paper", "a"), ("separate", "sA"), ("separate", "sI"),
                                         ("paper_area", "beta")])
def test_identifiability_does_not_depend_on_a_signed_value_near_zero(name, param):
    """A signed parameter whose true value is exactly 0, 1e-6 or its usual size: the same states determine it
    equally well, so the verdict is the same (and the same with 1e-7 m of noise)."""
    form = get_form(name)
    j = form.names.index(param)
    verdicts = []
    for value, noise in ((0.0, 0.0), (1e-6, 0.0), (TRUE[name][j], 0.0), (0.0, 1e-7)):
        theta = np.array(TRUE[name], float)
        theta[j] = value
        obs = synthetic(form, theta, CASES, noise=noise, seed=1)
        start = theta.copy()
        start[j] = 0.0
        res = fit(form, obs, BASE, start)
        verdicts.append(res.identifiable[param])
    assert verdicts == [verdicts[2]] * 4, verdicts
    assert verdicts[2], "these states determine the slope at its usual size"


@pytest.mark.parametrize("markers", [False, True])
def test_two_states_claim_nothing(markers):
    """Two states of the paper form's four parameters: an exact match is possible with wrong parameters, so
    every parameter and value is not identifiable (with the reason), no number carries an interval."""
    form = get_form("paper")
    theta = np.array(TRUE["paper"])
    design = default_design().training
    obs = synthetic(form, theta, [design[0], design[8]], noise=1e-5, seed=2)
    if not markers:
        obs.markers = obs.marker_s = obs.markers_std = None
    res = fit(form, obs, BASE, theta * np.array([1.1, 0.9, 1.05, 1.3]))
    assert not any(res.identifiable.values()), res.identifiable
    assert not any(res.values_identifiable.values())
    assert all(v is None for v in res.values.values()), res.values
    assert all(np.isnan(lo) and np.isnan(hi) for lo, hi in list(res.ci95.values()) + list(res.values_ci95.values()))
    assert all("too few" in res.reasons[nm] and "2 state" in res.reasons[nm] for nm in form.names)
