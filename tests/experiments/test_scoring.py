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
