"""The FEM reference's errors: the product's one exception tree, or a standalone copy of its part used here.

The FEM is an independent reference: it never needs the reduced model, nor the ``ancf`` package, to import or
to solve.  Its errors must still be the product's errors, so that one ``except BellowsError`` (and the command
line's one-line contract, :mod:`ancf.clitools`) catches a failed FEM solve like any other product error.  So:

* ``ancf`` importable (the product installed): the names below **are** the classes of :mod:`ancf.errors`
  (``fem_reference.errors.ConfigError is ancf.errors.ConfigError``) — one tree;
* ``ancf`` absent (the FEM used alone): the same names from :mod:`fem_reference._standalone_errors`, a minimal
  tree with the same subclass relations and constructors::

      BellowsError
      ├── ConfigError (ValueError)
      ├── InputError (ValueError)
      │   └── LimitError
      ├── ConvergenceError (RuntimeError)        solver=, iterations=, residual_norm=, tolerance=, history=
      └── UnstableEquilibriumError (RuntimeError)  solver=, min_eigenvalue=

Only a missing ``ancf`` package selects the standalone tree; an ``ancf`` that is present but fails to import
is an install error and is raised as such.  Every fem_reference module imports its errors from here, and only
this module names ``ancf`` (tests/test_layout.py).
"""

from __future__ import annotations

__all__ = ["STANDALONE", "BellowsError", "ConfigError", "ConvergenceError", "InputError", "LimitError",
           "UnstableEquilibriumError", "check_finite"]

try:
    import ancf  # noqa: F401  (the package itself: a missing ancf is the one case of the standalone tree)
except ModuleNotFoundError as exc:
    if exc.name != "ancf":          # ancf present but one of its imports missing: an install to repair
        raise
    from ._standalone_errors import (
        BellowsError,
        ConfigError,
        ConvergenceError,
        InputError,
        LimitError,
        UnstableEquilibriumError,
        check_finite,
    )
    #: True when the FEM runs without the ``ancf`` package (its errors are then the standalone tree)
    STANDALONE = True
else:
    from ancf.errors import (
        BellowsError,
        ConfigError,
        ConvergenceError,
        InputError,
        LimitError,
        UnstableEquilibriumError,
        check_finite,
    )
    STANDALONE = False
