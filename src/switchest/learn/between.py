"""The E-step of known modes whose switches fall inside the sampling intervals.

A continuous-time system sampled at :math:`t_k` whose mode changes between two samples
(:math:`r_k \\ne r_{k+1}`) switches at an instant :math:`t_k + \\tau` inside the interval, and
the interval then moves the state exactly through
:math:`F(\\tau) = e^{A_b (h - \\tau)} e^{A_a \\tau}`, :math:`G(\\tau)` and :math:`Q_d(\\tau)`
(Shankar et al. eqs (3)-(5), with the exact process noise of :mod:`switchest.discretize`), not
through the transition of either mode alone: an E-step that holds the mode over the whole
interval puts the difference into the noise (on the boost converter of Shankar et al. §V.A,
R = 5 fits as 60).

The instant is not known: it is a latent variable with a uniform prior on the grid of Shankar et
al. eq. (23), :math:`\\tau_i = i h / g - h / (2 g)`, independently in each interval with a switch
(the dwell time exceeds :math:`h`: at most one switch per interval, Shankar §II), and it is
marginalized.

- The likelihood: the switch-time Kalman filter with the instant marginalized over the grid
  (:class:`~switchest.estimators.SwitchTimeKalmanFilter`, ``switch_time="marginal"``, beyond
  Shankar et al.):
  :math:`\\sum_k \\log\\big(\\frac{1}{g} \\sum_i p(y_{k+1} \\mid y_{0:k}, \\tau_i)\\big)`, each
  mixture merged by moment matching after its sample; its gate is the E-step's outlier gate,
  and its posterior mean instants :math:`\\hat{\\tau}` are the E-step's working instants.
- The moments: the Kalman filter and RTS smoother with the instants at :math:`\\hat{\\tau}`, both
  along one table of transitions, the switched intervals discretized once
  (:func:`~switchest.estimators.tables.kalman_posteriors`,
  :func:`~switchest.estimators.smoothing.smooth_mode_matched` with one mode), then, interval by
  interval, the posterior of its own instant given the whole record and the others at
  :math:`\\hat{\\tau}`. Given :math:`x_{k+1}` the measurements after ``k + 1`` do not depend on
  the instant of the interval into it, so with the filtered :math:`\\mathcal{N}(m_i, P_i)` at
  ``k + 1`` under :math:`\\tau_i` (predicted from the filtered posterior at ``k`` and updated
  with :math:`y_{k+1}`, :func:`~switchest.estimators.kalman.kf_predict`,
  :func:`~switchest.estimators.kalman.kf_update`, innovation log-likelihood :math:`l_i`) and
  the likelihood of the later measurements
  :math:`\\beta(x) \\propto \\exp(-x^\\top \\Lambda x / 2 + \\eta^\\top x)`, which the smoother
  gives as the ratio of its smoothed to its filtered Gaussian at ``k + 1``
  (:math:`\\Lambda = P_s^{-1} - P_f^{-1}`, :math:`\\eta = P_s^{-1} m_s - P_f^{-1} m_f`: the
  two-filter form of the smoother, Fraser & Potter 1969, IEEE TAC 14):

  .. math::

      \\begin{aligned}
      \\log P(\\tau_i \\mid Y) &= l_i + b_i + \\text{const}, \\\\
      b_i &= \\log \\int \\mathcal{N}(x; m_i, P_i)\\, \\beta(x)\\, dx \\\\
      &= -\\log\\det(I + P_i \\Lambda) / 2
         + \\big(m_i^\\top (I + \\Lambda P_i)^{-1} (\\eta - \\Lambda m_i)
         + \\eta^\\top m_i^s\\big) / 2,
      \\end{aligned}

  :math:`x_{k+1} \\mid \\tau_i, Y \\sim \\mathcal{N}(m_i^s, P_i^s)` with
  :math:`P_i^s = (I + P_i \\Lambda)^{-1} P_i`,
  :math:`m_i^s = (I + P_i \\Lambda)^{-1} (m_i + P_i \\eta)` (the product of the two Gaussians),
  and :math:`x_k` given :math:`x_{k+1}` by the RTS step through :math:`F(\\tau_i)`: the interval
  is a mixture of :math:`g` components, component ``i`` through the grid's row
  :math:`(r_k, r_{k+1}, \\tau_i)` of :func:`~switchest.estimators.step_tables.grid_table`, with
  weight :math:`P(\\tau_i \\mid Y)` (an interval without a switch: one component, its mode's
  own row).

Each instant's posterior is exact given the others (it equals the normalized likelihood of the
whole record over the grid, one Kalman filter per instant, to 1e-7); holding the others at
:math:`\\hat{\\tau}` makes the E-step approximate (the exact posterior is a mixture of
:math:`g^S` Gaussians for ``S`` switches). The likelihood the fit maximizes is the filter's
above, so, as with unknown modes, :func:`~switchest.learn.fit` accepts EM's steps while they
raise it and finishes by direct ascent of it (:mod:`~switchest.learn.ascent`), whose maximum is
the fit: on the boost converter, whose switches come every second sample with an instant the data
place to about 0.1 of the interval, EM from the true parameters would drift to R = 8-9.5 for
5 (the neighbours' instants held at the filter's estimates, off by about 0.2 of the interval,
put their error into R), and its first step is rejected there; from R x 2 it climbs for a few
steps. Holding the instants at their maximum-likelihood values instead of marginalizing them
is biased (incidental parameters: R = 2.7-3.4 on three trials of the boost converter whose
true instants give 4.7-5.2), and Kim's smoother on the chain of instants, collapsing at every
sample, loses which instant each later state came through (its EM steps lowered the
likelihood from the first).
"""

from __future__ import annotations

import numpy as np

from .._linalg import log_normalize, mixture_moments, symmetrize
from ..discretize import Transition
from ..dyadic import dyadic_table, interval_transitions
from ..estimators import SwitchTimeKalmanFilter
from ..estimators.kalman import kf_predict, kf_update
from ..estimators.smoothing import smooth_mode_matched
from ..estimators.step_tables import grid_table
from ..estimators.tables import kalman_posteriors
from ..system import SwitchedLinearSystem
from .data import Record
from .markov_step import mode_term
from .moments import Moments

__all__ = ["between_log_likelihood", "instant_posteriors", "known_between"]


def _filter(system, x0, P0, grid: int, gate) -> SwitchTimeKalmanFilter:
    return SwitchTimeKalmanFilter(system, x0, P0, grid=grid, switch_time="marginal", gate=gate)


def between_log_likelihood(system: SwitchedLinearSystem, transition, x0, P0, data: Record, *,
                           grid: int) -> float:
    """The log-likelihood :func:`known_between` reports, without the smoother or a gate."""
    est = _filter(system, x0, P0, grid, None).run(data.y, data.u, data.t, modes=data.modes)
    return float(est.loglik.sum()) + mode_term(transition, data.modes)


def known_between(system: SwitchedLinearSystem, transition, x0, P0, data: Record, *,
                  grid: int, gate: float | None) -> Moments:
    """The E-step of known modes with switches inside the intervals, each instant marginalized
    over a grid of ``grid`` (module docstring); ``gate`` the filter's outlier gate."""
    est = _filter(system, x0, P0, grid, gate).run(data.y, data.u, data.t, modes=data.modes)
    used = np.where(est.outlier[..., None], np.nan, data.y)
    offset = np.nan_to_num(est.switch_time[:, 1:] - data.t[:-1])  # tau_hat, 0 without a switch
    part = instant_posteriors(system, x0, P0, Record(used, data.u, data.t, data.modes), offset,
                              grid)
    return Moments(loglik=float(est.loglik.sum()) + mode_term(transition, data.modes),
                   y=used, outlier=est.outlier, **part)


def instant_posteriors(system: SwitchedLinearSystem, x0, P0, data: Record, offset: np.ndarray,
                       grid: int) -> dict[str, np.ndarray]:
    """The moments of :class:`Moments` but ``loglik``, ``y`` and ``outlier``: the smoothed
    state and each interval's ``grid`` components with the instants ``offset (N, K-1)`` (in
    the intervals with a switch; module docstring). ``step_weight[i, k]`` is then the posterior
    of the instant of the interval :math:`k \\to k+1` of trial ``i`` on the grid, given the record
    and the other instants at ``offset``."""
    y, u, t, modes = data.y, data.u, data.t, data.modes
    (N, K), L, g = data.shape, system.n_modes, grid
    a, b = modes[:, :-1], modes[:, 1:]
    table, entry, switched = grid_table(system, t, g)
    trial, before = np.nonzero(a != b)  # the intervals with a switch, into sample before + 1
    S, M = trial.size, table.F.shape[0]
    at = _switched(system, np.diff(t)[before], np.stack([a, b], axis=-1)[trial, before],
                   offset[trial, before, None])
    F, G, Qd = (np.concatenate([getattr(table, name), getattr(at, name)])
                for name in ("F", "G", "Qd"))
    trans = np.zeros((N, K), dtype=np.int64)  # into each sample, the instants at ``offset``
    trans[:, 1:] = entry[np.arange(1, K), a]
    trans[trial, before + 1] = M + np.arange(S)
    kf = kalman_posteriors(y, u, F, G, Qd, trans, system.C, system.R, modes,
                           np.asarray(x0, dtype=float), np.asarray(P0, dtype=float))
    s = smooth_mode_matched(kf.x[:, :, None], kf.P[:, :, None], np.ones((N, K, 1)), u, F, G,
                            Qd, trans[:, :, None], np.ones((1, 1)),
                            lagged=True, timing="interval")  # one mode: the timings agree
    n = system.n_states
    x, P = s.x.copy(), s.P.copy()
    step_weight = np.zeros((N, K - 1, g))
    step_weight[..., 0] = 1.0  # an interval without a switch: one component
    comp = {"x1": s.x[:, 1:], "P1": s.P[:, 1:], "x0": s.lag_x[:, :, 0], "P0": s.lag_P[:, :, 0],
            "cross": s.lag_cross[:, :, 0]}
    comp = {k: np.repeat(v[:, :, None], g, axis=2) for k, v in comp.items()}
    rows = np.repeat(trans[:, 1:, None], g, axis=2)
    if S:
        rows[trial, before] = switched[before + 1, a[trial, before], b[trial, before]]
        r = rows[trial, before]  # (S, g)
        xk, Pk = kf.x[trial, before][:, None], kf.P[trial, before][:, None]
        xp, Pp = kf_predict(xk, Pk, table.F[r], table.G[r], u[trial, before][:, None],
                            table.Qd[r])
        after = modes[trial, before + 1]
        m, Pm, loglik = kf_update(xp, Pp, y[trial, before + 1][:, None], system.C[after][:, None],
                                  system.R[after][:, None])
        lam, eta = _later(kf.x[trial, before + 1], kf.P[trial, before + 1],
                          s.x[trial, before + 1], s.P[trial, before + 1])
        lam, eta = lam[:, None], eta[:, None]
        eye = np.eye(n)
        inner = eye + Pm @ lam  # I + P_i Lam
        Ps = symmetrize(np.linalg.solve(inner, Pm))  # (I + P Lam)^-1 P
        ms = np.linalg.solve(inner, (m + (Pm @ eta[..., None])[..., 0])[..., None])[..., 0]
        # (I + Lam P)^-1 (eta - Lam m) = eta - Lam ms, since (P^-1 + Lam) ms = P^-1 m + eta
        back = eta - (lam @ ms[..., None])[..., 0]
        b_i = 0.5 * (np.sum(m * back, axis=-1) + np.sum(eta * ms, axis=-1)
                     - np.linalg.slogdet(inner)[1])
        w = np.exp(log_normalize(loglik + b_i)[0])  # P(tau_i | Y), (S, g)
        # x_k given x_{k+1} and tau_i: the RTS step J = P_k F' (F P_k F' + Qd)^-1
        J = np.swapaxes(np.linalg.solve(Pp, table.F[r] @ Pk), -1, -2)
        step_weight[trial, before] = w
        comp["x1"][trial, before], comp["P1"][trial, before] = ms, Ps
        comp["x0"][trial, before] = xk + (J @ (ms - xp)[..., None])[..., 0]
        comp["P0"][trial, before] = symmetrize(Pk + J @ (Ps - Pp) @ np.swapaxes(J, -1, -2))
        comp["cross"][trial, before] = Ps @ np.swapaxes(J, -1, -2)
        # the smoothed state at the two samples of the interval: the mixture over the instants
        for k, (mean, cov) in ((before + 1, (ms, Ps)),
                               (before, (comp["x0"][trial, before], comp["P0"][trial, before]))):
            mx, mP = mixture_moments(w[..., None], mean, cov)
            x[trial, k], P[trial, k] = mx[:, 0], mP[:, 0]
    pairs = np.zeros((L, L))
    np.add.at(pairs, (a, b), 1.0)

    def modes_axis(v):
        return np.broadcast_to(v[:, :, None], (N, K, L, *v.shape[2:]))

    return dict(weight=np.eye(L)[modes], x=modes_axis(x), P=modes_axis(P),
                step_weight=step_weight, table=table, entry=rows, pairs=pairs, **comp)


def _switched(system, length, modes, offsets) -> Transition:
    """The exact transitions of the switched intervals ``(S,)`` of lengths ``length`` with the
    segments ``modes (S, 2)``, ``offsets (S, 1)`` (Shankar et al. eqs (3)-(5)), composed from
    each length's dyadic table (:func:`switchest.dyadic.interval_transitions`, as the
    clairvoyant :class:`~switchest.estimators.ModeKalmanFilter` does): computed once, for the
    filter and the smoother alike."""
    S, n, l = length.size, system.n_states, system.n_inputs
    F, G, Qd = np.zeros((S, n, n)), np.zeros((S, n, l)), np.zeros((S, n, n))
    for h in np.unique(length):
        at = length == h
        tr = interval_transitions(dyadic_table(system, float(h)), modes[at], offsets[at])
        F[at], G[at], Qd[at] = tr.F, tr.G, tr.Qd
    return Transition(F, G, Qd)


def _later(m_f, P_f, m_s, P_s) -> tuple[np.ndarray, np.ndarray]:
    """:math:`\\Lambda`, :math:`\\eta` of the likelihood of the later measurements,
    :math:`\\beta(x) \\propto \\exp(-x^\\top \\Lambda x / 2 + \\eta^\\top x)`: the smoothed Gaussian
    :math:`\\mathcal{N}(m_s, P_s)` divided by the filtered :math:`\\mathcal{N}(m_f, P_f)` (module
    docstring)."""
    # Lam = P_s^-1 - P_f^-1 = P_f^-1 (P_f - P_s) P_s^-1: solves of the difference, which keep
    # the digits that subtracting two inverses loses where the later samples add little
    ratio = np.linalg.solve(P_s, P_f - P_s)  # P_s^-1 (P_f - P_s)
    lam = symmetrize(np.linalg.solve(P_f, np.swapaxes(ratio, -1, -2)))
    eta = (np.linalg.solve(P_s, m_s[..., None]) - np.linalg.solve(P_f, m_f[..., None]))[..., 0]
    return lam, eta
