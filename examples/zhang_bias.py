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
# :func:`switchest.experiments.run_quick` runs the registered experiment at its small preset
# (that of ``switchest run zhang-example1 --quick``), which the keywords shrink further, in a
# temporary results store, and summarizes it: compared rows, and the figures of
# ``switchest run zhang-example1`` and ``switchest report``, drawn into ``figures/``.
from switchest.experiments import run_quick

summary = run_quick("zhang-example1", "figures", trials=400, block_size=200)

# %%
# The paper's printed values beside ours
# --------------------------------------
# One line per compared quantity: the printed value (``-`` where the paper prints none)
# and the measured one.
print("\n".join(summary.lines()))
