"""The estimators package loads a filter's module only when it is used (PEP 562)."""

import subprocess
import sys

import pytest

import switchest.estimators as estimators

# what a program that filters with one Gaussian filter must not pay for
_UNNEEDED = ("cvxpy", "scipy.optimize", "switchest.analysis", "switchest.estimators.min_distance",
             "switchest.estimators.registry")
_PROGRAM = """
import sys
from switchest.estimators import {name}
print(" ".join(sys.modules))
"""


@pytest.mark.parametrize("name", ["IMMFilter", "ModeKalmanFilter", "SwitchTimeKalmanFilter",
                                  "IMMEV1Filter"])
def test_importing_a_filter_loads_neither_the_analysis_nor_cvxpy(name):
    done = subprocess.run([sys.executable, "-c", _PROGRAM.format(name=name)],
                          capture_output=True, text=True, check=True)
    loaded = set(done.stdout.split())
    assert not [m for m in _UNNEEDED if m in loaded], sorted(m for m in loaded if "switchest" in m)


def test_every_exported_name_resolves_and_is_listed():
    for name in estimators.__all__:
        assert getattr(estimators, name) is not None, name
    assert set(estimators.__all__) <= set(dir(estimators))


def test_an_unknown_name_raises_attribute_error():
    with pytest.raises(AttributeError, match="no attribute 'KalmanSmoother'"):
        estimators.KalmanSmoother  # noqa: B018 - the lookup is the test
