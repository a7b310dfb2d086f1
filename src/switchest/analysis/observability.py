"""Observability of switched linear systems: per mode, jointly, and under sampling.

Rank tests on the observability matrix :math:`[C; CA; \\dots; CA^{n-1}]` fail from
:math:`n \\approx 12` on (its entries grow like :math:`\\lVert A \\rVert^{n-1}`; for
:math:`A = Q \\operatorname{diag}(-1, \\dots, -30) Q^\\top` numpy's rank of it is 6 instead of
30). Every verdict here therefore comes from a PBH test with deflation
(:func:`kalman_decomposition`): at each eigenvalue :math:`\\lambda` of :math:`A` the smallest
singular value of :math:`[A - \\lambda I; C]` is zero exactly when an eigenvector of
:math:`\\lambda` lies in :math:`\\ker C`. Such an eigenvector
(or the real 2-D invariant subspace of a complex pair) spans part of the
unobservable subspace; it is split off by an orthogonal change of basis and the
test repeats on the rest, which also catches generalized eigenvectors. The
observability matrix itself is offered for teaching and small :math:`n`
(:func:`observability_matrix`).

Paper keys: Lee et al. (002) Assumption 1 and §II (joint observability, :math:`W_{ij}(t)`,
:math:`\\omega_{\\min}(t)`); Wang et al. (003) §3.1 and Assumption 2 (per-mode Kalman
decomposition, :math:`W_S`); Shankar et al. (000) Definition 1, Assumption 1, Lemma 1
(uniform observability of the sampled system under a dwell time).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from itertools import combinations

import numpy as np
from scipy.linalg import expm, qr
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components

from .._checks import (
    broadcast_batch,
    check_finite,
    check_mode,
    check_symmetric_psd,
    float_array,
    positive_int,
    positive_scalar,
)
from .._linalg import symmetrize
from ..discretize import interval
from ..system import SwitchedLinearSystem

__all__ = [
    "CombinedObservability",
    "DwellTimeObservability",
    "JointObservability",
    "KalmanDecomposition",
    "ModeObservability",
    "UniformObservability",
    "combined_observability",
    "dwell_time_observability",
    "is_observable",
    "joint_gramian",
    "joint_observability",
    "kalman_decomposition",
    "mode_decompositions",
    "mode_observability",
    "observability_matrix",
    "omega_min",
    "uniform_observability",
    "window_gramian",
]

_RTOL = 1e-7


# ---------------------------------------------------------------------- results
@dataclass(frozen=True)
class KalmanDecomposition:
    """Observability (Kalman) decomposition of a pair :math:`(A, C)`, in Wang et al.'s names.

    Wang et al. §3.1: :math:`M` is a basis of the unobservable subspace :math:`\\ker W`,
    :math:`N` completes it so that :math:`T = [M, N]` is invertible, :math:`T^{-1} = [G; F]`,
    and :math:`T^{-1} A T = \\begin{bmatrix} A_{11} & A_{12} \\\\ 0 & A_{22} \\end{bmatrix}`,
    :math:`C T = [0, C_2]` with :math:`(A_{22}, C_2)` observable. Here :math:`T` is orthogonal,
    so :math:`G = M^\\top`, :math:`F = N^\\top`.

    Attributes
    ----------
    T : ndarray, shape (n, n)
        Orthogonal change of basis :math:`[M, N]`.
    M : ndarray, shape (n, n - n_observable)
        Orthonormal basis of the unobservable subspace.
    N : ndarray, shape (n, n_observable)
        Orthonormal basis of its orthogonal complement.
    G : ndarray, shape (n - n_observable, n)
        First block row of :math:`T^{-1}` (:math:`= M^\\top`).
    F : ndarray, shape (n_observable, n)
        Second block row of :math:`T^{-1}` (:math:`= N^\\top`): :math:`z = F x` is the observable
        sub-state of Wang et al.
    A_hat : ndarray, shape (n, n)
        :math:`T^{-1} A T`; its lower-left block is zero up to round-off.
    C_hat : ndarray, shape (m, n)
        :math:`C T`; its first ``n - n_observable`` columns are zero up to round-off.
    A11, A12, A22 : ndarray
        Blocks of ``A_hat``.
    C2 : ndarray, shape (m, n_observable)
        Observable output block.
    n_observable : int
        Dimension of the observable part, :math:`\\operatorname{rank} W` (:math:`n_i` of Wang
        et al.).
    margin : float
        :math:`\\min \\sigma_{\\min}([A_{22} - \\lambda I; C_2])` over the eigenvalues of
        :math:`A_{22}`: how far the observable part is from losing observability (an upper
        bound on its distance to unobservability; ``inf`` when ``n_observable = 0``).
    """

    T: np.ndarray
    M: np.ndarray
    N: np.ndarray
    G: np.ndarray
    F: np.ndarray
    A_hat: np.ndarray
    C_hat: np.ndarray
    A11: np.ndarray
    A12: np.ndarray
    A22: np.ndarray
    C2: np.ndarray
    n_observable: int
    margin: float


@dataclass(frozen=True)
class ModeObservability:
    """Per-mode observability of a switched system (:func:`mode_observability`).

    Attributes
    ----------
    holds : bool
        Every mode is observable.
    observable : ndarray of bool, shape (L,)
    n_observable : ndarray of int, shape (L,)
    margin : ndarray, shape (L,)
        PBH margin of each mode's observable part (see :class:`KalmanDecomposition`).
    """

    holds: bool
    observable: np.ndarray
    n_observable: np.ndarray
    margin: np.ndarray


@dataclass(frozen=True)
class JointObservability:
    """Lee et al. Assumption 1 (:func:`joint_observability`).

    Attributes
    ----------
    holds : bool
        :math:`\\operatorname{rank} [O_i^{(2n)}\\ O_j^{(2n)}] = 2n` for every pair :math:`i \\ne j`.
    failing_pairs : tuple of (int, int)
        The pairs :math:`(i, j)`, :math:`i < j`, 0-based, where it fails.
    margin : ndarray, shape (L, L)
        PBH margin of the augmented pair of each :math:`(i, j)`; ``nan`` on the diagonal.
    omega_min : float or None
        Lee et al.'s :math:`\\omega_{\\min}(t) = \\min_{i \\ne j} \\lambda_{\\min}(W_{ij}(t))` when
        a horizon :math:`t` was given (continuous-time systems only), else ``None``.
    """

    holds: bool
    failing_pairs: tuple[tuple[int, int], ...]
    margin: np.ndarray
    omega_min: float | None


@dataclass(frozen=True)
class CombinedObservability:
    """Wang et al. Assumption 2 (:func:`combined_observability`).

    Attributes
    ----------
    holds : bool
        Assumption 2(b): :math:`\\operatorname{rank} W_S = n`.
    rank : int
        Rank of :math:`W_S`, computed as the rank of :math:`F` (Wang et al. Lemma 3(b):
        :math:`\\ker F = \\ker W_S`), whose row blocks are orthonormal.
    W_S : ndarray, shape (L * n * n_outputs, n)
        Combined observability matrix, Wang et al. eq. (4) (for display; its rank
        is not computed from it).
    n_observable : ndarray of int, shape (L,)
        :math:`n_i = \\operatorname{rank} W(i)`, Assumption 2(a).
    F : ndarray, shape (n_s, n)
        :math:`[F_1; \\dots; F_L]` with :math:`n_s = \\sum_i n_i` (Wang et al. §3.2,
        :math:`z = F x`).
    Phi : ndarray, shape (n, n_s), or None
        :math:`(F^\\top F)^{-1} F^\\top` so that :math:`x = \\Phi z` (Wang et al. §3.2); ``None``
        unless ``holds``.
    """

    holds: bool
    rank: int
    W_S: np.ndarray
    n_observable: np.ndarray
    F: np.ndarray
    Phi: np.ndarray | None


@dataclass(frozen=True)
class UniformObservability:
    """Uniform observability constants of a sampled mode (:func:`uniform_observability`).

    Attributes
    ----------
    holds : bool
        :math:`(e^{AT}, H)` is observable (uniformly, with the window :math:`h`).
    h : int or None
        Smallest :math:`h \\ge 1` with the window Gramian of Shankar et al. Definition 1
        positive definite; ``None`` when not observable.
    rho : float
        :math:`\\lambda_{\\min}` of that Gramian (:math:`\\rho_1` of Definition 1); 0 when not
        observable.
    """

    holds: bool
    h: int | None
    rho: float


@dataclass(frozen=True)
class DwellTimeObservability:
    """Shankar et al. Lemma 1, as printed and corrected (:func:`dwell_time_observability`).

    Attributes
    ----------
    holds : bool
        The proven (corrected) lemma applies: every sampled mode is uniformly observable
        and :math:`\\tau_d \\ge (\\bar h + 1) T`, so every window of ``h_corrected`` samples has a
        Gramian of at least ``rho_corrected``.
    h_corrected : int or None
        :math:`2 \\bar h`: a window length that provably works under ``holds``.
    rho_corrected : float
        :math:`\\min_i \\rho_1^i \\cdot \\min(1, e^{2 \\nu \\bar h T})`,
        :math:`\\nu = \\min_i \\lambda_{\\min}((A_i + A_i^\\top)/2)`:
        a proven lower bound on the window Gramian under ``holds``.
    printed_lemma_holds : bool
        The hypotheses of Lemma 1 *as printed*: every sampled mode uniformly observable
        and :math:`\\tau_d > \\bar h T`. The printed lemma is false in general: its window ``h``
        and constant ``rho`` are not valid bounds (counter-example in
        :func:`dwell_time_observability`), so this is not a certificate.
    h : int or None
        :math:`2 \\bar h - 1`, the window claimed by the printed Lemma 1.
    rho : float
        :math:`\\min_i \\rho_1^i`, the constant claimed by the printed Lemma 1. NOT a valid bound
        in general.
    h_modes : tuple of (int or None)
        :math:`h_i` per mode.
    rho_modes : ndarray, shape (L,)
        :math:`\\rho_1^i` per mode.
    """

    holds: bool
    h_corrected: int | None
    rho_corrected: float
    printed_lemma_holds: bool
    h: int | None
    rho: float
    h_modes: tuple[int | None, ...]
    rho_modes: np.ndarray


# ---------------------------------------------------------------------- pairs (A, C)
def observability_matrix(A, C, order: int | None = None) -> np.ndarray:
    """Stacked observability matrix :math:`[C; CA; \\dots; CA^{\\mathrm{order}-1}]`.

    Lee et al. :math:`O_i^{(k)}` (§II, below Assumption 1); Wang et al. eq. (3) with
    ``order = n``. Its entries grow like :math:`\\lVert A \\rVert^{\\mathrm{order}-1}`: use it for
    teaching and small :math:`n`; decide observability with :func:`is_observable`.

    Parameters
    ----------
    A : array_like, shape (..., n, n)
    C : array_like, shape (..., m, n)
    order : int, optional
        Number of block rows :math:`k`; defaults to :math:`n`.

    Returns
    -------
    ndarray, shape (..., order * m, n)
    """
    A, C = _pair(A, C, batched=True)
    n = A.shape[-1]
    order = n if order is None else positive_int(order, "order")
    C = np.broadcast_to(C, (*np.broadcast_shapes(A.shape[:-2], C.shape[:-2]), *C.shape[-2:]))
    blocks = [C]
    for _ in range(order - 1):
        blocks.append(blocks[-1] @ A)
    return np.concatenate(blocks, axis=-2)


def is_observable(A, C, *, rtol: float = _RTOL) -> bool:
    """Whether :math:`(A, C)` is observable, by the PBH test with deflation.

    Correct where the rank of the observability matrix is not (e.g. :math:`n = 30` with
    eigenvalues :math:`-1, \\dots, -30`). The pair is declared unobservable when, at some
    eigenvalue,

    .. math::

        \\sigma_{\\min}([A - \\lambda I; C]) \\le \\mathrm{rtol} \\cdot
        \\max(\\lVert A \\rVert, \\lVert C \\rVert).

    Parameters
    ----------
    A, C, rtol
        As in :func:`kalman_decomposition`.

    Returns
    -------
    bool
    """
    return kalman_decomposition(A, C, rtol=rtol).n_observable == np.shape(A)[-1]


def kalman_decomposition(A, C, *, rtol: float = _RTOL) -> KalmanDecomposition:
    """Orthogonal observability decomposition of :math:`(A, C)` (Wang et al. §3.1).

    Unobservable directions are found one eigenvalue at a time by the PBH test
    (module docstring) and split off with orthogonal transformations, so :math:`T` is
    orthogonal and :math:`\\hat A = T^\\top A T` is exact up to round-off.

    Parameters
    ----------
    A : array_like, shape (n, n)
    C : array_like, shape (m, n)
    rtol : float, optional
        Relative tolerance of the PBH singular values (keyword-only).

    Returns
    -------
    KalmanDecomposition
    """
    A, C = _pair(A, C, batched=False)
    rtol = positive_scalar(rtol, "rtol")
    n = A.shape[0]
    M, N, margin = _unobservable_split(A, C, rtol)
    d = M.shape[1]
    T = np.concatenate([M, N], axis=1)
    A_hat = T.T @ A @ T
    C_hat = C @ T
    return KalmanDecomposition(
        T=T,
        M=M,
        N=N,
        G=M.T,
        F=N.T,
        A_hat=A_hat,
        C_hat=C_hat,
        A11=A_hat[:d, :d],
        A12=A_hat[:d, d:],
        A22=A_hat[d:, d:],
        C2=C_hat[:, d:],
        n_observable=n - d,
        margin=margin,
    )


# ---------------------------------------------------------------------- switched systems
def mode_observability(system: SwitchedLinearSystem, *, rtol: float = _RTOL) -> ModeObservability:
    """Observability of each mode :math:`(A_i, C_i)`.

    Lee et al. §II assume every mode observable; Wang et al. Assumption 2(a)
    allows :math:`n_i = \\operatorname{rank} W(i) < n`.
    """
    _check_system(system)
    decs = mode_decompositions(system, rtol=rtol)
    n_obs = np.array([d.n_observable for d in decs], dtype=np.int64)
    observable = n_obs == system.n_states
    return ModeObservability(
        holds=bool(observable.all()),
        observable=observable,
        n_observable=n_obs,
        margin=np.array([d.margin for d in decs]),
    )


def joint_observability(
    system: SwitchedLinearSystem, *, t: float | None = None, rtol: float = _RTOL
) -> JointObservability:
    """Lee et al. Assumption 1: :math:`\\operatorname{rank} [O_i^{(2n)}\\ O_j^{(2n)}] = 2n` for all
    :math:`i \\ne j`.

    :math:`[O_i^{(2n)}\\ O_j^{(2n)}]` is the observability matrix of order :math:`2n` of the
    augmented pair :math:`(\\operatorname{blockdiag}(A_i, A_j), [C_i, C_j])` (Lee et al. §II), so
    the rank condition is that pair's observability, tested here by PBH rather than by a rank.
    It implies that every mode is observable.

    Parameters
    ----------
    system : SwitchedLinearSystem
    t : float, optional
        Horizon for Lee et al.'s :math:`\\omega_{\\min}(t)` (continuous-time systems only).
    rtol : float, optional
        Relative tolerance of the PBH test.

    Returns
    -------
    JointObservability
        ``failing_pairs`` names the pairs :math:`(i, j)`, :math:`i < j` (0-based), that
        cannot be told apart from the output.
    """
    _check_system(system)
    L = system.n_modes
    margin = np.full((L, L), np.nan)
    failing = []
    for i, j in combinations(range(L), 2):
        Aij, Cij = _augmented(system, i, j)
        dec = kalman_decomposition(Aij, Cij, rtol=rtol)
        margin[i, j] = margin[j, i] = dec.margin if dec.n_observable == Aij.shape[0] else 0.0
        if dec.n_observable < Aij.shape[0]:
            failing.append((i, j))
    omega = None
    if t is not None:
        pairs = list(combinations(range(L), 2))
        omega = min((float(omega_min(system, i, j, t)) for i, j in pairs), default=float("inf"))
    return JointObservability(
        holds=not failing, failing_pairs=tuple(failing), margin=margin, omega_min=omega
    )


def joint_gramian(system: SwitchedLinearSystem, i: int, j: int, t) -> np.ndarray:
    """Joint observability Gramian :math:`W_{ij}(t)` of Lee et al. §II, exactly.

    .. math::

        W_{ij}(t) = \\int_0^t [\\phi_i\\ \\phi_j]^\\top [\\phi_i\\ \\phi_j]\\, d\\tau

    with :math:`\\phi_i(\\tau) = C_i e^{A_i \\tau}`, i.e. the observability Gramian of
    :math:`(\\bar A, \\bar C) = (\\operatorname{blockdiag}(A_i, A_j), [C_i, C_j])`. It equals the
    process-noise integral :math:`\\int_0^t e^{M s} Q e^{M^\\top s}\\, ds` of the system
    :math:`M = \\bar A^\\top`, :math:`Q = \\bar C^\\top \\bar C`, which
    :func:`switchest.discretize.interval` computes by Van Loan's block exponential — no
    quadrature.

    Parameters
    ----------
    system : SwitchedLinearSystem
        Continuous-time.
    i, j : int
        Modes, 0-based (:math:`i = j` is allowed and gives a singular Gramian).
    t : float or array_like of float
        Horizon(s), positive.

    Returns
    -------
    ndarray, shape (2n, 2n) or (..., 2n, 2n) for an array ``t``
    """
    _check_system(system)
    if system.domain != "continuous":
        raise ValueError(
            f"system must be continuous-time for the Gramian of Lee et al., got {system.domain!r}"
        )
    i, j = check_mode(i, system.n_modes, "i"), check_mode(j, system.n_modes, "j")
    t = float_array(t, "t")
    check_finite(t, "t")
    if np.any(t <= 0):
        raise ValueError(f"t must be positive, got minimum {t.min():.3g}")
    Abar, Cbar = _augmented(system, i, j)
    dual = SwitchedLinearSystem.continuous(Abar.T, Q=Cbar.T @ Cbar)
    return interval(dual, t, np.zeros(1, dtype=np.int64)).Qd


def omega_min(system: SwitchedLinearSystem, i: int, j: int, t) -> np.ndarray | float:
    """:math:`\\lambda_{\\min}(W_{ij}(t))` (Lee et al. §II); minimize over pairs for
    :math:`\\omega_{\\min}(t)`.

    :func:`joint_observability` with ``t=...`` reports the minimum over all pairs
    :math:`i \\ne j`, which is Lee et al.'s :math:`\\omega_{\\min}(t)`. An eigenvalue within the
    eigensolver's rounding, :math:`4 (2n) \\varepsilon \\lambda_{\\max}`, is 0: the Gramian is
    singular (the pair cannot be told apart) and its rounding, of either sign, carries no
    information.
    """
    W = joint_gramian(system, i, j, t)
    eig = np.linalg.eigvalsh(W)
    rounding = 4 * W.shape[-1] * np.finfo(float).eps * np.abs(eig[..., -1])
    lam = np.where(np.abs(eig[..., 0]) <= rounding, 0.0, eig[..., 0])
    return float(lam) if lam.ndim == 0 else lam


def mode_decompositions(
    system: SwitchedLinearSystem, *, rtol: float = _RTOL
) -> tuple[KalmanDecomposition, ...]:
    """Wang et al. §3.1: the Kalman observability decomposition of every mode."""
    _check_system(system)
    return tuple(
        kalman_decomposition(system.A[i], system.C[i], rtol=rtol) for i in range(system.n_modes)
    )


def combined_observability(
    system: SwitchedLinearSystem, *, rtol: float = _RTOL
) -> CombinedObservability:
    """Wang et al. Assumption 2: the combined observability matrix :math:`W_S` has rank :math:`n`.

    :math:`W_S = [W(1); \\dots; W(L)]` (eq. (4)) with :math:`W(i)` the observability matrix of
    mode :math:`i` (eq. (3); Wang et al. §2.2 print :math:`W` in :math:`\\mathbb{R}^{m \\times n}`,
    but with :math:`r` outputs it is :math:`(n r) \\times n` — their :math:`m` counts modes). Its
    rank equals that of :math:`F = [F_1; \\dots; F_L]` (Lemma 3(b)), whose blocks are orthonormal
    bases of the modes' observable subspaces; the rank is taken from :math:`F` with
    singular-value tolerance ``rtol``.
    """
    _check_system(system)
    rtol = positive_scalar(rtol, "rtol")
    decs = mode_decompositions(system, rtol=rtol)
    n = system.n_states
    F = np.concatenate([d.F for d in decs], axis=0)
    s = np.linalg.svd(F, compute_uv=False) if F.shape[0] else np.zeros(0)
    rank = int(np.sum(s > rtol))
    holds = rank == n
    return CombinedObservability(
        holds=holds,
        rank=rank,
        W_S=observability_matrix(system.A, system.C).reshape(-1, n),
        n_observable=np.array([d.n_observable for d in decs], dtype=np.int64),
        F=F,
        Phi=np.linalg.solve(F.T @ F, F.T) if holds else None,
    )


# ---------------------------------------------------------------------- sampled modes (Shankar)
def uniform_observability(A, H, T: float, *, R=None, rtol: float = _RTOL) -> UniformObservability:
    """Uniform observability constants of one periodically sampled mode.

    Shankar et al. Definition 1 and Assumption 1 for the constant pair
    :math:`(F, H) = (e^{AT}, H)`: the smallest :math:`h \\ge 1` such that

    .. math::

        O_h = \\sum_{i=0}^{h} (F^i)^\\top H^\\top R^{-1} H F^i

    is positive definite, and :math:`\\rho_1 = \\lambda_{\\min}(O_h)`. (Definition 1 writes the
    sum with :math:`\\Phi_{k+h,i}`, the proof of Lemma 1 with :math:`\\Phi_{i,k}`; for a constant
    :math:`F` both give this :math:`O_h`.) Observability of :math:`(F, H)` is decided by the
    PBH test; sampling can destroy it (eigenvalues of :math:`A` differing by
    :math:`2 \\pi k i / T`). :math:`h` is the first window with
    :math:`\\lambda_{\\min}(O_h) > \\mathrm{rtol} \\cdot \\lambda_{\\max}(O_h)`, at most
    :math:`\\max(n - 1, 1)`.

    Parameters
    ----------
    A : array_like, shape (n, n)
        Continuous-time mode matrix.
    H : array_like, shape (m, n)
        Output matrix.
    T : float
        Sampling period, positive.
    R : array_like, shape (m, m), optional
        Measurement-noise covariance (symmetric positive definite); identity when
        omitted.
    rtol : float, optional
        Relative tolerance of the PBH test and of the Gramian's definiteness.

    Returns
    -------
    UniformObservability
    """
    A, H = _pair(A, H, batched=False, output="H")
    T = positive_scalar(T, "T")
    rtol = positive_scalar(rtol, "rtol")
    m, n = H.shape
    if R is None:
        R = np.eye(m)
    else:
        R = float_array(R, "R", ndim=2)
        if R.shape != (m, m):
            raise ValueError(f"R must have shape ({m}, {m}), got {R.shape}")
        R = check_symmetric_psd(R, "R", definite=True)
    F = interval(SwitchedLinearSystem.continuous(A), T, np.zeros(1, dtype=np.int64)).F
    Hw = np.linalg.solve(np.linalg.cholesky(R), H)  # R^{-1/2} H: Hw' Hw = H' R^{-1} H
    if not is_observable(F, Hw, rtol=rtol):
        return UniformObservability(holds=False, h=None, rho=0.0)
    gram = Hw.T @ Hw
    power = np.eye(n)
    h_max = max(n - 1, 1)
    for h in range(1, h_max + 1):
        power = power @ F
        gram = gram + power.T @ Hw.T @ Hw @ power
        lam = np.linalg.eigvalsh(symmetrize(gram))
        if lam[0] > rtol * lam[-1] or h == h_max:
            return UniformObservability(holds=True, h=h, rho=float(max(lam[0], 0.0)))
    raise AssertionError("unreachable: the loop returns at h = h_max")  # pragma: no cover


def dwell_time_observability(
    system: SwitchedLinearSystem, T: float, tau_d: float, *, rtol: float = _RTOL
) -> DwellTimeObservability:
    """Shankar et al. Lemma 1: uniform observability under a dwell time.

    With every sampled mode :math:`(e^{A_i T}, C_i)` uniformly observable with
    constants :math:`(h_i, \\rho_1^i)` (Assumption 1) and :math:`\\tau_d > \\bar h T`,
    :math:`\\bar h = \\max_i h_i`, Lemma 1 states that every window Gramian

    .. math::

        \\sum_{i=k}^{k+h} \\Phi_{i,k}^\\top H^\\top R^{-1} H \\Phi_{i,k}

    of the switched sampled system is :math:`\\succeq \\rho_1 I` with :math:`h = 2 \\bar h - 1` and
    :math:`\\rho_1 = \\min_i \\rho_1^i`.
    Those printed constants are returned as ``h``, ``rho``, ``printed_lemma_holds``.

    They are not valid in general (tests/analysis/test_observability.py shows a
    window Gramian with min eigenvalue 4.6e-6 against a claimed 0.289): the
    window of :math:`2 \\bar h` samples need not contain the :math:`h_j + 1` consecutive
    samples of one mode that mode :math:`j`'s Gramian needs, and the samples of mode :math:`j`
    start from :math:`\\Phi_{s,k} x`, not from :math:`x`, so :math:`\\rho_j` must be scaled by
    :math:`\\sigma_{\\min}(\\Phi_{s,k})^2`. The corrected statement proved here:

    * a stay of length :math:`\\ge (\\bar h + 1) T` contains :math:`\\bar h + 1` consecutive
      samples :math:`t_s, \\dots, t_{s + \\bar h}` in one mode, whatever its phase on
      the sample grid; with :math:`\\tau_d \\ge (\\bar h + 1) T` every window of
      :math:`h = 2 \\bar h` intervals contains such a run starting at :math:`s \\le k + \\bar h`
      (the first switch after :math:`t_k` is either later than :math:`t_{k + \\bar h}` —
      the run starts at :math:`t_k` — or the next stay starts a run at
      :math:`t_{k + \\bar h}` at the latest, which lasts to :math:`t_{k + 2 \\bar h}`);
    * the window Gramian dominates that run's terms:
      :math:`x^\\top G x \\ge \\rho_j \\lVert \\Phi_{s,k} x \\rVert^2`, and
      :math:`\\sigma_{\\min}(e^{A t}) \\ge e^{\\nu t}` with
      :math:`\\nu = \\lambda_{\\min}((A + A^\\top)/2)` over every mode, so
      :math:`G \\succeq \\min_j \\rho_j \\min(1, e^{2 \\nu \\bar h T}) I`.

    That statement is returned as ``holds``, ``h_corrected``, ``rho_corrected``.

    Parameters
    ----------
    system : SwitchedLinearSystem
        Continuous-time; ``C[i]`` plays the role of :math:`H` in mode ``i`` (Shankar et
        al. have one :math:`H`); ``R[i]`` weights mode ``i``'s Gramian (identity for a
        noise-free system).
    T : float
        Sampling period.
    tau_d : float
        Dwell time.
    rtol : float, optional
        As in :func:`uniform_observability`.
    """
    _check_system(system)
    if system.domain != "continuous":
        raise ValueError(
            f"system must be continuous-time (sampled with period T), got {system.domain!r}"
        )
    T = positive_scalar(T, "T")
    tau_d = positive_scalar(tau_d, "tau_d")
    per_mode = []
    for i in range(system.n_modes):
        R = system.R[i] if system.has_measurement_noise else None
        per_mode.append(uniform_observability(system.A[i], system.C[i], T, R=R, rtol=rtol))
    h_modes = tuple(u.h for u in per_mode)
    rho_modes = np.array([u.rho for u in per_mode])
    if not all(u.holds for u in per_mode):
        return DwellTimeObservability(
            holds=False,
            h_corrected=None,
            rho_corrected=0.0,
            printed_lemma_holds=False,
            h=None,
            rho=0.0,
            h_modes=h_modes,
            rho_modes=rho_modes,
        )
    h_bar = max(h_modes)
    nu = float(np.min(np.linalg.eigvalsh(symmetrize(system.A))))
    return DwellTimeObservability(
        holds=tau_d >= (h_bar + 1) * T,
        h_corrected=2 * h_bar,
        rho_corrected=float(rho_modes.min() * min(1.0, np.exp(2 * nu * h_bar * T))),
        printed_lemma_holds=tau_d > h_bar * T,
        h=2 * h_bar - 1,
        rho=float(rho_modes.min()),
        h_modes=h_modes,
        rho_modes=rho_modes,
    )


def window_gramian(system: SwitchedLinearSystem, T: float, h: int, switch_times,
                   modes) -> np.ndarray:
    """The window Gramian of the sampled switched system (Shankar et al., proof of Lemma 1).

    .. math::

        G = \\sum_{i=0}^{h} \\Phi_{i,0}^\\top C_i^\\top R_i^{-1} C_i \\Phi_{i,0}

    over the samples :math:`t_i = i T`, where :math:`\\Phi_{i,0}` is the exact transition from
    :math:`t_0 = 0` to :math:`t_i` (segment exponentials composed across every switch inside an
    interval, Shankar et al. eqs (3)-(5)) and :math:`C_i`, :math:`R_i` are those of the mode
    active at :math:`t_i`; :math:`R` is the identity for a noise-free system. Lemma 1 claims
    :math:`G \\succeq \\rho_1 I`: the smallest
    eigenvalue of this matrix is what the claim is checked against
    (:func:`dwell_time_observability`).

    Parameters
    ----------
    system : SwitchedLinearSystem
        Continuous-time.
    T : float
        Sampling period.
    h : int
        The window: samples :math:`0, \\dots, h`.
    switch_times : array_like, shape (S,)
        Increasing switching instants (any sign: a switch before 0 sets the mode at 0).
    modes : array_like of int, shape (S + 1,)
        ``modes[q]`` is active between ``switch_times[q-1]`` and ``switch_times[q]``.
    """
    _check_system(system)
    if system.domain != "continuous":
        raise ValueError(f"system must be continuous-time, got {system.domain!r}")
    T = positive_scalar(T, "T")
    h = positive_int(h, "h")
    times = float_array(switch_times, "switch_times", ndim=1)
    check_finite(times, "switch_times")
    if np.any(np.diff(times) <= 0):
        raise ValueError("switch_times must be strictly increasing")
    modes = np.asarray(modes)
    if modes.shape != (times.size + 1,):
        raise ValueError(f"modes must have shape ({times.size + 1},) (one more than the switch "
                         f"times), got {modes.shape}")
    for q, mode in enumerate(modes):
        check_mode(mode, system.n_modes, f"modes[{q}]")

    def mode_at(t: float) -> int:
        return int(modes[np.searchsorted(times, t, side="right")])

    n = system.n_states
    gram, phi = np.zeros((n, n)), np.eye(n)
    for i in range(h + 1):
        mode = mode_at(i * T)
        C = system.C[mode]
        if system.has_measurement_noise:
            C = np.linalg.solve(np.linalg.cholesky(system.R[mode]), C)  # R^{-1/2} C
        gram += phi.T @ C.T @ C @ phi
        inside = times[(times > i * T) & (times < (i + 1) * T)]
        cuts = np.concatenate([[i * T], inside, [(i + 1) * T]])
        for lo, hi in itertools.pairwise(cuts):
            phi = expm(system.A[mode_at(lo)] * (hi - lo)) @ phi
    return symmetrize(gram)


# ---------------------------------------------------------------------- helpers
def _unobservable_split(A: np.ndarray, C: np.ndarray, rtol: float):
    """Orthonormal bases :math:`(M, N)` of the unobservable subspace and its complement.

    PBH with deflation: while some eigenvalue of the remaining block has
    :math:`\\sigma_{\\min}([A - \\lambda I; C]) \\le \\mathrm{tol}`, its null vector (an eigenvector
    in :math:`\\ker C`; real and imaginary parts for a complex pair) is split off by an
    orthogonal similarity and the test repeats on the complement.
    """
    n = A.shape[0]
    scale = max(np.linalg.norm(A, 2), np.linalg.norm(C, 2) if C.size else 0.0)
    tol = rtol * scale
    basis = np.eye(n)  # columns span the part still to be examined
    found = []
    Ak, Ck = A, C
    margin = np.inf
    while Ak.shape[0] > 0:
        k = Ak.shape[0]
        lam = _pbh_points(np.linalg.eigvals(Ak), scale)
        stack = np.concatenate(
            [Ak[None] - lam[:, None, None] * np.eye(k), np.broadcast_to(Ck, (len(lam), *Ck.shape))],
            axis=1,
        )
        _, s, vh = np.linalg.svd(stack)
        smin = s[:, -1]
        worst = int(np.argmin(smin))
        if smin[worst] > tol:
            margin = float(smin[worst])
            break
        v = vh[worst, -1].conj()  # right singular vector of the smallest value
        if abs(lam[worst].imag) > tol:
            V = np.stack([v.real, v.imag], axis=1)
        else:
            V = (v.real if np.linalg.norm(v.real) >= np.linalg.norm(v.imag) else v.imag)[:, None]
        Q, _ = qr(V, mode="full")
        d = V.shape[1]
        found.append(basis @ Q[:, :d])
        W = Q[:, d:]
        basis = basis @ W
        Ak, Ck = W.T @ Ak @ W, Ck @ W
    M = np.concatenate(found, axis=1) if found else np.zeros((n, 0))
    return M, basis, margin


def _pbh_points(lam: np.ndarray, scale: float) -> np.ndarray:
    """Eigenvalues plus the centroids of their clusters.

    A Jordan block of size :math:`k` splits under round-off into :math:`k` eigenvalues about
    :math:`\\varepsilon^{1/k} \\lVert A \\rVert` apart, where the PBH singular value is no longer
    small; their centroid is accurate to round-off. Clusters are taken at the relative
    radii 1e-6, 1e-4 and 1e-2 (single linkage).
    """
    points = [lam]
    dist = np.abs(lam[:, None] - lam[None, :])
    for radius in (1e-6, 1e-4, 1e-2):
        n_comp, label = connected_components(csr_matrix(dist <= radius * max(scale, 1e-300)))
        if n_comp < lam.size:
            sizes = np.bincount(label)
            means = np.bincount(label, lam.real) / sizes + 1j * np.bincount(label, lam.imag) / sizes
            points.append(means[sizes > 1])
    return np.concatenate(points)


def _augmented(system: SwitchedLinearSystem, i: int, j: int) -> tuple[np.ndarray, np.ndarray]:
    n = system.n_states
    Abar = np.zeros((2 * n, 2 * n))
    Abar[:n, :n] = system.A[i]
    Abar[n:, n:] = system.A[j]
    return Abar, np.concatenate([system.C[i], system.C[j]], axis=1)


def _pair(A, C, *, batched: bool, output: str = "C") -> tuple[np.ndarray, np.ndarray]:
    """Validated :math:`(A, C)`; ``output`` is the name of the output matrix in messages.

    At least one output is required (:math:`m \\ge 1`), as for a
    :class:`~switchest.system.SwitchedLinearSystem`.
    """
    A = float_array(A, "A", ndim=None if batched else 2)
    C = float_array(C, output, ndim=None if batched else 2)
    if A.ndim < 2 or A.shape[-1] != A.shape[-2] or A.shape[-1] == 0:
        raise ValueError(f"A must be a non-empty square (n, n) matrix, got shape {A.shape}")
    if C.ndim < 2 or C.shape[-1] != A.shape[-1] or C.shape[-2] == 0:
        raise ValueError(
            f"{output} must have shape (m, {A.shape[-1]}) with m >= 1 to match A, got {C.shape}"
        )
    if batched:
        broadcast_batch({"A": A.shape[:-2], output: C.shape[:-2]})
    check_finite(A, "A")
    check_finite(C, output)
    return A, C


def _check_system(system) -> None:
    if not isinstance(system, SwitchedLinearSystem):
        raise TypeError(f"system must be a SwitchedLinearSystem, got {type(system).__name__}")


