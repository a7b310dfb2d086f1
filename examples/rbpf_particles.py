"""The particle filter's error against its particle count
=========================================================

The Rao-Blackwellized particle filter (:class:`~switchest.estimators.RBPFilter`) samples
mode sequences and runs a Kalman filter along each; its error falls towards that of the
exact posterior as particles are added. On the Markov-jump vehicle of Shankar et al. §V.B
(:func:`switchest.models.vehicle_2d`), this example measures the RMSE of the position
estimates for a range of particle counts, beside the IMM filter (one Kalman filter per mode,
merged at every step).
"""

# %%
# The vehicle and its maneuvers
# -----------------------------
import sys

import numpy as np

from switchest import simulate
from switchest.estimators import IMMFilter, RBPFilter
from switchest.metrics import rmse
from switchest.models import vehicle_2d
from switchest.plotting import curves
from switchest.signals import markov_at_samples

trials = int(sys.argv[1]) if len(sys.argv) > 1 else 20
system = vehicle_2d()
transition = np.array([[0.9, 0.05, 0.05], [0.05, 0.9, 0.05], [0.05, 0.05, 0.9]])
t = 0.5 * np.arange(21)  # 10 s sampled every 0.5 s
u = np.ones((trials, t.size, system.n_inputs))
x0, P0 = np.zeros(system.n_states), 0.01 * np.eye(system.n_states)
traj = simulate(system, lambda rng: markov_at_samples(transition, t, rng=rng), t, x0, u,
                trials=trials, rng=1)

# %%
# RMSE against the number of particles
# ------------------------------------
counts = np.array([5, 10, 20, 50, 100, 200])
position = [0, 2]  # the states x and y
rbpf = np.array([rmse(RBPFilter(system, transition, x0, P0, particles=n, rng=0)
                      .run(traj.y, u, t).x, traj.x).overall[position].mean() for n in counts])
imm = rmse(IMMFilter(system, transition, x0, P0).run(traj.y, u, t).x,
           traj.x).overall[position].mean()
for n, e in zip(counts, rbpf):
    print(f"{n:4d} particles: position RMSE {e:.3f}")
print(f" IMM          : position RMSE {imm:.3f}")

# %%
# The figure
# ----------
curves("figures/rbpf-particles.png", counts,
       {"RBPF": rbpf, "IMM (one filter per mode)": np.full(counts.size, imm)},
       xlabel="particles", ylabel="position RMSE", title=f"RBPF on the vehicle, {trials} trials")
