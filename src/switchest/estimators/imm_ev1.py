"""IMM extended-Viterbi filter with switching-time estimation (Shankar et al., Algorithm 1).

One filter per destination mode. At each sample, for every predecessor j and
destination i the switching instant inside the interval is estimated on a grid
of g points by maximizing ``J_k(tau)`` (eq. (23)); each destination keeps the
predecessor whose path is best (extended Viterbi, Ho & Chen), predicts with the
transition of the estimated instant (eqs (4)-(5)), adds ``epsilon I`` to the
predicted covariance (§IV), and updates; its weight is
``a^i_{k+1} = b_ji a^j_k`` (times ``pi_ji`` when a transition matrix is given),
normalized, kept in log domain.

Outliers: a hypothesis (predecessor, destination, grid point) whose filter rejects
the measurement (its normalized innovation squared overflows or exceeds ``gate``,
:func:`~switchest.estimators.kalman.kf_update`) gets likelihood zero; when every
hypothesis rejects it, the sample is treated as missing and flagged in
``Estimate.outlier``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._checks import check_probability_vector, check_row_stochastic, positive_scalar
from .._linalg import log_normalize
from ..discretize import pairwise_grid, switch_grid
from .base import Estimate, Estimator
from .kalman import kf_predict, kf_update
from .switch_time import _switch_time_loglik, marginalize_switch_time

__all__ = ["IMMEV1State", "IMMEV1Filter"]


@dataclass(frozen=True, eq=False)
class IMMEV1State:
    """Per-destination filters ``x (N, L, n)``, ``P (N, L, n, n)``, normalized log-weights
    ``log_weight (N, L)``, and for the last interval each destination's chosen
    predecessor ``predecessor (N, L)`` and switch offset ``switch_offset (N, L)``
    (NaN when the predecessor is the same mode); ``outlier (N,)`` is True where
    every hypothesis rejected the last measurement."""

    x: np.ndarray
    P: np.ndarray
    log_weight: np.ndarray
    predecessor: np.ndarray
    switch_offset: np.ndarray
    outlier: np.ndarray


class IMMEV1Filter(Estimator):
    """Shankar et al. Algorithm 1: IMM-EV1 Kalman filter with gridded switching times.

    Parameters
    ----------
    system : SwitchedLinearSystem
        A continuous-time system.
    transition : array_like, shape (L, L), optional
        ``transition[i, j]`` = P(mode j at k+1 | mode i at k). When given, path
        weights are multiplied by it; the paper's Algorithm 1 uses none.
    x0, P0 : array_like
        Prior mean and covariance at the first sample.
    grid : int
        Number g of candidate switching instants per interval (eq. (23)).
    epsilon : float
        The ``epsilon I`` added to every predicted covariance (§IV).
    mode_prob0 : array_like, shape (L,), optional
        Prior mode weights at the first sample; uniform by default.
    predecessor : {"path", "likelihood"}
        How each destination picks its predecessor. ``"path"`` (default) maximizes
        the path weight ``a^j b_ji (pi_ji)`` — the extended Viterbi rule of Ho &
        Chen. ``"likelihood"`` maximizes ``b_ji`` alone, the literal reading of the
        printed line "j_hat = max_j b_ij" of Algorithm 1.
    likelihood : {"innovation", "printed"}
        The ``J_k`` maximized over the grid, see
        :func:`switchest.estimators.switch_time.switch_time_loglik`.
    switch_time : {"max", "marginal"}
        ``"max"`` (the paper) keeps the grid point of largest ``J_k`` (eq. (23)).
        ``"marginal"`` (beyond the paper) treats the switching instant as uniform
        over the grid and integrates it out: ``b_ji`` is the mean of ``J_k`` over
        the grid, the destination's posterior is the moment-matched mixture of the
        g updated hypotheses weighted by ``J_k``, and the reported switching time
        is their weighted mean.
    gate : float, optional
        Largest normalized innovation squared ``e' S^-1 e`` a hypothesis accepts
        (keyword-only); ``None`` rejects only measurements whose innovation
        overflows. A sample every hypothesis rejects is treated as missing and
        flagged in ``Estimate.outlier``.

    Notes
    -----
    The reported ``x``, ``P``, ``mode`` and ``switch_time`` are those of the
    destination with the largest weight (the MAP path); ``mode_prob`` are the
    normalized weights.
    """

    def __init__(self, system, transition=None, *, x0, P0, grid: int = 5, epsilon: float = 1e-9,
                 mode_prob0=None, predecessor: str = "path", likelihood: str = "innovation",
                 switch_time: str = "max", gate: float | None = None):
        self._set_prior(system, x0, P0)
        if not system.is_continuous:
            raise ValueError("IMMEV1Filter needs a continuous-time system (switches inside intervals)")
        L = system.n_modes
        switch_grid(1.0, grid)
        self.grid = int(grid)
        self.epsilon = positive_scalar(epsilon, "epsilon", allow_zero=True)
        self.gate = None if gate is None else positive_scalar(gate, "gate")
        self.transition = None if transition is None else check_row_stochastic(transition, "transition", n=L)
        p0 = np.full(L, 1.0 / L) if mode_prob0 is None else mode_prob0
        self.mode_prob0 = check_probability_vector(p0, "mode_prob0", n=L)
        if predecessor not in ("path", "likelihood"):
            raise ValueError(f"predecessor must be 'path' or 'likelihood', got {predecessor!r}")
        if likelihood not in ("innovation", "printed"):
            raise ValueError(f"likelihood must be 'innovation' or 'printed', got {likelihood!r}")
        if switch_time not in ("max", "marginal"):
            raise ValueError(f"switch_time must be 'max' or 'marginal', got {switch_time!r}")
        self.predecessor = predecessor
        self.likelihood = likelihood
        self.switch_time = switch_time
        with np.errstate(divide="ignore"):
            self._log_p0 = np.log(self.mode_prob0)
            self._log_transition = None if transition is None else np.log(self.transition)

    def init(self, batch_shape=()) -> IMMEV1State:
        """Every destination filter starts from the prior."""
        L, n = self.system.n_modes, self.system.n_states
        return IMMEV1State(
            x=np.broadcast_to(self.x0, (*batch_shape, L, n)).copy(),
            P=np.broadcast_to(self.P0, (*batch_shape, L, n, n)).copy(),
            log_weight=np.broadcast_to(self._log_p0, (*batch_shape, L)).copy(),
            predecessor=np.broadcast_to(np.arange(L), (*batch_shape, L)).copy(),
            switch_offset=np.full((*batch_shape, L), np.nan),
            outlier=np.zeros(batch_shape, dtype=bool),
        )

    def step(self, state: IMMEV1State, y, u=None, *, dt=None) -> IMMEV1State:
        """One sample of Algorithm 1: switch-time grid search for every mode pair,
        predecessor selection, prediction and update."""
        sys = self.system
        L = sys.n_modes
        N = state.x.shape[0]
        if dt is None:  # first sample: update each mode's filter with the prior
            x, P, ll = kf_update(state.x, state.P, y[:, None, :], sys.C, sys.R, gate=self.gate)
            outlier = np.all(np.isneginf(ll), axis=-1)  # every mode rejected y: a missing sample
            ll = np.where(outlier[:, None], 0.0, ll)
            log_w, _ = log_normalize(state.log_weight + ll)
            return IMMEV1State(x, P, log_w, state.predecessor, state.switch_offset, outlier)
        if u is None:
            u = np.zeros((N, sys.n_inputs))
        grid = pairwise_grid(sys, dt, self.grid)  # [j, i, k]: from j to i at tau_k
        # predictions for every (trial, predecessor j, destination i, grid point k)
        x_pred, P_pred = kf_predict(
            state.x[:, :, None, None, :], state.P[:, :, None, None, :, :],
            grid.F, grid.G, u[:, None, None, None, :], grid.Qd, inflation=self.epsilon,
        )
        C = sys.C[None, None, :, None]
        R = sys.R[None, None, :, None]
        y_h = y[:, None, None, None, :]
        # every hypothesis updated; a rejected one keeps its prediction, J = -inf
        x_up, P_up, J = kf_update(x_pred, P_pred, y_h, C, R, gate=self.gate)
        if self.likelihood == "printed":
            J = np.where(np.isneginf(J), -np.inf,
                         _switch_time_loglik(x_pred, P_pred, y_h, C, R, likelihood="printed"))
        outlier = np.all(np.isneginf(J), axis=(1, 2, 3))  # every hypothesis rejected y
        if outlier.any():  # a missing sample: every hypothesis keeps its prediction
            J = np.where(outlier[:, None, None, None], 0.0, J)
            x_up = np.where(outlier[:, None, None, None, None], x_pred, x_up)
            P_up = np.where(outlier[:, None, None, None, None, None], P_pred, P_up)
        tau = switch_grid(dt, self.grid)
        if self.switch_time == "max":
            best_k = np.argmax(J, axis=-1)[..., None]  # eq. (23) for every pair (N, j, i, 1)
            log_b = np.take_along_axis(J, best_k, axis=-1)[..., 0]  # (N, j, i)
            x_pair = np.take_along_axis(x_up, best_k[..., None], axis=-2)[..., 0, :]
            P_pair = np.take_along_axis(P_up, best_k[..., None, None], axis=-3)[..., 0, :, :]
            tau_pair = tau[best_k[..., 0]]
        else:
            x_pair, P_pair, log_b, tau_pair = marginalize_switch_time(J, x_up, P_up, tau)
        path = state.log_weight[:, :, None] + log_b
        if self._log_transition is not None:
            path = path + self._log_transition
        chooser = path if self.predecessor == "path" else log_b
        j_hat = np.argmax(chooser, axis=1)  # (N, i): each destination's predecessor
        n_idx, i_idx = np.arange(N)[:, None], np.arange(L)[None, :]
        x, P = x_pair[n_idx, j_hat, i_idx], P_pair[n_idx, j_hat, i_idx]
        log_w, _ = log_normalize(path[n_idx, j_hat, i_idx])  # a^i = b_ji a^j (pi_ji), normalized
        offset = np.where(j_hat == i_idx, np.nan, tau_pair[n_idx, j_hat, i_idx])
        return IMMEV1State(x, P, log_w, j_hat, offset, outlier)

    def _output(self, state: IMMEV1State) -> dict[str, np.ndarray]:
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
        """Filter ``y (..., K, m)``; ``switch_time`` holds the MAP path's estimated
        absolute switching instant in ``(t_{k-1}, t_k)``, NaN where it has none."""
        y2, u2, t, batch = self._prepare(y, u, t)
        est = self._loop(y2, u2, t)
        start = np.concatenate([[np.nan], t[:-1]])
        est = Estimate(x=est.x, P=est.P, mode_prob=est.mode_prob, mode=est.mode,
                       switch_time=est.switch_time + start, outlier=est.outlier)
        return self._unflatten(est, batch)
