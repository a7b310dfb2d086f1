"""Exact transitions at any switching instant, without a matrix exponential per instant.

Over a segment of length :math:`s` in mode :math:`i` the continuous system gives
:math:`\\Phi_i(s)`, :math:`\\Gamma_i(s) = \\int_0^s e^{A_i r}\\, dr\\, B_i` and
:math:`Q_{d,i}(s) = \\int_0^s e^{A_i r} Q_i e^{A_i^\\top r}\\, dr`
(the blocks of Shankar et al. eqs (3)-(5)). Once per mode and interval length :math:`T` the
:class:`DyadicTable` holds them at :math:`T / 2^k` for :math:`k = 0, \\dots, D` (Van Loan,
through :func:`switchest.discretize.interval`). Any length :math:`s` is then
:math:`q T / 2^D + r` with :math:`0 \\le r < T / 2^D`: the segment is the flow over :math:`r`
followed by the table entries of the set bits of :math:`q`, composed exactly by the semigroup
property

.. math::

    \\Phi = \\Phi_b \\Phi_a, \\qquad \\Gamma = \\Phi_b \\Gamma_a + \\Gamma_b, \\qquad
    Q_d = \\Phi_b Q_{d,a} \\Phi_b^\\top + Q_{d,b}

(the segments of one mode commute, so the order of the bits does not matter). The remainder
:math:`r` is short, :math:`\\|A_i\\| r \\le 2^{-10}`, and its flow is the Taylor series

.. math::

    \\begin{aligned}
    \\Phi(r) &= \\sum_j (A r)^j / j!, \\qquad \\Gamma(r) = \\sum_j A^j r^{j+1} / (j+1)!\\, B, \\\\
    Q_d(r) &= \\sum_j M_j r^{j+1} / (j+1)!, \\qquad M_0 = Q, \\quad
        M_j = A M_{j-1} + M_{j-1} A^\\top
    \\end{aligned}

(the derivatives of :math:`e^{A r} Q e^{A^\\top r}` at 0), truncated after the term of order
``ORDER = 5``: the first omitted term is below :math:`(2^{-10})^6 / 6! < 10^{-20}` of the sum,
so the result is exact to rounding at the instant given, not at a quantized one.

A switched interval is a sequence of such segments, composed the same way: the exact
transition of :func:`switchest.discretize.interval` at a few dozen small matrix products
instead of an ``expm`` of a :math:`(2n + l)`-square block. :func:`interval_transitions` does it
for many intervals at once (the clairvoyant filter's switched intervals, a switching-time
search's probes), in numpy: each product is taken over all the intervals together, entry by
entry, and Python loops only over the segments, the Taylor terms and the table's bits. An
interval whose :math:`q` lacks a bit is composed with the identity there, which changes
nothing: products by 1 and 0 and sums with 0 round nothing.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ._checks import check_finite, float_array, int_array, positive_scalar
from .discretize import Transition, interval
from .system import SwitchedLinearSystem

__all__ = ["DyadicTable", "dyadic_table", "interval_transitions"]

ORDER = 5  # Taylor terms of the remainder's flow beyond the constant one
_REMAINDER_REACH = 2.0**-10  # largest ||A|| r of a remainder


@dataclass(frozen=True, eq=False)
class DyadicTable:
    """Per-mode flows over :math:`T / 2^k`, :math:`k = 0, \\dots, \\mathrm{depth}`, and the
    generators.

    Attributes
    ----------
    T : float
        The interval length.
    depth : int
        :math:`D`: the finest table entry is :math:`T / 2^D`, with
        :math:`\\|A_i\\| T / 2^D \\le 2^{-10}`.
    Phi, Gamma, Qd : ndarray, shapes (L, D+1, n, n), (L, D+1, n, l), (L, D+1, n, n)
        :math:`\\Phi_i(T / 2^k)` etc.
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
    F, G, W = _intervals(table, modes, offsets)
    Qd = 0.5 * (W + np.swapaxes(W, 0, 1))  # symmetric to the last bit, as discretize returns it
    return Transition(*(np.ascontiguousarray(np.moveaxis(a, -1, 0)) for a in (F, G, Qd)))


# The flows of all M intervals are held entry-major, ``F[a, c, i]`` for interval ``i``, and
# multiplied by ``einsum`` over the last axis: for a few states a stacked ``matmul`` of
# (M, n, n) matrices (a BLAS call per matrix) is several times slower.


def _intervals(table, modes, offsets):
    """``(F, G, W)``, shapes (n, n, M), (n, l, M), (n, n, M): every interval's segments composed
    (the module docstring's recursions), ``W`` not yet symmetrized."""
    M, S1 = modes.shape
    K, n, n_in = table.Gamma.shape[1:]
    generators = [np.moveaxis(a, 0, -1) for a in (table.A, table.B, table.Q)]
    # the table's entries by bit, entry-major, each bit with an entry L appended: the identity
    # flow (Phi = I, Gamma = 0, Qd = 0), for the intervals whose q lacks the bit. Composed with
    # it a flow comes back as it was, exactly (products by 1 and 0, sums with 0); a product
    # computed for every interval and then selected away could overflow past any real flow
    identity = (np.broadcast_to(np.eye(n), (1, K, n, n)), np.zeros((1, K, n, n_in)),
                np.zeros((1, K, n, n)))
    entries = [np.moveaxis(np.concatenate([a, e]), 0, -1)
               for a, e in zip((table.Phi, table.Gamma, table.Qd), identity)]
    flow = None  # the identity: composed with the first segment, it gives that segment
    start = np.zeros(M)
    for s in range(S1):
        end = offsets[:, s] if s < S1 - 1 else np.full(M, table.T)
        segment = _segment(table, generators, entries, modes[:, s],
                           np.maximum(end - start, 0.0))
        flow = segment if flow is None else _compose(*flow, *segment)
        start = end
    return flow


def _segment(table, generators, entries, mode, s):
    """The flows of ``mode (M,)`` over segments of lengths :math:`0 \\le s \\le T` (M,): the
    Taylor series of the remainder, then the table entries of the bits of
    :math:`q = \\lfloor s\\, 2^D / T \\rfloor`
    (``generators``, ``entries``: those of :func:`_intervals`)."""
    depth, L = table.depth, table.Phi.shape[0]
    unit = table.T / 2.0**depth
    q = np.minimum(np.trunc(s / unit), 2.0**depth).astype(np.int64)
    flow = _taylor(*(np.take(a, mode, axis=-1) for a in generators),
                   np.maximum(s - q * unit, 0.0))
    for k in range(depth + 1):
        bit = ((q >> (depth - k)) & 1).astype(bool)
        if bit.any():
            which = np.where(bit, mode, L)
            flow = _compose(*flow, *(np.take(a[k], which, axis=-1) for a in entries))
    return flow


def _taylor(A, B, Q, r):
    """:math:`\\Phi(r)`, :math:`\\Gamma(r)`, :math:`Q_d(r)` by their Taylor series to ``ORDER``
    (the module docstring), for :math:`\\|A\\| r \\le 2^{-10}`; ``A, B, Q`` and the results
    entry-major, ``r (M,)``."""
    F = P = np.broadcast_to(np.eye(A.shape[0])[:, :, None], A.shape)  # P: A^j r^j / j!
    Mj = Q  # M_j r^j / j!
    W, G = Q * r, B * r
    for j in range(1, ORDER + 1):
        f, g = r / j, r / (j + 1)
        P = _product(A, P) * f
        F = F + P
        Mj = _lyapunov(A, Mj) * f
        W = W + Mj * g
        G = G + _product(P, B) * g
    return F, G, W


def _compose(F, G, W, Fb, Gb, Wb):
    """``(F, G, W)`` followed by ``(Fb, Gb, Wb)``: ``(Fb F, Fb G + Gb, Fb W Fb' + Wb)``."""
    return (_product(Fb, F), _product(Fb, G, Gb),
            _product(_product(Fb, W), np.swapaxes(Fb, 0, 1), Wb))


def _product(X, Y, start=None):
    """``start + X Y`` (or ``X Y``) entry-major: ``X (a, b, M)``, ``Y (b, c, M)``."""
    out = np.einsum("abm,bcm->acm", X, Y)
    return out if start is None else start + out


def _lyapunov(A, Mj):
    """``A Mj + Mj A'`` entry-major."""
    return np.einsum("akm,kcm->acm", A, Mj) + np.einsum("akm,ckm->acm", Mj, A)
