"""Suite-wide settings."""

import matplotlib
import pytest
from threadpoolctl import threadpool_limits

matplotlib.use("Agg")


@pytest.fixture(autouse=True, scope="session")
def single_threaded_blas():
    """The suite works on small matrices, where threaded BLAS only adds contention (on 2 cores
    a closed-loop simulation ran 150x slower with it)."""
    with threadpool_limits(1):
        yield
