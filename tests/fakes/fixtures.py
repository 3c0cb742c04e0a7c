"""Fixtures shared by the rig tests (imported into the test modules: a conftest.py in a test sub-folder
would shadow the top-level ``conftest`` module that other tests import helpers from)."""

import logging

import pytest

P = 60e3


@pytest.fixture(scope="module")
def target(paper_model):
    """A near-horizontal tip position [m] reachable with interior tensions."""
    return paper_model.fk((2.2, 1.6, 1.6), P, (0, 0, 0)).tip


@pytest.fixture
def quiet_canopen():
    """canopen logs every SDO fallback and timeout; keep the test output readable."""
    logging.getLogger("canopen").setLevel(logging.ERROR)
    yield


def hold_the_gil(seconds: float) -> None:
    """Stall every other thread of this process for ``seconds``, as a compiled kernel that does not release the
    GIL does: libc's ``usleep`` called through ``ctypes.PyDLL``, which keeps the GIL held during the call.
    (Raising ``sys.setswitchinterval`` instead leaves threads that started waiting meanwhile with its long
    timeout, starving them for far longer than asked.)"""
    import ctypes
    ctypes.PyDLL(None).usleep(int(seconds * 1e6))
