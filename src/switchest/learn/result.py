"""The result of a fit: the fitted model, the log-likelihood trace and the standard errors."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from ..system import SwitchedLinearSystem

__all__ = ["FitResult"]


@dataclass(frozen=True, eq=False)
class FitResult:
    """What :func:`switchest.learn.fit` returns.

    Attributes
    ----------
    system : SwitchedLinearSystem
        The fitted system (the parameters not estimated are those given).
    transition : ndarray, shape (L, L)
        The fitted (or given) transition matrix, ``transition[i, j]`` =
        :math:`P(\\text{mode } j \\text{ at } k+1 \\mid \\text{mode } i \\text{ at } k)`.
    loglik : ndarray, shape (iterations,)
        ``loglik[i]``: the log-likelihood of the data under the parameters of iteration ``i``
        (``i = 0`` the starting ones); the last entry is that of ``system``, ``transition``.
    converged : bool
        Whether EM's stopping rule (the gain, and the gain still to come, at most ``tol``
        nats) held before ``max_iter`` iterations (after a direct ascent: whether it reached a
        stationary point).
    iterations : int
        Number of iterations in ``loglik``: accepted E-steps, then those of the ascent.
    ascent_from : int or None
        With an approximate E-step (unknown modes with ``e_step="two-filter"``, or switches
        between the samples), the index of ``loglik`` where the direct ascent
        (:mod:`~switchest.learn.ascent`) begins, from the last EM iterate (EM stops at the
        first step that would lower the likelihood, and that step is not in ``loglik``). None
        when the fit was EM throughout.
    se : Mapping of str to ndarray
        Standard error of each estimated parameter, with the parameter's shape (``"transition"``
        ``(L, L)``, ``"Q"`` ``(L, n, n)``, ``"R"`` ``(L, m, m)``, ...); NaN where none exists (a
        component held at zero, a mode never visited, ``A``, ``B``, ``C`` when both the
        dynamics and ``C`` are fitted, a singular information matrix).
    rates : ndarray, shape (L, L), or None
        For a continuous-time system sampled periodically, the generator of a continuous-time
        Markov chain whose transition over one period is ``transition`` (None where no valid
        generator exists: :func:`switchest.learn.rates_from_transition`).
    shared : tuple of str
        The matrices fitted as one for all modes (``fit``'s ``shared``).
    switch_times : str
        ``"samples"`` or ``"between"``: where the E-step put the switches of known modes.
    outlier : ndarray of bool, shape (N, K), or None
        The samples the E-step's filter gated (treated as missing) at the fit.
    outliers : int
        Their number.
    """

    system: SwitchedLinearSystem
    transition: np.ndarray
    loglik: np.ndarray
    converged: bool
    iterations: int
    se: Mapping[str, np.ndarray]
    rates: np.ndarray | None = None
    ascent_from: int | None = None
    shared: tuple[str, ...] = ()
    switch_times: str = "samples"
    outlier: np.ndarray | None = None
    outliers: int = 0
