"""Bias of a mode-based Kalman filter under mode mismatch (Zhang & Natarajan, paper 001).

A Kalman filter that runs with a wrong mode ``i`` while the system is in mode ``t`` is
biased. With steady-state gains :math:`K_i` the bias
:math:`e_k = \\mathbb{E}(\\hat x_k) - \\mathbb{E}(x_k)` obeys (Zhang eqs. (6)–(7))

.. math::

    \\begin{aligned}
    e_k &= \\Lambda_i e_{k-1} + (\\Lambda_i - \\Gamma_{i,t}) \\mathbb{E}(x_{k-1}), \\\\
    \\Lambda_i &= A_i - K_i C_i A_i, \\qquad \\Gamma_{i,t} = A_t - K_i C_t A_t,
    \\end{aligned}

and, when the filter's mode is ``i`` with probability ``lam[i, t]`` given the true
mode ``t``, its mean follows the transformed switched system (9)–(10)

.. math::

    \\begin{aligned}
    x^*_k &= F_t x^*_{k-1} + G_t u_{k-1}, \\qquad F_t = \\sum_i \\lambda_{i,t} \\Lambda_i, \\\\
    G_t &= \\sum_i \\lambda_{i,t} (\\Lambda_i - \\Gamma_{i,t}), \\qquad u_k = \\mathbb{E}(x_k).
    \\end{aligned}

Conventions (0-based modes; the paper's are 1-based):

* ``lam[i, q]``
  :math:`= \\lambda_{i,q} = P(\\text{filter uses mode } i \\mid \\text{true mode } q)`: each
  **column** sums to one (the paper's :math:`\\sum_i \\lambda_{i,q} = 1`). This is the
  transpose of the row-stochastic ``transition`` convention used elsewhere in switchest.
* ``S[i, q]`` :math:`= \\Lambda_i - \\Gamma_{i,q}` is the matrix :math:`T_{i,q}` of Algorithm 2
  and :math:`S_{i,q}` of eqs. (17)–(18); ``S[q, q]`` :math:`= 0`.
* Gains are the filter (a-posteriori update) form of Algorithm 1, line 8:
  :math:`K_i = M_i C_i^\\top (C_i M_i C_i^\\top + R_i)^{-1}` with :math:`M_i` the steady
  **a-priori** covariance, the stabilizing solution of the filter DARE
  :math:`M = A M A^\\top - A M C^\\top (C M C^\\top + R)^{-1} C M A^\\top + Q`. This convention
  reproduces the printed :math:`\\Lambda_1, \\Lambda_2, \\Gamma_{1,2}, \\Gamma_{2,1}` of Example 1
  (§5.1) to all four printed decimals; the a-posteriori covariance in its place does not.

The text of the paper (as available) prints :math:`\\Lambda` as "A" in many places (Example 1's
matrices, :math:`\\lVert A_q \\rVert` in §5.1–5.2, Lemma 3, Theorem 3, eq. (17), Algorithm 2's
:math:`T = A_i - F_{i,q}`); the proofs and numbers show :math:`\\Lambda` is meant, and
:math:`\\Lambda` is implemented. Other printed numbers checked against this module
(tests/analysis/test_mode_mismatch.py):

* §5.2 (smart grid, :math:`\\tau = 0.1`): :math:`\\lVert \\Lambda_1 \\rVert = 0.9817` and the
  mode-1 entries of :math:`T_{1,2}`, :math:`T_{1,3}` are not the steady-state values (0.9828,
  -0.3307, 0.0376) but those of the Algorithm 1 gain after about 100 steps (99 from
  :math:`\\Sigma_0 = I`, :func:`riccati_gains`); mode 1's Riccati recursion converges slowly.
* §5.2: printed :math:`T_{2,3}[2,2] = -0.0088` and :math:`T_{3,2}[2,2] = 0.0086` are ten times
  the computed -0.00088 and 0.00086 (a slipped decimal).
* Fig. 6: :math:`\\lambda_{1,2} = \\lambda_{2,1} = 0.154554` for :math:`B = 0.3` needs the
  unstated :math:`\\eta \\cdot \\sup \\lVert u \\rVert = 1.04` in eq. (18).
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import product

import numpy as np
from scipy.linalg import schur

from .._checks import (
    broadcast_batch,
    check_finite,
    check_symmetric_psd,
    float_array,
    int_array,
    positive_int,
    positive_scalar,
)
from .._linalg import joseph_update, psd_sqrt
from ..system import SwitchedLinearSystem
from .observability import is_observable
from .stability import LyapunovCertificate, cqlf, decrease_margin, spectral_radius
from .steady_state_kalman import steady_state_gain

__all__ = [
    "AutonomousBiasStability",
    "MismatchDynamics",
    "ToleranceCheck",
    "TransformedSystem",
    "UnstableComponents",
    "autonomous_stability",
    "bias_recursion",
    "bibo_gain",
    "filter_stability_hypotheses",
    "max_mismatch_probability",
    "mean_state",
    "mismatch_dynamics",
    "riccati_gains",
    "stable_mismatch_region",
    "steady_state_gains",
    "mismatch_bias_bound",
    "tolerance_region",
    "transformed_system",
    "unstable_components",
]

_COLUMN_TOL = 1e-9


# ---------------------------------------------------------------------- results
@dataclass(frozen=True, eq=False)
class MismatchDynamics:
    """Per-mode matrices of the mismatch bias, Zhang & Natarajan equations (6)–(7).

    Attributes
    ----------
    K : ndarray, shape (L, n, m)
        Kalman gain of each mode (filter form, Algorithm 1 line 8).
    Lambda : ndarray, shape (L, n, n)
        ``Lambda[i]`` :math:`= A_i - K_i C_i A_i` (eq. (7)).
    Gamma : ndarray, shape (L, L, n, n)
        ``Gamma[i, t]`` :math:`= A_t - K_i C_t A_t` (eq. (7)); :math:`\\Gamma_{i,i} = \\Lambda_i`.
    """

    K: np.ndarray
    Lambda: np.ndarray
    Gamma: np.ndarray

    @property
    def S(self) -> np.ndarray:
        """``S[i, q]`` :math:`= \\Lambda_i - \\Gamma_{i,q}`, shape (L, L, n, n).

        The :math:`T_{i,q}` of Algorithm 2 and :math:`S_{i,q}` of eqs. (17)–(18); it is the
        input matrix of eq. (7) when the filter uses mode i and the system is in q.
        """
        return self.Lambda[:, None] - self.Gamma

    @property
    def n_modes(self) -> int:
        """Number of modes L."""
        return self.Lambda.shape[0]


@dataclass(frozen=True, eq=False)
class TransformedSystem:
    """The transformed switched system (10) of the mean bias, for given mismatch probabilities.

    Attributes
    ----------
    F : ndarray, shape (L, n, n)
        ``F[q]`` :math:`= \\sum_i \\lambda_{i,q} \\Lambda_i`.
    G : ndarray, shape (L, n, n)
        ``G[q]`` :math:`= \\sum_i \\lambda_{i,q} (\\Lambda_i - \\Gamma_{i,q})`.
    lam : ndarray, shape (L, L)
        The mismatch probabilities,
        ``lam[i, q]`` :math:`= P(\\text{filter mode } i \\mid \\text{true mode } q)`.
    """

    F: np.ndarray
    G: np.ndarray
    lam: np.ndarray


@dataclass(frozen=True, eq=False)
class AutonomousBiasStability:
    """Stability of the autonomous bias system (11), Zhang Lemmas 3–4, Theorems 2–3.

    Attributes
    ----------
    lambda_radius : ndarray, shape (L,)
        :math:`\\rho(\\Lambda_i)`; Lemma 3 says each is below one for a controllable and
        observable mode.
    certificate : LyapunovCertificate
        Common quadratic Lyapunov function of :math:`\\{\\Lambda_i\\}` (eq. (13)). When it is
        feasible, Theorem 2 (every :math:`F_q` is Schur) and Theorem 3 (the same :math:`P`
        is a CQLF of every :math:`F_q`, so (11) is asymptotically stable under
        arbitrary switching) hold for **every** choice of lam.
    F_radius : ndarray, shape (L,), or None
        :math:`\\rho(F_q)` for the lam given (Lemma 2's direct test); None without lam.
    F_margin : float or None
        :math:`\\min_q -\\max \\operatorname{eig}(F_q^\\top P F_q - P)` with :math:`P` of
        ``certificate``: Theorem 3's conclusion checked with numpy (positive when it holds); NaN
        when there is no certificate, None without lam.
    one_mode_per_column : bool or None
        Lemma 4's hypothesis: every column of lam has exactly one non-zero entry
        (then :math:`F_q = \\Lambda_{k_q}`); None without lam.
    """

    lambda_radius: np.ndarray
    certificate: LyapunovCertificate
    F_radius: np.ndarray | None
    F_margin: float | None
    one_mode_per_column: bool | None

    @property
    def each_mode_contracts(self) -> bool:
        """Lemma 3's conclusion: :math:`\\rho(\\Lambda_i) < 1` for every mode."""
        return bool(np.all(self.lambda_radius < 1.0))

    @property
    def holds(self) -> bool:
        """Theorems 2–3: a CQLF of :math:`\\{\\Lambda_i\\}` exists, so (11) is stable
        for every lam."""
        return self.certificate.holds


@dataclass(frozen=True, eq=False)
class UnstableComponents:
    """The set :math:`I` of unstable state components of the original system
    (Algorithm 2, step 2).

    Attributes
    ----------
    components : ndarray of bool, shape (n,)
        ``components[j]`` is True when state component j is in :math:`I`.
    certificate : LyapunovCertificate
        CQLF of :math:`\\{A_i\\}` (Algorithm 2, step 1). When feasible the original system is
        asymptotically stable under arbitrary switching and :math:`I` is empty.
    words : tuple of tuple of int
        Mode words (0-based, first applied first) whose product has an eigenvalue
        of modulus :math:`\\ge 1`; each witnesses the components it marks.
    holds : bool or None
        The original system is asymptotically stable under arbitrary switching: True
        with a CQLF, False when a product in ``words`` witnesses an eigenvalue of modulus
        :math:`\\ge 1`, None when neither was found up to ``max_length`` (stability undecided, every
        component marked: the conservative choice).
    """

    components: np.ndarray
    certificate: LyapunovCertificate
    words: tuple[tuple[int, ...], ...]
    holds: bool | None

    @property
    def conclusive(self) -> bool:
        """Deprecated: ``holds is not None`` (stability decided)."""
        return self.holds is not None


@dataclass(frozen=True, eq=False)
class ToleranceCheck:
    """The tolerance test of Zhang & Natarajan, equation (18), for given mismatch probabilities.

    Attributes
    ----------
    value : ndarray, shape (L,)
        :math:`\\sum_{i \\ne q} \\lambda_{i,q} \\lVert S_{i,q} \\rVert` for each true mode
        :math:`q`.
    threshold : float
        :math:`B / (\\eta \\sup \\lVert u \\rVert)`.
    holds : bool
        :math:`\\max_q \\mathrm{value}_q \\le \\mathrm{threshold}`: lam lies in the tolerance
        region, so the bias bound :math:`B` is guaranteed by (14).
    """

    value: np.ndarray
    threshold: float
    holds: bool


# ---------------------------------------------------------------------- gains
def steady_state_gains(system: SwitchedLinearSystem) -> np.ndarray:
    """Steady-state Kalman gain of each mode (Zhang & Natarajan, equation (6)).

    :math:`K_i = M_i C_i^\\top (C_i M_i C_i^\\top + R_i)^{-1}` with :math:`M_i` the stabilizing
    solution of the filter Riccati equation of mode i (the limit of :math:`M_{k|k-1}` in
    Algorithm 1 with the mode held at i), from
    :func:`.steady_state_kalman.steady_state_gain` (``scipy.linalg.solve_discrete_are``).

    Parameters
    ----------
    system : SwitchedLinearSystem
        Discrete time, with measurement noise (``R`` positive definite).

    Returns
    -------
    ndarray, shape (L, n, m)

    Raises
    ------
    ValueError
        If the system is continuous, noise-free, or a mode has no stabilizing
        Riccati solution (not detectable / not stabilizable on the unit circle).
    """
    _check_filterable(system)
    gains = []
    for i in range(system.n_modes):
        A, C, Q, R = system.A[i], system.C[i], system.Q[i], system.R[i]
        try:
            K = steady_state_gain(A, C, Q, R)[0]
        except (np.linalg.LinAlgError, ValueError) as exc:
            raise ValueError(
                f"system mode {i} has no stabilizing steady-state Kalman covariance "
                f"(is (C, A) detectable and (A, Q^1/2) stabilizable?): {exc}"
            ) from exc
        gains.append(K)
    return np.stack(gains)


def riccati_gains(system: SwitchedLinearSystem, *, P0, steps: int) -> np.ndarray:
    """Kalman gain of each mode after ``steps`` steps of Algorithm 1 (Zhang & Natarajan).

    Runs lines 6–10 of Algorithm 1 with the mode held at i from :math:`M_{0|0}` = ``P0``:

    .. math::

        \\begin{aligned}
        M_{k|k-1} &= A_i M_{k-1|k-1} A_i^\\top + Q_i, \\\\
        K_{i,k} &= M_{k|k-1} C_i^\\top (C_i M_{k|k-1} C_i^\\top + R_i)^{-1}, \\\\
        M_{k|k} &= (I - K_{i,k} C_i) M_{k|k-1}
        \\end{aligned}

    (in Joseph form), and returns :math:`K_{i,\\mathrm{steps}}`. As ``steps`` grows this tends
    to :func:`steady_state_gains`; slowly for a mode with a pole near the unit circle and weak
    process noise, where the time-varying gains of Algorithm 1 stay far from the steady ones
    that eq. (6) assumes.

    Parameters
    ----------
    system : SwitchedLinearSystem
        Discrete time, with measurement noise.
    P0 : array_like, shape (n, n)
        Initial covariance :math:`\\Sigma_0` (keyword-only), symmetric PSD.
    steps : int
        Number of filter steps :math:`k \\ge 1`.

    Returns
    -------
    ndarray, shape (L, n, m)
    """
    _check_filterable(system)
    n = system.n_states
    P0 = float_array(P0, "P0", ndim=2)
    if P0.shape != (n, n):
        raise ValueError(f"P0 must have shape ({n}, {n}), got {P0.shape}")
    check_finite(P0, "P0")
    P = np.broadcast_to(check_symmetric_psd(P0, "P0"), system.A.shape).copy()
    steps = positive_int(steps, "steps")
    A, C, Q, R = system.A, system.C, system.Q, system.R
    At = np.swapaxes(A, -1, -2)
    for _ in range(steps):
        M = A @ P @ At + Q  # line 7
        K = _gain(M, C, R)  # line 8
        P = joseph_update(M, K, C, R)  # line 10, Joseph form
    return K


def mismatch_dynamics(system: SwitchedLinearSystem, *, gains=None) -> MismatchDynamics:
    """:math:`\\Lambda_i` and :math:`\\Gamma_{i,t}` of Zhang & Natarajan, equations (6)–(7).

    :math:`\\Lambda_i = A_i - K_i C_i A_i` and :math:`\\Gamma_{i,t} = A_t - K_i C_t A_t`: the
    bias of a filter run in mode i while the system is in mode t obeys
    :math:`e_k = \\Lambda_i e_{k-1} + (\\Lambda_i - \\Gamma_{i,t}) \\mathbb{E}(x_{k-1})`.

    Parameters
    ----------
    system : SwitchedLinearSystem
        Discrete time, with measurement noise.
    gains : array_like, shape (L, n, m), optional
        Filter gains :math:`K_i` (keyword-only); default :func:`steady_state_gains`, as
        eq. (6) assumes. Pass :func:`riccati_gains` for the gains of Algorithm 1
        at a finite step.

    Returns
    -------
    MismatchDynamics
        ``.K (L, n, m)``, ``.Lambda (L, n, n)``, ``.Gamma (L, L, n, n)`` with
        ``Gamma[i, t]`` :math:`= \\Gamma_{i,t}`.
    """
    if gains is None:
        K = steady_state_gains(system)
    else:
        _check_filterable(system)
        K = float_array(gains, "gains", ndim=3)
        want = (system.n_modes, system.n_states, system.n_outputs)
        if K.shape != want:
            raise ValueError(f"gains must have shape {want} (L, n, m), got {K.shape}")
        check_finite(K, "gains")
    A, C = system.A, system.C
    CA = C @ A  # (L, m, n), C_t A_t
    Gamma = A[None] - np.einsum("inm,tmk->itnk", K, CA)  # A_t - K_i C_t A_t
    Lambda = np.ascontiguousarray(np.diagonal(Gamma, axis1=0, axis2=1).transpose(2, 0, 1))
    return MismatchDynamics(K=_frozen(K), Lambda=_frozen(Lambda), Gamma=_frozen(Gamma))


# ---------------------------------------------------------------------- eqs (9)-(10)
def transformed_system(dynamics: MismatchDynamics, lam) -> TransformedSystem:
    """The transformed switched system of the mean bias, Zhang & Natarajan equation (10).

    :math:`F_q = \\sum_i \\lambda_{i,q} \\Lambda_i` and
    :math:`G_q = \\sum_i \\lambda_{i,q} (\\Lambda_i - \\Gamma_{i,q})`.

    Parameters
    ----------
    dynamics : MismatchDynamics
    lam : array_like, shape (L, L)
        ``lam[i, q]`` :math:`= P(\\text{filter mode } i \\mid \\text{true mode } q)`; non-negative,
        each column summing to one.

    Returns
    -------
    TransformedSystem
    """
    lam = _check_lam(lam, _check_dynamics(dynamics).n_modes)
    F = np.einsum("iq,iab->qab", lam, dynamics.Lambda)
    G = np.einsum("iq,iqab->qab", lam, dynamics.S)
    return TransformedSystem(F=_frozen(F), G=_frozen(G), lam=_frozen(lam))


def mean_state(system: SwitchedLinearSystem, modes, mean_x0) -> np.ndarray:
    """Mean of the state of model (1) along a mode sequence:
    :math:`\\mathbb{E}(x_k) = A_{q_k} \\mathbb{E}(x_{k-1})`.

    Zhang & Natarajan, proof of Theorem 1 (zero-mean noise, no input).

    Parameters
    ----------
    system : SwitchedLinearSystem
    modes : array_like of int, shape (..., K)
        True modes :math:`q_1, \\dots, q_K` (0-based); leading axes are batch axes.
    mean_x0 : array_like, shape (..., n)
        :math:`\\mathbb{E}(x_0)`, broadcast against the batch axes of ``modes``.

    Returns
    -------
    ndarray, shape (..., K + 1, n)
        :math:`\\mathbb{E}(x_0), \\dots, \\mathbb{E}(x_K)`.
    """
    _check_discrete(system)
    modes = _check_modes(modes, system.n_modes)
    n = system.n_states
    m0 = _vector(mean_x0, "mean_x0", n)
    batch = broadcast_batch({"modes": modes.shape[:-1], "mean_x0": m0.shape[:-1]})
    modes = np.broadcast_to(modes, (*batch, modes.shape[-1]))
    out = np.empty((*batch, modes.shape[-1] + 1, n))
    out[..., 0, :] = m0
    for k in range(modes.shape[-1]):
        out[..., k + 1, :] = np.einsum("...ab,...b->...a", system.A[modes[..., k]], out[..., k, :])
    return out


def bias_recursion(dynamics: MismatchDynamics, lam, modes, mean_x, *, e0=None) -> np.ndarray:
    """Mean bias of the mode-based Kalman filter, Zhang & Natarajan equation (9).

    :math:`\\mathbb{E}(e_k) = F_{q_k} \\mathbb{E}(e_{k-1}) + G_{q_k} \\mathbb{E}(x_{k-1})` (eq. (10)
    with :math:`x^*_k = \\mathbb{E}(e_k)`, :math:`u_{k-1} = \\mathbb{E}(x_{k-1})`), where the
    filter's mode at each step is drawn independently with probabilities ``lam[:, q_k]`` and the
    gains are the ones in ``dynamics`` (steady state, as eq. (6) assumes).

    Parameters
    ----------
    dynamics : MismatchDynamics
    lam : array_like, shape (L, L)
        ``lam[i, q]`` :math:`= P(\\text{filter mode } i \\mid \\text{true mode } q)`; columns sum
        to one.
    modes : array_like of int, shape (..., K)
        True modes :math:`q_1, \\dots, q_K` (0-based); leading axes are batch axes.
    mean_x : array_like, shape (..., K, n)
        :math:`\\mathbb{E}(x_0), \\dots, \\mathbb{E}(x_{K-1})` — the input of step k is
        :math:`\\mathbb{E}(x_{k-1})`
        (e.g. ``mean_state(system, modes, m0)[..., :-1, :]``).
    e0 : array_like, shape (..., n), optional
        Initial bias :math:`\\mathbb{E}(\\hat x_0) - \\mathbb{E}(x_0)` (keyword-only); default zero
        (the filter starts at the prior mean).

    Returns
    -------
    ndarray, shape (..., K + 1, n)
        :math:`\\mathbb{E}(e_0), \\dots, \\mathbb{E}(e_K)`.
    """
    ts = transformed_system(dynamics, lam)
    L, n = dynamics.n_modes, dynamics.Lambda.shape[-1]
    modes = _check_modes(modes, L)
    K = modes.shape[-1]
    u = float_array(mean_x, "mean_x")
    if u.ndim < 2 or u.shape[-2:] != (K, n):
        raise ValueError(
            f"mean_x must have shape (..., {K}, {n}) (E(x_0) .. E(x_{{K-1}}), one row per "
            f"mode in modes), got {u.shape}"
        )
    check_finite(u, "mean_x")
    e = np.zeros(n) if e0 is None else _vector(e0, "e0", n)
    batch = broadcast_batch({"modes": modes.shape[:-1], "mean_x": u.shape[:-2], "e0": e.shape[:-1]})
    modes = np.broadcast_to(modes, (*batch, K))
    u = np.broadcast_to(u, (*batch, K, n))
    out = np.empty((*batch, K + 1, n))
    out[..., 0, :] = e
    for k in range(K):
        q = modes[..., k]
        out[..., k + 1, :] = np.einsum("...ab,...b->...a", ts.F[q], out[..., k, :]) + np.einsum(
            "...ab,...b->...a", ts.G[q], u[..., k, :]
        )
    return out


# ---------------------------------------------------------------------- §4.1-4.2
def autonomous_stability(
    dynamics: MismatchDynamics, lam=None, *, margin: float = 1e-6
) -> AutonomousBiasStability:
    """Lemmas 3–4 and Theorems 2–3 of Zhang & Natarajan for the autonomous system (11).

    * Lemma 3: :math:`\\rho(\\Lambda_i) < 1` (computed, not assumed).
    * Theorems 2–3: a CQLF :math:`P` of :math:`\\{\\Lambda_i\\}` (eq. (13), by :func:`cqlf`) makes
      every :math:`F_q` Schur and is itself a CQLF of :math:`\\{F_q\\}`, for every lam — since
      :math:`\\{X : X^\\top P X - P \\prec 0\\}` is convex and each :math:`F_q` is a convex
      combination of the :math:`\\Lambda_i`. (The printed proof of Theorem 2 reaches this
      through steps that do not hold as written — step (a) equates
      :math:`\\Lambda^\\top P \\Lambda \\prec P` with :math:`\\Lambda P \\Lambda^\\top \\prec P`,
      true with :math:`P^{-1}` in place of :math:`P`, and the block sum has :math:`d P` on its
      diagonal — but the conclusion is right by the convexity argument above, which is what is
      used here.)
    * With lam: Lemma 4's hypothesis (one non-zero entry per column), :math:`\\rho(F_q)`
      and Theorem 3's conclusion checked with numpy on the certificate's :math:`P`.

    Parameters
    ----------
    dynamics : MismatchDynamics
    lam : array_like, shape (L, L), optional
        Mismatch probabilities ``lam[i, q]``; columns sum to one.
    margin : float, optional
        Decrease margin of the LMI (keyword-only), passed to :func:`cqlf`.

    Returns
    -------
    AutonomousBiasStability
    """
    certificate = cqlf(_check_dynamics(dynamics).Lambda, "discrete", margin=margin)
    radius = spectral_radius(dynamics.Lambda)
    if lam is None:
        return AutonomousBiasStability(radius, certificate, None, None, None)
    ts = transformed_system(dynamics, lam)
    F_margin = (
        decrease_margin(ts.F, certificate.P, domain="discrete")
        if certificate.holds
        else float("nan")
    )
    one_mode = bool(np.all(np.count_nonzero(ts.lam, axis=0) == 1))
    return AutonomousBiasStability(radius, certificate, spectral_radius(ts.F), F_margin, one_mode)


def filter_stability_hypotheses(system: SwitchedLinearSystem) -> np.ndarray:
    """Hypotheses of Zhang & Natarajan Lemma 3 (and §2.2 assumption 3), per mode.

    :math:`(A_i, B_i Q B_i^\\top)` controllable — here :math:`(A_i, Q_i^{1/2})` with the system's
    process-noise covariance :math:`Q_i = B_i Q B_i^\\top` — and :math:`(C_i, A_i)` observable,
    both by the PBH test of :func:`~switchest.analysis.observability.is_observable`
    (controllability as observability of the transposed pair). They make the
    steady-state Kalman filter stable, hence :math:`\\rho(\\Lambda_i) < 1`.

    Parameters
    ----------
    system : SwitchedLinearSystem
        Discrete time.

    Returns
    -------
    ndarray of bool, shape (L,)
    """
    _check_discrete(system)
    root = psd_sqrt(system.Q)  # Q_i = root root'
    return np.array(
        [
            is_observable(A.T, W.T) and is_observable(A, C)
            for A, C, W in zip(system.A, system.C, root)
        ]
    )


# ---------------------------------------------------------------------- Algorithm 2
def unstable_components(
    system: SwitchedLinearSystem, *, max_length: int = 2, margin: float = 1e-6, tol: float = 1e-9
) -> UnstableComponents:
    """Unstable state components of the original system, Zhang & Natarajan Algorithm 2, steps 1–2.

    Step 1: a CQLF of :math:`\\{A_i\\}` (:func:`cqlf`) proves the original system stable
    under arbitrary switching, and :math:`I` is empty (Scenario 2 of §4.3).

    Step 2 (the paper gives no procedure):
    :math:`I = \\{j : \\sup_k \\mathbb{E}(x_k)^{[j]} = \\infty\\}` for some switching. For every
    mode word :math:`W = A_{w_p} \\cdots A_{w_1}` of length :math:`\\le` ``max_length`` (all
    rotations included, so every phase of a periodic switching is covered), the invariant
    subspace of :math:`W` for eigenvalues of modulus :math:`\\ge 1 - \\mathrm{tol}` is computed
    by an ordered real Schur decomposition; component j is unstable when :math:`e_j` is not
    orthogonal to that subspace (then :math:`e_j^\\top W^k x_0` does not decay for some
    :math:`x_0`). Eigenvalues on the unit circle count as unstable: bounded but non-decaying
    components are treated conservatively. If neither step decides (no CQLF, every product
    Schur), every component is marked and ``conclusive`` is False.

    Parameters
    ----------
    system : SwitchedLinearSystem
        Discrete time.
    max_length : int, optional
        Longest mode word examined (keyword-only); ``L ** max_length`` products.
    margin : float, optional
        LMI margin passed to :func:`cqlf`.
    tol : float, optional
        Relative tolerance for the unit circle and for a zero row of the subspace
        basis.

    Returns
    -------
    UnstableComponents
    """
    _check_discrete(system)
    max_length = positive_int(max_length, "max_length")
    tol = positive_scalar(tol, "tol")
    n = system.n_states
    certificate = cqlf(system.A, "discrete", margin=margin)
    if certificate.holds:
        return UnstableComponents(np.zeros(n, dtype=bool), certificate, (), holds=True)
    components = np.zeros(n, dtype=bool)
    words = []
    for length in range(1, max_length + 1):
        for word in product(range(system.n_modes), repeat=length):
            W = np.eye(n)
            for mode in word:
                W = system.A[mode] @ W
            marked = _unstable_rows(W, tol)
            if marked.any():
                components |= marked
                words.append(word)
    if not words:
        return UnstableComponents(np.ones(n, dtype=bool), certificate, (), holds=None)
    return UnstableComponents(components, certificate, tuple(words), holds=False)


def stable_mismatch_region(
    system: SwitchedLinearSystem,
    *,
    dynamics: MismatchDynamics | None = None,
    max_length: int = 2,
    atol: float = 1e-9,
) -> np.ndarray:
    """Which mismatch probabilities may be non-zero, Zhang & Natarajan Algorithm 2.

    For every pair (i, q), ``lam[i, q]`` must be 0 if :math:`T_{i,q} = \\Lambda_i - \\Gamma_{i,q}`
    has a non-zero column j for an unstable component j in :math:`I`
    (:func:`unstable_components`); otherwise it may take any value in [0, 1]
    (subject to the columns of lam summing to one, line 12). Then :math:`G_q`
    annihilates the unbounded part of :math:`u_k = \\mathbb{E}(x_k)` and, with (11) stable, the
    bias system (10) is BIBO stable. The diagonal is always allowed
    (:math:`T_{q,q} = 0`). (The printed line 5 reads :math:`T = A_i - F_{i,q}`; the text
    and the printed :math:`T_{i,q}` of §5.2 show :math:`\\Lambda_i - \\Gamma_{i,q}` is meant.)

    Parameters
    ----------
    system : SwitchedLinearSystem
        Discrete time, with measurement noise.
    dynamics : MismatchDynamics, optional
        Precomputed :func:`mismatch_dynamics` of ``system`` (keyword-only);
        computed with steady-state gains when omitted.
    max_length : int, optional
        Passed to :func:`unstable_components`.
    atol : float, optional
        A column counts as zero when its largest entry is at most
        :math:`\\mathrm{atol} \\cdot \\max(1, \\max \\lvert S \\rvert)`.

    Returns
    -------
    ndarray of bool, shape (L, L)
        ``mask[i, q]`` True when Algorithm 2 allows ``lam[i, q] > 0``.
    """
    _check_discrete(system)
    dyn = mismatch_dynamics(system) if dynamics is None else _check_dynamics(dynamics)
    if dyn.Lambda.shape != system.A.shape:
        raise ValueError(
            f"dynamics must belong to system: Lambda has shape {dyn.Lambda.shape}, "
            f"system.A has shape {system.A.shape}"
        )
    atol = positive_scalar(atol, "atol")
    unstable = unstable_components(system, max_length=max_length).components
    S = dyn.S
    scale = atol * max(1.0, float(np.max(np.abs(S))))
    column_nonzero = np.max(np.abs(S), axis=-2) > scale  # (L, L, n): column j of T_{i,q}
    return ~np.any(column_nonzero & unstable, axis=-1)


# ---------------------------------------------------------------------- §4.3 bounds
def bibo_gain(dynamics: MismatchDynamics, *, margin: float = 1e-6) -> float:
    """A BIBO gain :math:`\\eta` of the bias system (10) valid for every lam (Zhang equation (14)).

    Beyond the paper, which takes :math:`\\eta` as given. With a CQLF :math:`P` of
    :math:`\\{\\Lambda_i\\}` (or :math:`P = I` when every :math:`\\lVert \\Lambda_i \\rVert < 1`,
    whichever gives the smaller :math:`\\eta`), every :math:`F_q` is a convex combination of the
    :math:`\\Lambda_i`, so
    :math:`\\lVert F_q \\rVert_P \\le r = \\max_i \\lVert \\Lambda_i \\rVert_P < 1` and, from
    :math:`x^*_0 = 0`,

    .. math::

        \\lVert x^*_k \\rVert \\le \\frac{\\sqrt{\\operatorname{cond}(P)}}{1 - r}
        \\sup_{j, q} \\lVert G_q u_j \\rVert.

    Hence :math:`\\eta = \\sqrt{\\operatorname{cond}(P)} / (1 - r)` satisfies eq. (14).

    Parameters
    ----------
    dynamics : MismatchDynamics
    margin : float, optional
        LMI margin passed to :func:`cqlf` (keyword-only).

    Returns
    -------
    float
        ``inf`` when neither :math:`P = I` nor a CQLF gives :math:`r < 1`.
    """
    Lam = _check_dynamics(dynamics).Lambda
    best = _p_gain(Lam, np.eye(Lam.shape[-1]))
    certificate = cqlf(Lam, "discrete", margin=margin)
    if certificate.holds:
        best = min(best, _p_gain(Lam, certificate.P))
    return best


def mismatch_bias_bound(
    dynamics: MismatchDynamics, probability: float, *, eta: float, sup_input: float
) -> float:
    """Lowest achievable upper bound on the bias, Zhang & Natarajan Theorem 4.

    .. math::

        \\lVert x^*_k \\rVert \\le \\eta \\cdot P \\cdot \\sup_j \\lVert u_j \\rVert \\cdot
        \\max_q \\min_{i \\ne q} \\lVert \\Lambda_i - \\Gamma_{i,q} \\rVert

    for a total mismatch probability :math:`P = \\sum_{i \\ne q} \\lambda_{i,q}` (the same for
    every :math:`q`) placed on the best wrong mode of each :math:`q`; for a stable original
    system.

    Parameters
    ----------
    dynamics : MismatchDynamics
        At least two modes.
    probability : float
        Mismatch probability :math:`P \\in [0, 1]`.
    eta : float
        BIBO gain of (10) (keyword-only), e.g. :func:`bibo_gain`.
    sup_input : float
        :math:`\\sup_j \\lVert u_j \\rVert = \\sup_j \\lVert \\mathbb{E}(x_j) \\rVert`.

    Returns
    -------
    float
    """
    p = _probability(probability, "probability")
    c = _gain_product(eta, sup_input)
    return p * c * float(np.max(_best_wrong_norm(dynamics)))


def tolerance_region(
    dynamics: MismatchDynamics, lam, *, bound: float, eta: float, sup_input: float
) -> ToleranceCheck:
    """Whether lam lies in the tolerance region of Zhang & Natarajan equation (18).

    .. math::

        \\max_q \\sum_{i \\ne q} \\lambda_{i,q} \\lVert S_{i,q} \\rVert \\le
        \\frac{B}{\\eta \\sup_j \\lVert u_j \\rVert}

    with :math:`S_{i,q} = \\Lambda_i - \\Gamma_{i,q}`: the triangle-inequality relaxation of
    eq. (17) that guarantees the bias bound :math:`\\lVert x^*_k \\rVert \\le B` through (14).

    Parameters
    ----------
    dynamics : MismatchDynamics
    lam : array_like, shape (L, L)
        ``lam[i, q]``; columns sum to one.
    bound : float
        The target bias bound :math:`B` (keyword-only), positive.
    eta, sup_input : float
        As in :func:`mismatch_bias_bound`.

    Returns
    -------
    ToleranceCheck
    """
    lam = _check_lam(lam, _check_dynamics(dynamics).n_modes)
    threshold = positive_scalar(bound, "bound") / _gain_product(eta, sup_input)
    norms = _s_norms(dynamics)  # (L, L), zero on the diagonal
    value = np.einsum("iq,iq->q", lam, norms)
    return ToleranceCheck(
        value=_frozen(value), threshold=threshold, holds=bool(value.max() <= threshold)
    )


def max_mismatch_probability(
    dynamics: MismatchDynamics, *, bound: float, eta: float, sup_input: float
) -> float:
    """Largest mismatch probability for which a bias bound :math:`B` is achievable
    (Zhang §4.3, Q. (2)).

    Inverting Theorem 4 with eq. (18):

    .. math::

        P_{\\max} = \\frac{B}{\\eta \\sup_j \\lVert u_j \\rVert
        \\max_q \\min_{i \\ne q} \\lVert S_{i,q} \\rVert},

    the largest :math:`P = \\sum_{i \\ne q} \\lambda_{i,q}` for which
    some lam (all of each column's mismatch on its best wrong mode) satisfies (18).
    With two modes it is the common value ``lam[0, 1] = lam[1, 0]`` on the boundary
    of (18) — Fig. 6's ``0.154554`` for :math:`B = 0.3` with
    :math:`\\eta \\sup \\lVert u \\rVert = 1.04`. The result is not clipped: a value above 1
    means every :math:`P` achieves :math:`B`.

    Parameters
    ----------
    dynamics : MismatchDynamics
        At least two modes.
    bound : float
        Target bias bound :math:`B` (keyword-only), positive.
    eta, sup_input : float
        As in :func:`mismatch_bias_bound`.

    Returns
    -------
    float
        ``inf`` when some mismatch costs nothing (a zero :math:`S_{i,q}`) for every :math:`q`.
    """
    c = positive_scalar(bound, "bound") / _gain_product(eta, sup_input)
    worst = float(np.max(_best_wrong_norm(dynamics)))
    return np.inf if worst == 0.0 else c / worst


# ---------------------------------------------------------------------- helpers
def _gain(M: np.ndarray, C: np.ndarray, R: np.ndarray) -> np.ndarray:
    """:math:`K = M C^\\top (C M C^\\top + R)^{-1}` over a stack (Algorithm 1, line 8), via a
    solve."""
    S = C @ M @ np.swapaxes(C, -1, -2) + R
    # K S = M C'  <=>  S' K' = C M'  (S symmetric)
    return np.swapaxes(np.linalg.solve(S, C @ np.swapaxes(M, -1, -2)), -1, -2)


def _unstable_rows(W: np.ndarray, tol: float) -> np.ndarray:
    """Rows j with :math:`e_j` not orthogonal to :math:`W`'s invariant subspace for
    :math:`\\lvert \\operatorname{eig} \\rvert \\ge 1 - \\mathrm{tol}`."""
    _, Z, sdim = schur(W, output="real", sort=lambda re, im: np.hypot(re, im) >= 1.0 - tol)
    if sdim == 0:
        return np.zeros(W.shape[0], dtype=bool)
    return np.linalg.norm(Z[:, :sdim], axis=1) > tol


def _p_gain(Lam: np.ndarray, P: np.ndarray) -> float:
    w, V = np.linalg.eigh(P)
    root = (V * np.sqrt(w)) @ V.T
    root_inv = (V / np.sqrt(w)) @ V.T
    r = float(np.max(np.linalg.norm(root @ Lam @ root_inv, ord=2, axis=(-2, -1))))
    return np.inf if r >= 1.0 else float(np.sqrt(w[-1] / w[0]) / (1.0 - r))


def _s_norms(dynamics: MismatchDynamics) -> np.ndarray:
    """:math:`\\lVert S_{i,q} \\rVert_2` (spectral norm), shape (L, L); zero on the diagonal."""
    return np.linalg.norm(dynamics.S, ord=2, axis=(-2, -1))


def _best_wrong_norm(dynamics: MismatchDynamics) -> np.ndarray:
    """:math:`\\min_{i \\ne q} \\lVert S_{i,q} \\rVert` for each :math:`q`, shape (L,)."""
    L = _check_dynamics(dynamics).n_modes
    if L < 2:
        raise ValueError(f"dynamics must have at least two modes for a mode mismatch, got {L}")
    norms = _s_norms(dynamics)
    np.fill_diagonal(norms, np.inf)
    return norms.min(axis=0)


def _gain_product(eta, sup_input) -> float:
    return positive_scalar(eta, "eta") * positive_scalar(sup_input, "sup_input")



def _probability(value, name: str) -> float:
    p = positive_scalar(value, name, allow_zero=True)
    if p > 1.0:
        raise ValueError(f"{name} must be a probability in [0, 1], got {value!r}")
    return p


def _check_lam(lam, L: int) -> np.ndarray:
    lam = float_array(lam, "lam", ndim=2)
    if lam.shape != (L, L):
        raise ValueError(
            f"lam must have shape ({L}, {L}) (lam[i, q], one row and column per mode), "
            f"got {lam.shape}"
        )
    check_finite(lam, "lam")
    if np.any(lam < 0):
        raise ValueError(f"lam must have non-negative entries, got minimum {lam.min():.3g}")
    cols = lam.sum(axis=0)
    worst = int(np.argmax(np.abs(cols - 1.0)))
    if abs(cols[worst] - 1.0) > _COLUMN_TOL:
        raise ValueError(
            "lam columns must sum to 1 (lam[i, q] = P(filter mode i | true mode q)), "
            f"got column {worst} summing to {cols[worst]:.12g}"
        )
    return lam


def _check_modes(modes, L: int) -> np.ndarray:
    modes = int_array(modes, "modes")
    if modes.ndim == 0:
        raise ValueError(f"modes must have at least 1 dimension (..., K), got shape {modes.shape}")
    if modes.size and (modes.min() < 0 or modes.max() >= L):
        bad = modes.min() if modes.min() < 0 else modes.max()
        raise ValueError(f"modes must be 0-based mode indices in [0, {L - 1}], got {bad}")
    return modes


def _vector(value, name: str, n: int) -> np.ndarray:
    v = float_array(value, name)
    if v.ndim < 1 or v.shape[-1] != n:
        raise ValueError(f"{name} must have shape (..., {n}), got {v.shape}")
    check_finite(v, name)
    return v


def _check_dynamics(dynamics) -> MismatchDynamics:
    if not isinstance(dynamics, MismatchDynamics):
        got = type(dynamics).__name__
        raise TypeError(f"dynamics must be a MismatchDynamics, got {got}")
    return dynamics


def _check_discrete(system) -> None:
    if not isinstance(system, SwitchedLinearSystem):
        raise TypeError(f"system must be a SwitchedLinearSystem, got {type(system).__name__}")
    if system.domain != "discrete":
        raise ValueError(
            f"system must be discrete-time (Zhang eq. (1)), got domain {system.domain!r}"
        )


def _check_filterable(system) -> None:
    _check_discrete(system)
    if not system.has_measurement_noise:
        raise ValueError(
            "system must have measurement noise (R positive definite) for Kalman gains, "
            "got a noise-free system (R = 0)"
        )



def _frozen(arr: np.ndarray) -> np.ndarray:
    arr = np.array(arr, dtype=float)
    arr.setflags(write=False)
    return arr
