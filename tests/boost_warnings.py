"""The warnings a fit of the boost converter gives by design (tests/test_learn_between*.py)."""

import warnings
from contextlib import contextmanager

__all__ = ["boost_fit_warnings_ignored"]


@contextmanager
def boost_fit_warnings_ignored():
    """Ignore what a boost converter fit says of its model, not of the fit's working: mode 0
    leaves i_L unobservable, and the data do not inform Q (its observed information is not
    positive definite, or the fit lies on the boundary)."""
    with warnings.catch_warnings():
        for message in ("mode 0: the pair", "the observed information is not positive definite",
                        "the fit lies on the boundary"):
            warnings.filterwarnings("ignore", message)
        yield
