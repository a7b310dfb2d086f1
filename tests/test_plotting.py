"""Figures: what estimate_figure draws, read back from the figure it builds."""

import matplotlib.pyplot as plt
import numpy as np
import pytest

from switchest import plotting


def test_estimate_figure_draws_bands_truth_measurements_modes_and_switch_ticks(tmp_path,
                                                                               monkeypatch):
    figures = []
    monkeypatch.setattr(plotting, "_save", lambda fig, path, rect=None: figures.append(fig) or path)
    t = np.linspace(0.0, 1.0, 50)
    x = np.stack([np.sin(t), np.cos(t)], axis=1)
    plotting.estimate_figure(tmp_path / "e.png", t, x, std=0.1 * np.ones_like(x), truth=x + 0.01,
                             measured={1: np.cos(t)}, mode_prob=np.full((50, 2), 0.5),
                             true_mode=(t > 0.5).astype(int), switch_times=[0.5],
                             names=["i_L", "v_0"], units=["A", "V"], title="demo")
    fig = figures[0]
    axes = fig.axes
    assert [ax.get_ylabel() for ax in axes[:2]] == ["i_L (A)", "v_0 (V)"]
    assert [tick.get_text() for tick in axes[2].get_yticklabels()] == ["mode 0", "mode 1"]
    assert len(axes[0].collections) == 1  # the ± 2σ band
    assert len(axes[1].lines) == 3  # measured dots, true and estimated v_0
    assert len(axes[2].collections) == 1 and len(axes[2].lines) == 2  # strip, true, ticks
    legend = fig.legends[0]  # one legend, above the panels, names every mark
    assert {text.get_text() for text in legend.get_texts()} == {
        "measurements", "true state", "estimate",
        "± 2σ band of the estimate (95 %)\nmedian half-width: i_L 0.2 A, v_0 0.2 V",
        "P(mode): the shade of its row,\nwhite 0 to black 1", "true mode",
        "estimated switching instants"}
    fig.canvas.draw()  # the legend inside the figure: not clipped at its sides
    box = legend.get_window_extent()
    assert box.x0 >= 0 and box.x1 <= fig.bbox.width
    plt.close(fig)


def test_estimate_figure_draws_a_window_of_the_record(tmp_path, monkeypatch):
    figures = []
    monkeypatch.setattr(plotting, "_save", lambda fig, path, rect=None: figures.append(fig) or path)
    t = np.linspace(0.0, 1.0, 101)
    x = np.stack([t, -t], axis=1)
    plotting.estimate_figure(tmp_path / "w.png", t, x, switch_times=[0.1, 0.45, 0.9],
                             mode_prob=np.full((101, 2), 0.5), t_window=(0.4, 0.6))
    ax = figures[0].axes[0]
    drawn = ax.lines[0].get_xdata()
    assert drawn.min() >= 0.4 and drawn.max() <= 0.6 and drawn.size == 21
    assert list(figures[0].axes[-1].lines[-1].get_xdata()) == [0.45]  # the ticks inside it
    plt.close(figures[0])
    for window, message in (((0.6, 0.4), "t0 < t1"), ((2.0, 3.0), "holds 0 sample"),
                            ("0.4", "a pair")):
        with pytest.raises(ValueError, match=message):
            plotting.estimate_figure(tmp_path / "x.png", t, x, t_window=window)


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


def test_curves_name_bands_and_markers_in_a_legend_under_the_panels(tmp_path, monkeypatch):
    figures = []
    monkeypatch.setattr(plotting, "_save", lambda fig, path, rect=None: figures.append(fig) or path)
    x = np.arange(5.0)
    plotting.curves(tmp_path / "c.png", x, {"ours": np.stack([x, -x], 1)},
                    bands={"ours": np.ones((5, 2))}, paper={"Table I": (x, np.stack([x, x], 1))},
                    markers=[1.0, 3.0], marker_label="switches", xlabel="g",
                    ylabel=["a", "b"])
    fig = figures[0]
    assert not any(ax.get_legend() for ax in fig.axes)  # none over the data
    assert [t.get_text() for t in fig.legends[0].get_texts()] == [
        "ours", "ours: 95 % band", "paper: Table I", "switches"]
    plt.close(fig)


def test_bars_give_every_series_a_colour_of_its_own(tmp_path, monkeypatch):
    figures = []
    monkeypatch.setattr(plotting, "_save", lambda fig, path, rect=None: figures.append(fig) or path)
    series = {f"method {j}": [1.0 + j, 2.0] for j in range(15)}  # the bake-off's fifteen
    plotting.bars(tmp_path / "b.png", ["case a", "case b"], series, ylabel="RMSE")
    ax = figures[0].axes[0]
    colours = {tuple(bar.patches[0].get_facecolor()) for bar in ax.containers}
    assert len(ax.containers) == 15 and len(colours) == 15
    with pytest.raises(ValueError, match="at most 20 series"):
        plotting.bars(tmp_path / "c.png", ["a"], {f"s{j}": [1.0] for j in range(21)}, ylabel="y")
    plt.close(figures[0])
