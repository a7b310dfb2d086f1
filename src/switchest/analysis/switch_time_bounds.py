"""Error bounds from a switching-time error (Shankar et al., Lemma 2 and Remark 1).

A switch from mode i to mode j at offset :math:`\\bar t` inside a sample interval of
length :math:`T` gives the exact sampled matrices (Shankar et al. eqs (4)-(5)):

.. math::

    \\begin{aligned}
    F &= e^{A_j (T - \\bar t)} e^{A_i \\bar t} \\\\
    G &= F \\int_0^{\\bar t} e^{-A_i \\tau} B_i \\, d\\tau
        + \\int_{\\bar t}^T e^{A_j (T - \\tau)} B_j \\, d\\tau
    \\end{aligned}

An estimate :math:`\\hat t` of the switching time gives :math:`\\hat F`, :math:`\\hat G`; Lemma 2
bounds :math:`\\lVert \\hat F - F \\rVert` and :math:`\\lVert \\hat G - G \\rVert` with
:math:`\\tilde t = \\hat t - \\bar t`.
Norms are spectral norms (the lemma holds for any submultiplicative norm).

Verdict of the numerical check (tests/analysis/test_switch_time_bounds.py: 10 000 random
cases, exact F and G by matrix exponentials): the printed bounds (11) and (12)
hold in every case, and (11) is tight as :math:`T \\to 0`. The proof has typos that do
not reach the printed statement:

* :math:`E_j := e^{-A(j) \\bar t}` must read :math:`e^{-A(j) \\tilde t}`;
* the perturbation in :math:`\\lVert e^{X+Y} - e^X \\rVert
  \\le \\lVert Y \\rVert e^{\\lVert X \\rVert + \\lVert Y \\rVert}` must be
  :math:`Y = -(A(j) - A(i)) \\tilde t`, not :math:`-A(j) \\tilde t - A(i) \\tilde t`; the printed
  (11) does use :math:`\\lVert Y \\rVert = |\\tilde t| \\, \\lVert A(j) - A(i) \\rVert` (a bound
  built on the printed :math:`Y` would be zero for :math:`A(j) = -A(i)` and fails — shown in
  the tests);
* in the expression of :math:`\\tilde G` the middle factor is :math:`e^{A(j)(T - \\bar t)}`
  and the last integrand :math:`e^{-A(j) \\tau} B(j)`;
* in (12) the first term drops the time factor of
  :math:`\\int_0^{\\hat t} e^{\\lVert A(i) \\rVert \\tau} \\, d\\tau
  \\le T e^{\\lVert A(i) \\rVert T}` (it is not dimensionally consistent); the printed (12)
  still held in every case, the slack of its second term absorbing the missing factor.

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
        Bound on :math:`\\lVert \\hat F - F \\rVert` (eq. (11), first line, for ``form="printed"``).
    F_uniform : ndarray
        Eq. (11), second line: :math:`|\\tilde t|` replaced by :math:`T`, valid for every
        :math:`\\hat t` in the interval.
    G : ndarray
        Bound on :math:`\\lVert \\hat G - G \\rVert` (eq. (12)).
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
        Bound on :math:`\\lVert \\mathbb{E}[e_k] \\rVert`, eq. (21).
    trace : ndarray
        Bound on :math:`\\operatorname{tr}(\\Sigma_k)`, eq. (22).
    """

    mean: np.ndarray
    trace: np.ndarray


def switch_matrix_bounds(
    A_i, A_j, B_i, B_j, *, T, t_bar, t_hat, form: Form = "printed", F_error=None
) -> SwitchMatrixBounds:
    """Shankar et al. Lemma 2: bounds on :math:`\\lVert \\hat F - F \\rVert` and
    :math:`\\lVert \\hat G - G \\rVert`.

    With :math:`a = \\lVert A(i) \\rVert`, :math:`b = \\lVert A(j) \\rVert`,
    :math:`d = \\lVert A(j) - A(i) \\rVert`, :math:`\\tilde t = \\hat t - \\bar t`:

    ``form="printed"`` — eqs (11)-(12) as printed:

    .. math::

        \\begin{aligned}
        \\text{(11)} \\quad \\lVert \\tilde F \\rVert &\\le |\\tilde t| \\, d \\, e^{(d + 3a + b) T}
            \\quad \\bigl(\\le T d \\, e^{(d + 3a + b) T}\\bigr) \\\\
        \\text{(12)} \\quad \\lVert \\tilde G \\rVert &\\le \\lVert \\tilde F \\rVert e^{aT}
            \\lVert B(i) \\rVert + |\\tilde t| e^{bT} \\bigl(e^{aT} \\lVert B(i) \\rVert
            + e^{bT} \\lVert B(j) \\rVert\\bigr)
        \\end{aligned}

    ``form="proof"`` — the proof's own inequalities, typos corrected, before the
    exponents are rounded up to :math:`T`. From :math:`\\hat F = F_j (E_j E_i) F_i` with
    :math:`F_j = e^{A(j)(T - \\bar t)}`, :math:`F_i = e^{A(i) \\bar t}`,
    :math:`E_j = e^{-A(j) \\tilde t}`, :math:`E_i = e^{A(i) \\tilde t}`, and
    :math:`\\lVert e^{X+Y} - e^X \\rVert
    \\le \\lVert Y \\rVert e^{\\lVert X \\rVert + \\lVert Y \\rVert}` at
    :math:`X = -A(i) \\tilde t`, :math:`Y = -(A(j) - A(i)) \\tilde t`:

    .. math::

        \\lVert \\tilde F \\rVert \\le |\\tilde t| \\, d \\, e^{(d + 2a)|\\tilde t|}
        e^{b (T - \\bar t) + a \\bar t}

    and from :math:`\\tilde G = \\tilde F \\int_0^{\\hat t} e^{-A(i) s} B(i) \\, ds
    + e^{A(j)(T - \\bar t)} \\int_0^{\\tilde t} (e^{-A(i) s} B(i) - e^{-A(j) s} B(j)) \\, ds`:

    .. math::

        \\begin{aligned}
        \\lVert \\tilde G \\rVert \\le{} & \\lVert \\tilde F \\rVert \\lVert B(i) \\rVert
            \\psi(a, \\hat t) \\\\
        & + e^{b (T - \\bar t)} \\bigl(\\lVert B(i) \\rVert \\psi(a, |\\tilde t|)
            + \\lVert B(j) \\rVert \\psi(b, |\\tilde t|)\\bigr)
        \\end{aligned}

    with :math:`\\psi(c, s) = (e^{cs} - 1) / c` (:math:`= s` at :math:`c = 0`). ``F_uniform``
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
        True and estimated switching offsets inside the interval, in :math:`[0, T]`.
    form : {"printed", "proof"}, optional
        Which inequalities to evaluate (keyword-only).
    F_error : float or array_like, optional
        A value of :math:`\\lVert \\hat F - F \\rVert` to use in the G bound instead of the F
        bound (e.g. the exact one).

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

    From :math:`e_k = (I - K H) z_k + K v_k` (eq. (13)) and
    :math:`\\Sigma_k = (I - K H) \\Omega_k (I - K H)^\\top + K R K^\\top` (eq. (16)):

    .. math::

        \\begin{aligned}
        \\text{(21)} \\quad \\lVert \\mathbb{E}[e_k] \\rVert
            &\\le \\lVert I - K H \\rVert \\, \\lVert \\mathbb{E}[z_k] \\rVert \\\\
        \\text{(22)} \\quad \\operatorname{tr}(\\Sigma_k)
            &\\le \\lVert I - K H \\rVert^2 \\operatorname{tr}(\\Omega_k)
            + \\lVert K \\rVert^2 \\operatorname{tr}(R)
        \\end{aligned}

    (spectral norms; (22) uses :math:`\\operatorname{tr}(X \\Omega X^\\top)
    \\le \\lVert X \\rVert^2 \\operatorname{tr}(\\Omega)` for :math:`\\Omega \\succeq 0`).
    Both are exact consequences of (13) and (16).

    Parameters
    ----------
    K : array_like, shape (..., n, m)
        Kalman gain :math:`K_{k-1}`.
    H : array_like, shape (m, n)
        Output matrix.
    mean_prediction_error : float or array_like
        A bound on (or the value of) :math:`\\lVert \\mathbb{E}[z_k] \\rVert`, e.g. from Theorem 1
        eq. (19).
    prediction_mse_trace : float or array_like
        A bound on (or the value of) :math:`\\operatorname{tr}(\\Omega_k)`, e.g. from eq. (20).
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
    """:math:`\\int_0^s e^{c \\tau} \\, d\\tau = (e^{cs} - 1)/c`, equal to :math:`s` at
    :math:`c = 0`."""
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
