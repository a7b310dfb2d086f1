"""The E-step of unknown modes: the IMM and the two-filter smoother on a chain of members
(:mod:`~switchest.estimators.mode_chains`: the pairs of consecutive modes, or (mode before,
mode after, switching instant)), :math:`s_k` the member of sample :math:`k` and :math:`r_k` the
mode it ends in.

- The likelihood: the IMM on the chain (Bar-Shalom, Li & Kirubarajan §11.6.6, one mode-matched
  filter per member), :math:`\\sum_k \\log p(y_k \\mid y_{0:k-1})`; its outlier gate is the
  E-step's.
- The moments: the two-filter smoother of the IMM's mode-matched posteriors
  (:func:`~switchest.estimators.two_filter.two_filter_smooth`, stable where Kim's diverges, as
  on the boost converter of Shankar et al.) gives :math:`P(s_k \\mid Y)` and
  :math:`x_k \\mid s_k, Y`, so :math:`P(r_k = b \\mid Y)` and :math:`x_k \\mid r_k = b, Y` as the
  mixtures over the members that end in ``b``. The interval :math:`k \\to k+1` is a mixture over
  the members :math:`c` of :math:`s_{k+1}`. Given :math:`s_{k+1} = c` with first mode ``a``, the
  IMM's prior of :math:`x_k` is its mixture for ``c``, :math:`\\mathcal{N}(\\bar{x}_a,
  \\bar{P}_a)`, the filtered posterior given :math:`r_k = a` (the chain's mixing weights
  :math:`\\mu_{d \\mid c} \\propto \\mu_d\\, P(c \\mid d)` depend on ``c`` only through ``a``),
  and the later measurements depend on :math:`x_k` only through :math:`x_{k+1}`: the joint
  posterior of :math:`(x_k, x_{k+1})` given ``c`` is the smoothed
  :math:`\\mathcal{N}(x^s_c, P^s_c)` of :math:`x_{k+1}` and one Rauch-Tung-Striebel step back
  from it through ``c``'s :math:`F_c, G_c, Q_{d,c}` (one step, not a recursion):

  .. math::

      \\begin{aligned}
      J &= \\bar{P}_a F_c^\\top (F_c \\bar{P}_a F_c^\\top + Q_{d,c})^{-1}, \\\\
      E[x_k \\mid c, Y] &= \\bar{x}_a + J (x^s_c - F_c \\bar{x}_a - G_c u_k), \\\\
      \\operatorname{Cov}(x_k \\mid c, Y) &= \\bar{P}_a
          + J (P^s_c - F_c \\bar{P}_a F_c^\\top - Q_{d,c}) J^\\top, \\qquad
      \\operatorname{Cov}(x_{k+1}, x_k \\mid c, Y) = P^s_c J^\\top.
      \\end{aligned}

  The members that move through one transition (the pairs of one driving mode, switching at
  the samples) are merged into one component of :class:`~switchest.learn.moments.Moments`
  (Gaussian-mixture moments of the joint :math:`(x_{k+1}, x_k)`).

Over one interval (two samples) the IMM and the smoother merge nothing and the E-step is exact;
over more it is approximate twice over (the IMM's and the smoother's merging: the exact
posterior is a mixture of :math:`L^K`, or :math:`(L + L (L - 1) g)^K`, Gaussians), so
:func:`~switchest.learn.fit` accepts EM's steps while they raise the IMM's likelihood and
finishes by direct ascent of it (:mod:`~switchest.learn.ascent`).
"""

from __future__ import annotations

import math

import numpy as np

from .._linalg import symmetrize
from ..estimators.mode_chains import ModeChain
from ..estimators.tables import imm_posteriors
from ..estimators.two_filter import two_filter_smooth
from .data import Record
from .moments import Moments, mode_mixture

__all__ = ["chain_log_likelihood", "chain_moments"]


def _forward(chain: ModeChain, data: Record, x0, P0, gate: float, modes_out: bool = True):
    """The IMM on the chain, with its mode-matched posteriors (``modes_out``), and its outlier
    flags."""
    with np.errstate(divide="ignore"):  # log 0 = -inf: an impossible member
        log_matrix, log_prior = np.log(chain.matrix), np.log(chain.prior)
    t = chain.table
    return imm_posteriors(data.y, data.u, t.F, t.G, t.Qd, chain.trans, chain.C, chain.R,
                          log_matrix, np.asarray(x0, dtype=float), np.asarray(P0, dtype=float),
                          log_prior, gate=gate, timing="interval", modes_out=modes_out)


def chain_log_likelihood(chain: ModeChain, data: Record, x0, P0) -> float:
    """The log-likelihood :func:`chain_moments` reports, without the smoother or a gate."""
    return float(_forward(chain, data, x0, P0, math.inf, modes_out=False)[0].loglik.sum())


def chain_moments(chain: ModeChain, data: Record, x0, P0, L: int,
                  gate: float | None) -> Moments:
    """The E-step on ``chain`` of a system of ``L`` modes (module docstring); ``gate`` the
    filter's outlier gate."""
    fwd, outlier = _forward(chain, data, x0, P0, math.inf if gate is None else gate)
    y = np.where(outlier[..., None], np.nan, data.y)
    table = chain.table
    s = two_filter_smooth(fwd.x_modes, fwd.P_modes, fwd.mode_prob, y, data.u, table.F, table.G,
                          table.Qd, chain.trans, chain.matrix, chain.C, chain.R,
                          outlier=outlier, timing="interval")
    prob = s.mode_prob  # (N, K, M): P(s_k | Y)
    after = np.eye(L)[chain.second]  # (M, L): the members that end in each mode
    weight = prob @ after  # P(r_k = b | Y)
    x, P = mode_mixture(prob, weight, after, s.x_modes, s.P_modes)
    # x_k given r_k = a and y_{0:k}: the IMM's prior of every member leaving a at k
    prior_x, prior_P = mode_mixture(fwd.mode_prob, fwd.mode_prob @ after, after, fwd.x_modes,
                                    fwd.P_modes)
    rows = chain.trans[1:]  # (K-1, M)
    F, G, Qd = table.F[rows], table.G[rows], table.Qd[rows]
    xa = prior_x[:, :-1][:, :, chain.first]  # (N, K-1, M, n)
    Pa = prior_P[:, :-1][:, :, chain.first]
    x_pred = (F @ xa[..., None])[..., 0] + (G @ data.u[:, :-1, None, :, None])[..., 0]
    P_pred = symmetrize(F @ Pa @ np.swapaxes(F, -1, -2) + Qd)
    Jt = np.linalg.solve(P_pred, F @ Pa)  # J' = P_pred^-1 F Pa
    J = np.swapaxes(Jt, -1, -2)
    x1, P1 = s.x_modes[:, 1:], s.P_modes[:, 1:]
    x0_c = xa + (J @ (x1 - x_pred)[..., None])[..., 0]
    P0_c = symmetrize(Pa + J @ (P1 - P_pred) @ Jt)
    cross = P1 @ Jt
    n, H = x.shape[-1], chain.entry.shape[1]
    step_weight = prob[:, 1:]
    if H < chain.first.size:  # merge the members of each component: their joint moments
        member = np.eye(H)[chain.component]
        step_weight = prob[:, 1:] @ member
        jx, jP = mode_mixture(prob[:, 1:], step_weight, member,
                              np.concatenate([x1, x0_c], axis=-1),
                              np.block([[P1, cross], [np.swapaxes(cross, -1, -2), P0_c]]))
        x1, x0_c = jx[..., :n], jx[..., n:]
        P1, P0_c, cross = jP[..., :n, :n], jP[..., n:, n:], jP[..., :n, n:]
    pairs = np.zeros((L, L))
    np.add.at(pairs, (chain.first, chain.second), prob[:, 1:].sum(axis=(0, 1)))
    return Moments(loglik=float(fwd.loglik.sum()), weight=weight, x=x, P=P,
                   step_weight=step_weight, x1=x1, P1=P1, x0=x0_c, P0=P0_c, cross=cross,
                   table=table, entry=chain.entry, pairs=pairs, y=y, outlier=outlier)
