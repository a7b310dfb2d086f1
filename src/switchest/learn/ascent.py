"""The end of a fit with unknown modes: direct ascent of the E-step's log-likelihood.

With unknown modes, the E-step (:mod:`~switchest.learn.chain`) is approximate, and the
fixed point of EM with it is not a maximum of the log-likelihood it reports (the pair chain's
IMM): near the optimum its M-steps can lower that likelihood and stall away from the top, where
the observed information is not even negative definite. :func:`ascend` therefore finishes the
fit by maximizing that log-likelihood itself from EM's last point, over the estimated
transition matrix and noise covariances, with L-BFGS-B (Byrd, Lu, Nocedal & Zhu 1995, SIAM J.
Sci. Comput. 16; EM followed by quasi-Newton: Lange 1995, Statistica Sinica 5, and Jamshidian &
Jennrich 1997, JRSS B 59). Its line search accepts only steps that raise the likelihood
(sufficient increase), so this phase of the trace never decreases, and it stops at a
stationary point, where :mod:`.standard_errors` takes the observed information. It stops when
an iteration gains less than ``tol``, which can leave a parameter on its way to a bound short
of it (a 3-mode fit at K = 8000: two transition probabilities at 0.002 and 0.001, the
information indefinite, every standard error NaN): the parameters whose gradient points at
the boundary of the parameter space (0) are then tried on it (:func:`_onto_bounds`), and from
a point that gains the search runs again (that fit: 1.96 log-units higher, both entries on the
bound, standard errors for the rest).

The parameters, bounded (L-BFGS-B's box), so that a maximum on the boundary of the parameter
space (a transition that never happens, a singular process noise) is a point the search can
reach, its bound then active, where in logarithms or logits it would lie at :math:`-\\infty`
(the search crawled towards it: a 3-mode fit at K = 8000 still moving after 300 iterations):

- row ``j`` of the transition matrix: its nonzero entries other than its largest one,
  :math:`\\pi_{jr}` (:func:`.markov_step.free_rows`), each divided by its value at the start
  (so that all start at 1 and their curvatures are alike) and at least 0, with
  :math:`\\pi_{jr} = 1 - \\sum_{i \\ne r} \\pi_{ji}` (a point where that is negative is outside
  the simplex: no value); a zero entry stays zero, as under EM's M-step;
- each fitted block of ``Q`` and ``R`` (per mode, or once for a matrix the fit ties across the
  modes; on the components of positive variance, :func:`.noise_step.support`): its Cholesky
  factor :math:`F` (:math:`F F^\\top` is positive semidefinite wherever it goes), row ``a``
  divided by the standard deviation :math:`d_a` of component ``a`` at the start, so every
  parameter starts at most 1 in size. A diagonal entry lies in :math:`[0, e^{\\mathrm{SPAN}}]`
  for ``Q`` (a singular process noise is a model) and in
  :math:`[e^{-\\mathrm{SPAN}}, e^{\\mathrm{SPAN}}]` for ``R`` (whose inverse the filter needs),
  an entry below it in :math:`[-e^{\\mathrm{SPAN}}, e^{\\mathrm{SPAN}}]` (:data:`SPAN` = 9: about
  four orders of magnitude).

Gradients are central differences with steps :math:`\\epsilon^{1/3} \\max(1, |\\theta_i|)`
(error :math:`O(h^2)`, against :math:`O(h)` for forward differences; one-sided where the other
side has no value), the :math:`2 p + 1` likelihoods of each point evaluated together
(:func:`.expectation.log_likelihoods`: the candidates fill the compiled filter's SIMD lanes).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy.optimize import minimize

from ..system import SwitchedLinearSystem
from .markov_step import free_rows
from .noise_step import groups, support

__all__ = ["SPAN", "ascend", "values_at"]

SPAN = 9.0
_STEP = np.finfo(float).eps ** (1 / 3)  # central differences: h^2 truncation vs eps / h rounding


class _Layout:
    """Where each free parameter lives: transition rows, then the noise blocks."""

    def __init__(self, system: SwitchedLinearSystem, transition: np.ndarray, names,
                 tied=frozenset()):
        self.system = system
        # (row j, reference column r, free columns)
        self.rows = free_rows(transition) if "transition" in names else []
        self.start = transition  # the other entries, and the free ones' scales
        self.blocks = []  # (matrix name, modes, support, the support's standard deviations)
        for name in ("Q", "R"):
            if name in names:
                stack = getattr(system, name)
                for g in groups(system.n_modes, name in tied):
                    idx = support(stack[g[0]])
                    if idx.size:
                        scale = np.sqrt(np.diag(stack[g[0]])[idx])
                        self.blocks.append((name, g, idx, scale))

    def pack(self, system: SwitchedLinearSystem, transition: np.ndarray) -> np.ndarray:
        """The parameter vector of ``system``, ``transition``."""
        parts = [transition[j, cols] / self.start[j, cols] for j, r, cols in self.rows]
        for name, modes, idx, scale in self.blocks:
            factor = np.linalg.cholesky(getattr(system, name)[modes[0]][np.ix_(idx, idx)])
            factor /= scale[:, None]
            parts += [np.diag(factor), factor[np.tril_indices(idx.size, -1)]]
        return np.concatenate(parts) if parts else np.zeros(0)

    def bounds(self) -> list[tuple[float, float]]:
        """L-BFGS-B's box, in the order of :meth:`pack` (module docstring)."""
        wide = float(np.exp(SPAN))
        out = [(0.0, 1.0 / self.start[j, i]) for j, _, cols in self.rows for i in cols]
        for name, _, idx, _ in self.blocks:
            out += [(0.0 if name == "Q" else 1.0 / wide, wide)] * idx.size
            out += [(-wide, wide)] * (idx.size * (idx.size - 1) // 2)
        return out

    def unpack(self, theta: np.ndarray) -> tuple[SwitchedLinearSystem, np.ndarray]:
        """The system and transition matrix of ``theta`` (other entries from the start).

        Raises
        ------
        ValueError
            Where a row of the transition matrix would have a negative entry (outside the
            simplex: the central differences step beyond the bounds).
        """
        pi = self.start.copy()
        at = 0
        for j, r, cols in self.rows:
            pi[j, cols] = theta[at:at + cols.size] * self.start[j, cols]
            at += cols.size
            pi[j, r] = 1.0 - pi[j, cols].sum()
            if pi[j, r] < 0.0 or np.any(pi[j, cols] < 0.0):
                raise ValueError(f"row {j} of the transition matrix leaves the simplex")
        mats = {"Q": self.system.Q.copy(), "R": self.system.R.copy()}
        for name, modes, idx, scale in self.blocks:
            k = idx.size
            factor = np.diag(theta[at:at + k])
            at += k
            below = k * (k - 1) // 2
            factor[np.tril_indices(k, -1)] = theta[at:at + below]
            at += below
            factor *= scale[:, None]
            for j in modes:
                mats[name][j][np.ix_(idx, idx)] = factor @ factor.T
        return self.system.replace(Q=mats["Q"], R=mats["R"]), pi


def ascend(system: SwitchedLinearSystem, transition: np.ndarray, names,
           logliks: Callable[[list], np.ndarray], *, tied=frozenset(), start_loglik: float,
           max_iter: int, tol: float, report: Callable[[float], object]
           ) -> tuple[SwitchedLinearSystem, np.ndarray, bool]:
    """Maximize the log-likelihood over the estimated ``names`` among ``"transition"``,
    ``"Q"``, ``"R"`` (module docstring) from the given point, at most ``max_iter`` iterations,
    stopping when an iteration raises it by at most ``tol`` of its value; ``Q`` or ``R`` in
    ``tied`` is one matrix for all modes. ``logliks`` maps a
    list of ``(system, transition)`` candidates to their log-likelihoods (NaN where one has
    none); ``start_loglik`` is the value at the start. ``report(loglik)`` is called after
    every iteration. Returns the maximizer and whether L-BFGS-B reported convergence."""
    layout = _Layout(system, transition, names, tied)
    start = layout.pack(system, transition)
    if start.size == 0:
        return system, transition, True
    # below the start: a value the line search must reject, kept finite for it
    floor = -start_loglik + 1e6 * max(1.0, abs(start_loglik))

    def objective(theta):
        """Minus the log-likelihood and its gradient by central differences."""
        h = _STEP * np.maximum(1.0, np.abs(theta))
        shifts = np.concatenate([np.zeros((1, theta.size)), np.diag(h), -np.diag(h)])
        values = -values_at(layout.unpack, theta + shifts, logliks)
        if not np.isfinite(values[0]):
            return floor, np.zeros(theta.size)
        up, down = values[1:theta.size + 1], values[theta.size + 1:]
        grad = (up - down) / (2 * h)
        lame = ~np.isfinite(grad)  # a one-sided difference where one side has no value
        grad[lame] = np.where(np.isfinite(up), (up - values[0]) / h, (values[0] - down) / h)[lame]
        grad[~np.isfinite(grad)] = 0.0
        return values[0], grad

    box = np.array(layout.bounds())

    def search(theta, iterations):
        return minimize(objective, theta, method="L-BFGS-B", jac=True, bounds=box,
                        callback=lambda intermediate_result: report(-intermediate_result.fun),
                        options={"maxiter": iterations, "ftol": tol})

    result = search(start, max_iter)
    theta, value, converged, used = result.x, result.fun, result.success, result.nit
    while used < max_iter:  # each round raises the likelihood: it ends
        moved = _onto_bounds(theta, value, result.jac, box[:, 0] == 0.0, layout.unpack, logliks)
        if moved is None:
            break
        (theta, value), converged, used = moved, False, used + 1
        report(-value)
        if used == max_iter:
            break
        result = search(theta, max_iter - used)
        theta, value, converged, used = result.x, result.fun, result.success, used + result.nit
    if -value < start_loglik:  # never below EM's point (cannot happen with a monotone search)
        return system, transition, False
    fitted, pi = layout.unpack(theta)
    return fitted, pi, bool(converged)


def _onto_bounds(theta: np.ndarray, value: float, grad: np.ndarray, edge: np.ndarray,
                 make: Callable, logliks: Callable[[list], np.ndarray]
                 ) -> tuple[np.ndarray, float] | None:
    """A point with parameters the search left above the boundary of the parameter space moved
    onto it, where that lowers ``value`` (minus the log-likelihood at ``theta``); ``None`` where
    no such move does.

    The boundary is where a parameter with ``edge`` (lower bound 0: a transition probability, a
    process-noise variance) is 0; the other bounds of the box only keep the search finite, and
    nothing is moved onto them. L-BFGS-B stops when an iteration gains less than ``tol``: a
    parameter on its way to the boundary (a transition that never happens, a singular process
    noise) may stop short of it, where the observed information is indefinite. Each such
    parameter whose gradient points at 0 is tried there alone, then those that gained
    together; the better of the best single move and the joint one is returned with its value.
    """
    toward = np.flatnonzero(edge & (grad > 0.0) & (theta > 0.0))
    if toward.size == 0:
        return None
    points = np.repeat(theta[None], toward.size, axis=0)
    points[np.arange(toward.size), toward] = 0.0
    values = -values_at(make, points, logliks)
    gained = values < value  # NaN (no value) gains nothing
    if not gained.any():
        return None
    best = int(np.argmin(np.where(gained, values, np.inf)))
    point, best_value = points[best], float(values[best])
    if gained.sum() > 1:
        joint = theta.copy()
        joint[toward[gained]] = 0.0
        joint_value = float(-values_at(make, [joint], logliks)[0])
        if joint_value < best_value:
            point, best_value = joint, joint_value
    return point, best_value


def values_at(make: Callable, points, logliks: Callable[[list], np.ndarray]) -> np.ndarray:
    """The log-likelihood of the candidate ``make(point)`` for each of ``points``, in one call
    of ``logliks``; NaN where ``make`` finds no candidate (a covariance that is not positive
    definite in floating point raises ``ValueError`` or ``LinAlgError``)."""
    values = np.full(len(points), np.nan)
    candidates, where = [], []
    for q, point in enumerate(points):
        try:
            candidates.append(make(point))
        except (ValueError, np.linalg.LinAlgError):
            continue
        where.append(q)
    if candidates:
        values[where] = logliks(candidates)
    return values
