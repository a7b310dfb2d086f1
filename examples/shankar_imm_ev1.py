"""IMM-EV1: the switching instants of the vehicle maneuver
==========================================================

Algorithm 1 of Shankar, Yang & Hespanha (:class:`~switchest.estimators.IMMEV1Filter`)
estimates the modes *and* the instant of each switch inside its sample interval, on a grid of
``g`` instants. On the maneuver of §V.B (:func:`switchest.models.vehicle_maneuver`: mode 1,
then 2 at 1.65 s, 3 at 2.75 s and 1 again at 3.9 s, sampled every 0.5 s) this example runs it
with ``g = 10``, measures how far the estimated instants fall from the true ones, and draws one
trial's estimate with them. Without a prior on the modes (Algorithm 1
as printed) the filter also declares many switches that did not happen: the
``shankar-vehicle`` reproduction (:doc:`/papers/shankar`) studies why.
"""

# %%
# The maneuver, and the filter
# ----------------------------
import sys

import numpy as np

from switchest import simulate
from switchest.estimators import IMMEV1Filter
from switchest.metrics import switch_time_error
from switchest.models import vehicle_2d, vehicle_maneuver
from switchest.plotting import estimate_figure

trials = int(sys.argv[1]) if len(sys.argv) > 1 else 50
system, maneuver = vehicle_2d(), vehicle_maneuver()
x0, P0 = np.zeros(4), 0.01 * np.eye(4)
traj = simulate(system, maneuver.signal, maneuver.t, x0, u=maneuver.u, trials=trials, rng=2019)
# Algorithm 1 as printed: no transition matrix, every mode equally likely at each step
est = IMMEV1Filter(system, x0=x0, P0=P0, grid=10).run(traj.y, maneuver.u, maneuver.t)

# %%
# How far the estimated instants fall from the true ones
# ------------------------------------------------------
# ``est.switch_time[n, k]`` is the instant the filter places in interval ``k`` of trial
# ``n`` (NaN where it sees no switch); :func:`switchest.metrics.switch_time_error` pairs
# them with the true ones.
true = traj.switch_times()
errors = switch_time_error(est.switch_time, true)
found = np.isfinite(est.switch_time)
false = np.sum(found & ~np.isfinite(true)) / trials
print(f"{errors.size} of the {3 * trials} switches found in their interval, median |error| "
      f"{np.median(errors):.3f} s of a 0.5 s interval; {false:.1f} false switches per trial")

# %%
# One trial
# ---------
# The positions and velocities with their bands, and the estimated switching instants as
# ticks along the bottom; the true switches are at 1.65, 2.75 and 3.9 s. (Without a
# transition matrix the filter's ``mode_prob`` stays at 1/3 for every mode, so the figure
# leaves out the mode strip.)
estimate_figure("figures/imm-ev1-trial.png", maneuver.t, est.x[0],
                std=np.sqrt(np.diagonal(est.P[0], axis1=-2, axis2=-1)), truth=traj.x[0],
                switch_times=est.switch_time[0][np.isfinite(est.switch_time[0])],
                names=["x", "dx/dt", "y", "dy/dt"], title="IMM-EV1, g = 10, trial 0")
