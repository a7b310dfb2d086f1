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


_LONG_LABEL = 30  # characters: a legend of longer labels takes one column


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
    marker_label: str | None = None,
) -> Path:
    """Lines ``series[label]`` against ``x``; 2-D series get one panel per column.

    ``paper`` adds the paper's printed points as black markers (label ->
    ``(x, y)``); ``markers`` draws vertical lines (e.g. true switching times), named
    ``marker_label`` in the legend; ``bands[label]`` (the shape of ``series[label]``) shades
    ``y ± band`` around a line: a 95 % band, e.g. 1.96 standard errors of a Monte Carlo mean,
    named in the legend. The legend lies under the panels, off the data.
    """
    first = np.asarray(next(iter(series.values())))
    panels = 1 if first.ndim == 1 else first.shape[1]
    ylabels = [ylabel] * panels if isinstance(ylabel, str) else list(ylabel)
    with plt.rc_context(_STYLE):
        cols = min(panels, 2)
        rows = -(-panels // cols)
        entries = (len(series) + len(paper or {}) + len(bands or {})
                   + bool(len(markers) and marker_label))
        ncols = 1 if max(len(label) for label in series) > _LONG_LABEL else 2
        legend_in = 0.2 * -(-entries // ncols) + 0.3  # inches under the panels
        fig, axes = plt.subplots(rows, cols, squeeze=False, figsize=(
            4.6 * cols, 3.2 * rows + legend_in))
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
                                    alpha=0.25, lw=0, label=f"{label}: 95 % band")
            for label, (px, py) in (paper or {}).items():
                py = np.asarray(py)
                ax.plot(px, py if py.ndim == 1 else py[:, p], "k^", ms=6, label=f"paper: {label}")
            for k, m in enumerate(markers):
                ax.axvline(m, color="0.5", lw=0.8, ls=":",
                           label=marker_label if k == 0 and marker_label else None)
            ax.set_xlabel(xlabel)
            ax.set_ylabel(ylabels[p])
            if logy:
                ax.set_yscale("log")
        # centred under the panels, never over a curve or a label
        handles, labels = flat[panels - 1].get_legend_handles_labels()
        fig.legend(handles, labels, fontsize=7, frameon=False, loc="lower center", ncols=ncols)
        rect = (0.0, legend_in / fig.get_figheight(), 1.0, 1.0)
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
    ``errors[label]`` draws ``± errors`` on the series' bars (e.g. 1.96 standard errors).
    Each series has a colour of its own: matplotlib's ten colours up to ten series, the
    twenty of ``tab20`` beyond, its dark shades first (the bake-off has fifteen series)."""
    k = len(series)
    width = 0.8 / max(k, 1)
    x = np.arange(len(groups))
    tab20 = plt.get_cmap("tab20").colors  # dark then light of each hue: the dark ones first
    colours = plt.get_cmap("tab10").colors if k <= 10 else tab20[0::2] + tab20[1::2]
    if k > len(colours):
        raise ValueError(f"series must hold at most {len(colours)} series (one colour each), "
                         f"got {k}")
    with plt.rc_context(_STYLE):
        size = (max(6.0, 1.6 * len(groups) + 2), 3.6 + 0.2 * ((k + 3) // 4))
        fig, ax = plt.subplots(figsize=size)
        for j, (label, values) in enumerate(series.items()):
            half = None if errors is None or label not in errors else np.asarray(errors[label])
            ax.bar(x + (j - (k - 1) / 2) * width, np.asarray(values, dtype=float), width,
                   label=label, yerr=half, color=colours[j], error_kw={"lw": 0.8, "capsize": 2})
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
    t_window: tuple[float, float] | None = None,
) -> Path:
    """An estimate to read at a glance: one panel per state, and the modes as a strip.

    Each state panel shows the estimate ``x[:, i]`` with its :math:`\\pm 2\\, \\mathrm{std}` band,
    the true state (``truth``, black) and the samples that measure it directly
    (``measured[i]``, grey dots). The last panel shows the modes as a strip: a row per mode
    shaded by its probability ``mode_prob (K, L)`` (white 0, dark 1), with the true mode
    (``true_mode``) as a red line through its row. Estimated switching instants are ticks along
    the bottom edge (not lines across the figure: a fast-switching system has thousands of
    them). One legend, above the panels, names every mark. ``names``/``units`` label the axes
    (``x0 ..`` without units when empty); ``t_window = (t0, t1)`` draws only the samples in
    :math:`t_0 \\le t \\le t_1`.
    """
    t, x = np.asarray(t, float), np.asarray(x, float)
    n = x.shape[1]
    names = list(names) or [f"x{i}" for i in range(n)]
    units = list(units) or [""] * n
    for label, given in (("names", names), ("units", units)):
        if len(given) != n:
            raise ValueError(f"{label} must have one entry per state ({n}), got {len(given)}")
    keep = window_mask(t, t_window)
    t, x = t[keep], x[keep]
    std, truth, mode_prob, true_mode = (None if a is None else np.asarray(a)[keep]
                                        for a in (std, truth, mode_prob, true_mode))
    measured = {i: np.asarray(v)[keep] for i, v in (measured or {}).items()}
    ticks = np.asarray(switch_times, float)
    ticks = ticks[(ticks >= t[0]) & (ticks <= t[-1])]
    panels = n + (mode_prob is not None)
    with plt.rc_context(_STYLE):
        heights = [1.0] * n + ([0.12 + 0.18 * mode_prob.shape[1]] if mode_prob is not None
                                else [])
        fig, axes = plt.subplots(panels, 1, figsize=(7.5, 1.8 * sum(heights) + 1.0),
                                 sharex=True, squeeze=False, height_ratios=heights)
        axes = axes[:, 0]
        marks: dict[str, object] = {}
        band = ""
        if std is not None:  # its width named: a narrow band is hard to see
            widths = ", ".join(f"{names[i]} {2 * np.median(std[:, i]):.2g}"
                               + (f" {units[i]}" if units[i] else "") for i in range(n))
            band = f"± 2σ band of the estimate (95 %)\nmedian half-width: {widths}"
        for i, ax in enumerate(axes[:n]):
            if i in measured:
                marks["measurements"], = ax.plot(t, measured[i], ".", color="0.6", ms=2.5)
            if truth is not None:
                marks["true state"], = ax.plot(t, truth[:, i], color="k", lw=1.0)
            marks["estimate"], = ax.plot(t, x[:, i], color="C0", lw=1.2)
            if std is not None:
                marks[band] = ax.fill_between(
                    t, x[:, i] - 2 * std[:, i], x[:, i] + 2 * std[:, i], color="C0", alpha=0.3,
                    lw=0)
            ax.set_ylabel(names[i] + (f" ({units[i]})" if units[i] else ""))
        if mode_prob is not None:
            _mode_strip(axes[-1], t, mode_prob, true_mode, marks)
        if len(ticks):
            bottom = axes[-1]
            marks["estimated switching instants"], = bottom.plot(
                ticks, np.zeros(len(ticks)), "|", color="C3", ms=8, clip_on=False,
                transform=bottom.get_xaxis_transform())
        axes[-1].set_xlabel("t (s)")
        axes[-1].set_xlim(t[0], t[-1])
        height = fig.get_figheight()  # inches: the title, then the legend, then the panels
        title_in = 0.28 if title else 0.05
        rows = -(-len(marks) // 3)  # a two-line label makes its row one line taller
        lines = rows + any("\n" in label for label in marks)
        legend_in = 0.15 * lines + 0.08 if marks else 0.0
        if title:
            fig.suptitle(title, y=1.0 - 0.04 / height, va="top", fontsize=9)
        if marks:
            fig.legend(list(marks.values()), list(marks), loc="upper center", ncols=3,
                       fontsize=7, frameon=False, bbox_to_anchor=(0.5, 1.0 - title_in / height))
        return _save(fig, path, rect=(0.0, 0.0, 1.0, 1.0 - (title_in + legend_in) / height))


def window_mask(t: np.ndarray, t_window) -> np.ndarray:
    """The samples of ``t`` inside ``t_window = (t0, t1)`` (all of them for None); a window
    holding fewer than two is refused."""
    if t_window is None:
        return np.ones(t.shape, dtype=bool)
    try:
        t0, t1 = (float(v) for v in t_window)
    except (TypeError, ValueError):
        raise ValueError(f"t_window must be a pair (t0, t1) of times, got {t_window!r}") from None
    if not t0 < t1:
        raise ValueError(f"t_window must have t0 < t1, got ({t0:g}, {t1:g})")
    keep = (t >= t0) & (t <= t1)
    if keep.sum() < 2:
        raise ValueError(f"t_window ({t0:g}, {t1:g}) holds {int(keep.sum())} sample(s) of the "
                         f"record ({t[0]:g} .. {t[-1]:g} s); it needs at least 2")
    return keep


def _mode_strip(ax, t: np.ndarray, mode_prob: np.ndarray, true_mode, marks: dict) -> None:
    """The modes as a strip: row ``j`` shaded by P(mode j), the true mode a line through its
    row (:func:`estimate_figure`)."""
    L = mode_prob.shape[1]
    edges = np.concatenate([t[:1], (t[1:] + t[:-1]) / 2, t[-1:]])
    ax.pcolormesh(edges, np.arange(L + 1) - 0.5, np.asarray(mode_prob, float).T,
                  cmap="Greys", vmin=0.0, vmax=1.0, shading="flat")
    marks["P(mode): the shade of its row,\nwhite 0 to black 1"] = plt.Rectangle(
        (0, 0), 1, 1, color="0.45")
    if true_mode is not None:
        marks["true mode"], = ax.step(t, np.asarray(true_mode, float), where="post",
                                      color="C3", lw=1.0)
    ax.set_yticks(range(L), [f"mode {j}" for j in range(L)])
    ax.set_ylim(L - 0.5, -0.5)
    ax.grid(False)


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
