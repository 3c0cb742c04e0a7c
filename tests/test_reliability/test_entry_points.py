"""Every public entry point of the ANCF model checks shape, dtype and finiteness before a compiled kernel
sees an array: a coordinate vector of a model with another element count, a string, a boolean, NaN or a
ragged list raises :class:`InputError` (never garbage, never a crashed interpreter)."""

import subprocess
import sys
import textwrap

import numpy as np
import pytest

from ancf import Model, presets
from ancf import compliance as cp
from ancf.errors import BellowsError, CollapsedStateError, InputError


@pytest.fixture(scope="module")
def models():
    return Model(presets.paper()), Model(presets.paper().replace(n_elements=4))


def _q_methods(m):
    return {
        "evaluate": lambda q: m.evaluate(q),
        "residual": lambda q: m.residual(q),
        "tangent": lambda q: m.tangent(q),
        "dQ_dT": lambda q: m.dQ_dT(q),
        "dQ_dp": lambda q: m.dQ_dp(q),
        "dQ_dF": lambda q: m.dQ_dF(q),
        "tendon_lengths": lambda q: m.tendon_lengths(q),
        "tendon_jacobian": lambda q: m.tendon_jacobian(q),
        "tip": lambda q: m.tip(q),
        "tip_jacobian": lambda q: m.tip_jacobian(q),
        "tip_rotation": lambda q: m.tip_rotation(q),
        "tip_angular_jacobian": lambda q: m.tip_angular_jacobian(q),
        "centreline": lambda q: m.centreline(q),
        "tendon_paths": lambda q: m.tendon_paths(q),
        "to_free": lambda q: m.to_free(q),
        "stretches": lambda q: m.stretches(q),
        "fk(q0)": lambda q: m.fk((1.0, 0, 0), 0.0, q0=q),
        "ik(q0)": lambda q: m.ik((0.15, 0.0, 0.0), 0.0, q0=q),
        "fk_locked(q0)": lambda q: m.fk_locked((0.16, 0.16, 0.16), 0.0, q0=q),
    }


BAD_Q = {
    "other element count": lambda m, other: other.q_ref,
    "too short by one": lambda m, other: m.q_ref[:-1],
    "2-D": lambda m, other: m.q_ref[None, :],
    "NaN": lambda m, other: np.where(np.arange(m.ndof) == 10, np.nan, m.q_ref),
    "inf": lambda m, other: np.where(np.arange(m.ndof) == 7, np.inf, m.q_ref),
    "text": lambda m, other: "q",
    "booleans": lambda m, other: np.ones(m.ndof, bool),
    "complex": lambda m, other: m.q_ref + 0j,
    "ragged": lambda m, other: [[1.0, 2.0], [3.0]],
    "None inside": lambda m, other: [None] * m.ndof,
}


@pytest.mark.parametrize("bad", sorted(BAD_Q))
def test_every_q_entry_point_rejects_bad_coordinates(models, bad):
    m, other = models
    q = BAD_Q[bad](m, other)
    for name, call in _q_methods(m).items():
        with pytest.raises(InputError):
            call(q)
            pytest.fail(f"{name} accepted {bad}")


def test_scalar_and_vector_arguments_are_checked(models):
    m, _ = models
    q = m.q_ref
    cases = [
        lambda: m.evaluate(q, tensions=(1.0, 2.0)),                   # wrong tendon count
        lambda: m.evaluate(q, pressure="30e3"),                       # text where a number belongs
        lambda: m.evaluate(q, pressure=True),                         # boolean where a number belongs
        lambda: m.evaluate(q, tip_force=(0, 0)),
        lambda: m.evaluate(q, gravity_scale=np.nan),
        lambda: m.evaluate(q, lengths="some"),
        lambda: m.fk((1.0, 0.0, 0.0), "30"),
        lambda: m.fk((1.0, 0.0, 0.0), 0.0, tol=0.0),                  # tolerance 0 is never reached
        lambda: m.fk((1.0, 0.0, 0.0), 0.0, max_iter=0),
        lambda: m.fk((1.0, 0.0, 0.0), 0.0, max_iter=2.5),
        lambda: m.ik((0.15, 0.0), 0.0),
        lambda: m.ik((0.15, 0.0, np.nan), 0.0),
        lambda: m.fk_locked((0.16, 0.16), 0.0),
        lambda: m.fk_locked((0.16, -0.16, 0.16), 0.0),
        lambda: m.fk_locked((0.16, 0.16, 0.16), 0.0, method="newton"),
        lambda: m.to_full(np.zeros(m.nz + 1)),
        lambda: m.reduce_vec(np.zeros(5)),
        lambda: m.reduce_mat(np.zeros((m.ndof, 5))),
        lambda: m.centreline(q, per_element=0),
        lambda: m.centreline(q, per_element=True),
    ]
    for i, case in enumerate(cases):
        with pytest.raises(InputError):
            case()
            pytest.fail(f"case {i} accepted")


def test_compliance_rejects_an_equilibrium_of_another_model(models):
    m, other = models
    eq = other.fk((1.0, 0.0, 0.0), 10e3)
    for fn in (lambda: cp.tension(m, eq), lambda: cp.locked(m, eq), lambda: cp.active_set(m, eq)):
        with pytest.raises(InputError, match="element count"):
            fn()
    with pytest.raises(InputError):
        cp.tension(m, "eq")


def test_collapsed_state_is_a_typed_error_not_an_infinite_energy(models):
    m, _ = models
    q = 0.1 * m.q_ref       # uniformly compressed to |r_x| = 0.1: a collapsed section
    with pytest.raises(CollapsedStateError):
        m.evaluate(q)
    q = m.q_ref.copy()
    q[-3:] = -q[-3:]        # tip folded back by 180 degrees: no tip frame
    with pytest.raises(BellowsError):
        m.tip_rotation(q)


def test_repeated_bad_calls_do_not_crash_the_interpreter():
    """Mixing element counts used to corrupt memory and abort ("double free or corruption") after a few
    hundred calls: run them in a subprocess and require a clean exit."""
    code = textwrap.dedent("""
        import numpy as np
        from ancf import Model, presets
        from ancf.errors import InputError
        a, b = Model(presets.paper()), Model(presets.paper().replace(n_elements=3))
        rejected = 0
        for k in range(300):
            for call in (a.evaluate, a.residual, a.tangent, a.dQ_dp, a.tendon_lengths, b.evaluate):
                try:
                    call(b.q_ref if call.__self__ is a else a.q_ref)
                except InputError:
                    rejected += 1
        print(rejected)
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    assert int(out.stdout.strip()) == 300 * 6
