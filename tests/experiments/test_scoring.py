"""Monte Carlo summaries merged from blocks equal those of all trials at once."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from switchest.experiments.scoring import blocks, mean_and_se, merge_blocks


@settings(max_examples=50, deadline=None)
@given(st.integers(2, 40), st.integers(1, 7), st.integers(0, 2**32 - 1))
def test_mean_and_se_from_merged_blocks_are_numpys_over_all_trials(trials, block_size, seed):
    x = np.random.default_rng(seed).normal(3.0, 2.0, size=(trials, 4))
    sizes = [n for _, n in blocks(trials, block_size)]
    parts = [{"sum": part.sum(axis=0).tolist(), "sq": (part**2).sum(axis=0).tolist()}
             for part in np.split(x, np.cumsum(sizes)[:-1])]
    total = merge_blocks(parts)
    mean, se = mean_and_se(total["sum"], total["sq"], trials)
    np.testing.assert_allclose(mean, x.mean(axis=0), rtol=1e-12, atol=1e-12)
    expected = x.std(axis=0, ddof=1) / np.sqrt(trials)
    np.testing.assert_allclose(se, expected, rtol=1e-7, atol=1e-12)


def test_rmse_standard_error_matches_the_spread_over_repeated_experiments():
    """The delta-method SE of the pooled RMSE against the RMSE's scatter over 400 repeated
    experiments of 50 trials; the scatter's own relative error is about 1/sqrt(2 * 399) =
    3.5 %, so 15 % is four of them."""
    from types import SimpleNamespace

    from switchest.experiments.scoring import rmse_and_se, score

    rng = np.random.default_rng(11)
    rmse, se = [], []
    for _ in range(400):
        truth = SimpleNamespace(x=np.zeros((50, 30, 2)), n_trials=50)
        scale = np.array([1.0, 3.0]) * rng.uniform(0.5, 1.5, size=(50, 1, 1))  # unequal trials
        est = SimpleNamespace(x=rng.normal(size=(50, 30, 2)) * scale, mode=None,
                              switch_time=None)
        halves = [score(SimpleNamespace(x=est.x[a:b], mode=None, switch_time=None),
                        SimpleNamespace(x=truth.x[a:b], n_trials=b - a), start=5)
                  for a, b in ((0, 20), (20, 50))]
        r, s = rmse_and_se(merge_blocks(halves))
        rmse.append(r)
        se.append(s)
    scatter, predicted = np.std(rmse, axis=0, ddof=1), np.mean(se, axis=0)
    np.testing.assert_allclose(predicted, scatter, rtol=0.15)
    assert np.all(np.isnan(rmse_and_se({"sse": [1.0], "count": 3, "trials": 1})[1]))
