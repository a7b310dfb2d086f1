"""Maximization steps for the noise covariances ``Q`` (process) and ``R`` (measurement).

Both maximize the expected complete-data log-likelihood of Shumway & Stoffer (1982, eqs
(13)-(14)) given the E-step's moments (:class:`~.expectation.Moments`), per mode, or pooled
over the modes where the fit ties the matrix across them (``shared``). A noise component with
zero variance in the starting model (a state without process noise, an output without sensor
noise) stays noise-free: only the block on the other components is fitted.

- ``R``: :math:`\\mathbb{E}[v v^\\top \\mid Y]` of :math:`v = y - C x` at each sample, weighted by
  :math:`P(r_k = j \\mid Y)`. A sample missing some components contributes exactly, by the
  Gaussian conditional of the missing noise given the observed one under the current ``R``
  (:math:`v_m \\mid v_o \\sim
  \\mathcal{N}(R_{mo} R_{oo}^{-1} v_o, R_{mm} - R_{mo} R_{oo}^{-1} R_{om})`, Shumway & Stoffer
  1982 §4, "missing observations"), a sample missing all of them contributes the current ``R``:
  a proper EM step, not a drop.
- ``Q``: the E-step's intervals move through the rows of a
  :class:`~switchest.estimators.step_tables.StepTable`, each row ``r`` with its own
  :math:`Q_{d,r}`; with :math:`n_r = \\sum w` the weight of the components through row ``r`` and
  :math:`S_r = \\sum w\\, \\mathbb{E}[w w^\\top \\mid Y]` of
  :math:`w = x_{k+1} - F_r x_k - G_r u_k`
  (:math:`\\mathbb{E}[w w^\\top] = e e^\\top + P_1 - F C^\\top - C F^\\top + F P_0 F^\\top`,
  ``e`` the mean residual, :math:`C = \\operatorname{Cov}(x_{k+1}, x_k)`), the step minimizes
  :math:`\\sum_r \\left(n_r \\log\\det Q_{d,r} + \\operatorname{tr}(Q_{d,r}^{-1} S_r)\\right)`.
  Discrete time: :math:`Q_{d,r} = Q_j` of the row's mode, so
  :math:`Q_j = \\sum_r S_r / \\sum_r n_r` over the rows of ``j`` (of the modes tied with it).
  Continuous time: ``Q`` is the intensity, and
  :math:`Q_{d,r} = \\Phi_b Q_{d,a}(\\tau) \\Phi_b^\\top + Q_{d,b}(h - \\tau)` (a row that switches
  from ``a`` to ``b`` at :math:`\\tau`, Shankar et al. eqs (3)-(5) with the exact noise;
  :math:`a = b` without a switch; Van Loan 1978, the exact discretization of
  :mod:`switchest.discretize`) is linear in :math:`Q_a` and :math:`Q_b` together: its map is
  computed once per row on a basis of symmetric matrices of each fitted block (once per fit:
  ``A`` and the rows do not change between its M-steps, and ``fit_Q``'s ``cache`` keeps the
  maps and the share of the modes not fitted), and the objective is minimized over all the
  fitted blocks at once, :math:`Q = L L^\\top` (Cholesky factors, BFGS with the analytic
  gradient :math:`d/dQ = \\sum Q_d^*(n Q_d^{-1} - Q_d^{-1} S Q_d^{-1})`, :math:`Q_d^*` the
  adjoint map), from the current ``Q``; the result is kept only if it does not increase the
  objective: a generalized EM step (Dempster, Laird & Rubin 1977, §3), which never decreases the
  likelihood. The rows that switch couple the modes' intensities, so they are fitted jointly.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import minimize

from ..estimators.step_tables import StepTable
from ..system import SwitchedLinearSystem
from .expectation import Moments

__all__ = ["fit_Q", "fit_R", "groups", "intensity_maps", "row_sums", "step_residual_moments",
           "support"]


def groups(L: int, tied: bool) -> list[list[int]]:
    """Modes fitted together: all ``L`` where the fit ties the matrix across them, else one
    each."""
    return [list(range(L))] if tied else [[j] for j in range(L)]


def support(matrix: np.ndarray) -> np.ndarray:
    """Indices of the components with positive variance (the block a fit may change)."""
    return np.flatnonzero(np.diag(matrix) > 0)


def _place(block: np.ndarray, idx: np.ndarray, n: int) -> np.ndarray:
    out = np.zeros((n, n))
    out[np.ix_(idx, idx)] = 0.5 * (block + block.T)
    return out


def fit_R(C: np.ndarray, R: np.ndarray, mom: Moments, *, tied: bool) -> np.ndarray:
    """The R step: new ``R (L, m, m)`` from the E-step's measurements ``mom.y`` (those its
    filter gated are missing); a mode (or tied group) of zero weight keeps its ``R``."""
    L, m = R.shape[0], R.shape[1]
    total, weight = np.zeros((L, m, m)), np.zeros(L)
    flat_y = mom.y.reshape(-1, m)
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
    for group in groups(L, tied):
        n_g = weight[group].sum()
        idx = support(R[group[0]])
        if n_g <= 0 or idx.size == 0:
            continue
        block = total[group].sum(axis=0)[np.ix_(idx, idx)] / n_g
        new[group] = _place(block, idx, m)
    return new


def step_residual_moments(F: np.ndarray, G: np.ndarray, u: np.ndarray,
                          mom: Moments) -> np.ndarray:
    """:math:`\\mathbb{E}[w w^\\top \\mid h, Y]` of every interval and component ``h``,
    ``(N, K-1, H, n, n)``, with :math:`w = x_{k+1} - F x_k - G u_k` and ``F, G`` of shape
    ``(K-1, H, n, .)`` or ``(N, K-1, H, n, .)`` (the table's rows of the components,
    ``table.F[mom.entry]``)."""
    e = (mom.x1 - np.einsum("...jab,...jb->...ja", F, mom.x0)
         - np.einsum("...jab,...b->...ja", G, u[:, :-1]))
    FC = np.einsum("...jab,...jcb->...jac", F, mom.cross)  # F C'
    return (e[..., :, None] * e[..., None, :] + mom.P1 - FC - np.swapaxes(FC, -1, -2)
            + np.einsum("...jab,...jbc,...jdc->...jad", F, mom.P0, F))


def row_sums(mom: Moments, u: np.ndarray, table: StepTable) -> tuple[np.ndarray, np.ndarray]:
    """The weight :math:`n_r` ``(M,)`` and the weighted
    :math:`S_r = \\sum w\\, \\mathbb{E}[w w^\\top]` ``(M, n, n)`` of every row of ``table`` (module
    docstring), the E-step's components mapped to their rows by ``mom.entry``."""
    F, G = table.F[mom.entry], table.G[mom.entry]
    E = step_residual_moments(F, G, u, mom)
    M, n = table.F.shape[0], E.shape[-1]
    rows = np.broadcast_to(mom.entry, mom.step_weight.shape).ravel()
    w = mom.step_weight.ravel()
    wE = (mom.step_weight[..., None, None] * E).reshape(-1, n * n)
    S = np.stack([np.bincount(rows, weights=wE[:, c], minlength=M) for c in range(n * n)],
                 axis=-1).reshape(M, n, n)
    return np.bincount(rows, weights=w, minlength=M), S


def fit_Q(system: SwitchedLinearSystem, u: np.ndarray, mom: Moments, table: StepTable, *,
          tied: bool, cache: dict | None = None) -> np.ndarray:
    """The Q step: new ``Q (L, n, n)`` (the intensity of a continuous system), module
    docstring. ``table`` holds the E-step's rows under ``system`` (those of the E-step, or
    rediscretized with dynamics an earlier conditional step updated); a mode (or tied group)
    that drives no interval keeps its ``Q``. ``cache``, a dict the caller keeps over the
    M-steps of one fit, holds the continuous-time maps of :func:`intensity_maps` and the noise
    of the modes not fitted, keyed by ``A`` and the table's rows (what they depend on)."""
    count, S = row_sums(mom, u, table)
    Q, n, L = system.Q, system.n_states, system.n_modes
    involved = np.zeros((len(count), L), dtype=bool)  # the modes of each row's segments
    involved[np.arange(len(count)), table.modes[:, 0]] = True
    involved[np.arange(len(count)), table.modes[:, 1]] = True
    fitted = []  # (modes, support) of every block that the data inform
    for group in groups(L, tied):
        idx = support(Q[group[0]])
        if idx.size and count[involved[:, group].any(axis=1)].sum() > 0:
            fitted.append((group, idx))
    new = Q.copy()
    if not fitted:
        return new
    if not system.is_continuous:
        for group, idx in fitted:
            rows = np.isin(table.modes[:, 0], group)
            block = S[rows].sum(axis=0)[np.ix_(idx, idx)] / count[rows].sum()
            new[group] = _place(block, idx, n)
        return new
    use = count > 0
    return _intensity(system, table, use, fitted, count[use], S[use],
                      {} if cache is None else cache)


def _basis(k: int) -> list[tuple[int, int]]:
    return [(a, b) for a in range(k) for b in range(a, k)]


def intensity_maps(system: SwitchedLinearSystem, table: StepTable, modes, idx) -> np.ndarray:
    """:math:`Q_{d,r}` of every row of ``table`` when the intensity of ``modes`` is :math:`E_p`,
    for the symmetric basis :math:`E_p` of the block ``idx`` (:math:`E_{aa}`, and
    :math:`E_{ab} + E_{ba}` for :math:`a < b`), and zero in the other modes: ``(P, M, n, n)``, by
    the exact discretization of each row's segments (:meth:`StepTable.under`, Van Loan's)."""
    n, L = system.n_states, system.n_modes
    on = np.isin(np.arange(L), modes)[:, None, None]

    def qd(vec):
        return table.under(system.replace(Q=np.where(on, np.outer(vec, vec), 0.0))).Qd

    diag = {a: qd(np.eye(n)[idx[a]]) for a in range(idx.size)}
    maps = []
    for a, b in _basis(idx.size):
        if a == b:
            maps.append(diag[a])
        else:  # (e_a + e_b)(e_a + e_b)' - e_a e_a' - e_b e_b' = E_ab + E_ba
            maps.append(qd(np.eye(n)[idx[a]] + np.eye(n)[idx[b]]) - diag[a] - diag[b])
    return np.stack(maps)


def _intensity(system, table: StepTable, use, fitted, count, S, cache: dict) -> np.ndarray:
    """Minimize
    :math:`\\sum \\left(n \\log\\det Q_d(Q) + \\operatorname{tr}(Q_d(Q)^{-1} S)\\right)` over the
    fitted blocks :math:`Q = L L^\\top` together, on the rows ``use`` of ``table``, from the
    current ``Q`` (module docstring); the current ``Q`` if no better point is found. The maps of
    every row are taken from ``cache`` (computed there at the first M-step of a fit)."""
    n = system.n_states
    held = system.Q.copy()  # the modes not fitted keep theirs: their fixed share of each Qd
    for group, _ in fitted:
        held[group] = 0.0
    rows = (system.A.tobytes(), table.length.tobytes(), table.modes.tobytes(),
            table.offset.tobytes())  # what the maps depend on (Qd is linear in Q)

    def cached(key, compute):
        if key not in cache:
            cache[key] = compute()
        return cache[key]

    fixed = cached((rows, "held", held.tobytes()),
                   lambda: table.under(system.replace(Q=held)).Qd)[use]
    maps = [cached((rows, tuple(group), tuple(idx)),
                   lambda group=group, idx=idx: intensity_maps(system, table, group, idx))[:, use]
            for group, idx in fitted]
    pairs = [_basis(idx.size) for _, idx in fitted]
    lows = [np.tril_indices(idx.size) for _, idx in fitted]
    sizes = np.cumsum([0] + [low[0].size for low in lows])

    def blocks(theta):
        out = []
        for (_, idx), low, a in zip(fitted, lows, sizes):
            Lf = np.zeros((idx.size, idx.size))
            Lf[low] = theta[a:a + low[0].size]
            out.append(Lf)
        return out

    def objective(theta):
        factors = blocks(theta)
        Qd = fixed.copy()
        for Lf, mp, pr in zip(factors, maps, pairs):
            Qb = Lf @ Lf.T
            Qd += np.einsum("p,psab->sab", np.array([Qb[a, b] for a, b in pr]), mp)
        try:
            chol = np.linalg.cholesky(Qd)
        except np.linalg.LinAlgError:
            return np.inf, np.zeros_like(theta)
        inv = np.linalg.inv(Qd)
        logdet = 2 * np.log(np.diagonal(chol, axis1=-2, axis2=-1)).sum(axis=-1)
        f = float(np.sum(count * logdet) + np.einsum("sab,sba->", inv, S))
        M = count[:, None, None] * inv - inv @ S @ inv  # d f / d Qd
        grad = []
        for Lf, mp, pr, low in zip(factors, maps, pairs, lows):
            g = np.einsum("sab,psba->p", M, mp)  # d f / d q_p
            k = Lf.shape[0]
            Gs = np.zeros((k, k))
            for (a, b), gp in zip(pr, g):
                Gs[a, b] += gp if a == b else 0.5 * gp
                Gs[b, a] += 0.0 if a == b else 0.5 * gp
            grad.append((2 * Gs @ Lf)[low])
        return f, np.concatenate(grad)

    starts = [system.Q[group[0]][np.ix_(idx, idx)] for group, idx in fitted]
    theta0 = np.concatenate([
        np.linalg.cholesky(q + 1e-12 * np.trace(q) / q.shape[0] * np.eye(q.shape[0]))[low]
        for q, low in zip(starts, lows)])
    f0, _ = objective(theta0)
    # a trial point of the line search may send Qd towards singular and the gradient beyond
    # the floating-point range: BFGS then stops, and its result is kept only if it improves
    with np.errstate(over="ignore", invalid="ignore"):
        res = minimize(objective, theta0, jac=True, method="BFGS",
                       options={"gtol": 1e-10 * max(1.0, abs(f0)), "maxiter": 500})
    new = system.Q.copy()
    if not np.isfinite(res.fun) or res.fun > f0:
        return new
    for (group, idx), Lf in zip(fitted, blocks(res.x)):
        new[group] = _place(Lf @ Lf.T, idx, n)
    return new
