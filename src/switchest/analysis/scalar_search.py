"""The largest value of a scalar at which a monotone feasibility problem is still feasible.

The scalar design searches of Etienne et al. (seed 004) fix every scalar of an LMI family
but one (the decay rate :math:`\\alpha` of Theorem 8's (6) or Theorem 10's (25)): the LMIs stay
feasible when :math:`\\alpha` decreases (it multiplies :math:`P \\succ 0`), so the largest feasible
:math:`\\alpha` is bracketed upward by doubling steps and bisected.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TypeVar

from .._checks import positive_scalar

__all__ = ["largest_feasible"]

Solution = TypeVar("Solution")


def largest_feasible(
    solve: Callable[[float], Solution],
    feasible: Callable[[Solution], bool],
    start: float,
    *,
    tol: float,
    step: float,
    doublings: int,
) -> tuple[float, Solution] | None:
    """Largest :math:`a \\ge \\mathrm{start}` with ``feasible(solve(a))``, within ``tol``, for a
    monotone problem.

    The problem must be feasible on :math:`[\\mathrm{start}, a^*]` and infeasible above
    :math:`a^*` (as the LMIs of Etienne et al. Theorems 8 and 10 in their rate :math:`\\alpha`).
    From ``start`` the bracket grows by
    :math:`\\mathrm{step}, 2\\,\\mathrm{step}, 4\\,\\mathrm{step}, \\dots` until the problem
    fails (at most ``doublings`` trials), then bisection halves it until it is at most ``tol``
    wide. When no trial fails the last feasible point is returned (:math:`a^*` lies beyond the
    bracket's reach).

    Parameters
    ----------
    solve : callable
        ``a -> solution`` (one solve per call; the calls are made in increasing :math:`a`
        while bracketing, then at the midpoints).
    feasible : callable
        ``solution -> bool``.
    start : float
        Lower end of the search: where the search starts and what is returned if
        bracketing already fails at :math:`\\mathrm{start} + \\mathrm{step}`.
    tol : float
        Width of the final bracket, :math:`> 0`.
    step : float
        First bracketing step, :math:`> 0`.
    doublings : int
        Most bracketing trials, :math:`\\ge 1`.

    Returns
    -------
    (float, solution) or None
        The largest feasible :math:`a` found and its solution; ``None`` when ``start`` is
        infeasible.

    Raises
    ------
    TypeError, ValueError
        If ``tol`` or ``step`` is not a positive number, or ``doublings`` not a positive int.
    """
    tol, step = positive_scalar(tol, "tol"), positive_scalar(step, "step")
    if not isinstance(doublings, int) or isinstance(doublings, bool) or doublings < 1:
        raise ValueError(f"doublings must be a positive int, got {doublings!r}")
    lo, best = start, solve(start)
    if not feasible(best):
        return None
    hi = None
    for _ in range(doublings):  # bracket: double the step until the problem fails
        trial = solve(lo + step)
        if not feasible(trial):
            hi = lo + step
            break
        lo, best, step = lo + step, trial, 2 * step
    while hi is not None and hi - lo > tol:
        mid = 0.5 * (lo + hi)
        trial = solve(mid)
        if feasible(trial):
            lo, best = mid, trial
        else:
            hi = mid
    return lo, best
