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
# its small preset (the size of ``switchest run bakeoff --quick``); the tasks' results are
# committed to a store, here a temporary one.
import tempfile
from pathlib import Path

from switchest.experiments import Store, get, run_experiment

experiment = get("bakeoff")
params = experiment.params(quick=True, cases=["boost converter"])
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
# The same figures as ``switchest run bakeoff`` and ``switchest report`` draw.
print(f"{len(summary.figures)} figures:", ", ".join(f.name for f in summary.figures))
