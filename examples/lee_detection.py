"""Lee, Ping & Shim: switch detection within a guaranteed delay
================================================================

The minimum-distance detector of Lee, Ping & Shim
(:class:`~switchest.estimators.MinimumDistanceDetector`) estimates the mode of a switched
system from a window of ``delta`` seconds of bounded-noise measurements, and Theorem 2
guarantees that each switch is declared within ``Delta`` of happening, with no false
declaration, when Assumptions 1-3 hold (:func:`switchest.analysis.lee_assumptions`). The paper
prints no example; the ``lee-detection`` reproduction runs the whole algorithm on the phasor of
:data:`switchest.models.lee.LEE_SCENARIO` (frequency 1 Hz or 2 Hz, ``delta = 0.25`` s, ``Delta
= 1`` s) at growing noise levels, and at noise above the bound the detector was told.
"""

# %%
# Run the reproduction at a small size
# ------------------------------------
# :func:`switchest.experiments.get` gives the registered experiment, ``params(quick=True)``
# its small preset (the size of ``switchest run lee-detection --quick``); the tasks' results are
# committed to a store, here a temporary one.
import sys
import tempfile
from pathlib import Path

from switchest.experiments import Store, get, run_experiment

trials = int(sys.argv[1]) if len(sys.argv) > 1 else 20
experiment = get("lee-detection")
params = experiment.params(quick=True, trials=trials, block_size=trials)
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
# The same figures as ``switchest run lee-detection`` and ``switchest report`` draw.
print(f"{len(summary.figures)} figures:", ", ".join(f.name for f in summary.figures))
