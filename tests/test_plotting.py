"""Figures: what estimate_figure draws, read back from the figure it builds."""

import matplotlib.pyplot as plt
import numpy as np
import pytest

from switchest import plotting


def test_estimate_figure_draws_bands_truth_measurements_modes_and_switch_ticks(tmp_path,
                                                                               monkeypatch):
    figures = []
    monkeypatch.setattr(plotting, "_save", lambda fig, path: figures.append(fig) or path)
    t = np.linspace(0.0, 1.0, 50)
    x = np.stack([np.sin(t), np.cos(t)], axis=1)
    plotting.estimate_figure(tmp_path / "e.png", t, x, std=0.1 * np.ones_like(x), truth=x + 0.01,
                             measured={1: np.cos(t)}, mode_prob=np.full((50, 2), 0.5),
                             true_mode=(t > 0.5).astype(int), switch_times=[0.5],
                             names=["i_L", "v_0"], units=["A", "V"], title="demo")
    fig = figures[0]
    axes = fig.axes
    assert [ax.get_ylabel() for ax in axes] == ["i_L (A)", "v_0 (V)", "mode probability"]
    assert len(axes[0].collections) == 1  # the ± 2σ band
    assert len(axes[1].lines) == 3  # measured dots, true and estimated v_0
    assert len(axes[2].lines) == 4  # two probabilities, the true mode, the switch ticks
    plt.close(fig)


def test_estimate_figure_labels_default_to_state_indices(tmp_path):
    path = plotting.estimate_figure(tmp_path / "e.png", np.arange(3.0), np.zeros((3, 2)))
    assert path.stat().st_size > 0
    with pytest.raises(ValueError, match=r"names must have one entry per state \(2\), got 1"):
        plotting.estimate_figure(tmp_path / "f.png", np.arange(3.0), np.zeros((3, 2)),
                                 names=["only one"])


def test_measured_states_keeps_outputs_that_are_one_state_in_every_mode():
    y = np.arange(12.0).reshape(4, 3)
    C = np.array([[[0, 1, 0], [1, 1, 0], [0, 0, 2]],
                  [[0, 1, 0], [1, 1, 0], [0, 0, 2]]], dtype=float)
    measured = plotting.measured_states(C, y)
    assert list(measured) == [1]  # output 0 is state 1; output 1 mixes, output 2 scales
    np.testing.assert_array_equal(measured[1], y[:, 0])
    C[1, 0] = [1, 0, 0]  # another state in mode 1: not one state throughout
    assert plotting.measured_states(C, y) == {}
