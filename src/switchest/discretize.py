r"""Exact sampled-data transitions, with switches anywhere inside a sample interval.

Over an interval of length :math:`T` that starts in ``modes[0]`` and switches to
``modes[s]`` at offset ``offsets[s-1]``, the continuous system (zero-order-hold
input) gives exactly

.. math::

    x(T) = F\, x(0) + G\, u + w, \qquad w \sim \mathcal N(0, Q_d),

with, for segments :math:`s = 0, \dots, S` of lengths :math:`h_s` in modes :math:`m_s`,
:math:`F = \Phi_S \cdots \Phi_0`, :math:`\Phi_s = e^{A_{m_s} h_s}`. With one switch this is
Shankar et al. eq. (4), :math:`F_k = e^{A_{k+1}(T - t_k)}\, e^{A_k t_k}`, and :math:`G` is
eq. (5); here any number of switches is allowed, and :math:`Q_d` is the exact
covariance of the integrated process noise.

Each segment's :math:`\Phi_s`, :math:`G_s = \int_0^{h} e^{A s}\, ds\, B` and
:math:`Q_{d,s} = \int_0^{h} e^{A s} Q e^{A^\top s}\, ds` come from ONE block-matrix exponential
(Van Loan, 1978):

.. math::

    \exp\left(\begin{bmatrix} -A & Q & 0 \\ 0 & A^\top & 0 \\ 0 & B^\top & 0 \end{bmatrix} h
    \right) = \begin{bmatrix} e^{-A h} & e^{-A h} Q_{d,s} & 0 \\ 0 & \Phi_s^\top & 0 \\
    0 & G_s^\top & I \end{bmatrix},

and segments compose as :math:`F \leftarrow \Phi F`, :math:`G \leftarrow \Phi G + G_s`,
:math:`Q_d \leftarrow \Phi Q_d \Phi^\top + Q_{d,s}`. This module is the only place where
switchest takes matrix exponentials; repeated small queries are cached.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy.linalg import expm

from ._checks import check_finite, check_memory, float_array, int_array, positive_scalar
from ._linalg import symmetrize
from ._threads import one_blas_thread
from .system import SwitchedLinearSystem

__all__ = [
    "Transition",
    "distinct_steps",
    "interval",
    "switch_grid",
    "pairwise_grid",
    "pairwise_grid_nbytes",
    "mode_steps",
    "sample_mode_steps",
    "segment_transitions",
    "OFFSET_BITS",
    "OffsetTable",
    "offset_table",
    "offset_table_nbytes",
]

_CACHE_MAX_ELEMENTS = 4096
_VAN_LOAN_REACH = 4.0  # largest ||A|| h exponentiated at once (see _segments)
_EXPM_COPIES = 8  # arrays of the stacked blocks' size alive at once in expm and the compositions
OFFSET_BITS = 9  # an offset table splits T into 2^9 coarse steps, each into 2^9 fine ones
# (resolution 3.8e-6 T, under 1/25 of the refinement's tolerance; 2^11 gave 2.4e-7 T, but its
# 1 MB table for the boost converter left the core's L2 cache and cost the refined filter 15 %)


@dataclass(frozen=True, eq=False)
class Transition:
    r"""Exact one-interval transition :math:`x^+ = F x + G u + w`,
    :math:`w \sim \mathcal{N}(0, Q_d)`.

    Attributes
    ----------
    F : ndarray, shape (..., n, n)
    G : ndarray, shape (..., n, l)
    Qd : ndarray, shape (..., n, n)
        Symmetric positive semidefinite.
    """

    F: np.ndarray
    G: np.ndarray
    Qd: np.ndarray


@one_blas_thread()
def interval(system: SwitchedLinearSystem, T, modes, offsets=None) -> Transition:
    """The exact transition over one sample interval with switches inside it.

    Parameters
    ----------
    system : SwitchedLinearSystem
    T : float or array_like, shape (...)
        Interval length(s).
    modes : array_like of int, shape (..., S+1)
        Active mode on each of the S+1 segments, in order.
    offsets : array_like, shape (..., S), optional
        Switch instants measured from the start of the interval, non-decreasing,
        within :math:`[0, T]`. Omit (or pass shape ``(..., 0)``) for no switch.

    Returns
    -------
    Transition
        ``F (..., n, n)``, ``G (..., n, l)``, ``Qd (..., n, n)``, the batch shape
        being the broadcast of ``T``'s shape with the leading axes of ``modes`` and
        ``offsets`` (Shankar et al. eqs (3)-(5), generalized to S switches).

    Raises
    ------
    ValueError
        On a bad shape or value, and when the block exponentials of the whole batch
        would not fit in memory (:func:`switchest._checks.check_memory`).

    Notes
    -----
    For a discrete-time system the model passes through unchanged: :math:`F = A(m)`,
    :math:`G = B(m)`, :math:`Q_d = Q(m)`; then ``T`` must equal ``system.dt`` and no switch
    may fall inside the step.
    """
    _check_system(system)
    T = float_array(T, "T")
    check_finite(T, "T")
    if np.any(T <= 0):
        raise ValueError(f"T must be positive, got {T.min():g}")
    modes = int_array(modes, "modes")
    if modes.ndim == 0:
        raise ValueError("modes must have a last axis of length S+1 (one mode per segment), "
                         "got a scalar")
    if np.any((modes < 0) | (modes >= system.n_modes)):
        raise ValueError(f"modes must be in 0..{system.n_modes - 1}, "
                         f"got {modes.min()}..{modes.max()}")
    if offsets is None:
        offsets = np.zeros((*modes.shape[:-1], 0))
    offsets = float_array(offsets, "offsets")
    if offsets.ndim == 0 or offsets.shape[-1] != modes.shape[-1] - 1:
        raise ValueError(
            f"offsets must have a last axis of length S = {modes.shape[-1] - 1} "
            f"(one fewer than modes), got shape {offsets.shape}"
        )
    check_finite(offsets, "offsets")
    try:
        batch = np.broadcast_shapes(T.shape, modes.shape[:-1], offsets.shape[:-1])
    except ValueError:
        raise ValueError(
            f"T {T.shape}, modes {modes.shape[:-1]} (without the last axis) and offsets "
            f"{offsets.shape[:-1]} (without the last axis) must broadcast to one batch shape"
        ) from None
    if not system.is_continuous:
        return _discrete_passthrough(system, T, modes, offsets)
    _check_offsets(offsets, T[..., None])
    d = 2 * system.n_states + system.n_inputs
    check_memory(
        _EXPM_COPIES * 8 * d * d * int(np.prod(batch, dtype=float)) * modes.shape[-1],
        f"interval over a batch of shape {batch} with {modes.shape[-1]} segments "
        f"({_EXPM_COPIES} copies of one {d}x{d} block exponential per segment)",
    )
    if modes.size + offsets.size + T.size <= _CACHE_MAX_ELEMENTS:
        return _cached(system, T.tobytes(), T.shape, modes.tobytes(), modes.shape,
                       offsets.tobytes(), offsets.shape)
    return _compute(system, T, modes, offsets, batch)


def switch_grid(T: float, g: int) -> np.ndarray:
    r"""The switching-time grid of Shankar et al.'s equation (23), :math:`\tau_i = (i - 1/2) T / g`.

    The midpoints of ``g`` equal sub-intervals of :math:`[0, T)`, :math:`i = 1, \dots, g`.
    """
    T = positive_scalar(T, "T")
    if isinstance(g, (bool, np.bool_)) or not isinstance(g, (int, np.integer)):
        raise TypeError(f"g must be a positive int (number of grid points), got {type(g).__name__}")
    if g < 1:
        raise ValueError(f"g must be a positive int (number of grid points), got {g!r}")
    check_memory(8 * g, f"switch_grid with g = {g} points")
    i = np.arange(1, g + 1)
    return i * T / g - T / (2 * g)


def pairwise_grid(system: SwitchedLinearSystem, T: float, g: int) -> Transition:
    """Transitions for every mode pair and every grid switching time (cached).

    Returns arrays with batch shape ``(L, L, g)``: entry ``[i, j, k]`` switches from
    mode i to mode j at ``switch_grid(T, g)[k]``; for ``i == j`` it is the interval
    without a switch. The filters of Shankar et al. §IV evaluate eq. (23) on it at
    every step with a switch, so it is memoized on ``(system, T, g)`` like
    :func:`mode_steps`.
    """
    switch_grid(T, g)  # validates T and g before they become a cache key
    check_memory(pairwise_grid_nbytes(system, g),
                 f"pairwise_grid with g = {g} switching instants and L = {system.n_modes} modes")
    return _pairwise_grid(system, float(T), int(g))


def pairwise_grid_nbytes(system: SwitchedLinearSystem, g: int) -> int:
    """Bytes :func:`pairwise_grid` works in: the block exponentials of its :math:`2 L^2 g`
    segments.

    ``_EXPM_COPIES`` arrays of the stacked :math:`(2n + l) \\times (2n + l)` blocks are alive at
    once inside ``expm`` and the compositions; the result itself is smaller.
    """
    _check_system(system)
    L, d = system.n_modes, 2 * system.n_states + system.n_inputs
    return _EXPM_COPIES * 8 * d * d * 2 * L * L * int(g)


@lru_cache(maxsize=64)
def _pairwise_grid(system: SwitchedLinearSystem, T: float, g: int) -> Transition:
    L = system.n_modes
    tau = switch_grid(T, g)
    pairs = np.stack(np.meshgrid(np.arange(L), np.arange(L), indexing="ij"), axis=-1)
    modes = np.broadcast_to(pairs[:, :, None, :], (L, L, g, 2))
    offsets = np.broadcast_to(tau[None, None, :, None], (L, L, g, 1))
    return interval(system, T, modes, offsets)


def mode_steps(system: SwitchedLinearSystem, T: float) -> Transition:
    """Transitions without a switch, one per mode: batch shape ``(L,)`` (cached).

    Called at every filter step, so it is memoized on ``(system, T)`` directly.
    """
    _check_system(system)
    return _mode_steps(system, positive_scalar(T, "T"))


@lru_cache(maxsize=256)
def _mode_steps(system: SwitchedLinearSystem, T: float) -> Transition:
    return interval(system, T, np.arange(system.n_modes)[:, None])


STEP_ULPS = 8
"""Sampling steps closer than this many units in the last place of the largest sample time are
one step (:func:`distinct_steps`)."""


def distinct_steps(t) -> tuple[np.ndarray, np.ndarray]:
    """The distinct sampling steps of the sample times ``t (K,)``, ascending, and the index of
    each interval's step ``(K-1,)``.

    Steps that differ by at most :data:`STEP_ULPS` units in the last place of the largest
    :math:`|t|` are one step, the smallest standing for all: the times themselves carry that
    rounding (``np.arange(K) * h`` gives steps a few units apart), and each distinct step costs
    its own matrix exponentials. The transitions then differ from those of each interval's own
    rounded length by that relative amount, times :math:`\\lVert A h \\rVert`.
    """
    t = np.asarray(t, dtype=float)
    length = np.diff(t)
    if length.size == 0:
        return length, np.zeros(0, dtype=np.intp)
    order = np.argsort(length, kind="stable")
    ordered = length[order]
    tol = STEP_ULPS * np.spacing(np.abs(t).max())
    starts = [0]
    while True:  # each step stands for the steps within tol above it
        nxt = int(np.searchsorted(ordered, ordered[starts[-1]] + tol, side="right"))
        if nxt >= ordered.size:
            break
        starts.append(nxt)
    group = np.zeros(ordered.size, dtype=np.intp)
    group[starts[1:]] = 1
    which = np.empty(length.size, dtype=np.intp)
    which[order] = np.cumsum(group)
    return ordered[starts], which


def sample_mode_steps(system: SwitchedLinearSystem, t) -> tuple[Transition, np.ndarray]:
    """Every mode's transition over every distinct interval of the sample times ``t (K,)``.

    Returns the table ``(F, G, Qd)`` with batch shape ``(D L,)`` (:func:`mode_steps` of each
    distinct step :math:`h_d` of :func:`distinct_steps`, concatenated: entry :math:`d L + j` is
    mode ``j`` over :math:`h_d`) and
    ``entry (K, L)`` of int64, ``entry[k, j]`` the row of mode ``j`` over the interval into
    sample ``k`` (row 0, before the first sample, is 0 and unused): the layout the compiled
    multiple-model filters read. One sample gives a table of one unit step, never read.
    """
    t = np.asarray(t, dtype=float)
    steps, which = distinct_steps(t)
    if steps.size == 0:  # one sample: update only, the table is not read
        steps = np.ones(1)
    table = [mode_steps(system, h) for h in steps]
    L = system.n_modes
    entry = np.zeros((t.size, L), dtype=np.int64)
    entry[1:] = np.arange(L) + L * which.reshape(-1, 1)
    return Transition(*(np.concatenate([getattr(s, a) for s in table])
                        for a in ("F", "G", "Qd"))), entry


def segment_transitions(system: SwitchedLinearSystem, T: float, modes, offsets) -> Transition:
    """One transition per trial over an interval of length ``T``, batch shape ``(N,)``.

    ``modes (N, S+1)`` and ``offsets (N, S)`` describe each trial's segments, padded
    as :func:`switchest.signals.sample_segments` returns them. Trials without a
    switch reuse the cached per-mode steps; trials that share a switch pattern (a
    signal common to all trials) are discretized once.
    """
    steps = mode_steps(system, T)  # validates system and T
    T = float(T)
    modes = int_array(modes, "modes", ndim=2)
    if modes.shape[1] == 0:
        raise ValueError(f"modes must have shape (N, S+1) with S+1 >= 1, got {modes.shape}")
    if np.any((modes < 0) | (modes >= system.n_modes)):
        raise ValueError(
            f"modes must be in 0..{system.n_modes - 1}, got {modes.min()}..{modes.max()}"
        )
    offsets = float_array(offsets, "offsets", ndim=2)
    if offsets.shape != (modes.shape[0], modes.shape[1] - 1):
        raise ValueError(
            f"offsets must have shape (N, S) = ({modes.shape[0]}, {modes.shape[1] - 1}), "
            f"got {offsets.shape}"
        )
    check_finite(offsets, "offsets")  # every row, also those without a switch
    _check_offsets(offsets, T)
    m0 = modes[:, 0]
    F, G, Qd = steps.F[m0], steps.G[m0], steps.Qd[m0]  # fancy indexing: fresh copies
    switched = np.flatnonzero(np.any(modes[:, 1:] != m0[:, None], axis=1))
    if switched.size:
        pattern = np.concatenate([modes[switched], offsets[switched]], axis=1)
        unique, inverse = np.unique(pattern, axis=0, return_inverse=True)
        S1 = modes.shape[1]
        tr = interval(system, T, unique[:, :S1].astype(np.int64), unique[:, S1:])
        inverse = inverse.ravel()
        F[switched], G[switched], Qd[switched] = tr.F[inverse], tr.G[inverse], tr.Qd[inverse]
    return Transition(F, G, Qd)


def _check_system(system) -> None:
    if not isinstance(system, SwitchedLinearSystem):
        raise TypeError(f"system must be a SwitchedLinearSystem, got {type(system).__name__}")


def _check_offsets(offsets: np.ndarray, T) -> None:
    """Switch offsets lie in :math:`[0, T]` and do not decrease (``T`` broadcasts against them)."""
    if np.any(offsets < 0) or np.any(offsets > T):
        lo, hi = float(offsets.min()), float(offsets.max())
        raise ValueError(f"offsets must lie within [0, T], got {lo:g}..{hi:g}")
    if np.any(np.diff(offsets, axis=-1) < 0):
        raise ValueError("offsets must be non-decreasing along their last axis")


@lru_cache(maxsize=256)
def _cached(system, T_bytes, T_shape, m_bytes, m_shape, o_bytes, o_shape) -> Transition:
    T = np.frombuffer(T_bytes, dtype=float).reshape(T_shape)
    modes = np.frombuffer(m_bytes, dtype=np.int64).reshape(m_shape)
    offsets = np.frombuffer(o_bytes, dtype=float).reshape(o_shape)
    batch = np.broadcast_shapes(T.shape, modes.shape[:-1], offsets.shape[:-1])
    out = _compute(system, T, modes, offsets, batch)
    for arr in (out.F, out.G, out.Qd):
        arr.setflags(write=False)
    return out


def _compute(system, T, modes, offsets, batch) -> Transition:
    S1 = modes.shape[-1]
    T = np.broadcast_to(T, batch)
    modes = np.broadcast_to(modes, (*batch, S1))
    offsets = np.broadcast_to(offsets, (*batch, S1 - 1))
    bounds = np.concatenate([np.zeros((*batch, 1)), offsets, T[..., None]], axis=-1)
    h = np.diff(bounds, axis=-1)  # (..., S+1) segment lengths
    Phi, Gs, Qs = _segments(system, modes, h)
    F, G, Qd = Phi[..., 0, :, :], Gs[..., 0, :, :], Qs[..., 0, :, :]
    for s in range(1, S1):
        P = Phi[..., s, :, :]
        F = P @ F  # F <- Phi_s F
        G = P @ G + Gs[..., s, :, :]  # G <- Phi_s G + G_s
        Qd = P @ Qd @ np.swapaxes(P, -1, -2) + Qs[..., s, :, :]  # Qd <- Phi Qd Phi' + Qd_s
    _check_overflow(T, F, G, Qd)
    return Transition(np.ascontiguousarray(F), np.ascontiguousarray(G), symmetrize(Qd))


def _check_overflow(T, *parts) -> None:
    """An unstable mode over a long interval overflows: refuse it rather than return inf/NaN."""
    finite = np.logical_and.reduce([np.isfinite(p).all(axis=(-2, -1)) for p in parts])
    if not np.all(finite):
        bad = float(np.broadcast_to(T, finite.shape)[~finite].max())
        raise ValueError(
            f"the transition over T = {bad:g} overflows the floating-point range (an unstable "
            "mode over too long an interval); shorten T"
        )


def _segments(system, modes, h):
    """:math:`\\Phi`, :math:`G_s`, :math:`Q_{d,s}` for every (mode, length) pair, from one stacked
    Van Loan expm.

    The Van Loan block holds :math:`e^{-A h}`: for a fast mode (:math:`\\|A\\| h` large) it is
    so large that :math:`Q_d` drowns in its round-off (a non-normal :math:`A` with
    :math:`\\|A\\| h \\approx 10` already loses four digits). Such segments are exponentiated
    over :math:`h / 2^k`, with :math:`\\|A\\| h / 2^k \\le 4`, and doubled :math:`k` times by the
    exact recursions :math:`\\Phi(2h) = \\Phi(h)^2`, :math:`G(2h) = \\Phi(h) G(h) + G(h)`,
    :math:`Q_d(2h) = \\Phi(h) Q_d(h) \\Phi(h)^\\top + Q_d(h)` (a sum of PSD terms, so
    :math:`Q_d` stays PSD however stiff the mode).
    """
    M, q_scale, b_scale, a_norm = _van_loan_generators(system)
    n = system.n_states
    reach = float(np.max(a_norm[modes] * h, initial=0.0))
    if not np.isfinite(reach):
        raise ValueError(f"the interval T = {float(np.max(h)):g} is too long: ||A|| T overflows")
    k = int(np.ceil(np.log2(reach / _VAN_LOAN_REACH))) if reach > _VAN_LOAN_REACH else 0
    E = expm(M[modes] * (h / 2.0**k)[..., None, None])
    Phi = np.swapaxes(E[..., n : 2 * n, n : 2 * n], -1, -2)
    Qs = symmetrize(Phi @ E[..., :n, n : 2 * n]) / q_scale[modes][..., None, None]
    Gs = np.swapaxes(E[..., 2 * n :, n : 2 * n], -1, -2) / b_scale[modes][..., None, None]
    for _ in range(k):
        Qs = symmetrize(Phi @ Qs @ np.swapaxes(Phi, -1, -2) + Qs)
        Gs = Phi @ Gs + Gs
        Phi = Phi @ Phi
    return Phi, Gs, Qs


@lru_cache(maxsize=64)
def _van_loan_generators(system):
    """Per-mode block generators (Q and B rescaled to the size of A) and :math:`\\|A_i\\|`.

    Scaling the Q and B blocks by :math:`c` scales :math:`Q_{d,s}` and :math:`G_s` by :math:`c`
    exactly, and
    keeps the exponential well conditioned when, e.g., Q is tiny next to A.
    """
    n, l = system.n_states, system.n_inputs
    L = system.n_modes
    a = np.maximum(np.linalg.norm(system.A, ord=2, axis=(1, 2)), 1.0)
    q = np.linalg.norm(system.Q, ord=2, axis=(1, 2))
    b = np.linalg.norm(system.B, ord=2, axis=(1, 2)) if l else np.zeros(L)
    q_scale = np.where(q > 0, a / np.where(q > 0, q, 1.0), 1.0)
    b_scale = np.where(b > 0, a / np.where(b > 0, b, 1.0), 1.0)
    a_norm = np.linalg.norm(system.A, ord=2, axis=(1, 2))
    M = np.zeros((L, 2 * n + l, 2 * n + l))
    M[:, :n, :n] = -system.A
    M[:, :n, n : 2 * n] = system.Q * q_scale[:, None, None]
    M[:, n : 2 * n, n : 2 * n] = np.swapaxes(system.A, 1, 2)
    M[:, 2 * n :, n : 2 * n] = np.swapaxes(system.B, 1, 2) * b_scale[:, None, None]
    return M, q_scale, b_scale, a_norm


def _discrete_passthrough(system, T, modes, offsets) -> Transition:
    if offsets.shape[-1] != 0:
        raise ValueError(
            "a discrete-time system cannot switch inside a step: offsets must be empty, "
            f"got shape {offsets.shape}"
        )
    if np.any(np.abs(T - system.dt) > 1e-9 * system.dt):
        raise ValueError(f"T must equal the discrete system's dt = {system.dt:g}, "
                         f"got {T.ravel()[0]:g}")
    m = np.broadcast_to(modes[..., 0], np.broadcast_shapes(T.shape, modes.shape[:-1]))
    return Transition(system.A[m], system.B[m], system.Q[m])


@dataclass(frozen=True, eq=False)
class OffsetTable:
    """Flows from which a switch at any offset of an interval is composed exactly.

    With :math:`N = 2^{\\mathrm{OFFSET\\_BITS}}` and :math:`h = T / N^2`, an offset :math:`\\tau`
    is quantized to :math:`(j N + q) h` (:math:`0 \\le j < N`, :math:`0 \\le q \\le N`) and a
    switch from mode ``a`` to mode ``b`` there is the composition, in time order, of three
    entries of the table (Shankar et al. eq. (4),
    :math:`F = e^{A_b (T - \\tau)} e^{A_a \\tau}`, and eq. (5), with the exact process
    noise)::

        coarse[a, j],  switch[a, b, q],  coarse[b, N - 1 - j]

    composed as in the module docstring (:math:`F \\leftarrow \\Phi F`,
    :math:`G \\leftarrow \\Phi G + G_s`, :math:`Q_d \\leftarrow \\Phi Q_d \\Phi^\\top + Q_{d,s}`).

    Attributes
    ----------
    T : float
        The interval length.
    coarse : Transition
        Batch shape ``(L, N)``: mode ``i`` over :math:`j T / N`, :math:`j = 0, \\dots, N-1`.
    switch : Transition
        Batch shape ``(L, L, N + 1)``: a span :math:`T / N` that switches from mode ``a`` to
        mode ``b`` at :math:`q h`: ``a`` over :math:`q h`, then ``b`` over :math:`(N - q) h`.
    """

    T: float
    coarse: Transition
    switch: Transition


def offset_table(system: SwitchedLinearSystem, T: float) -> OffsetTable:
    """The :class:`OffsetTable` of a continuous-time ``system`` for intervals of length ``T``
    (cached on ``(system, T)``).

    The flows of one mode over :math:`q h` and :math:`j T / N` compose those over the dyadic
    lengths :math:`2^i h`, :math:`i = 0, \\dots, 2\\, \\mathrm{OFFSET\\_BITS} - 1`, of the set bits
    of :math:`q` or :math:`j N` (the flows of one mode commute), each one Van Loan exponential
    (:func:`interval`): :math:`2\\, \\mathrm{OFFSET\\_BITS}` exponentials per mode, every entry
    exact to the rounding of a dozen products. The resolution
    :math:`T / 2^{2\\, \\mathrm{OFFSET\\_BITS}}` (:math:`3.8 \\cdot 10^{-6}\\, T`) is what a switch
    offset is quantized to.
    """
    T = positive_scalar(T, "T")
    _check_system(system)
    if not system.is_continuous:
        raise ValueError("an offset table needs a continuous-time system (switches inside "
                         "intervals)")
    check_memory(offset_table_nbytes(system),
                 f"offset_table of L (N + L (N + 1)) flows (N = {2**OFFSET_BITS}, "
                 f"L = {system.n_modes} modes, n = {system.n_states} states)")
    return _offset_table(system, T)


def offset_table_nbytes(system: SwitchedLinearSystem) -> int:
    """Bytes of one :class:`OffsetTable`: :math:`L (N + L (N + 1))` flows ``(F, G, Qd)``."""
    _check_system(system)
    n, l, L, N = system.n_states, system.n_inputs, system.n_modes, 2**OFFSET_BITS
    return 8 * L * (N + L * (N + 1)) * n * (2 * n + l)


@lru_cache(maxsize=32)
def _offset_table(system: SwitchedLinearSystem, T: float) -> OffsetTable:
    N = 2**OFFSET_BITS
    lengths = T / N**2 * 2.0 ** np.arange(2 * OFFSET_BITS)  # exact: powers of two times T
    dyadic = interval(system, lengths[None, :], np.arange(system.n_modes)[:, None, None])
    F, G, Qd = _binary_table(dyadic, 0)  # mode i over q h, q = 0..N-1; then q = N: T / N
    F, G, Qd = (np.concatenate([a, b[:, OFFSET_BITS : OFFSET_BITS + 1]], axis=1)
                for a, b in zip((F, G, Qd), (dyadic.F, dyadic.G, dyadic.Qd)))
    Fa, Ga, Qa = F[:, None], G[:, None], Qd[:, None]  # a over q h, then b over (N - q) h
    Fb, Gb, Qb = F[None, :, ::-1], G[None, :, ::-1], Qd[None, :, ::-1]
    switch = Transition(Fb @ Fa, Fb @ Ga + Gb,  # F <- Phi F, G <- Phi G + G_s
                        symmetrize(Fb @ Qa @ np.swapaxes(Fb, -1, -2) + Qb))
    table = OffsetTable(T, Transition(*_binary_table(dyadic, OFFSET_BITS)), switch)
    for part in (table.coarse, table.switch):
        for arr in (part.F, part.G, part.Qd):
            arr.setflags(write=False)
    return table


def _binary_table(dyadic: Transition, first: int):
    """``F, G, Qd`` of entries :math:`q = 0, \\dots, 2^{\\mathrm{OFFSET\\_BITS}} - 1` from the
    dyadic flows ``first .. first + OFFSET_BITS - 1`` (batch ``(L, 2 OFFSET_BITS)``): entry
    :math:`q` composes the flows of the set bits of :math:`q`, built by doubling the table with
    one bit at a time."""
    L, n, l = dyadic.F.shape[0], dyadic.F.shape[-1], dyadic.G.shape[-1]
    F = np.broadcast_to(np.eye(n), (L, 1, n, n))
    G, Qd = np.zeros((L, 1, n, l)), np.zeros((L, 1, n, n))
    for i in range(first, first + OFFSET_BITS):
        Phi, Gs, Qs = dyadic.F[:, i : i + 1], dyadic.G[:, i : i + 1], dyadic.Qd[:, i : i + 1]
        F = np.concatenate([F, Phi @ F], axis=1)  # F <- Phi F
        G = np.concatenate([G, Phi @ G + Gs], axis=1)  # G <- Phi G + G_s
        Qd = np.concatenate([Qd, Phi @ Qd @ np.swapaxes(Phi, -1, -2) + Qs], axis=1)
    return np.ascontiguousarray(F), G, symmetrize(Qd)
