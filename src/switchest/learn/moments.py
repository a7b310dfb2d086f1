"""What an E-step hands to the maximization steps: smoothed moments, weights, the table of the
intervals' transitions, and the measurements it used."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._linalg import mixture_moments
from ..estimators.step_tables import StepTable

__all__ = ["Moments", "mode_mixture"]


@dataclass(frozen=True, eq=False)
class Moments:
    """The E-step's output for ``N`` trials, ``K`` samples, ``L`` modes.

    Each interval :math:`k \\to k+1` is a mixture of ``H`` components, each moving through one row
    of ``table``: with switches at the samples the component ``h`` is the mode ``h`` that
    drives the interval (:math:`H = L`); with switches inside the intervals
    (:mod:`~switchest.learn.between`) it is the switch instant ``h`` of the grid (:math:`H = g`).

    Attributes
    ----------
    loglik : float
        Log-likelihood of the record under the parameters of the E-step (known modes:
        :math:`\\log p(y \\mid r) + \\sum_k \\log \\pi_{r_k r_{k+1}}`, with switches inside the
        intervals the switch-time filter's with the instants marginalized; unknown: the pair
        chain's IMM's :math:`\\sum \\log p(y_k \\mid y_{0:k-1})`, or with the exact E-step the exact
        :math:`\\log p(y)`, which :class:`~switchest.estimators.ExactMixtureFilter`'s ``loglik``
        sums to).
    weight : ndarray, shape (N, K, L)
        :math:`P(r_k = j \\mid Y)` (one-hot for known modes).
    x, P : ndarray, shapes (N, K, L, n), (N, K, L, n, n)
        Smoothed state moments given :math:`r_k = j` (broadcast views for known modes).
    step_weight : ndarray, shape (N, K-1, H)
        Weight of component ``h`` of the interval :math:`k \\to k+1`.
    x1, P1 : ndarray, shapes (N, K-1, H, n), (N, K-1, H, n, n)
        Moments of :math:`x_{k+1}` given the component and ``Y``.
    x0, P0, cross : ndarray, shapes (N, K-1, H, n), (N, K-1, H, n, n), (N, K-1, H, n, n)
        Moments of :math:`x_k` and :math:`\\operatorname{Cov}(x_{k+1}, x_k)` given the component and
        ``Y``.
    table : StepTable
        The exact transitions of the components, with their segments.
    entry : ndarray of int64, shape (K-1, H) or (N, K-1, H)
        The table row of each component of each interval.
    pairs : ndarray, shape (L, L)
        Expected transition counts :math:`\\sum_k P(r_k = j, r_{k+1} = i \\mid Y)`.
    y : ndarray, shape (N, K, m)
        The measurements the E-step used: the record's, with the samples its filter gated
        (``outlier``) missing.
    outlier : ndarray of bool, shape (N, K)
        The samples the filter's gate rejected.
    """

    loglik: float
    weight: np.ndarray
    x: np.ndarray
    P: np.ndarray
    step_weight: np.ndarray
    x1: np.ndarray
    P1: np.ndarray
    x0: np.ndarray
    P0: np.ndarray
    cross: np.ndarray
    table: StepTable
    entry: np.ndarray
    pairs: np.ndarray
    y: np.ndarray
    outlier: np.ndarray


def mode_mixture(prob, weight, member, x, P) -> tuple[np.ndarray, np.ndarray]:
    """Moments given each mode: the mixture of the components (mode pairs, chain members or
    mode sequences) that hold it. ``prob (N, K', S)`` the components' probabilities,
    ``member (..., S, L)`` (broadcast against them) which components hold each mode,
    ``weight (N, K', L)`` the sums :math:`P(\\text{mode} \\mid Y)`; a mode of weight zero gets
    the mixture of all components (it carries no weight)."""
    w = prob[..., :, None] * member  # (N, K', S, L)
    none = weight <= 0.0
    cond = np.where(none[:, :, None], prob[..., :, None],
                    w / np.where(none, 1.0, weight)[:, :, None])
    return mixture_moments(cond, x, P)
