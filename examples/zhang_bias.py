"""Zhang & Natarajan: the bias of the Kalman filter under mode mismatch, and its bound
===================================================================================

A Kalman filter told the wrong mode is biased. Zhang & Natarajan give the mean of its error
under a random mode mismatch of probability ``P`` (eq. (9),
:func:`switchest.analysis.bias_recursion`), a bound on it (Theorem 4,
:func:`switchest.analysis.mismatch_bias_bound`) and the largest mismatch probability that keeps
the bias below a tolerance ``B`` (:func:`switchest.analysis.max_mismatch_probability`). The
``zhang-example1`` reproduction computes them on the two-mode system of Example 1
(:func:`switchest.models.zhang_two_mode`) and checks eq. (9) against a Monte Carlo run of the
mismatched filter (Figs. 3-6).
"""

# %%
# Run the reproduction at a small size
# ------------------------------------
# :func:`switchest.experiments.get` gives the registered experiment, ``params(quick=True)``
# its small preset (the size of ``switchest run zhang-example1 --quick``); the tasks' results are
# committed to a store, here a temporary one.
import tempfile
from pathlib import Path

from switchest.experiments import Store, get, run_experiment

experiment = get("zhang-example1")
params = experiment.params(quick=True, trials=400, block_size=200)
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
# The same figures as ``switchest run zhang-example1`` and ``switchest report`` draw.
print(f"{len(summary.figures)} figures:", ", ".join(f.name for f in summary.figures))
