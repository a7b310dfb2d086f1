"""Filtered and smoothed mode probabilities against the exact posterior
======================================================================

On a short record the posterior of the mode sequence can be computed exactly: the exact
mixture filter (:class:`~switchest.estimators.ExactMixtureFilter`) keeps one Kalman filter
per mode sequence, ``L^K`` of them. The IMM filter keeps one per mode and merges them at
every step; its smoother (:meth:`~switchest.estimators.ModeBankFilter.smooth`) runs a
backward pass over the filter's results. This example compares the probability of mode 1
that each gives, at every sample, on a scalar system with two modes of very different
dynamics.
"""

# %%
# A scalar system with two modes
# ------------------------------
# :math:`x_{k+1} = a_j x_k + w_k` with :math:`a_0 = 0.5` (fast decay, small noise) and
# :math:`a_1 = 1` (random walk, large noise), measured with unit noise; the mode is a Markov
# chain.
import sys

import numpy as np

from switchest import SwitchedLinearSystem, simulate
from switchest.estimators import ExactMixtureFilter, IMMFilter
from switchest.plotting import curves
from switchest.signals import markov_at_samples

K = int(sys.argv[1]) if len(sys.argv) > 1 else 12  # samples: 2^12 sequences for the exact one
system = SwitchedLinearSystem(
    A=np.array([[[0.5]], [[1.0]]]), B=np.zeros((2, 1, 1)), C=np.ones((2, 1, 1)),
    Q=np.array([[[0.05]], [[1.0]]]), R=np.array([[[0.3]], [[0.3]]]), domain="discrete", dt=1.0)
transition = np.array([[0.85, 0.15], [0.2, 0.8]])
t = np.arange(K, dtype=float)
traj = simulate(system, lambda rng: markov_at_samples(transition, t, rng=rng), t,
                np.zeros(1), trials=1, rng=3)
x0, P0 = np.zeros(1), np.eye(1)

# %%
# The exact posterior, the IMM filter and its smoother
# ----------------------------------------------------
exact = ExactMixtureFilter(system, transition, x0, P0)
imm = IMMFilter(system, transition, x0, P0)
probabilities = {
    "exact filter": exact.run(traj.y, t=t).mode_prob[0, :, 1],
    "exact smoother": exact.smooth(traj.y, t=t).mode_prob[0, :, 1],
    "IMM filter": imm.run(traj.y, t=t).mode_prob[0, :, 1],
    "IMM smoother": imm.smooth(traj.y, t=t).mode_prob[0, :, 1],
}
gap = {name: np.max(np.abs(p - probabilities[f"exact {name.split()[1]}"]))
       for name, p in probabilities.items() if name.startswith("IMM")}
for name, g in gap.items():
    print(f"{name}: largest gap to the exact posterior {g:.3f}")

# %%
# The probability of mode 1 at each sample
# ----------------------------------------
# The smoothed probabilities use the samples after ``k`` too: they are nearer 0 or 1 than
# the filtered ones, and nearer the true mode (black).
curves("figures/smoother-exact.png", t,
       {"true": traj.mode[0].astype(float), **probabilities}, xlabel="sample k",
       ylabel="P(mode 1)", title="Mode probabilities: IMM against the exact posterior")
