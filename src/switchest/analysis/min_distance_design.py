"""Lee, Ping & Shim (002): the constants of §II, Assumptions 1-3, the smallest windows.

Lee et al. estimate the mode of a continuous-time switched system from the
output on a window of length :math:`\\delta` and detect each switch within :math:`\\Delta`
after it happened, provided (Assumption 2, conditions (3) and (4)), for all :math:`t`:

.. math::

    \\begin{aligned}
    \\omega_{\\min}(\\delta) \\lvert x(t) \\rvert^2 &> \\bigl(u_{\\max} \\sqrt{N_u(\\delta)}
        + 2 v_{\\max} \\sqrt{\\delta}\\bigr)^2 && (3) \\\\
    \\omega_{\\min}(\\Delta) \\lvert x(t) \\rvert^2 &> \\tfrac{1}{2} \\bigl(u_{\\max}
        \\sqrt{N_u(\\Delta)} + 2 v_{\\max} \\sqrt{\\Delta} \\\\
    &\\qquad + 2 v_{\\max} C_{\\max} (\\mu_c e^{\\lambda_c \\Delta} + 1)^2
        \\hat E(\\delta) \\sqrt{\\Delta}\\bigr)^2 && (4)
    \\end{aligned}

with :math:`\\lVert e^{A_i t} \\rVert \\le \\mu_c e^{\\lambda_c t}` (:math:`\\mu_c \\ge 1`,
:math:`\\lambda_c \\ge 0`; the paper's check accents),
:math:`\\lVert e^{(A_i - L_i C_i) t} \\rVert \\le \\mu_h e^{-\\lambda_h t}` (hat accents),
:math:`L_{\\max} = \\max_i \\lVert L_i \\rVert`, :math:`C_{\\max} = \\max_i \\lVert C_i \\rVert`,
:math:`h_i(t) = C_i e^{A_i t} B_i`, :math:`\\phi_i(t) = C_i e^{A_i t}`,
:math:`U_i(t) = \\int_0^t \\phi_i^\\top \\phi_i`:

.. math::

    \\begin{aligned}
    N_u(t) &= \\max_{i \\ne j} \\int_0^t \\Bigl(\\int_0^\\tau \\lVert h_i(s) - h_j(s) \\rVert\\, ds
        \\Bigr)^2 d\\tau \\\\
    M_i(t) &= \\int_0^t \\lVert U_i(t)^{-1} \\phi_i(\\tau)^\\top \\rVert\\, d\\tau,
        \\qquad M_{\\max} = \\max_i M_i \\\\
    \\hat E(d) &= \\mu_h \\max(M_{\\max}(d), L_{\\max} / \\lambda_h) \\\\
    S_\\Delta &= v_{\\max}^2 \\bigl(1 + C_{\\max} (\\mu_c e^{\\lambda_c \\Delta} + 2)
        \\hat E(\\delta)\\bigr)^2 \\Delta && (\\text{§IV})
    \\end{aligned}

All norms are spectral norms; :math:`\\lvert x(t) \\rvert` is bounded below by the caller's
``x_min``.

How each constant is obtained
-----------------------------
* :math:`\\mu_c, \\lambda_c` and :math:`\\mu_h, \\lambda_h`: Lyapunov bounds. For a shift
  :math:`r` above the spectral abscissa of :math:`A`, :math:`P` solves
  :math:`(A - rI)^\\top P + P(A - rI) = -I`; then :math:`V = x^\\top P x` obeys
  :math:`dV/dt \\le (2r - 1/\\lambda_{\\max}(P)) V` and
  :math:`\\lVert e^{At} \\rVert \\le
  \\sqrt{\\operatorname{cond} P}\\, e^{(r - 1/(2 \\lambda_{\\max}(P))) t}`.
  As :math:`r \\to \\infty` this tends to :math:`\\mu = 1` with the logarithmic norm
  :math:`\\lambda_{\\max}((A + A^\\top)/2)` as rate, which is also a candidate. One shift is
  shared by all modes (:math:`\\mu` = max over modes, rate = max over modes) and chosen on a
  log-spaced grid of shifts to minimize what the conditions use:
  :math:`\\mu_c e^{\\lambda_c \\Delta}` for :math:`A_i`, and :math:`\\hat E(\\delta)` for
  :math:`A_i - L_i C_i`. Both bounds are re-checked on a time grid
  (``bound_ratio_*`` :math:`\\le 1`).
* :math:`U_i(t)` and :math:`\\omega_{\\min}(t)`: exact, by Van Loan's block exponential
  (:func:`switchest.analysis.observability.joint_gramian`).
* :math:`N_u` and :math:`M_i`: the norms inside the integrals are not linear, so these are
  composite trapezoid sums on a uniform grid of ``n_grid`` points with
  :math:`e^{A_i \\tau}` exact at every node (relative error
  :math:`\\sim (t / \\mathrm{n\\_grid})^2`).
* Observer gains (when not given): :func:`default_observer_gains`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from itertools import combinations

import numpy as np

from .._checks import check_finite, check_memory, float_array, positive_int, positive_scalar
from .._linalg import symmetrize
from ..discretize import interval, mode_steps
from ..signals import SwitchingSignal
from ..system import SwitchedLinearSystem
from .observability import is_observable, joint_observability, omega_min

__all__ = [
    "LeeAssumptions",
    "LeeCondition",
    "LeeConstants",
    "LeeWindows",
    "decay_observer_gains",
    "default_observer_gains",
    "lee_assumptions",
    "lee_constants",
    "lee_windows",
    "observability_gramians",
]

_N_SHIFTS = 161
_N_DECAYING_SHIFTS = 41
_MAX_RESIDUAL = 0.5  # largest |M P + P M' + I| of a Lyapunov solution kept as a bound
_BOUND_TOL = 1e-8
_MAX_EXPONENT = 700.0  # e^700 ~ 1e304: the largest growth factor a float64 holds


# ---------------------------------------------------------------------- results
@dataclass(frozen=True, eq=False)
class LeeConstants:
    """The constants of Lee et al. §II-§IV for given windows (:func:`lee_constants`).

    Attributes
    ----------
    delta, Delta : float
        Estimation window and detection delay.
    mu_check, lambda_check : float
        :math:`\\lVert e^{A_i t} \\rVert \\le \\check\\mu e^{\\check\\lambda t}` for all
        :math:`t \\ge 0` and modes.
    mu_hat, lambda_hat : float
        :math:`\\lVert e^{(A_i - L_i C_i) t} \\rVert \\le \\hat\\mu e^{-\\hat\\lambda t}`.
    observer_gains : ndarray, shape (L, n, m)
        The :math:`L_i` used.
    L_max, C_max : float
        :math:`\\max_i \\lVert L_i \\rVert`, :math:`\\max_i \\lVert C_i \\rVert`.
    U : ndarray, shape (L, n, n)
        :math:`U_i(\\delta)`, the observability Gramians of the modes.
    M : ndarray, shape (L,)
        :math:`M_i(\\delta)`; ``M_max = M.max()``.
    M_max : float
    N_u_delta, N_u_Delta : float
        :math:`N_u(\\delta)`, :math:`N_u(\\Delta)` (zero without inputs).
    omega_min_delta, omega_min_Delta : float
        :math:`\\omega_{\\min}(\\delta)`, :math:`\\omega_{\\min}(\\Delta)`.
    E_hat : float
        :math:`\\hat E(\\delta)`.
    growth : float
        :math:`\\check\\mu e^{\\check\\lambda \\Delta}`.
    reset_factor : float
        :math:`(\\mathrm{growth} + 1) \\hat E`: the threshold of (21) and (23) is ``v_max`` times
        it.
    s_factor : float
        :math:`(1 + C_{\\max} (\\mathrm{growth} + 2) \\hat E)^2 \\Delta`:
        :math:`S_\\Delta = v_{\\max}^2 \\, \\mathrm{s\\_factor}`.
    bound_ratio_check, bound_ratio_hat : float
        :math:`\\max \\lVert e^{M t} \\rVert / (\\mu e^{\\mathrm{rate}\\, t})` over
        :math:`t \\in [0, \\mathrm{bound\\_horizon}]`
        (501 points) for the two bounds; at most 1 (checked).
    bound_horizon : float
    """

    delta: float
    Delta: float
    mu_check: float
    lambda_check: float
    mu_hat: float
    lambda_hat: float
    observer_gains: np.ndarray
    L_max: float
    C_max: float
    U: np.ndarray
    M: np.ndarray
    M_max: float
    N_u_delta: float
    N_u_Delta: float
    omega_min_delta: float
    omega_min_Delta: float
    E_hat: float
    growth: float
    reset_factor: float
    s_factor: float
    bound_ratio_check: float
    bound_ratio_hat: float
    bound_horizon: float

    def S_Delta(self, v_max: float) -> float:
        """The bound :math:`S_\\Delta` of §IV.

        .. math::

            S_\\Delta = v_{\\max}^2 \\bigl(1 + C_{\\max} (\\mu e^{\\lambda \\Delta} + 2)
            \\hat E(\\delta)\\bigr)^2 \\Delta
        """
        v_max = positive_scalar(v_max, "v_max", allow_zero=True)
        return v_max * v_max * self.s_factor  # a product: inf, not OverflowError, for a huge v_max

    def reset_threshold(self, v_max: float) -> float:
        """:math:`v_{\\max} (\\mu e^{\\lambda \\Delta} + 1) \\hat E(\\delta)`, the threshold of (21)
        and (23)."""
        return positive_scalar(v_max, "v_max", allow_zero=True) * self.reset_factor


@dataclass(frozen=True)
class LeeCondition:
    """One hypothesis of Lee et al.: verdict, margin and the two sides compared.

    Attributes
    ----------
    holds : bool
    margin : float
        ``lhs - rhs`` (Assumption 1: the smallest PBH margin over mode pairs;
        Assumption 3: the slack of the tighter of its two requirements); the
        condition holds exactly when ``margin > 0`` (a dwell exactly equal to
        :math:`\\delta + \\Delta` counts as failing).
    lhs, rhs : float
        The two sides (Assumption 1: :math:`\\omega_{\\min}(\\delta)` and 0).
    """

    holds: bool
    margin: float
    lhs: float
    rhs: float


@dataclass(frozen=True, eq=False)
class LeeAssumptions:
    """Lee et al. Assumptions 1-3 for given windows (:func:`lee_assumptions`).

    Attributes
    ----------
    holds : bool
        Assumption 1, (3), (4) and — when a signal or ``min_dwell`` was given —
        Assumption 3 all hold.
    assumption1, condition3, condition4 : LeeCondition
    assumption3 : LeeCondition or None
        ``None`` when neither ``signal`` nor ``min_dwell`` was given: the dwell time
        ``required_dwell`` is then a requirement on the signal left to the caller.
    required_dwell : float
        :math:`\\delta + \\Delta` (Assumption 3).
    v_max_allowed : float
        The largest noise bound for which (3) and (4) hold with the given
        ``u_max``, ``x_min``, ``delta``, ``Delta`` (strictly below it; negative when
        the input alone breaks them).
    constants : LeeConstants
    """

    holds: bool
    assumption1: LeeCondition
    condition3: LeeCondition
    condition4: LeeCondition
    assumption3: LeeCondition | None
    required_dwell: float
    v_max_allowed: float
    constants: LeeConstants


@dataclass(frozen=True, eq=False)
class LeeWindows:
    """Smallest windows satisfying (3) and (4) (:func:`lee_windows`).

    Attributes
    ----------
    holds : bool
        Windows satisfying (3) and (4) exist on the grid up to ``t_max`` (found).
    delta : float or None
        Smallest multiple of ``step`` in :math:`(0, t_{\\max}]` for which (3) holds.
    Delta : float or None
        Smallest multiple of ``step`` in :math:`(0, t_{\\max}]` for which (4) holds with
        that :math:`\\delta`.
    step : float
    assumptions : LeeAssumptions or None
        :func:`lee_assumptions` re-evaluated at :math:`(\\delta, \\Delta)`.
    """

    holds: bool
    delta: float | None
    Delta: float | None
    step: float
    assumptions: LeeAssumptions | None


# ---------------------------------------------------------------------- public
def default_observer_gains(system: SwitchedLinearSystem) -> np.ndarray:
    """Observer gains :math:`L_i` with :math:`A_i - L_i C_i` Hurwitz, by pole placement.

    For mode :math:`i` the poles are :math:`-\\rho_i (1, 1.25, 1.5, \\dots)` with
    :math:`\\rho_i = \\max(1, 2 \\max \\lvert \\operatorname{eig}(A_i) \\rvert)`: twice as fast as
    the mode's own dynamics. Distinct real poles are placed by ``scipy.signal.place_poles`` on
    the dual pair :math:`(A_i^\\top, C_i^\\top)` (its robust method makes the closed-loop
    eigenvectors as orthogonal as it can, which keeps :math:`\\hat\\mu` small).

    Returns
    -------
    ndarray, shape (L, n, m)
    """
    _check_system(system)

    def poles(A, C):
        rho = max(1.0, 2.0 * float(np.max(np.abs(np.linalg.eigvals(A)))))
        return -rho * (1.0 + 0.25 * np.arange(system.n_states))

    return _placed_gains(system, poles)


def decay_observer_gains(system: SwitchedLinearSystem, decay: float) -> np.ndarray:
    """Observer gains: poles of :math:`A_i - L_i C_i` at :math:`-a`, :math:`-1.25 a`, ... for
    :math:`a` = ``decay``.

    Each pole is repeated :math:`\\operatorname{rank} C_i` times (the multiplicity
    ``scipy.signal.place_poles`` allows), so with :math:`C_i = I` every pole is :math:`-a`:
    :math:`L_i = A_i + a I` and :math:`A_i - L_i C_i = -a I`, the gains of the lee-detection
    experiment (:attr:`switchest.models.lee.LeeScenario.observer_gains`).

    Returns
    -------
    ndarray, shape (L, n, m)
    """
    _check_system(system)
    a = positive_scalar(decay, "decay")

    def poles(A, C):
        return -a * (1.0 + 0.25 * (np.arange(system.n_states) // np.linalg.matrix_rank(C)))

    return _placed_gains(system, poles)


def observability_gramians(system: SwitchedLinearSystem, t) -> np.ndarray:
    """:math:`U_i(t) = \\int_0^t e^{A_i^\\top s} C_i^\\top C_i e^{A_i s}\\, ds` for every mode
    (Lee et al. §II).

    Exact: the process-noise integral of the dual system :math:`(A_i^\\top, C_i^\\top C_i)` from
    :func:`switchest.discretize.interval` (Van Loan).

    Parameters
    ----------
    system : SwitchedLinearSystem
        Continuous-time.
    t : float or array_like, shape (K,)
        Positive horizon(s).

    Returns
    -------
    ndarray, shape (L, n, n) or (K, L, n, n)
    """
    _check_system(system)
    t = float_array(t, "t", ndim=(0, 1))
    check_finite(t, "t")
    if np.any(t <= 0):
        raise ValueError(f"t must be positive, got minimum {t.min():.3g}")
    L = system.n_modes
    modes = np.arange(L)[:, None] if t.ndim == 0 else np.arange(L)[None, :, None]
    T = t if t.ndim == 0 else t[:, None]
    return interval(_dual(system), T, modes).Qd


def lee_constants(
    system: SwitchedLinearSystem, delta: float, Delta: float, observer_gains=None, *,
    n_grid: int = 2001,
) -> LeeConstants:
    """The constants of Lee et al. §II (and :math:`S_\\Delta` of §IV) for windows ``delta``,
    ``Delta``.

    Parameters
    ----------
    system : SwitchedLinearSystem
        Continuous-time, every mode observable.
    delta, Delta : float
        Estimation window and detection delay (positive).
    observer_gains : array_like, shape (L, n, m) or (n, m), optional
        :math:`L_i` with :math:`A_i - L_i C_i` Hurwitz; default :func:`default_observer_gains`.
    n_grid : int
        Quadrature nodes for :math:`N_u` and :math:`M_i` (keyword-only).

    Returns
    -------
    LeeConstants
        See the module docstring for how each number is obtained.
    """
    _check_system(system)
    delta = positive_scalar(delta, "delta")
    Delta = positive_scalar(Delta, "Delta")
    n_grid = positive_int(n_grid, "n_grid")
    if n_grid < 3:
        raise ValueError(f"n_grid must be at least 3, got {n_grid}")
    _check_grid(system, n_grid, f"lee_constants with n_grid = {n_grid} quadrature nodes")
    _check_horizon(system, delta, "delta")
    _check_horizon(system, Delta, "Delta")
    gains = _gains(system, observer_gains)
    closed = system.A - gains @ system.C
    L_max = float(np.max(np.linalg.norm(gains, ord=2, axis=(1, 2))))
    C_max = float(np.max(np.linalg.norm(system.C, ord=2, axis=(1, 2))))
    U, M = _gramian_terms(system, delta, n_grid)
    M_max = float(M.max())
    growth_table = _shift_table(system.A)
    mu_c, lam_c = _best_growth(growth_table, np.array([Delta]))
    mu_c, lam_c = float(mu_c[0]), float(lam_c[0])
    mu_h, lam_h = _best_decay(_shift_table(closed), M_max, L_max)
    E_hat = mu_h * max(M_max, L_max / lam_h)
    growth = mu_c * np.exp(lam_c * Delta)
    horizon = 4.0 * max(delta, Delta, 1.0 / lam_h)
    ratio_c = _bound_ratio(system.A, mu_c, lam_c, horizon)
    ratio_h = _bound_ratio(closed, mu_h, -lam_h, horizon)
    if max(ratio_c, ratio_h) > 1.0 + _BOUND_TOL:
        raise RuntimeError(
            f"the Lyapunov bounds failed their numerical check (ratios {ratio_c:.6g}, "
            f"{ratio_h:.6g} > 1): the system is too ill-conditioned for them"
        )
    return LeeConstants(
        delta=delta,
        Delta=Delta,
        mu_check=mu_c,
        lambda_check=lam_c,
        mu_hat=mu_h,
        lambda_hat=lam_h,
        observer_gains=gains,
        L_max=L_max,
        C_max=C_max,
        U=U,
        M=M,
        M_max=M_max,
        N_u_delta=_n_u(system, delta, n_grid),
        N_u_Delta=_n_u(system, Delta, n_grid),
        omega_min_delta=_omega_min(system, delta),
        omega_min_Delta=_omega_min(system, Delta),
        E_hat=float(E_hat),
        growth=float(growth),
        reset_factor=float((growth + 1.0) * E_hat),
        s_factor=float((1.0 + C_max * (growth + 2.0) * E_hat) ** 2 * Delta),
        bound_ratio_check=ratio_c,
        bound_ratio_hat=ratio_h,
        bound_horizon=horizon,
    )


def lee_assumptions(
    system: SwitchedLinearSystem,
    *,
    u_max: float,
    v_max: float,
    x_min: float,
    delta: float,
    Delta: float,
    observer_gains=None,
    signal: SwitchingSignal | Sequence[SwitchingSignal] | None = None,
    min_dwell: float | None = None,
) -> LeeAssumptions:
    """Check Lee et al. Assumption 1, conditions (3) and (4), and Assumption 3.

    Parameters
    ----------
    system : SwitchedLinearSystem
        Continuous-time.
    u_max, v_max : float
        Bounds on :math:`\\lvert u(t) \\rvert` and :math:`\\lvert v(t) \\rvert` (eq. (2)); zero
        allowed.
    x_min : float
        A lower bound on :math:`\\lvert x(t) \\rvert` over the time considered; (3) and (4) are
        required "for all t", so they are checked at :math:`\\lvert x(t) \\rvert = x_{\\min}`.
    delta, Delta : float
        Estimation window and detection delay.
    observer_gains : array_like, optional
        :math:`L_i`; default :func:`default_observer_gains`.
    signal : SwitchingSignal or sequence of them, optional
        Switching signal(s) to check Assumption 3 on: no switch in :math:`[0, \\delta]`
        and every dwell at least :math:`\\delta + \\Delta`.
    min_dwell : float, optional
        Instead of ``signal``: a dwell-time bound of the signal class, also
        bounding the first switch instant from below.

    Returns
    -------
    LeeAssumptions
        Margins are ``lhs - rhs`` of each inequality; ``v_max_allowed`` is the
        noise bound at which (3) or (4) becomes an equality.
    """
    _check_system(system)
    u_max, v_max, x_min = _bounds(u_max, v_max, x_min)
    if signal is not None and min_dwell is not None:
        raise ValueError("pass either signal or min_dwell for Assumption 3, got both")
    k = lee_constants(system, delta, Delta, observer_gains)
    joint = joint_observability(system)
    off = joint.margin[~np.eye(system.n_modes, dtype=bool)]
    pbh = float(off.min()) if off.size else float("inf")
    a1 = LeeCondition(holds=bool(joint.holds), margin=pbh, lhs=k.omega_min_delta, rhs=0.0)
    lhs3 = k.omega_min_delta * x_min * x_min  # products, not **: inf rather than OverflowError
    rhs3 = (u_max * np.sqrt(k.N_u_delta) + 2 * v_max * np.sqrt(k.delta)) ** 2
    lhs4 = k.omega_min_Delta * x_min * x_min
    rhs4 = 0.5 * (u_max * np.sqrt(k.N_u_Delta) + v_max * _noise_gain4(k)) ** 2
    c3 = LeeCondition(holds=bool(lhs3 > rhs3), margin=float(lhs3 - rhs3), lhs=float(lhs3),
                      rhs=float(rhs3))
    c4 = LeeCondition(holds=bool(lhs4 > rhs4), margin=float(lhs4 - rhs4), lhs=float(lhs4),
                      rhs=float(rhs4))
    a3 = _assumption3(signal, min_dwell, k.delta, k.Delta)
    # omega_min is a Gramian's smallest eigenvalue: >= 0 but for rounding (modes that cannot be
    # told apart give -1e-17), where no noise is allowed
    root_delta, root_Delta = (np.sqrt(max(w, 0.0)) for w in (k.omega_min_delta, k.omega_min_Delta))
    v3 = (root_delta * x_min - u_max * np.sqrt(k.N_u_delta)) / (2 * np.sqrt(k.delta))
    v4 = (np.sqrt(2) * root_Delta * x_min - u_max * np.sqrt(k.N_u_Delta)) / _noise_gain4(k)
    holds = a1.holds and c3.holds and c4.holds and (a3 is None or a3.holds)
    return LeeAssumptions(
        holds=bool(holds),
        assumption1=a1,
        condition3=c3,
        condition4=c4,
        assumption3=a3,
        required_dwell=k.delta + k.Delta,
        v_max_allowed=float(min(v3, v4)),
        constants=k,
    )


def lee_windows(
    system: SwitchedLinearSystem,
    *,
    u_max: float,
    v_max: float,
    x_min: float,
    observer_gains=None,
    t_max: float = 10.0,
    step: float | None = None,
) -> LeeWindows:
    """The smallest :math:`\\delta` satisfying (3), then the smallest :math:`\\Delta` satisfying
    (4).

    Both are searched among the multiples of ``step`` in :math:`(0, t_{\\max}]` (so they
    can be used as they are on a detector grid of that step): :math:`\\delta` is the
    first at which (3) holds, :math:`\\Delta` the first at which (4) holds with
    :math:`\\hat E(\\delta)` of that :math:`\\delta`. Neither condition is monotone in its window
    in general, so "smallest" means the first on the scan. The pair is then
    re-checked with :func:`lee_assumptions`.

    Parameters
    ----------
    system : SwitchedLinearSystem
    u_max, v_max, x_min : float
        As in :func:`lee_assumptions`.
    observer_gains : array_like, optional
    t_max : float
        Longest window considered.
    step : float, optional
        Scan step; default ``t_max / 2000``.

    Returns
    -------
    LeeWindows
        ``holds=False`` when no window up to ``t_max`` works (``delta`` is still
        given when only (4) failed). The scan integrates :math:`N_u` on the scan grid;
        ``assumptions`` re-evaluates the pair with :func:`lee_constants`'
        quadrature, so read its ``holds`` for the verdict.
    """
    _check_system(system)
    u_max, v_max, x_min = _bounds(u_max, v_max, x_min)
    t_max = positive_scalar(t_max, "t_max")
    step = t_max / 2000 if step is None else positive_scalar(step, "step")
    if step > t_max:
        raise ValueError(f"step must not exceed t_max = {t_max:g}, got {step:g}")
    gains = _gains(system, observer_gains)
    K = int(np.floor(t_max / step * (1 + 1e-12)))
    _check_grid(system, K, f"lee_windows with t_max / step = {K} scan points")
    _check_horizon(system, t_max, "t_max")
    t = step * np.arange(1, K + 1)
    omega = _omega_min(system, t)
    N_u = _n_u_cumulative(system, t)
    ok3 = omega * (x_min * x_min) > (u_max * np.sqrt(N_u) + 2 * v_max * np.sqrt(t)) ** 2
    if not ok3.any():
        return LeeWindows(holds=False, delta=None, Delta=None, step=step, assumptions=None)
    delta = float(t[np.argmax(ok3)])
    closed = system.A - gains @ system.C
    L_max = float(np.max(np.linalg.norm(gains, ord=2, axis=(1, 2))))
    C_max = float(np.max(np.linalg.norm(system.C, ord=2, axis=(1, 2))))
    M_max = float(_gramian_terms(system, delta, 2001)[1].max())
    mu_h, lam_h = _best_decay(_shift_table(closed), M_max, L_max)
    E_hat = mu_h * max(M_max, L_max / lam_h)
    mu_c, lam_c = _best_growth(_shift_table(system.A), t)
    growth = mu_c * np.exp(lam_c * t)
    gain = 2 * np.sqrt(t) * (1 + C_max * (growth + 1) ** 2 * E_hat)
    ok4 = omega * (x_min * x_min) > 0.5 * (u_max * np.sqrt(N_u) + v_max * gain) ** 2
    if not ok4.any():
        return LeeWindows(holds=False, delta=delta, Delta=None, step=step, assumptions=None)
    Delta = float(t[np.argmax(ok4)])
    check = lee_assumptions(system, u_max=u_max, v_max=v_max, x_min=x_min, delta=delta, Delta=Delta,
                            observer_gains=gains)
    return LeeWindows(holds=True, delta=delta, Delta=Delta, step=step, assumptions=check)


# ---------------------------------------------------------------------- pieces
def _check_system(system) -> None:
    if not isinstance(system, SwitchedLinearSystem):
        raise TypeError(f"system must be a SwitchedLinearSystem, got {type(system).__name__}")
    if not system.is_continuous:
        raise ValueError(f"system must be continuous-time (Lee et al. eq. (1)), "
                         f"got {system.domain!r}")


def _placed_gains(system: SwitchedLinearSystem, poles) -> np.ndarray:
    """:math:`L_i` ``(L, n, m)`` placing the eigenvalues of :math:`A_i - L_i C_i` at
    ``poles(A_i, C_i)``, by ``scipy.signal.place_poles`` on the dual pair
    :math:`(A_i^\\top, C_i^\\top)`; every mode must be observable (Lee et al. §II)."""
    from scipy.signal import place_poles  # scipy.signal: most of a second to import
    gains = []
    for i in range(system.n_modes):
        A, C = system.A[i], system.C[i]
        if not is_observable(A, C):
            raise ValueError(f"system mode {i} must be observable (Lee et al. §II), "
                             f"(A_{i}, C_{i}) is not")
        gains.append(place_poles(A.T, C.T, poles(A, C)).gain_matrix.T)
    return np.array(gains)


def _bounds(u_max: float, v_max: float, x_min: float) -> tuple[float, float, float]:
    """The input and noise bounds of eq. (2) and the state's lower bound, each :math:`\\ge 0`."""
    return (positive_scalar(u_max, "u_max", allow_zero=True),
            positive_scalar(v_max, "v_max", allow_zero=True),
            positive_scalar(x_min, "x_min", allow_zero=True))


def _gains(system: SwitchedLinearSystem, observer_gains) -> np.ndarray:
    """Validated :math:`L_i` ``(L, n, m)`` with every :math:`A_i - L_i C_i` Hurwitz."""
    if observer_gains is None:
        return default_observer_gains(system)
    L, n, m = system.n_modes, system.n_states, system.n_outputs
    gains = float_array(observer_gains, "observer_gains", ndim=(2, 3))
    check_finite(gains, "observer_gains")
    if gains.ndim == 2:
        gains = np.broadcast_to(gains, (L, *gains.shape))
    if gains.shape != (L, n, m):
        raise ValueError(f"observer_gains must have shape (L, n, m) = ({L}, {n}, {m}), "
                         f"got {gains.shape}")
    abscissa = np.linalg.eigvals(system.A - gains @ system.C).real.max(axis=1)
    if np.any(abscissa >= 0):
        i = int(np.argmax(abscissa))
        raise ValueError(
            f"observer_gains must make every A_i - L_i C_i Hurwitz, got eigenvalue real part "
            f"{abscissa[i]:.3g} in mode {i}"
        )
    return np.array(gains)


def _check_grid(system: SwitchedLinearSystem, count: int, what: str) -> None:
    """Refuse a time grid whose per-node matrices would not fit in memory.

    Per node: the exponentials of every mode and the Van Loan blocks of every mode
    pair's Gramian, :math:`8 L^2 (4n)^2` floats with the copies ``expm`` makes.
    """
    L, n = system.n_modes, system.n_states
    check_memory(8 * count * 8 * L * L * (4 * n) ** 2, f"{what} (8 L^2 (4n)^2 floats per node)")


def _check_horizon(system: SwitchedLinearSystem, value: float, name: str) -> None:
    """Refuse a window over which :math:`e^{A_i t}` may overflow:
    :math:`\\max_i \\lVert A_i \\rVert t \\le 700`."""
    exponent = float(np.max(np.linalg.norm(system.A, ord=2, axis=(1, 2)))) * value
    if exponent > _MAX_EXPONENT:
        raise ValueError(
            f"{name} = {value:g} is too long for this system: max ||A_i|| {name} = {exponent:.3g} "
            f"> {_MAX_EXPONENT:g}, and the exponentials e^(A_i t) of the bounds overflow"
        )


def _dual(system: SwitchedLinearSystem) -> SwitchedLinearSystem:
    """:math:`(A_i^\\top, C_i^\\top C_i)`: its process-noise integral is the observability
    Gramian."""
    At = np.swapaxes(system.A, 1, 2)
    return SwitchedLinearSystem.continuous(At, Q=np.swapaxes(system.C, 1, 2) @ system.C)


def _omega_min(system: SwitchedLinearSystem, t):
    """:math:`\\omega_{\\min}(t) = \\min_{i \\ne j} \\lambda_{\\min}(W_{ij}(t))` (Lee et al. §II),
    scalar or array."""
    pairs = list(combinations(range(system.n_modes), 2))
    if not pairs:
        return np.full(np.shape(t), np.inf) if np.ndim(t) else float("inf")
    values = [omega_min(system, i, j, t) for i, j in pairs]
    return np.min(values, axis=0) if np.ndim(t) else float(min(values))


def _exponentials(system: SwitchedLinearSystem, tau: np.ndarray) -> np.ndarray:
    """:math:`e^{A_i \\tau_k}` on a uniform grid :math:`\\tau = k h` (:math:`k = 0, \\dots, K-1`),
    shape (K, L, n, n).

    One exact step :math:`e^{A_i h}` (:func:`switchest.discretize.mode_steps`) and its
    powers: no exponential of a long horizon, which could overflow.
    """
    L, n = system.n_modes, system.n_states
    out = np.empty((tau.size, L, n, n))
    out[0] = np.eye(n)
    if tau.size > 1:
        step = mode_steps(SwitchedLinearSystem.continuous(system.A), float(tau[1] - tau[0])).F
        for k in range(1, tau.size):
            out[k] = step @ out[k - 1]
    return out


def _gramian_terms(system: SwitchedLinearSystem, t: float, n_grid: int):
    """:math:`U_i(t)` (exact) and
    :math:`M_i(t) = \\int_0^t \\lVert U_i(t)^{-1} \\phi_i(\\tau)^\\top \\rVert\\, d\\tau`
    (trapezoid)."""
    U = observability_gramians(system, t)
    tau = np.linspace(0.0, t, n_grid)
    phi_t = np.swapaxes(system.C @ _exponentials(system, tau), -1, -2)  # phi_i(tau)' (K, L, n, m)
    integrand = np.linalg.norm(np.linalg.solve(U, phi_t), ord=2, axis=(-2, -1))
    return U, np.trapezoid(integrand, tau, axis=0)


def _input_kernel_gaps(system: SwitchedLinearSystem, tau: np.ndarray) -> np.ndarray:
    """:math:`\\lVert h_i(\\tau) - h_j(\\tau) \\rVert` for every pair :math:`i < j`, shape
    (pairs, K)."""
    h = system.C @ _exponentials(system, tau) @ system.B  # (K, L, m, l)
    pairs = list(combinations(range(system.n_modes), 2))
    return np.array([np.linalg.norm(h[:, i] - h[:, j], ord=2, axis=(-2, -1)) for i, j in pairs])


def _n_u(system: SwitchedLinearSystem, t: float, n_grid: int) -> float:
    """:math:`N_u(t)` by two nested composite trapezoid sums (Lee et al. §II)."""
    if system.n_inputs == 0 or system.n_modes < 2:
        return 0.0
    tau = np.linspace(0.0, t, n_grid)
    inner = _cumtrapz(_input_kernel_gaps(system, tau), tau)
    return float(np.max(np.trapezoid(inner**2, tau, axis=-1)))


def _n_u_cumulative(system: SwitchedLinearSystem, t: np.ndarray) -> np.ndarray:
    """:math:`N_u` at every node of the uniform grid
    :math:`t = \\mathrm{step} \\cdot (1, \\dots, K)` (trapezoid from 0)."""
    if system.n_inputs == 0 or system.n_modes < 2:
        return np.zeros_like(t)
    tau = np.concatenate([[0.0], t])
    inner = _cumtrapz(_input_kernel_gaps(system, tau), tau)
    return np.max(_cumtrapz(inner**2, tau), axis=0)[1:]


def _cumtrapz(f: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Cumulative trapezoid along the last axis, starting at 0."""
    parts = 0.5 * (f[..., 1:] + f[..., :-1]) * np.diff(x)
    return np.concatenate([np.zeros((*f.shape[:-1], 1)), np.cumsum(parts, axis=-1)], axis=-1)


@dataclass(frozen=True)
class _ShiftTable:
    """Candidate bounds :math:`\\lVert e^{At} \\rVert \\le \\mu e^{\\mathrm{rate}\\, t}` shared by
    all modes (one per row)."""

    mu: np.ndarray
    rate: np.ndarray


def _shift_table(A: np.ndarray) -> _ShiftTable:
    """Lyapunov bounds for a log-spaced grid of shifts plus the logarithmic-norm bound.

    The shifts run from the spectral abscissa up by :math:`10^{-4}, \\dots, 10^3` times the
    largest mode norm and, for a Hurwitz :math:`A`, also across :math:`(\\text{abscissa}, 0]`: far
    from normal, the first grid starts above 0 and would hold no decaying bound at all.

    For shift :math:`r` above every mode's spectral abscissa, :math:`P_i` solves
    :math:`(A_i - rI)^\\top P + P(A_i - rI) = -I`; mode :math:`i` gives
    :math:`\\mu_i = \\sqrt{\\operatorname{cond} P_i}` and
    :math:`\\mathrm{rate}_i = r - (1 - \\lVert E_i \\rVert)/(2 \\lambda_{\\max}(P_i))`, where
    :math:`E_i` is the residual of the computed :math:`P_i` (0 in exact arithmetic: the rate
    stays a bound for the :math:`P_i` actually computed); the row is
    :math:`(\\max_i \\mu_i, \\max_i \\mathrm{rate}_i)`. Shifts where some
    :math:`\\lVert E_i \\rVert` reaches 1/2 (:math:`P_i` inaccurate or singular, next to a sum of
    eigenvalues) are dropped.
    The equations of all shifts and modes are solved at once in Kronecker form.
    """
    n = A.shape[-1]
    abscissa = float(np.linalg.eigvals(A).real.max())
    scale = max(1.0, float(np.max(np.linalg.norm(A, ord=2, axis=(1, 2)))))
    shifts = abscissa + scale * np.logspace(-4, 3, _N_SHIFTS)
    if abscissa < 0:  # also shifts in (abscissa, 0): the decaying bounds (rate < 0) lie there,
        # below the grid above when the matrix is far from normal (scale >> -abscissa)
        shifts = np.union1d(shifts, abscissa * (1.0 - np.logspace(-4, 0, _N_DECAYING_SHIFTS)))
    # (A_i - rI)', (S, L, n, n)
    M = np.swapaxes(A, 1, 2)[None] - shifts[:, None, None, None] * np.eye(n)
    eye = np.eye(n)
    # M P + P M' = -I  <=>  (I kron M + M kron I) vec(P) = -vec(I)   (P symmetric)
    K = np.einsum("ac,slbd->slabcd", eye, M) + np.einsum("slac,bd->slabcd", M, eye)
    rhs = np.broadcast_to(-eye.reshape(n * n, 1), (*K.shape[:2], n * n, 1))
    P = symmetrize(_solve_each(K.reshape(*K.shape[:2], n * n, n * n), rhs).reshape(M.shape))
    # the residual E = M P + P M' + I of the computed P: with |E| < 1 the bound holds at the rate
    # r - (1 - |E|) / (2 lambda_max(P)) (d/dt x'Px <= -(1 - |E|) |x|^2); near a sum of
    # eigenvalues, where P is inaccurate, |E| grows and the shift is dropped
    solved = np.all(np.isfinite(P), axis=(-2, -1))
    P[~solved] = eye
    residual = np.linalg.norm(M @ P + P @ np.swapaxes(M, -1, -2) + eye, ord=2, axis=(-2, -1))
    residual[~solved] = np.inf
    certified = np.all(residual < _MAX_RESIDUAL, axis=1)
    lam = np.linalg.eigvalsh(P[certified])  # (S, L, n)
    positive = np.all(lam[..., 0] > 0, axis=1)  # round-off at extreme shifts can break P > 0
    lam, residual = lam[positive], residual[certified][positive]
    mu = np.sqrt(lam[..., -1] / lam[..., 0]).max(axis=1)
    rate = (shifts[certified][positive, None] - 0.5 * (1.0 - residual) / lam[..., -1]).max(axis=1)
    log_norm = float(np.linalg.eigvalsh(symmetrize(A))[:, -1].max())
    return _ShiftTable(mu=np.concatenate([[1.0], mu]), rate=np.concatenate([[log_norm], rate]))


def _solve_each(systems: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """``np.linalg.solve`` of a stack of systems; NaN for those that are singular."""
    try:
        return np.linalg.solve(systems, rhs)
    except np.linalg.LinAlgError:  # one at least: each on its own
        out = np.full(rhs.shape, np.nan)
        for index in np.ndindex(systems.shape[:-2]):
            try:
                out[index] = np.linalg.solve(systems[index], rhs[index])
            except np.linalg.LinAlgError:
                continue
        return out


def _best_growth(table: _ShiftTable, Delta: np.ndarray):
    """:math:`(\\check\\mu, \\check\\lambda)` minimizing
    :math:`\\mu e^{\\max(\\mathrm{rate}, 0) \\Delta}`, for each :math:`\\Delta`."""
    lam = np.maximum(table.rate, 0.0)  # the paper asks lambda_check >= 0
    cost = np.log(table.mu)[None, :] + lam[None, :] * Delta[:, None]
    best = np.argmin(cost, axis=1)
    return table.mu[best], lam[best]


def _best_decay(table: _ShiftTable, M_max: float, L_max: float):
    """:math:`(\\hat\\mu, \\hat\\lambda)` minimizing
    :math:`\\hat E = \\mu \\max(M_{\\max}, L_{\\max} / \\lambda)`."""
    decaying = table.rate < 0
    if not decaying.any():  # cannot happen for a Hurwitz matrix: the shifts reach below 0
        raise RuntimeError("no decaying Lyapunov bound found for A_i - L_i C_i")
    mu, lam = table.mu[decaying], -table.rate[decaying]
    best = int(np.argmin(mu * np.maximum(M_max, L_max / lam)))
    return float(mu[best]), float(lam[best])


def _bound_ratio(A: np.ndarray, mu: float, rate: float, horizon: float) -> float:
    """:math:`\\max_t \\lVert e^{A_i t} \\rVert / (\\mu e^{\\mathrm{rate}\\, t})` over 501 points of
    :math:`[0, \\mathrm{horizon}]` and all modes.

    Compared in logarithms, at the points where :math:`\\lVert e^{A_i t} \\rVert > 10^{-250}`
    (beyond, the computed norm has lost its relative precision to underflow).
    """
    tau = np.linspace(0.0, horizon, 501)
    E = _exponentials(SwitchedLinearSystem.continuous(A), tau)
    norms = np.linalg.norm(E, ord=2, axis=(-2, -1))  # (K, L)
    resolved = norms > 1e-250  # where the powers of e^{Ah} have not reached underflow
    with np.errstate(divide="ignore"):
        log_ratio = np.log(norms) - (np.log(mu) + rate * tau)[:, None]
    return float(np.exp(np.max(log_ratio[resolved])))


def _noise_gain4(k: LeeConstants) -> float:
    """The factor of :math:`v_{\\max}` inside (4):
    :math:`2 \\sqrt{\\Delta} (1 + C_{\\max} (\\mathrm{growth} + 1)^2 \\hat E)`."""
    return 2 * np.sqrt(k.Delta) * (1 + k.C_max * (k.growth + 1) ** 2 * k.E_hat)


def _assumption3(signal, min_dwell, delta: float, Delta: float) -> LeeCondition | None:
    """No switch on :math:`[0, \\delta]` and dwell time :math:`\\delta + \\Delta` (Lee et al.
    Assumption 3)."""
    need = delta + Delta
    if min_dwell is not None:
        d = positive_scalar(min_dwell, "min_dwell")
        return LeeCondition(holds=d > need, margin=d - need, lhs=d, rhs=need)
    if signal is None:
        return None
    if not isinstance(signal, (SwitchingSignal, Sequence)) or isinstance(signal, str):
        got = type(signal).__name__
        raise TypeError(f"signal must be a SwitchingSignal or a sequence of them, got {got}")
    signals = [signal] if isinstance(signal, SwitchingSignal) else list(signal)
    for i, s in enumerate(signals):
        if not isinstance(s, SwitchingSignal):
            raise TypeError(f"signal must be a SwitchingSignal or a sequence of them, "
                            f"got {type(s).__name__} at {i}")
    gaps = [np.diff(s.times) for s in signals]
    dwell = min((float(g.min()) for g in gaps if g.size), default=np.inf)
    first = min((float(s.times[0]) for s in signals if s.times.size), default=np.inf)
    margin = min(dwell - need, first - delta)
    return LeeCondition(holds=bool(margin > 0), margin=float(margin), lhs=dwell, rhs=need)

