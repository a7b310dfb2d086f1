"""Etienne et al.: the impulsive observer and its certified decay rate
=====================================================================

The impulsive observer of Etienne, Di Gennaro & Barbot
(:class:`~switchest.estimators.ImpulsiveObserver`) corrects its estimate by jumps at the
measurement instants. The LMIs of the paper
(:func:`switchest.analysis.impulsive_observer_search`) certify an exponential decay rate of its
error for every switching signal with dwell times in the allowed range; the ``etienne-sync``
reproduction checks the paper's gains, searches its own, and measures the decay of the error on
many simulated switching signals against the certified envelope (Fig. 1).
"""

# %%
# Run the reproduction at a small size
# ------------------------------------
# :func:`switchest.experiments.get` gives the registered experiment, ``params(quick=True)``
# its small preset (that of ``switchest run etienne-sync --quick``), which the keywords after it
# shrink further; the tasks' results are committed to a store, here a temporary one.
import tempfile
from pathlib import Path

from switchest.experiments import Store, get, run_experiment

experiment = get("etienne-sync")
params = experiment.params(quick=True, trials=100, block_size=50)
with tempfile.TemporaryDirectory() as folder:
    store = Store(Path(folder) / "results.sqlite")
    results = run_experiment(experiment, params, store=store)

# %%
# The figures
# -----------
# ``summarize`` turns the results into compared rows and draws the figures of
# ``switchest run etienne-sync`` and ``switchest report``.
summary = experiment.summarize(params, results, Path("figures"))

# %%
# The paper's printed values beside ours
# --------------------------------------
# One line per compared quantity: the printed value (``-`` where the paper prints none)
# and the measured one.
for row in summary.rows:
    ours = f"{row.measured:.4g}" if isinstance(row.measured, float) else row.measured
    paper = "-" if row.paper is None else row.paper
    print(f"{row.quantity[:64]:64s} paper {paper!s:>9}  ours {ours} {row.unit}")
