"""Suite-wide settings."""

import matplotlib
import scipy.linalg  # noqa: F401  (loads scipy's own BLAS, so that the limit below reaches it)
from threadpoolctl import threadpool_limits

matplotlib.use("Agg")

# The suite works on small matrices, where threaded BLAS only adds contention (on 2 cores a
# closed-loop simulation ran 150x slower with it). The limit holds from the collection on: test
# modules simulate at import (tests/test_malformed_inputs.py), and with each xdist worker's BLAS
# threads spinning on the same two cores their collection once took four minutes.
_ONE_BLAS_THREAD = threadpool_limits(1)
