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
# :func:`switchest.experiments.run_quick` runs the registered experiment at its small preset
# (that of ``switchest run etienne-sync --quick``), which the keywords shrink further, in a
# temporary results store, and summarizes it: compared rows, and the figures of
# ``switchest run etienne-sync`` and ``switchest report``, drawn into ``figures/``.
from switchest.experiments import run_quick

summary = run_quick("etienne-sync", "figures", trials=100, block_size=50)

# %%
# The paper's printed values beside ours
# --------------------------------------
# One line per compared quantity: the printed value (``-`` where the paper prints none)
# and the measured one.
print("\n".join(summary.lines()))
