"""Maximization step of the mode transition matrix, and the rate matrix of a continuous chain.

:math:`\\pi_{ji} = \\sum_k \\xi_k(j, i) / \\sum_k \\sum_{i'} \\xi_k(j, i')` with
:math:`\\xi_k(j, i) = P(r_k = j, r_{k+1} = i \\mid Y)` (Hamilton 1990, J. Econometrics 45, eq.
(4.8); with known modes the counts of the observed transitions, the exact MLE of a Markov chain,
Anderson & Goodman 1957, Ann. Math. Stat. 28, eq. (2.4)). Its standard error is the multinomial
one, :math:`\\sqrt{\\pi_{ji} (1 - \\pi_{ji}) / n_j}` with :math:`n_j` the visits of ``j``
(Anderson & Goodman 1957, §3), for known modes; with unknown modes the expected counts would be
treated as observed, which understates the uncertainty (the missing information of the modes),
and :func:`switchest.learn.fit` takes the observed information instead (:mod:`.standard_errors`).
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import logm

__all__ = ["fit_transition", "free_rows", "mode_term", "rates_from_transition", "transition_se"]


def fit_transition(pairs: np.ndarray, current: np.ndarray) -> np.ndarray:
    """New transition matrix from (expected) counts ``pairs[j, i]``; a row with less than one
    (expected) visit keeps its ``current`` value."""
    visits = pairs.sum(axis=1)
    new = current.copy()
    ok = visits >= 1.0
    new[ok] = pairs[ok] / visits[ok, None]
    return new


def free_rows(transition: np.ndarray, allowed: np.ndarray | None = None
              ) -> list[tuple[int, int, np.ndarray]]:
    """The free entries of a transition matrix, row by row: ``(j, r, cols)`` with ``r`` the
    row's largest entry, which the others fix (the row sums to one), and ``cols`` its other
    nonzero entries (a zero entry stays zero under EM's M-step, so it is not free), or its
    other entries where ``allowed`` (a fit's start, whose zeros were held) is nonzero; rows
    without a free entry are left out."""
    support = transition if allowed is None else allowed
    out = []
    for j, row in enumerate(transition):
        r = int(np.argmax(row))
        cols = np.flatnonzero((support[j] > 0) & (np.arange(row.size) != r))
        if cols.size:
            out.append((j, r, cols))
    return out


def mode_term(transition: np.ndarray, modes: np.ndarray) -> float:
    """:math:`\\sum_k \\log \\pi_{r_k r_{k+1}}` of the known mode sequences ``modes (N, K)``
    (``-inf`` if one is impossible): the modes' share of the complete-data log-likelihood."""
    with np.errstate(divide="ignore"):
        return float(np.log(transition)[modes[:, :-1], modes[:, 1:]].sum())


def transition_se(transition: np.ndarray, visits: np.ndarray) -> np.ndarray:
    """Multinomial standard errors :math:`\\sqrt{p (1 - p) / n_j}`; NaN for a row never visited."""
    with np.errstate(divide="ignore", invalid="ignore"):
        se = np.sqrt(transition * (1 - transition) / visits[:, None])
    se[visits < 1.0] = np.nan
    return se


def rates_from_transition(transition: np.ndarray, period: float) -> np.ndarray | None:
    """The generator :math:`\\Lambda` with :math:`\\exp(\\Lambda T) = \\mathrm{transition}`:
    :math:`\\log(\\mathrm{transition}) / T` (Israel, Rosenthal & Wei 2001, Math. Finance 11, §2),
    or None where the principal logarithm is not a valid generator (complex, or a negative
    off-diagonal rate beyond rounding): then no continuous-time chain sampled at ``T`` has this
    transition matrix."""
    with np.errstate(all="ignore"):
        try:
            G = logm(transition)
        except (ValueError, np.linalg.LinAlgError):
            return None
    if not np.all(np.isfinite(G)) or np.max(np.abs(np.imag(G))) > 1e-9:
        return None
    G = np.real(G) / period
    off = G - np.diag(np.diag(G))
    scale = max(float(np.max(np.abs(G))), 1e-300)
    if np.min(off) < -1e-9 * scale:
        return None
    off = np.maximum(off, 0.0)
    return off - np.diag(off.sum(axis=1))
