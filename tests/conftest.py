import pathlib
import sys

import numpy as np
import pytest

sys.path.insert(0, str(pathlib.Path(__file__).parent))

from ancf import Model, StiffnessLaw, presets  # noqa: E402


@pytest.fixture(scope="session")
def paper_model():
    return Model(presets.paper_unscaled())


@pytest.fixture
def python_sigint():
    """Python's own SIGINT handler (KeyboardInterrupt) for the test's duration, the previous one restored after: a
    test run started in the background by a non-interactive shell inherits SIGINT ignored, and a run then rightly
    leaves an ignored SIGINT alone (ancf/dynamics/interrupt.py), so a test of Ctrl-C must set the handler itself."""
    import signal
    import threading
    if threading.current_thread() is not threading.main_thread():
        pytest.skip("signal handlers need the main thread")
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


def uniform_params(**changes):
    """Weightless paper actuator with a constant law and no tool offset (closed-form comparisons)."""
    base = presets.paper_unscaled().replace(stiffness=StiffnessLaw.constant(EA=767.2, EI=0.0839), line_mass=0.0,
                                   tip_mass=0.0, tool_offset=0.0)
    return base.replace(**changes) if changes else base


def rotation(axis, angle):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K
