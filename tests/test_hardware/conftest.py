import pytest

P = 60e3


@pytest.fixture(scope="module")
def target(paper_model):
    """A near-horizontal tip position [m] reachable with interior tensions."""
    return paper_model.fk((2.2, 1.6, 1.6), P, (0, 0, 0)).tip


@pytest.fixture
def quiet_canopen():
    import logging
    logging.getLogger("canopen").setLevel(logging.ERROR)
    yield
