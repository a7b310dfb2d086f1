"""The Kalman equations as functions over stacks, on the compiled engine.

:func:`kf_predict` and :func:`kf_update` take any leading batch axes (trials, modes,
hypotheses, grid points; the last one or two are the vector or matrix; shapes broadcast) and
run one sample of the compiled Kalman kernel
(:func:`switchest.engine.kalman.kalman_step`) on the flattened stack: the one
implementation of each equation that every filter runs.

``steady_state_gain`` (the Riccati equation of one mode) is a design and lives in
:mod:`switchest.analysis.steady_state_kalman` (numpy and scipy.linalg only); it stays
importable from here.
"""

from __future__ import annotations

import math

import numpy as np

from .._checks import check_cores, float_array, positive_scalar
from ..analysis.steady_state_kalman import steady_state_gain
from ..engine import GATED, raise_for_status, warn_for_repairs
from ..engine.kalman import kalman_step

__all__ = ["kf_predict", "kf_update", "steady_state_gain"]


def kf_predict(x, P, F, G, u, Qd, *, inflation: float = 0.0):
    """Time update :math:`x^- = F x + G u`, :math:`P^- = FPF^\\top + Q_d (+ \\mathrm{inflation} I)`.

    Shankar et al. eqs (6)-(7) with the process noise of the exact discretization
    added; ``inflation`` is the :math:`\\epsilon I` of their Algorithm 1 (§IV). Shapes
    broadcast over leading axes (a 2-D ``F`` or ``Qd`` is shared by the whole
    stack); ``u`` may have a zero-length last axis. The kernel runs the prediction
    with a measurement that is never observed, so nothing is updated.
    """
    arrays = _stack({"x": x, "P": P, "F": F, "G": G, "u": u, "Qd": Qd},
                    {"x": "n", "P": "nn", "F": "nn", "G": "nl", "u": "l", "Qd": "nn"})
    batch, N, flat = arrays.pop("batch"), arrays.pop("N"), arrays
    n = flat["x"].shape[-1]
    Qd = flat["Qd"]
    inflation = positive_scalar(inflation, "inflation", allow_zero=True)
    if inflation:
        Qd = Qd + inflation * np.eye(n)
    out = kalman_step(flat["x"], flat["P"], np.full((N, 1), np.nan), flat["u"], flat["F"],
                      flat["G"], Qd, np.zeros((N, 1, n)), np.ones((N, 1, 1)), predict_first=True)
    raise_for_status(out.status)
    return out.x.reshape(*batch, n), out.P.reshape(*batch, n, n)


def kf_update(x, P, y, C, R, *, gate: float | None = None):
    """Measurement update with innovation log-likelihood; NaN entries of ``y`` are missing.

    :math:`S = C P C^\\top + R`, :math:`K = P C^\\top S^{-1}` by a Cholesky solve of the
    equilibrated :math:`S` (no inverse), :math:`x^+ = x + K (y - C x)`, and the covariance in
    Joseph form :math:`P^+ = (I - K C) P (I - K C)^\\top + K R K^\\top` (Shankar et al. eqs
    (8)-(10) in their numerically stable form); where Joseph's form loses its digits (a
    diffuse prior) the information form. The log-likelihood is
    :math:`\\log \\mathcal{N}(y; C x, S) = -(e^\\top S^{-1} e + \\log \\det S + m \\log 2\\pi) / 2`.

    A missing component (NaN) is removed exactly, so the update uses the observed
    components only and the log-likelihood is that of their marginal. An all-NaN ``y``
    leaves ``x, P`` unchanged with log-likelihood 0. A 2-D ``C`` or ``R`` is shared by the
    whole stack.

    A measurement is *rejected* when its normalized innovation squared is not finite (a
    measurement so far off that it overflows, e.g. ``1e300``) or exceeds ``gate``: ``x, P``
    are left unchanged, as for a missing measurement, and the log-likelihood is ``-inf``
    (the likelihood truncated to zero outside the gate), so that a caller tells a rejected
    measurement (``-inf``) from a missing one (0).

    Parameters
    ----------
    x, P : array_like
        Prior mean ``(..., n)`` and covariance ``(..., n, n)``.
    y : array_like, shape (..., m)
    C, R : array_like
        ``(..., m, n)`` and ``(..., m, m)``.
    gate : float, optional
        Largest normalized innovation squared accepted (keyword-only); ``None``
        rejects only measurements whose innovation overflows.

    Returns
    -------
    x, P, loglik
        Updated mean ``(..., n)``, covariance ``(..., n, n)`` and log-likelihood ``(...)``.

    Raises
    ------
    numpy.linalg.LinAlgError
        If ``S`` is not positive definite, or ``S`` or ``P`` is not finite (overflowed).

    Notes
    -----
    A state covariance whose condition number exceeds :math:`1/\\varepsilon` can lose positive
    semidefiniteness to round-off; such a covariance — a posterior found indefinite, or a
    prior whose ``S`` fails its factorization — is repaired: its eigenvalues are raised to
    its rounding level :math:`n \\varepsilon \\max |\\operatorname{eig} P|`, with a
    ``RuntimeWarning`` (and the update is retried once).
    """
    arrays = _stack({"x": x, "P": P, "y": y, "C": C, "R": R},
                    {"x": "n", "P": "nn", "y": "m", "C": "mn", "R": "mm"})
    batch, N, flat = arrays.pop("batch"), arrays.pop("N"), arrays
    n = flat["x"].shape[-1]
    gate = math.inf if gate is None else positive_scalar(gate, "gate")
    out = kalman_step(flat["x"], flat["P"], flat["y"], np.zeros((N, 0)), np.zeros((N, n, n)),
                      np.zeros((N, n, 0)), np.zeros((N, n, n)), flat["C"], flat["R"],
                      predict_first=False, gate=gate)
    raise_for_status(out.status)
    warn_for_repairs(out)
    loglik = np.where(out.flag == GATED, -np.inf, out.loglik)
    return out.x.reshape(*batch, n), out.P.reshape(*batch, n, n), loglik.reshape(batch)


def _stack(arrays: dict, cores: dict) -> dict:
    """The arrays with their batch axes broadcast and flattened to one, ``(N, ...)``, with
    ``"batch"`` (the broadcast shape) and ``"N"`` (shapes checked by
    :func:`switchest._checks.check_cores`)."""
    arrays = {k: float_array(v, k) for k, v in arrays.items()}
    batch = check_cores(arrays, cores)
    N = int(np.prod(batch, dtype=np.int64))
    flat = {}
    for name, arr in arrays.items():
        core = arr.shape[arr.ndim - len(cores[name]):]
        flat[name] = np.broadcast_to(arr, (*batch, *core)).reshape(N, *core)
    return {**flat, "batch": batch, "N": N}

