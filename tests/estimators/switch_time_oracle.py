"""Numpy oracle of SwitchTimeKalmanFilter: the filter as it was before the compiled engine.

A copy of the numpy implementation: each step predicts and updates the whole batch of trials
with :func:`switchest.estimators.kalman.kf_predict` and ``kf_update``, the grid transitions come
from :func:`switchest.discretize.pairwise_grid` and every refinement probe from its own
:func:`switchest.discretize.interval` (a block matrix exponential). One addition:
``resolution``, the number of steps per interval to which a probe's instant is rounded before its
transition is taken (``None``: exact, as before); given the compiled filter's resolution, the two
follow the same golden-section path.
"""

from __future__ import annotations

import numpy as np
from numpy_kalman import kf_predict, kf_update

from switchest._linalg import log_normalize, mixture_moments
from switchest.discretize import interval, mode_steps, pairwise_grid, switch_grid

_GOLDEN = (np.sqrt(5.0) - 1.0) / 2.0


class SwitchTimeOracle:
    """The numpy switch-time Kalman filter; options as in ``SwitchTimeKalmanFilter``."""

    def __init__(self, system, x0, P0, *, grid=5, refine=False, likelihood="innovation",
                 refine_iterations=20, switch_time="max", gate=None, resolution=None):
        self.system, self.x0, self.P0 = system, np.asarray(x0, float), np.asarray(P0, float)
        self.grid, self.refine, self.likelihood = grid, refine, likelihood
        self.refine_iterations, self.switch_time, self.gate = refine_iterations, switch_time, gate
        self.resolution = resolution

    def run(self, y, u, t, modes):
        """Filter ``y (N, K, m)`` with inputs ``u (N, K, l)`` along ``modes (N, K)``; returns a
        dict of ``x``, ``P``, ``loglik``, ``switch_time`` (absolute) and ``outlier``."""
        N, K, _ = y.shape
        n = self.system.n_states
        x, P = np.tile(self.x0, (N, 1)), np.tile(self.P0, (N, 1, 1))
        out = {"x": np.empty((N, K, n)), "P": np.empty((N, K, n, n)), "loglik": np.empty((N, K)),
               "switch_time": np.full((N, K), np.nan), "outlier": np.empty((N, K), bool)}
        for k in range(K):
            dt = None if k == 0 else t[k] - t[k - 1]
            prev = modes[:, k - 1] if k else modes[:, 0]
            x, P, ll, offset, outlier = self.step(x, P, y[:, k], u[:, k - 1] if k else u[:, 0],
                                                  dt=dt, mode=modes[:, k], prev_mode=prev)
            out["x"][:, k], out["P"][:, k], out["loglik"][:, k] = x, P, ll
            out["outlier"][:, k] = outlier
            if k:
                out["switch_time"][:, k] = offset + t[k - 1]
        return out

    def step(self, x, P, y, u, *, dt, mode, prev_mode):
        """One sample: returns ``x``, ``P``, ``loglik``, the switch offset and the outlier flag."""
        sys = self.system
        N = mode.shape[0]
        offset = np.full(N, np.nan)
        merged = None
        C, R = sys.C[mode], sys.R[mode]
        if dt is not None:
            prev = prev_mode
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
        if merged is not None:
            x[sw], P[sw], loglik[sw], offset[sw] = merged
        outlier = np.isneginf(loglik)
        return x, P, np.where(outlier, 0.0, loglik), offset, outlier

    def _estimate(self, x, P, y, u, prev, mode, dt):
        grid = pairwise_grid(self.system, dt, self.grid)
        F, G, Qd = grid.F[prev, mode], grid.G[prev, mode], grid.Qd[prev, mode]
        ll = self._loglik(x[:, None], P[:, None], F, G, u[:, None], Qd, y[:, None], mode[:, None])
        best = np.argmax(ll, axis=1)
        uninformed = np.all(np.isnan(y), axis=-1) | np.all(np.isneginf(ll), axis=1)
        best[uninformed] = self.grid // 2
        rows = np.arange(best.size)
        tau = switch_grid(dt, self.grid)[best]
        chosen = (F[rows, best], G[rows, best], Qd[rows, best])
        if not self.refine:
            return tau, chosen
        half = dt / (2 * self.grid)
        lo, hi = np.clip(tau - half, 0.0, dt), np.clip(tau + half, 0.0, dt)
        best_ll = np.where(uninformed, np.inf, ll[rows, best])
        return self._golden(x, P, y, u, prev, mode, dt, lo, hi, tau, best_ll, chosen)

    def _marginal(self, x, P, y, u, prev, mode, dt):
        sys = self.system
        grid = pairwise_grid(sys, dt, self.grid)
        F, G, Qd = grid.F[prev, mode], grid.G[prev, mode], grid.Qd[prev, mode]
        x_pred, P_pred = kf_predict(x[:, None], P[:, None], F, G, u[:, None], Qd)
        x_up, P_up, ll = kf_update(x_pred, P_pred, y[:, None], sys.C[mode][:, None],
                                   sys.R[mode][:, None], gate=self.gate)
        rejected = np.all(np.isneginf(ll), axis=1)
        ll[rejected] = 0.0
        log_w, log_sum = log_normalize(ll)
        w = np.exp(log_w)
        xm, Pm = mixture_moments(w[..., :, None], x_up, P_up)
        tau = switch_grid(dt, self.grid)
        loglik = log_sum - np.log(tau.size)
        loglik[rejected] = -np.inf
        return xm[..., 0, :], Pm[..., 0, :, :], loglik, w @ tau

    def _loglik(self, x, P, F, G, u, Qd, y, mode):
        x_pred, P_pred = kf_predict(x, P, F, G, u, Qd)
        C, R = self.system.C[mode], self.system.R[mode]
        if self.likelihood == "innovation":
            return kf_update(x_pred, P_pred, y, C, R, gate=self.gate)[2]
        ll = kf_update(x_pred, np.zeros_like(P_pred), y, C, R)[2]  # "printed": R alone
        if self.gate is not None:
            gated = np.isneginf(kf_update(x_pred, P_pred, y, C, R, gate=self.gate)[2])
            ll = np.where(gated, -np.inf, ll)
        return ll

    def _golden(self, x, P, y, u, prev, mode, dt, lo, hi, best_tau, best_ll, best_tr):
        best_F, best_G, best_Q = (a.copy() for a in best_tr)
        best_tau, best_ll = best_tau.copy(), best_ll.copy()
        pair = np.stack([prev, mode], axis=1)

        def probe(tau):
            if self.resolution is not None:
                steps = np.clip(np.floor(tau / dt * self.resolution + 0.5), 0, self.resolution)
                tau = steps * (dt / self.resolution)
            tr = interval(self.system, dt, pair, tau[:, None])
            ll = self._loglik(x, P, tr.F, tr.G, u, tr.Qd, y, mode)
            better = ll > best_ll
            best_tau[better], best_ll[better] = tau[better], ll[better]
            best_F[better], best_G[better] = tr.F[better], tr.G[better]
            best_Q[better] = tr.Qd[better]
            return ll

        a, b = lo.copy(), hi.copy()
        c, d = b - _GOLDEN * (b - a), a + _GOLDEN * (b - a)
        fc, fd = probe(c), probe(d)
        for _ in range(self.refine_iterations):
            left = fc > fd
            a, b = np.where(left, a, c), np.where(left, d, b)
            c_new, d_new = b - _GOLDEN * (b - a), a + _GOLDEN * (b - a)
            f_new = probe(np.where(left, c_new, d_new))
            c, d = np.where(left, c_new, d), np.where(left, c, d_new)
            fc, fd = np.where(left, f_new, fd), np.where(left, fc, f_new)
        return best_tau, (best_F, best_G, best_Q)
