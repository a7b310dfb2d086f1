"""Shankar et al. Table I: RMSE against the switching-time grid
===============================================================

Table I of Shankar, Yang & Hespanha prints the RMSE of the switch-time Kalman filter on the
boost converter (§V.A) for ``g = 1 .. 5`` grid points per sample interval (eq. (23)): the finer
the grid, the nearer each switch is placed to its true instant, and the smaller the error. This
example computes the same table with the reproduction's recipe
(:func:`switchest.experiments.shankar.table1_estimate`,
:class:`~switchest.models.shankar.BoostTable1`) at a small size, beside the printed values and
the clairvoyant filter that knows the true switching instants.

The paper's size is 100 trials x 10 s (``switchest run shankar-table1``, most of an hour);
``python examples/shankar_table1.py TRIALS DURATION`` chooses another.
"""

# %%
# Simulate the converter
# ----------------------
import sys

import numpy as np

from switchest.experiments.shankar import TABLE1_PAPER, table1_estimate
from switchest.metrics import rmse
from switchest.models.shankar import BoostTable1
from switchest.plotting import curves

trials = int(sys.argv[1]) if len(sys.argv) > 1 else 4
duration = float(sys.argv[2]) if len(sys.argv) > 2 else 0.25  # seconds
grids = np.array(TABLE1_PAPER["g"])  # 1, 2, 3, 4, 5
setting = BoostTable1()
traj = setting.simulate(duration, trials, 2019)

# %%
# The switch-time filter on each grid, and the clairvoyant filter
# ---------------------------------------------------------------
# RMSE of ``(i_L, v_0)`` over the trials and the samples after the transient.
def score(method, g=None):
    est = table1_estimate(setting, method, traj, g=g)
    return rmse(est.x, traj.x, start=setting.transient).overall


grid_rmse = np.array([score("grid", g) for g in grids])  # (5, 2)
clairvoyant = score("clairvoyant")
paper = np.array([TABLE1_PAPER["i_L"], TABLE1_PAPER["v_0"]], dtype=float).T  # printed digits
print(" g   paper i_L  ours i_L   paper v_0  ours v_0")
for g, ours, printed in zip(grids, grid_rmse, paper):
    print(f"{g:2d}  {printed[0]:9.3g} {ours[0]:9.3g}   {printed[1]:9.3g} {ours[1]:9.3g}")
print(f"clairvoyant: i_L {clairvoyant[0]:.3g} A, v_0 {clairvoyant[1]:.3g} V")

# %%
# The table as a figure
# ---------------------
# The printed values are black triangles. At this size (a few trials of a quarter
# second) the measured RMSE is noisy, but it falls with ``g`` as the paper's does. (The
# clairvoyant filter's error, printed above, is a hundred times smaller: off this scale.)
curves("figures/table1.png", grids, {"switch-time KF (eq. (23))": grid_rmse},
       xlabel="grid points g per sample interval", ylabel=["i_L RMSE (A)", "v_0 RMSE (V)"],
       paper={"Table I": (grids, paper)},
       title=f"Table I, boost converter: {trials} trials x {duration:g} s")
