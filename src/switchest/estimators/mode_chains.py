"""Chains of members: the modes of a switched system rewritten as a Markov chain whose member of
sample :math:`k + 1` fixes the interval into it and the measurement there.

With the modes unknown, each interval :math:`k \\to k+1` holds a latent member :math:`s_{k+1}` of
a Markov chain that fixes both what moves the state over the interval and what measures
:math:`y_{k+1}`, so that the model is a switched linear system in Bar-Shalom's timing
(``"interval"``: the member of sample :math:`k+1` governs the interval into it):

- switches at the samples (:func:`pair_chain`): :math:`s_{k+1} = (r_k, r_{k+1})`, in the
  package's timing (:doc:`/conventions`) moving through mode :math:`r_k`'s transition and
  measuring through mode :math:`r_{k+1}`'s ``C``, ``R``, with
  :math:`P(s_{k+1} = (b', c) \\mid s_k = (a, b)) = [b' = b]\\, \\pi_{bc}`: :math:`L^2` members,
  the pairs GPB2 merges (Bar-Shalom, Li & Kirubarajan §11.6.5);
- switches inside the intervals (:func:`instant_chain`, a continuous-time system):
  :math:`s_{k+1} = (r_k, r_{k+1}, \\tau)`, with, when the modes differ, the switch instant on the
  grid of Shankar et al. eq. (23), :math:`\\tau_i = i h / g - h / (2 g)`, uniform a priori (at
  most one switch per interval: the dwell time exceeds :math:`h`, Shankar §II), moving through
  the exact switched transition :math:`F(\\tau) = e^{A_b (h - \\tau)} e^{A_a \\tau}`,
  :math:`G(\\tau)`, :math:`Q_d(\\tau)` of Shankar et al. eqs (3)-(5) (the grid's row of
  :func:`~switchest.estimators.step_tables.grid_table`; mode ``a``'s own row when :math:`a = b`) and
  measuring through mode ``b``'s ``C``, ``R``, with

  .. math::

      P\\big(s_{k+1} = (b', c, \\tau') \\mid s_k = (a, b, \\tau)\\big)
      = [b' = b]\\, \\pi_{bc} \\, g^{-[b \\ne c]}:

  :math:`L + L (L - 1) g` members, the exact rewriting of the model on the grid.

At sample 0 the member is :math:`(r_0, r_0)`, :math:`r_0` uniform, measured only.

The IMM on the instant chain is a filter of its own
(:class:`~switchest.estimators.BetweenSamplesIMMFilter`); the E-steps of :mod:`switchest.learn`
run the IMM and the two-filter smoother on either chain (:mod:`switchest.learn.chain`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..system import SwitchedLinearSystem
from .step_tables import StepTable, grid_table, sample_table

__all__ = ["ModeChain", "chain_transition", "instant_chain", "instant_members", "pair_chain"]


@dataclass(frozen=True, eq=False)
class ModeChain:
    """A chain of ``M`` members over a record's sample times (module docstring).

    Attributes
    ----------
    table : StepTable
        The transitions the members move through.
    trans : ndarray of int64, shape (K, M)
        The row of ``table`` of each member into each sample (row 0 unused).
    first, second : ndarray of int64, shape (M,)
        Each member's mode before and after the interval into its sample (``second``
        measures it).
    component : ndarray of int64, shape (M,)
        Each member's component of :class:`~switchest.learn.moments.Moments`: the members of
        one component move through the same row into every sample.
    entry : ndarray of int64, shape (K-1, H)
        The row of each component of each interval.
    matrix : ndarray, shape (M, M)
        The chain's transition matrix.
    prior : ndarray, shape (M,)
        The members' probabilities at sample 0.
    C, R : ndarray, shapes (M, m, n), (M, m, m)
        Each member's measurement (mode ``second``'s).
    """

    table: StepTable
    trans: np.ndarray
    first: np.ndarray
    second: np.ndarray
    component: np.ndarray
    entry: np.ndarray
    matrix: np.ndarray
    prior: np.ndarray
    C: np.ndarray
    R: np.ndarray


def pair_chain(system: SwitchedLinearSystem, transition, t) -> ModeChain:
    """The chain of consecutive mode pairs of ``system`` at the sample times ``t`` (switches at
    the samples; module docstring), pair ``(a, b)`` at index :math:`a L + b`, one component
    per driving mode ``a``."""
    L = system.n_modes
    table, entry = sample_table(system, t)
    a, b = np.divmod(np.arange(L * L), L)
    return _chain(system, table, entry[:, a], a, b, a, entry[1:], transition[a, b])


def instant_members(transition, g: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The members ``(M,)`` of the instant chain of the ``L`` modes of ``transition (L, L)`` on
    a grid of ``g`` instants (:func:`instant_chain`): the mode before and after the interval of
    each and the probability of entering it from a member that ends in its mode before,
    :math:`\\pi_{ab} g^{-[a \\ne b]}`. The ``L`` members that stay come first, then each
    switching pair ``(a, b)``, :math:`a \\ne b` in row-major order, at the grid's instants in
    order (member ``L + p g + i``: pair ``p`` at instant ``i``)."""
    L = transition.shape[0]
    a, b = np.divmod(np.arange(L * L), L)
    a, b = a[a != b], b[a != b]
    first = np.concatenate([np.arange(L), np.repeat(a, g)])
    second = np.concatenate([np.arange(L), np.repeat(b, g)])
    return first, second, transition[first, second] / np.where(first != second, g, 1)


def instant_chain(system: SwitchedLinearSystem, transition, t, g: int) -> ModeChain:
    """The chain of (mode before, mode after, instant) of ``system`` at the sample times ``t``
    on a grid of ``g`` instants (switches inside the intervals; module docstring), members in
    the order of :func:`instant_members`, a component each."""
    L = system.n_modes
    table, entry, switched = grid_table(system, t, g)
    first, second, move = instant_members(transition, g)
    a, b = first[L::g], second[L::g]
    trans = np.concatenate([entry, switched[:, a, b].reshape(len(t), -1)], axis=1)
    return _chain(system, table, trans, first, second, np.arange(first.size), trans[1:], move)


def chain_transition(first, second, move, L: int) -> tuple[np.ndarray, np.ndarray]:
    """The transition matrix of a chain whose members ``first``, ``second`` ``(M,)`` are entered
    with probability ``move (M,)`` from any member that ends in their ``first`` mode, and its
    prior at sample 0: :math:`(r_0, r_0)` with :math:`r_0` uniform over the ``L`` modes
    (module docstring)."""
    matrix = np.where(second[:, None] == first[None, :], move[None, :], 0.0)
    return matrix, np.where(first == second, 1.0 / L, 0.0)


def _chain(system, table, trans, first, second, component, entry, move) -> ModeChain:
    """The chain of members ``first``, ``second`` entered with probability ``move``
    (:func:`chain_transition`)."""
    matrix, prior = chain_transition(first, second, move, system.n_modes)
    return ModeChain(table, trans, first, second, component, entry, matrix, prior,
                     system.C[second], system.R[second])


