"""Estimation from measured data: pandas DataFrames (or CSV files) in and out.

The data are a measurement table (:mod:`switchest.measurements`: columns ``t``,
``u..``, ``y..`` and, for the methods that need it, ``mode``), read and checked by
:func:`~switchest.measurements.read_measurements`. The method's row of the registry
(:mod:`switchest.estimators.registry`) builds its estimator from the model file, a transition
matrix or gains the file does not give coming from :mod:`switchest.default_designs`, and runs it;
this module tabulates its estimates. The readers and designs it uses stay importable from
here.

The methods (:data:`METHODS`), what each needs and where it finds it:

``kalman``, ``switch-time``
    Mode-based Kalman filters (Zhang & Natarajan; Shankar et al.) along the
    ``mode`` column (required); ``[initial]`` starts them.
``imm``, ``gpb1``, ``gpb2``, ``rbpf``, ``imm-ev1``
    The multiple-model filters (IMM, GPB1, GPB2, the Rao-Blackwellized particle
    filter) and Shankar et al.'s Algorithm 1; modes unknown. The transition matrix
    comes from the switching model (:func:`transition_for`) or ``stay``. ``smooth``
    (``imm``, ``gpb1``, ``gpb2``) gives fixed-interval smoothed estimates instead of
    filtered ones; ``particles`` and ``seed`` configure ``rbpf``; ``timing`` picks which
    interval the mode of a sample governs (:doc:`/conventions`).
``min-distance``
    Lee, Ping & Shim's mode estimation and switching detection
    (:class:`~switchest.estimators.MinimumDistanceDetector`) on a continuous-time
    model, the output sampled on a *uniform* grid ``t``. The noise bound
    ``v_max``, the windows ``delta`` and ``Delta`` (and ``u_max``,
    ``observer_decay``) come from the model file's ``[noise]`` table; the
    options ``v_max``, ``delta``, ``Delta`` override it. There is no estimate
    until the first window of length ``delta`` has filled, nor from a declared
    switch until the next window has: those rows have empty ``x`` and ``mode``
    (they are kept, not dropped). A missing sample is bridged by holding the
    last complete one, which the detector's guarantees do not cover.
``rsls``
    Wang et al.'s subsystem observer for randomly switched systems
    (:class:`~switchest.estimators.RSLSObserver`). **Here the ``y`` columns hold
    the integrated output** :math:`z(t) = \\int_{t_0}^t y` (Wang et al. eq. (1): the Ito
    output :math:`dz = C x\\, dt + \\Xi\\, dw`, e.g. ``Trajectory.y_fine`` of
    ``simulate(..., output="integrated")``) at fine instants ``t`` that include
    every switching instant ``t[0] + kT``; the ``mode`` column (required) gives
    the mode at each instant. :math:`T` is ``sampling.period`` or the option
    ``switch_interval``; gains by :func:`rsls_gains`.
``impulsive``
    Etienne et al.'s impulsive observer at (aperiodic) samples
    (:class:`~switchest.estimators.ImpulsiveObserver`), along the switching
    signal of the ``mode`` column (required, :func:`mode_signal`), with gains
    from Theorem 8's LMIs (:func:`impulsive_gains`).

The estimate table has ``t``, the state estimates ``x0 ..``, their standard
deviations ``std_x0 ..`` (methods with a covariance: all but
``min-distance``) and, where the method gives them, ``mode`` (empty where
undefined), ``p_mode0 ..`` and ``switch_time`` (empty where no switch is
estimated or declared).
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pandas as pd

from .default_designs import impulsive_gains, rsls_gains, transition_for
from .estimators import METHOD_NAMES, Estimate, get_method
from .measurements import mode_signal, read_measurements
from .metrics import FEWEST_SAMPLES, IMPLAUSIBLE_Z, innovation_consistency
from .modelfile import ModelSpec

__all__ = [
    "METHODS",
    "ImplausibleEstimateWarning",
    "estimate_table",
    "impulsive_gains",
    "mode_signal",
    "read_measurements",
    "rsls_gains",
    "transition_for",
]

METHODS = METHOD_NAMES
"""The method names, :data:`switchest.estimators.registry.METHOD_NAMES`."""
_WITHOUT_DEFAULT = ("switch_time", "estimate", "v_max", "delta", "Delta", "switch_interval",
                    "smooth", "particles", "seed", "timing", "gate")
"""The options of :func:`estimate_table` that are refused for a method they do not apply to when
set; ``grid``, ``refine`` (which have a default) and ``stay`` apply only where they are used."""


def estimate_table(spec: ModelSpec, data: pd.DataFrame | str | Path, *, method: str, grid: int = 5,
                   refine: bool = False, switch_time: str | None = None,
                   estimate: str | None = None, stay: float | None = None,
                   v_max: float | None = None, delta: float | None = None,
                   Delta: float | None = None,
                   switch_interval: float | None = None, smooth: bool = False,
                   particles: int | None = None, seed: int | None = None,
                   timing: str | None = None, gate: float | None = None,
                   trial: int | None = None) -> pd.DataFrame:
    """Run ``method`` on measured data; returns a table of estimates per sample.

    Parameters
    ----------
    spec : ModelSpec
        The model file (:func:`switchest.modelfile.load_model`).
    data : DataFrame or path of a CSV file
        The measurement table (:mod:`switchest.measurements`; for ``rsls`` the
        ``y`` columns are the integrated output).
    method : str
        One of :data:`METHODS`.
    grid, refine : int, bool
        Switching-time grid points per interval (``switch-time``, ``imm-ev1``) and
        the refinement beyond the grid (``switch-time``).
    switch_time : {"marginal", "max"}, optional
        ``switch-time`` and ``imm-ev1``: weigh the grid's candidate instants by their likelihood
        (``"marginal"``, the default without ``refine``: the covariance counts the instant's
        uncertainty) or take the maximizer of Shankar et al. eq. (23) (``"max"``, the paper's,
        the default with ``refine``: the covariance is conditional on the chosen instant and
        claims far too little on a fast-switching converter); see
        :class:`~switchest.estimators.SwitchTimeKalmanFilter` and
        :class:`~switchest.estimators.IMMEV1Filter`.
    estimate : {"mixture", "map"}, optional
        ``imm-ev1`` only: report the moments of the mixture of the destinations' posteriors
        (``"mixture"``, the default: on the boost converter with the merged instants, NEES
        median 1.7 and :math:`i_L` RMSE 14.7 A) or the MAP destination's (``"map"``, the paper's:
        its covariance ignores the other destinations).
    stay : float, optional
        Per-sample probability of staying in a mode (``imm``, ``imm-ev1``).
    v_max, delta, Delta : float, optional
        ``min-distance`` only: noise bound (Lee et al. eq. (2)), estimation window
        and detection delay (conditions (3), (4)); each overrides the model
        file's ``[noise]`` entry of the same name.
    switch_interval : float, optional
        ``rsls`` only: the switching interval :math:`T` (Wang et al. Assumption 1);
        overrides ``sampling.period``.
    smooth : bool
        ``imm``, ``imm-between``, ``gpb1``, ``gpb2``: fixed-interval smoothed estimates (the
        two-filter smoother, given the whole record) instead of filtered ones. Those of
        ``imm``, ``gpb1`` and ``gpb2`` model the switches at the samples: on a model file whose
        switches fall between them
        (:attr:`~switchest.modelfile.ModelSpec.switches_between_samples`, the boost
        converter's) an :class:`ImplausibleEstimateWarning` says the smoothed estimate need
        not beat the filtered one and names ``imm-between``, whose chain models them there.
    particles, seed : int, optional
        ``rbpf`` only: the number of particles (default 1000) and the seed of its random
        numbers (default 0).
    timing : {"sample", "interval"}, optional
        ``imm``, ``gpb1``, ``gpb2``, ``rbpf``: which interval the mode of a sample governs
        (``"sample"``, the one after it, as ``simulate`` draws; ``"interval"``, Bar-Shalom's,
        the one before it: :doc:`/conventions`). Default: the model file's ``timing``, the
        convention of its data (its system's); another is named in a
        :class:`~switchest.estimators.TimingWarning` by the filter.
    gate : float, optional
        The Kalman-type filters' outlier gate: the largest normalized innovation squared
        :math:`e^\\top S^{-1} e` a measurement may have to be used, e.g.
        ``scipy.stats.chi2.ppf(0.9999, m)``; one beyond it is treated as missing and flagged in
        the ``outlier`` column.
        Default: no gate.
    trial : int, optional
        The trial to estimate from a table of several (a ``trial`` column).

    Returns
    -------
    DataFrame
        ``t``, ``x0 ..``, ``std_x0 ..`` (where the method has a covariance), and
        where the method gives them ``mode`` (nullable integers, empty where
        undefined), ``p_mode0 ..``, ``switch_time`` (NaN where none), and for the filters
        with an outlier gate ``outlier`` (True where the measurement was rejected and
        treated as missing).
    """
    entry = get_method(method)
    if method in ("switch-time", "imm-ev1") and switch_time is None:
        switch_time = "max" if refine else "marginal"
    if method == "imm-ev1" and estimate is None:
        estimate = "mixture"
    options = {"grid": grid, "refine": refine, "switch_time": switch_time, "estimate": estimate,
               "stay": stay, "v_max": v_max, "delta": delta, "Delta": Delta,
               "switch_interval": switch_interval, "smooth": smooth, "particles": particles,
               "seed": seed, "timing": timing, "gate": gate}
    entry.check_options(name for name in _WITHOUT_DEFAULT
                        if options[name] is not None and options[name] is not False)
    meas = read_measurements(data, spec, trial=trial)
    modes = _modes(meas, method) if entry.needs_modes else None
    estimator = entry.build(spec, meas["t"], **{
        name: options[name] for name in entry.options
        if name != "smooth" and options[name] is not None})
    est = entry.run(estimator, meas["y"], meas["u"], meas["t"], modes=modes, smooth=smooth)
    if entry.innovation_check:
        _warn_if_inconsistent(spec, meas, est, modes, method)
    if smooth and spec.switches_between_samples and not entry.between_samples:
        warnings.warn(f"the model file's switches fall between the samples, {method}'s "
                      "smoother models them at the samples: on such data the smoothed "
                      "estimate need not be closer than the filtered one; use method "
                      "'imm-between', whose smoother models them between the samples",
                      ImplausibleEstimateWarning, stacklevel=2)
    return _table(meas["t"], est)


class ImplausibleEstimateWarning(UserWarning):
    """The estimate does not fit the model file or the data: the filter's residuals do not
    match the covariance it claims (:func:`switchest.metrics.innovation_consistency`), or a
    smoother's model of the switches is not the file's."""



# what else makes a method's residuals larger than its covariance claims, with a model that fits
_OWN_APPROXIMATION = {
    "kalman": "; switches between the samples also do it, which method 'switch-time' models",
    "switch-time": ("; so does the filter's own approximation (each switching instant taken "
                    "on its grid of candidates, and the hypotheses merged into one Gaussian "
                    "after each sample: a finer --grid narrows it, and --switch-time max "
                    "claims a covariance as if the chosen instant were the true one)"),
}


def _warn_if_inconsistent(spec: ModelSpec, meas: dict, est: Estimate, modes, method: str) -> None:
    """Warn when the mean normalized innovation squared is more than
    :data:`~switchest.metrics.IMPLAUSIBLE_Z` standard deviations from its value for a consistent
    filter, naming the likely cause."""
    used = None if est.outlier is None else ~np.asarray(est.outlier)
    check = innovation_consistency(spec.system, meas["y"], est.x, est.P, modes, used=used)
    if check.samples < FEWEST_SAMPLES or abs(check.z) <= IMPLAUSIBLE_Z:
        return
    seen = (f"mean normalized innovation squared {check.mean_nis:.3g} over {check.samples} "
            f"samples, {check.expected:g} expected for a filter whose model fits the data "
            f"(z = {check.z:.1f})")
    if check.z > 0:
        cause = ("the residuals are larger than the filter's covariance claims: the mode column, "
                 "the process noise Q or the measurement noise R of the model file do not fit "
                 "the data" + _OWN_APPROXIMATION.get(method, ""))
    else:
        cause = ("the residuals are smaller than the filter's covariance claims: the model "
                 "file's Q or R is larger than the data's")
    warnings.warn(f"implausible estimate ({method}): {seen}; {cause}",
                  ImplausibleEstimateWarning, stacklevel=3)


# ---------------------------------------------------------------------- shared pieces
def _modes(meas: dict, method: str) -> np.ndarray:
    if "mode" not in meas:
        raise ValueError(f"method {method!r} needs the known modes: add a 'mode' column to the "
                         "data")
    return meas["mode"]


def _table(t: np.ndarray, est: Estimate) -> pd.DataFrame:
    n = est.x.shape[-1]
    cols = {"t": t}
    cols.update({f"x{i}": est.x[:, i] for i in range(n)})
    if est.P is not None:
        std = np.sqrt(np.clip(np.diagonal(est.P, axis1=-2, axis2=-1), 0.0, None))
        cols.update({f"std_x{i}": std[:, i] for i in range(n)})
    if est.mode is not None:  # -1 (undefined, e.g. inside a detection window) -> empty
        cols["mode"] = pd.Series(est.mode, dtype="Int64").where(est.mode >= 0)
    if est.mode_prob is not None:
        cols.update({f"p_mode{j}": est.mode_prob[:, j] for j in range(est.mode_prob.shape[-1])})
    if est.switch_time is not None:
        cols["switch_time"] = est.switch_time
    if est.outlier is not None:  # samples the filter's gate rejected (treated as missing)
        cols["outlier"] = np.asarray(est.outlier, dtype=bool)
    return pd.DataFrame(cols)
