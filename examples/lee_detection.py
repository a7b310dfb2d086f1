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
# :func:`switchest.experiments.run_quick` runs the registered experiment at its small preset
# (that of ``switchest run lee-detection --quick``), which the keywords shrink further, in a
# temporary results store, and summarizes it: compared rows, and the figures of
# ``switchest run lee-detection`` and ``switchest report``, drawn into ``figures/``.
import sys

from switchest.experiments import run_quick

trials = int(sys.argv[1]) if len(sys.argv) > 1 else 20
summary = run_quick("lee-detection", "figures", trials=trials, block_size=trials)

# %%
# The paper's printed values beside ours
# --------------------------------------
# One line per compared quantity: the printed value (``-`` where the paper prints none)
# and the measured one.
print("\n".join(summary.lines()))
