"""The IMM on the chain of switching instants: modes unknown, switches inside the sampling
intervals.

A continuous-time switched system sampled at :math:`t_k` whose mode changes between two samples
moves the state over that interval through the exact switched transition
:math:`F(\\tau) = e^{A_b (h - \\tau)} e^{A_a \\tau}`, :math:`G(\\tau)`, :math:`Q_d(\\tau)` (Shankar
et al. eqs (3)-(5)), not through either mode's own. The IMM and GPB filters
(:mod:`~switchest.estimators.mode_bank`) model the switches at the samples; their mode-matched
filters then meet the mis-timed switch as model error, and their smoothers, which sharpen the
mode probabilities on that model, can end up worse than the filter.

With the switch instant of an interval on the grid of Shankar et al. eq. (23),
:math:`\\tau_i = i h / g - h / (2 g)`, uniform a priori, and at most one switch per interval
(the dwell time exceeds :math:`h`, Shankar et al. §II), the sampled model is exactly a Markov
chain of :math:`L + L (L - 1) g` members (mode before, mode after, instant)
(:func:`~switchest.estimators.mode_chains.instant_chain`): member :math:`(a, b, \\tau_i)` of
sample :math:`k + 1` moves the state over the interval into it through the grid's row
:math:`F(\\tau_i)`, :math:`G(\\tau_i)`, :math:`Q_d(\\tau_i)` (mode ``a``'s own transition when
:math:`a = b`), is measured through mode ``b``'s ``C``, ``R``, and is entered from any member
that ends in ``a`` with probability :math:`\\pi_{ab} / g^{[a \\ne b]}`. This filter is the IMM on
that chain (Blom & Bar-Shalom 1988; the interaction, member-matched Kalman filters and output
of Bar-Shalom, Li & Kirubarajan §11.6.6, in their timing: the member of a sample governs the
interval into it): :class:`~switchest.estimators.IMMFilter`'s kernel with one filter per member.
It reports

- the modes' probabilities, the sums of the members' over those that end in each mode;
- the switching instant of an interval (``switch_time``) where a switch in it is more probable
  than none: the posterior mean instant given a switch,
  :math:`t_k + \\sum_i \\mu_{(a, b, \\tau_i)} \\tau_i / \\sum_i \\mu_{(a, b, \\tau_i)}`
  over the switching members :math:`(a, b, \\tau_i)`;

and its ``smooth`` runs the two-filter smoother on the chain
(:mod:`switchest.estimators.two_filter`), whose model of the switches is then the data's.

Shankar et al.'s own filter with unknown modes, the IMM extended-Viterbi filter
(:class:`~switchest.estimators.IMMEV1Filter`, their Algorithm 1), keeps one maximum-likelihood
instant per hypothesis; this one weighs every instant of the grid (beyond the paper). The
:math:`L (L - 1) g` switching members make it cost about :math:`1 + (L - 1) g` times the IMM.

On the boost converter of Shankar et al. §V.A (``examples/models/shankar-boost.toml``, 20
trials of 201 samples simulated from the file, ``g = 5``, the file's transition matrix),
median state RMSE (:math:`i_L`, :math:`v_0`):

============================  ==============  ==============  ==============
filter                        filtered        smoothed        mode accuracy
============================  ==============  ==============  ==============
``IMMFilter``                 18.35, 2.13     20.17, 2.35     0.77, 0.62
``BetweenSamplesIMMFilter``   13.31, 1.98     9.16, 1.73      0.80, 0.90
============================  ==============  ==============  ==============

(the mode accuracy of the filtered and smoothed most probable modes).
"""

from __future__ import annotations

import numpy as np

from .._checks import positive_int
from ..discretize import switch_grid
from ..system import SwitchedLinearSystem
from .base import _with_mode_model_parameters
from .mode_bank import Members, ModeBankFilter
from .mode_chains import chain_transition, instant_chain, instant_members

__all__ = ["BetweenSamplesIMMFilter"]


@_with_mode_model_parameters
class BetweenSamplesIMMFilter(ModeBankFilter):
    """The IMM on the chain of (mode before, mode after, switching instant) of a continuous-time
    switched system whose switches fall between the samples (module docstring); batched over
    trials and members.

    Parameters
    ----------
    {mode model parameters}
    grid : int, optional
        The instants :math:`g` of the grid of Shankar et al. eq. (23) in each interval
        (keyword-only; default 5): :math:`L + L (L - 1) g` members.
    gate : float, optional
        Largest normalized innovation squared a member-matched filter accepts (keyword-only), as
        for :class:`~switchest.estimators.IMMFilter`; a sample every member rejects is treated
        as missing and flagged in ``Estimate.outlier``.

    Attributes
    ----------
    member_modes : ndarray of int64, shape (M, 2)
        Each member's mode before and after the interval into its sample, in the order of
        ``step``'s state (:func:`~switchest.estimators.mode_chains.instant_members`).

    Notes
    -----
    ``transition[i, j]`` is the probability of mode ``j`` at the next sample given mode ``i`` now,
    as for every filter of switchest, and at most one switch falls in an interval. ``step``'s
    state is :class:`~switchest.estimators.IMMState` over the members: one Gaussian and one
    log-probability per member, and the combined estimate. The system's ``timing`` does not
    change the model: the modes at the samples are those of the continuous-time signal.

    Examples
    --------
    >>> import numpy as np
    >>> from switchest.models.shankar import BoostTable1
    >>> boost = BoostTable1()
    >>> traj = boost.simulate(0.01, 2, rng=0)  # 2 trials x 10 ms
    >>> imm = BetweenSamplesIMMFilter(boost.system(), boost.transition, *boost.prior, grid=4)
    >>> imm.member_modes.shape  # 2 members that stay, 2 switching pairs at 4 instants
    (10, 2)
    >>> est = imm.run(traj.y, boost.input, traj.t)
    >>> est.mode_prob.shape  # the modes' probabilities: sums over the members
    (2, 21, 2)
    >>> imm.smooth(traj.y, boost.input, traj.t).x.shape  # the two-filter smoother on the chain
    (2, 21, 2)
    """

    _interaction = "mix"

    def __init__(self, system, transition, x0, P0, *, grid: int = 5, mode_prob0=None,
                 gate: float | None = None):
        if isinstance(system, SwitchedLinearSystem) and not system.is_continuous:
            raise ValueError("system must be continuous-time: a discrete-time system switches at "
                             "its samples: IMMFilter (method 'imm') models it")
        self.grid = positive_int(grid, "grid")
        super().__init__(system, transition, x0, P0, mode_prob0=mode_prob0, gate=gate)

    def _bank_members(self) -> Members:
        """The members of the instant chain, in Bar-Shalom's timing (module docstring)."""
        sys, L = self.system, self.system.n_modes
        first, second, move = instant_members(self.transition, self.grid)
        self.member_modes = np.stack([first, second], axis=1)  # (read by users of step)
        matrix, _ = chain_transition(first, second, move, L)
        prob0 = np.where(first == second, self.mode_prob0[first], 0.0)
        return Members(sys.C[second], sys.R[second], matrix, prob0, second, "interval")

    def _table(self, t):
        """The instant chain's rows over the record ``t`` and each member's row into each
        sample (:func:`~switchest.estimators.mode_chains.instant_chain`)."""
        chain = instant_chain(self.system, self.transition, t, self.grid)
        return chain.table.F, chain.table.G, chain.table.Qd, chain.trans

    def _step_rows(self, dt: float):
        """The instant chain's rows of one interval of length ``dt`` and each member's row."""
        F, G, Qd, trans = self._table(np.array([0.0, dt]))
        return F, G, Qd, trans[1]

    def _switch_time(self, member_prob, t) -> np.ndarray:
        """The switching instant of each interval from the members' probabilities (module
        docstring), filtered or smoothed."""
        return _switch_times(member_prob, t, self.system.n_modes, self.grid)


def _switch_times(member_prob, t, L: int, g: int) -> np.ndarray:
    """``(N, K)``: in each interval into sample ``k`` where the members that switch are more
    probable than those that stay, the posterior mean instant given a switch (module
    docstring); NaN elsewhere and at sample 0. ``member_prob (N, K, M)``, members in the order of
    :func:`~switchest.estimators.mode_chains.instant_members`."""
    N, K, _ = member_prob.shape
    out = np.full((N, K), np.nan)
    if K < 2 or L < 2:
        return out
    switching = member_prob[:, 1:, L:].reshape(N, K - 1, -1, g).sum(axis=2)  # (N, K-1, g)
    total = switching.sum(axis=-1)
    offsets = np.diff(t)[:, None] * switch_grid(1.0, g)  # (K-1, g): eq. (23) in each interval
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.sum(switching * offsets, axis=-1) / total
    out[:, 1:] = np.where(total > 0.5, t[:-1] + mean, np.nan)
    return out

