"""The engine's thread split: whole lane blocks per thread, so every output is the same whatever
the thread count (same machine, same code: equal to the bit), and the merged report is the
first failing range's status, the repairs summed, the smallest eigenvalue over all."""


import numpy as np
import pytest

from switchest import models, signals, simulate
from switchest.engine import _parallel
from switchest.estimators import GPB2Filter, IMMFilter, ModeKalmanFilter, set_threads


@pytest.fixture
def split_every_batch(monkeypatch):
    monkeypatch.setattr(_parallel, "MIN_WORK", 1)  # small test batches split too
    yield
    set_threads(None)


def test_estimates_do_not_depend_on_the_thread_count(split_every_batch):
    system = models.boost_converter()
    t = signals.periodic(0.5e-3, 0.1)[:60]
    traj = simulate(system, lambda rng: models.boost_switching(rng, t_end=0.1), t,
                    x0=np.array([0.0, 100.0]), u=np.array([100.0]), trials=53, rng=3)
    x0, P0 = np.array([0.0, 100.0]), np.diag([100.0, 100.0])
    stay = np.array([[0.9, 0.1], [0.2, 0.8]])
    filters = [(ModeKalmanFilter(system, x0, P0), {"modes": traj.mode}),
               (IMMFilter(system, stay, x0, P0), {}), (GPB2Filter(system, stay, x0, P0), {})]
    for est, kw in filters:
        set_threads(1)
        one = est.run(traj.y, [100.0], t, **kw)
        set_threads(3)
        three = est.run(traj.y, [100.0], t, **kw)
        np.testing.assert_array_equal(three.x, one.x)
        np.testing.assert_array_equal(three.P, one.P)


def test_ranges_are_whole_blocks_and_reports_merge(split_every_batch):
    set_threads(3)
    seen = []

    def run_range(begin, end):
        seen.append((begin, end))
        return (2 if begin >= 32 else 0), end - begin, -float(begin)

    status, repaired, smallest = _parallel.over_trials(run_range, 70, 10, block=16)
    # five blocks, at most CHUNKS ranges per thread: a range per block, taken in turn
    assert sorted(seen) == [(0, 16), (16, 32), (32, 48), (48, 64), (64, 70)]
    assert (status, repaired, smallest) == (2, 70, -64.0)


def test_many_blocks_make_a_few_ranges_per_thread(split_every_batch):
    set_threads(2)
    seen = []

    def run_range(begin, end):
        seen.append((begin, end))
        return 0, 0, float("inf")

    _parallel.over_trials(run_range, 1000, 10, block=16)  # 63 blocks
    seen.sort()
    assert len(seen) == 2 * _parallel.CHUNKS
    assert seen[0][0] == 0 and seen[-1][1] == 1000
    assert all(a % 16 == 0 and a == b_prev for (a, _), (_, b_prev) in zip(seen[1:], seen))


def test_a_bad_thread_count_is_refused():
    for bad in (0, -1, 1.5, True):
        with pytest.raises(ValueError, match="threads must be a positive integer"):
            set_threads(bad)
