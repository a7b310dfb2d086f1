"""Kalman filtering with known modes at the samples and unknown switching times.

Shankar et al. §III-§IV: the mode at each sample is known, but when the mode
changes between ``t_{k-1}`` and ``t_k`` the instant of the switch is not. It is
estimated by maximizing the likelihood of the new measurement over a grid of
``g`` candidate instants (eq. (23)), and the filter then predicts with the
transition of the estimated instant (eqs (4)-(5), (6)-(10)).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._checks import (
    check_bool,
    check_cores,
    check_finite,
    check_memory,
    float_array,
    int_array,
    positive_scalar,
)
from .._linalg import log_normalize, mixture_moments
from ..discretize import interval, mode_steps, pairwise_grid, pairwise_grid_nbytes, switch_grid
from .base import Estimate, Estimator
from .kalman import kf_predict, kf_update

__all__ = ["SwitchTimeState", "SwitchTimeKalmanFilter", "switch_time_loglik", "marginalize_switch_time"]

_GOLDEN = (np.sqrt(5.0) - 1.0) / 2.0


@dataclass(frozen=True, eq=False)
class SwitchTimeState:
    """Posterior ``x (N, n)``, ``P (N, n, n)``, ``loglik (N,)``, the estimated switch
    offset inside the last interval, ``switch_offset (N,)`` (NaN without a switch), and
    ``outlier (N,)``, True where the measurement was rejected."""

    x: np.ndarray
    P: np.ndarray
    loglik: np.ndarray
    switch_offset: np.ndarray
    outlier: np.ndarray


def switch_time_loglik(x_pred, P_pred, y, C, R, *, likelihood: str = "innovation"):
    """Log of the switching-time likelihood ``J_k(tau)`` of Shankar et al. §IV.

    ``likelihood="innovation"`` gives ``log N(y; C x-(tau), C P-(tau) C' + R)``, the
    likelihood of the measurement given the past, whose maximizer is the
    maximum-likelihood switching time. ``likelihood="printed"`` gives the paper's
    literal ``J_k(tau) = p(y_{k+1} | x_{k+1} = x-(tau)) = N(y; C x-(tau), R)``, which
    ignores the prediction covariance (and so how much each hypothesis is
    trusted). Both are evaluated by the Kalman core; shapes broadcast. NaN entries
    of ``y`` are missing components.
    """
    _check_likelihood(likelihood)
    arrays = {k: float_array(v, k) for k, v in zip(("x_pred", "P_pred", "y", "C", "R"),
                                                   (x_pred, P_pred, y, C, R))}
    check_cores(arrays, {"x_pred": "n", "P_pred": "nn", "y": "m", "C": "mn", "R": "mm"})
    for name in ("x_pred", "P_pred", "C", "R"):
        check_finite(arrays[name], name)
    return _switch_time_loglik(*arrays.values(), likelihood=likelihood)


def _switch_time_loglik(x_pred, P_pred, y, C, R, *, likelihood: str):
    """:func:`switch_time_loglik` on validated arrays (the filter's per-step kernel)."""
    P = P_pred if likelihood == "innovation" else np.zeros_like(P_pred)  # "printed": R alone
    return kf_update(x_pred, P, y, C, R)[2]


def _check_likelihood(likelihood) -> None:
    if not isinstance(likelihood, str) or likelihood not in ("innovation", "printed"):
        raise ValueError(f"likelihood must be 'innovation' or 'printed', got {likelihood!r}")


def marginalize_switch_time(loglik, x_up, P_up, tau):
    """Collapse the hypotheses of a switching-time grid into one Gaussian (beyond Shankar et al.).

    Instead of keeping the maximizer of eq. (23), the switching instant is
    integrated out with a uniform prior on the grid ``tau (g,)``: the posterior
    weights are ``w_i = p(y | tau_i) / sum_k p(y | tau_k)`` from the innovation
    log-likelihoods ``loglik (..., g)``, the updated estimates ``x_up (..., g, n)``,
    ``P_up (..., g, n, n)`` are merged by moment matching, and the likelihood of
    the measurement is the grid mean ``(1/g) sum_i p(y | tau_i)``.

    Returns
    -------
    x, P, loglik, tau_mean
        Merged mean ``(..., n)`` and covariance, ``log((1/g) sum_i p(y | tau_i))``
        and the posterior mean switching instant ``sum_i w_i tau_i``, each ``(...)``.
    """
    log_w, log_sum = log_normalize(loglik)
    w = np.exp(log_w)
    x, P = mixture_moments(w[..., :, None], x_up, P_up)
    return x[..., 0, :], P[..., 0, :, :], log_sum - np.log(tau.size), w @ tau


class SwitchTimeKalmanFilter(Estimator):
    """Kalman filter with gridded maximum-likelihood switching times (Shankar et al.).

    Parameters
    ----------
    system : SwitchedLinearSystem
        A continuous-time system.
    x0, P0 : array_like
        Prior mean and covariance at the first sample.
    grid : int
        Number g of candidate switching instants per interval,
        ``tau_i = i T / g - T / (2 g)`` (eq. (23)).
    refine : bool
        Beyond the paper: polish the grid maximum by a golden-section search of
        the exact likelihood over the grid cell around it, ``[tau - T/(2g),
        tau + T/(2g)]`` (batched over trials; ``refine_iterations`` steps shrink
        the cell by 0.618 each).
    likelihood : {"innovation", "printed"}
        Which ``J_k`` to maximize, see :func:`switch_time_loglik`.
    refine_iterations : int
        Golden-section steps when ``refine=True``.
    switch_time : {"max", "marginal"}
        ``"max"``: the grid maximizer of eq. (23) (the paper). ``"marginal"``
        (beyond the paper): every grid instant is predicted and updated, and the
        hypotheses are merged with their posterior weights
        (:func:`marginalize_switch_time`); the reported switching instant is the
        posterior mean. Needs ``likelihood="innovation"`` and ``refine=False``.
    gate : float, optional
        Largest normalized innovation squared accepted. A measurement beyond it,
        or one whose innovation overflows (whatever the gate), is rejected: treated
        as missing and flagged in ``Estimate.outlier``. Where every grid instant
        rejects it, the measurement says nothing of the switching instant: the
        hypotheses are weighed equally (``"marginal"``) or the middle grid instant
        is taken (``"max"``, as for a missing measurement).

    Notes
    -----
    At most one switch per interval is assumed (dwell time > T, Shankar §II).
    """

    def __init__(self, system, x0, P0, *, grid: int = 5, refine: bool = False,
                 likelihood: str = "innovation", refine_iterations: int = 20, switch_time: str = "max",
                 gate: float | None = None):
        self._set_prior(system, x0, P0)
        if not system.is_continuous:
            raise ValueError("SwitchTimeKalmanFilter needs a continuous-time system (switches inside intervals)")
        switch_grid(1.0, grid)  # validates g
        check_memory(pairwise_grid_nbytes(system, grid),
                     f"grid = {grid} switching instants per interval (the transitions of every "
                     f"mode pair at every instant, L = {system.n_modes} modes)")
        refine = check_bool(refine, "refine")
        _check_likelihood(likelihood)
        iters = int_array(refine_iterations, "refine_iterations", ndim=0)
        if iters < 1:
            raise ValueError(f"refine_iterations must be >= 1, got {int(iters)}")
        if not isinstance(switch_time, str) or switch_time not in ("max", "marginal"):
            raise ValueError(f"switch_time must be 'max' or 'marginal', got {switch_time!r}")
        if switch_time == "marginal" and (refine or likelihood != "innovation"):
            raise ValueError("switch_time='marginal' weighs the grid by the innovation likelihood: it needs "
                             "likelihood='innovation' and refine=False")
        self.switch_time = switch_time
        self.grid = int(grid)
        self.refine = refine
        self.likelihood = likelihood
        self.refine_iterations = int(iters)
        self.gate = None if gate is None else positive_scalar(gate, "gate")

    def init(self, batch_shape=()) -> SwitchTimeState:
        """The prior, replicated over ``batch_shape``."""
        n = self.system.n_states
        return SwitchTimeState(
            x=np.broadcast_to(self.x0, (*batch_shape, n)).copy(),
            P=np.broadcast_to(self.P0, (*batch_shape, n, n)).copy(),
            loglik=np.zeros(batch_shape),
            switch_offset=np.full(batch_shape, np.nan),
            outlier=np.zeros(batch_shape, dtype=bool),
        )

    def step(self, state: SwitchTimeState, y, u=None, *, dt=None, mode, prev_mode=None) -> SwitchTimeState:
        """Predict over ``dt`` from ``prev_mode`` to ``mode``, estimating the switch time
        when they differ, then update with ``y (N, m)``."""
        sys = self.system
        mode = np.asarray(mode)
        N = mode.shape[0]
        offset = np.full(N, np.nan)
        merged = None  # the switched trials' merged hypotheses with switch_time="marginal"
        x, P = state.x, state.P
        C, R = sys.C[mode], sys.R[mode]
        if dt is not None:
            prev = mode if prev_mode is None else np.asarray(prev_mode)
            if u is None:
                u = np.zeros((N, sys.n_inputs))
            steps = mode_steps(sys, dt)
            F, G, Qd = steps.F[prev], steps.G[prev], steps.Qd[prev]
            sw = np.flatnonzero(prev != mode)
            if sw.size and self.switch_time == "marginal":
                merged = self._marginal(x[sw], P[sw], y[sw], u[sw], prev[sw], mode[sw], dt)
            elif sw.size:
                tau, tr = self._estimate(x[sw], P[sw], y[sw], u[sw], prev[sw], mode[sw], dt)
                F, G, Qd = F.copy(), G.copy(), Qd.copy()
                F[sw], G[sw], Qd[sw] = tr
                offset[sw] = tau
            x, P = kf_predict(x, P, F, G, u, Qd)
        x, P, loglik = kf_update(x, P, y, C, R, gate=self.gate)
        if merged is not None:  # the rows of switched trials above assumed no switch: replace them
            x[sw], P[sw], loglik[sw], offset[sw] = merged
        outlier = np.isneginf(loglik)  # the core's mark of a rejected measurement
        return SwitchTimeState(x, P, np.where(outlier, 0.0, loglik), offset, outlier)

    def _estimate(self, x, P, y, u, prev, mode, dt):
        """Grid maximum of eq. (23), optionally refined; returns offsets and (F, G, Qd)."""
        sys = self.system
        grid = pairwise_grid(sys, dt, self.grid)
        F, G, Qd = grid.F[prev, mode], grid.G[prev, mode], grid.Qd[prev, mode]  # (q, g, ...)
        ll = self._loglik(x[:, None], P[:, None], F, G, u[:, None], Qd, y[:, None], mode[:, None])
        best = np.argmax(ll, axis=1)
        # a missing or rejected y says nothing of the instant: take the middle of the grid
        uninformed = np.all(np.isnan(y), axis=-1) | np.all(np.isneginf(ll), axis=1)
        best[uninformed] = self.grid // 2
        rows = np.arange(best.size)
        tau = switch_grid(dt, self.grid)[best]
        chosen = (F[rows, best], G[rows, best], Qd[rows, best])
        if not self.refine:
            return tau, chosen
        half = dt / (2 * self.grid)
        lo, hi = np.clip(tau - half, 0.0, dt), np.clip(tau + half, 0.0, dt)
        best_ll = np.where(uninformed, np.inf, ll[rows, best])  # nothing to refine there
        return self._golden(x, P, y, u, prev, mode, dt, lo, hi, tau, best_ll, chosen)

    def _marginal(self, x, P, y, u, prev, mode, dt):
        """Predict and update every grid instant, then merge (:func:`marginalize_switch_time`)."""
        sys = self.system
        grid = pairwise_grid(sys, dt, self.grid)
        F, G, Qd = grid.F[prev, mode], grid.G[prev, mode], grid.Qd[prev, mode]  # (q, g, ...)
        x_pred, P_pred = kf_predict(x[:, None], P[:, None], F, G, u[:, None], Qd)
        x_up, P_up, ll = kf_update(x_pred, P_pred, y[:, None], sys.C[mode][:, None],
                                   sys.R[mode][:, None], gate=self.gate)
        rejected = np.all(np.isneginf(ll), axis=1)  # predictions kept, weighed equally
        ll[rejected] = 0.0
        x, P, loglik, tau = marginalize_switch_time(ll, x_up, P_up, switch_grid(dt, self.grid))
        loglik[rejected] = -np.inf  # flagged by step as a rejected measurement
        return x, P, loglik, tau

    def _loglik(self, x, P, F, G, u, Qd, y, mode):
        """``J_k`` of each hypothesis; ``-inf`` where the gate rejects ``y`` under it."""
        x_pred, P_pred = kf_predict(x, P, F, G, u, Qd)
        C, R = self.system.C[mode], self.system.R[mode]
        if self.likelihood == "innovation":  # the core applies the gate itself
            return kf_update(x_pred, P_pred, y, C, R, gate=self.gate)[2]
        ll = _switch_time_loglik(x_pred, P_pred, y, C, R, likelihood=self.likelihood)
        if self.gate is not None:
            gated = np.isneginf(kf_update(x_pred, P_pred, y, C, R, gate=self.gate)[2])
            ll = np.where(gated, -np.inf, ll)
        return ll

    def _golden(self, x, P, y, u, prev, mode, dt, lo, hi, best_tau, best_ll, best_tr):
        """Batched golden-section maximization of the exact likelihood on ``[lo, hi]``.

        The grid point is kept if no probed instant beats it, so refining never
        lowers the likelihood of the chosen switching time.
        """
        best_F, best_G, best_Q = (a.copy() for a in best_tr)
        best_tau, best_ll = best_tau.copy(), best_ll.copy()
        pair = np.stack([prev, mode], axis=1)

        def probe(tau):
            tr = interval(self.system, dt, pair, tau[:, None])
            ll = self._loglik(x, P, tr.F, tr.G, u, tr.Qd, y, mode)
            better = ll > best_ll
            best_tau[better], best_ll[better] = tau[better], ll[better]
            best_F[better], best_G[better], best_Q[better] = tr.F[better], tr.G[better], tr.Qd[better]
            return ll

        a, b = lo.copy(), hi.copy()
        c, d = b - _GOLDEN * (b - a), a + _GOLDEN * (b - a)
        fc, fd = probe(c), probe(d)
        for _ in range(self.refine_iterations):
            left = fc > fd  # the maximum lies in [a, d]
            a, b = np.where(left, a, c), np.where(left, d, b)
            c_new, d_new = b - _GOLDEN * (b - a), a + _GOLDEN * (b - a)
            probe_at = np.where(left, c_new, d_new)
            f_new = probe(probe_at)
            c, d = np.where(left, c_new, d), np.where(left, c, d_new)
            fc, fd = np.where(left, f_new, fd), np.where(left, fc, f_new)
        return best_tau, (best_F, best_G, best_Q)

    def _output(self, state: SwitchTimeState) -> dict[str, np.ndarray]:
        return {"x": state.x, "P": state.P, "loglik": state.loglik, "switch_time": state.switch_offset,
                "outlier": state.outlier}

    def run(self, y, u=None, t=None, *, modes) -> Estimate:
        """Filter ``y (..., K, m)`` given the true ``modes`` at the samples ``(K,)`` or ``(..., K)``.

        The returned ``switch_time`` holds the estimated absolute switching instant
        in ``(t_{k-1}, t_k)`` at sample k, NaN where the mode did not change.
        """
        y2, u2, t, batch = self._prepare(y, u, t)
        K = t.size
        modes = self._modes(modes, batch, K)
        n, N = self.system.n_states, y2.shape[0]
        check_memory(  # a step's hypotheses: F, Qd, P predicted and updated, and temporaries
            8 * N * self.grid * (6 * n * n + 4 * n + self.system.n_inputs * n),
            f"grid = {self.grid} switching-time hypotheses for each of N = {N} trials",
        )
        prev = np.concatenate([modes[:, :1], modes[:, :-1]], axis=1)
        est = self._loop(y2, u2, t, {"mode": modes, "prev_mode": prev})
        start = np.concatenate([[np.nan], t[:-1]])
        est = Estimate(x=est.x, P=est.P, loglik=est.loglik, switch_time=est.switch_time + start,
                       outlier=est.outlier)
        return self._unflatten(est, batch)
