"""Maximum-likelihood fitting of a switched linear system by expectation-maximization.

The loop of Dempster, Laird & Rubin (1977, JRSS B 39): an E-step
(:mod:`~switchest.learn.expectation`, :mod:`~switchest.learn.between`) and conditional M-steps
(Meng & Rubin 1993): transition matrix (:mod:`~switchest.learn.markov_step`), then ``A``, ``B``
and ``C`` (:mod:`~switchest.learn.dynamics_step`), then ``Q`` and ``R``
(:mod:`~switchest.learn.noise_step`) with the new matrices.

EM stops by Aitken's rule (Böhning, Dietz, Schaub, Schlattmann & Lindsay 1994, Ann. Inst.
Statist. Math. 46; McNicholas, Murphy, McDaid & Frost 2010, Comput. Statist. Data Anal. 54):
near its fixed point EM's gains :math:`d_i = l_i - l_{i-1}` fall geometrically,
:math:`d_{i+1} \\approx a d_i` with :math:`a = d_i / d_{i-1}`, so the likelihood still to gain is
:math:`d_i a / (1 - a)`; EM stops when that and :math:`d_i` are at most ``tol`` nats. The
distance of the parameters from the maximum is then at most :math:`\\sqrt{2\\, \\mathrm{tol}}` of
their standard errors (the log-likelihood is quadratic there, :math:`l_{\\max} - l = z^2 / 2` in
standard-error units), whatever the number of samples: a relative tolerance
:math:`\\mathrm{tol}\\, |l|` grows with :math:`|l| \\sim K`. Where EM crawls (each gain at
least :data:`_SLOW` = 0.9 of the one before: a parameter the data barely inform), and after an
approximate E-step, whose fixed point is not a maximum of the likelihood it reports, a direct
ascent of that likelihood (:mod:`~switchest.learn.ascent`) finishes the fit.
"""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Callable, Iterable

import numpy as np
from scipy.stats import chi2

from .._checks import (
    as_rng,
    check_row_stochastic,
    check_symmetric_psd,
    float_array,
    positive_int,
    positive_scalar,
)
from ..analysis.observability import mode_observability
from ..system import SwitchedLinearSystem
from .ascent import ascend
from .consistency import warn_if_mistimed
from .data import Record, record
from .dynamics_step import fit_AB, fit_C
from .expectation import MAX_SEQUENCES, expectation, log_likelihoods
from .markov_step import fit_transition, rates_from_transition, transition_se
from .noise_step import fit_Q, fit_R
from .result import FitResult
from .standard_errors import observed_standard_errors

__all__ = ["GATE_PROBABILITY", "fit"]

_PARAMETERS = ("transition", "A", "B", "C", "Q", "R")
_MATRICES = ("A", "B", "C", "Q", "R")  # what ``shared`` may tie across the modes
_SLOW = 0.9  # EM's rate of convergence beyond which the direct ascent takes over
GATE_PROBABILITY = 1e-9
"""The default gate's probability: a measurement of the model is rejected this rarely."""


def fit(system: SwitchedLinearSystem, y, u=None, t=None, *, transition=None, x0, P0,
        modes=None, estimate: Iterable[str] = ("transition", "Q", "R"),
        shared: Iterable[str] = (), switch_times: str = "samples", grid: int = 16,
        gate: float | str | None = "auto", max_iter: int = 200, tol: float = 1e-3, rng=None,
        e_step: str = "two-filter", progress: Callable[[int, float], object] | None = None
        ) -> FitResult:
    """Fit the transition matrix and the noise covariances (and optionally ``A``, ``B``, ``C``)
    of a switched linear system to measurements, by expectation-maximization.

    Parameters
    ----------
    system : SwitchedLinearSystem
        The model; its matrices are the starting point, and those not estimated stay fixed.
        Each mode's matrices are fitted on their own unless ``shared`` ties them; a noise
        component of zero variance stays zero.
    y : array_like, shape (K, m) or (N, K, m)
        Measurements of one or ``N`` trials; NaN marks a missing component.
    u : array_like, optional
        Inputs ``(l,)``, ``(K, l)`` or ``(N, K, l)``, ``u[k]`` held over the interval into
        sample ``k + 1``; zero by default.
    t : array_like, shape (K,)
        Sample times (required for a continuous-time system; periodic or not).
    transition : array_like, shape (L, L), optional
        Starting (or, without ``"transition"`` in ``estimate``, fixed) transition matrix,
        ``transition[i, j]`` = :math:`P(\\text{mode } j \\text{ at } k+1 \\mid
        \\text{mode } i \\text{ at } k)`. Default: with known modes the counts' estimate;
        otherwise drawn from ``rng`` around a stay of 0.9 (Dirichlet rows), which breaks the
        symmetry between modes of equal starting parameters.
    x0, P0 : array_like
        Prior mean ``(n,)`` and covariance ``(n, n)`` of the state at the first sample (fixed).
    modes : array_like of int, shape (K,) or (N, K), optional
        The known mode at each sample (mode :math:`r_k` drives the interval into ``k + 1`` and
        the measurement at ``k``, as ``switchest.simulate`` draws them). With them and
        ``switch_times="samples"`` the E-step is exact and the log-likelihood never decreases;
        without them the IMM and two-filter smoother of the chain of mode pairs give an
        approximate E-step, or enumeration an exact one
        (``e_step``), in the same timing (the package's, :doc:`/conventions`), and the first
        mode has the uniform prior.
    estimate : iterable of str
        What to fit, among ``"transition"``, ``"Q"``, ``"R"``, ``"C"`` and, for a
        discrete-time system, ``"A"``, ``"B"``.
    shared : iterable of str
        The estimated matrices, among ``"A"``, ``"B"``, ``"C"``, ``"Q"``, ``"R"``, tied across
        the modes: fitted as one matrix from the data of all of them (their starting values
        must then be equal in every mode). ``A`` and ``B`` estimated together are tied
        together or not at all.
    switch_times : {"samples", "between"}
        Where the switches fall. ``"samples"``: at the sample instants, the mode of a sample
        held over the interval after it. ``"between"`` (a continuous-time system): inside the
        intervals, at unknown instants, once per interval at most, each marginalized over the
        grid of Shankar et al. eq. (23); with ``modes`` by the switch-time Kalman filter
        (:mod:`~switchest.learn.between`), without them by the IMM and the two-filter
        smoother on the chain of (mode before, mode after, instant)
        (:mod:`~switchest.learn.between_unknown`); an approximate E-step either way, ended by
        direct ascent as ``e_step="two-filter"``.
    grid : int
        :math:`g`, the switch instants per interval of ``switch_times="between"``.
    gate : float, "auto" or None
        The filters' outlier gate in the E-step: the largest normalized innovation squared
        accepted; a rejected sample is missing for the fit (``FitResult.outlier``; each
        E-step gates under its own parameters, and the last one's samples are those of the
        standard errors; when a flagged set comes back after another, the gate flip-flops on
        samples at its edge, and the union of the sets since then is held missing for the rest
        of the fit, so that EM can stop). ``"auto"``: the chi-square quantile of probability
        :math:`1 -` :data:`GATE_PROBABILITY` with ``m`` degrees of freedom (a measurement of the
        model is rejected once in 1e9). ``None``: only measurements whose innovation overflows
        (a wild but finite one then enters the fit as any other).
    max_iter : int
        Most iterations, of EM and of the direct ascent of the log-likelihood over the
        transition matrix, ``Q`` and ``R`` that finishes an EM which crawls (its gains falling
        by less than 10 % per iteration: the data barely inform a parameter) or which an
        approximate E-step stopped (:mod:`~switchest.learn.ascent`; not with ``A``, ``B`` or
        ``C`` estimated).
    tol : float
        In nats: EM stops when an iteration gains at most ``tol`` and Aitken's estimate of
        the gain still to come is at most ``tol`` (module docstring); the direct ascent when
        an iteration gains at most ``tol``.
    rng : numpy.random.Generator, int or None
        Draws the starting transition matrix when none is given with unknown modes (unused
        otherwise).
    e_step : {"two-filter", "exact"}
        The E-step of unknown modes (with known modes it is exact whatever this says):
        ``"two-filter"``, the IMM on the chain of mode pairs and the two-filter smoother
        (:mod:`~switchest.learn.chain`; approximate, any record length): EM stops at
        the first step that lowers that IMM's log-likelihood (the step is rejected: EM with an
        approximate E-step need not climb), and the fit continues from there by direct ascent
        of the same log-likelihood over the transition matrix, ``Q`` and ``R``
        (:mod:`~switchest.learn.ascent`; not when ``A``, ``B`` or ``C`` are estimated), so it
        ends at a maximum of the likelihood it reports, possibly on the boundary (a
        transition probability of 0, a singular ``Q``: those entries then have no standard
        error), and ``loglik`` never decreases;
        ``"exact"``, the enumeration of all :math:`L^K` mode sequences of each trial (the Kalman
        filter and RTS smoother of each, weighted by its posterior probability): the exact
        E-step, so the exact log-likelihood (that of
        :class:`~switchest.estimators.ExactMixtureFilter`, which ``loglik`` then reports)
        never decreases; for short records only (:math:`L^K` up to
        :data:`~switchest.learn.expectation.MAX_SEQUENCES` = 65536, refused beyond).
    progress : callable, optional
        Called as ``progress(iteration, loglik)`` after each accepted E-step and ascent
        iteration.

    Returns
    -------
    FitResult

    Raises
    ------
    TypeError
        For an argument of the wrong type (``progress`` not callable, ``estimate`` a string).
    ValueError
        For a bad value, naming it: ``y`` beyond the floating-point range of a covariance (the
        trial and sample), a ``shared`` matrix not estimated or with different starting
        values, ``switch_times="between"`` for a discrete system or with ``e_step="exact"``, and a
        fit whose likelihood overflows (naming the largest measurement).

    Warns
    -----
    RuntimeWarning
        Naming the mode: a mode never visited (known modes) or whose smoothed probability mass
        is below one sample (unknown modes), whose parameters keep their starting values; a mode
        whose pair ``(C, A)`` is unobservable, whose ``Q`` is not identifiable from ``y``. Also
        when the log-likelihood decreases from one iteration to the next with an exact E-step
        (naming the iteration and the drop: digits lost, or a partial M-step), when the
        approximate E-step stopped EM with ``A``, ``B`` or ``C`` estimated (no ascent
        follows, so the fit need not be a maximum), and when the fitted model's innovations
        after the mode changes are implausibly large for it (known modes, ``switch_times=
        "samples"``: the mean normalized innovation squared more than 4 standard deviations
        above its value, as ``switchest estimate`` warns): switches between the samples.

    Notes
    -----
    Continuous-time systems: ``Q`` is the intensity, fitted through the exact discretization
    :math:`Q_d(h) = \\int_0^h e^{A s} Q e^{A^\\top s}\\, ds` of every distinct step, and of every
    switch instant of the grid with ``switch_times="between"`` (generalized EM); ``A``, ``B`` are
    not fitted (no closed-form M-step exists for them in continuous time) and are refused.
    ``FitResult.rates`` gives the generator of a continuous-time chain matching the fitted
    per-sample ``transition`` (periodic sampling).

    Standard errors: from the observed information (:mod:`~switchest.learn.standard_errors`)
    of ``Q``, ``R`` and, with unknown modes, jointly of the transition matrix; with known modes
    the transition's from the counts (the same information, in closed form); jointly with
    ``A``, ``B`` or ``C`` when those are fitted, except that with both the dynamics and ``C``
    fitted the state's coordinates are not identified: ``A``, ``B``, ``C`` then get NaN and the
    others are conditional on them. The gated samples are missing in them too.

    Floating-point warnings of numpy are not shown where an overflow is expected and handled:
    a candidate of the direct ascent or of the standard errors' finite differences whose filter
    or difference overflows gets no value (the ascent then takes the one-sided difference or
    none, the information matrix gives no standard error along it), and a trial point of the
    continuous-time Q step's line search whose gradient overflows ends it (the step is kept
    only if it improves). Anywhere else an overflow is not hidden.
    """
    if progress is not None and not callable(progress):
        raise TypeError(f"progress must be a callable progress(iteration, loglik) or None, "
                        f"got {type(progress).__name__}")
    return _fit(system, y, u, t, transition, x0, P0, modes, estimate, shared, switch_times,
                grid, gate, max_iter, tol, rng, e_step, progress)


def _fit(system, y, u, t, transition, x0, P0, modes, estimate, shared, switch_times, grid,
         gate, max_iter, tol, rng, e_step, progress) -> FitResult:
    data = record(system, y, u, t, modes)
    wanted = _estimate(estimate, system)
    tied = _shared(shared, wanted, system)
    grid = _grid(switch_times, grid, system, data)
    gate = _gate(gate, system.n_outputs)
    x0 = float_array(x0, "x0", ndim=1)
    P0 = check_symmetric_psd(float_array(P0, "P0", ndim=2), "P0")
    max_iter = positive_int(max_iter, "max_iter")
    tol = positive_scalar(tol, "tol")
    L = system.n_modes
    exact = _exact(e_step, data, L, grid)
    transition = _start_transition(transition, data, L, rng)
    allowed = transition > 0  # the entries that may be nonzero: the start's zeros are held
    _warn_unobservable(system, wanted, tied)
    approximate = (data.modes is None and not exact) or grid is not None
    names = [w for w in wanted if w != "transition" or data.modes is None]
    ascends = bool(names) and not {"A", "B", "C"} & set(wanted)  # a direct ascent may finish
    trace: list[float] = []
    warned: set[int] = set()
    maps: dict = {}  # the Q step's intensity maps, computed once per fit
    converged = False
    dropped = None  # the iteration whose approximate E-step found a lower likelihood
    accepted = None  # the parameters of trace[-1] and their E-step
    flagged: list[np.ndarray] = []  # the gate's flagged sets, until one comes back
    held = None  # the flagged set held missing, once the gate flip-flops
    for it in range(max_iter):
        if held is None:
            mom = expectation(system, transition, x0, P0, data, exact=exact, gate=gate,
                              grid=grid)
            held = _held_if_cycling(mom.outlier, flagged)
        if held is not None:  # the set held, the gate no longer moves it (overflow rejected)
            kept = dataclasses.replace(data, y=np.where(held[..., None], np.nan, data.y))
            mom = expectation(system, transition, x0, P0, kept, exact=exact, gate=None,
                              grid=grid)
            mom = dataclasses.replace(mom, outlier=mom.outlier | held)
        if not np.isfinite(mom.loglik):
            raise ValueError(_overflowed(it, mom.loglik, data))
        # the likelihoods of two iterations compare where their gates left the same samples
        same = accepted is not None and np.array_equal(mom.outlier, accepted[2].outlier)
        if approximate and same and mom.loglik < trace[-1] - 1e-9 * max(1.0, abs(trace[-1])):
            dropped = it  # the approximate E-step lowered its likelihood: reject the step
            break
        accepted = system, transition, mom
        trace.append(mom.loglik)
        if progress is not None:
            progress(it, mom.loglik)
        if same and _stalled(trace, tol, it, exact=not approximate):
            converged = True
            break
        if it == max_iter - 1 or (ascends and _slow(trace, tol)):
            break
        system, transition = _maximize(system, transition, data, mom, wanted, tied, warned,
                                       maps)
    system, transition, mom = accepted
    used = dataclasses.replace(data, y=mom.y)  # the gated samples missing, as in the E-step

    def logliks(points):
        return log_likelihoods(points, x0, P0, used, exact=exact, grid=grid)

    ascent_from = None
    budget = max_iter - len(trace)  # EM's iterations and the ascent's: at most max_iter
    if (approximate or not converged) and ascends and budget > 0:
        def report(value):
            trace.append(value)
            if progress is not None:
                progress(len(trace) - 1, value)

        ascent_from = len(trace)
        start = float(logliks([(system, transition)])[0])
        with np.errstate(over="ignore", invalid="ignore"):  # candidates beyond the range
            system, transition, converged = ascend(
                system, transition, names, logliks, tied=tied, start_loglik=start,
                max_iter=budget, tol=tol / max(1.0, abs(start)), report=report)
    elif dropped is not None:
        warnings.warn(f"EM iteration {dropped}: the approximate E-step lowered the "
                      f"log-likelihood, so EM stopped at the iteration before (log-likelihood "
                      f"{trace[-1]:.10g}); with A, B or C estimated no direct ascent follows, and "
                      "the fit need not be a maximum", RuntimeWarning, stacklevel=3)
    with np.errstate(over="ignore", invalid="ignore"):  # differences beyond the range
        se = _standard_errors(system, transition, used, wanted, tied, mom, allowed, logliks)
    if data.modes is not None and grid is None:
        warn_if_mistimed(system, x0, P0, used)
    period = np.diff(data.t)
    rates = (rates_from_transition(transition, float(period[0]))
             if system.is_continuous and np.ptp(period) <= 1e-9 * period.max() else None)
    return FitResult(system=system, transition=transition, loglik=np.array(trace),
                     converged=converged, iterations=len(trace), se=se, rates=rates,
                     ascent_from=ascent_from, shared=tuple(n for n in _MATRICES if n in tied),
                     switch_times=switch_times, outlier=mom.outlier,
                     outliers=int(mom.outlier.sum()))


def _held_if_cycling(outlier: np.ndarray, flagged: list[np.ndarray]) -> np.ndarray | None:
    """The samples to hold missing ``(N, K)`` once the gate flip-flops, else None.

    Each E-step gates under its own parameters, and the likelihoods of two iterations compare
    only where their gates left the same samples (``fit``'s stopping rule). A sample on the
    gate's edge may be rejected and accepted in turn, and EM would then never stop. When a
    flagged set comes back after another, the union of the sets since its first occurrence is
    held missing for the rest of the fit (the gate then rejects only overflowing
    innovations), and EM continues on one record. ``flagged`` collects the sets seen."""
    for first, seen in enumerate(flagged):
        if np.array_equal(seen, outlier):
            if first == len(flagged) - 1:  # the same as the last: no cycle
                return None
            return np.logical_or.reduce([*flagged[first:], outlier])
    flagged.append(outlier)
    return None


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


def _shared(shared, wanted: tuple[str, ...], system: SwitchedLinearSystem) -> frozenset[str]:
    """The matrices ``shared`` ties across the modes, checked (:func:`fit` documents them)."""
    if isinstance(shared, str):
        raise TypeError(f"shared must be a collection of names such as ('R',), got the string "
                        f"{shared!r}")
    tied = tuple(shared)
    bad = [name for name in tied if name not in _MATRICES]
    if bad:
        raise ValueError(f"shared must name some of {_MATRICES}, got {tied}")
    loose = [name for name in tied if name not in wanted]
    if loose:
        raise ValueError(f"shared: {', '.join(loose)} not estimated (estimate={wanted}); "
                         "only an estimated matrix can be tied across the modes")
    for name in tied:
        stack = getattr(system, name)
        differ = np.flatnonzero(np.any(stack != stack[:1], axis=(1, 2)))
        if differ.size:
            raise ValueError(f"shared: {name} is tied across the modes but its starting value "
                             f"in mode {differ[0]} differs from mode 0's; start every mode "
                             "from one matrix")
    if "A" in wanted and "B" in wanted and ("A" in tied) != ("B" in tied):
        raise ValueError("shared: A and B are fitted by one regression; tie both or neither")
    return frozenset(tied)


def _grid(switch_times, grid, system: SwitchedLinearSystem, data: Record) -> int | None:
    """The grid of ``switch_times="between"`` (None for ``"samples"``), checked."""
    if switch_times not in ("samples", "between"):
        raise ValueError(f"switch_times must be 'samples' or 'between', got {switch_times!r}")
    grid = positive_int(grid, "grid")
    if switch_times == "samples":
        return None
    if not system.is_continuous:
        raise ValueError("switch_times='between' needs a continuous-time system (a "
                         "discrete-time one switches at its steps)")
    return grid


def _gate(gate, m: int) -> float | None:
    if isinstance(gate, str):
        if gate != "auto":
            raise ValueError(f"gate must be a positive number, 'auto' or None, got {gate!r}")
        return float(chi2.isf(GATE_PROBABILITY, m))
    return None if gate is None else positive_scalar(gate, "gate")


def _exact(e_step, data: Record, L: int, grid: int | None) -> bool:
    """Whether the E-step of unknown modes enumerates the mode sequences (``e_step``)."""
    if e_step not in ("two-filter", "exact"):
        raise ValueError(f"e_step must be 'two-filter' or 'exact', got {e_step!r}")
    if e_step == "exact" and grid is not None and data.modes is None:
        raise ValueError("e_step='exact' enumerates mode sequences that switch at the samples; "
                         "with switch_times='between' the E-step of unknown modes is the IMM "
                         "and two-filter smoother of the chain of switch instants: use "
                         "e_step='two-filter'")
    K = data.shape[1]
    if e_step == "exact" and data.modes is None and L**K > MAX_SEQUENCES:
        raise ValueError(f"e_step='exact' enumerates L^K = {L}^{K} mode sequences per trial, "
                         f"more than {MAX_SEQUENCES}; use e_step='two-filter' or shorter records")
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


def _warn_unobservable(system: SwitchedLinearSystem, wanted, tied) -> None:
    if "Q" not in wanted:
        return
    obs = mode_observability(system)
    for j in np.flatnonzero(~obs.observable):
        warnings.warn(f"mode {j}: the pair (C, A) is unobservable ({obs.n_observable[j]} of "
                      f"{system.n_states} states observable): its process noise Q is not "
                      "identifiable from y" + (" alone (Q is shared with the other modes)"
                                               if "Q" in tied and system.n_modes > 1 else ""),
                      RuntimeWarning, stacklevel=4)


def _overflowed(it: int, loglik: float, data: Record) -> str:
    """The message of a fit whose log-likelihood left the floating-point range."""
    size = np.where(np.isnan(data.y), -np.inf, np.abs(data.y))
    i, k, c = np.unravel_index(int(np.argmax(size)), size.shape)
    return (f"the log-likelihood of EM iteration {it} is {loglik} (the fit left the "
            f"floating-point range); the largest measurement is y = {data.y[i, k, c]:.6g} "
            f"(trial {i}, sample {k}, output {c}): a measurement far outside the model's range "
            "is rejected by the gate (gate='auto'), not with gate=None")


def _stalled(trace: list[float], tol: float, it: int, *, exact: bool) -> bool:
    """Aitken's stopping rule (module docstring); with an ``exact`` E-step (known modes at the
    samples, or ``e_step="exact"``) warns where the log-likelihood decreased, which it leaves to
    a numerical loss of digits or a partial M-step, e.g. ``C`` with partly missing samples
    (:func:`fit` rejects the step that lowers the likelihood of an approximate E-step before
    it gets here)."""
    new, old = trace[-1], trace[-2]
    gain = new - old
    if exact and gain < -1e-9 * max(1.0, abs(old)):
        warnings.warn(f"EM iteration {it}: the log-likelihood decreased by {-gain:.6g} (from "
                      f"{old:.10g} to {new:.10g}); the E-step is exact, so an M-step did not "
                      "maximize (e.g. C with partly missing samples) or digits were lost",
                      RuntimeWarning, stacklevel=4)
    if gain <= 0.0:  # no progress: at the maximum to rounding
        return True
    if gain > tol or len(trace) < 3:
        return False
    before = old - trace[-3]
    if not 0.0 < gain < before:  # not yet converging geometrically
        return False
    rate = gain / before
    return gain * rate / (1.0 - rate) <= tol


def _slow(trace: list[float], tol: float) -> bool:
    """Whether EM crawls: its last three gains each at least :data:`_SLOW` of the one before
    and more than ``tol`` still to come by Aitken's estimate (module docstring), where a
    quasi-Newton ascent gets to the maximum in far fewer iterations (Jamshidian & Jennrich
    1997, JRSS B 59)."""
    if len(trace) < 5:
        return False
    gains = np.diff(trace[-5:])
    if np.any(gains <= 0):
        return False
    rates = gains[1:] / gains[:-1]
    rate = rates[-1]
    return bool(np.all(rates >= _SLOW) and rate < 1 and gains[-1] * rate / (1 - rate) > tol)


def _maximize(system, transition, data: Record, mom, wanted, tied, warned, maps: dict):
    """One round of conditional M-steps; returns the new system and transition. ``maps`` is the
    fit's cache of the Q step's intensity maps (:func:`~switchest.learn.noise_step.fit_Q`)."""
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
    dynamics = "A" in wanted or "B" in wanted
    if dynamics:
        newA, newB = fit_AB(A, B, data.u, mom, with_B="B" in wanted and np.any(data.u),
                            tied="A" in tied)
        A = newA if "A" in wanted else A
        B = newB if "B" in wanted else B
    if "C" in wanted:
        C = fit_C(C, R, mom, tied="C" in tied)
    system = system.replace(A=A, B=B, C=C, Q=Q, R=R)
    if "Q" in wanted:
        table = mom.table.under(system) if dynamics else mom.table
        Q = fit_Q(system, data.u, mom, table, tied="Q" in tied, cache=maps)
    if "R" in wanted:
        R = fit_R(C, R, mom, tied="R" in tied)
    keep = (mass < 1.0)[:, None, None]  # unidentifiable modes keep their own matrices
    A, B, C, Q, R = (new if name in tied else np.where(keep, old, new) for name, old, new in
                     zip(_MATRICES, (system.A, system.B, system.C, system.Q, system.R),
                         (A, B, C, Q, R)))
    return system.replace(A=A, B=B, C=C, Q=Q, R=R), transition


def _standard_errors(system, transition, data: Record, wanted, tied, mom, allowed, logliks
                     ) -> dict[str, np.ndarray]:
    """Standard errors of the fit from the observed information (:mod:`.standard_errors`) of
    ``logliks``, jointly for the parameters fitted (the transition's on the support
    ``allowed``); with known modes the transition's from the counts (its information separates
    from the others'). Where both the dynamics (``A`` or ``B``) and ``C`` are fitted, the
    state's coordinates are not identified (:math:`x \\to T x` leaves the likelihood unchanged):
    ``A``, ``B``, ``C`` get NaN and the others are conditional on them. ``B`` with all inputs
    zero is not fitted: NaN."""
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
        se.update(observed_standard_errors(system, transition, joint, logliks, tied=tied,
                                           allowed=allowed))
    return se
