"""The estimators package loads a filter's module only when it is used (PEP 562)."""

import subprocess
import sys

import pytest

import switchest.estimators as estimators

# what a program that filters with one Gaussian filter must not pay for: of the analysis, only
# the steady-state Kalman gain (numpy and scipy.linalg) may come along
_UNNEEDED = ("cvxpy", "scipy.optimize", "switchest.estimators.min_distance",
             "switchest.estimators.registry")
_ANALYSIS_USED = {"switchest.analysis", "switchest.analysis.steady_state_kalman"}
_PROGRAM = """
import sys
from switchest.estimators import {name}
print(" ".join(sys.modules))
"""


@pytest.mark.parametrize("name", ["IMMFilter", "ModeKalmanFilter", "SwitchTimeKalmanFilter",
                                  "IMMEV1Filter"])
def test_importing_a_filter_loads_only_the_analysis_it_runs_and_no_cvxpy(name):
    done = subprocess.run([sys.executable, "-c", _PROGRAM.format(name=name)],
                          capture_output=True, text=True, check=True)
    loaded = set(done.stdout.split())
    analysis = {m for m in loaded if m.startswith("switchest.analysis")}
    assert not [m for m in _UNNEEDED if m in loaded], sorted(m for m in loaded if "switchest" in m)
    assert analysis <= _ANALYSIS_USED, sorted(analysis - _ANALYSIS_USED)


def test_every_exported_name_resolves_and_is_listed():
    for name in estimators.__all__:
        assert getattr(estimators, name) is not None, name
    assert set(estimators.__all__) <= set(dir(estimators))


def test_an_unknown_name_raises_attribute_error():
    with pytest.raises(AttributeError, match="no attribute 'KalmanSmoother'"):
        estimators.KalmanSmoother  # noqa: B018 - the lookup is the test
