"""The Kalman and IMM equations over a block of trials laid across SIMD lanes (numba).

Every array here carries a block of trials as its *last* axis, the lanes: ``x (n, B)``,
``P (n, n, B)``, ``y (m, B)``, of which the first ``nb`` are in use. Each equation loops over
matrix entries outside and over the lanes inside, so the compiler runs the innermost loops on
SIMD registers across trials; the matrices of a switched system are a few states across, too
short a loop to vectorize along.

The functions work in place and allocate nothing; each is compiled once and called by the
kernels (:mod:`.bank`), a block of trials per call, so a call costs little; those that call
others are compiled by :func:`switchest._jit.borrow`, without the reference counts numba would
otherwise take of every array on each call. (Inlining them into the kernel, numba's
``inline="always"``, ran 10 % faster at 10 trials but took 36 instead of 20 CPU-s to compile
once.) Only the smallest helpers, called per lane or within an equation (:func:`write_lane`,
:func:`symmetric_sum`), are inlined. Divisions follow
numpy's error model (no zero-division checks; every divisor is checked positive first).

A missing component of ``y`` (NaN) is removed exactly by decoupling it: its row of ``C`` and
its noise are replaced by a unit innovation that is never observed (``e_a = 0``, ``S_aa = 1``,
no correlation), so each lane updates with its observed components only and its likelihood is
their marginal. The measurement update is split in two so that a filter decides on gating
before it changes anything: :func:`innovation`, then :func:`correct` for the lanes that use
the measurement. Where trials share their covariance (:mod:`.kalman_kernel`), those two run once
for the shared covariance and :func:`innovation_mean`, :func:`correct_mean` (their per-lane
halves, the same operations) finish each trial's mean.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..._jit import borrow, jit

__all__ = [
    "jit",
    "borrow",
    "inline",
    "OK",
    "NOT_POSITIVE_DEFINITE",
    "NOT_FINITE",
    "ACCEPTED",
    "GATED",
    "PARTLY_GATED",
    "gather_samples",
    "gather_rows",
    "scatter_rows",
    "gather_modes",
    "scatter_modes",
    "write_lane",
    "gather_matrices",
    "observe",
    "predict_mean",
    "predict",
    "copy_gaussian",
    "copy_lanes",
    "symmetric_sum",
    "residual",
    "innovation",
    "innovation_mean",
    "factor",
    "solve_rows",
    "correct",
    "correct_mean",
    "joseph_lost",
    "information_form",
    "information_or_repair",
    "repair",
    "log_normalize",
    "predicted_mode_probabilities",
    "mix",
    "collapse",
    "merge",
    "combine",
    "write_modes",
]

# status codes a kernel returns (the Python side raises; nothing raises inside compiled code)
OK = 0
NOT_POSITIVE_DEFINITE = 1  # an innovation covariance failed its Cholesky factorization
NOT_FINITE = 2  # an innovation covariance holds an infinity or NaN (the covariance overflowed)

# per-sample flags a kernel writes
ACCEPTED = 0  # updated (or nothing observed)
GATED = 1  # the measurement was an outlier or failed the gate: treated as missing
PARTLY_GATED = 2  # IMM only: some modes gated the measurement, others used it

_LOG_2PI = math.log(2.0 * math.pi)
_EPS = 2.220446049250313e-16  # numpy.finfo(float).eps
_CORRELATION_BOUND = 1.0 + math.sqrt(_EPS)
_TINY_SUM = 1e-250  # below it, a sum of probability products is redone in the log domain

# For the smallest helpers (a lane's outputs, one loop of an equation), inlined into their callers
# by numba: a call passing a dozen arrays costs about 100 ns, as much as their arithmetic on a few
# lanes.
inline = njit(cache=True, error_model="numpy", inline="always")



@jit
def gather_samples(data, i0, nb, k, out):
    """``out[a, b] = data[i0 + b, k, a]``: sample ``k`` of trials ``i0 .. i0 + nb - 1``."""
    for a in range(out.shape[0]):
        for b in range(nb):
            out[a, b] = data[i0 + b, k, a]


@jit
def gather_rows(data, i0, nb, out):
    """``out[:, b] = data[i0 + b]`` for the ``nb`` lanes of a block (a trial's initial state)."""
    for r in range(data.shape[1]):
        for b in range(nb):
            out[r, b] = data[i0 + b, r]


@jit
def scatter_rows(src, i0, nb, data):
    """``data[i0 + b] = src[:, b]`` for the ``nb`` lanes of a block: :func:`gather_rows` back."""
    for r in range(data.shape[1]):
        for b in range(nb):
            data[i0 + b, r] = src[r, b]


@jit
def gather_modes(x_init, P_init, i0, nb, x, P):
    """``x[j, :, b] = x_init[i0 + b, j]``, ``P[j, :, :, b] = P_init[i0 + b, j]``: the
    mode-matched means ``(N, L, n)`` and covariances ``(N, L, n, n)`` of the block's trials
    into their lanes."""
    n = x.shape[1]
    for j in range(x.shape[0]):
        for r in range(n):
            for b in range(nb):
                x[j, r, b] = x_init[i0 + b, j, r]
            for c in range(n):
                for b in range(nb):
                    P[j, r, c, b] = P_init[i0 + b, j, r, c]


@jit
def scatter_modes(x, P, i0, nb, x_last, P_last):
    """``x_last[i0 + b, j] = x[j, :, b]``, ``P_last[i0 + b, j] = P[j, :, :, b]``:
    :func:`gather_modes` back."""
    n = x.shape[1]
    for b in range(nb):
        for j in range(x.shape[0]):
            for r in range(n):
                x_last[i0 + b, j, r] = x[j, r, b]
                for c in range(n):
                    P_last[i0 + b, j, r, c] = P[j, r, c, b]


@inline
def write_lane(x, P, b, i, k, x_out, P_out):
    """Lane ``b`` of ``x (n, B)`` and ``P (n, n, B)`` as sample ``k`` of trial ``i`` of the
    outputs ``x_out (N, K, n)``, ``P_out (N, K, n, n)``."""
    for r in range(x.shape[0]):
        x_out[i, k, r] = x[r, b]
        for c in range(x.shape[0]):
            P_out[i, k, r, c] = P[r, c, b]


@jit
def gather_matrices(table, index, nb, out):
    """``out[r, c, b] = table[index[b], r, c]``: each lane's matrix from a table."""
    for r in range(out.shape[0]):
        for c in range(out.shape[1]):
            for b in range(nb):
                out[r, c, b] = table[index[b], r, c]


@jit
def observe(y, nb, obs, n_obs):
    """``obs[a, b] = 1`` where ``y[a, b]`` is observed (not NaN), else 0; ``n_obs[b]`` counts
    them."""
    for b in range(nb):
        n_obs[b] = 0.0
    for a in range(y.shape[0]):
        for b in range(nb):
            seen = 0.0 if math.isnan(y[a, b]) else 1.0
            obs[a, b] = seen
            n_obs[b] += seen


@jit
def predict_mean(x, F, G, u, nb, xs):
    """Mean time update ``x <- F x + G u`` (Shankar et al. eq. (6)); ``xs (n, B)`` is scratch."""
    n, n_in = x.shape[0], u.shape[0]
    for i in range(n):
        for b in range(nb):
            xs[i, b] = 0.0
        for j in range(n):
            for b in range(nb):
                xs[i, b] += F[i, j, b] * x[j, b]
        for j in range(n_in):
            for b in range(nb):
                xs[i, b] += G[i, j, b] * u[j, b]
    for i in range(n):
        for b in range(nb):
            x[i, b] = xs[i, b]


@borrow
def predict(x, P, F, G, u, Qd, nb, FP, xs):
    """Time update ``x <- F x + G u``, ``P <- F P F' + Qd`` (Shankar et al. eqs (6)-(7)).

    ``Qd`` is the process-noise covariance of the exact discretization (symmetric; its upper
    triangle is read). ``P`` comes back exactly symmetric: its upper triangle is computed and
    mirrored. ``FP (n, n, B)`` and ``xs (n, B)`` are scratch.
    """
    n = x.shape[0]
    predict_mean(x, F, G, u, nb, xs)
    for i in range(n):
        for j in range(n):
            for b in range(nb):
                FP[i, j, b] = 0.0
            for k in range(n):
                for b in range(nb):
                    FP[i, j, b] += F[i, k, b] * P[k, j, b]
    symmetric_sum(Qd, FP, F, nb, P)


@inline
def copy_gaussian(x, P, nb, x_to, P_to):
    """``x_to = x``, ``P_to = P`` in the first ``nb`` lanes of ``x (n, B)``, ``P (n, n, B)``."""
    n = x.shape[0]
    for r in range(n):
        for b in range(nb):
            x_to[r, b] = x[r, b]
        for c in range(n):
            for b in range(nb):
                P_to[r, c, b] = P[r, c, b]


@jit
def copy_lanes(source, nb, out):
    """``out[:, :, b] = source[:, :, b]`` in the first ``nb`` lanes of ``(p, q, B)`` arrays."""
    for r in range(source.shape[0]):
        for c in range(source.shape[1]):
            for b in range(nb):
                out[r, c, b] = source[r, c, b]


@inline
def symmetric_sum(base, X, Y, nb, out):
    """``out = base + X Y'`` per lane, for ``X``, ``Y (n, q, B)`` whose sum is symmetric
    (``Qd + (F P) F'``, ``A P + T K'``): the upper triangle is computed, ``base``'s read, and
    mirrored, so ``out`` is exactly symmetric. ``out`` may be ``base``."""
    n, q = X.shape[0], X.shape[1]
    for i in range(n):
        for j in range(i, n):
            for b in range(nb):
                out[i, j, b] = base[i, j, b]
            for k in range(q):
                for b in range(nb):
                    out[i, j, b] += X[i, k, b] * Y[j, k, b]
            for b in range(nb):
                out[j, i, b] = out[i, j, b]


@jit
def residual(x, y, C, nb, e):
    """``e = y - C x`` in every lane, ``C (m, n, B)``: the innovation before missing components
    are removed, or ``y`` less the response to an input ``x``."""
    m, n = C.shape[0], C.shape[1]
    for a in range(m):
        for b in range(nb):
            e[a, b] = y[a, b]
        for j in range(n):
            for b in range(nb):
                e[a, b] -= C[a, j, b] * x[j, b]


@borrow
def observed_residual(x, y, C, obs, nb, e):
    """``e = y - C x`` (Shankar et al. eq. (8)) with each lane's unobserved components zeroed."""
    residual(x, y, C, nb, e)
    for a in range(y.shape[0]):
        for b in range(nb):
            e[a, b] = e[a, b] if obs[a, b] > 0.0 else 0.0


@jit
def whiten(e, chol, scale, nb, z, nis):
    """``z = L^-1 D^-1/2 e`` by forward substitution and ``nis = |z|^2 = e' S^-1 e``, per lane,
    for ``S = D^1/2 L L' D^1/2`` as :func:`innovation` factors it."""
    m = e.shape[0]
    for b in range(nb):
        nis[b] = 0.0
    for a in range(m):
        for b in range(nb):
            z[a, b] = scale[a, b] * e[a, b]
        for c in range(a):
            for b in range(nb):
                z[a, b] -= chol[a, c, b] * z[c, b]
        for b in range(nb):
            z[a, b] /= chol[a, a, b]
            nis[b] += z[a, b] * z[a, b]


@borrow
def innovation(x, P, y, C, R, obs, n_obs, nb, e, PCt, chol, scale, z, nis, loglik, work, bad,
               report=None):
    """Innovation of ``y`` against ``(x, P)`` over each lane's observed components.

    ``e = y - C x``, ``P C'`` and ``S = C P C' + R`` (Shankar et al. eq. (8)), with every
    unobserved component decoupled (``e_a = 0``, row and column ``a`` of ``S`` those of the
    identity). ``S`` is equilibrated by its diagonal ``D`` before its Cholesky factorization,
    ``D^-1/2 S D^-1/2 = L L'``, so entries of 1e300 or 1e-300 neither overflow nor underflow;
    ``log det S = sum log D + log prod L_aa^2`` (the product lies in (0, 1]: it underflows only
    for a condition number beyond 1e300, which the factorization refuses). Written per lane:
    ``nis = e' S^-1 e = |L^-1 D^-1/2 e|^2`` and
    ``loglik = log N(e; 0, S) = -(e' S^-1 e + log det S + m_o log 2 pi) / 2`` (0 with nothing
    observed). ``work (3, B)`` is scratch; ``e``, ``PCt``, ``chol``, ``scale``, ``z`` keep what
    :func:`correct` needs.

    With ``report`` (``[count, smallest eigenvalue]`` of :func:`repair`), the lanes whose
    factorization fails have their ``P`` repaired and every lane is factored once more: the rule
    of the filters here. Without it the caller decides (a group's repair in
    :mod:`.kalman_kernel`, a full prediction in :mod:`.imm_ev1`).

    Returns
    -------
    status
        ``OK``; ``NOT_FINITE`` if a lane's ``S`` has a non-finite diagonal; else
        ``NOT_POSITIVE_DEFINITE`` if a lane's factorization failed (with ``report``: again, or
        where its ``P`` needed no repair), ``bad (B,)`` then marking those lanes (the others
        are complete).
    """
    n, m = x.shape[0], y.shape[0]
    log_det, det, pivot = work[0], work[1], work[2]
    repaired = False
    while True:  # once; with report, again after the failing lanes' P are repaired
        observed_residual(x, y, C, obs, nb, e)
        for a in range(m):
            for i in range(n):
                for b in range(nb):
                    PCt[i, a, b] = 0.0
                for j in range(n):
                    for b in range(nb):
                        PCt[i, a, b] += P[i, j, b] * C[a, j, b]
                for b in range(nb):
                    PCt[i, a, b] *= obs[a, b]
        for a in range(m):  # S, lower triangle, into chol
            for c in range(a + 1):
                for b in range(nb):
                    chol[a, c, b] = R[a, c, b] * obs[c, b]
                for i in range(n):
                    for b in range(nb):
                        chol[a, c, b] += C[a, i, b] * PCt[i, c, b]
                unit = 1.0 if a == c else 0.0
                for b in range(nb):
                    chol[a, c, b] = chol[a, c, b] * obs[a, b] + unit * (1.0 - obs[a, b])
        for b in range(nb):
            log_det[b] = 0.0
        for a in range(m):  # log det D, before the factorization overwrites the diagonal
            for b in range(nb):
                log_det[b] += math.log(chol[a, a, b])
        finite, positive = factor(chol, scale, nb, det, pivot)
        if not finite:
            return NOT_FINITE
        whiten(e, chol, scale, nb, z, nis)
        for b in range(nb):
            loglik[b] = -0.5 * (nis[b] + log_det[b] + math.log(det[b]) + n_obs[b] * _LOG_2PI)
        if positive:
            return OK
        for b in range(nb):  # a failed pivot leaves NaN (or 0) in det: the lanes to repair
            bad[b] = not det[b] > 0.0
        if report is None:  # decided as numba compiles: report omitted, or an array
            return NOT_POSITIVE_DEFINITE
        if repaired:
            return NOT_POSITIVE_DEFINITE
        for b in range(nb):
            if bad[b] and not repair(P, b, False, report):
                return NOT_POSITIVE_DEFINITE
        repaired = True


@inline
def factor(chol, scale, nb, det, pivot):
    """Equilibrated Cholesky factorization, in place, of each lane's symmetric ``S (m, m)``
    held in the lower triangle of ``chol (m, m, B)`` (the factorization of :func:`innovation`).

    ``S`` is equilibrated by its diagonal ``D``, ``D^-1/2 S D^-1/2 = L L'`` (Golub & Van Loan,
    "Matrix Computations", 4th ed., Algorithm 4.2.2, column by column), so entries of 1e300 or
    1e-300 neither overflow nor underflow (``|S_ac| <= sqrt(S_aa S_cc)``). Written: ``L`` in
    the lower triangle of ``chol`` (the upper one is not read), ``scale = D^-1/2 (m, B)`` and
    ``det (B,) = prod L_aa^2``, in ``(0, 1]`` for a positive definite ``S`` and NaN or 0 where a
    lane's factorization failed; ``pivot (B,)`` is scratch.

    Returns
    -------
    finite, positive : bool
        Whether every lane's diagonal of ``S`` is finite (if not, nothing else is done), and
        whether every lane's ``S`` is positive definite (its diagonal and pivots positive).
    """
    m = chol.shape[0]
    finite, positive = True, True
    for a in range(m):
        for b in range(nb):
            d = chol[a, a, b]
            finite &= math.isfinite(d)
            positive &= d > 0.0
            scale[a, b] = 1.0 / math.sqrt(d)
    if not finite:
        return finite, positive
    for b in range(nb):
        det[b] = 1.0
    for a in range(m):  # D^-1/2 S D^-1/2: |S_ac| <= sqrt(S_aa S_cc), so nothing overflows
        for c in range(a + 1):
            for b in range(nb):
                chol[a, c, b] = chol[a, c, b] * scale[a, b] * scale[c, b]
    for j in range(m):  # Cholesky, column by column
        for b in range(nb):
            pivot[b] = chol[j, j, b]
        for p in range(j):
            for b in range(nb):
                pivot[b] -= chol[j, p, b] * chol[j, p, b]
        for b in range(nb):
            positive &= pivot[b] > 0.0
            root = math.sqrt(pivot[b])
            chol[j, j, b] = root
            det[b] *= pivot[b]
        for i in range(j + 1, m):
            for p in range(j):
                for b in range(nb):
                    chol[i, j, b] -= chol[i, p, b] * chol[j, p, b]
            for b in range(nb):
                chol[i, j, b] /= chol[j, j, b]
    return finite, positive


@borrow
def innovation_mean(x, y, C, obs, n_obs, chol, scale, log_det, nb, e, z, nis, loglik):
    """The per-lane half of :func:`innovation`, from a factorization of ``S`` computed elsewhere.

    Where lanes share their covariance (the same ``P``, ``C``, ``R`` and observed components:
    the same ``S``), :func:`innovation` factors ``S`` once and this function finishes each
    lane: ``e = y - C x`` (Shankar et al. eq. (8)) with the unobserved components zeroed,
    ``z = L^-1 D^-1/2 e``, ``nis = |z|^2 = e' S^-1 e`` and
    ``loglik = -(e' S^-1 e + log det S + m_o log 2 pi) / 2``. ``chol``, ``scale`` are the
    factorization :func:`innovation` leaves, and ``log_det (2, B)`` its ``log det S`` in two
    terms, ``sum log D`` and ``log prod L_aa^2`` (``work[0]`` and the logarithm of
    ``work[1]`` there), each lane's copy of its covariance's. The operations are those of
    :func:`innovation`, in its order: a lane gets the same bits either way.
    """
    observed_residual(x, y, C, obs, nb, e)
    whiten(e, chol, scale, nb, z, nis)
    for b in range(nb):
        loglik[b] = -0.5 * (nis[b] + log_det[0, b] + log_det[1, b] + n_obs[b] * _LOG_2PI)


@borrow
def _solve(chol, scale, v, nb):
    """``v <- S^-1 v`` per lane, with ``S = D^1/2 L L' D^1/2`` as :func:`innovation` left it."""
    m = v.shape[0]
    for a in range(m):  # forward: L w = D^-1/2 v
        for b in range(nb):
            v[a, b] *= scale[a, b]
        for c in range(a):
            for b in range(nb):
                v[a, b] -= chol[a, c, b] * v[c, b]
        for b in range(nb):
            v[a, b] /= chol[a, a, b]
    back_substitute(chol, scale, v, nb)


@jit
def solve_rows(chol, scale, V, nb, inv):
    """``V[r] <- S^-1 V[r]`` per lane for every row ``r`` of ``V (q, m, B)``, with
    ``S = D^1/2 L L' D^1/2`` as :func:`factor` left it: forward and back substitution (Golub &
    Van Loan, "Matrix Computations", 4th ed., §3.1) as :func:`_solve`'s, multiplying by the
    reciprocals of ``L``'s diagonal, ``inv (m, B)`` (written), taken once for all ``q`` rows
    (a division costs several multiplications)."""
    q, m = V.shape[0], V.shape[1]
    for a in range(m):
        for b in range(nb):
            inv[a, b] = 1.0 / chol[a, a, b]
    for r in range(q):
        v = V[r]
        for a in range(m):  # forward: L w = D^-1/2 v
            for b in range(nb):
                v[a, b] *= scale[a, b]
            for c in range(a):
                for b in range(nb):
                    v[a, b] -= chol[a, c, b] * v[c, b]
            for b in range(nb):
                v[a, b] *= inv[a, b]
        for a in range(m - 1, -1, -1):  # back: D^-1/2 L'^-1 w
            for c in range(a + 1, m):
                for b in range(nb):
                    v[a, b] -= chol[c, a, b] * v[c, b]
            for b in range(nb):
                v[a, b] *= inv[a, b]
        for a in range(m):
            for b in range(nb):
                v[a, b] *= scale[a, b]


@jit
def back_substitute(chol, scale, v, nb):
    """``v <- D^-1/2 L'^-1 v`` per lane: the second half of :func:`_solve` (``S^-1 e`` from
    ``z = L^-1 D^-1/2 e``)."""
    m = v.shape[0]
    for a in range(m - 1, -1, -1):
        for c in range(a + 1, m):
            for b in range(nb):
                v[a, b] -= chol[c, a, b] * v[c, b]
        for b in range(nb):
            v[a, b] /= chol[a, a, b]
    for a in range(m):
        for b in range(nb):
            v[a, b] *= scale[a, b]


@borrow
def correct(x, P, C, R, use, nb, PCt, chol, scale, z, K, T, AP, prior):
    """Measurement update, in the lanes where ``use`` is true (Shankar et al. eqs (9)-(10)).

    From what :func:`innovation` left: ``K = P C' S^-1`` by Cholesky solves (no inverse),
    ``x <- x + K e`` computed as ``x + P C' (S^-1 e)``, and the covariance in Joseph form
    ``P <- (I - K C) P (I - K C)' + K R K'``, valid for any gain. It is evaluated through
    ``A = I - K C`` without forming ``A``: ``A P = P - K (P C')'``, then
    ``A P A' + K R K' = A P + (K R - A P C') K'`` (O(n^2 m) instead of O(n^3)); the upper
    triangle is computed and mirrored, so ``P`` is exactly symmetric. The other lanes get
    ``K = 0``, which leaves ``x`` and ``P`` exactly as they were. ``z`` is overwritten;
    ``prior (n, n, B)`` gets the covariance before the update (for :func:`joseph_lost`).
    """
    n, m = x.shape[0], z.shape[0]
    for i in range(n):
        for j in range(n):
            for b in range(nb):
                prior[i, j, b] = P[i, j, b]
    correct_mean(x, z, PCt, chol, scale, use, nb)  # x <- x + P C' S^-1 e, eq. (9)
    for i in range(n):
        Ki = K[i]
        for a in range(m):
            for b in range(nb):
                Ki[a, b] = PCt[i, a, b]
        _solve(chol, scale, Ki, nb)  # row i of K is S^-1 (row i of P C'), S symmetric
        for a in range(m):
            for b in range(nb):
                Ki[a, b] = Ki[a, b] if use[b] else 0.0
    for i in range(n):  # A P = P - K (C P), with C P = (P C')' as P is symmetric
        for j in range(n):
            for b in range(nb):
                AP[i, j, b] = P[i, j, b]
            for a in range(m):
                for b in range(nb):
                    AP[i, j, b] -= K[i, a, b] * PCt[j, a, b]
    for i in range(n):  # T = K R - A P C'
        for c in range(m):
            for b in range(nb):
                T[i, c, b] = 0.0
            for a in range(m):
                for b in range(nb):
                    T[i, c, b] += K[i, a, b] * R[a, c, b]
            for j in range(n):
                for b in range(nb):
                    T[i, c, b] -= AP[i, j, b] * C[c, j, b]
    symmetric_sum(AP, T, K, nb, P)  # P = A P + T K'


@borrow
def correct_mean(x, z, PCt, chol, scale, use, nb):
    """The per-lane half of :func:`correct`: ``x <- x + P C' S^-1 e`` in the lanes where
    ``use`` is true (Shankar et al. eq. (9)), from ``z`` as :func:`innovation_mean` left it and
    a factorization of ``S`` with its ``P C'`` computed elsewhere (each lane's copy of its
    covariance's); ``z`` is overwritten with ``S^-1 e``. :func:`correct` updates ``x`` with it
    too, so a lane gets the same bits either way."""
    n, m = x.shape[0], z.shape[0]
    back_substitute(chol, scale, z, nb)  # S^-1 e = D^-1/2 L'^-1 z
    for i in range(n):
        for a in range(m):
            for b in range(nb):
                x[i, b] += PCt[i, a, b] * z[a, b] if use[b] else 0.0


@jit
def joseph_lost(P, prior, use, nb, root, lost):
    """Mark the lanes where Joseph's form has lost its digits; return whether there is one.

    Joseph's ``A = I - K C`` is accurate to ``eps |K C|`` only, so ``A P A'`` carries an error
    of about ``eps^2 |K C|^2 P``. Where the update removes nearly all the prior variance of a
    state (``P+_ii < eps P_ii``: a diffuse prior, a nearly noise-free measurement) or the
    result is no longer a covariance (a correlation beyond ``1 + sqrt(eps)``, or a NaN), that
    error has swamped ``P+``: ``lost[b]`` is set there, among the lanes that ``use`` the
    measurement, for :func:`information_form`. ``root (n, B)`` is scratch.
    """
    n = P.shape[0]
    for b in range(nb):
        lost[b] = False
    for i in range(n):
        for b in range(nb):
            lost[b] |= not P[i, i, b] >= _EPS * prior[i, i, b]
            root[i, b] = math.sqrt(abs(P[i, i, b]))
    for i in range(n):
        for j in range(i + 1, n):
            for b in range(nb):
                lost[b] |= not abs(P[i, j, b]) <= _CORRELATION_BOUND * root[i, b] * root[j, b]
    found = False
    for b in range(nb):
        lost[b] &= use[b]
        found |= lost[b]
    return found


@borrow
def information_or_repair(P, prior, C, R, obs, n_obs, lost, nb, report):
    """The posterior of each ``lost`` lane (:func:`joseph_lost`) that observed something, in
    information form (:func:`information_form`), or where that fails, repaired if indefinite
    (:func:`repair`, counted in ``report``): the rule of the filters here, after
    :func:`correct` (a group's repair in :mod:`.kalman_kernel` counts its trials)."""
    for b in range(nb):
        if lost[b] and n_obs[b] > 0.0 and not information_form(P, prior, C, R, obs, b):
            repair(P, b, True, report)


@jit
def _cholesky(A, out):
    """Equilibrated Cholesky factor of one symmetric ``A (n, n)`` (lower triangle read):
    ``out = D L`` (lower, zero above), ``A = (D L)(D L)'``, with ``D`` the powers of two near
    ``sqrt(A_ii)`` and ``L`` the factor of ``D^-1 A D^-1`` (no overflow for entries of 1e300).
    Returns False if ``A`` is not positive definite or not finite."""
    n = A.shape[0]
    d = np.empty(n)
    for i in range(n):
        if not (A[i, i] > 0.0 and math.isfinite(A[i, i])):
            return False
        d[i] = math.ldexp(1.0, math.frexp(A[i, i])[1] // 2)
    for j in range(n):
        for i in range(j):
            out[i, j] = 0.0
        pivot = A[j, j] / d[j] / d[j]
        for p in range(j):
            pivot -= out[j, p] * out[j, p]
        if not (pivot > 0.0 and math.isfinite(pivot)):
            return False
        out[j, j] = math.sqrt(pivot)
        for i in range(j + 1, n):
            v = A[i, j] / d[i] / d[j]
            for p in range(j):
                v -= out[i, p] * out[j, p]
            out[i, j] = v / out[j, j]
    for i in range(n):
        for j in range(i + 1):
            out[i, j] *= d[i]
    return True


@jit
def _forward(Lo, B):
    """``B <- Lo^-1 B`` for a lower-triangular ``Lo (m, m)`` and ``B (m, k)``."""
    for a in range(Lo.shape[0]):
        for c in range(a):
            for q in range(B.shape[1]):
                B[a, q] -= Lo[a, c] * B[c, q]
        for q in range(B.shape[1]):
            B[a, q] /= Lo[a, a]


@jit
def information_form(P, prior, C, R, obs, b):
    """Lane ``b`` of the posterior in information form, where Joseph's has lost its digits.

    ``P+ = (P^-1 + C' R^-1 C)^-1 = L (I + L' C' R^-1 C L)^-1 L'`` with ``P = L L'`` the prior
    (``prior``), over the observed components of ``y`` (``obs``); computed as the Gram matrix
    ``Z' Z``, ``Z = N^-1 L'``, ``N N' = I + W' W``, ``W = R^-1/2 C L``: accurate to the
    conditioning of ``C' R^-1 C`` however diffuse the prior. A scalar path for one lane (rare).
    Returns False, leaving ``P`` alone, if ``P`` or ``R`` is not positive definite.
    """
    n, m = P.shape[0], C.shape[0]
    A = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            A[i, j] = prior[i, j, b]
    Lp = np.empty((n, n))
    if not _cholesky(A, Lp):
        return False
    Rd = np.empty((m, m))
    for a in range(m):
        for c in range(m):
            unit = 1.0 - obs[a, b] if a == c else 0.0
            Rd[a, c] = R[a, c, b] * obs[a, b] * obs[c, b] + unit
    Lr = np.empty((m, m))
    if not _cholesky(Rd, Lr):
        return False
    W = np.zeros((m, n))  # R^-1/2 C L, the unobserved rows zero
    for a in range(m):
        for j in range(n):
            for i in range(j, n):
                W[a, j] += C[a, i, b] * obs[a, b] * Lp[i, j]
    _forward(Lr, W)
    for i in range(n):
        for j in range(n):
            A[i, j] = 1.0 if i == j else 0.0
            for a in range(m):
                A[i, j] += W[a, i] * W[a, j]
    Ln = np.empty((n, n))
    if not _cholesky(A, Ln):
        return False
    Z = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            Z[i, j] = Lp[j, i]
    _forward(Ln, Z)
    for i in range(n):
        for j in range(i, n):
            v = 0.0
            for q in range(n):
                v += Z[q, i] * Z[q, j]
            P[i, j, b] = v
            P[j, i, b] = v
    return True


@jit
def repair(P, b, indefinite_only, report):
    """Raise lane ``b``'s covariance's eigenvalues to its rounding level ``n eps max|eig|``.

    A covariance whose condition number exceeds ``1/eps`` (a prior of 1e300 on a state seen
    only through the dynamics, a mixture of estimates 1e50 apart) cannot be told from a
    singular or indefinite one: its eigenvalues below that level (with ``indefinite_only``,
    below minus that level: negative beyond rounding) are raised to it, as much as is known
    about them. Returns whether ``P`` was changed; ``report`` ``[count, smallest eigenvalue]``
    records it for the caller's ``RuntimeWarning``. A non-finite ``P`` is left alone.
    """
    n = P.shape[0]
    A = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            A[i, j] = 0.5 * (P[i, j, b] + P[j, i, b])
            if not math.isfinite(A[i, j]):
                return False
    w, V = np.linalg.eigh(A)
    top = 0.0
    for i in range(n):
        top = max(top, abs(w[i]))
    level = n * _EPS * top
    if not w[0] < (-level if indefinite_only else level):
        return False
    report[0] += 1.0
    report[1] = min(report[1], w[0])
    for i in range(n):
        w[i] = max(w[i], level)
    for i in range(n):
        for j in range(n):
            A[i, j] = 0.0
            for q in range(n):
                A[i, j] += V[i, q] * w[q] * V[j, q]
    for i in range(n):
        for j in range(i, n):
            v = 0.5 * (A[i, j] + A[j, i])
            P[i, j, b] = v
            P[j, i, b] = v
    return True


@jit
def log_normalize(a, prob, total, nb):
    """Normalize log-weights ``a (L, B)`` over the modes by log-sum-exp, per lane.

    ``a <- (a - max) - log sum exp(a - max)``, ``prob <- exp(a)`` computed as
    ``exp(a - max) / sum exp(a - max)`` and ``total <- log sum exp(a)``. A lane whose weights
    are all ``-inf`` keeps them, with probabilities 0 and total ``-inf``.
    """
    for b in range(nb):
        top = -math.inf
        for j in range(a.shape[0]):
            top = max(top, a[j, b])
        if top == -math.inf:
            for j in range(a.shape[0]):
                prob[j, b] = 0.0
            total[b] = -math.inf
            continue
        acc = 0.0
        for j in range(a.shape[0]):
            prob[j, b] = math.exp(a[j, b] - top)
            acc += prob[j, b]
        log_acc = math.log(acc)
        for j in range(a.shape[0]):
            a[j, b] = (a[j, b] - top) - log_acc
            prob[j, b] /= acc
        total[b] = top + log_acc


@borrow
def mix(x, P, prob, log_prob, transition, log_transition, nb, log_c, w, xm, Pm):
    """IMM interaction, in place on the mode-matched ``x (L, n, B)``, ``P (L, n, n, B)``.

    Predicted mode probabilities ``log c_j = logsumexp_i(log mu_i + log pi_ij)``, mixing
    weights ``mu_{i|j} = exp(log mu_i + log pi_ij - log c_j)``, mixed means
    ``x0_j = sum_i mu_{i|j} x_i`` and covariances
    ``P0_j = sum_i mu_{i|j} (P_i + (x_i - x0_j)(x_i - x0_j)')``, the deviations taken from
    each mixture's own mean (Blom & Bar-Shalom, 1988; Bar-Shalom, Li & Kirubarajan
    §11.6.6). A mode no predecessor reaches gets ``log c_j = -inf`` and zero weights.

    The sums are taken over the probabilities ``prob = exp(log_prob)`` themselves (their
    largest is at least 1/L, so they need no shift): ``c_j = sum_i pi_ij mu_i``, without an
    exponential. A sum below 1e-250 (a mode all but unreachable, where the products may
    underflow) is redone in the log domain. ``transition (L, L, B)`` is each lane's transition
    matrix, ``exp(log_transition)``; ``w (L, L, B)`` (``w[j]``: the weights of mixture j),
    ``xm (L, n, B)`` and ``Pm (L, n, n, B)`` are scratch; ``log_c (L, B)`` is written.
    """
    n_modes = x.shape[0]
    predicted_mode_probabilities(prob, log_prob, transition, log_transition, nb, log_c, w)
    for j in range(n_modes):
        _moments(w[j], x, P, nb, xm[j], Pm[j])
    for j in range(n_modes):
        for r in range(x.shape[1]):
            for b in range(nb):
                x[j, r, b] = xm[j, r, b]
            for c in range(x.shape[1]):
                for b in range(nb):
                    P[j, r, c, b] = Pm[j, r, c, b]


@borrow
def predicted_mode_probabilities(prob, log_prob, transition, log_transition, nb, log_c, w):
    """Predicted mode probabilities ``log c_j = log sum_i pi_ij mu_i`` and the IMM's mixing
    weights ``w[j][i] = mu_{i|j} = pi_ij mu_i / c_j`` (Blom & Bar-Shalom, 1988; Bar-Shalom, Li &
    Kirubarajan §11.6.6), per lane, for ``L`` modes of probabilities ``prob (L, B)`` (and their
    logarithms ``log_prob``) and the lane's transition matrix ``transition (L, L, B)`` (and its
    logarithm): the first half of :func:`mix`, shared with :func:`collapse`.

    The sums are taken over the probabilities themselves; one below 1e-250 is redone in the log
    domain (see :func:`mix`). A mode no predecessor reaches gets ``log c_j = -inf`` and zero
    weights. ``log_c (L, B)`` and ``w (L, L, B)`` are written.
    """
    n_modes = prob.shape[0]
    for j in range(n_modes):
        wj, cj = w[j], log_c[j]
        for b in range(nb):
            cj[b] = 0.0
        for i in range(n_modes):
            for b in range(nb):
                wj[i, b] = transition[i, j, b] * prob[i, b]
                cj[b] += wj[i, b]
        for b in range(nb):
            if cj[b] > _TINY_SUM:
                for i in range(n_modes):
                    wj[i, b] /= cj[b]
                cj[b] = math.log(cj[b])
            else:
                cj[b] = _log_weights(log_prob, log_transition, j, b, wj)


@borrow
def collapse(x, P, prob, log_prob, transition, log_transition, nb, log_c, w, xm, Pm):
    """GPB1 interaction, in place on the mode-matched ``x (L, n, B)``, ``P (L, n, n, B)``.

    Every mode-matched filter restarts from one Gaussian, the moments of the mixture of all
    of them, ``x0 = sum_i mu_i x_i``, ``P0 = sum_i mu_i (P_i + (x_i - x0)(x_i - x0)')`` (the
    mixing weights ``mu_{i|j} = mu_i`` for every ``j``); the predicted mode probabilities are
    the IMM's, ``c_j = sum_i pi_ij mu_i`` (Bar-Shalom, Li & Kirubarajan §11.6.4, "GPB1").
    Arguments as :func:`mix`, whose scratch ``w``, ``xm``, ``Pm`` it uses (``w`` gets the IMM's
    mixing weights, unused here).
    """
    predicted_mode_probabilities(prob, log_prob, transition, log_transition, nb, log_c, w)
    _moments(prob, x, P, nb, xm[0], Pm[0])
    n = x.shape[1]
    for j in range(x.shape[0]):
        for r in range(n):
            for b in range(nb):
                x[j, r, b] = xm[0, r, b]
            for c in range(n):
                for b in range(nb):
                    P[j, r, c, b] = Pm[0, r, c, b]


@borrow
def merge(w, x, P, nb, xm, Pm):
    """Moments of the mixture ``sum_i w_i N(x_i, P_i)`` per lane, ``w (L, B)`` summing to one:
    ``xm = sum_i w_i x_i``, ``Pm = sum_i w_i (P_i + (x_i - xm)(x_i - xm)')`` (``xm (n, B)``,
    ``Pm (n, n, B)``, exactly symmetric): the merging of Gaussians of GPB2 (Bar-Shalom, Li &
    Kirubarajan §11.6.5), the computation :func:`mix` and :func:`combine` make."""
    _moments(w, x, P, nb, xm, Pm)


@inline
def write_modes(x, P, b, i, k, x_out, P_out):
    """Lane ``b`` of the mode-matched ``x (L, n, B)``, ``P (L, n, n, B)`` as sample ``k`` of
    trial ``i`` of ``x_out (N, K, L, n)``, ``P_out (N, K, L, n, n)``."""
    n = x.shape[1]
    for j in range(x.shape[0]):
        for r in range(n):
            x_out[i, k, j, r] = x[j, r, b]
            for c in range(n):
                P_out[i, k, j, r, c] = P[j, r, c, b]


@jit
def _log_weights(log_prob, log_transition, j, b, w):
    """Lane ``b`` of mixture ``j`` in the log domain: ``w[i, b] = exp(log mu_i + log pi_ij -
    lse)``, returning ``lse = logsumexp_i(log mu_i + log pi_ij)``; zero weights and ``-inf``
    when every term is ``-inf``."""
    top = -math.inf
    for i in range(w.shape[0]):
        w[i, b] = log_prob[i, b] + log_transition[i, j, b]
        top = max(top, w[i, b])
    if top == -math.inf:
        for i in range(w.shape[0]):
            w[i, b] = 0.0
        return -math.inf
    acc = 0.0
    for i in range(w.shape[0]):
        acc += math.exp(w[i, b] - top)
    lse = top + math.log(acc)
    for i in range(w.shape[0]):
        w[i, b] = math.exp(w[i, b] - lse)
    return lse


@jit
def _moments(w, x, P, nb, xm, Pm):
    """Mean ``xm (n, B)`` and covariance ``Pm (n, n, B)`` of the mixture
    ``sum_i w_i N(x_i, P_i)`` per lane, the deviations taken from its mean; upper triangle
    computed, then mirrored."""
    n_modes, n = x.shape[0], x.shape[1]
    for r in range(n):
        for b in range(nb):
            xm[r, b] = 0.0
        for i in range(n_modes):
            for b in range(nb):
                xm[r, b] += w[i, b] * x[i, r, b]
    for r in range(n):
        for c in range(r, n):
            for b in range(nb):
                Pm[r, c, b] = 0.0
            for i in range(n_modes):
                for b in range(nb):
                    Pm[r, c, b] += w[i, b] * (P[i, r, c, b] + (x[i, r, b] - xm[r, b])
                                              * (x[i, c, b] - xm[c, b]))
            for b in range(nb):
                Pm[c, r, b] = Pm[r, c, b]


@borrow
def combine(x, P, prob, log_prob, nb, xc, Pc, best):
    """IMM output ``x = sum_j mu_j x_j``, ``P = sum_j mu_j (P_j + (x_j - x)(x_j - x)')``
    (Bar-Shalom, Li & Kirubarajan §11.6.6) with ``mu = prob``, into ``xc (n, B)``,
    ``Pc (n, n, B)``; ``best (B,)`` gets the most probable mode (the first on a tie)."""
    for b in range(nb):
        best[b] = 0
        for j in range(1, log_prob.shape[0]):
            if log_prob[j, b] > log_prob[best[b], b]:
                best[b] = j
    _moments(prob, x, P, nb, xc, Pc)
