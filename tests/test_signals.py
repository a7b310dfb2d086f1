"""Switching signals: evaluation, generators' contracts, sampling times, segments."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from switchest import signals as sg


def test_at_is_right_continuous_and_vectorized():
    s = sg.SwitchingSignal([1.0, 2.0], [0, 2, 1])
    np.testing.assert_array_equal(s.at([0.0, 1.0, 1.5, 2.0, 9.0]), [0, 2, 2, 1, 1])
    assert s.at(np.zeros((2, 3))).shape == (2, 3)


def test_switches_in_is_strictly_inside():
    s = sg.SwitchingSignal([1.0, 2.0, 3.0], [0, 1, 0, 1])
    times, modes = s.switches_in(1.0, 3.0)
    np.testing.assert_array_equal(times, [2.0])
    np.testing.assert_array_equal(modes, [0])


def test_then_splices_two_signals():
    a = sg.schedule([1.0, 2.0], [0, 1, 0])
    b = sg.schedule([1.5, 3.0], [1, 0, 1])
    c = a.then(b, at=1.7)
    np.testing.assert_array_equal(c.times, [1.0, 1.7, 3.0])
    np.testing.assert_array_equal(c.modes, [0, 1, 0, 1])
    t = np.linspace(0, 4, 401)
    np.testing.assert_array_equal(c.at(t), np.where(t < 1.7, a.at(t), b.at(t)))


@pytest.mark.parametrize(
    "times, modes, match",
    [
        ([1.0, 1.0], [0, 1, 0], "strictly increasing"),
        ([1.0], [0], "one more entry"),
        ([1.0], [0, 0], "must change"),
        ([np.nan], [0, 1], "finite"),
        ([1.0], [0, -1], "non-negative"),
        ([1.0], [0.5, 1], "integers"),
    ],
)
def test_signal_validation(times, modes, match):
    with pytest.raises(ValueError, match=match):
        sg.SwitchingSignal(times, modes)


def test_dwell_time_respects_bounds_and_reproduces():
    s = sg.dwell_time(3, 100.0, 0.9, 1.2, rng=5)
    gaps = np.diff(np.concatenate([[0.0], s.times]))
    assert gaps.min() >= 0.9 and gaps.max() <= 1.2
    assert np.all(s.modes[1:] != s.modes[:-1]) and set(s.modes) == {0, 1, 2}
    again = sg.dwell_time(3, 100.0, 0.9, 1.2, rng=5)
    np.testing.assert_array_equal(s.times, again.times)
    np.testing.assert_array_equal(s.modes, again.modes)


def test_dwell_time_next_mode_is_uniform_among_the_others():
    s = sg.dwell_time(4, 20000.0, 1.0, 1.0, rng=1)
    jumps = (s.modes[1:] - s.modes[:-1]) % 4
    counts = np.bincount(jumps, minlength=4)[1:]
    n = counts.sum()
    # each shift 1..3 has probability 1/3; 5 standard errors
    assert np.all(np.abs(counts / n - 1 / 3) < 5 * np.sqrt((1 / 3) * (2 / 3) / n))


@settings(max_examples=30, deadline=None)
@given(tau_a=st.floats(0.2, 3.0), N0=st.floats(1.0, 4.0), seed=st.integers(0, 2**31))
def test_average_dwell_time_inequality_holds(tau_a, N0, seed):
    s = sg.average_dwell_time(3, 40.0, tau_a, N0, rng=seed)
    t = s.times
    # brute force over every pair of switches: j - i + 1 <= N0 + (t_j - t_i) / tau_a
    i, j = np.triu_indices(t.size)
    assert np.all(j - i + 1 <= N0 + (t[j] - t[i]) / tau_a + 1e-9)


def test_average_dwell_time_checker_catches_chattering():
    burst = sg.SwitchingSignal([1.0, 1.01, 1.02, 1.03], [0, 1, 0, 1, 0])
    assert not sg.satisfies_average_dwell_time(burst, tau_a=1.0, N0=3)
    assert sg.satisfies_average_dwell_time(burst, tau_a=1.0, N0=4)


def test_average_dwell_time_achieves_its_rate_budget():
    tau_a, t_end = 0.5, 2000.0
    s = sg.average_dwell_time(2, t_end, tau_a, 2.0, rng=3, rate=20.0)
    # with attempts far more frequent than 1/tau_a the budget is nearly exhausted
    assert 0.9 * t_end / tau_a < s.n_switches <= 2.0 + t_end / tau_a


def test_markov_continuous_holding_times_and_jumps():
    rates = np.array([[-2.0, 1.5, 0.5], [1.0, -1.0, 0.0], [0.2, 0.8, -1.0]])
    s = sg.markov_continuous(rates, 4000.0, rng=2)
    holds = np.diff(s.times)
    left = s.modes[1:-1]
    for i in range(3):
        h = holds[left == i]
        # exponential holding time with mean 1/q_i: 5 standard errors (std of mean = mean/sqrt(n))
        assert abs(h.mean() - 1 / -rates[i, i]) < 5 / -rates[i, i] / np.sqrt(h.size)
    from_0 = s.modes[1:][s.modes[:-1] == 0]
    p = np.mean(from_0 == 1)
    assert abs(p - 0.75) < 5 * np.sqrt(0.75 * 0.25 / from_0.size)


def test_markov_continuous_validates_generator():
    with pytest.raises(ValueError, match="sum to zero"):
        sg.markov_continuous([[-1.0, 2.0], [1.0, -1.0]], 1.0, rng=0)
    with pytest.raises(ValueError, match="non-negative off-diagonal"):
        sg.markov_continuous([[1.0, -1.0], [1.0, -1.0]], 1.0, rng=0)


def test_markov_at_samples_frequencies_match_asymmetric_transition():
    P = np.array([[0.9, 0.1, 0.0], [0.3, 0.5, 0.2], [0.0, 0.6, 0.4]])
    t = np.arange(60000.0)
    s = sg.markov_at_samples(P, t, rng=4, initial=0)
    m = s.at(t)
    for i in range(3):
        nxt = m[1:][m[:-1] == i]
        freq = np.bincount(nxt, minlength=3) / nxt.size
        se = np.sqrt(P[i] * (1 - P[i]) / nxt.size)
        assert np.all(np.abs(freq - P[i]) <= 5 * se + 1e-12), (i, freq)
    assert np.all(np.isin(s.times, t))


def test_markov_at_samples_rejects_columns_stochastic_matrix():
    with pytest.raises(ValueError, match="rows must sum to 1"):
        sg.markov_at_samples([[0.9, 0.8], [0.1, 0.2]], np.arange(3.0), rng=0)


def test_iid_at_samples_frequencies():
    p = np.array([0.2, 0.5, 0.3])
    t = np.arange(50000.0)
    m = sg.iid_at_samples(p, t, rng=0).at(t)
    freq = np.bincount(m, minlength=3) / t.size
    assert np.all(np.abs(freq - p) < 5 * np.sqrt(p * (1 - p) / t.size))
    with pytest.raises(ValueError, match="p must sum to 1"):
        sg.iid_at_samples([0.5, 0.6], t, rng=0)


def test_sampling_times():
    np.testing.assert_allclose(sg.periodic(0.1, 0.3), [0.0, 0.1, 0.2, 0.3])
    t = sg.aperiodic(0.3, 0.4, 50.0, rng=1)
    gaps = np.diff(t)
    assert t[0] == 0.0 and t[-1] <= 50.0 and t[-1] > 49.6
    assert gaps.min() >= 0.3 and gaps.max() <= 0.4
    with pytest.raises(ValueError, match="tau_max must be >= tau_min"):
        sg.aperiodic(0.4, 0.3, 1.0, rng=0)
    with pytest.raises(ValueError, match="T must be a finite positive"):
        sg.periodic(-1.0, 1.0)


def test_sample_segments_describes_each_interval():
    a = sg.schedule([1.0, 2.2, 2.5], [0, 1, 0, 2])
    b = sg.schedule([0.5], [1, 0])
    mode_at, modes, offsets = sg.sample_segments([a, b], np.arange(5.0))
    np.testing.assert_array_equal(mode_at, [[0, 1, 1, 2, 2], [1, 0, 0, 0, 0]])
    np.testing.assert_array_equal(modes[0, 2], [1, 0, 2])
    np.testing.assert_allclose(offsets[0, 2], [0.2, 0.5])
    np.testing.assert_array_equal(modes[1, 0], [1, 0, 0])  # padded with the last mode
    np.testing.assert_allclose(offsets[1, 0], [0.5, 1.0])  # padded with the interval length


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31))
def test_sample_segments_agrees_with_pointwise_evaluation(seed):
    rng = np.random.default_rng(seed)
    sigs = [sg.dwell_time(3, 10.0, 0.05, 0.7, rng=rng) for _ in range(4)]
    t = np.sort(rng.uniform(0, 10, 12))
    mode_at, modes, offsets = sg.sample_segments(sigs, t)
    for n, s in enumerate(sigs):
        np.testing.assert_array_equal(mode_at[n], s.at(t))
        for k in range(t.size - 1):
            times, entered = s.switches_in(t[k], t[k + 1])
            c = times.size
            np.testing.assert_allclose(offsets[n, k, :c], times - t[k])
            np.testing.assert_array_equal(modes[n, k, 1 : c + 1], entered)
