"""A study that fails with a typed error (BellowsError) is reported as "not run"; a bug (any other exception)
propagates instead of being hidden as "not run"."""

import pytest

from ancf import presets
from ancf.errors import ConfigError
from validation.paper import comparison, states


def test_a_typed_failure_is_reported_and_a_bug_propagates():
    def typed():
        raise ConfigError("preset outside the study's range")

    def bug():
        raise TypeError("unsupported operand type(s)")

    res, err = comparison._guard(typed)
    assert res is None and err.startswith("not run: ConfigError")
    with pytest.raises(TypeError):
        comparison._guard(bug)


def test_reading_facts_reports_no_root_and_lets_a_bug_through(monkeypatch):
    prm = presets.paper()
    facts = states.reading_facts(prm, compression=1e9)           # beyond the law's limit: no root → NaN
    assert facts["stretch_under_compression"] != facts["stretch_under_compression"]
    law = type(prm.stiffness)

    def broken(self, force, lam0=1.0):
        if force < 0:
            raise ZeroDivisionError("a bug")
        return 1.0

    monkeypatch.setattr(law, "stretch_under_force", broken)
    with pytest.raises(ZeroDivisionError):
        states.reading_facts(prm)
