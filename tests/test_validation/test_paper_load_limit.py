"""A load beyond what the actuator carries: the FK's error says so, at what fraction of the load the equilibrium
path ended and where the tip was (the `bellows fk` example of a 50 N tip load on the default preset)."""

import re

import numpy as np
import pytest

from ancf import ConvergenceError, Model, presets
from validation.commands.main import main

PATTERN = (r"ends at ([\d.]+) % of the asked load.*last converged state at load factor ([\d.]+): .*"
           r"F = \(([-\d., ]+)\) N, weight × [\d.]+, tip at \(([-\d., ]+)\) mm")


def test_fk_cli_names_the_load_fraction_and_the_last_tip(capsys):
    with pytest.raises(SystemExit) as info:
        main(["fk", "--tip-force-n", "0,0,-50"])
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert info.value.code == 2 and len(err) == 1 and err[0].startswith("error: ")
    assert "beyond what the actuator can carry" in err[0]
    m = re.search(PATTERN, err[0])
    assert m, err[0]
    pct, s = float(m.group(1)), float(m.group(2))
    assert 0 < s < 1 and pct == pytest.approx(100 * s, abs=0.01)
    F = np.array([float(v) for v in m.group(3).split(",")])
    assert F == pytest.approx([0.0, 0.0, -50.0 * s], abs=3e-3)          # the load reached [N] (s has 4 decimals)


def test_the_reported_state_is_the_equilibrium_at_that_fraction_of_the_load():
    """Independent check of the reported tip: the same actuator with every load (tip force, weight) scaled by the
    reported factor — gravity itself scaled, an input the message does not depend on — solved from scratch."""
    prm = presets.paper()
    F = np.array([0.0, 0.0, -50.0])
    with pytest.raises(ConvergenceError) as info:          # the type is kept
        Model(prm).fk((0, 0, 0), 0.0, F)
    m = re.search(PATTERN, str(info.value))
    assert m, str(info.value)
    s = float(m.group(2))
    tip_mm = np.array([float(v) for v in m.group(4).split(",")])
    scaled = Model(prm.replace(gravity=tuple(s * np.asarray(prm.gravity))))
    eq = scaled.fk((0, 0, 0), 0.0, s * F)
    assert eq.tip * 1e3 == pytest.approx(tip_mm, abs=0.02)                 # printed with 2 decimals [mm]
    assert np.linalg.norm(eq.tip) > 0.1                                      # a real, bent state, not the origin
