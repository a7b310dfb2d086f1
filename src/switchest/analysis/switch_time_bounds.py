"""Error bounds from a switching-time error (Shankar et al., Lemma 2 and Remark 1).

A switch from mode i to mode j at offset ``t_bar`` inside a sample interval of
length ``T`` gives the exact sampled matrices (Shankar et al. eqs (4)-(5))::

    F = e^{A_j (T - t_bar)} e^{A_i t_bar}
    G = F int_0^{t_bar} e^{-A_i tau} B_i dtau + int_{t_bar}^T e^{A_j (T - tau)} B_j dtau

An estimate ``t_hat`` of the switching time gives ``F_hat``, ``G_hat``; Lemma 2
bounds ``||F_hat - F||`` and ``||G_hat - G||`` with ``t_tilde = t_hat - t_bar``.
Norms are spectral norms (the lemma holds for any submultiplicative norm).

Verdict of the numerical check (tests/analysis/test_switch_time_bounds.py: 10 000 random
cases, exact F and G by matrix exponentials): the printed bounds (11) and (12)
hold in every case, and (11) is tight as ``T -> 0``. The proof has typos that do
not reach the printed statement:

* ``E_j := e^{-A(j) t_bar}`` must read ``e^{-A(j) t_tilde}``;
* the perturbation in ``||e^{X+Y} - e^X|| <= ||Y|| e^{||X|| + ||Y||}`` must be
  ``Y = -(A(j) - A(i)) t_tilde``, not ``-A(j) t_tilde - A(i) t_tilde``; the printed
  (11) does use ``||Y|| = |t_tilde| ||A(j) - A(i)||`` (a bound built on the printed
  ``Y`` would be zero for ``A(j) = -A(i)`` and fails — shown in the tests);
* in the expression of ``G_tilde`` the middle factor is ``e^{A(j)(T - t_bar)}``
  and the last integrand ``e^{-A(j) tau} B(j)``;
* in (12) the first term drops the time factor of
  ``int_0^{t_hat} e^{||A(i)|| tau} dtau <= T e^{||A(i)|| T}`` (it is not
  dimensionally consistent); the printed (12) still held in every case, the
  slack of its second term absorbing the missing factor.

``form="proof"`` evaluates the tighter intermediate inequalities of the proof,
typos corrected; both forms are tested.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from .._checks import broadcast_batch, check_finite, check_symmetric_psd, float_array

__all__ = [
    "EstimationErrorBounds",
    "SwitchMatrixBounds",
    "estimation_error_bounds",
    "switch_matrix_bounds",
]

Form = Literal["printed", "proof"]


@dataclass(frozen=True)
class SwitchMatrixBounds:
    """Bounds of Shankar et al. Lemma 2 (:func:`switch_matrix_bounds`), over the batch shape.

    Attributes
    ----------
    F : ndarray
        Bound on ``||F_hat - F||`` (eq. (11), first line, for ``form="printed"``).
    F_uniform : ndarray
        Eq. (11), second line: ``|t_tilde|`` replaced by ``T``, valid for every
        ``t_hat`` in the interval.
    G : ndarray
        Bound on ``||G_hat - G||`` (eq. (12)).
    form : str
        ``"printed"`` or ``"proof"``.
    """

    F: np.ndarray
    F_uniform: np.ndarray
    G: np.ndarray
    form: str


@dataclass(frozen=True)
class EstimationErrorBounds:
    """Bounds of Shankar et al. Remark 1 (:func:`estimation_error_bounds`).

    Attributes
    ----------
    mean : ndarray
        Bound on ``||E[e_k]||``, eq. (21).
    trace : ndarray
        Bound on ``tr(Sigma_k)``, eq. (22).
    """

    mean: np.ndarray
    trace: np.ndarray


def switch_matrix_bounds(
    A_i, A_j, B_i, B_j, *, T, t_bar, t_hat, form: Form = "printed", F_error=None
) -> SwitchMatrixBounds:
    """Shankar et al. Lemma 2: bounds on ``||F_hat - F||`` and ``||G_hat - G||``.

    With ``a = ||A(i)||``, ``b = ||A(j)||``, ``d = ||A(j) - A(i)||``,
    ``t_tilde = t_hat - t_bar``:

    ``form="printed"`` — eqs (11)-(12) as printed::

        (11)  ||F~|| <= |t~| d e^{(d + 3a + b) T}  (<= T d e^{(d + 3a + b) T})
        (12)  ||G~|| <= ||F~|| e^{aT} ||B(i)|| + |t~| e^{bT} (e^{aT} ||B(i)|| + e^{bT} ||B(j)||)

    ``form="proof"`` — the proof's own inequalities, typos corrected, before the
    exponents are rounded up to ``T``. From ``F_hat = F_j (E_j E_i) F_i`` with
    ``F_j = e^{A(j)(T - t_bar)}``, ``F_i = e^{A(i) t_bar}``,
    ``E_j = e^{-A(j) t~}``, ``E_i = e^{A(i) t~}``, and
    ``||e^{X+Y} - e^X|| <= ||Y|| e^{||X|| + ||Y||}`` at ``X = -A(i) t~``,
    ``Y = -(A(j) - A(i)) t~``::

        ||F~|| <= |t~| d e^{(d + 2a)|t~|} e^{b (T - t_bar) + a t_bar}

    and from ``G~ = F~ int_0^{t_hat} e^{-A(i) s} B(i) ds
    + e^{A(j)(T - t_bar)} int_0^{t~} (e^{-A(i) s} B(i) - e^{-A(j) s} B(j)) ds``::

        ||G~|| <= ||F~|| ||B(i)|| psi(a, t_hat)
                  + e^{b (T - t_bar)} (||B(i)|| psi(a, |t~|) + ||B(j)|| psi(b, |t~|))

    with ``psi(c, s) = (e^{cs} - 1) / c`` (``= s`` at ``c = 0``). ``F_uniform``
    is the printed second line of (11) in both forms.

    Parameters
    ----------
    A_i, A_j : array_like, shape (..., n, n)
        Modes before and after the switch (continuous time).
    B_i, B_j : array_like, shape (..., n, l)
        Their input matrices.
    T : float or array_like
        Sampling period, positive; broadcast against the batch shape.
    t_bar, t_hat : float or array_like
        True and estimated switching offsets inside the interval, in ``[0, T]``.
    form : {"printed", "proof"}, optional
        Which inequalities to evaluate (keyword-only).
    F_error : float or array_like, optional
        A value of ``||F_hat - F||`` to use in the G bound instead of the F bound
        (e.g. the exact one).

    Returns
    -------
    SwitchMatrixBounds
        Arrays over the broadcast batch shape.
    """
    A_i = _stack(A_i, "A_i")
    A_j = _stack(A_j, "A_j")
    if A_i.shape[-1] != A_i.shape[-2] or A_j.shape[-2:] != A_i.shape[-2:]:
        raise ValueError(
            f"A_i and A_j must be square with one shape (n, n), got {A_i.shape} and {A_j.shape}"
        )
    n = A_i.shape[-1]
    B_i = _stack(B_i, "B_i")
    B_j = _stack(B_j, "B_j")
    for name, B in (("B_i", B_i), ("B_j", B_j)):
        if B.shape[-2] != n:
            raise ValueError(f"{name} must have shape (..., {n}, l), got {B.shape}")
    if not isinstance(form, str) or form not in ("printed", "proof"):
        raise ValueError(f"form must be 'printed' or 'proof', got {form!r}")
    T = _times(T, "T")
    t_bar = _times(t_bar, "t_bar")
    t_hat = _times(t_hat, "t_hat")
    F_error = None if F_error is None else _times(F_error, "F_error")
    shapes = {"A_i": A_i.shape[:-2], "A_j": A_j.shape[:-2], "B_i": B_i.shape[:-2],
              "B_j": B_j.shape[:-2], "T": T.shape, "t_bar": t_bar.shape, "t_hat": t_hat.shape}
    broadcast_batch(shapes if F_error is None else {**shapes, "F_error": F_error.shape})
    if F_error is not None and np.any(F_error < 0):
        raise ValueError(f"F_error must be a norm (non-negative), got minimum {F_error.min():.3g}")
    if np.any(T <= 0):
        raise ValueError(f"T must be positive, got minimum {T.min():.3g}")
    for name, t in (("t_bar", t_bar), ("t_hat", t_hat)):
        T_b, t_b = np.broadcast_arrays(T, t)
        if np.any(t_b < 0) or np.any(t_b > T_b):
            raise ValueError(
                f"{name} must lie in [0, T], got a value outside it: {t_b.ravel()[0]:.3g}"
            )
    a, b = _norm(A_i), _norm(A_j)
    d = _norm(A_j - A_i)
    nb_i, nb_j = _norm(B_i), _norm(B_j)
    tt = np.abs(t_hat - t_bar)
    F_uniform = T * d * np.exp((d + 3 * a + b) * T)
    if form == "printed":
        F_bound = tt * d * np.exp((d + 3 * a + b) * T)
    else:
        F_bound = tt * d * np.exp((d + 2 * a) * tt + b * (T - t_bar) + a * t_bar)
    F_use = F_bound if F_error is None else F_error
    if form == "printed":
        G_bound = F_use * np.exp(a * T) * nb_i + tt * np.exp(b * T) * (
            np.exp(a * T) * nb_i + np.exp(b * T) * nb_j
        )
    else:
        G_bound = F_use * nb_i * _psi(a, t_hat) + np.exp(b * (T - t_bar)) * (
            nb_i * _psi(a, tt) + nb_j * _psi(b, tt)
        )
    shape = np.broadcast_shapes(F_bound.shape, G_bound.shape, F_uniform.shape)
    return SwitchMatrixBounds(
        F=np.broadcast_to(F_bound, shape).copy(),
        F_uniform=np.broadcast_to(F_uniform, shape).copy(),
        G=np.broadcast_to(G_bound, shape).copy(),
        form=form,
    )


def estimation_error_bounds(K, H, *, mean_prediction_error, prediction_mse_trace, R):
    """Shankar et al. Remark 1: estimation-error bounds from prediction-error bounds.

    From ``e_k = (I - K H) z_k + K v_k`` (eq. (13)) and
    ``Sigma_k = (I - K H) Omega_k (I - K H)' + K R K'`` (eq. (16))::

        (21)  ||E[e_k]||   <= ||I - K H|| ||E[z_k]||
        (22)  tr(Sigma_k)  <= ||I - K H||^2 tr(Omega_k) + ||K||^2 tr(R)

    (spectral norms; (22) uses ``tr(X Omega X') <= ||X||^2 tr(Omega)`` for
    ``Omega >= 0``). Both are exact consequences of (13) and (16).

    Parameters
    ----------
    K : array_like, shape (..., n, m)
        Kalman gain ``K_{k-1}``.
    H : array_like, shape (m, n)
        Output matrix.
    mean_prediction_error : float or array_like
        A bound on (or the value of) ``||E[z_k]||``, e.g. from Theorem 1 eq. (19).
    prediction_mse_trace : float or array_like
        A bound on (or the value of) ``tr(Omega_k)``, e.g. from eq. (20).
    R : array_like, shape (m, m)
        Measurement-noise covariance, symmetric positive semidefinite.

    Returns
    -------
    EstimationErrorBounds
    """
    K = _stack(K, "K")
    H = float_array(H, "H", ndim=2)
    check_finite(H, "H")
    n, m = K.shape[-2:]
    if H.shape != (m, n):
        raise ValueError(
            f"H must have shape ({m}, {n}) to match K of shape {K.shape}, got {H.shape}"
        )
    R = float_array(R, "R", ndim=2)
    if R.shape != (m, m):
        raise ValueError(f"R must have shape ({m}, {m}), got {R.shape}")
    R = check_symmetric_psd(R, "R")
    z_mean = _times(mean_prediction_error, "mean_prediction_error")
    omega_tr = _times(prediction_mse_trace, "prediction_mse_trace")
    broadcast_batch({"K": K.shape[:-2], "mean_prediction_error": z_mean.shape,
                     "prediction_mse_trace": omega_tr.shape})
    for name, v in (("mean_prediction_error", z_mean), ("prediction_mse_trace", omega_tr)):
        if np.any(v < 0):
            raise ValueError(f"{name} must be non-negative, got minimum {v.min():.3g}")
    gain = _norm(np.eye(n) - K @ H)
    return EstimationErrorBounds(
        mean=gain * z_mean,
        trace=gain**2 * omega_tr + _norm(K) ** 2 * np.trace(R),
    )


def _psi(c: np.ndarray, s: np.ndarray) -> np.ndarray:
    """``int_0^s e^{c tau} dtau = (e^{cs} - 1)/c``, equal to ``s`` at ``c = 0``."""
    cs = c * s
    return np.where(cs == 0, s, s * np.expm1(cs) / np.where(cs == 0, 1.0, cs))


def _norm(M: np.ndarray) -> np.ndarray:
    """Spectral norm of each matrix in a stack; 0 for empty matrices."""
    if M.shape[-1] == 0 or M.shape[-2] == 0:
        return np.zeros(M.shape[:-2])
    return np.linalg.norm(M, ord=2, axis=(-2, -1))


def _stack(value, name: str) -> np.ndarray:
    arr = float_array(value, name)
    if arr.ndim < 2:
        raise ValueError(f"{name} must be a matrix or a stack of matrices, got shape {arr.shape}")
    check_finite(arr, name)
    return arr


def _times(value, name: str) -> np.ndarray:
    arr = float_array(value, name)
    check_finite(arr, name)
    return arr
