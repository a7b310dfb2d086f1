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
# its small preset (that of ``switchest run lee-detection --quick``), which the keywords after it
# shrink further; the tasks' results are committed to a store, here a temporary one.
import sys
import tempfile
from pathlib import Path

from switchest.experiments import Store, get, run_experiment

trials = int(sys.argv[1]) if len(sys.argv) > 1 else 20
experiment = get("lee-detection")
params = experiment.params(quick=True, trials=trials, block_size=trials)
with tempfile.TemporaryDirectory() as folder:
    store = Store(Path(folder) / "results.sqlite")
    results = run_experiment(experiment, params, store=store)

# %%
# The figures
# -----------
# ``summarize`` turns the results into compared rows and draws the figures of
# ``switchest run lee-detection`` and ``switchest report``.
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
