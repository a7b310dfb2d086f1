"""Numpy oracle of SwitchTimeKalmanFilter: the filter as it was before the compiled engine.

A copy of the numpy implementation: each step predicts and updates the whole batch of trials
with :func:`switchest.estimators.kalman.kf_predict` and ``kf_update``, the grid transitions come
from :func:`switchest.discretize.pairwise_grid` and every refinement probe from its own
:func:`switchest.discretize.interval` (a block matrix exponential), the search of the cell
written here from Brent's ``fmin`` with the compiled filter's edge step (:func:`brent_maximize`),
a lane at a time. One addition:
``resolution``, the number of steps per interval to which a probe's instant is rounded before its
transition is taken (``None``: exact); given the compiled filter's resolution, the two follow
the same search path. ``tolerance`` (units of the interval) is the compiled filter's
``REFINE_TOLERANCE`` unless given.
"""

from __future__ import annotations

import math

import numpy as np
from numpy_kalman import kf_predict, kf_update

from switchest._linalg import log_normalize, mixture_moments
from switchest.discretize import interval, mode_steps, pairwise_grid, switch_grid
from switchest.engine.switch_time import REFINE_TOLERANCE


class SwitchTimeOracle:
    """The numpy switch-time Kalman filter; options as in ``SwitchTimeKalmanFilter``."""

    def __init__(self, system, x0, P0, *, grid=5, refine=False, likelihood="innovation",
                 refine_iterations=20, switch_time="max", gate=None, inflation=0.0,
                 resolution=None, tolerance=REFINE_TOLERANCE):
        self.system, self.x0, self.P0 = system, np.asarray(x0, float), np.asarray(P0, float)
        self.grid, self.refine, self.likelihood = grid, refine, likelihood
        self.refine_iterations, self.switch_time, self.gate = refine_iterations, switch_time, gate
        self.resolution, self.tolerance = resolution, tolerance
        self.inflation = inflation

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
            x, P = kf_predict(x, P, F, G, u, Qd, inflation=self.inflation)
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
        x_pred, P_pred = kf_predict(x[:, None], P[:, None], F, G, u[:, None], Qd,
                                    inflation=self.inflation)
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
        x_pred, P_pred = kf_predict(x, P, F, G, u, Qd, inflation=self.inflation)
        C, R = self.system.C[mode], self.system.R[mode]
        if self.likelihood == "innovation":
            return kf_update(x_pred, P_pred, y, C, R, gate=self.gate)[2]
        ll = kf_update(x_pred, np.zeros_like(P_pred), y, C, R)[2]  # "printed": R alone
        if self.gate is not None:
            gated = np.isneginf(kf_update(x_pred, P_pred, y, C, R, gate=self.gate)[2])
            ll = np.where(gated, -np.inf, ll)
        return ll

    def _golden(self, x, P, y, u, prev, mode, dt, lo, hi, best_tau, best_ll, best_tr):
        """Brent's search of each lane's cell, one lane at a time (:func:`brent_maximize`),
        started from the grid instant; a probe replaces the grid instant only where its
        likelihood is higher."""
        best_F, best_G, best_Q = (a.copy() for a in best_tr)
        best_tau, best_ll = best_tau.copy(), best_ll.copy()
        for i in np.flatnonzero(np.isfinite(best_ll)):  # an uninformed lane is not searched
            sl = slice(i, i + 1)

            def probe(tau, i=i, sl=sl):
                if self.resolution is not None:
                    steps = min(max(np.floor(tau / dt * self.resolution + 0.5), 0),
                                self.resolution)
                    tau = steps * (dt / self.resolution)
                tr = interval(self.system, dt, [prev[i], mode[i]], [tau])
                ll = float(self._loglik(x[sl], P[sl], tr.F[None], tr.G[None], u[sl],
                                        tr.Qd[None], y[sl], mode[sl])[0])
                if ll > best_ll[i]:
                    best_tau[i], best_ll[i] = tau, ll
                    best_F[i], best_G[i], best_Q[i] = tr.F, tr.G, tr.Qd
                return ll

            brent_maximize(probe, float(lo[i]), float(hi[i]), float(best_tau[i]),
                           float(best_ll[i]), self.tolerance * dt, self.refine_iterations)
        return best_tau, (best_F, best_G, best_Q)


def brent_maximize(f, a, b, x, fx, tol, max_probes):
    """Brent's method for a maximum of ``f`` on ``[a, b]`` from ``x`` with ``f(x) = fx``
    (Brent 1973, ch. 5; Forsythe, Malcolm & Moler's ``fmin`` on ``-f``) with the compiled
    filter's edge step, at most ``max_probes`` evaluations; returns how many were made.

    From ``fmin``: stop when ``|x - (a + b)/2| <= 2 tol1 - (b - a)/2`` with
    ``tol1 = sqrt(eps) |x| + tol / 3``; else a parabola through ``x``, ``w``, ``v`` if it falls
    inside ``(a, b)`` and moves less than half the step before last, else a golden-section
    step ``c e`` (``c = (3 - sqrt 5) / 2``) into the larger part; never nearer than ``tol1``.
    The edge step replaces a golden step where ``x``, ``w``, ``v`` lie in order toward an edge
    of the starting interval that still bounds the bracket, more than ``2 tol1`` from ``x``:
    that edge is probed (once), and if it is the best point, ``tol1`` inside it next.
    """
    c = 0.5 * (3.0 - math.sqrt(5.0))
    eps = math.sqrt(np.finfo(float).eps)
    fx = -fx
    v = w = x
    fv = fw = fx
    d = e = 0.0
    edge_a, edge_b = a, b  # NaN once probed
    inward = 0.0
    for count in range(max_probes):
        xm = 0.5 * (a + b)
        tol1 = eps * abs(x) + tol / 3.0
        tol2 = 2.0 * tol1
        if abs(x - xm) <= tol2 - 0.5 * (b - a):
            return count
        edge = 0.0
        if inward:
            u, inward = x + inward * tol1, 0.0
        else:
            parabola = False
            if abs(e) > tol1:
                r = (x - w) * (fx - fv)
                q = (x - v) * (fx - fw)
                p = (x - v) * q - (x - w) * r
                q = 2.0 * (q - r)
                if q > 0.0:
                    p = -p
                q = abs(q)
                r, e = e, d
                if abs(p) < abs(0.5 * q * r) and q * (a - x) < p < q * (b - x):
                    parabola = True
                    d = p / q
                    if (x + d) - a < tol2 or b - (x + d) < tol2:
                        d = tol1 if xm - x >= 0.0 else -tol1
            if not parabola and a == edge_a and x < w < v and x - a > tol2:
                u, edge, edge_a = a, 1.0, math.nan
            elif not parabola and b == edge_b and x > w > v and b - x > tol2:
                u, edge, edge_b = b, -1.0, math.nan
            else:
                if not parabola:
                    e = (a - x) if x >= xm else (b - x)
                    d = c * e
                u = x + d if abs(d) >= tol1 else x + (tol1 if d >= 0.0 else -tol1)
        fu = -f(u)
        if fu <= fx:
            inward = edge
            if u >= x:
                a = x
            else:
                b = x
            v, fv, w, fw, x, fx = w, fw, x, fx, u, fu
        else:
            if u < x:
                a = u
            else:
                b = u
            if fu <= fw or w == x:
                v, fv, w, fw = w, fw, u, fu
            elif fu <= fv or v == x or v == w:
                v, fv = u, fu
    return max_probes
