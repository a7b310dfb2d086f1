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
# :func:`switchest.experiments.run_quick` runs the registered experiment at its small preset
# (that of ``switchest run bakeoff --quick``), which the keywords shrink further, in a
# temporary results store, and summarizes it: compared rows, and the figures of
# ``switchest run bakeoff`` and ``switchest report``, drawn into ``figures/``.
from switchest.experiments import run_quick

summary = run_quick("bakeoff", "figures", cases=["boost converter"])

# %%
# The paper's printed values beside ours
# --------------------------------------
# One line per compared quantity: the printed value (``-`` where the paper prints none)
# and the measured one.
print("\n".join(summary.lines()))
