"""The designs :func:`switchest.tabular.estimate_table` makes from a model file alone.

A method that needs a transition matrix or observer gains the model file does not give gets
them here, from the model's switching model, sampling and system:
:func:`transition_for` (the IMM filters), :func:`rsls_gains` (Wang et al.'s observer) and
:func:`impulsive_gains` (Etienne et al.'s observer). Each is one choice among the designs
and certificates of :mod:`switchest.analysis`, documented with the reasons for it.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import expm

from ._checks import check_row_stochastic, positive_scalar
from .analysis import (
    critical_interval,
    error_dynamics,
    impulsive_observer_search,
    ms_convergence,
    place_gains,
    steady_state,
    subsystem_structure,
)
from .modelfile import ModelSpec
from .switching import IID, AverageDwell, Dwell, MarkovAtSamples, MarkovContinuous

__all__ = ["impulsive_gains", "rsls_gains", "transition_for"]

_POLE_SCALES = np.geomspace(0.25, 2.0, 7)  # pole scales rsls_gains compares (i.i.d. switching)


def transition_for(spec: ModelSpec, T: float, *, stay: float | None = None) -> np.ndarray:
    """A per-sample mode transition matrix for IMM filters, from the model's switching model.

    ``markov`` gives its matrix; ``iid`` repeats ``p`` in every row;
    ``markov-continuous`` gives :math:`\\exp(\\mathrm{rates}\\, T)`; ``dwell`` and
    ``average-dwell`` stay with probability :math:`1 - T / \\text{mean dwell}` (at most one
    switch per sample)
    and move uniformly to the others; ``stay`` overrides all of these.

    Parameters
    ----------
    spec : ModelSpec
        The model; its switching model gives the matrix unless ``stay`` is given.
    T : float
        The sampling interval the matrix is for.
    stay : float, optional
        Probability in ``(0, 1]`` of staying in a mode from one sample to the next;
        the rest is spread evenly over the other modes.

    Returns
    -------
    ndarray, shape (L, L)
        ``P[i, j]`` is P(mode j at the next sample | mode i now); rows sum to one.

    Raises
    ------
    ValueError
        When ``stay`` is not a probability, or there is no ``stay`` and the
        switching model (none, or a schedule) implies no matrix.
    """
    L = spec.system.n_modes
    sw = spec.switching
    if stay is not None:
        stay = positive_scalar(stay, "stay")
        if stay > 1:
            raise ValueError(f"stay must be a probability, got {stay}")
        P = np.full((L, L), (1 - stay) / max(L - 1, 1))
        np.fill_diagonal(P, stay)
        return P
    if isinstance(sw, MarkovAtSamples):
        return check_row_stochastic(sw.transition)
    if isinstance(sw, IID):
        return np.tile(sw.p, (L, 1))
    if isinstance(sw, MarkovContinuous):
        P = expm(sw.rates * T)
        return P / P.sum(axis=1, keepdims=True)
    if isinstance(sw, (Dwell, AverageDwell)):
        mean_dwell = 0.5 * (sw.min_dwell + sw.max_dwell) if isinstance(sw, Dwell) else sw.tau_a
        return transition_for(spec, T, stay=max(1e-6, 1.0 - T / mean_dwell))
    kind = None if sw is None else sw.kind
    raise ValueError(f"the model's switching model ({kind!r}) implies no transition matrix: "
                     "give stay")


def rsls_gains(spec: ModelSpec, T: float) -> np.ndarray:
    """Sub-observer gains for Wang et al.'s observer when the user gives none.

    Per-mode pole placement (Wang et al. §4.2, §6;
    :func:`~switchest.analysis.place_gains`) with one free scale :math:`s`: mode :math:`i`'s
    observable sub-state gets the poles :math:`-s \\rho_i (1, 1.25, 1.5, \\dots)`,
    :math:`\\rho_i = \\max(\\max |\\operatorname{eig} A_{22}^i|, 1 / T)` (as fast as the mode's
    own dynamics and at least one time constant per switching interval). With i.i.d. switching
    (``switching.kind = "iid"``, probabilities ``p``) :math:`s` is the one of seven
    log-spaced values from 0.25 to 2 that minimizes the exact steady-state mean-square error
    :math:`\\operatorname{tr} \\Phi V \\Phi^\\top` (:func:`~switchest.analysis.steady_state`,
    Wang et al. eq. (21) corrected) among the designs that pass the exact mean-square test
    (:func:`~switchest.analysis.ms_convergence`): §5.2's design, restricted to
    this one-parameter family. Other switching models (outside Wang et al.'s
    i.i.d. assumption) get :math:`s = 1`, unchecked.

    Why this design rather than the others of :mod:`switchest.analysis.subsystem_observers`:
    the Kalman-Bucy gains (§4.1) need no choice but ignore the random switching —
    the paper's Example 1 shows them diverging (exact MS spectral radius 1.079 on
    ``wang-example1``) and on ``wang-ieee5bus`` (an eigenvalue 0, no process noise)
    the Riccati equation has no stabilizing solution. The unrestricted §5.2
    optimum (:func:`~switchest.analysis.optimal_gains`) needs an MS-stable start
    and a Nelder-Mead search over every gain entry (about ten minutes on
    ``wang-ieee5bus``); the one-parameter search costs a few milliseconds per
    candidate. On ``wang-example1`` it gives :math:`\\operatorname{tr} V_x = 0.602` (the full
    optimum 0.532), on ``wang-ieee5bus`` 0.0519 (the paper's first pole set 0.0517). Scales
    above 2 are not tried: the gains grow like the cube of the scale and only
    amplify the output noise (on ``wang-ieee5bus`` the error at scale 2 is ten
    times that at scale 1).

    Parameters
    ----------
    spec : ModelSpec
        The model: its system and, for the scale search, its switching model.
    T : float
        The switching interval (Wang et al. Assumption 1).

    Returns
    -------
    ndarray, shape (L, n, m)
        Gains in state coordinates.

    Raises
    ------
    ValueError
        With i.i.d. switching, when no candidate is mean-square convergent.
    """
    system = spec.system
    T = positive_scalar(T, "T")
    structure = subsystem_structure(system)
    rates = [max(float(np.max(np.abs(np.linalg.eigvals(A22)), initial=0.0)), 1.0 / T)
             for A22 in structure.A22]

    def design(scale: float) -> np.ndarray:
        return place_gains(structure, [-scale * r * (1.0 + 0.25 * np.arange(A22.shape[0]))
                                       if A22.size else None
                                       for r, A22 in zip(rates, structure.A22)])

    if not isinstance(spec.switching, IID):
        return design(1.0)
    p = spec.switching.p
    best, best_mu, radius = None, np.inf, np.inf
    for scale in _POLE_SCALES:
        gains = design(scale)
        dyn = error_dynamics(system, gains, T, structure=structure)
        ms = ms_convergence(dyn, p)
        radius = min(radius, ms.radius)
        mu = steady_state(dyn, p).mu_x if ms.holds else np.inf
        if 0.0 < mu < best_mu:
            best, best_mu = gains, mu
    if best is None:
        limit = critical_interval(system, p, structure=structure).fast_observer
        raise ValueError(
            f"method 'rsls': no default sub-observer design is mean-square convergent at T = {T:g} "
            f"(smallest spectral radius {radius:.4g} >= 1, Wang et al. Theorem 1); fast enough "
            f"sub-observers converge only for T < {limit:.4g} (critical interval): design gains "
            "with switchest.analysis.place_gains and run switchest.estimators.RSLSObserver")
    return best


def impulsive_gains(spec: ModelSpec, t: np.ndarray) -> np.ndarray:
    """Observer gains from Etienne et al. Theorem 8 for the model's sampling and dwell time.

    The sampling bounds are ``sampling.tau_min`` / ``tau_max`` (or ``period`` for
    both, Assumption 2) and the dwell time is ``switching.tau_a`` (kind
    ``average-dwell``) or ``min_dwell`` (kind ``dwell``), Assumption 1. The
    scalars ``(alpha, mu_s, mu_c)``, which the paper fixes by hand (Remark 12),
    are searched for the largest guaranteed decay rate
    (:func:`~switchest.analysis.impulsive_observer_search`, the search
    ``switchest check`` also runs). The sample times ``t`` must keep to the
    bounds the gains are designed for.

    Parameters
    ----------
    spec : ModelSpec
        The model: its system, sampling bounds and dwell time.
    t : ndarray, shape (K,)
        The sample times the gains will run at.

    Returns
    -------
    ndarray, shape (L, n, m)
        One observer gain per mode (Theorem 8's ``G``).

    Raises
    ------
    ValueError
        When the model lacks the bounds or the dwell time, ``t`` leaves the
        bounds, or the LMIs give no certificate (with the synthesis' diagnostic).
    """
    smp, sw = spec.sampling, spec.switching
    lo, hi = smp.get("tau_min", smp.get("period")), smp.get("tau_max", smp.get("period"))
    if lo is None:
        raise ValueError("method 'impulsive' needs the sampling bounds (Etienne et al. "
                         "Assumption 2): set sampling.tau_min and sampling.tau_max (or "
                         "sampling.period) in the model file")
    dwell = (sw.tau_a if isinstance(sw, AverageDwell)
             else sw.min_dwell if isinstance(sw, Dwell) else None)
    if dwell is None:
        raise ValueError("method 'impulsive' needs a dwell time (Etienne et al. Assumption 1): a "
                         "[switching] table of kind 'average-dwell' (tau_a) or 'dwell' "
                         f"(min_dwell), got {getattr(sw, 'kind', None)!r}")
    steps = np.diff(np.asarray(t, dtype=float))
    outside = (steps < lo * (1 - 1e-9)) | (steps > hi * (1 + 1e-9))
    if outside.any():
        row = int(np.flatnonzero(outside)[0]) + 1
        raise ValueError(f"method 'impulsive': data row {row} is {steps[row - 1]:.6g} after the "
                         f"previous row, outside the model's sampling bounds [{lo:g}, {hi:g}] the "
                         "gains are designed for (Etienne et al. Assumption 2); widen "
                         "sampling.tau_min / tau_max")
    best = impulsive_observer_search(spec.system, lo, hi, dwell).best
    if not best.holds:
        raise ValueError(f"method 'impulsive': Theorem 8's LMIs give no observer for sampling in "
                         f"[{lo:g}, {hi:g}] and dwell time {dwell:g} (Etienne et al.): {best.note}")
    return best.G
