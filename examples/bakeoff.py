"""The bake-off: every method on one system
=========================================

Every registered estimation method (:func:`switchest.estimators.methods`) that applies to a
system runs on the same simulated data: the Kalman filter told the modes, the switch-time
filter, IMM, GPB1, GPB2 and their smoothers, the particle filter, IMM-EV1, and where their
assumptions allow it the detectors and observers of Lee, Wang and Etienne. The ``bakeoff``
reproduction scores each on five systems (RMSE, mode accuracy, switching-time error, run
time); this example runs it on the boost converter only.
"""

# %%
# Run the reproduction at a small size
# ------------------------------------
# :func:`switchest.experiments.get` gives the registered experiment, ``params(quick=True)``
# its small preset (that of ``switchest run bakeoff --quick``), which the keywords after it
# shrink further; the tasks' results are committed to a store, here a temporary one.
import tempfile
from pathlib import Path

from switchest.experiments import Store, get, run_experiment

experiment = get("bakeoff")
params = experiment.params(quick=True, cases=["boost converter"])
with tempfile.TemporaryDirectory() as folder:
    store = Store(Path(folder) / "results.sqlite")
    results = run_experiment(experiment, params, store=store)

# %%
# The figures
# -----------
# ``summarize`` turns the results into compared rows and draws the figures of
# ``switchest run bakeoff`` and ``switchest report``.
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
