"""Exact transitions at any switching instant, without a matrix exponential per instant.

Over a segment of length ``s`` in mode ``i`` the continuous system gives ``Phi_i(s)``,
``Gamma_i(s) = int_0^s exp(A_i r) dr B_i`` and ``Qd_i(s) = int_0^s exp(A_i r) Q_i exp(A_i' r) dr``
(the blocks of Shankar et al. eqs (3)-(5)). Once per mode and interval length ``T`` the
:class:`DyadicTable` holds them at ``T / 2^k`` for ``k = 0..D`` (Van Loan, through
:func:`switchest.discretize.interval`). Any length ``s`` is then ``q T / 2^D + r`` with
``0 <= r < T / 2^D``: the segment is the flow over ``r`` followed by the table entries of the
set bits of ``q``, composed exactly by the semigroup property

    ``Phi = Phi_b Phi_a``,  ``Gamma = Phi_b Gamma_a + Gamma_b``,
    ``Qd = Phi_b Qd_a Phi_b' + Qd_b``

(the segments of one mode commute, so the order of the bits does not matter). The remainder
``r`` is short, ``||A_i|| r <= 2^-10``, and its flow is the Taylor series
``Phi(r) = sum_j (A r)^j / j!``, ``Gamma(r) = sum_j A^j r^(j+1) / (j+1)! B``,
``Qd(r) = sum_j M_j r^(j+1) / (j+1)!`` with ``M_0 = Q``, ``M_j = A M_(j-1) + M_(j-1) A'``
(the derivatives of ``exp(A r) Q exp(A' r)`` at 0), truncated after the term of order
``ORDER = 5``: the first omitted term is below ``(2^-10)^6 / 6! < 1e-20`` of the sum, so the
result is exact to rounding at the instant given, not at a quantized one.

A switched interval is a sequence of such segments, composed the same way: the exact
transition of :func:`switchest.discretize.interval` at a few dozen small matrix products
instead of an ``expm`` of a ``(2n + l)``-square block. :func:`interval_transitions` does it in
compiled code for many intervals at once (the clairvoyant filter's switched intervals, a
switching-time search's probes).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numba import njit

from ._checks import check_finite, float_array, int_array, positive_scalar
from ._jit import jit
from .discretize import Transition, interval
from .system import SwitchedLinearSystem

__all__ = ["DyadicTable", "dyadic_table", "interval_transitions"]

ORDER = 5  # Taylor terms of the remainder's flow beyond the constant one
_REMAINDER_REACH = 2.0**-10  # largest ||A|| r of a remainder
# the small loops of a composition, inlined into it: a call passing arrays costs about as much
# as their arithmetic on a few states (a call each ran the composition 20 % slower at n = 2)
_inline = njit(cache=True, error_model="numpy", inline="always")


@dataclass(frozen=True, eq=False)
class DyadicTable:
    """Per-mode flows over ``T / 2^k``, ``k = 0..depth``, and the generators.

    Attributes
    ----------
    T : float
        The interval length.
    depth : int
        ``D``: the finest table entry is ``T / 2^D``, with ``||A_i|| T / 2^D <= 2^-10``.
    Phi, Gamma, Qd : ndarray, shapes (L, D+1, n, n), (L, D+1, n, l), (L, D+1, n, n)
        ``Phi_i(T / 2^k)`` etc.
    A, B, Q : ndarray
        The modes' generators, for the Taylor series of the remainder.
    """

    T: float
    depth: int
    Phi: np.ndarray
    Gamma: np.ndarray
    Qd: np.ndarray
    A: np.ndarray
    B: np.ndarray
    Q: np.ndarray


def dyadic_table(system: SwitchedLinearSystem, T: float) -> DyadicTable:
    """The :class:`DyadicTable` of a continuous-time ``system`` for intervals of length ``T``
    (cached on ``(system, T)``)."""
    if not isinstance(system, SwitchedLinearSystem):
        raise TypeError(f"system must be a SwitchedLinearSystem, got {type(system).__name__}")
    if not system.is_continuous:
        raise ValueError("a dyadic table needs a continuous-time system (switches inside "
                         "intervals)")
    return _table(system, positive_scalar(T, "T"))


@lru_cache(maxsize=64)
def _table(system: SwitchedLinearSystem, T: float) -> DyadicTable:
    reach = float(np.max(np.linalg.norm(system.A, ord=2, axis=(1, 2)))) * T
    depth = max(0, math.ceil(math.log2(reach / _REMAINDER_REACH))) if reach > 0 else 0
    h = T / 2.0 ** np.arange(depth + 1)
    modes = np.arange(system.n_modes)[:, None, None]
    tr = interval(system, h[None, :], modes)  # (L, D+1): Van Loan, the module's exponentials
    # writeable C-contiguous copies: the one array type the kernel is compiled for
    arrays = (np.array(a, order="C") for a in (tr.F, tr.G, tr.Qd, system.A, system.B, system.Q))
    return DyadicTable(T, depth, *arrays)


def interval_transitions(table: DyadicTable, modes, offsets) -> Transition:
    """Exact transitions over intervals of length ``table.T`` with switches inside.

    Parameters
    ----------
    table : DyadicTable
    modes : array_like of int, shape (M, S+1)
        Mode of each segment of each interval.
    offsets : array_like, shape (M, S)
        Switching instants from the start of each interval, non-decreasing, in
        ``[0, table.T]``.

    Returns
    -------
    Transition
        ``F (M, n, n)``, ``G (M, n, l)``, ``Qd (M, n, n)``: those of
        :func:`switchest.discretize.interval` (Shankar et al. eqs (3)-(5) with S switches),
        to rounding.
    """
    if not isinstance(table, DyadicTable):
        raise TypeError(f"table must be a DyadicTable, got {type(table).__name__}")
    L = table.Phi.shape[0]
    modes = np.ascontiguousarray(int_array(modes, "modes", ndim=2), dtype=np.int64)
    offsets = np.ascontiguousarray(float_array(offsets, "offsets", ndim=2))
    if modes.shape[1] == 0 or offsets.shape != (modes.shape[0], modes.shape[1] - 1):
        raise ValueError(f"modes must have shape (M, S+1) and offsets (M, S), got {modes.shape} "
                         f"and {offsets.shape}")
    if modes.size and (modes.min() < 0 or modes.max() >= L):
        raise ValueError(f"modes must be in 0..{L - 1}, got {modes.min()}..{modes.max()}")
    check_finite(offsets, "offsets")
    if np.any(offsets < 0) or np.any(offsets > table.T) or np.any(np.diff(offsets) < 0):
        raise ValueError(f"offsets must be non-decreasing within [0, T] = [0, {table.T:g}]")
    M, n, n_in = modes.shape[0], table.Phi.shape[2], table.Gamma.shape[3]
    F, G, Qd = np.empty((M, n, n)), np.empty((M, n, n_in)), np.empty((M, n, n))
    _intervals(table.Phi, table.Gamma, table.Qd, table.A, table.B, table.Q, table.T,
               table.depth, modes, offsets, F, G, Qd)
    return Transition(F, G, Qd)


@jit
def _intervals(Phi, Gamma, Qd, A, B, Q, T, depth, modes, offsets, F_out, G_out, Qd_out):
    """Compose every interval's segments (the module docstring's recursions)."""
    M, S1 = modes.shape
    n, n_in = Phi.shape[2], Gamma.shape[3]
    F, G, W = np.empty((n, n)), np.empty((n, n_in)), np.empty((n, n))
    Fs, Gs, Ws = np.empty((n, n)), np.empty((n, n_in)), np.empty((n, n))
    scratch = np.empty((3, n, max(n, n_in)))
    for i in range(M):
        _identity(F, G, W)
        start = 0.0
        for s in range(S1):
            end = offsets[i, s] if s < S1 - 1 else T
            _segment(Phi, Gamma, Qd, A, B, Q, T, depth, modes[i, s], max(end - start, 0.0),
                     Fs, Gs, Ws, scratch)
            _compose(F, G, W, Fs, Gs, Ws, scratch)
            start = end
        F_out[i] = F
        G_out[i] = G
        for r in range(n):  # symmetric to the last bit, as discretize returns it
            for c in range(n):
                Qd_out[i, r, c] = 0.5 * (W[r, c] + W[c, r])


@jit
def _identity(F, G, W):
    F[:] = 0.0
    G[:] = 0.0
    W[:] = 0.0
    for r in range(F.shape[0]):
        F[r, r] = 1.0


@jit
def _segment(Phi, Gamma, Qd, A, B, Q, T, depth, mode, s, F, G, W, scratch):
    """The flow of ``mode`` over a segment of length ``0 <= s <= T``: the Taylor series of the
    remainder, then the table entries of the bits of ``q = floor(s 2^D / T)``."""
    unit = T / 2.0**depth
    q = min(int(s / unit), 2**depth)
    _taylor(A[mode], B[mode], Q[mode], max(s - q * unit, 0.0), F, G, W, scratch)
    for k in range(depth + 1):
        if (q >> (depth - k)) & 1:
            _compose(F, G, W, Phi[mode, k], Gamma[mode, k], Qd[mode, k], scratch)


@jit
def _taylor(A, B, Q, r, F, G, W, scratch):
    """``Phi(r)``, ``Gamma(r)``, ``Qd(r)`` of one mode by their Taylor series to ``ORDER``
    (the module docstring), for ``||A|| r <= 2^-10``. ``scratch (3, n, n)``."""
    n, n_in = A.shape[0], B.shape[1]
    P, Mj, T = scratch[0], scratch[1], scratch[2]  # A^j r^j / j!, M_j r^j / j!, temporary
    _identity(F, G, W)
    for a in range(n):
        for c in range(n):
            P[a, c] = F[a, c]
            Mj[a, c] = Q[a, c]
            W[a, c] = Q[a, c] * r
        for c in range(n_in):
            G[a, c] = B[a, c] * r
    for j in range(1, ORDER + 1):
        f, g = r / j, r / (j + 1)
        for a in range(n):  # P <- A P r / j
            for c in range(n):
                v = 0.0
                for k in range(n):
                    v += A[a, k] * P[k, c]
                T[a, c] = v * f
        for a in range(n):
            for c in range(n):
                P[a, c] = T[a, c]
                F[a, c] += T[a, c]
        for a in range(n):  # M <- (A M + M A') r / j
            for c in range(n):
                v = 0.0
                for k in range(n):
                    v += A[a, k] * Mj[k, c] + Mj[a, k] * A[c, k]
                T[a, c] = v * f
        for a in range(n):
            for c in range(n):
                Mj[a, c] = T[a, c]
                W[a, c] += T[a, c] * g
        for a in range(n):  # G += P B r / (j + 1)
            for c in range(n_in):
                v = 0.0
                for k in range(n):
                    v += P[a, k] * B[k, c]
                G[a, c] += v * g


@jit
def _compose(F, G, W, Fb, Gb, Wb, scratch):
    """``(F, G, W)`` followed by ``(Fb, Gb, Wb)``, in place: ``F <- Fb F``,
    ``G <- Fb G + Gb``, ``W <- Fb W Fb' + Wb``. ``scratch (3, n, n)``."""
    n = F.shape[0]
    T, U = scratch[0], scratch[1]
    for a in range(n):
        for c in range(n):
            v, w = 0.0, 0.0
            for k in range(n):
                v += Fb[a, k] * F[k, c]
                w += Fb[a, k] * W[k, c]
            T[a, c] = v
            U[a, c] = w
    _copy(T, F)
    _add_product(Gb, Fb, G, T)  # Fb G + Gb
    _copy(T, G)
    _add_product(Wb, U, Fb.T, W)  # (Fb W) Fb' + Wb


@_inline
def _add_product(start, X, Y, out):
    """``out = start + X Y`` on the shape of ``start``, each entry summed onto ``start`` in
    the order of the inner index (``out``, which may be larger, is neither ``X`` nor ``Y``)."""
    rows, cols = start.shape
    for a in range(rows):
        for c in range(cols):
            v = start[a, c]
            for k in range(Y.shape[0]):
                v += X[a, k] * Y[k, c]
            out[a, c] = v


@_inline
def _copy(source, target):
    """``target`` takes the leading block of ``source`` of its own shape."""
    for a in range(target.shape[0]):
        for c in range(target.shape[1]):
            target[a, c] = source[a, c]
