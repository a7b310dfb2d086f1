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
# its small preset (the size of ``switchest run etienne-sync --quick``); the tasks' results are
# committed to a store, here a temporary one.
import tempfile
from pathlib import Path

from switchest.experiments import Store, get, run_experiment

experiment = get("etienne-sync")
params = experiment.params(quick=True, trials=100, block_size=50)
with tempfile.TemporaryDirectory() as folder:
    results = run_experiment(experiment, params, store=Store(Path(folder) / "results.sqlite"))

# %%
# The paper's printed values beside ours
# --------------------------------------
# Each row is one compared quantity: the printed value (``-`` where the paper prints none)
# and the measured one.
summary = experiment.summarize(params, results, Path("figures"))
for row in summary.rows:
    measured = f"{row.measured:.4g}" if isinstance(row.measured, float) else row.measured
    print(f"{row.quantity[:70]:70s}  paper {row.paper if row.paper is not None else '-'!s:>8}"
          f"  ours {measured} {row.unit}")

# %%
# The figures
# -----------
# The same figures as ``switchest run etienne-sync`` and ``switchest report`` draw.
print(f"{len(summary.figures)} figures:", ", ".join(f.name for f in summary.figures))
