"""How many threads the estimators' compiled loops use: one process-wide setting.

Each ``run`` of a Gaussian filter splits its batch of trials over threads, in whole blocks of
SIMD lanes, so a trial's numbers are the same on any thread count. The default is every core
this process may run on, or the environment variable ``SWITCHEST_THREADS``; a batch too small
to gain from threads runs on the calling thread. The experiment runner gives each of its
worker processes its share of the cores, so that processes and threads together do not
oversubscribe the machine.
"""

from ..engine import set_threads, threads

__all__ = ["set_threads", "threads"]
