"""The exact transitions the intervals of a chain of members move through (the filters on the
chains of :mod:`~switchest.estimators.mode_chains`, and the E-steps of :mod:`switchest.learn`),
each with the segments it covers.

A row of a :class:`StepTable` is one interval of length ``h`` that starts in mode ``a`` and
switches to mode ``b`` at offset :math:`\\tau` (:math:`a = b`: no switch):
:math:`x^+ = F x + G u + w`, :math:`w \\sim \\mathcal{N}(0, Q_d)`, with
:math:`F = e^{A_b (h - \\tau)} e^{A_a \\tau}` and ``G`` the zero-order hold of Shankar et al.
eqs (4)-(5), and :math:`Q_d = \\Phi_b Q_{d,a}(\\tau) \\Phi_b^\\top + Q_{d,b}(h - \\tau)` the exact
covariance of the integrated noise (Van Loan 1978; :mod:`switchest.discretize`, the one place
where matrix exponentials are taken). The maximization steps of :mod:`switchest.learn` read the
segments to rebuild a row under other parameters: :math:`Q_d` is linear in the intensities
:math:`Q_a` and :math:`Q_b` of the two segments (:func:`switchest.learn.noise_step.fit_Q`).

Two layouts, both built from :mod:`switchest.discretize`'s cached tables:

- :func:`sample_table`, switches at the sample instants: each mode over each distinct
  sampling step (:func:`~switchest.discretize.sample_mode_steps`), row :math:`d L + j`;
- :func:`grid_table`, switches inside the intervals: those rows, then for each distinct step
  ``d`` every mode pair ``(a, b)`` switching at each instant
  :math:`\\tau_i = i h / g - h / (2 g)` of the grid of Shankar et al. eq. (23)
  (:func:`~switchest.discretize.pairwise_grid`), row :math:`D L + ((d L + a) L + b) g + i`
  (:math:`D` distinct steps).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..discretize import (
    Transition,
    distinct_steps,
    interval,
    pairwise_grid,
    sample_mode_steps,
    switch_grid,
)
from ..system import SwitchedLinearSystem

__all__ = ["StepTable", "grid_table", "sample_table"]


@dataclass(frozen=True, eq=False)
class StepTable:
    """Rows of exact one-interval transitions and the segments of each.

    Attributes
    ----------
    F, G, Qd : ndarray, shapes (M, n, n), (M, n, l), (M, n, n)
        The transitions (module docstring).
    length : ndarray, shape (M,)
        The interval length ``h`` of each row.
    modes : ndarray of int64, shape (M, 2)
        The mode before and after the switch (equal: no switch).
    offset : ndarray, shape (M,)
        The switch instant from the start of the interval, in :math:`[0, h]` (0 without a
        switch).
    """

    F: np.ndarray
    G: np.ndarray
    Qd: np.ndarray
    length: np.ndarray
    modes: np.ndarray
    offset: np.ndarray

    def under(self, system: SwitchedLinearSystem) -> StepTable:
        """The same rows discretized with ``system``'s matrices (the segments kept)."""
        if not system.is_continuous:  # one mode per step: F = A, G = B, Qd = Q
            m = self.modes[:, 0]
            tr = Transition(system.A[m], system.B[m], system.Q[m])
        else:
            tr = interval(system, self.length, self.modes, self.offset[:, None])
        return StepTable(tr.F, tr.G, tr.Qd, self.length, self.modes, self.offset)


def sample_table(system: SwitchedLinearSystem, t: np.ndarray) -> tuple[StepTable, np.ndarray]:
    """Every mode over every distinct interval of ``t (K,)``, and ``entry (K, L)``, the row of
    mode ``j`` over the interval into sample ``k`` (row 0 unused), as
    :func:`~switchest.discretize.sample_mode_steps` lays them out."""
    tr, entry = sample_mode_steps(system, t)
    steps = _steps(t)
    L = system.n_modes
    modes = np.tile(np.arange(L), steps.size)
    return StepTable(tr.F, tr.G, tr.Qd, np.repeat(steps, L), np.stack([modes, modes], axis=1),
                     np.zeros(steps.size * L)), entry


def grid_table(system: SwitchedLinearSystem, t: np.ndarray, g: int
               ) -> tuple[StepTable, np.ndarray, np.ndarray]:
    """:func:`sample_table`'s rows followed by the switched ones on the grid of ``g`` instants
    (module docstring). Returns the table, ``entry (K, L)`` of :func:`sample_table` and
    ``switched (K, L, L, g)``: ``switched[k, a, b, i]``, the row of the interval into sample
    ``k`` switching from ``a`` to ``b`` at the grid's instant ``i`` (row 0 unused)."""
    base, entry = sample_table(system, t)
    steps = _steps(t)
    L = system.n_modes
    grids = [pairwise_grid(system, h, g) for h in steps]  # (L, L, g) each, eq. (23)
    a, b, _ = np.meshgrid(np.arange(L), np.arange(L), np.arange(g), indexing="ij")
    tau = np.concatenate([np.broadcast_to(switch_grid(h, g), (L, L, g)).ravel() for h in steps])
    rows = L * L * g  # of each step's grid (explicit: G has no columns without an input)
    table = StepTable(
        *(np.concatenate([getattr(base, name)] + [getattr(p, name).reshape(rows, *getattr(
            p, name).shape[3:]) for p in grids]) for name in ("F", "G", "Qd")),
        length=np.concatenate([base.length, np.repeat(steps, L * L * g)]),
        modes=np.concatenate([base.modes,
                              np.tile(np.stack([a.ravel(), b.ravel()], axis=1), (steps.size, 1))]),
        offset=np.concatenate([base.offset, tau]))
    which = (entry[:, 0] // L)[:, None, None, None]  # the distinct step of each interval
    switched = (steps.size * L + ((which * L + np.arange(L)[:, None, None]) * L
                                  + np.arange(L)[:, None]) * g + np.arange(g))
    switched[0] = 0
    return table, entry, switched


def _steps(t: np.ndarray) -> np.ndarray:
    """The distinct sampling steps of ``t``, as :func:`~switchest.discretize.sample_mode_steps`
    orders them (a unit step for one sample)."""
    steps = distinct_steps(t)[0]
    return steps if steps.size else np.ones(1)
