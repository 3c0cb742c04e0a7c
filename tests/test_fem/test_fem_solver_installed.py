"""The tests run the linear solver the README's main command installs.

The main command installs ``.[pardiso]`` (MKL PARDISO on x86-64; elsewhere the extra installs nothing and the FEM
uses SciPy's SuperLU); the test command installs ``.[test]``, which includes it.  Without this check the PARDISO
tests (forked workers, the symmetric solve, stability) would be skipped silently where users run PARDISO.
"""

import platform

import pytest

from fem_reference.solver import available_solvers


@pytest.mark.skipif(platform.machine() not in ("x86_64", "AMD64"), reason="MKL PARDISO has wheels for x86-64 only")
def test_pardiso_is_installed_where_the_main_command_installs_it():
    assert "pardiso" in available_solvers(), (
        "pypardiso is missing on x86-64: the FEM's default solver is untested (install .[test], which includes it)")
