"""Matplotlib figures for trajectories, estimates and reproduction curves.

Every function draws one figure, writes it to ``path`` (PNG) and returns the
path; nothing is shown on screen, so the functions work on headless machines.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

__all__ = ["bars", "curves", "estimate_figure", "measured_states"]

_STYLE = {"figure.dpi": 110, "axes.grid": True, "grid.alpha": 0.3, "axes.spines.top": False,
          "axes.spines.right": False, "font.size": 9}


_LONG_LABEL = 30  # characters: a legend of longer labels goes below the panels


def curves(
    path: str | Path,
    x: np.ndarray,
    series: Mapping[str, np.ndarray],
    *,
    xlabel: str,
    ylabel: str | Sequence[str],
    title: str = "",
    paper: Mapping[str, tuple[np.ndarray, np.ndarray]] | None = None,
    logy: bool = False,
    markers: Sequence[float] = (),
    bands: Mapping[str, np.ndarray] | None = None,
) -> Path:
    """Lines ``series[label]`` against ``x``; 2-D series get one panel per column.

    ``paper`` adds the paper's printed points as black markers (label ->
    ``(x, y)``); ``markers`` draws vertical lines (e.g. true switching times);
    ``bands[label]`` (the shape of ``series[label]``) shades ``y ± band`` around a
    line, e.g. 1.96 standard errors of a Monte Carlo mean.
    """
    first = np.asarray(next(iter(series.values())))
    panels = 1 if first.ndim == 1 else first.shape[1]
    ylabels = [ylabel] * panels if isinstance(ylabel, str) else list(ylabel)
    with plt.rc_context(_STYLE):
        cols = min(panels, 2)
        rows = -(-panels // cols)
        below = max(len(label) for label in series) > _LONG_LABEL  # the legend under the axes
        entries = len(series) + len(paper or {})
        fig, axes = plt.subplots(rows, cols, squeeze=False, figsize=(
            4.6 * cols, 3.2 * rows + (0.2 * entries + 0.4 if below else 0.0)))
        flat = axes.ravel()
        for ax in flat[panels:]:
            ax.set_visible(False)
        for p, ax in enumerate(flat[:panels]):
            for label, y in series.items():
                y = np.asarray(y)
                style = {"color": "k", "lw": 2.0, "zorder": 3} if label == "true" else {}
                line, = ax.plot(x, y if y.ndim == 1 else y[:, p],
                                marker="o" if len(x) < 30 else None, ms=3, label=label, **style)
                if bands is not None and label in bands:
                    half = np.asarray(bands[label])
                    mid, half = (y, half) if y.ndim == 1 else (y[:, p], half[:, p])
                    ax.fill_between(x, mid - half, mid + half, color=line.get_color(),
                                    alpha=0.2, lw=0)
            for label, (px, py) in (paper or {}).items():
                py = np.asarray(py)
                ax.plot(px, py if py.ndim == 1 else py[:, p], "k^", ms=6, label=f"paper: {label}")
            for m in markers:
                ax.axvline(m, color="0.5", lw=0.8, ls=":")
            ax.set_xlabel(xlabel)
            ax.set_ylabel(ylabels[p])
            if logy:
                ax.set_yscale("log")
        rect = None
        if below:  # centred under the panels, never over a curve or a label
            handles, labels = flat[panels - 1].get_legend_handles_labels()
            fig.legend(handles, labels, fontsize=7, frameon=False, loc="lower center")
            rect = (0.0, (0.2 * entries + 0.3) / fig.get_figheight(), 1.0, 1.0)
        else:
            flat[panels - 1].legend(fontsize=7, frameon=False)
        if title:
            fig.suptitle(title)
        return _save(fig, path, rect)


def bars(
    path: str | Path,
    groups: Sequence[str],
    series: Mapping[str, Sequence[float]],
    *,
    ylabel: str,
    title: str = "",
    logy: bool = False,
    errors: Mapping[str, Sequence[float]] | None = None,
) -> Path:
    """Grouped bars: one group per entry of ``groups``, one bar per series (NaN = no bar);
    ``errors[label]`` draws ``± errors`` on the series' bars (e.g. 1.96 standard errors)."""
    k = len(series)
    width = 0.8 / max(k, 1)
    x = np.arange(len(groups))
    with plt.rc_context(_STYLE):
        size = (max(6.0, 1.6 * len(groups) + 2), 3.6 + 0.2 * ((k + 3) // 4))
        fig, ax = plt.subplots(figsize=size)
        for j, (label, values) in enumerate(series.items()):
            half = None if errors is None or label not in errors else np.asarray(errors[label])
            ax.bar(x + (j - (k - 1) / 2) * width, np.asarray(values, dtype=float), width,
                   label=label, yerr=half, error_kw={"lw": 0.8, "capsize": 2})
        ax.set_xticks(x, groups)
        ax.set_ylabel(ylabel)
        if logy:
            ax.set_yscale("log")
        # below the axes, so the legend never covers a bar however many series there are
        ax.legend(fontsize=7, frameon=False, ncol=min(k, 4), loc="upper center",
                  bbox_to_anchor=(0.5, -0.12))
        if title:
            ax.set_title(title)
        return _save(fig, path)


def estimate_figure(
    path: str | Path,
    t: np.ndarray,
    x: np.ndarray,
    *,
    std: np.ndarray | None = None,
    truth: np.ndarray | None = None,
    measured: Mapping[int, np.ndarray] | None = None,
    mode_prob: np.ndarray | None = None,
    true_mode: np.ndarray | None = None,
    switch_times: Sequence[float] = (),
    names: Sequence[str] = (),
    units: Sequence[str] = (),
    title: str = "",
) -> Path:
    """An estimate to read at a glance: one panel per state, and the modes.

    Each state panel shows the estimate ``x[:, i]`` with its ``± 2 std`` band, the true
    state (``truth``, black) and the samples that measure it directly
    (``measured[i]``, grey dots); a last panel shows the mode probabilities
    ``mode_prob (K, L)`` with the true mode (``true_mode``) as a step. Estimated
    switching instants are ticks along the bottom edge (not lines across the figure:
    a fast-switching system has thousands of them). ``names``/``units`` label the axes
    (``x0 ..`` without units when empty).
    """
    t, x = np.asarray(t, float), np.asarray(x, float)
    n = x.shape[1]
    names = list(names) or [f"x{i}" for i in range(n)]
    units = list(units) or [""] * n
    for label, given in (("names", names), ("units", units)):
        if len(given) != n:
            raise ValueError(f"{label} must have one entry per state ({n}), got {len(given)}")
    panels = n + (mode_prob is not None)
    with plt.rc_context(_STYLE):
        fig, axes = plt.subplots(panels, 1, figsize=(7.5, 1.9 * panels + 0.6), sharex=True,
                                 squeeze=False)
        axes = axes[:, 0]
        for i, ax in enumerate(axes[:n]):
            if measured is not None and i in measured:
                ax.plot(t, measured[i], ".", color="0.6", ms=2.5, label="measured")
            if truth is not None:
                ax.plot(t, truth[:, i], color="k", lw=1.2, label="true")
            line, = ax.plot(t, x[:, i], lw=1.2, label="estimate")
            if std is not None:
                ax.fill_between(t, x[:, i] - 2 * std[:, i], x[:, i] + 2 * std[:, i],
                                color=line.get_color(), alpha=0.2, lw=0, label="± 2σ")
            ax.set_ylabel(names[i] + (f" ({units[i]})" if units[i] else ""))
        axes[0].legend(loc="upper right", fontsize=7, ncols=4)
        if mode_prob is not None:
            ax = axes[-1]
            for j in range(mode_prob.shape[1]):
                ax.plot(t, mode_prob[:, j], lw=1.0, label=f"P(mode {j})")
            if true_mode is not None and mode_prob.shape[1] > 1:
                scale = 1.0 / (mode_prob.shape[1] - 1)
                ax.step(t, np.asarray(true_mode) * scale, where="post", color="k", lw=0.8,
                        ls="--", label="true mode (0 bottom, last top)")
            ax.set_ylim(-0.05, 1.05)
            ax.set_ylabel("mode probability")
            ax.legend(loc="upper right", fontsize=7, ncols=3)
        if len(switch_times):
            bottom = axes[-1]
            bottom.plot(switch_times, np.zeros(len(switch_times)), "|", color="C3", ms=8,
                        transform=bottom.get_xaxis_transform(), label="estimated switches")
        axes[-1].set_xlabel("t (s)")
        if title:
            axes[0].set_title(title)
        return _save(fig, path)


def measured_states(C: np.ndarray, y: np.ndarray) -> dict[int, np.ndarray]:
    """The samples that measure a state directly, for :func:`estimate_figure`'s grey dots:
    ``{i: y[:, j]}`` for each output ``j`` that is state ``i`` alone, with weight 1, in every
    mode (``C (L, m, n)``, ``y (K, m)``)."""
    measured = {}
    for j in range(C.shape[1]):
        row = C[:, j, :]
        hits = np.flatnonzero(row[0])
        if hits.size == 1 and row[0, hits[0]] == 1.0 and np.all(row == row[0]):
            measured[int(hits[0])] = np.asarray(y)[:, j]
    return measured


def _save(fig, path: str | Path, rect: tuple[float, ...] | None = None) -> Path:
    """Lay out (within ``rect`` of the figure, default all of it), write and close ``fig``."""
    fig.tight_layout(rect=rect)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)
    return path
