"""The compiled kernel of the Kalman filter along given transitions: covariances shared by trials.

The covariance recursion of a Kalman filter (Shankar et al. eqs (7)-(10)) does not depend on the
measured values: trials that start from the same ``P``, predict through equal ``F``, ``Qd``,
update with equal ``C``, ``R``, observe the same components and use (or gate) the measurement
alike carry the same ``P``, gain and innovation covariance, to the last bit. :func:`kalman_filter`
therefore keeps the trials of a block in *groups* of one covariance each and runs the covariance
equations once per group, the mean equations once per trial, all from :mod:`.linalg`:

- per group (the group's covariance in a lane of its own, its mean zero):
  :func:`.linalg.predict`, :func:`.linalg.innovation`, :func:`.linalg.correct`,
  :func:`.linalg.joseph_lost` with :func:`.linalg.information_form`, and :func:`.linalg.repair`;
- per trial: :func:`.linalg.predict_mean`, :func:`.linalg.innovation_mean`,
  :func:`.linalg.correct_mean` (the mean halves of the same equations), reading a copy of their
  group's factorization.

A group splits when its trials part ways: another transition or output matrix (compared by
value, so per-trial copies of one matrix stay together), other observed components, or a
measurement some trials gate and others use. Groups never merge. In the common case (every trial
in one mode and fully observed) a block is one group, and a trial-step costs a prediction of the
mean, a whitened residual and the writing of the outputs; with every trial apart (different
transitions, scattered missing components) there is one group per trial, the equations of
:mod:`.bank` lane by lane. Either way each trial gets exactly the numbers its own filter would
compute: a group runs the same operations on the same operands.

A covariance recursion with a fixed sample (the same transition, output matrices, observed
components and use of the measurement at every step) reaches a fixed point to the last bit
within some tens of samples: ``P = f(P)`` in floating point. From the sample after the block's
covariances reached it under an unchanged sample, the covariance equations of the next sample
with that sample would repeat the last ones operand for operand, so the kernel skips them and
keeps their results (``P`` and the factorization of ``S``): the same bits, at the cost of the
means alone. Any change (another entry, other observed components, a gated measurement, a new
group, a repair) runs the equations again.

A block of one group runs the covariance equations on one lane, where each lane loop costs more
than its arithmetic. numba compiles a function again for a literal argument, and the functions
it calls with it, so calling :func:`.linalg.predict` and :func:`.linalg.correct` with a constant
1 where the block is one group runs them without lane loops. Measured on the vehicle (n = 4,
m = 2), a run of 10 trials over 200 samples then took 0.80-0.87 of the time, with
:func:`.linalg.innovation` and :func:`.linalg.joseph_lost` too 0.77-0.86; but this kernel's first
compile took 5 and 10 CPU-s longer (of 40), for every user once, so it is not done.

The outputs ``(N, K, ...)`` are written through buffers of ``CHUNK`` samples, trial by trial,
so that each store continues a run of contiguous memory (:func:`write_out`): stored sample by
sample, a block's trials write to ``lanes`` places ``K`` samples apart, and the kernel ran
15-20 % slower.
"""

from __future__ import annotations

import math

import numpy as np

from .linalg import (
    ACCEPTED,
    GATED,
    NOT_POSITIVE_DEFINITE,
    OK,
    borrow,
    copy_lanes,
    correct,
    correct_mean,
    gather_matrices,
    gather_rows,
    gather_samples,
    information_form,
    innovation,
    innovation_mean,
    jit,
    joseph_lost,
    observe,
    predict,
    predict_mean,
    repair,
)

__all__ = ["CHUNK", "LANES", "kalman_filter", "lane_entries", "predict_means", "write_out"]

LANES = 256  # trials per block: a group's covariance equations serve up to this many
CHUNK = 16  # samples buffered per block before they are written out, trial by trial

# rows of a block's group index ``slot (4, B)``
_MEMBER = 0  # the lane of a trial in the group (whose sample stands for the group's)
_PARENT = 1  # the group it split from, while splits are being made
_TRANS = 2  # the entry of F, Qd in the group's lane (-1: to be gathered)
_MODE = 3  # the entry of C, R in the group's lane (-1: to be gathered)


@jit
def kalman_filter(y, u, F, G, Qd, trans, C, R, mode, x_init, P_init, predict_first, gate, lanes,
                  x_out, P_out, loglik_out, flag_out, report):
    """Kalman filter of ``N`` trials over ``K`` samples, in blocks of ``lanes`` trials.

    Parameters
    ----------
    y : (N, K, m) float64
        Measurements; NaN components are missing (each trial updates with its observed ones).
    u : (N, K, l) float64
        Inputs; ``u[:, k-1]`` is held over the interval into sample ``k``, ``u[:, 0]`` over the
        interval into sample 0 when ``predict_first``.
    F, G, Qd : (M, n, n), (M, n, l), (M, n, n) float64
        Table of exact transitions ``x+ = F x + G u + w``, ``w ~ N(0, Qd)``.
    trans : (N, K) int64
        Transition into sample ``k`` of each trial.
    C, R : (L, m, n), (L, m, m) float64
        Table of output matrices and measurement-noise covariances.
    mode : (N, K) int64
        Which ``C``, ``R`` sample ``k`` of each trial uses.
    x_init, P_init : (N, n), (N, n, n) float64
        State of every trial before the first sample.
    predict_first : bool
        Whether the first sample is predicted into (a streaming step) or only updated.
    gate : float
        Largest normalized innovation squared accepted.
    lanes : int
        Trials per block.
    x_out, P_out, loglik_out, flag_out
        Written: posterior ``(N, K, n)``, ``(N, K, n, n)``, log-likelihood (0 when nothing was
        observed or the sample was gated) and flag (``ACCEPTED`` or ``GATED``) ``(N, K)``.
    report : (2,) float64
        Written: the number of covariances repaired (a group's repair counts once per trial of
        the group) and the smallest eigenvalue one had before its repair (``inf`` if none).

    Returns
    -------
    status : int
        ``OK`` or the failure code that stopped the kernel (outputs then incomplete).

    Notes
    -----
    A measurement whose normalized innovation squared exceeds ``gate``, or whose likelihood is
    not finite, is treated as missing (flag ``GATED``). Ill-conditioned covariances as in
    :func:`.bank.filter_bank`: the information form where Joseph's form loses its digits, a
    repair where neither resolves it or where the innovation covariance fails its
    factorization; only a covariance that needs no repair and still fails stops the kernel.
    """
    N, K, m = y.shape
    n, n_in, B = x_init.shape[1], u.shape[2], lanes
    # the trials, one per lane; PCt, chol, scale, log_det: each a copy of its group's
    x, xs, held = np.empty((n, B)), np.empty((n, B)), np.empty((2, B), dtype=np.int64)
    Fl, Gl, Cl = np.empty((n, n, B)), np.empty((n, n_in, B)), np.empty((m, n, B))
    yl, ul, obs, n_obs = np.empty((m, B)), np.empty((n_in, B)), np.empty((m, B)), np.empty(B)
    e, z, nis, loglik = np.empty((m, B)), np.empty((m, B)), np.empty(B), np.empty(B)
    PCt, chol, scale = np.empty((n, m, B)), np.empty((m, m, B)), np.empty((m, B))
    log_det, use, group = np.empty((2, B)), np.empty(B, dtype=np.bool_), np.empty(B, dtype=np.int64)
    # the groups, one per lane: covariance, sample, factorization; mean, input, output stay 0
    slot, P = np.empty((4, B), dtype=np.int64), np.empty((n, n, B))
    Fg, Qg = np.empty((n, n, B)), np.empty((n, n, B))
    Cg, Rg = np.empty((m, n, B)), np.empty((m, m, B))
    obs_g, n_obs_g, use_g = np.empty((m, B)), np.empty(B), np.empty(B, dtype=np.bool_)
    xg, Gg, ug, yg = np.zeros((n, B)), np.zeros((n, n_in, B)), np.zeros((n_in, B)), np.zeros((m, B))
    eg, zg = np.empty((m, B)), np.empty((m, B))
    PCt_g, chol_g = np.empty((n, m, B)), np.empty((m, m, B))
    scale_g, nis_g, loglik_g = np.empty((m, B)), np.empty(B), np.empty(B)
    work, log_det_g, bad = np.empty((3, B)), np.empty((2, B)), np.zeros(B, dtype=np.bool_)
    gain, T, FP = np.empty((n, m, B)), np.empty((n, m, B)), np.empty((n, n, B))
    prior, root, lost = np.empty((n, n, B)), np.empty((n, B)), np.empty(B, dtype=np.bool_)
    # the groups' posterior covariances and use of the measurement at the previous sample
    P_last, use_last = np.empty((n, n, B)), np.empty(B, dtype=np.bool_)
    PCt_rows, PCt_g_rows = PCt.reshape((n * m, B)), PCt_g.reshape((n * m, B))
    chol_rows, chol_g_rows = chol.reshape((m * m, B)), chol_g.reshape((m * m, B))
    # the last samples of the block, written out by trial (long runs of contiguous memory)
    x_buf, P_buf = np.empty((B, CHUNK, n)), np.empty((B, CHUNK, n * n))
    group_buf, loglik_buf = np.empty((B, CHUNK), dtype=np.int64), np.empty((B, CHUNK))
    flag_buf = np.empty((B, CHUNK), dtype=np.uint8)
    P_rows = P_out.reshape((N, K, n * n))
    report[0], report[1] = 0.0, math.inf
    for i0 in range(0, N, B):
        nb = min(B, N - i0)
        gather_rows(x_init, i0, nb, x)
        held.fill(-1)  # no entry held: each lane gathers its matrices at its first sample
        n_groups = _group_equal(P_init, i0, nb, group, slot, P)
        fixed = False  # the groups' covariances are at a fixed point of the last sample's map
        for k in range(K):
            gather_samples(y, i0, nb, k, yl)
            observe(yl, nb, obs, n_obs)
            predicting = k > 0 or predict_first
            before, repairs = n_groups, report[0]
            n_groups = _split_samples(trans, mode, F, Qd, C, R, obs, i0, nb, k, predicting, group,
                                      n_groups, slot, P)
            changed = _gather_groups(trans, mode, F, Qd, C, R, obs, n_obs, i0, k, predicting,
                                     n_groups, slot, Fg, Qg, Cg, Rg, obs_g, n_obs_g)
            # the same covariances through the same equations: the last sample's results, kept
            # in P, prior, PCt_g, chol_g, scale_g and log_det_g, to the last bit
            repeat = fixed and predicting and n_groups == before and not changed
            if predicting:  # Shankar et al. eqs (6)-(7)
                predict_means(trans, F, G, u, i0, nb, k, held[0], Fl, Gl, ul, x, xs)
                if not repeat:
                    predict(xg, P, Fg, Gg, ug, Qg, n_groups, FP, xs)
            if lane_entries(mode, i0, nb, k, held[1]):
                gather_matrices(C, held[1], nb, Cl)
            if not repeat:
                status = _factor(xg, P, yg, Cg, Rg, obs_g, n_obs_g, n_groups, eg, PCt_g, chol_g,
                                 scale_g, zg, nis_g, loglik_g, work, bad, log_det_g, group, nb,
                                 report)  # eq. (8)
                if status != OK:
                    return status
            _spread(PCt_g_rows, group, nb, n_groups, PCt_rows)
            _spread(chol_g_rows, group, nb, n_groups, chol_rows)
            _spread(scale_g, group, nb, n_groups, scale)
            _spread(log_det_g, group, nb, n_groups, log_det)
            innovation_mean(x, yl, Cl, obs, n_obs, chol, scale, log_det, nb, e, z, nis, loglik)
            for j in range(n_groups):
                use_g[j] = False
            for b in range(nb):  # the gate, then the update (eqs (9)-(10)) where it passed
                use[b] = math.isfinite(loglik[b]) and nis[b] <= gate
                use_g[group[b]] |= use[b]
            lost_any = False
            if not (repeat and _same_flags(use_g, use_last, n_groups)):
                if repeat:  # the prediction skipped above: the prior, as the last sample's
                    copy_lanes(prior, n_groups, P)
                correct(xg, P, Cg, Rg, use_g, n_groups, PCt_g, chol_g, scale_g, zg, gain, T, FP,
                        prior)
                lost_any = joseph_lost(P, prior, use_g, n_groups, root, lost)
                if lost_any:  # rare
                    for j in range(n_groups):
                        if lost[j] and n_obs_g[j] > 0.0 and not information_form(
                                P, prior, Cg, Rg, obs_g, j):
                            _repair(P, j, True, _users(group, use, nb, j), report)
            correct_mean(x, z, PCt, chol, scale, use, nb)
            for j in range(n_groups):
                use_last[j] = use_g[j]
            n_groups = _split_gated(use, use_g, group, nb, n_groups, slot, P, prior)
            # P = f(P) for this sample's map f: the next sample, with the same map, repeats it
            fixed = (k > 0 and predicting and n_groups == before and not lost_any
                     and report[0] == repairs and _same_lanes(P, P_last, n_groups))
            copy_lanes(P, n_groups, P_last)
            _record(x, P, group, use, n_obs, loglik, nb, n_groups, k % CHUNK, x_buf, P_buf,
                    group_buf, loglik_buf, flag_buf)
            if k % CHUNK == CHUNK - 1 or k == K - 1:
                write_out(x_buf, P_buf, group_buf, loglik_buf, flag_buf, i0, nb, k - k % CHUNK,
                          k % CHUNK + 1, x_out, P_rows, loglik_out, flag_out)
    return OK


@jit
def lane_entries(index, i0, nb, k, held):
    """``held[b] <- index[i0 + b, k]`` for every lane; return whether one changed (the lanes'
    matrices are then gathered again)."""
    changed = False
    for b in range(nb):
        changed |= index[i0 + b, k] != held[b]
        held[b] = index[i0 + b, k]
    return changed


@borrow
def predict_means(trans, F, G, u, i0, nb, k, held, Fl, Gl, ul, x, xs):
    """Every trial's mean predicted into sample ``k``, ``x <- F x + G u`` (Shankar et al. eq.
    (6), :func:`.linalg.predict_mean`), with ``u[:, k-1]`` and the transition
    ``trans[i0 + b, k]`` of the table ``F``, ``G``, whose lane matrices ``Fl``, ``Gl`` are
    gathered again where it changed (:func:`lane_entries`); ``ul``, ``xs`` are scratch."""
    if lane_entries(trans, i0, nb, k, held):
        gather_matrices(F, held, nb, Fl)
        gather_matrices(G, held, nb, Gl)
    gather_samples(u, i0, nb, max(k - 1, 0), ul)
    predict_mean(x, Fl, Gl, ul, nb, xs)


@jit
def _same_entry(table, i, j):
    """Whether entries ``i`` and ``j`` of ``table`` are equal, element by element (NaN is not
    equal to itself: such entries stay apart)."""
    if i == j:
        return True
    for r in range(table.shape[1]):
        for c in range(table.shape[2]):
            if table[i, r, c] != table[j, r, c]:
                return False
    return True


@jit
def _open(slot, j, b, parent, source, i, P):
    """Open group ``j`` with lane ``b`` as its member, split from ``parent``, with the
    covariance in lane ``i`` of ``source (n, n, B)`` (its matrices are gathered at the next
    sample)."""
    slot[_MEMBER, j] = b
    slot[_PARENT, j] = parent
    slot[_TRANS, j] = -1
    slot[_MODE, j] = -1
    for r in range(P.shape[0]):
        for c in range(P.shape[1]):
            P[r, c, j] = source[r, c, i]


@borrow
def _group_equal(P_init, i0, nb, group, slot, P):
    """Group the block's trials by equal initial covariance (each compared with the previous
    trial's group and with the first group); returns the number of groups."""
    n_groups = 0
    for b in range(nb):
        j = -1
        if b > 0 and _same_entry(P_init, i0 + b, i0 + slot[_MEMBER, group[b - 1]]):
            j = group[b - 1]
        elif b > 0 and _same_entry(P_init, i0 + b, i0 + slot[_MEMBER, 0]):
            j = 0
        if j < 0:
            j = n_groups
            n_groups += 1
            slot[_MEMBER, j] = b
            slot[_TRANS, j] = -1
            slot[_MODE, j] = -1
            _copy_entry(P_init, i0 + b, P, j)
        group[b] = j
    return n_groups


@borrow
def _same_sample(trans, mode, F, Qd, C, R, obs, i0, k, predicting, b, s):
    """Whether lanes ``b`` and ``s`` take sample ``k`` through the same covariance equations:
    the same observed components, equal ``C``, ``R`` and (when ``predicting``) ``F``, ``Qd``
    (the same entry, or entries equal by value)."""
    for a in range(obs.shape[0]):
        if obs[a, b] != obs[a, s]:
            return False
    i, j = i0 + b, i0 + s
    if mode[i, k] != mode[j, k] and not (_same_entry(C, mode[i, k], mode[j, k])
                                         and _same_entry(R, mode[i, k], mode[j, k])):
        return False
    return not predicting or trans[i, k] == trans[j, k] or (
        _same_entry(F, trans[i, k], trans[j, k]) and _same_entry(Qd, trans[i, k], trans[j, k]))


@borrow
def _split_samples(trans, mode, F, Qd, C, R, obs, i0, nb, k, predicting, group, n_groups, slot,
                   P):
    """Move each trial whose sample differs from its group member's (:func:`_same_sample`) to a
    new group with a copy of the covariance, shared with the trials that move alike; returns
    the number of groups."""
    m, first = obs.shape[0], n_groups
    for b in range(nb):
        s = slot[_MEMBER, group[b]]
        alike = trans[i0 + b, k] == trans[i0 + s, k] or not predicting
        alike &= mode[i0 + b, k] == mode[i0 + s, k]
        for a in range(m):
            alike &= obs[a, b] == obs[a, s]
        if alike:  # the common case, decided without a call
            continue
        if _same_sample(trans, mode, F, Qd, C, R, obs, i0, k, predicting, b, s):
            continue
        h = first
        while h < n_groups and not (slot[_PARENT, h] == group[b] and _same_sample(
                trans, mode, F, Qd, C, R, obs, i0, k, predicting, b, slot[_MEMBER, h])):
            h += 1
        if h == n_groups:
            n_groups += 1
            _open(slot, h, b, group[b], P, group[b], P)
        group[b] = h
    return n_groups


@jit
def _copy_entry(table, i, out, j):
    """``out[:, :, j] = table[i]``: entry ``i`` of a table into lane ``j``."""
    for r in range(table.shape[1]):
        for c in range(table.shape[2]):
            out[r, c, j] = table[i, r, c]


@borrow
def _gather_groups(trans, mode, F, Qd, C, R, obs, n_obs, i0, k, predicting, n_groups, slot, Fg,
                   Qg, Cg, Rg, obs_g, n_obs_g):
    """Each group's sample from its member trial: the observed components, and the matrices of
    the entries whose index changed. Returns whether any group's sample differs from the one
    its lane held (other observed components or entries)."""
    changed = False
    for j in range(n_groups):
        b = slot[_MEMBER, j]
        i = i0 + b
        for a in range(obs.shape[0]):
            changed |= obs_g[a, j] != obs[a, b]
            obs_g[a, j] = obs[a, b]
        n_obs_g[j] = n_obs[b]
        if predicting and trans[i, k] != slot[_TRANS, j]:
            changed = True
            slot[_TRANS, j] = trans[i, k]
            _copy_entry(F, trans[i, k], Fg, j)
            _copy_entry(Qd, trans[i, k], Qg, j)
        if mode[i, k] != slot[_MODE, j]:
            changed = True
            slot[_MODE, j] = mode[i, k]
            _copy_entry(C, mode[i, k], Cg, j)
            _copy_entry(R, mode[i, k], Rg, j)
    return changed


@jit
def _same_lanes(P, Q, n_groups):
    """Whether ``P[:, :, j]`` equals ``Q[:, :, j]`` bit for bit in every group's lane (NaN is
    not equal to itself: a covariance with a NaN is never at a fixed point)."""
    for r in range(P.shape[0]):
        for c in range(P.shape[1]):
            for j in range(n_groups):
                if P[r, c, j] != Q[r, c, j]:
                    return False
    return True


@jit
def _same_flags(a, b, n_groups):
    """Whether ``a[j] == b[j]`` in every group's lane."""
    for j in range(n_groups):
        if a[j] != b[j]:
            return False
    return True


@jit
def _members(group, nb, j):
    """The number of trials in group ``j``."""
    count = 0
    for b in range(nb):
        count += group[b] == j
    return count


@jit
def _users(group, use, nb, j):
    """The number of trials in group ``j`` that use the measurement."""
    count = 0
    for b in range(nb):
        count += group[b] == j and use[b]
    return count


@borrow
def _repair(P, j, indefinite_only, trials, report):
    """:func:`.linalg.repair` of group ``j``'s covariance, reported once per trial of the group
    (``trials``), as if each had been repaired; returns whether ``P`` changed."""
    if not repair(P, j, indefinite_only, report):
        return False
    report[0] += trials - 1
    return True


@borrow
def _factor(xg, P, yg, Cg, Rg, obs_g, n_obs_g, n_groups, eg, PCt_g, chol_g, scale_g, zg, nis_g,
            loglik_g, work, bad, log_det_g, group, nb, report):
    """:func:`.linalg.innovation` of every group, for its covariance (the group's mean and
    measurement are zero), repairing the covariance of a group whose ``S`` fails its
    factorization and factoring once more; then ``log det S`` in its two terms (``log_det_g``,
    for :func:`.linalg.innovation_mean`). Returns the status."""
    status = innovation(xg, P, yg, Cg, Rg, obs_g, n_obs_g, n_groups, eg, PCt_g, chol_g, scale_g,
                        zg, nis_g, loglik_g, work, bad)
    if status == NOT_POSITIVE_DEFINITE:
        for j in range(n_groups):
            if bad[j] and not _repair(P, j, False, _members(group, nb, j), report):
                return status
        status = innovation(xg, P, yg, Cg, Rg, obs_g, n_obs_g, n_groups, eg, PCt_g, chol_g,
                            scale_g, zg, nis_g, loglik_g, work, bad)
    if status == OK:
        for j in range(n_groups):  # log det S = sum log D + log prod L_aa^2
            log_det_g[0, j] = work[0, j]
            log_det_g[1, j] = math.log(work[1, j])
    return status


@jit
def _spread(source, group, nb, n_groups, out):
    """``out[a, b] = source[a, group[b]]``: each lane's copy of its group's values."""
    for a in range(out.shape[0]):
        if n_groups == 1:  # one group: a broadcast
            for b in range(nb):
                out[a, b] = source[a, 0]
        else:
            for b in range(nb):
                out[a, b] = source[a, group[b]]


@borrow
def _split_gated(use, use_g, group, nb, n_groups, slot, P, prior):
    """Move the trials that did not use the measurement out of a group that did (its covariance
    was updated): to a new group with the covariance before the update (``prior``). Returns the
    number of groups."""
    first = n_groups
    for b in range(nb):
        j = group[b]
        if use[b] or not use_g[j]:
            continue
        h = first
        while h < n_groups and slot[_PARENT, h] != j:
            h += 1
        if h == n_groups:
            n_groups += 1
            _open(slot, h, b, j, prior, j, P)
        group[b] = h
    for j in range(first):  # a group that used the measurement keeps a member that used it
        if use_g[j] and not use[slot[_MEMBER, j]]:
            b = 0
            while group[b] != j:
                b += 1
            slot[_MEMBER, j] = b
    return n_groups


@jit
def _record(x, P, group, use, n_obs, loglik, nb, n_groups, t, x_buf, P_buf, group_buf,
            loglik_buf, flag_buf):
    """Keep the block's posterior as sample ``t`` of the buffers (each trial's, and each group's,
    samples contiguous): the trials' means, the groups' covariances (as rows of ``n^2``) and
    each trial's group, its log-likelihood (0 where nothing was used) and its flag."""
    n = x.shape[0]
    for b in range(nb):
        for r in range(n):
            x_buf[b, t, r] = x[r, b]
    for j in range(n_groups):
        for r in range(n):
            for c in range(n):
                P_buf[j, t, r * n + c] = P[r, c, j]
    for b in range(nb):
        group_buf[b, t] = group[b]
        loglik_buf[b, t] = loglik[b] if use[b] and n_obs[b] > 0.0 else 0.0
        flag_buf[b, t] = ACCEPTED if use[b] else GATED


@jit
def write_out(x_buf, P_buf, group_buf, loglik_buf, flag_buf, i0, nb, k0, count, x_out, P_out,
              loglik_out, flag_out):
    """Write the ``count`` buffered samples of the block's trials out as samples ``k0 ..`` of
    the outputs, trial by trial (each trial's samples are contiguous there, as in the buffers);
    ``P_out`` holds each covariance as a row of ``n^2``."""
    for b in range(nb):
        i = i0 + b
        for t in range(count):
            k = k0 + t
            loglik_out[i, k] = loglik_buf[b, t]
            flag_out[i, k] = flag_buf[b, t]
            for r in range(x_out.shape[2]):
                x_out[i, k, r] = x_buf[b, t, r]
            j = group_buf[b, t]
            for q in range(P_out.shape[2]):
                P_out[i, k, q] = P_buf[j, t, q]
