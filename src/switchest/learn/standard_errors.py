"""Standard errors of the fitted noise covariances from the observed information.

The observed information is the negative Hessian of the log-likelihood at the optimum with
respect to the free entries of ``Q`` and ``R`` (the upper triangle of each fitted block), taken
by central finite differences of the filter's summed log-likelihood (Efron & Hinkley 1978,
Biometrika 65, "Assessing the accuracy of the maximum likelihood estimator: observed versus
expected Fisher information"); the standard errors are the square roots of the diagonal of its
inverse. With known modes the likelihood is exact (the Kalman filter along the modes); with
unknown modes it is the approximation of the E-step (:mod:`~switchest.learn.expectation`),
and the standard errors are those of that approximate likelihood. Each step is ``1e-3`` of
the entry's scale ``sqrt(V_aa V_bb)``: the truncation error is ``O(1e-6)`` relative, far above
the rounding of the summed likelihood.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable

import numpy as np

from ..system import SwitchedLinearSystem
from .noise_step import shared, support

__all__ = ["noise_standard_errors"]

_REL_STEP = 1e-3


def _free(system: SwitchedLinearSystem, names) -> list[tuple[str, list[int], int, int]]:
    """The free entries: ``(matrix name, modes sharing it, a, b)`` with ``a <= b`` in the
    matrix's support, per mode or once for a shared matrix."""
    out = []
    for name in names:
        stack = getattr(system, name)
        groups = [list(range(stack.shape[0]))] if shared(stack) else [[j] for j in
                                                                        range(stack.shape[0])]
        for group in groups:
            idx = support(stack[group[0]])
            out += [(name, group, int(idx[a]), int(idx[b])) for a in range(idx.size)
                    for b in range(a, idx.size)]
    return out


def _with(system: SwitchedLinearSystem, free, theta) -> SwitchedLinearSystem:
    mats = {"Q": system.Q.copy(), "R": system.R.copy()}
    for (name, group, a, b), value in zip(free, theta):
        mats[name][group, a, b] = value
        mats[name][group, b, a] = value
    build = SwitchedLinearSystem.continuous if system.is_continuous else (
        lambda A, B, C, Q, R: SwitchedLinearSystem.discrete(A, B, C, Q, R, dt=system.dt))
    return build(system.A, system.B, system.C, mats["Q"], mats["R"])


def noise_standard_errors(system: SwitchedLinearSystem, names,
                          loglik: Callable[[SwitchedLinearSystem], float]
                          ) -> dict[str, np.ndarray]:
    """Standard errors of the fitted ``Q`` and/or ``R`` (``names``) at ``system``, shaped like
    the matrices, NaN outside the fitted blocks or where the information is not positive
    definite (then a ``RuntimeWarning`` says so)."""
    free = _free(system, names)
    out = {name: np.full(getattr(system, name).shape, np.nan) for name in names}
    if not free:
        return out
    theta = np.array([getattr(system, name)[g[0], a, b] for name, g, a, b in free])
    h = np.array([_REL_STEP * np.sqrt(getattr(system, name)[g[0], a, a]
                                      * getattr(system, name)[g[0], b, b])
                  for name, g, a, b in free])
    p = theta.size

    def f(delta):
        try:
            return loglik(_with(system, free, theta + delta))
        except ValueError:  # a step left the PSD cone: no curvature there
            return np.nan

    f0 = f(np.zeros(p))
    H = np.empty((p, p))
    e = np.eye(p) * h
    for i in range(p):
        H[i, i] = (f(e[i]) - 2 * f0 + f(-e[i])) / h[i] ** 2
        for j in range(i):
            H[i, j] = H[j, i] = (f(e[i] + e[j]) - f(e[i] - e[j]) - f(-e[i] + e[j])
                                 + f(-e[i] - e[j])) / (4 * h[i] * h[j])
    info = -H
    if not np.all(np.isfinite(info)) or np.min(np.linalg.eigvalsh(info)) <= 0:
        warnings.warn("the observed information of Q, R is not positive definite at the fit "
                      "(a parameter is not identifiable, or the fit is not at a maximum): their "
                      "standard errors are NaN", RuntimeWarning, stacklevel=3)
        return out
    se = np.sqrt(np.diag(np.linalg.inv(info)))
    for (name, group, a, b), s in zip(free, se):
        out[name][group, a, b] = s
        out[name][group, b, a] = s
    return out
