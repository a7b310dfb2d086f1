"""The boost converter: switch-time filter, IMM and GPB2 against the truth
=========================================================================

The boost converter of Shankar, Yang & Hespanha §V.A
(:func:`switchest.models.boost_converter`) switches between its two modes every 0.9 to
1.2 ms while its output voltage ``v_0`` is sampled every T = 0.5 ms: several switches fall
between two samples, at instants no sample sees. Three filters estimate the inductor current
``i_L`` and ``v_0`` from the same record:

* the switch-time Kalman filter (:class:`~switchest.estimators.SwitchTimeKalmanFilter`), told
  the mode at each sample, which places each switch on a grid of ``g`` instants inside its
  interval (Shankar et al., eq. (23));
* the IMM filter (:class:`~switchest.estimators.IMMFilter`) and the GPB2 filter
  (:class:`~switchest.estimators.GPB2Filter`), which are told nothing about the modes and
  assume the switches happen at the samples.

The setting (process noise, prior, the IMM's switch probability) is that of the Table I
reproduction, :class:`switchest.models.shankar.BoostTable1`.
"""

# %%
# Simulate a few trials of the converter
# --------------------------------------
import sys

import numpy as np

from switchest.estimators import GPB2Filter, IMMFilter, SwitchTimeKalmanFilter
from switchest.metrics import rmse
from switchest.models.shankar import BoostTable1
from switchest.plotting import bars, curves

duration = float(sys.argv[1]) if len(sys.argv) > 1 else 0.05  # seconds of operation
setting = BoostTable1()
system, (x0, P0), u = setting.system(), setting.prior, setting.input
traj = setting.simulate(duration, 4, 0)  # 4 trials, seed 0
print(f"{traj.t.size} samples of {traj.y.shape[0]} trials")

# %%
# Run the three filters on the same measurements
# ----------------------------------------------
# The switch-time filter is told the true mode at each sample; the two mixture filters get
# only the transition matrix of the modes.
transition = np.array(setting.transition)
estimates = {
    "switch-time KF, g = 5": SwitchTimeKalmanFilter(system, x0, P0, grid=5).run(
        traj.y, u, traj.t, modes=traj.mode),
    # beyond the paper: the grid's instants weighed by their likelihood, so that the
    # covariance also counts the uncertainty of the instant (what `switchest estimate` runs)
    "switch-time KF, g = 5, merged": SwitchTimeKalmanFilter(
        system, x0, P0, grid=5, switch_time="marginal").run(traj.y, u, traj.t, modes=traj.mode),
    "IMM": IMMFilter(system, transition, x0, P0).run(traj.y, u, traj.t),
    "GPB2": GPB2Filter(system, transition, x0, P0).run(traj.y, u, traj.t),
}

# %%
# The estimates of one trial beside the truth
# -------------------------------------------
# A window of 5 ms after the transient: the switch-time filter follows the current's ramps
# within a sample; the filters that put each switch at a sample lag behind them.
window = (traj.t >= 0.02) & (traj.t <= 0.025)
series = {"true": traj.x[0, window]}
series |= {name: est.x[0, window] for name, est in estimates.items()}
curves("figures/boost-trial.png", 1e3 * traj.t[window], series, xlabel="t (ms)",
       ylabel=["i_L (A)", "v_0 (V)"], title="Boost converter, trial 0")

# %%
# The error over every trial
# --------------------------
# The root-mean-square error of each state after the transient (``setting.transient``
# samples), over the four trials.
errors = {name: rmse(est.x, traj.x, start=setting.transient).overall
          for name, est in estimates.items()}
for name, e in errors.items():
    print(f"{name:30s} i_L {e[0]:6.2f} A   v_0 {e[1]:6.2f} V")
bars("figures/boost-rmse.png", ["i_L (A)", "v_0 (V)"],
     {name: e for name, e in errors.items()}, ylabel="RMSE", title="RMSE after the transient")
