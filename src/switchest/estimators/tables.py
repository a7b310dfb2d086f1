"""Log-likelihoods of many models' trials in one call: filters over a table of transitions.

Fitting a model (:mod:`switchest.learn`) compares candidate systems on the same record. Their
filters run together when each (candidate, trial) pair is one trial of a batch whose
transitions are indexed into one table: the trials then fill the compiled kernels' SIMD lanes,
where one record alone would leave all but one empty. These functions run such a batch and
return each sample's log-likelihood, or None when a covariance failed (a transition or a
covariance beyond the floating-point range): the caller then tells the candidates apart.
:func:`kalman_posteriors` runs one model's Kalman filter along a table a caller built (and
smooths on), so that the filter and the smoother take the same transitions.
"""

from __future__ import annotations

import numpy as np

from ..engine import GATED, OK, raise_for_status, warn_for_repairs
from ..engine.imm import IMMOutput, imm_run, imm_run_per_trial
from ..engine.kalman import KalmanOutput, kalman_run

__all__ = ["imm_logliks", "imm_posteriors", "kalman_logliks", "kalman_posteriors"]


def kalman_posteriors(y, u, F, G, Qd, trans, C, R, mode, x0, P0) -> KalmanOutput:
    """The Kalman filter's posteriors ``x (N, K, n)``, ``P`` and log-likelihoods along the
    table ``F, G, Qd`` (the arguments of :func:`switchest.engine.kalman.kalman_run`, Shankar
    et al. eqs (6)-(10)); raises the package's error for a failed covariance and warns of a
    repaired one."""
    out = kalman_run(y, u, F, G, Qd, trans, C, R, mode, x0, P0)
    raise_for_status(out.status)
    warn_for_repairs(out)
    return out


def kalman_logliks(y, u, F, G, Qd, trans, C, R, mode, x0, P0) -> np.ndarray | None:
    """Per-sample log-likelihoods ``(N, K)`` of Kalman filters along given transitions.

    The arguments are :func:`switchest.engine.kalman.kalman_run`'s: trial ``i`` predicts into
    sample ``k`` through table entry ``trans[i, k]`` and measures through ``C[mode[i, k]]``,
    ``R[mode[i, k]]`` (Shankar et al. eqs (6)-(10)). None when a filter failed; repaired
    covariances are reported by the package's ``RuntimeWarning``.
    """
    return _logliks(kalman_run(y, u, F, G, Qd, trans, C, R, mode, x0, P0))


def imm_logliks(y, u, F, G, Qd, trans, C, R, out_index, log_transition, x0, P0,
                log_prob0, *, timing: str) -> np.ndarray | None:
    """Per-sample log-likelihoods ``(N, K)`` of IMM filters, each trial under its own model.

    The arguments are :func:`switchest.engine.imm.imm_run_per_trial`'s: trial ``i``'s mode
    ``j`` moves through table entry ``trans[i, k, j]`` and measures through
    ``C[out_index[i, j]]``, its mode chain is ``log_transition[i]``. None when a filter failed.
    """
    return _logliks(imm_run_per_trial(y, u, F, G, Qd, trans, C, R, out_index, log_transition,
                                      x0, P0, log_prob0, timing=timing))


def imm_posteriors(y, u, F, G, Qd, trans, C, R, log_transition, x0, P0, log_prob0, *,
                   gate, timing: str, modes_out: bool = True) -> tuple[IMMOutput, np.ndarray]:
    """One model's IMM along the table ``F, G, Qd`` a caller built, with its mode-matched
    posteriors after every sample (the arguments of :func:`switchest.engine.imm.imm_run`,
    Bar-Shalom, Li & Kirubarajan §11.6.6; without them if not ``modes_out``), for a smoother
    that takes the same transitions, and the samples its gate rejected in every mode
    ``(N, K)``; raises the package's error for a failed covariance and warns of a repaired
    one."""
    out = imm_run(y, u, F, G, Qd, trans, C, R, log_transition, x0, P0, log_prob0, gate=gate,
                  timing=timing, modes_out=modes_out)
    raise_for_status(out.status)
    warn_for_repairs(out)
    return out, out.flag == GATED


def _logliks(out) -> np.ndarray | None:
    if out.status != OK:
        return None
    warn_for_repairs(out)
    return out.loglik
