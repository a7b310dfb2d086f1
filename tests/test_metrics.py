"""Metrics against direct formulas."""

import numpy as np
import pytest

from switchest.metrics import mode_accuracy, rmse, switch_time_error


def test_rmse_per_step_and_overall():
    truth = np.zeros((2, 3, 2))
    est = np.array([[[1.0, 0.0], [2.0, 0.0], [3.0, 1.0]], [[1.0, 0.0], [0.0, 0.0], [1.0, 1.0]]])
    r = rmse(est, truth, start=1)
    np.testing.assert_allclose(r.per_step[:, 0], [1.0, np.sqrt(2.0), np.sqrt(5.0)])
    np.testing.assert_allclose(r.overall, [np.sqrt((4 + 0 + 9 + 1) / 4), np.sqrt(0.5)])
    with pytest.raises(ValueError, match="share a shape"):
        rmse(est[0], truth)


def test_mode_accuracy_and_switch_time_error():
    assert mode_accuracy([[0, 1, 1, 0]], [[0, 1, 0, 0]]) == 0.75
    assert mode_accuracy([[0, 1, 1, 0]], [[1, 1, 0, 0]], start=1) == pytest.approx(2 / 3)
    err = switch_time_error([np.nan, 1.2, 2.0, np.nan], [np.nan, 1.0, np.nan, 3.0])
    np.testing.assert_allclose(err, [0.2])
