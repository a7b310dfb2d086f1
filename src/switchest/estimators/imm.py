"""The interacting multiple model filter (Blom & Bar-Shalom, 1988).

One Kalman filter per mode; before each prediction their estimates are mixed
with the mode transition probabilities, after each update the mode
probabilities are re-weighted by the filters' likelihoods. Switches are assumed
to happen at the sample instants. Mode probabilities are kept as log-weights.

Both ``run`` (a whole record) and ``step`` (streaming) call the compiled kernel of
:mod:`switchest.estimators._compiled` (``imm_run``, ``imm_step``), which holds the one
implementation of each equation: interaction (Blom & Bar-Shalom, 1988), mode-matched
Kalman prediction and update (Joseph form; the information form where that loses its
digits, a covariance beyond ``1/eps`` repaired with a ``RuntimeWarning``), and the
combined output (Bar-Shalom, Li & Kirubarajan §11.6.6).

Outliers: a mode whose filter rejects the measurement (its normalized innovation
squared overflows or exceeds ``gate``) is not updated and gets likelihood zero at
that sample; when every mode rejects it, the sample is treated as missing — no
update, the mode probabilities stay the predicted ones — and it is flagged in
``Estimate.outlier``.

Convention (all of switchest): ``transition[i, j]`` = P(mode j at k+1 | mode i at k);
rows sum to one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .._checks import check_probability_vector, check_row_stochastic, positive_scalar
from ..discretize import mode_steps
from ._compiled import GATED, imm_run, imm_step, raise_for_status, warn_for_repairs
from .base import Estimate, Estimator

__all__ = ["IMMState", "IMMFilter"]


@dataclass(frozen=True, eq=False)
class IMMState:
    """The state of the IMM after a sample, for ``N`` trials.

    Attributes
    ----------
    x, P : ndarray, shapes (N, L, n), (N, L, n, n)
        Mode-matched posteriors.
    log_prob : ndarray, shape (N, L)
        Log mode probabilities.
    loglik : ndarray, shape (N,)
        Log-likelihood of the last measurement given the past (0 when nothing was observed
        or every mode rejected it).
    outlier : ndarray of bool, shape (N,)
        True where every mode rejected the last measurement.
    combined_x, combined_P : ndarray, shapes (N, n), (N, n, n)
        The combined estimate, the moments of the mixture of the mode-matched posteriors
        (Bar-Shalom, Li & Kirubarajan §11.6.6, the output of the IMM): what ``run`` reports.
    """

    x: np.ndarray
    P: np.ndarray
    log_prob: np.ndarray
    loglik: np.ndarray
    outlier: np.ndarray
    combined_x: np.ndarray
    combined_P: np.ndarray


class IMMFilter(Estimator):
    """Interacting multiple model filter, batched over trials and modes.

    Parameters
    ----------
    system : SwitchedLinearSystem
    transition : array_like, shape (L, L)
        ``transition[i, j]`` = P(mode j at k+1 | mode i at k), rows sum to 1.
    x0, P0 : array_like
        Prior mean and covariance of the state at the first sample (every mode).
    mode_prob0 : array_like, shape (L,), optional
        Prior mode probabilities at the first sample (keyword-only); uniform by default.
    gate : float, optional
        Largest normalized innovation squared ``e' S^-1 e`` a mode-matched filter
        accepts (keyword-only); e.g. ``scipy.stats.chi2.ppf(0.9999, m)``. ``None``
        rejects only measurements whose innovation overflows. A sample every mode
        rejects is treated as missing and flagged in ``Estimate.outlier``.
    """

    def __init__(self, system, transition, x0, P0, *, mode_prob0=None, gate: float | None = None):
        self._set_prior(system, x0, P0)
        self.gate = None if gate is None else positive_scalar(gate, "gate")
        L = system.n_modes
        self.transition = check_row_stochastic(transition, "transition", n=L)
        p0 = np.full(L, 1.0 / L) if mode_prob0 is None else mode_prob0
        self.mode_prob0 = check_probability_vector(p0, "mode_prob0", n=L)
        with np.errstate(divide="ignore"):
            self._log_transition = np.log(self.transition)
            self._log_p0 = np.log(self.mode_prob0)
        self._gate = math.inf if self.gate is None else self.gate

    def init(self, batch_shape=()) -> IMMState:
        """Every mode-matched filter starts from the prior ``(x0, P0)``."""
        L = self.system.n_modes
        x, P = self._prior_copies((*batch_shape, L))
        combined_x, combined_P = self._prior_copies(batch_shape)
        return IMMState(x=x, P=P, log_prob=np.broadcast_to(self._log_p0, (*batch_shape, L)).copy(),
                        loglik=np.zeros(batch_shape), outlier=np.zeros(batch_shape, dtype=bool),
                        combined_x=combined_x, combined_P=combined_P)

    def step(self, state: IMMState, y, u=None, *, dt=None) -> IMMState:
        """Mix and predict over ``dt`` (skipped when ``None``), update with ``y (..., m)``.

        One sample of the compiled kernel (:func:`~switchest.estimators._compiled.imm_step`),
        the one ``run`` loops over: interaction (Blom & Bar-Shalom, 1988), mode-matched
        prediction and update, mode probabilities ``mu_j ∝ c_j Lambda_j`` and the combined
        output (Bar-Shalom, Li & Kirubarajan §11.6.6).
        """
        sys = self.system
        batch = state.log_prob.shape[:-1]
        L, n = sys.n_modes, sys.n_states
        N = int(np.prod(batch, dtype=np.int64))
        y = np.asarray(y, dtype=float).reshape(N, sys.n_outputs)
        if u is None:
            u = np.zeros((N, sys.n_inputs))
        u = np.broadcast_to(np.asarray(u, dtype=float), (*batch, sys.n_inputs)).reshape(N, -1)
        if dt is None:  # update only: the transition table is not read
            F, G, Qd = np.zeros((L, n, n)), np.zeros((L, n, sys.n_inputs)), np.zeros((L, n, n))
        else:
            steps = mode_steps(sys, dt)
            F, G, Qd = steps.F, steps.G, steps.Qd
        out, (x, P, log_prob) = imm_step(
            state.x.reshape(N, L, n), state.P.reshape(N, L, n, n), state.log_prob.reshape(N, L),
            y, u, F, G, Qd, np.arange(L), sys.C, sys.R, self._log_transition,
            predict_first=dt is not None, gate=self._gate)
        raise_for_status(out.status)
        warn_for_repairs(out)
        return IMMState(
            x=x.reshape(*batch, L, n), P=P.reshape(*batch, L, n, n),
            log_prob=log_prob.reshape(*batch, L), loglik=out.loglik.reshape(batch),
            outlier=(out.flag == GATED).reshape(batch),
            combined_x=out.x.reshape(*batch, n), combined_P=out.P.reshape(*batch, n, n),
        )

    def run(self, y, u=None, t=None) -> Estimate:
        """Filter ``y (..., K, m)``; returns combined ``x``, ``P``, ``mode_prob``, the
        most probable ``mode``, ``loglik`` and the ``outlier`` flags at each sample.

        The whole record runs in the compiled kernel
        (:func:`~switchest.estimators._compiled.imm_run`), with one exact transition per mode
        and distinct sampling step.
        """
        y2, u2, t, batch = self._prepare(y, u, t)
        sys = self.system
        L, K = sys.n_modes, t.size
        steps, which = np.unique(np.diff(t), return_inverse=True)
        if steps.size == 0:  # one sample: update only, the table is not read
            steps = np.ones(1)
        table = [mode_steps(sys, h) for h in steps]
        F = np.concatenate([s.F for s in table])
        G = np.concatenate([s.G for s in table])
        Qd = np.concatenate([s.Qd for s in table])
        trans = np.zeros((K, L), dtype=np.int64)
        trans[1:] = np.arange(L) + L * which.reshape(-1, 1)
        out = imm_run(y2, u2, F, G, Qd, trans, sys.C, sys.R, self._log_transition,
                      self.x0, self.P0, self._log_p0, gate=self._gate)
        raise_for_status(out.status)
        warn_for_repairs(out)
        est = Estimate(x=out.x, P=out.P, mode_prob=out.mode_prob, mode=out.mode,
                       loglik=out.loglik, outlier=out.flag == GATED)
        return self._unflatten(est, batch)
