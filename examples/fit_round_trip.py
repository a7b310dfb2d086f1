"""A fit round trip: simulate, fit, compare with the standard errors
====================================================================

:func:`switchest.learn.fit` (``switchest fit``) estimates the mode transition matrix and the
noise covariances of a switched linear system from its measurements alone, the modes unknown,
by expectation-maximization, and gives the standard error of each parameter from the observed
information. This example simulates a scalar system with two modes, fits it from a wrong
starting point, and compares the fitted parameters with the true ones: about 95 % of them
should lie within 1.96 standard errors.
"""

# %%
# The true system and its data
# ----------------------------
# :math:`x_{k+1} = a_j x_k + w_k`, :math:`w_k \sim \mathcal{N}(0, Q_j)`,
# :math:`y_k = x_k + v_k`, :math:`v_k \sim \mathcal{N}(0, R_j)`.
import sys

import numpy as np

from switchest import SwitchedLinearSystem, simulate
from switchest.learn import fit
from switchest.plotting import bars
from switchest.signals import markov_at_samples


def scalar_system(Q, R):
    return SwitchedLinearSystem(
        A=np.array([[[0.9]], [[-0.5]]]), B=np.zeros((2, 1, 1)), C=np.ones((2, 1, 1)),
        Q=np.reshape(Q, (2, 1, 1)), R=np.reshape(R, (2, 1, 1)), domain="discrete", dt=1.0)


trials = int(sys.argv[1]) if len(sys.argv) > 1 else 20
truth = {"Q": np.array([0.5, 2.0]), "R": np.array([0.2, 0.2])}
transition = np.array([[0.9, 0.1], [0.2, 0.8]])
t = np.arange(200, dtype=float)
traj = simulate(scalar_system(truth["Q"], truth["R"]),
                lambda rng: markov_at_samples(transition, t, rng=rng), t, np.zeros(1),
                trials=trials, rng=7)

# %%
# Fit from a wrong start
# ----------------------
# Every noise variance starts at 1 and the transition matrix at 0.5 everywhere; ``A`` and
# ``C`` are taken as known.
start = scalar_system([1.0, 1.0], [1.0, 1.0])
result = fit(start, traj.y, t=t, transition=np.full((2, 2), 0.5), x0=np.zeros(1),
             P0=np.eye(1), estimate=("transition", "Q", "R"))
print(f"{result.iterations} iterations, converged: {result.converged}")

# %%
# Fitted against true, with standard errors
# -----------------------------------------
names = ["P(0→1)", "P(1→0)", "Q_0", "Q_1", "R_0", "R_1"]
true = np.array([transition[0, 1], transition[1, 0], *truth["Q"], *truth["R"]])
fitted = np.array([result.transition[0, 1], result.transition[1, 0],
                   *result.system.Q[:, 0, 0], *result.system.R[:, 0, 0]])
se = np.array([result.se["transition"][0, 1], result.se["transition"][1, 0],
               *result.se["Q"][:, 0, 0], *result.se["R"][:, 0, 0]])
z = (fitted - true) / se
for name, a, b, s, zi in zip(names, true, fitted, se, z):
    print(f"{name:7s} true {a:.3f}  fitted {b:.3f} ± {s:.3f}  ({zi:+.1f} s.e.)")
bars("figures/fit.png", names, {"true": true, "fitted": fitted},
     errors={"fitted": 1.96 * se}, ylabel="value",
     title=f"EM fit of {trials} records of {t.size} samples (bars: 1.96 s.e.)")
