"""Standard errors of the fitted parameters from the observed information.

The observed information is the negative Hessian of the log-likelihood at the optimum with
respect to the free parameters, taken by central finite differences of the filter's summed
log-likelihood (Efron & Hinkley 1978, Biometrika 65, "Assessing the accuracy of the maximum
likelihood estimator: observed versus expected Fisher information"); the covariance of the
estimate is its inverse. The free parameters:

- of ``Q`` and ``R``, the upper triangle of each fitted block (its support), each step ``1e-3``
  of the entry's scale :math:`\\sqrt{V_{aa} V_{bb}}`;
- of ``A``, ``B`` and ``C``, every entry (per mode, or once for a matrix the fit ties across
  the modes), each step ``1e-3`` of the entry, or of ``1e-3`` of the matrix's largest entry
  for a smaller one;
- of the transition matrix (with unknown modes: ``"transition"`` in ``names``), the entries
  :math:`\\pi_{ji}` of each row but its largest that were nonzero at the fit's start,
  :math:`\\pi_{jr} = 1 - \\sum_{i \\ne r} \\pi_{ji}`, which depends on them
  (:func:`.markov_step.free_rows`; a zero entry of the start stays zero under EM's M-step and
  the ascent, so it is not free, while one the fit moved to zero lies on the boundary); each
  step ``1e-3`` of :math:`\\min(\\pi_{ji}, \\pi_{jr})`, so that the perturbed rows stay
  probabilities. The dependent entry's standard error follows by the delta method,
  :math:`\\operatorname{Var} \\pi_{jr} = \\mathbf{1}^\\top \\Sigma_j \\mathbf{1}` over the row's
  free entries off the boundary (the covariance of the whole row does not depend on which entry
  is the dependent one).

Truncation errors are :math:`O(10^{-6})` relative, far above the rounding of the summed likelihood.

A fit on the boundary of the parameter space (a transition probability near zero, a singular
``Q`` or ``R`` block: a maximum where the likelihood need not be flat) has no information
there in the regular sense: those entries get NaN and are held fixed, and the others' standard
errors come from the information of the rest (conditional on them; Self & Liang 1987, JASA 82,
on the boundary's non-standard asymptotics). Likewise where the information is not positive
definite (a parameter the data barely inform, whose curvature is lost in the rounding of the
summed likelihood, or a fit not at a maximum along it): the entries of least information
relative to their scale are held fixed, one at a time, until that of the rest is, and named.

The parameters are taken jointly: with unknown modes the transition's estimates are correlated
with the others' (the modes are told apart through them), and the marginal standard errors
come from the inverse of the joint information. With known modes the transition's
information separates from the others' and equals the counts' (:mod:`.markov_step`), which
:func:`switchest.learn.fit` uses there. With known modes the likelihood is exact (the Kalman
filter along the modes); with unknown modes it is that of the E-step
(:mod:`~switchest.learn.expectation`), and the standard errors are those of that likelihood.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable

import numpy as np
from scipy.linalg import cho_factor, cho_solve

from ..system import SwitchedLinearSystem
from .ascent import values_at
from .markov_step import free_rows
from .noise_step import groups, support

__all__ = ["observed_standard_errors"]

_REL_STEP = 1e-3
_BOUNDARY = 1e-4


def _free(system: SwitchedLinearSystem, names, tied) -> list[tuple[str, list[int], int, int]]:
    """The free entries: ``(matrix name, modes sharing it, a, b)``, per mode or once for a
    matrix tied across the modes (``tied``): for ``Q``, ``R`` those with :math:`a \\le b` in the
    matrix's support, for ``A``, ``B``, ``C`` every entry."""
    out = []
    for name in names:
        stack = getattr(system, name)
        for group in groups(system.n_modes, name in tied):
            if name in ("A", "B", "C"):
                out += [(name, group, a, b) for a, b in np.ndindex(stack.shape[1:])]
                continue
            idx = support(stack[group[0]])
            out += [(name, group, int(idx[a]), int(idx[b])) for a in range(idx.size)
                    for b in range(a, idx.size)]
    return out


def _free_transition(transition: np.ndarray, allowed
                     ) -> list[tuple[str, list[int], int, int]]:
    """The free entries of the transition matrix: ``("transition", [r], j, i)`` for each
    free :math:`\\pi_{ji}` of :func:`.markov_step.free_rows` (on the support ``allowed``), with
    ``r`` the column of the row's largest entry, which depends on them."""
    return [("transition", [r], j, int(i)) for j, r, cols in free_rows(transition, allowed)
            for i in cols]


def _step(system: SwitchedLinearSystem, transition: np.ndarray, entry) -> float:
    """Finite-difference step of a free entry (module docstring)."""
    name, group, a, b = entry
    if name == "transition":  # group[0]: the row's dependent (largest) entry
        return _REL_STEP * min(transition[a, b], transition[a, group[0]])
    stack = getattr(system, name)
    if name in ("A", "B", "C"):  # relative to the entry, or to the matrix for a small one
        return _REL_STEP * max(abs(stack[group[0], a, b]), 1e-3 * np.abs(stack[group[0]]).max(),
                               1e-12)
    # sqrt(Q_aa) sqrt(Q_bb): the product of the variances overflows beyond 1.3e154 each
    return _REL_STEP * float(np.sqrt(stack[group[0], a, a]) * np.sqrt(stack[group[0], b, b]))


def _with(system: SwitchedLinearSystem, transition: np.ndarray, free, theta
          ) -> tuple[SwitchedLinearSystem, np.ndarray]:
    mats = {name: getattr(system, name).copy() for name in ("A", "B", "C", "Q", "R")}
    mats["transition"] = transition.copy()
    for (name, group, a, b), value in zip(free, theta):
        if name == "transition":
            mats[name][a, group[0]] += mats[name][a, b] - value  # the row still sums to one
            mats[name][a, b] = value
            continue
        mats[name][group, a, b] = value
        if name in ("Q", "R"):
            mats[name][group, b, a] = value
    pi = mats.pop("transition")
    return system.replace(**mats), pi


def observed_standard_errors(system: SwitchedLinearSystem, transition: np.ndarray, names,
                             logliks: Callable[[list], np.ndarray], *, tied=frozenset(),
                             allowed: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """Standard errors of the fitted ``transition``, ``A``, ``B``, ``C``, ``Q`` and ``R`` (those
    in ``names``) at ``system``, ``transition``, from the observed information of the
    log-likelihood; ``logliks`` maps a list of ``(system, transition)`` candidates to their
    log-likelihoods (NaN where one has none), and is called once, with every point of the
    finite-difference Hessian. A matrix in ``tied`` is one for all modes (one set of free
    entries). ``allowed`` (nonzero where the fit's start transition matrix
    is) says which transition entries may be nonzero (default: those of ``transition``).
    Shaped like the matrices, NaN outside the fitted blocks (and at a zero entry of
    ``allowed``), at the entries on the boundary and those held fixed where the information is
    not positive definite (module docstring), or everywhere when no entry's is (each case with
    a ``RuntimeWarning`` that says so)."""
    free = _free(system, [name for name in names if name != "transition"], tied)
    if "transition" in names:
        free = _free_transition(transition, allowed) + free
    out = {name: np.full((transition if name == "transition" else getattr(system, name)).shape,
                         np.nan) for name in names}
    if not free:
        return out
    edge = _on_boundary(system, transition, free)
    inner = np.flatnonzero(~edge)  # the Hessian of these only: the others are held fixed
    theta = np.array([transition[a, b] if name == "transition" else
                      getattr(system, name)[g[0], a, b] for name, g, a, b in free])
    h = np.array([_step(system, transition, entry) for entry in free])
    p = theta.size

    e = np.eye(p) * h
    # the points of the central differences: 0, then +-e_i, then +-e_i +-e_j (j before i)
    steps = [np.zeros(p)] + [sign * e[i] for i in inner for sign in (1, -1)]
    pairs = [(u, v) for u in range(inner.size) for v in range(u)]
    steps += [si * e[inner[u]] + sj * e[inner[v]] for u, v in pairs
              for si, sj in ((1, 1), (1, -1), (-1, 1), (-1, -1))]
    f = values_at(lambda step: _with(system, transition, free, theta + step), steps,
                  logliks)
    f0, axis, cross = f[0], f[1:1 + 2 * inner.size].reshape(-1, 2), f[1 + 2 * inner.size:]
    info = np.empty((inner.size, inner.size))  # minus the Hessian
    for u, i in enumerate(inner):
        info[u, u] = -(axis[u, 0] - 2 * f0 + axis[u, 1]) / h[i] ** 2
    for (u, v), four in zip(pairs, cross.reshape(-1, 4)):
        info[u, v] = info[v, u] = -(four[0] - four[1] - four[2] + four[3]) / (
            4 * h[inner[u]] * h[inner[v]])
    if np.any(edge):
        where = ", ".join(_label(free[q]) for q in np.flatnonzero(edge))
        warnings.warn(f"the fit lies on the boundary of the parameter space at {where}: these "
                      "have no standard error, and the others' are conditional on them",
                      RuntimeWarning, stacklevel=3)
    kept, factor = _definite(info, h[inner] / _REL_STEP)
    if factor is None:
        warnings.warn(f"the observed information of {', '.join(names)} is not positive definite "
                      "at the fit (a parameter is not identifiable, or the fit is not at a "
                      "maximum): their standard errors are NaN", RuntimeWarning, stacklevel=3)
        return out
    if kept.size < inner.size:
        held = inner[np.setdiff1d(np.arange(inner.size), kept)]
        warnings.warn(f"the observed information is not positive definite at the fit along "
                      f"{', '.join(_label(free[q]) for q in held)} (not identifiable from the "
                      "data, or the fit is not at a maximum along them): these have no standard "
                      "error, and the others' are conditional on them", RuntimeWarning,
                      stacklevel=3)
        edge = edge.copy()
        edge[held] = True  # held fixed, as those on the boundary
        inner = inner[kept]
    cov = np.full((p, p), np.nan)
    cov[np.ix_(inner, inner)] = cho_solve(factor, np.eye(inner.size))
    for (name, group, a, b), s in zip(free, np.sqrt(np.diag(cov))):
        if name == "transition":
            out[name][a, b] = s
            continue
        out[name][group, a, b] = s
        if name in ("Q", "R"):
            out[name][group, b, a] = s
    if "transition" in names:  # each row's dependent entry, by the delta method
        for j in range(transition.shape[0]):
            row = [q for q, (name, _, a, _) in enumerate(free) if name == "transition" and a == j]
            r = free[row[0]][1][0] if row else int(np.argmax(transition[j]))
            row = [q for q in row if not edge[q]]  # those on the boundary are held fixed
            out["transition"][j, r] = np.sqrt(cov[np.ix_(row, row)].sum()) if row else 0.0
    return out


def _definite(info: np.ndarray, scale: np.ndarray) -> tuple[np.ndarray, tuple | None]:
    """The parameters whose observed information ``info`` is positive definite, and its
    Cholesky factor (None if there are none): all of them if it is; otherwise, one at a time,
    the one of least information relative to its ``scale``
    (:math:`\\mathrm{info}_{ii}\\, \\mathrm{scale}_i^2`, the curvature in relative units; a
    non-finite one first) is left out until the rest is."""
    kept = np.arange(info.shape[0])
    while kept.size:
        sub = info[np.ix_(kept, kept)]
        if np.all(np.isfinite(sub)):
            try:
                return kept, cho_factor(sub)
            except np.linalg.LinAlgError:
                pass
        finite = np.all(np.isfinite(sub), axis=1)
        relative = np.where(finite, np.diag(sub) * scale[kept] ** 2, -np.inf)
        kept = np.delete(kept, int(np.argmin(relative)))
    return kept, None


def _on_boundary(system: SwitchedLinearSystem, transition: np.ndarray, free) -> np.ndarray:
    """Which free entries sit on the boundary of the parameter space, where the likelihood
    need not be flat: a transition probability (or its row's diagonal) below
    :data:`_BOUNDARY`, an entry of a ``Q`` or ``R`` block whose smallest eigenvalue is below
    :data:`_BOUNDARY` times the largest variance of that matrix in any mode (a singular
    covariance)."""
    singular = {}  # (name, mode) of each Q, R block: whether it is singular
    for name in ("Q", "R"):
        stack = getattr(system, name)
        largest = np.diagonal(stack, axis1=1, axis2=2).max()
        for j, V in enumerate(stack):
            idx = support(V)
            singular[name, j] = bool(idx.size) and (
                np.linalg.eigvalsh(V[np.ix_(idx, idx)])[0] < _BOUNDARY * largest)
    edge = np.zeros(len(free), dtype=bool)
    for q, (name, group, a, b) in enumerate(free):
        if name == "transition":  # the row's dependent entry is its largest: >= 1/L
            edge[q] = transition[a, b] < _BOUNDARY
        elif name in ("Q", "R"):
            edge[q] = singular[name, group[0]]
    return edge


def _label(entry) -> str:
    name, group, a, b = entry
    if name == "transition":
        return f"transition {a}->{b}"
    where = "all modes" if len(group) > 1 else f"mode {group[0]}"
    return f"{name} {where} [{a},{b}]"
