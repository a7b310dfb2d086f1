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
# its small preset (that of ``switchest run zhang-example1 --quick``), which the keywords after it
# shrink further; the tasks' results are committed to a store, here a temporary one.
import tempfile
from pathlib import Path

from switchest.experiments import Store, get, run_experiment

experiment = get("zhang-example1")
params = experiment.params(quick=True, trials=400, block_size=200)
with tempfile.TemporaryDirectory() as folder:
    store = Store(Path(folder) / "results.sqlite")
    results = run_experiment(experiment, params, store=store)

# %%
# The figures
# -----------
# ``summarize`` turns the results into compared rows and draws the figures of
# ``switchest run zhang-example1`` and ``switchest report``.
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
