"""Second and fourth moments of the subsystem observers' error, per component and given the modes.

Wang, Yin, Lin, Polis & Chen (seed 003): with modes i.i.d. with probabilities ``p`` on
:math:`[kT, (k+1)T)` the sampled error obeys (Theorem 1, eq. (15)):

.. math::

    e_{k+1} = \\Lambda(\\alpha_k) e_k + \\Gamma(\\alpha_k) d_k, \\qquad d_k \\sim \\mathcal{N}(0, I)

(:class:`~switchest.analysis.subsystem_observers.ErrorDynamics`). Beside the full second
moment of :mod:`.subsystem_observers`, this module gives what a Monte Carlo of the error
is compared with:

* the mean square of each state component from a known initial error
  (:func:`state_error_moments`), :math:`\\mathbb{E}[\\Lambda^\\top \\Lambda]` of §5.1
  (:func:`moment_matrix`) and the second-moment fixed point of any map :math:`\\Lambda(i)` with
  noise :math:`W(i)` (:func:`moment_fixed_point`);
* for a decoupled error (diagonal :math:`\\Lambda(i)`, the scalar Examples 1-4): each
  component's steady state of eq. (23) (:func:`component_steady_state`), its exact second
  and fourth moments (eqs. (22)-(23), :func:`scalar_error_moments`), the exact spread of a
  run's time average of :math:`e_k^2` (:func:`window_average_sd`) and the loop gain that
  minimizes a component's steady state (§5.2, :func:`optimal_component_gain`);
* given one run's modes, the exact mean and variance of its window sum of weighted squared
  errors (:func:`window_sums_given_modes`), a check that heavy tails cannot upset.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize_scalar

from .._checks import check_probability_vector, float_array
from ..system import SwitchedLinearSystem
from .subsystem_observers import (
    ErrorDynamics,
    decoupled_gain_bounds,
    error_dynamics,
    second_moments,
    steady_state,
)

__all__ = [
    "ComponentOptimum",
    "ScalarErrorMoments",
    "WindowSums",
    "component_steady_state",
    "moment_fixed_point",
    "moment_matrix",
    "optimal_component_gain",
    "scalar_error_moments",
    "state_error_moments",
    "window_average_sd",
    "window_sums_given_modes",
]


@dataclass(frozen=True)
class ScalarErrorMoments:
    """Exact moments of each component of a decoupled error (:func:`scalar_error_moments`).

    Attributes
    ----------
    E2, E4 : ndarray, shape (steps + 1, n)
        :math:`\\mathbb{E}\\, e_k^2` and :math:`\\mathbb{E}\\, e_k^4` per component.
    factor : ndarray, shape (n,)
        :math:`\\mathbb{E}[g^2]`, the second-moment factor per step
        (:math:`g = \\Lambda(\\alpha_k)_{cc}`).
    noise : ndarray, shape (n,)
        :math:`\\mathbb{E}[q^2]`, the noise injected per step (:math:`q^2 = W(\\alpha_k)_{cc}`).
    """

    E2: np.ndarray
    E4: np.ndarray
    factor: np.ndarray
    noise: np.ndarray


@dataclass(frozen=True)
class WindowSums:
    """Moments of each run's window sum given its modes (:func:`window_sums_given_modes`).

    Attributes
    ----------
    mean, var : ndarray, shape (N, d)
        :math:`\\mathbb{E}[S \\mid \\alpha]` and :math:`\\operatorname{Var}(S \\mid \\alpha)` per
        run and weight.
    """

    mean: np.ndarray
    var: np.ndarray


@dataclass(frozen=True)
class ComponentOptimum:
    """The gain minimizing a decoupled component's steady state (:func:`optimal_component_gain`).

    Attributes
    ----------
    gain : float
        The minimizing loop gain :math:`L`.
    steady_state : float
        :math:`\\sigma_\\infty` of the component at ``gain``.
    holds : bool
        The bounded scalar search converged.
    """

    gain: float
    steady_state: float
    holds: bool


def moment_matrix(dyn: ErrorDynamics, p) -> np.ndarray:
    """:math:`M = \\mathbb{E}[\\Lambda_k^\\top \\Lambda_k]
    = \\sum_i p_i \\Lambda(i)^\\top \\Lambda(i)` (Wang et al. §5.1).

    Its diagonal is each scalar component's second-moment factor per step, its eigenvalues
    the printed gammas of Example 2 and §6.

    Returns
    -------
    ndarray, shape (n_s, n_s)
    """
    p = check_probability_vector(p, "p", n=dyn.Lam.shape[0])
    return np.einsum("i,iba,ibc->ac", p, dyn.Lam, dyn.Lam)


def moment_fixed_point(Lam, W, p) -> np.ndarray:
    """The fixed point :math:`V = \\sum_i p_i (\\Lambda(i) V \\Lambda(i)^\\top + W(i))` (Wang et al.
    eq. (21)).

    For any per-mode error map ``Lam (L, n, n)`` and noise covariance ``W (L, n, n)``,
    e.g. the fine-step discretization of an observer rather than the exact one of
    :func:`~switchest.analysis.subsystem_observers.error_dynamics`, solved through

    .. math::

        \\Bigl(I - \\sum_i p_i \\Lambda(i) \\otimes \\Lambda(i)\\Bigr) \\operatorname{vec} V
        = \\operatorname{vec}\\Bigl(\\sum_i p_i W(i)\\Bigr).

    The caller ensures mean-square stability (:func:`~switchest.analysis.ms_stable_iid`).

    Returns
    -------
    ndarray, shape (n, n)
    """
    Lam, W = float_array(Lam, "Lam", ndim=3), float_array(W, "W", ndim=3)
    if W.shape != Lam.shape or Lam.shape[1] != Lam.shape[2]:
        raise ValueError(f"Lam and W must both have shape (L, n, n), got {Lam.shape} and {W.shape}")
    p = check_probability_vector(p, "p", n=Lam.shape[0])
    n = Lam.shape[1]
    K = np.einsum("i,iab,icd->acbd", p, Lam, Lam).reshape(n * n, n * n)
    return np.linalg.solve(np.eye(n * n) - K, np.einsum("i,iab->ab", p, W).ravel()).reshape(n, n)


def state_error_moments(dyn: ErrorDynamics, p, e0, steps: int) -> np.ndarray:
    """Exact :math:`\\mathbb{E}[(\\hat x_k - x_k)_c^2]` per state component from a known initial
    error ``e0``.

    :math:`\\operatorname{diag}(\\Phi V_k \\Phi^\\top)` with :math:`V_k` the second moment of the
    sub-state error (:func:`~switchest.analysis.subsystem_observers.second_moments`, Wang et al.
    §5.1) from :math:`V_0 = z_0 z_0^\\top`, :math:`z_0 = F e_0`.

    Parameters
    ----------
    dyn : ErrorDynamics
    p : array_like, shape (L,)
        Mode probabilities.
    e0 : array_like, shape (n,)
        Initial state error :math:`\\hat x_0 - x_0`.
    steps : int
        Number of switching intervals.

    Returns
    -------
    ndarray, shape (steps + 1, n)
    """
    F, Phi = dyn.structure.F, dyn.structure.Phi
    z0 = F @ _initial_error(e0, Phi.shape[0])
    V = second_moments(dyn, p, np.outer(z0, z0), steps)
    return np.einsum("ia,kab,ib->ki", Phi, V, Phi)


def component_steady_state(dyn: ErrorDynamics, p) -> np.ndarray:
    """Steady state of each component of a decoupled error, NaN where a component diverges.

    :math:`\\sigma_\\infty = \\mathbb{E}[W]_{cc} / (1 - \\mathbb{E}[\\Lambda^\\top \\Lambda]_{cc})`
    (Wang et al. eq. (23)) for diagonal :math:`\\Lambda(i)`; defined even when another component
    diverges, as for Example 1's Kalman-Bucy gains.

    Returns
    -------
    ndarray, shape (n_s,)
    """
    p = check_probability_vector(p, "p", n=dyn.Lam.shape[0])
    factor = np.diag(np.einsum("i,iba,ibc->ac", p, dyn.Lam, dyn.Lam))
    noise = np.diag(np.einsum("i,iab->ab", p, dyn.W))
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(factor < 1.0, noise / (1.0 - factor), np.nan)


def scalar_error_moments(dyn: ErrorDynamics, p, e0, steps: int) -> ScalarErrorMoments:
    """Exact :math:`\\mathbb{E}\\, e_k^2` and :math:`\\mathbb{E}\\, e_k^4` per component of a
    decoupled error (diagonal :math:`\\Lambda`).

    With :math:`e_{k+1} = g e_k + q d_k` (:math:`g = \\Lambda(\\alpha_k)_{cc}`,
    :math:`q^2 = W(\\alpha_k)_{cc}`, :math:`d_k \\sim \\mathcal{N}(0, 1)`, all independent of
    :math:`e_k`; Wang et al. eqs. (22)-(23)):

    .. math::

        \\begin{aligned}
        \\mathbb{E}\\, e^2_{k+1} &= \\mathbb{E}[g^2] \\, \\mathbb{E}\\, e^2_k
            + \\mathbb{E}[q^2] \\\\
        \\mathbb{E}\\, e^4_{k+1} &= \\mathbb{E}[g^4] \\, \\mathbb{E}\\, e^4_k
            + 6 \\, \\mathbb{E}[g^2 q^2] \\, \\mathbb{E}\\, e^2_k + 3 \\, \\mathbb{E}[q^4]
        \\end{aligned}

    The fourth moments give the exact spread of Monte Carlo squared errors, whose tails
    can be too heavy for their sample variance (Example 4's error has a power-law tail of
    index about 3.7). ``e0`` is the initial error, :math:`z^c = \\pm x_c`: squares agree in both
    coordinates.

    Returns
    -------
    ScalarErrorMoments
    """
    p = check_probability_vector(p, "p", n=dyn.Lam.shape[0])
    e0, steps = _initial_error(e0, dyn.Lam.shape[-1]), _steps(steps)
    g = np.einsum("icc->ic", dyn.Lam)
    w = np.einsum("icc->ic", dyn.W)
    m2, m4, c22, s2, s4 = p @ g**2, p @ g**4, p @ (g**2 * w), p @ w, 3.0 * (p @ w**2)
    E2, E4 = np.zeros((steps + 1, g.shape[1])), np.zeros((steps + 1, g.shape[1]))
    E2[0], E4[0] = e0**2, e0**4
    for k in range(steps):
        E2[k + 1] = m2 * E2[k] + s2
        E4[k + 1] = m4 * E4[k] + 6.0 * c22 * E2[k] + s4
    return ScalarErrorMoments(E2=E2, E4=E4, factor=m2, noise=s2)


def window_average_sd(moments: ScalarErrorMoments, start: int) -> np.ndarray:
    """Exact standard deviation of a run's average of :math:`e_k^2` over
    :math:`k = \\mathrm{start}, \\dots, K` per component.

    From :func:`scalar_error_moments`: for :math:`j \\le k` (Wang et al. eqs. (22)-(23) iterated)

    .. math::

        \\mathbb{E}[e_j^2 e_k^2] = m_2^{k-j} \\, \\mathbb{E}\\, e_j^4
        + s_2 (1 + m_2 + \\dots + m_2^{k-j-1}) \\, \\mathbb{E}\\, e_j^2,

    with :math:`m_2 = \\mathbb{E}[g^2]` and :math:`s_2 = \\mathbb{E}[q^2]`.

    Returns
    -------
    ndarray, shape (n,)
    """
    E2, E4, m2, s2 = moments.E2, moments.E4, moments.factor, moments.noise
    if not 0 <= start < E2.shape[0]:
        raise ValueError(f"start must be in [0, {E2.shape[0] - 1}], got {start!r}")
    W = E2.shape[0] - start
    lag = np.arange(W)
    power = m2[None, :] ** lag[:, None]  # (W, n)
    accumulated = s2[None, :] * np.concatenate([np.zeros((1, m2.size)),
                                                np.cumsum(power, axis=0)[:-1]])
    j, k = np.meshgrid(np.arange(W), np.arange(W), indexing="ij")
    lo, hi = np.minimum(j, k), np.maximum(j, k)
    d = hi - lo
    cross = power[d] * E4[start + lo] + accumulated[d] * E2[start + lo]  # (W, W, n)
    cov = cross - E2[start + j] * E2[start + k]
    return np.sqrt(np.maximum(cov.sum(axis=(0, 1)), 0.0)) / W


def window_sums_given_modes(dyn: ErrorDynamics, e0, modes, start: int, selectors) -> WindowSums:
    """Exact mean and variance of each run's window sum of weighted squared errors, given its modes.

    Given :math:`\\alpha_0, \\dots, \\alpha_{K-1}` the error of Wang et al. eq. (15) is Gaussian,
    :math:`e_{k+1} = \\Lambda(\\alpha_k) e_k + \\Gamma(\\alpha_k) d_k` from the given :math:`e_0`
    (here in state coordinates, :math:`\\Phi \\Lambda F` and :math:`\\Phi W \\Phi^\\top`; needs
    :math:`n_s = n`), with mean :math:`m_k` and covariance :math:`V_k`. For each diagonal weight
    :math:`D` (a row of ``selectors``) the window sum
    :math:`S = \\sum_{k \\ge \\mathrm{start}} e_k^\\top D e_k` then has exactly

    .. math::

        \\begin{aligned}
        \\mathbb{E}[S \\mid \\alpha]
            &= \\sum_k \\left(m_k^\\top D m_k + \\operatorname{tr}(D V_k)\\right), \\\\
        \\operatorname{Var}(S \\mid \\alpha)
            &= \\sum_{j, k} \\left(2 \\operatorname{tr}(D C_{jk} D C_{jk}^\\top)
            + 4 m_j^\\top D C_{jk} D m_k\\right), \\\\
        C_{jk} &= V_j \\Phi_{k,j}^\\top
        \\end{aligned}

    (Gaussian fourth moments; :math:`\\Phi_{k,j}` the product of the :math:`\\Lambda` from j to k).
    :math:`(S - \\mathbb{E}[S \\mid \\alpha]) / \\sqrt{\\operatorname{Var}(S \\mid \\alpha)}` has
    mean 0 and variance 1 whatever the tails of the mode sequences.

    Parameters
    ----------
    dyn : ErrorDynamics
    e0 : array_like, shape (n,)
        Initial state error.
    modes : array_like of int, shape (N, K)
        Each run's mode on each switching interval (0-based).
    start : int
        First step of the window, :math:`0 \\le \\mathrm{start} \\le K`.
    selectors : array_like, shape (d, n)
        Diagonals of the weights :math:`D`.

    Returns
    -------
    WindowSums
    """
    F, Phi = dyn.structure.F, dyn.structure.Phi
    if F.shape[0] != F.shape[1]:
        raise ValueError(f"window_sums_given_modes needs one sub-state per state (n_s = n), "
                         f"got n_s = {F.shape[0]}, n = {F.shape[1]}")
    modes = np.asarray(modes)
    if modes.ndim != 2 or modes.dtype.kind not in "iu":
        raise ValueError(f"modes must be an (N, K) integer array, got {modes.dtype} {modes.shape}")
    N, K = modes.shape
    if not 0 <= start <= K:
        raise ValueError(f"start must be in [0, {K}], got {start!r}")
    Lx, Wx = Phi @ dyn.Lam @ F, Phi @ dyn.W @ Phi.T
    m, V = np.zeros((N, K + 1, F.shape[1])), np.zeros((N, K + 1, F.shape[1], F.shape[1]))
    m[:, 0] = _initial_error(e0, F.shape[1])
    for k in range(K):
        A = Lx[modes[:, k]]
        m[:, k + 1] = np.einsum("nab,nb->na", A, m[:, k])
        V[:, k + 1] = A @ V[:, k] @ np.swapaxes(A, -1, -2) + Wx[modes[:, k]]
    D = float_array(selectors, "selectors", ndim=2)
    mw, C = m[:, start:], V[:, start:].copy()  # C[:, j] = C_{j, j+d}, starting at lag d = 0
    maps = np.swapaxes(Lx[modes[:, start:]], -1, -2)  # Lambda' of the steps start..K-1
    W = K + 1 - start
    mean = np.einsum("dc,nkc->nd", D, mw**2) + np.einsum("dc,nkcc->nd", D, C)
    var = np.zeros((N, D.shape[0]))
    for d in range(W):
        term = (2.0 * np.einsum("da,db,njab->nd", D, D, C**2)
                + 4.0 * np.einsum("nja,da,njab,db,njb->nd", mw[:, : W - d], D, C, D, mw[:, d:]))
        var += term if d == 0 else 2.0 * term  # (j, k) and (k, j)
        if d < W - 1:
            C = C[:, : W - 1 - d] @ maps[:, d : W - 1]  # C_{j, j+d+1} = C_{j, j+d} Lambda_{j+d}'
    return WindowSums(mean=mean, var=var)


def optimal_component_gain(system: SwitchedLinearSystem, p, T: float, gains, component: int, *,
                           upper: float = 1000.0, xatol: float = 1e-9) -> ComponentOptimum:
    """The loop gain minimizing a decoupled component's steady state (Wang et al. §5.2, Example 4).

    Component :math:`c` is closed by one mode :math:`i` with the scalar gain
    ``gains[i, c, 0] = L``; the other gains stay as given. :math:`\\sigma_\\infty^c(L)` is the
    steady state :math:`(\\Phi V \\Phi^\\top)_{cc}` of eq. (21) corrected
    (:func:`~switchest.analysis.subsystem_observers.steady_state`), minimized by bounded
    Brent search from just above the mean-square bound on :math:`L`
    (:func:`~switchest.analysis.subsystem_observers.decoupled_gain_bounds`) to ``upper``.

    Parameters
    ----------
    system : SwitchedLinearSystem
        With a decoupled error (one-dimensional blocks, diagonal :math:`\\Lambda(i)`).
    p : array_like, shape (L,)
    T : float
    gains : array_like, shape (L, n, 1)
        State-coordinate gains; the closing mode's entry of ``component`` is varied.
    component : int
        0-based state component.
    upper : float, optional
        Largest loop gain searched.
    xatol : float, optional
        Absolute tolerance on the gain.

    Returns
    -------
    ComponentOptimum
    """
    bounds = decoupled_gain_bounds(system, p, T)
    if not 0 <= component < bounds.mode.size:
        raise ValueError(f"component must be in [0, {bounds.mode.size - 1}], got {component!r}")
    base = float_array(gains, "gains", ndim=3)
    mode = int(bounds.mode[component])

    def sigma(L: float) -> float:
        G = base.copy()
        G[mode, component, 0] = L
        return float(steady_state(error_dynamics(system, G, T), p).V_x[component, component])

    lo = float(bounds.min_loop_gain[component]) + 1e-6
    r = minimize_scalar(sigma, bounds=(lo, upper), method="bounded", options={"xatol": xatol})
    return ComponentOptimum(gain=float(r.x), steady_state=float(r.fun), holds=bool(r.success))


def _initial_error(e0, n: int) -> np.ndarray:
    e0 = float_array(e0, "e0", ndim=1)
    if e0.shape != (n,):
        raise ValueError(f"e0 must have shape ({n},), got {e0.shape}")
    return e0


def _steps(steps) -> int:
    if not isinstance(steps, (int, np.integer)) or isinstance(steps, bool) or steps < 0:
        raise ValueError(f"steps must be a non-negative int, got {steps!r}")
    return int(steps)
