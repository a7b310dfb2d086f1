"""Maximization steps for the noise covariances ``Q`` (process) and ``R`` (measurement).

Both maximize the expected complete-data log-likelihood of Shumway & Stoffer (1982, eqs
(13)-(14)) given the E-step's moments (:class:`~.expectation.Moments`), per mode, or pooled
over the modes where the model shares the matrix (all modes equal). A noise component with
zero variance in the starting model (a state without process noise, an output without sensor
noise) stays noise-free: only the block on the other components is fitted.

- ``R``: ``E[v v' | Y]`` of ``v = y - C x`` at each sample, weighted by ``P(r_k = j | Y)``.
  A sample missing some components contributes exactly, by the Gaussian conditional of the
  missing noise given the observed one under the current ``R`` (``v_m | v_o ~ N(R_mo R_oo^-1
  v_o, R_mm - R_mo R_oo^-1 R_om)``, Shumway & Stoffer 1982 §4, "missing observations"), a sample
  missing all of them contributes the current ``R``: a proper EM step, not a drop.
- ``Q`` of a discrete-time system: ``Q_j = sum_k w_kj E[w w' | Y] / sum_k w_kj`` with
  ``w = x_{k+1} - F x_k - G u_k``, ``E[w w'] = e e' + P1 - F C' - C F' + F P0 F'`` (``e`` the
  mean residual, ``C = Cov(x_{k+1}, x_k)``).
- ``Q`` of a continuous-time system is the intensity: ``Qd(h) = int_0^h e^{As} Q e^{A's} ds``
  (Van Loan 1978, the exact discretization of :mod:`switchest.discretize`) is linear in ``Q``,
  so its map is computed once per (mode, distinct step) on a basis of symmetric matrices, and
  ``sum_(j,h) n_jh log det Qd_jh(Q) + tr(Qd_jh(Q)^-1 S_jh)`` is minimized over ``Q = L L'``
  (Cholesky factor, BFGS with the analytic gradient ``d/dQ = sum Qd*(n Qd^-1 - Qd^-1 S Qd^-1)``,
  ``Qd*`` the adjoint map) from the current ``Q``; the result is kept only if it does not
  increase the objective: a generalized EM step (Dempster, Laird & Rubin 1977, §3), which never
  decreases the likelihood.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import minimize

from ..discretize import interval
from ..system import SwitchedLinearSystem
from .expectation import Moments

__all__ = ["fit_R", "fit_Q", "groups", "step_residual_moments", "shared", "support"]


def shared(stack: np.ndarray) -> bool:
    """Whether a per-mode stack holds one matrix for all modes (the model shares it)."""
    return stack.shape[0] > 1 and bool(np.all(stack == stack[:1]))


def support(matrix: np.ndarray) -> np.ndarray:
    """Indices of the components with positive variance (the block a fit may change)."""
    return np.flatnonzero(np.diag(matrix) > 0)


def groups(*stacks: np.ndarray) -> list[list[int]]:
    """Modes fitted together: all of them when the model shares every one of the matrices,
    else one each."""
    L = stacks[0].shape[0]
    return [list(range(L))] if all(shared(s) for s in stacks) else [[j] for j in range(L)]


def _place(block: np.ndarray, idx: np.ndarray, n: int) -> np.ndarray:
    out = np.zeros((n, n))
    out[np.ix_(idx, idx)] = 0.5 * (block + block.T)
    return out


def fit_R(C: np.ndarray, R: np.ndarray, y: np.ndarray, mom: Moments) -> tuple[np.ndarray,
                                                                               np.ndarray]:
    """The R step: new ``R (L, m, m)`` and each mode's weight (expected samples) ``(L,)``.

    A mode of zero weight keeps its ``R``.
    """
    L, m = R.shape[0], R.shape[1]
    total, weight = np.zeros((L, m, m)), np.zeros(L)
    flat_y = y.reshape(-1, m)
    w_all = mom.weight.reshape(-1, L)
    x_all = mom.x.reshape(-1, L, mom.x.shape[-1])
    P_all = mom.P.reshape(-1, L, *mom.P.shape[-2:])
    patterns, which = np.unique(np.isnan(flat_y), axis=0, return_inverse=True)
    for p, missing in enumerate(patterns):
        rows = np.flatnonzero(which.ravel() == p)
        o, mi = np.flatnonzero(~missing), np.flatnonzero(missing)
        w = w_all[rows]  # (S, L)
        E = np.empty((rows.size, L, m, m))
        if o.size:
            Co = C[:, o]  # (L, mo, n)
            e = flat_y[rows][:, None, o] - np.einsum("jon,sjn->sjo", Co, x_all[rows])
            Eoo = (e[..., :, None] * e[..., None, :]
                   + np.einsum("jon,sjnp,jqp->sjoq", Co, P_all[rows], Co))
            T = np.linalg.solve(R[:, o][:, :, o], R[:, o][:, :, mi]).transpose(0, 2, 1)
            Emo = np.einsum("jmo,sjoq->sjmq", T, Eoo)
            E[..., o[:, None], o] = Eoo
            E[..., mi[:, None], o] = Emo
            E[..., o[:, None], mi] = np.swapaxes(Emo, -1, -2)
            E[..., mi[:, None], mi] = (np.einsum("sjmo,jqo->sjmq", Emo, T)
                                       + R[:, mi][:, :, mi] - np.einsum(
                                           "jmo,joq->jmq", T, R[:, o][:, :, mi]))
        else:
            E[:] = R
        total += np.einsum("sj,sjab->jab", w, E)
        weight += w.sum(axis=0)
    new = R.copy()
    for group in groups(R):
        n_g = weight[group].sum()
        idx = support(R[group[0]])
        if n_g <= 0 or idx.size == 0:
            continue
        block = total[group].sum(axis=0)[np.ix_(idx, idx)] / n_g
        new[group] = _place(block, idx, m)
    return new, weight


def step_residual_moments(F: np.ndarray, G: np.ndarray, u: np.ndarray,
                          mom: Moments) -> np.ndarray:
    """``E[w w' | j, Y]`` of every interval and driving mode, ``(N, K-1, L, n, n)``, with
    ``w = x_{k+1} - F x_k - G u_k`` and ``F, G`` of shape ``(K-1, L, n, .)``."""
    e = (mom.x1 - np.einsum("kjab,nkjb->nkja", F, mom.x0)
         - np.einsum("kjab,nkb->nkja", G, u[:, :-1]))
    FC = np.einsum("kjab,nkjcb->nkjac", F, mom.cross)  # F C'
    return (e[..., :, None] * e[..., None, :] + mom.P1 - FC - np.swapaxes(FC, -1, -2)
            + np.einsum("kjab,nkjbc,kjdc->nkjad", F, mom.P0, F))


def _step_sums(system, mom: Moments, u, table):
    """Weight ``(D, L)`` and weighted ``E[w w']`` sums ``(D, L, n, n)`` per distinct step."""
    L = system.n_modes
    F, G = table.F[mom.entry], table.G[mom.entry]
    E = step_residual_moments(F, G, u, mom)
    which = mom.entry[:, 0] // L  # the distinct step of each interval
    D = mom.table.F.shape[0] // L
    S = np.zeros((D, L, *E.shape[-2:]))
    np.add.at(S, which, np.einsum("nkj,nkjab->kjab", mom.step_weight, E))
    count = np.zeros((D, L))
    np.add.at(count, which, mom.step_weight.sum(axis=0))
    return count, S


def fit_Q(system: SwitchedLinearSystem, steps: np.ndarray, u, mom: Moments, table
          ) -> tuple[np.ndarray, np.ndarray]:
    """The Q step: new ``Q (L, n, n)`` (intensity for a continuous system) and each mode's
    weight (expected intervals it drives) ``(L,)``; a mode of zero weight keeps its ``Q``.

    ``steps (D,)`` are the distinct sampling steps, in the order of the E-step's table;
    ``table`` the exact transitions of ``system`` in that layout (those of the E-step, or of
    dynamics updated by an earlier conditional step).
    """
    count, S = _step_sums(system, mom, u, table)
    Q, n = system.Q, system.n_states
    new = Q.copy()
    for group in groups(Q):
        idx = support(Q[group[0]])
        if count[:, group].sum() <= 0 or idx.size == 0:
            continue
        if not system.is_continuous:
            block = S[:, group].sum(axis=(0, 1))[np.ix_(idx, idx)] / count[:, group].sum()
        else:
            block = _intensity(system, steps, group, idx, count[:, group], S[:, group])
        new[group] = _place(block, idx, n)
    return new, count.sum(axis=0)


def _basis(k: int) -> list[tuple[int, int]]:
    return [(a, b) for a in range(k) for b in range(a, k)]


def intensity_maps(system: SwitchedLinearSystem, steps, modes, idx) -> np.ndarray:
    """``Qd_{h, j}(E_p)`` for the symmetric basis ``E_p`` of the block ``idx`` (``E_aa``, and
    ``E_ab + E_ba`` for ``a < b``): ``(P, D, len(modes), n, n)``, by Van Loan's exact
    discretization (:func:`switchest.discretize.interval`) of unit intensities."""
    n = system.n_states
    steps = np.asarray(steps, dtype=float)

    def qd(vec):
        q = np.outer(vec, vec)
        sysb = system.replace(Q=q)
        return interval(sysb, steps[:, None], np.asarray(modes)[None, :, None]).Qd

    diag = {a: qd(np.eye(n)[idx[a]]) for a in range(idx.size)}
    maps = []
    for a, b in _basis(idx.size):
        if a == b:
            maps.append(diag[a])
        else:
            maps.append(qd(np.eye(n)[idx[a]] + np.eye(n)[idx[b]]) - diag[a] - diag[b])
    return np.stack(maps)


def _intensity(system, steps, group, idx, count, S) -> np.ndarray:
    """Minimize ``sum n log det Qd(Q) + tr(Qd(Q)^-1 S)`` over ``Q = L L'`` on the block ``idx``,
    from the current ``Q``; the current block if no better point is found."""
    pairs = _basis(idx.size)
    maps = intensity_maps(system, steps, group, idx)  # (P, D, G, n, n)
    use = count > 0
    maps, count, S = maps[:, use], count[use], S[use]
    k = idx.size
    low = np.tril_indices(k)

    def unpack(theta):
        Lf = np.zeros((k, k))
        Lf[low] = theta
        return Lf

    def objective(theta):
        Lf = unpack(theta)
        Qb = Lf @ Lf.T
        q = np.array([Qb[a, b] for a, b in pairs])
        Qd = np.einsum("p,psab->sab", q, maps)
        try:
            chol = np.linalg.cholesky(Qd)
        except np.linalg.LinAlgError:
            return np.inf, np.zeros_like(theta)
        inv = np.linalg.inv(Qd)
        logdet = 2 * np.log(np.diagonal(chol, axis1=-2, axis2=-1)).sum(axis=-1)
        f = float(np.sum(count * logdet) + np.einsum("sab,sba->", inv, S))
        M = count[:, None, None] * inv - inv @ S @ inv  # d f / d Qd
        g = np.einsum("sab,psba->p", M, maps)  # d f / d q_p
        Gs = np.zeros((k, k))
        for (a, b), gp in zip(pairs, g):
            Gs[a, b] += gp if a == b else 0.5 * gp
            Gs[b, a] += 0.0 if a == b else 0.5 * gp
        return f, (2 * Gs @ Lf)[low]

    start = system.Q[group[0]][np.ix_(idx, idx)]
    theta0 = np.linalg.cholesky(start + 1e-12 * np.trace(start) / k * np.eye(k))[low]
    f0, _ = objective(theta0)
    res = minimize(objective, theta0, jac=True, method="BFGS",
                   options={"gtol": 1e-10 * max(1.0, abs(f0)), "maxiter": 500})
    if not np.isfinite(res.fun) or res.fun > f0:
        return start
    Lf = unpack(res.x)
    return Lf @ Lf.T
