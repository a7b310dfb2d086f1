"""Maximum-likelihood fitting of a switched linear system by expectation-maximization.

The loop of Dempster, Laird & Rubin (1977, JRSS B 39): an E-step
(:mod:`~switchest.learn.expectation`) and conditional M-steps (Meng & Rubin 1993): transition
matrix (:mod:`~switchest.learn.markov_step`), then ``A``, ``B`` and ``C``
(:mod:`~switchest.learn.dynamics_step`), then ``Q`` and ``R``
(:mod:`~switchest.learn.noise_step`) with the new matrices.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Iterable

import numpy as np

from .._checks import (
    as_rng,
    check_row_stochastic,
    check_symmetric_psd,
    float_array,
    positive_int,
    positive_scalar,
)
from ..analysis.observability import mode_observability
from ..discretize import sample_mode_steps
from ..system import SwitchedLinearSystem
from .ascent import ascend
from .data import Record, record
from .dynamics_step import fit_AB, fit_C
from .expectation import MAX_SEQUENCES, expectation, log_likelihoods
from .markov_step import fit_transition, rates_from_transition, transition_se
from .noise_step import fit_Q, fit_R, shared
from .result import FitResult
from .standard_errors import observed_standard_errors

__all__ = ["fit"]

_PARAMETERS = ("transition", "A", "B", "C", "Q", "R")


def fit(system: SwitchedLinearSystem, y, u=None, t=None, *, transition=None, x0, P0,
        modes=None, estimate: Iterable[str] = ("transition", "Q", "R"), max_iter: int = 200,
        tol: float = 1e-6, rng=None, e_step: str = "kim",
        progress: Callable[[int, float], object] | None = None) -> FitResult:
    """Fit the transition matrix and the noise covariances (and optionally ``A``, ``B``, ``C``)
    of a switched linear system to measurements, by expectation-maximization.

    Parameters
    ----------
    system : SwitchedLinearSystem
        The model; its matrices are the starting point, and those not estimated stay fixed. A
        matrix equal in all modes is shared and fitted as one; a noise component of zero
        variance stays zero.
    y : array_like, shape (K, m) or (N, K, m)
        Measurements of one or ``N`` trials; NaN marks a missing component.
    u : array_like, optional
        Inputs ``(l,)``, ``(K, l)`` or ``(N, K, l)``, ``u[k]`` held over the interval into
        sample ``k + 1``; zero by default.
    t : array_like, shape (K,)
        Sample times (required for a continuous-time system; periodic or not).
    transition : array_like, shape (L, L), optional
        Starting (or, without ``"transition"`` in ``estimate``, fixed) transition matrix,
        ``transition[i, j]`` = P(mode j at k+1 | mode i at k). Default: with known modes the
        counts' estimate; otherwise drawn from ``rng`` around a stay of 0.9 (Dirichlet rows),
        which breaks the symmetry between modes of equal starting parameters.
    x0, P0 : array_like
        Prior mean ``(n,)`` and covariance ``(n, n)`` of the state at the first sample (fixed).
    modes : array_like of int, shape (K,) or (N, K), optional
        The known mode at each sample (mode ``r_k`` drives the interval into ``k + 1`` and the
        measurement at ``k``, as ``switchest.simulate`` draws them). With them the E-step is
        exact and the log-likelihood never decreases; without them Kim's smoother gives an
        approximate E-step, or enumeration an exact one (``e_step``), in the same timing
        (the package's, docs/conventions.rst), and the first mode has the uniform prior.
    estimate : iterable of str
        What to fit, among ``"transition"``, ``"Q"``, ``"R"``, ``"C"`` and, for a
        discrete-time system, ``"A"``, ``"B"``.
    max_iter : int
        Most E-steps (and, after an approximate EM, most iterations of the direct ascent).
    tol : float
        Stop when ``|loglik_i - loglik_{i-1}| <= tol |loglik_{i-1}|``.
    rng : numpy.random.Generator, int or None
        Draws the starting transition matrix when none is given with unknown modes (unused
        otherwise).
    e_step : {"kim", "exact"}
        The E-step of unknown modes (with known modes it is exact whatever this says):
        ``"kim"``, the IMM on the chain of mode pairs and Kim's smoother
        (:mod:`~switchest.learn.expectation`; approximate, any record length): EM stops at
        the first step that lowers that IMM's log-likelihood (the step is rejected: EM with an
        approximate E-step need not climb), and the fit continues from there by direct ascent
        of the same log-likelihood over the transition matrix, ``Q`` and ``R``
        (:mod:`~switchest.learn.ascent`; not when ``A``, ``B`` or ``C`` are estimated), so it
        ends at a maximum of the likelihood it reports, possibly on the boundary (a
        transition probability of 0, a singular ``Q``: those entries then have no standard
        error), and ``loglik`` never decreases;
        ``"exact"``, the enumeration of all ``L^K`` mode sequences of each trial (the Kalman
        filter and RTS smoother of each, weighted by its posterior probability): the exact
        E-step, so the exact log-likelihood (that of
        :class:`~switchest.estimators.ExactMixtureFilter`, which ``loglik`` then reports)
        never decreases; for short records only (``L^K`` up to
        :data:`~switchest.learn.expectation.MAX_SEQUENCES` = 65536, refused beyond).
    progress : callable, optional
        Called as ``progress(iteration, loglik)`` after each accepted E-step and ascent
        iteration.

    Returns
    -------
    FitResult

    Warns
    -----
    RuntimeWarning
        Naming the mode: a mode never visited (known modes) or whose smoothed probability mass
        is below one sample (unknown modes), whose parameters keep their starting values; a mode
        whose pair ``(C, A)`` is unobservable, whose ``Q`` is not identifiable from ``y``. Also
        when the log-likelihood decreases from one iteration to the next with an exact E-step
        (naming the iteration and the drop: digits lost, or a partial M-step), and when Kim's
        approximate E-step stopped EM with ``A``, ``B`` or ``C`` estimated (no ascent
        follows, so the fit need not be a maximum).

    Notes
    -----
    Continuous-time systems: ``Q`` is the intensity, fitted through the exact discretization
    ``Qd(h) = int_0^h e^{As} Q e^{A's} ds`` of every distinct step (generalized EM); ``A``,
    ``B`` are not fitted (no closed-form M-step exists for them in continuous time) and are
    refused. With known modes a switch is taken at the sample instants (the mode at a sample
    holds until the next one). ``FitResult.rates`` gives the generator of a continuous-time
    chain matching the fitted per-sample ``transition`` (periodic sampling).

    Standard errors: from the observed information (:mod:`~switchest.learn.standard_errors`)
    of ``Q``, ``R`` and, with unknown modes, jointly of the transition matrix; with known modes
    the transition's from the counts (the same information, in closed form); jointly with
    ``A``, ``B`` or ``C`` when those are fitted, except that with both the dynamics and ``C``
    fitted the state's coordinates are not identified: ``A``, ``B``, ``C`` then get NaN and the
    others are conditional on them.
    """
    data = record(system, y, u, t, modes)
    wanted = _estimate(estimate, system)
    x0 = float_array(x0, "x0", ndim=1)
    P0 = check_symmetric_psd(float_array(P0, "P0", ndim=2), "P0")
    max_iter = positive_int(max_iter, "max_iter")
    tol = positive_scalar(tol, "tol")
    L = system.n_modes
    exact = _exact(e_step, data, L)
    transition = _start_transition(transition, data, L, rng)
    allowed = transition > 0  # the entries that may be nonzero: the start's zeros are held
    _warn_unobservable(system, wanted)
    steps = np.unique(np.diff(data.t))
    approximate = data.modes is None and not exact
    trace: list[float] = []
    warned: set[int] = set()
    converged = False
    dropped = None  # the iteration whose approximate E-step found a lower likelihood
    accepted = system, transition  # the parameters of trace[-1]
    for it in range(max_iter):
        mom = expectation(system, transition, x0, P0, data, exact=exact)
        if approximate and trace and mom.loglik < trace[-1] - 1e-9 * max(1.0, abs(trace[-1])):
            dropped = it  # Kim's EM lowered its likelihood: reject the step
            system, transition = accepted
            break
        accepted = system, transition
        trace.append(mom.loglik)
        if progress is not None:
            progress(it, mom.loglik)
        if it and _stalled(trace, tol, it):
            converged = True
            break
        if it == max_iter - 1:
            break
        system, transition = _maximize(system, transition, data, steps, mom, wanted, warned)
    ascent_from = None
    if approximate and not {"A", "B", "C"} & set(wanted):
        def report(value):
            trace.append(value)
            if progress is not None:
                progress(len(trace) - 1, value)

        ascent_from = len(trace)
        system, transition, converged = ascend(
            system, transition, wanted, lambda pts: log_likelihoods(pts, x0, P0, data),
            start_loglik=trace[-1], max_iter=max_iter, tol=tol, report=report)
    elif dropped is not None:
        warnings.warn(f"EM iteration {dropped}: Kim's approximate E-step lowered the "
                      f"log-likelihood, so EM stopped at the iteration before (log-likelihood "
                      f"{trace[-1]:.10g}); with A, B or C estimated no direct ascent follows, and "
                      "the fit need not be a maximum", RuntimeWarning, stacklevel=2)
    se = _standard_errors(system, transition, x0, P0, data, wanted, mom, exact, allowed)
    period = np.diff(data.t)
    rates = (rates_from_transition(transition, float(period[0]))
             if system.is_continuous and np.ptp(period) <= 1e-9 * period.max() else None)
    return FitResult(system=system, transition=transition, loglik=np.array(trace),
                     converged=converged, iterations=len(trace), se=se, rates=rates,
                     ascent_from=ascent_from)


def _estimate(estimate, system: SwitchedLinearSystem) -> tuple[str, ...]:
    if isinstance(estimate, str):
        raise TypeError(f"estimate must be a collection of names such as ('transition', 'Q'), "
                        f"got the string {estimate!r}")
    wanted = tuple(estimate)
    bad = [e for e in wanted if e not in _PARAMETERS]
    if bad or not wanted:
        raise ValueError(f"estimate must name some of {_PARAMETERS}, got {wanted}")
    if system.is_continuous and ("A" in wanted or "B" in wanted):
        raise ValueError("estimate: 'A' and 'B' can be fitted only for a discrete-time system "
                         "(a continuous-time A enters the likelihood through expm; no "
                         "closed-form M-step); leave them out")
    if "B" in wanted and system.n_inputs == 0:
        raise ValueError("estimate: 'B' given but the system has no input")
    return wanted


def _exact(e_step, data: Record, L: int) -> bool:
    """Whether the E-step of unknown modes enumerates the mode sequences (``e_step``)."""
    if e_step not in ("kim", "exact"):
        raise ValueError(f"e_step must be 'kim' or 'exact', got {e_step!r}")
    K = data.shape[1]
    if e_step == "exact" and data.modes is None and L**K > MAX_SEQUENCES:
        raise ValueError(f"e_step='exact' enumerates L^K = {L}^{K} mode sequences per trial, "
                         f"more than {MAX_SEQUENCES}; use e_step='kim' or shorter records")
    return e_step == "exact"


def _start_transition(transition, data: Record, L: int, rng) -> np.ndarray:
    if transition is not None:
        return check_row_stochastic(transition, "transition", n=L)
    if data.modes is not None:
        pairs = np.zeros((L, L))
        np.add.at(pairs, (data.modes[:, :-1], data.modes[:, 1:]), 1.0)
        return fit_transition(pairs, np.full((L, L), 1.0 / L))
    if L == 1:
        return np.ones((1, 1))
    mean = np.full((L, L), 0.1 / (L - 1))
    np.fill_diagonal(mean, 0.9)
    gen = as_rng(rng)
    return np.array([gen.dirichlet(20.0 * row) for row in mean])  # concentration 20


def _warn_unobservable(system: SwitchedLinearSystem, wanted) -> None:
    if "Q" not in wanted:
        return
    obs = mode_observability(system)
    for j in np.flatnonzero(~obs.observable):
        warnings.warn(f"mode {j}: the pair (C, A) is unobservable ({obs.n_observable[j]} of "
                      f"{system.n_states} states observable): its process noise Q is not "
                      "identifiable from y" + (" alone (Q is shared with the other modes)"
                                               if np.all(system.Q == system.Q[:1]) and
                                               system.n_modes > 1 else ""),
                      RuntimeWarning, stacklevel=3)


def _stalled(trace: list[float], tol: float, it: int) -> bool:
    """Convergence test; warns where the log-likelihood decreased, which an exact E-step
    (known modes, or ``e_step="exact"``) leaves to a numerical loss of digits or a partial
    M-step, e.g. ``C`` with partly missing samples (:func:`fit` rejects the step that lowers
    the likelihood of Kim's approximate E-step before it gets here)."""
    new, old = trace[-1], trace[-2]
    drop = old - new
    if drop > 1e-9 * max(1.0, abs(old)):
        warnings.warn(f"EM iteration {it}: the log-likelihood decreased by {drop:.6g} (from "
                      f"{old:.10g} to {new:.10g}); the E-step is exact, so an M-step did not "
                      "maximize (e.g. C with partly missing samples) or digits were lost",
                      RuntimeWarning, stacklevel=3)
    return abs(new - old) <= tol * max(abs(old), 1e-300)


def _maximize(system, transition, data: Record, steps, mom, wanted, warned):
    """One round of conditional M-steps; returns the new system and transition."""
    mass = mom.weight.sum(axis=(0, 1))
    for j in np.flatnonzero(mass < 1.0):
        if int(j) not in warned:
            warned.add(int(j))
            how = ("was never visited" if data.modes is not None else
                   f"has smoothed probability mass {mass[j]:.3g} < 1 sample")
            warnings.warn(f"mode {j} {how}: its parameters are not identifiable from the data "
                          "and keep their starting values", RuntimeWarning, stacklevel=4)
    if "transition" in wanted:
        transition = fit_transition(mom.pairs, transition)
    A, B, C, Q, R = system.A, system.B, system.C, system.Q, system.R
    if "A" in wanted or "B" in wanted:
        newA, newB = fit_AB(A, B, data.u, mom, with_B="B" in wanted and np.any(data.u))
        A = newA if "A" in wanted else A
        B = newB if "B" in wanted else B
    if "C" in wanted:
        C = fit_C(C, R, data.y, mom)
    system = system.replace(A=A, B=B, C=C, Q=Q, R=R)
    if "Q" in wanted:
        table = mom.table if not ("A" in wanted or "B" in wanted) else sample_mode_steps(
            system, data.t)[0]
        Q = fit_Q(system, steps, data.u, mom, table)[0]
    if "R" in wanted:
        R = fit_R(C, R, data.y, mom)[0]
    keep = (mass < 1.0)[:, None, None]  # unidentifiable modes keep their own matrices
    A, B, C, Q, R = (new if shared(old) else np.where(keep, old, new) for old, new in
                     zip((system.A, system.B, system.C, system.Q, system.R), (A, B, C, Q, R)))
    return system.replace(A=A, B=B, C=C, Q=Q, R=R), transition


def _standard_errors(system, transition, x0, P0, data, wanted, mom, exact, allowed
                     ) -> dict[str, np.ndarray]:
    """Standard errors of the fit from the observed information (:mod:`.standard_errors`),
    jointly for the parameters fitted (the transition's on the support ``allowed``); with known
    modes the transition's from the counts (its information separates from the others').
    Where both the dynamics (``A`` or ``B``) and ``C`` are fitted, the state's coordinates are
    not identified (``x -> T x`` leaves the likelihood unchanged): ``A``, ``B``, ``C`` get NaN
    and the others are conditional on them. ``B`` with all inputs zero is not fitted: NaN."""
    se = {name: np.full(getattr(system, name).shape, np.nan) for name in ("A", "B", "C")
          if name in wanted}
    regression = [name for name in ("A", "B", "C") if name in wanted
                  and not (name == "B" and not np.any(data.u))]
    if "C" in regression and len(regression) > 1:
        regression = []
    joint = [name for name in ("transition", *regression, "Q", "R") if name in wanted]
    if data.modes is not None and "transition" in wanted:
        se["transition"] = transition_se(transition, mom.pairs.sum(axis=1))
        joint.remove("transition")
    if joint:
        se.update(observed_standard_errors(
            system, transition, joint,
            lambda pts: log_likelihoods(pts, x0, P0, data, exact=exact), allowed=allowed))
    return se
