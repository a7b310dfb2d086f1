"""The numpy IMM-EV1 filter as it was before the compiled engine: the oracle of its kernel.

A self-contained copy of ``IMMEV1Filter`` (Shankar, Yang & Hespanha, Algorithm 1; extended
Viterbi of Ho & Chen) as it ran on the numpy Kalman core before the compiled kernel of
:mod:`switchest.engine.imm_ev1` replaced it: every hypothesis (predecessor
``j``, destination ``i``, grid point ``k``) predicted with its own transition (eqs (4)-(7),
``epsilon I`` added, §IV) and updated (eqs (8)-(10)) by :func:`kf_predict` and
:func:`kf_update`, broadcast over trials, modes and grid points. The switching-time
likelihood ``J_k`` and the marginalization over the grid are written out here (they came from
``switch_time.py``, which has since changed), so the oracle stays what the kernel was checked
against.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy_kalman import kf_predict, kf_update

from switchest._checks import check_probability_vector, check_row_stochastic, positive_scalar
from switchest._linalg import log_normalize, mixture_moments
from switchest.discretize import pairwise_grid, switch_grid
from switchest.estimators.base import Estimate, Estimator


def printed_loglik(x_pred, y, C, R):
    """The paper's literal ``J_k(tau) = N(y; C x-(tau), R)`` (§IV): the update of a zero
    covariance, ``-inf`` where ``y`` is so far off that its quadratic form overflows."""
    return kf_update(x_pred, np.zeros((*x_pred.shape, x_pred.shape[-1])), y, C, R)[2]


def marginalize(loglik, x_up, P_up, tau):
    """Merge the ``g`` hypotheses of a grid weighted by ``p(y | tau_k)`` (uniform prior on the
    grid): moment-matched mean and covariance, ``log((1/g) sum_k p(y | tau_k))`` and the
    weighted mean instant, each over the last axis of ``loglik (..., g)``."""
    log_w, log_sum = log_normalize(loglik)
    w = np.exp(log_w)
    x, P = mixture_moments(w[..., :, None], x_up, P_up)
    return x[..., 0, :], P[..., 0, :, :], log_sum - np.log(tau.size), w @ tau


@dataclass(frozen=True, eq=False)
class OracleState:
    """As ``IMMEV1State``: ``x (N, L, n)``, ``P (N, L, n, n)``, ``log_weight (N, L)``,
    ``predecessor (N, L)``, ``switch_offset (N, L)``, ``outlier (N,)``."""

    x: np.ndarray
    P: np.ndarray
    log_weight: np.ndarray
    predecessor: np.ndarray
    switch_offset: np.ndarray
    outlier: np.ndarray


class OracleIMMEV1Filter(Estimator):
    """``IMMEV1Filter`` on the numpy Kalman core, with its constructor, ``init``, ``step``
    and ``run`` (see ``switchest.estimators.IMMEV1Filter`` for the parameters)."""

    def __init__(self, system, transition=None, *, x0, P0, grid=5, epsilon=1e-9,
                 mode_prob0=None, predecessor="path", likelihood="innovation",
                 switch_time="max", gate=None):
        self._set_prior(system, x0, P0)
        L = system.n_modes
        self.grid = int(grid)
        self.epsilon = positive_scalar(epsilon, "epsilon", allow_zero=True)
        self.gate = None if gate is None else positive_scalar(gate, "gate")
        self.transition = (None if transition is None
                           else check_row_stochastic(transition, "transition", n=L))
        p0 = np.full(L, 1.0 / L) if mode_prob0 is None else mode_prob0
        self.mode_prob0 = check_probability_vector(p0, "mode_prob0", n=L)
        self.predecessor = predecessor
        self.likelihood = likelihood
        self.switch_time = switch_time
        with np.errstate(divide="ignore"):
            self._log_p0 = np.log(self.mode_prob0)
            self._log_transition = None if transition is None else np.log(self.transition)

    def init(self, batch_shape=()) -> OracleState:
        """Every destination filter starts from the prior."""
        L, n = self.system.n_modes, self.system.n_states
        return OracleState(
            x=np.broadcast_to(self.x0, (*batch_shape, L, n)).copy(),
            P=np.broadcast_to(self.P0, (*batch_shape, L, n, n)).copy(),
            log_weight=np.broadcast_to(self._log_p0, (*batch_shape, L)).copy(),
            predecessor=np.broadcast_to(np.arange(L), (*batch_shape, L)).copy(),
            switch_offset=np.full((*batch_shape, L), np.nan),
            outlier=np.zeros(batch_shape, dtype=bool),
        )

    def step(self, state: OracleState, y, u=None, *, dt=None) -> OracleState:
        """One sample of Algorithm 1 on ``N`` trials (``y (N, m)``)."""
        sys = self.system
        L = sys.n_modes
        N = state.x.shape[0]
        if dt is None:  # first sample: update each mode's filter with the prior
            x, P, ll = kf_update(state.x, state.P, y[:, None, :], sys.C, sys.R, gate=self.gate)
            outlier = np.all(np.isneginf(ll), axis=-1)
            ll = np.where(outlier[:, None], 0.0, ll)
            log_w, _ = log_normalize(state.log_weight + ll)
            return OracleState(x, P, log_w, state.predecessor, state.switch_offset, outlier)
        if u is None:
            u = np.zeros((N, sys.n_inputs))
        grid = pairwise_grid(sys, dt, self.grid)  # [j, i, k]: from j to i at tau_k
        x_pred, P_pred = kf_predict(
            state.x[:, :, None, None, :], state.P[:, :, None, None, :, :],
            grid.F, grid.G, u[:, None, None, None, :], grid.Qd, inflation=self.epsilon,
        )
        C = sys.C[None, None, :, None]
        R = sys.R[None, None, :, None]
        y_h = y[:, None, None, None, :]
        x_up, P_up, J = kf_update(x_pred, P_pred, y_h, C, R, gate=self.gate)
        if self.likelihood == "printed":
            J = np.where(np.isneginf(J), -np.inf, printed_loglik(x_pred, y_h, C, R))
        outlier = np.all(np.isneginf(J), axis=(1, 2, 3))
        if outlier.any():
            J = np.where(outlier[:, None, None, None], 0.0, J)
            x_up = np.where(outlier[:, None, None, None, None], x_pred, x_up)
            P_up = np.where(outlier[:, None, None, None, None, None], P_pred, P_up)
        tau = switch_grid(dt, self.grid)
        if self.switch_time == "max":
            best_k = np.argmax(J, axis=-1)[..., None]  # eq. (23) for every pair
            log_b = np.take_along_axis(J, best_k, axis=-1)[..., 0]
            x_pair = np.take_along_axis(x_up, best_k[..., None], axis=-2)[..., 0, :]
            P_pair = np.take_along_axis(P_up, best_k[..., None, None], axis=-3)[..., 0, :, :]
            tau_pair = tau[best_k[..., 0]]
        else:
            x_pair, P_pair, log_b, tau_pair = marginalize(J, x_up, P_up, tau)
        path = state.log_weight[:, :, None] + log_b
        if self._log_transition is not None:
            path = path + self._log_transition
        chooser = path if self.predecessor == "path" else log_b
        j_hat = np.argmax(chooser, axis=1)
        n_idx, i_idx = np.arange(N)[:, None], np.arange(L)[None, :]
        x, P = x_pair[n_idx, j_hat, i_idx], P_pair[n_idx, j_hat, i_idx]
        log_w, _ = log_normalize(path[n_idx, j_hat, i_idx])
        offset = np.where(j_hat == i_idx, np.nan, tau_pair[n_idx, j_hat, i_idx])
        return OracleState(x, P, log_w, j_hat, offset, outlier)

    def _output(self, state: OracleState) -> dict[str, np.ndarray]:
        best = np.argmax(state.log_weight, axis=-1)
        rows = np.arange(best.size)
        return {
            "x": state.x[rows, best],
            "P": state.P[rows, best],
            "mode_prob": np.exp(state.log_weight),
            "mode": best,
            "switch_time": state.switch_offset[rows, best],
            "outlier": state.outlier,
        }

    def run(self, y, u=None, t=None) -> Estimate:
        """Filter ``y (..., K, m)``; ``switch_time`` is absolute, NaN without a switch."""
        y2, u2, t, batch = self._prepare(y, u, t)
        est = self._loop(y2, u2, t)
        start = np.concatenate([[np.nan], t[:-1]])
        est = Estimate(x=est.x, P=est.P, mode_prob=est.mode_prob, mode=est.mode,
                       switch_time=est.switch_time + start, outlier=est.outlier)
        return self._unflatten(est, batch)
