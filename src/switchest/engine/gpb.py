"""The compiled second-order generalized pseudo-Bayesian filter, GPB2 (Bar-Shalom, Li &
Kirubarajan 2001, §11.6.5).

The state of a trial after sample ``k - 1`` is one Gaussian per mode, ``N(x_i, P_i)`` with
probability ``mu_i``. Into sample ``k`` run ``L^2`` Kalman filters, one per pair (mode ``i``
at ``k - 1``, mode ``j`` at ``k``): predicted from mode ``i``'s Gaussian and updated with
``C[j]``, ``R[j]``, with probability ``mu_ij ∝ Lambda_ij pi_ij mu_i``. The prediction goes
through the transition of the mode that governs the interval into ``k`` (the ``timing``,
:doc:`/conventions`): mode ``i``'s, ``trans[k, i]`` of the table ``F, G, Qd``, in the
``"sample"`` timing (the same for every ``j``: computed once per ``i``), mode ``j``'s,
``trans[k, j]``, in the ``"interval"`` timing (Bar-Shalom, Li & Kirubarajan §11.6.5). Each
mode's pairs are then merged into one Gaussian, ``mu_j = sum_i mu_ij``,
``mu_{i|j} = mu_ij / mu_j``,
``x_j = sum_i mu_{i|j} x_ij``, ``P_j = sum_i mu_{i|j} (P_ij + (x_ij - x_j)(x_ij - x_j)')``,
and the output is the moments of the mixture over ``j`` (as the IMM's). Sample 0 has only
the prior: ``L`` filters, mode ``j``'s from its prior Gaussian with probability ``mu_j(0)``
(the first sample of ``se_filter_bank``, ``engine/c/bank.c``).

``gpb2_run`` filters every trial over every sample, ``gpb2_step`` one sample (the streaming
API); both run the C kernel ``se_gpb2_bank`` of ``engine/c/gpb.c`` (through :mod:`._bank`) on
the equations of ``engine/c/linalg.c`` (prediction, innovation, Joseph-form correction with
its information-form fallback, merging, combination), over blocks of trials laid across SIMD
lanes. Convention of switchest: ``transition[i, j]`` = P(mode j at k+1 | mode i at k), passed
as its logarithm; probabilities are log-weights.

Gating is decided pair by pair, as ``se_filter_bank`` decides it mode by mode: a pair whose
normalized innovation squared exceeds the gate, or whose likelihood is not finite, is not
updated and gets weight 0 (``PARTLY_GATED``); a sample no pair can use counts as missing (no
update, ``mu_ij ∝ pi_ij mu_i``, log-likelihood 0, ``GATED``).
"""

from __future__ import annotations

import math

import numpy as np

from .._checks import positive_int
from ._arrays import check_gate, checked, replicated
from ._bank import gpb2_bank
from ._parallel import run_values
from .imm import LANES, IMMOutput, is_sample_timing, outputs

__all__ = ["gpb2_run", "gpb2_step"]


def gpb2_run(y, u, F, G, Qd, trans, C, R, log_transition, x0, P0, log_prob0, *,
             gate=math.inf, lanes: int = LANES, timing: str = "interval",
             modes_out: bool = False) -> IMMOutput:
    """GPB2 filter of ``N`` trials over ``K`` samples (Bar-Shalom, Li & Kirubarajan §11.6.5).

    Arguments as :func:`.imm.imm_run` (``trans (K, L)``: the transition of mode ``j`` into
    sample ``k``, row 0 unused; ``x0, P0``: the prior of every mode at the first sample;
    ``timing``: the pair (``i``, ``j``) predicts through mode ``i``'s transition in the
    ``"sample"`` timing, through mode ``j``'s in the ``"interval"`` timing).
    Returns the combined estimate, ``mu_j``, the most probable mode, the log-likelihood and the
    flags as an :class:`.imm.IMMOutput`, with the merged Gaussians ``x_j``, ``P_j`` after each
    sample if ``modes_out``.
    """
    sizes: dict[str, int] = {}
    y, u, F, G, Qd, C, trans, R, log_transition, x0, P0, log_prob0 = checked(
        sizes, "y:NKm u:NKl F:Mnn G:Mnl Qd:Mnn C:Lmn trans:KL<M R:Lmm log_transition:LL x0:n "
        "P0:nn log_prob0:L", y, u, F, G, Qd, C, trans, R, log_transition, x0, P0, log_prob0)
    N, L = sizes["N"], sizes["L"]
    output, _ = _gpb2(y, u, F, G, Qd, trans[None], C, R, log_transition,
                      replicated(x0, (N, L)), replicated(P0, (N, L)),
                      replicated(log_prob0, (N,)), is_sample_timing(timing), False,
                      check_gate(gate), positive_int(lanes, "lanes"), bool(modes_out))
    return output


def gpb2_step(x, P, log_prob, y, u, F, G, Qd, trans, C, R, log_transition, *,
              predict_first: bool, gate=math.inf,
              timing: str = "interval") -> tuple[IMMOutput, tuple[np.ndarray, ...]]:
    """One sample of every trial: the ``L^2`` pairs predicted (in the ``timing`` of
    :func:`gpb2_run`) and updated, then merged (when ``predict_first``; else the ``L`` modes
    updated), as :func:`.imm.imm_step`.

    ``x (N, L, n)``, ``P (N, L, n, n)``, ``log_prob (N, L)`` are the merged Gaussians and log
    mode probabilities at the previous sample, ``y (N, m)``, ``u (N, l)``, ``trans (L,)`` the
    transition of each mode into this sample. Returns the :class:`.imm.IMMOutput` of this
    sample (a sample axis of length 1) and the state ``(x, P, log_prob)`` after it.
    """
    sizes: dict[str, int] = {}
    x, P, log_prob, y, u, F, G, Qd, trans, C, R, log_transition = checked(
        sizes, "x:NLn P:NLnn log_prob:NL y:Nm u:Nl F:Mnn G:Mnl Qd:Mnn trans:L<M C:Lmn R:Lmm "
        "log_transition:LL", x, P, log_prob, y, u, F, G, Qd, trans, C, R, log_transition)
    return _gpb2(y[:, None], u[:, None], F, G, Qd, trans[None, None], C, R, log_transition,
                 x, P, log_prob, is_sample_timing(timing), bool(predict_first),
                 check_gate(gate), LANES, False)


def _gpb2(y, u, F, G, Qd, trans, C, R, log_transition, x_init, P_init, log_prob_init,
          sample_timing, predict_first, gate, lanes, modes_out):
    """The C kernel ``se_gpb2_bank`` (:func:`._bank.gpb2_bank`) on checked arrays: the
    :class:`.imm.IMMOutput` and the merged state ``(x, P, log_prob)`` after the last sample."""
    N, K, _ = y.shape
    L, n = x_init.shape[1], x_init.shape[2]
    x, P, prob, mode, loglik, flag, x_modes, P_modes = outputs(N, K, L, n, modes_out)
    last = np.empty_like(x_init), np.empty_like(P_init), np.empty_like(log_prob_init)
    mine, shared = True, False  # per-trial arrays, sliced to each thread's trials; the rest
    # (``trans`` with a first axis of length 1 serves every trial; ``log_transition (L, L)``
    # is one table for all)
    outcome = run_values(gpb2_bank, (
        y, u, F, G, Qd, trans, C, R, log_transition, x_init, P_init, log_prob_init,
        sample_timing, predict_first, gate, lanes, x, P, prob, mode, loglik, flag, x_modes,
        P_modes, *last), (
        mine, mine, shared, shared, shared, len(trans) > 1, shared, shared, shared, mine, mine,
        mine, shared, shared, shared, shared, mine, mine, mine, mine, mine, mine, modes_out,
        modes_out, mine, mine, mine), trials=N, samples=K, block=lanes)
    modes = (x_modes, P_modes) if modes_out else (None, None)
    return IMMOutput(x, P, prob, mode, loglik, flag, *modes, **outcome._asdict()), last
