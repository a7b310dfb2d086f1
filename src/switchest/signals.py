"""Switching signals and sampling times.

A switching signal :math:`\\sigma(t)` is piecewise constant and right-continuous: it is
stored as the switch instants ``times (S,)`` and the modes ``modes (S+1,)``, with
``modes[0]`` active before ``times[0]`` and ``modes[s]`` on ``[times[s-1], times[s])``.

Generators draw one signal from an explicit ``rng``; pass them as
``lambda rng: dwell_time(..., rng=rng)`` to :func:`switchest.simulate.simulate`
to get one independent signal per trial.

A generator refuses up front, with ``ValueError``, a request whose expected number
of switches (or of sample times) exceeds :data:`MAX_EVENTS` = 10**7 (rate x
duration, or duration / mean gap): such a signal would take minutes to draw and
gigabytes downstream, and is almost always a unit mistake.
"""

from __future__ import annotations

from bisect import bisect_right
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ._checks import (
    as_rng,
    check_finite,
    check_memory,
    check_mode,
    check_probability_vector,
    check_row_stochastic,
    float_array,
    int_array,
    positive_scalar,
)

__all__ = [
    "SwitchingSignal",
    "schedule",
    "dwell_time",
    "average_dwell_time",
    "satisfies_average_dwell_time",
    "markov_continuous",
    "markov_at_samples",
    "iid_at_samples",
    "periodic",
    "aperiodic",
    "sample_segments",
    "MAX_EVENTS",
]

MAX_EVENTS = 10**7
"""Most switches (or sample times) a generator draws for one signal, in expectation."""

_CHUNK = 2**20  # random gaps drawn at once when the worst case would need more


@dataclass(frozen=True, eq=False)
class SwitchingSignal:
    """A right-continuous piecewise-constant switching signal.

    Parameters
    ----------
    times : array_like, shape (S,)
        Strictly increasing, finite switch instants.
    modes : array_like of int, shape (S+1,)
        Active modes (0-based): ``modes[0]`` before the first switch, ``modes[s]``
        from ``times[s-1]`` on. Consecutive entries must differ (a "switch" to the
        same mode is not a switch).
    """

    times: np.ndarray
    modes: np.ndarray

    def __post_init__(self) -> None:
        times = float_array(self.times, "times", ndim=1)
        check_finite(times, "times")
        modes = int_array(self.modes, "modes", ndim=1)
        if modes.shape[0] != times.shape[0] + 1:
            raise ValueError(
                f"modes must have one more entry than times (S+1 = {times.shape[0] + 1}), "
                f"got {modes.shape[0]}"
            )
        if np.any(np.diff(times) <= 0):
            raise ValueError("times must be strictly increasing")
        if np.any(modes < 0):
            raise ValueError(f"modes must be non-negative (0-based), got {modes.min()}")
        if np.any(modes[1:] == modes[:-1]):
            s = int(np.flatnonzero(modes[1:] == modes[:-1])[0])
            raise ValueError(
                f"modes must change at every switch, got mode {modes[s]} on both sides of "
                f"times[{s}] = {times[s]:g}"
            )
        times.setflags(write=False)
        modes.setflags(write=False)
        object.__setattr__(self, "times", times)
        object.__setattr__(self, "modes", modes)

    @property
    def n_switches(self) -> int:
        """Number of switches S."""
        return self.times.shape[0]

    def at(self, t) -> np.ndarray:
        """:math:`\\sigma(t)`, vectorized over ``t``; right-continuous (the new mode at a
        switch)."""
        t = float_array(t, "t")
        if np.any(np.isnan(t)):
            raise ValueError("t must not hold NaN: sigma(t) is defined at instants only")
        return self.modes[np.searchsorted(self.times, t, side="right")]

    def switches_in(self, t0: float, t1: float) -> tuple[np.ndarray, np.ndarray]:
        """Switches strictly inside ``(t0, t1)``: their instants and the modes they enter.

        A switch exactly at ``t0`` is not returned (:math:`\\sigma(t_0)` already holds its new
        mode), nor one at ``t1`` (it does not act on ``[t0, t1)``).
        """
        t0, t1 = (_finite_scalar(v, name) for v, name in ((t0, "t0"), (t1, "t1")))
        lo = np.searchsorted(self.times, t0, side="right")
        hi = np.searchsorted(self.times, t1, side="left")
        return self.times[lo:hi].copy(), self.modes[lo + 1 : hi + 1].copy()

    def then(self, other: SwitchingSignal, *, at: float) -> SwitchingSignal:
        """The signal equal to ``self`` before ``at`` and to ``other`` from ``at`` on."""
        if not isinstance(other, SwitchingSignal):
            raise TypeError(f"other must be a SwitchingSignal, got {type(other).__name__}")
        at = _finite_scalar(at, "at")
        i = np.searchsorted(self.times, at, side="left")  # self's switches before `at`
        j = np.searchsorted(other.times, at, side="right")  # other's switches after `at`
        times = np.concatenate([self.times[:i], [at], other.times[j:]])
        return schedule(times, np.concatenate([self.modes[: i + 1], other.modes[j:]]))

    def __repr__(self) -> str:
        return f"SwitchingSignal(switches={self.n_switches}, first_mode={int(self.modes[0])})"


def schedule(times, modes) -> SwitchingSignal:
    """A fixed schedule: switch to ``modes[s+1]`` at ``times[s]``.

    Equivalent to ``SwitchingSignal(times, modes)``; repeated modes are merged so a
    schedule may list a mode twice in a row.
    """
    times = float_array(times, "times", ndim=1)
    check_finite(times, "times")  # before merging: a dropped repeat must not hide a NaN
    modes = int_array(modes, "modes", ndim=1)
    if modes.shape[0] != times.shape[0] + 1:
        raise ValueError(
            f"modes must have one more entry than times, got {modes.shape[0]} and {times.shape[0]}"
        )
    change = modes[1:] != modes[:-1]
    return SwitchingSignal(times[change], np.concatenate([modes[:1], modes[1:][change]]))


def _check_n_modes(n_modes, minimum: int = 2) -> int:
    if isinstance(n_modes, (bool, np.bool_)) or not isinstance(n_modes, (int, np.integer)):
        raise TypeError(f"n_modes must be an int, got {type(n_modes).__name__}")
    if n_modes < minimum:
        raise ValueError(f"n_modes must be at least {minimum} to switch, got {n_modes}")
    return int(n_modes)


def _next_modes(first: int, count: int, n_modes: int, rng: np.random.Generator) -> np.ndarray:
    """``count + 1`` modes starting at ``first``, each next one uniform among the others."""
    steps = rng.integers(1, n_modes, size=count)  # a shift of 1..L-1 never stays put
    return (first + np.concatenate([[0], np.cumsum(steps)])) % n_modes


def dwell_time(
    n_modes: int,
    t_end: float,
    min_dwell: float,
    max_dwell: float,
    *,
    rng,
    t_start: float = 0.0,
    initial_mode: int = 0,
) -> SwitchingSignal:
    """Switches separated by gaps drawn uniformly in ``[min_dwell, max_dwell]``.

    The first switch comes one such gap after ``t_start``; each new mode is drawn
    uniformly among the other modes. Every gap is at least ``min_dwell``: the
    dwell-time condition tau_d of Shankar et al. §II.
    """
    n_modes = _check_n_modes(n_modes)
    lo, hi = _check_dwell_bounds(min_dwell, max_dwell)
    t_end = _check_span(t_start, t_end)
    first = check_mode(initial_mode, n_modes, "initial_mode")
    span = t_end - float(t_start)
    _check_events(span / (0.5 * (lo + hi)), "switches",
                  "(t_end - t_start) / ((min_dwell + max_dwell) / 2)")
    rng = as_rng(rng)
    times = _uniform_increments(float(t_start), t_end, lo, hi, rng)
    times = times[times < t_end]
    return SwitchingSignal(times, _next_modes(first, times.size, n_modes, rng))


def _check_dwell_bounds(min_dwell, max_dwell) -> tuple[float, float]:
    """``(min_dwell, max_dwell)`` as floats, both positive and ``max_dwell >= min_dwell``."""
    lo = positive_scalar(min_dwell, "min_dwell")
    hi = positive_scalar(max_dwell, "max_dwell")
    if hi < lo:
        raise ValueError(f"max_dwell must be >= min_dwell = {lo:g}, got {hi:g}")
    return lo, hi


def _uniform_increments(t_start: float, t_end: float, lo: float, hi: float, rng) -> np.ndarray:
    """``t_start + cumsum(gaps)``, gaps uniform on ``[lo, hi]``, drawn until one passes ``t_end``.

    The worst case needs ``ceil((t_end - t_start) / lo) + 1`` gaps: that many are drawn
    at once when it is at most ``_CHUNK``, otherwise ``_CHUNK`` at a time, so a tiny
    ``lo`` beside a large ``hi`` costs what the gaps need, not what the worst case would.
    """
    need = np.ceil((t_end - t_start) / lo) + 1  # a float: may exceed every integer type
    parts, last = [], t_start
    while last <= t_end and need > 0:
        size = int(min(need, _CHUNK))
        part = last + np.cumsum(rng.uniform(lo, hi, size=size))
        parts.append(part)
        last, need = float(part[-1]), need - size
    return np.concatenate(parts)


def average_dwell_time(
    n_modes: int,
    t_end: float,
    tau_a: float,
    N0: float,
    *,
    rng,
    rate: float | None = None,
    t_start: float = 0.0,
    initial_mode: int = 0,
) -> SwitchingSignal:
    """A random signal with average dwell time ``tau_a`` and chatter bound ``N0``.

    The number of switches in any interval :math:`(s, t)` obeys
    :math:`N(s, t) \\le N_0 + (t - s) / \\tau_a` (Hespanha & Morse's average dwell time, used
    by Etienne et al. Definition 2 / Assumption 4). Switch attempts arrive as a
    Poisson process of intensity ``rate`` (default :math:`2 / \\tau_a`, so the budget is
    often exhausted and bursts of up to :math:`N_0` fast switches occur); an attempt is
    accepted when a token bucket of capacity :math:`N_0`, refilled at :math:`1 / \\tau_a` and
    spending one token per switch, holds a whole token. The result is verified with
    :func:`satisfies_average_dwell_time` before it is returned.
    """
    n_modes = _check_n_modes(n_modes)
    tau_a, N0, rate = _check_average_dwell(tau_a, N0, rate)
    rate = 2.0 / tau_a if rate is None else rate
    t_end = _check_span(t_start, t_end)
    first = check_mode(initial_mode, n_modes, "initial_mode")
    _check_events(rate * (t_end - float(t_start)), "switch attempts", "rate * (t_end - t_start)")
    rng = as_rng(rng)
    n_try = int(rng.poisson(rate * (t_end - t_start)))
    attempts = np.sort(rng.uniform(t_start, t_end, size=n_try))
    accepted = []
    tokens, last = N0, t_start
    for s in attempts:  # sequential by nature: each acceptance spends the shared budget
        tokens = min(N0, tokens + (s - last) / tau_a)
        last = s
        if tokens >= 1.0:
            tokens -= 1.0
            accepted.append(s)
    times = np.asarray(accepted, dtype=float)
    signal = SwitchingSignal(times, _next_modes(first, times.size, n_modes, rng))
    if not satisfies_average_dwell_time(signal, tau_a, N0):
        raise RuntimeError("internal error: generated signal violates the average dwell time")
    return signal


def _check_average_dwell(tau_a, N0, rate) -> tuple[float, float, float | None]:
    """``(tau_a, N0, rate)`` as floats: positive, ``N0 >= 1``; ``rate`` may be None."""
    tau_a = positive_scalar(tau_a, "tau_a")
    N0 = positive_scalar(N0, "N0")
    if N0 < 1:
        raise ValueError(f"N0 must be >= 1 (one switch must be possible), got {N0:g}")
    return tau_a, N0, None if rate is None else positive_scalar(rate, "rate")


def satisfies_average_dwell_time(signal: SwitchingSignal, tau_a: float, N0: float) -> bool:
    """Check :math:`N(s, t) \\le N_0 + (t - s) / \\tau_a` for every interval.

    The tightest intervals run from just before one switch to just after another,
    so it suffices that :math:`j - i + 1 \\le N_0 + (t_j - t_i) / \\tau_a` for all switch
    pairs :math:`i \\le j`. With :math:`a_j = j - t_j / \\tau_a` that reads
    :math:`a_j - \\min_{i \\le j} a_i \\le N_0 - 1`: one pass with a running minimum,
    :math:`O(S)`. A slack of :math:`10^{-12} \\max(1, |t|)` in time absorbs round-off (it
    exceeds the rounding of :math:`t / \\tau_a` by more than three orders of magnitude).
    """
    if not isinstance(signal, SwitchingSignal):
        raise TypeError(f"signal must be a SwitchingSignal, got {type(signal).__name__}")
    tau_a = positive_scalar(tau_a, "tau_a")
    N0 = positive_scalar(N0, "N0")
    t = signal.times
    if t.size == 0:
        return True
    slack = 1e-12 * max(1.0, float(np.abs(t).max()))
    a = np.arange(t.size) - t / tau_a
    return bool(np.all(a - np.minimum.accumulate(a) <= N0 - 1 + slack / tau_a))


def markov_continuous(
    rates,
    t_end: float,
    *,
    rng,
    t_start: float = 0.0,
    initial_mode: int = 0,
) -> SwitchingSignal:
    """A continuous-time Markov chain with generator ``rates``.

    ``rates[i, j]`` (:math:`i \\ne j`) is the rate of jumps from mode i to j; the diagonal must
    equal minus the row sum of the off-diagonal entries (rows sum to zero). Holding
    times are exponential with rate ``-rates[i, i]``; a mode with zero outflow is
    absorbing.

    The jump chain is drawn in blocks: uniforms pick each next mode (the inverse
    of the cumulative jump probabilities), unit exponentials divided by the
    outflow rates give the holding times.
    """
    Q = _check_rates(rates)
    n_modes = Q.shape[0]
    off = Q - np.diag(np.diag(Q))
    t_end = _check_span(t_start, t_end)
    mode = check_mode(initial_mode, n_modes, "initial_mode")
    out = -np.diag(Q)
    expected = float(out.max()) * (t_end - float(t_start))
    _check_events(expected, "switches", "max(-rates[i, i]) * (t_end - t_start)")
    rng = as_rng(rng)
    moving = (out > 0).tolist()
    cum = np.cumsum(off, axis=1)
    cdf = (cum / np.where(cum[:, -1:] > 0, cum[:, -1:], 1.0)).tolist()  # each row ends at 1.0
    scale = np.where(out > 0, 1.0 / np.where(out > 0, out, 1.0), np.inf)  # absorbing: hold for ever
    block = int(min(_CHUNK, expected + 4.0 * np.sqrt(expected) + 16))
    times, modes, t = [], [np.array([mode])], float(t_start)
    while moving[mode]:
        hold = rng.standard_exponential(block)
        u = rng.random(block).tolist()
        path = []  # the mode held during each holding time of the block
        for k in range(block):  # sequential by nature: each jump leaves the mode reached
            path.append(mode)
            if moving[mode]:
                mode = bisect_right(cdf[mode], u[k])
        path = np.array(path)
        with np.errstate(invalid="ignore"):  # 0 * inf: a zero draw in an absorbing mode
            left = t + np.cumsum(np.where(scale[path] < np.inf, hold * scale[path], np.inf))
        jumps = int(np.searchsorted(left, t_end, side="left"))  # the jumps before t_end
        times.append(left[:jumps])
        modes.append(np.append(path[1:], mode)[:jumps])
        if jumps < block:
            break
        t = float(left[-1])
    return SwitchingSignal(np.concatenate(times) if times else np.zeros(0), np.concatenate(modes))


def _check_rates(rates) -> np.ndarray:
    """A generator matrix: square, finite, off-diagonal entries >= 0, rows summing to zero."""
    Q = float_array(rates, "rates", ndim=2)
    if Q.shape != (Q.shape[0], Q.shape[0]):
        raise ValueError(f"rates must be square, got shape {Q.shape}")
    check_finite(Q, "rates")
    if np.any(Q - np.diag(np.diag(Q)) < 0):
        raise ValueError("rates must have non-negative off-diagonal entries")
    if np.any(np.abs(Q.sum(axis=1)) > 1e-9 * max(1.0, np.abs(Q).max(initial=0.0))):
        raise ValueError(f"rates rows must sum to zero (generator matrix), got {Q.sum(axis=1)}")
    return Q


def _at_samples(t, modes: np.ndarray) -> SwitchingSignal:
    """A signal holding ``modes[k]`` on ``[t[k], t[k+1])``."""
    change = modes[1:] != modes[:-1]
    return SwitchingSignal(t[1:][change], np.concatenate([modes[:1], modes[1:][change]]))


def _sample_times(t) -> np.ndarray:
    t = float_array(t, "t", ndim=1)
    check_finite(t, "t")
    if t.size == 0 or np.any(np.diff(t) <= 0):
        raise ValueError("t must be a non-empty, strictly increasing array of sample times")
    return t


def markov_at_samples(transition, t, *, rng, initial=None) -> SwitchingSignal:
    """A discrete-time Markov chain whose switches happen only at the sample instants ``t``.

    ``transition[i, j]`` = :math:`\\Pr(\\text{mode } j \\text{ at } k+1 \\mid \\text{mode } i
    \\text{ at } k)`, rows sum to 1. ``initial``
    is the mode at ``t[0]`` (an int) or a probability vector to draw it from
    (default: uniform).
    """
    P = check_row_stochastic(transition, "transition")
    n_modes = P.shape[0]
    t = _sample_times(t)
    rng = as_rng(rng)
    initial = _check_initial(initial, n_modes)
    if isinstance(initial, int):
        first = initial
    else:
        p0 = np.full(n_modes, 1.0 / n_modes) if initial is None else initial
        first = int(rng.choice(n_modes, p=p0))
    cum = np.cumsum(P, axis=1)
    draws = rng.random(t.size - 1)
    modes = np.empty(t.size, dtype=np.int64)
    modes[0] = first
    for k in range(1, t.size):  # sequential by nature: a chain
        drawn = int(np.searchsorted(cum[modes[k - 1]], draws[k - 1], side="right"))
        modes[k] = min(drawn, n_modes - 1)
    return _at_samples(t, modes)


def _check_initial(initial, n_modes: int) -> int | np.ndarray | None:
    """A Markov chain's first mode: None (uniform), a mode index, or a probability vector."""
    if initial is None:
        return None
    if np.isscalar(initial):
        return check_mode(initial, n_modes, "initial")
    return check_probability_vector(initial, "initial", n=n_modes)


def iid_at_samples(p, t, *, rng) -> SwitchingSignal:
    """Modes drawn i.i.d. with probabilities ``p`` on each ``[t[k], t[k+1])``.

    The random switching of Wang et al. §2 (switches only at :math:`t = kT`, :math:`\\alpha_k`
    i.i.d.).
    """
    p = check_probability_vector(p, "p")
    t = _sample_times(t)
    modes = as_rng(rng).choice(p.size, size=t.size, p=p)
    return _at_samples(t, modes)


def periodic(T: float, t_end: float, *, t_start: float = 0.0) -> np.ndarray:
    """Sample times ``t_start, t_start + T, ...`` up to and including ``t_end``.

    ``t_end`` is included when it lies on the grid to within a relative ``1e-9``.
    """
    T = positive_scalar(T, "T")
    t_end = _check_span(t_start, t_end)
    _check_events((t_end - float(t_start)) / T, "sample times", "(t_end - t_start) / T")
    count = int(np.floor((t_end - t_start) / T * (1 + 1e-9) + 1e-9)) + 1
    return t_start + T * np.arange(count)


def aperiodic(
    tau_min: float, tau_max: float, t_end: float, *, rng, t_start: float = 0.0
) -> np.ndarray:
    """Sample times with gaps drawn uniformly in ``[tau_min, tau_max]``, up to ``t_end``.

    The aperiodic sampling of Etienne et al. §2
    (:math:`t_{k+1} - t_k \\in [\\tau_{\\min}, \\tau_{\\max}]`).
    """
    lo = positive_scalar(tau_min, "tau_min")
    hi = positive_scalar(tau_max, "tau_max")
    if hi < lo:
        raise ValueError(f"tau_max must be >= tau_min = {lo:g}, got {hi:g}")
    t_end = _check_span(t_start, t_end)
    span = t_end - float(t_start)
    _check_events(span / (0.5 * (lo + hi)), "sample times",
                  "(t_end - t_start) / ((tau_min + tau_max) / 2)")
    drawn = _uniform_increments(float(t_start), t_end, lo, hi, as_rng(rng))
    t = np.concatenate([[float(t_start)], drawn])
    return t[t <= t_end]


def sample_segments(signals, t) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Describe, per trial and sample interval, the modes and switch offsets inside it.

    Parameters
    ----------
    signals : sequence of SwitchingSignal, length N
    t : array_like, shape (K,)
        Strictly increasing sample times.

    Returns
    -------
    mode_at : ndarray of int, shape (N, K)
        :math:`\\sigma(t_k)` for each trial (right-continuous).
    modes : ndarray of int, shape (N, K-1, S+1)
        The modes on the segments of :math:`[t_k, t_{k+1})`; S is the largest number of
        switches inside any one interval.
    offsets : ndarray, shape (N, K-1, S)
        Switch instants inside each interval, measured from :math:`t_k`. Intervals with
        fewer than S switches are padded with offset :math:`t_{k+1} - t_k` and their last
        mode, i.e. with zero-length segments, which leave the transition unchanged.
        This is the input :func:`switchest.discretize.interval` takes.
    """
    t = _sample_times(t)
    if isinstance(signals, SwitchingSignal):
        raise TypeError("signals must be a sequence of SwitchingSignal (one per trial), "
                        "got one signal")
    if not isinstance(signals, Sequence):
        got = type(signals).__name__
        raise TypeError(f"signals must be a sequence of SwitchingSignal, got {got}")
    signals = list(signals)
    if not signals or not all(isinstance(s, SwitchingSignal) for s in signals):
        raise TypeError("signals must be a non-empty sequence of SwitchingSignal objects")
    # one shared signal: compute once, broadcast
    if len(signals) > 1 and all(s is signals[0] for s in signals[1:]):
        one = sample_segments(signals[:1], t)
        return tuple(np.broadcast_to(a, (len(signals), *a.shape[1:])) for a in one)
    N, K = len(signals), t.size
    counts = np.array([s.n_switches for s in signals])
    trial = np.repeat(np.arange(N), counts)
    times = np.concatenate([s.times for s in signals])
    entered = np.concatenate([s.modes[1:] for s in signals])
    # mode at the samples: the number of switches at or before t_k selects the mode
    first_sample_after = np.searchsorted(t, times, side="left")  # samples k with t_k >= s
    hist = np.zeros((N, K + 1), dtype=np.int64)
    np.add.at(hist, (trial, first_sample_after), 1)
    n_before = np.cumsum(hist, axis=1)[:, :K]
    start = np.concatenate([[0], np.cumsum(counts + 1)[:-1]])
    all_modes = np.concatenate([s.modes for s in signals])
    mode_at = all_modes[start[:, None] + n_before]
    # switches strictly inside (t_k, t_{k+1})
    k = first_sample_after - 1
    inside = (k >= 0) & (k < K - 1)
    inside[inside] &= times[inside] < t[k[inside] + 1]
    trial, k, times, entered = trial[inside], k[inside], times[inside], entered[inside]
    key = trial * (K - 1) + k  # sorted, since each trial's times are increasing
    per_interval = np.bincount(key, minlength=N * (K - 1))
    S = int(per_interval.max(initial=0))
    check_memory(8 * N * (K - 1) * (2 * S + 1),
                 f"sample_segments with N = {N} signals, K = {K} samples and up to S = {S} "
                 "switches in one interval (N (K-1) (2S+1) values)")
    group_start = np.concatenate([[0], np.cumsum(per_interval)[:-1]])
    rank = np.arange(key.size) - group_start[key]
    length = np.diff(t)
    offsets = np.broadcast_to(length[None, :, None], (N, K - 1, S)).copy()
    offsets[trial, k, rank] = times - t[k]
    modes = np.empty((N, K - 1, S + 1), dtype=np.int64)
    modes[:, :, 0] = mode_at[:, :-1]
    inner = np.full((N, K - 1, S), -1, dtype=np.int64)
    inner[trial, k, rank] = entered
    for s_ in range(S):  # pad with the last mode: a loop over the (small) switch count only
        modes[:, :, s_ + 1] = np.where(inner[:, :, s_] >= 0, inner[:, :, s_], modes[:, :, s_])
    return mode_at, modes, offsets


def _check_events(expected: float, what: str, how: str) -> None:
    """Refuse more than ``MAX_EVENTS`` expected events; ``how`` writes the estimate in arguments."""
    if not expected <= MAX_EVENTS:
        raise ValueError(
            f"{how} = {expected:.3g} expected {what}, more than the limit MAX_EVENTS = "
            f"{MAX_EVENTS:.0e}; check the units of the rates, dwell times and duration"
        )


def _finite_scalar(value, name: str) -> float:
    arr = float_array(value, name, ndim=0)
    check_finite(arr, name)
    return float(arr)


def _check_span(t_start, t_end) -> float:
    t_start = float_array(t_start, "t_start", ndim=0)
    t_end = float_array(t_end, "t_end", ndim=0)
    if not (np.isfinite(t_start) and np.isfinite(t_end)) or t_end <= t_start:
        raise ValueError(f"t_end must be finite and greater than t_start = {float(t_start):g}, "
                         f"got {float(t_end):g}")
    return float(t_end)
