"""The compiled interacting multiple model filter (Blom & Bar-Shalom, 1988).

``imm_run`` filters every trial over every sample inside compiled code; ``imm_step`` processes
one sample of every trial (the streaming API). Both call the C kernel ``se_filter_bank`` of
``engine/c/bank.c`` (through :mod:`._bank`), so they run the one implementation of each equation
(``engine/c/linalg.c``). Convention of switchest:
``transition[i, j]`` = P(mode j at k+1 | mode i at k), passed as its logarithm; mode
probabilities are kept as log-weights.

Mode ``j``'s transition into sample ``k`` is ``trans[k, j]`` of the table ``F (M, n, n)``,
``G (M, n, l)``, ``Qd (M, n, n)`` (irregular sample times give different entries per ``k``);
mode ``j`` is updated with ``C[j]``, ``R[j]``. The input held over the interval into sample
``k`` is ``u[:, k-1]``; sample 0 is update only. ``timing`` (:doc:`/conventions`) says which
mode's transition a mode-matched Gaussian takes into ``k``: in the ``"sample"`` timing (the
mode of sample ``k - 1`` governs the interval into ``k``) each posterior ``i`` of
sample ``k - 1`` is predicted through ``trans[k, i]`` and the predictions are then mixed; in
the ``"interval"`` timing (the default; Bar-Shalom, Li & Kirubarajan §11.6.6) the posteriors
are mixed and mode ``j``'s mixture is predicted through ``trans[k, j]``.

Gating is decided mode by mode, a gated mode getting no weight at that sample (a truncated
likelihood); a sample no mode can use counts as missing (``se_filter_bank``,
``engine/c/bank.c``).

``interaction="collapse"`` replaces the IMM's mixing by GPB1's collapse of the mode-matched
posteriors into one Gaussian (Bar-Shalom, Li & Kirubarajan §11.6.4); ``modes_out=True`` also
returns the mode-matched posteriors after each sample's update (the input of a smoother).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from typing import NamedTuple

import numpy as np

from .._checks import check_timing, positive_int
from ._arrays import all_ready, check_gate, checked, replicated
from ._bank import filter_bank
from ._parallel import MixtureOutput, run_values

__all__ = ["LANES", "MIX", "COLLAPSE", "GPB2", "Bank", "BankTable", "IMMOutput", "imm_run",
           "imm_run_per_trial", "imm_step", "is_sample_timing"]

LANES = 16  # trials per block: four AVX2 registers of float64 per row of lanes

# the interaction of filter_bank's mode-matched filters at each sample after the first
MIX = 0  # the IMM's: mode j restarts from the mixture with weights mu_{i|j}
COLLAPSE = 1  # GPB1's: every mode restarts from the one Gaussian of all modes' mixture

GPB2 = "gpb2"  # not an interaction of filter_bank: :class:`Bank` runs GPB2's kernel instead

_INTERACTIONS = {"mix": MIX, "collapse": COLLAPSE}


@dataclass
class IMMOutput(MixtureOutput):
    """The IMM's estimates (:func:`imm_run`, and :func:`imm_step` as ``K = 1``): ``x``, ``P``
    of the mixture of the mode-matched posteriors, their mode probabilities and most probable
    mode (:class:`MixtureOutput`), and

    Attributes
    ----------
    loglik : ndarray, shape (N, K)
        Log of the total likelihood ``sum_j c_j Lambda_j`` of the measurement given the past.
    flag : ndarray of uint8, shape (N, K)
        ``ACCEPTED`` (0), ``GATED`` (1: treated as missing) or ``PARTLY_GATED`` (2).
    status, repaired, smallest_eigenvalue
        The kernel's report (:class:`~switchest.engine.Reported`).
    x_modes : ndarray, shape (N, K, L, n), or None
        The mode-matched posterior means after each sample's update, where asked for
        (``modes_out=True``).
    P_modes : ndarray, shape (N, K, L, n, n), or None
        Their covariances.
    """

    loglik: np.ndarray
    flag: np.ndarray
    x_modes: np.ndarray | None = None
    P_modes: np.ndarray | None = None


def imm_run(y, u, F, G, Qd, trans, C, R, log_transition, x0, P0, log_prob0, *,
            gate=math.inf, lanes: int = LANES, interaction: str = "mix",
            timing: str = "interval", modes_out: bool = False) -> IMMOutput:
    """IMM filter of ``N`` trials over ``K`` samples (Bar-Shalom, Li & Kirubarajan §11.6.6),
    or GPB1 (``interaction="collapse"``, §11.6.4).

    Parameters
    ----------
    y : array_like, shape (N, K, m)
        Measurements; a NaN component is missing.
    u : array_like, shape (N, K, l)
        Inputs; ``u[:, k-1]`` is held over the interval into sample ``k``.
    F, G, Qd : array_like, shapes (M, n, n), (M, n, l), (M, n, n)
        Table of exact transitions.
    trans : array_like of int, shape (K, L)
        ``trans[k, j]``: the transition of mode ``j`` into sample ``k`` (row 0 unused).
    C, R : array_like, shapes (L, m, n), (L, m, m)
        Output matrix and measurement-noise covariance of each mode.
    log_transition : array_like, shape (L, L)
        ``log transition[i, j]``, ``-inf`` for an impossible switch.
    x0, P0 : array_like, shapes (n,), (n, n)
        Prior of every mode-matched filter at the first sample.
    log_prob0 : array_like, shape (L,)
        Log prior mode probabilities at the first sample.
    gate : float
        Largest normalized innovation squared a mode accepts (``inf``: no gate).
    lanes : int
        Trials per SIMD block (the results do not depend on it).
    interaction : {"mix", "collapse"}
        Into each sample, mode ``j`` restarts from the IMM's mixture with weights
        ``mu_{i|j} = pi_ij mu_i / c_j`` (``"mix"``) or, for GPB1, from the one Gaussian with
        the moments of all modes' mixture, ``mu_{i|j} = mu_i`` (``"collapse"``); the predicted
        mode probabilities ``c_j = sum_i pi_ij mu_i`` are the same.
    timing : {"sample", "interval"}
        Where the interaction falls (``se_filter_bank``, ``engine/c/bank.c``): after each
        mode-matched posterior is predicted through its own transition (``"sample"``), or
        before mode ``j``'s mixture is predicted through mode ``j``'s (``"interval"``,
        Bar-Shalom's, the default).
    modes_out : bool
        Whether to return the mode-matched posteriors after each sample's update
        (``IMMOutput.x_modes``, ``P_modes``; None otherwise).
    """
    sizes: dict[str, int] = {}
    y, u, F, G, Qd, C, trans, R, log_transition, x0, P0, log_prob0 = checked(
        sizes, "y:NKm u:NKl F:Mnn G:Mnl Qd:Mnn C:Lmn trans:KL<M R:Lmm log_transition:LL x0:n "
        "P0:nn log_prob0:L", y, u, F, G, Qd, C, trans, R, log_transition, x0, P0, log_prob0)
    N, L = sizes["N"], sizes["L"]
    output, _ = _bank(y, u, F, G, Qd, trans[None], C, R, np.arange(L)[None, None],
                      log_transition[None], replicated(x0, (N, L)), replicated(P0, (N, L)),
                      replicated(log_prob0, (N,)), _interaction(interaction),
                      is_sample_timing(timing), False, check_gate(gate),
                      positive_int(lanes, "lanes"), bool(modes_out))
    return output


def imm_run_per_trial(y, u, F, G, Qd, trans, C, R, out_index, log_transition, x0, P0, log_prob0,
                      *, gate=math.inf, timing: str = "interval") -> IMMOutput:
    """The IMM of :func:`imm_run` with a model of its own for each trial: its transitions,
    output matrices, noises and mode transition matrix (e.g. one record filtered under many
    candidate parameters at once, the trials then filling the SIMD lanes).

    Parameters
    ----------
    trans : array_like of int, shape (N, K, L)
        ``trans[i, k, j]``: the entry of the table ``F``, ``G``, ``Qd`` that mode ``j`` of
        trial ``i`` moves through into sample ``k`` (``[:, 0]`` unused).
    C, R : array_like, shapes (M', m, n), (M', m, m)
        Table of output matrices and measurement-noise covariances.
    out_index : array_like of int, shape (N, L)
        ``out_index[i, j]``: the entry of ``C``, ``R`` that mode ``j`` of trial ``i`` measures
        through.
    log_transition : array_like, shape (N, L, L)
        Each trial's ``log transition[i, j]``.

    The other arguments as in :func:`imm_run` (interaction ``"mix"``).
    """
    sizes: dict[str, int] = {}
    y, u, F, G, Qd, C, R, trans, out_index, log_transition, x0, P0, log_prob0 = checked(
        sizes, "y:NKm u:NKl F:Mnn G:Mnl Qd:Mnn C:Smn R:Smm trans:NKL<M out_index:NL<S "
        "log_transition:NLL x0:n P0:nn log_prob0:L", y, u, F, G, Qd, C, R, trans, out_index,
        log_transition, x0, P0, log_prob0)
    N, L = sizes["N"], sizes["L"]
    output, _ = _bank(y, u, F, G, Qd, trans, C, R, out_index[:, None], log_transition,
                      replicated(x0, (N, L)), replicated(P0, (N, L)),
                      replicated(log_prob0, (N,)), MIX, is_sample_timing(timing), False,
                      check_gate(gate), LANES, False)
    return output


def imm_step(x, P, log_prob, y, u, F, G, Qd, trans, C, R, log_transition, *,
             predict_first: bool, gate=math.inf, interaction: str = "mix",
             timing: str = "interval") -> tuple[IMMOutput, tuple[np.ndarray, ...]]:
    """One sample of every trial: mix (or collapse) and predict, in the order of ``timing``
    (when ``predict_first``), then update.

    ``x (N, L, n)``, ``P (N, L, n, n)``, ``log_prob (N, L)`` are the mode-matched posteriors
    at the previous sample, ``y (N, m)``, ``u (N, l)``, ``trans (L,)`` the transition of each
    mode into this sample; the rest as in :func:`imm_run`, whose compiled kernel runs this
    one sample, with the same ``interaction`` and ``timing``. Inputs are not modified.

    Returns
    -------
    output : IMMOutput
        What the IMM reports for this sample, each array with a sample axis of length 1.
    state : tuple of ndarray
        ``x``, ``P``, ``log_prob`` after this sample, shaped as given: the state to continue
        from.
    """
    sizes: dict[str, int] = {}
    x, P, log_prob, y, u, F, G, Qd, trans, C, R, log_transition = checked(
        sizes, "x:NLn P:NLnn log_prob:NL y:Nm u:Nl F:Mnn G:Mnl Qd:Mnn trans:L<M C:Lmn R:Lmm "
        "log_transition:LL", x, P, log_prob, y, u, F, G, Qd, trans, C, R, log_transition)
    return _bank(y[:, None], u[:, None], F, G, Qd, trans[None, None], C, R,
                 np.arange(sizes["L"])[None, None], log_transition[None], x, P, log_prob,
                 _interaction(interaction), is_sample_timing(timing), bool(predict_first),
                 check_gate(gate), LANES, False)


def _interaction(name) -> int:
    """The bank's code for the interaction called ``name``."""
    if not isinstance(name, str) or name not in _INTERACTIONS:
        raise ValueError(f"interaction must be one of {tuple(_INTERACTIONS)}, got {name!r}")
    return _INTERACTIONS[name]


def is_sample_timing(timing) -> bool:
    """Whether ``timing`` (checked: "sample" or "interval") is the ``"sample"`` timing: the
    kernels take it as a bool."""
    return check_timing(timing) == "sample"


def _bank(y, u, F, G, Qd, trans, C, R, out_index, log_transition, x_init, P_init,
          log_prob_init, interaction, sample_timing, predict_first, gate, lanes, modes_out,
          transition=None):
    """The bank kernel (``se_filter_bank``, ``engine/c/bank.c``: ``trans``, ``out_index``,
    ``log_transition`` shared by the trials where their first axis has length 1); returns the
    :class:`IMMOutput` (with the mode-matched posteriors of every sample if ``modes_out``)
    and the mode-matched state ``(x, P, log_prob)`` after the last sample. ``transition`` is
    ``exp(log_transition)`` where the caller holds it already."""
    N, K, _ = y.shape
    L, n = x_init.shape[1], x_init.shape[2]
    x, P, prob, mode, loglik, flag, x_modes, P_modes = outputs(N, K, L, n, modes_out)
    last = np.empty_like(x_init), np.empty_like(P_init), np.empty_like(log_prob_init)
    if transition is None:
        transition = np.exp(log_transition)
    mine, shared = True, False  # per-trial arrays, sliced to each thread's trials; the rest
    # (an array whose first axis of length 1 serves every trial is shared)
    outcome = run_values(filter_bank, (
        y, u, F, G, Qd, trans, C, R, out_index, transition, log_transition, x_init, P_init,
        log_prob_init, interaction, sample_timing, predict_first, gate, lanes, x, P, prob, mode,
        loglik, flag, x_modes, P_modes, *last), (
        mine, mine, shared, shared, shared, len(trans) > 1, shared, shared, len(out_index) > 1,
        len(transition) > 1, len(log_transition) > 1, mine, mine, mine, shared, shared, shared,
        shared, shared, mine, mine, mine, mine, mine, mine, modes_out, modes_out, mine, mine,
        mine), trials=N, samples=K, block=lanes)
    modes = (x_modes, P_modes) if modes_out else (None, None)
    return IMMOutput(x, P, prob, mode, loglik, flag, *modes, **outcome._asdict()), last


def outputs(N: int, K: int, L: int, n: int, modes_out: bool) -> tuple[np.ndarray, ...]:
    """New arrays for what the bank kernels write for ``N`` trials over ``K`` samples: ``x``,
    ``P``, ``prob``, ``mode``, ``loglik``, ``flag`` and the mode-matched posteriors (of zero size,
    not written, unless ``modes_out``)."""
    x_modes, P_modes = (np.empty((N, K, L, n)), np.empty((N, K, L, n, n))) if modes_out \
        else _no_modes(n)
    return (np.empty((N, K, n)), np.empty((N, K, n, n)), np.empty((N, K, L)),
            np.empty((N, K), dtype=np.int64), np.empty((N, K)), np.empty((N, K), dtype=np.uint8),
            x_modes, P_modes)


@lru_cache(maxsize=16)
def _no_modes(n: int) -> tuple[np.ndarray, np.ndarray]:
    """The zero-size mode-matched outputs ``(0, 0, 0, n)``, ``(0, 0, 0, n, n)``: nothing is
    written into them, so one pair serves every call."""
    return np.empty((0, 0, 0, n)), np.empty((0, 0, 0, n, n))


class BankTable(NamedTuple):
    """A table of transitions checked against a :class:`Bank` (:meth:`Bank.table`): ``F``,
    ``G``, ``Qd`` and ``trans`` as the kernels take them (``(1, K, L)`` for a record,
    ``(1, 1, L)`` for one sample), with the sizes they bound."""

    F: np.ndarray
    G: np.ndarray
    Qd: np.ndarray
    trans: np.ndarray
    sizes: dict


class Bank:
    """The configuration of a bank of mode-matched filters, checked and converted once: the
    output matrices ``C (L, m, n)``, noises ``R (L, m, m)``, ``log_transition (L, L)``, the
    prior ``x0 (n,)``, ``P0 (n, n)``, ``log_prob0 (L,)`` of every mode, the ``interaction``
    (``"mix"``, ``"collapse"`` or :data:`GPB2`, the kernel of :mod:`.gpb`), ``timing``,
    ``gate`` and ``lanes``. :meth:`run` and :meth:`step` then check only what changes between
    calls (the measurements, inputs and state) and call the kernel :func:`imm_run`,
    :func:`imm_step` (or :func:`.gpb.gpb2_run`, :func:`.gpb.gpb2_step`) call, on the same
    arrays. The arrays given are not modified; keep them unchanged while the bank is used.
    """

    def __init__(self, C, R, log_transition, x0, P0, log_prob0, *, gate=math.inf,
                 interaction: str = "mix", timing: str = "interval", lanes: int = LANES):
        sizes: dict[str, int] = {}
        self.C, self.R, self.log_transition, self.x0, self.P0, self.log_prob0 = checked(
            sizes, "C:Lmn R:Lmm log_transition:LL x0:n P0:nn log_prob0:L", C, R,
            log_transition, x0, P0, log_prob0)
        self.sizes = sizes
        self.gpb2 = interaction == GPB2
        self.interaction = None if self.gpb2 else _interaction(interaction)
        self.sample_timing = is_sample_timing(timing)
        self.gate = check_gate(gate)
        self.lanes = positive_int(lanes, "lanes")
        L, n = sizes["L"], sizes["n"]
        self._shared_log_transition = self.log_transition[None]
        self._transition = np.exp(self._shared_log_transition)
        self._out_index = np.arange(L)[None, None]
        self._step_sizes = L, n, sizes["m"]

    def table(self, F, G, Qd, trans) -> BankTable:
        """``F (M, n, n)``, ``G (M, n, l)``, ``Qd (M, n, n)`` checked, with ``trans (K, L)``
        (for :meth:`run`) or ``(L,)`` (for :meth:`step`) indexing them."""
        sizes = dict(self.sizes)
        record = np.ndim(trans) == 2
        F, G, Qd, trans = checked(sizes, "F:Mnn G:Mnl Qd:Mnn " + ("trans:KL<M" if record
                                                                  else "trans:L<M"),
                                  F, G, Qd, trans)
        return BankTable(F, G, Qd, trans[None] if record else trans[None, None], sizes)

    def run(self, y, u, table: BankTable, *, modes_out: bool = False) -> IMMOutput:
        """The filter of ``y (N, K, m)``, ``u (N, K, l)`` over a record's ``table``, from the
        prior: :func:`imm_run`."""
        if "K" not in table.sizes:
            raise ValueError("a table of one sample (trans of shape (L,)) serves step, not run")
        sizes = dict(table.sizes)
        y, u = checked(sizes, "y:NKm u:NKl", y, u)
        N, L = sizes["N"], sizes["L"]
        output, _ = self._kernel(y, u, table, replicated(self.x0, (N, L)),
                                 replicated(self.P0, (N, L)), replicated(self.log_prob0, (N,)),
                                 False, self.lanes, bool(modes_out))
        return output

    def step(self, x, P, log_prob, y, u, table: BankTable, *,
             predict_first: bool) -> tuple[IMMOutput, tuple[np.ndarray, ...]]:
        """One sample of every trial from the mode-matched state ``x (N, L, n)``,
        ``P (N, L, n, n)``, ``log_prob (N, L)`` with ``y (N, m)``, ``u (N, l)`` over a
        one-sample ``table``: :func:`imm_step`."""
        if "K" in table.sizes:
            raise ValueError("a record's table (trans of shape (K, L)) serves run, not step")
        values = (x, P, log_prob, y, u)
        N = x.shape[0] if type(x) is np.ndarray and x.ndim else -1
        (L, n, m), l = self._step_sizes, table.sizes["l"]
        if not all_ready(values, ((N, L, n), (N, L, n, n), (N, L), (N, m), (N, l))):
            x, P, log_prob, y, u = checked(dict(table.sizes), "x:NLn P:NLnn log_prob:NL y:Nm u:Nl",
                                           *values)
        return self._kernel(y[:, None], u[:, None], table, x, P, log_prob, bool(predict_first),
                            LANES, False)

    def _kernel(self, y, u, table, x_init, P_init, log_prob_init, predict_first, lanes,
                modes_out):
        if self.gpb2:
            from .gpb import _gpb2  # (gpb imports this module)

            return _gpb2(y, u, table.F, table.G, table.Qd, table.trans, self.C, self.R,
                         self.log_transition, x_init, P_init, log_prob_init, self.sample_timing,
                         predict_first, self.gate, lanes, modes_out)
        return _bank(y, u, table.F, table.G, table.Qd, table.trans, self.C, self.R,
                     self._out_index, self._shared_log_transition, x_init, P_init,
                     log_prob_init, self.interaction, self.sample_timing, predict_first,
                     self.gate, lanes, modes_out, self._transition)
