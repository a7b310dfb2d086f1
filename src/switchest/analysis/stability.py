"""Stability of switched linear systems under arbitrary and random switching.

* :func:`spectral_radius` — batched.
* :func:`cqlf` — a common quadratic Lyapunov function :math:`V(x) = x^\\top P x` for a family
  of matrices (Zhang & Natarajan, Lemma 1 (ii) and eq. (13) in discrete time; the
  continuous-time analogue :math:`A_i^\\top P + P A_i \\prec 0`), as an LMI re-verified with numpy.
* :func:`jsr_bounds` — a bracket on the joint spectral radius (beyond the papers):
  products of bounded length from below, the best common quadratic norm and a
  prefix-code product tree in that norm from above. It tells how conservative an
  infeasible CQLF was.
* :func:`ms_stable_iid` — mean-square stability of i.i.d. random switching.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from scipy.sparse.linalg import ArpackError, LinearOperator, eigs

from .._checks import (
    check_finite,
    check_probability_vector,
    float_array,
    positive_int,
    positive_scalar,
)
from .._threads import one_blas_thread
from ._lmi import (
    cp,
    max_eigenvalue,
    min_eigenvalue,
    rounding_allowance,
    solve_sdp,
    symmetric_block,
)

__all__ = [
    "JSRBounds",
    "LyapunovCertificate",
    "MeanSquareStability",
    "cqlf",
    "decrease_margin",
    "jsr_bounds",
    "ms_stable_iid",
    "spectral_radius",
]

Domain = Literal["discrete", "continuous"]

_MAX_BISECTIONS = 60  # lo = 0 (nilpotent families) never meets the relative tolerance
_DENSE_KRON_MAX = 32  # n above which ms_stable_iid works matrix-free (n^2 x n^2 would be dense)
_EPS = np.finfo(float).eps

_FEASIBLE_NOTE = "P >= I certifies stability under arbitrary switching (checked with numpy)"
_INFEASIBLE_NOTE = (
    "no common quadratic Lyapunov function was found; this is not a proof of instability "
    "(a switched system can be stable under arbitrary switching without a CQLF) — "
    "see jsr_bounds for how conservative the quadratic test is"
)


@dataclass(frozen=True)
class LyapunovCertificate:
    """Outcome of :func:`cqlf`.

    Attributes
    ----------
    holds : bool
        A common quadratic Lyapunov function exists: True only when the returned ``P``
        passed the numpy re-verification, with the rounding of that check allowed for.
    P : ndarray, shape (n, n), or None
        The certificate, scaled so that its smallest eigenvalue is 1 (:math:`P \\succeq I`);
        ``None`` when not feasible.
    margin : float
        Verified decrease margin of the scaled ``P``:
        :math:`\\min_i -\\lambda_{\\max}(A_i^\\top P A_i - P)` (discrete) or
        :math:`\\min_i -\\lambda_{\\max}(A_i^\\top P + P A_i)` (continuous). NaN when not feasible.
    solver_status : str
        Status reported by the solver that answered (``"optimal"``,
        ``"infeasible"``, ``"optimal_inaccurate"``, ``"solver_error"``, ...).
    domain : {"discrete", "continuous"}
    note : str
        What the verdict means; an infeasible verdict is not a proof of instability.
    """

    holds: bool
    P: np.ndarray | None
    margin: float
    solver_status: str
    domain: str
    note: str


@dataclass(frozen=True)
class JSRBounds:
    """Outcome of :func:`jsr_bounds`:
    :math:`\\mathrm{lower} \\le \\mathrm{JSR} \\le \\mathrm{upper}`.

    Both bounds are rounded outward by the rounding allowance of their computation, so
    that the bracket holds whatever the last bits of the arithmetic, and
    :math:`\\mathrm{lower} \\le \\mathrm{upper}` always.

    Attributes
    ----------
    lower : float
        :math:`\\max \\rho(W)^{1/|W|}` over the products :math:`W` visited, rounded down.
    upper : float
        :math:`\\min(\\mathrm{ellipsoid}, \\mathrm{tree})`, rounded up.
    ellipsoid : float
        Best common quadratic norm bound: smallest :math:`r` (to ``rtol``) with a CQLF
        for :math:`\\{A_i / r\\}` — the bound a CQLF alone can give
        (:math:`\\max_i \\lVert A_i \\rVert_2` when :func:`jsr_bounds` was called with
        ``quadratic=False``).
    tree : float
        Prefix-code bound :math:`\\max \\lVert W \\rVert_P^{1/|W|}` over the leaves of the product
        tree in the norm of that CQLF (the spectral norm when none was found).
    word : tuple of int
        Mode sequence (0-based, first applied first) attaining ``lower``.
    n_products : int
        Number of products whose norm and spectral radius were evaluated.
    """

    lower: float
    upper: float
    ellipsoid: float
    tree: float
    word: tuple[int, ...]
    n_products: int


@dataclass(frozen=True)
class MeanSquareStability:
    """Outcome of :func:`ms_stable_iid`.

    Attributes
    ----------
    radius : float
        Spectral radius of :math:`\\sum_i p_i (A_i \\otimes A_i)`.
    holds : bool
        :math:`\\mathrm{radius} < 1` by more than the rounding allowance of ``radius``: the
        second moment :math:`\\mathbb{E}[x_k x_k^\\top]` converges to zero.
    """

    radius: float
    holds: bool


def spectral_radius(A) -> np.ndarray:
    """Spectral radius :math:`\\max_j |\\lambda_j(A)|` of each matrix in a stack.

    Parameters
    ----------
    A : array_like, shape (..., n, n)

    Returns
    -------
    ndarray, shape (...)
    """
    A = _matrix_stack(A, "A", min_ndim=2)
    return np.max(np.abs(np.linalg.eigvals(A)), axis=-1)


def cqlf(matrices, domain: Domain = "discrete", *, margin: float = 1e-6) -> LyapunovCertificate:
    """Find a common quadratic Lyapunov function for a family of matrices.

    Discrete time (Zhang & Natarajan, eq. (13)): :math:`P = P^\\top`, :math:`P \\succeq I`,
    :math:`A_i^\\top P A_i - P \\preceq -\\mathrm{margin} \\, I` for all i. Continuous time:
    :math:`P \\succeq I`, :math:`A_i^\\top P + P A_i \\preceq -\\mathrm{margin} \\, I`. The strict
    inequalities of the papers are posed with the explicit margin; the homogeneous problem
    loses nothing by the normalization :math:`P \\succeq I`. The solver's ``P`` is then
    re-checked with numpy eigenvalues after rescaling it to :math:`\\lambda_{\\min}(P) = 1`;
    ``holds`` is True only if the verified decrease margin, less the rounding allowance of its
    computation (:func:`~switchest.analysis._lmi.rounding_allowance`: forming
    :math:`A_i^\\top P A_i - P` and its eigenvalues, :math:`2 (3n + 1) \\varepsilon` times the
    size of the terms), is at least :math:`\\mathrm{margin} / 2` (half the posed margin, leaving
    room for the solver's feasibility tolerance). The smallest eigenvalue of ``P`` must
    likewise exceed its rounding.

    Parameters
    ----------
    matrices : array_like, shape (L, n, n) or (n, n)
        The mode matrices (a single matrix is a family of one).
    domain : {"discrete", "continuous"}, optional
        ``"discrete"``: :math:`x_{k+1} = A_i x_k`; ``"continuous"``: :math:`dx/dt = A_i x`.
    margin : float, optional
        Decrease margin posed in the LMI (keyword-only), positive.

    Returns
    -------
    LyapunovCertificate
        An infeasible verdict is not a proof of instability (see ``note``).

    Raises
    ------
    ValueError
        If ``matrices`` is not a stack of finite square matrices, ``domain`` is
        unknown or ``margin`` is not positive.
    """
    A = _matrix_stack(matrices, "matrices", min_ndim=2, max_ndim=3)
    A = A[None] if A.ndim == 2 else A
    domain = _check_domain(domain)
    margin = positive_scalar(margin, "margin")
    n = A.shape[-1]
    P = cp.Variable((n, n), symmetric=True)
    eye = np.eye(n)
    constraints = [symmetric_block([[P - eye]]) >> 0]
    for Ai in A:
        constraints.append(symmetric_block([[_decrease(Ai, P, domain) + margin * eye]]) << 0)
    problem = cp.Problem(cp.Minimize(0), constraints)
    outcome = solve_sdp(problem)
    if outcome.status != cp.OPTIMAL and not (
        outcome.status == cp.OPTIMAL_INACCURATE and P.value is not None
    ):
        return _infeasible(outcome.status, domain, _INFEASIBLE_NOTE)
    Pv = 0.5 * (P.value + P.value.T)
    if not np.all(np.isfinite(Pv)):
        return _infeasible(outcome.status, domain,
                           "the solver's P is not finite; " + _INFEASIBLE_NOTE)
    lowest = float(min_eigenvalue(Pv))
    if lowest <= rounding_allowance(np.linalg.norm(Pv), n):
        return _infeasible(
            outcome.status,
            domain,
            f"the solver's P is not positive definite beyond rounding (min eigenvalue "
            f"{lowest:.3g}); " + _INFEASIBLE_NOTE,
        )
    Pv = Pv / lowest
    margins, allowance = _verified_decrease(A, Pv, domain)
    verified = float(np.min(margins))
    if np.min(margins - allowance) < 0.5 * margin:
        return _infeasible(
            outcome.status,
            domain,
            f"the solver's P failed the numpy check (decrease margin {verified:.3g}, less its "
            f"rounding allowance {float(np.max(allowance)):.2g}, < {0.5 * margin:.3g}); "
            + _INFEASIBLE_NOTE,
        )
    return LyapunovCertificate(
        holds=True,
        P=Pv,
        margin=verified,
        solver_status=outcome.status,
        domain=domain,
        note=_FEASIBLE_NOTE,
    )


def decrease_margin(matrices, P, *, domain: Domain = "discrete") -> float:
    """Numpy check of a candidate Lyapunov matrix: :math:`\\min_i -\\lambda_{\\max}(D_i)`.

    :math:`D_i = A_i^\\top P A_i - P` (discrete) or :math:`A_i^\\top P + P A_i` (continuous). A
    positive value means :math:`V(x) = x^\\top P x` decreases along every mode. The value is
    as computed; :func:`cqlf` compares it with its threshold only beyond its rounding.

    Parameters
    ----------
    matrices : array_like, shape (L, n, n) or (n, n)
    P : array_like, shape (n, n)
        Finite.
    domain : {"discrete", "continuous"}, optional

    Raises
    ------
    ValueError
        If ``matrices`` or ``P`` is not finite or their shapes disagree.
    """
    A = _matrix_stack(matrices, "matrices", min_ndim=2, max_ndim=3)
    A = A[None] if A.ndim == 2 else A
    P = float_array(P, "P", ndim=2)
    if P.shape != A.shape[1:]:
        raise ValueError(f"P must have shape {A.shape[1:]}, got {P.shape}")
    check_finite(P, "P")
    domain = _check_domain(domain)
    return float(np.min(_verified_decrease(A, P, domain)[0]))


def jsr_bounds(
    matrices,
    *,
    max_length: int = 32,
    max_products: int = 20000,
    rtol: float = 1e-4,
    prune_tol: float = 1e-3,
    quadratic: bool = True,
) -> JSRBounds:
    """Bracket the joint spectral radius of a finite family of matrices.

    Beyond the papers (Zhang & Natarajan cite the JSR only as undecidable, their
    ref. [40]); this shows how far a quadratic certificate is from the truth.

    * Ellipsoid bound: bisection on :math:`r` for a CQLF of :math:`\\{A_i / r\\}`
      (:func:`cqlf`); a CQLF :math:`P` gives :math:`\\lVert A_i \\rVert_P \\le r` for every mode,
      hence :math:`\\mathrm{JSR} \\le r`.
    * Lower bound: :math:`\\mathrm{JSR} \\ge \\rho(W)^{1/|W|}` for every product :math:`W` of the
      :math:`A_i`; products are enumerated breadth-first up to ``max_length``.
    * Tree bound (a prefix code in the CQLF norm :math:`\\lVert x \\rVert_P = \\sqrt{x^\\top P x}`):
      a product :math:`W` is not extended once
      :math:`\\lVert W \\rVert_P^{1/|W|} \\le \\mathrm{lower} \\, (1 + \\mathrm{prune\\_tol})`
      (pruning) or :math:`W` is zero to working precision, nor beyond ``max_length`` or once
      ``max_products`` are reached. The unextended products (the leaves) form a complete
      prefix code: every infinite mode sequence factors into leaves, so by submultiplicativity
      :math:`\\mathrm{JSR} \\le \\max_{\\mathrm{leaves}} \\lVert W \\rVert_P^{1/|W|}`.

    Rounding: a product :math:`W` of :math:`k` matrices is computed to within
    :math:`(k + 1) n` rounding errors of :math:`\\prod_j \\lVert A_{w_j} \\rVert_F` (the matrix
    products and the eigen- or singular value solver,
    :func:`~switchest.analysis._lmi.rounding_allowance`), and its :math:`P`-norm to
    within :math:`\\operatorname{cond}(R)` times that (:math:`P = R^\\top R`). Each
    :math:`\\rho(W)` is lowered and each :math:`\\lVert W \\rVert_P` raised by that allowance
    before the :math:`k`-th root, which is then rounded outward by a few ulps: the bracket holds
    whatever the last bits of the arithmetic. Singular values are perfectly
    conditioned, eigenvalues of a non-normal product need not be; should the two
    bounds still cross, ``lower`` is lowered to ``upper``.

    Parameters
    ----------
    matrices : array_like, shape (L, n, n)
    max_length : int, optional
        Longest product enumerated (keyword-only).
    max_products : int, optional
        Budget on the number of products evaluated.
    rtol : float, optional
        Relative tolerance of the ellipsoid bisection.
    prune_tol : float, optional
        Relative slack of the pruning rule.
    quadratic : bool, optional
        Search the best common quadratic norm (an LMI bisection whose cost grows
        like :math:`n^6`); ``False`` bounds in the spectral norm instead
        (:math:`\\mathrm{ellipsoid} = \\max_i \\lVert A_i \\rVert_2`), for large :math:`n`.

    Returns
    -------
    JSRBounds
    """
    A = _matrix_stack(matrices, "matrices", min_ndim=3, max_ndim=3)
    max_length = positive_int(max_length, "max_length")
    max_products = positive_int(max_products, "max_products")
    rtol = positive_scalar(rtol, "rtol")
    prune_tol = positive_scalar(prune_tol, "prune_tol")
    if not isinstance(quadratic, (bool, np.bool_)):
        raise TypeError(f"quadratic must be a bool, got {type(quadratic).__name__}")
    L, n = A.shape[0], A.shape[-1]
    ellipsoid, P = _ellipsoid_bound(A, rtol) if quadratic else (_spectral_bound(A, 0.0), np.eye(n))
    norm, cond = _p_norm(P)
    size_A = np.linalg.norm(A, axis=(-2, -1))  # Frobenius: bounds every entry's rounding
    radii = _radius_below(spectral_radius(A), size_A, n, 1)
    best = int(np.argmax(radii))
    lower, word = float(radii[best]), (best,)
    words = np.arange(L)[:, None]
    prods, sizes = A, size_A  # sizes: prod_j ||A_{w_j}||_F along each word
    leaf_bound = 0.0
    evaluated = L
    for length in range(1, max_length + 1):
        slack = rounding_allowance(cond * sizes, (length + 3) * n)
        norms = norm(prods)
        growth = (norms + slack) ** (1.0 / length) * (1.0 + 4 * _EPS)
        # a product that is zero to working precision is a leaf: its children would be too,
        # and the k-th root of their rounding allowance only grows with k
        expand = (growth > lower * (1.0 + prune_tol)) & (norms > slack)
        room = evaluated + L * int(expand.sum()) <= max_products
        if length == max_length or not room:
            expand[:] = False
        leaf_bound = max(leaf_bound, float(np.max(growth[~expand], initial=0.0)))
        if not expand.any():
            break
        # children W' = A_i W: mode i applied after the word W
        prods = np.einsum("iab,wbc->wiac", A, prods[expand]).reshape(-1, n, n)
        sizes = (sizes[expand][:, None] * size_A[None, :]).ravel()
        words = np.concatenate(
            [np.repeat(words[expand], L, axis=0), np.tile(np.arange(L), expand.sum())[:, None]],
            axis=1,
        )
        evaluated += prods.shape[0]
        radii = _radius_below(spectral_radius(prods), sizes, n, length + 1)
        k = int(np.argmax(radii))
        if radii[k] > lower:
            lower, word = float(radii[k]), tuple(int(w) for w in words[k])
    upper = min(ellipsoid, leaf_bound)
    return JSRBounds(
        lower=min(lower, upper),
        upper=upper,
        ellipsoid=ellipsoid,
        tree=leaf_bound,
        word=word,
        n_products=evaluated,
    )


def _radius_below(rho: np.ndarray, sizes: np.ndarray, n: int, k: int) -> np.ndarray:
    """:math:`\\rho(W)^{1/k}` of computed products :math:`W` of :math:`k` matrices, rounded down
    by the rounding allowance of :math:`W` and of its eigenvalues (exact for normal :math:`W`)."""
    certain = np.maximum(rho - rounding_allowance(sizes, (k + 1) * n), 0.0)
    return certain ** (1.0 / k) * (1.0 - 4 * _EPS)


def ms_stable_iid(A, p) -> MeanSquareStability:
    """Mean-square stability of :math:`x_{k+1} = A_{s_k} x_k` with i.i.d. modes.

    With :math:`\\Pr(s_k = i) = p_i` independently of the past, the second moment obeys

    .. math::

        \\operatorname{vec} \\mathbb{E}[x_{k+1} x_{k+1}^\\top]
        = \\Bigl(\\sum_i p_i A_i \\otimes A_i\\Bigr) \\operatorname{vec} \\mathbb{E}[x_k x_k^\\top],

    so the system is mean-square stable iff the spectral radius of that matrix is below 1.
    ``holds`` asks it to be below 1 by more than the rounding allowance of the
    computed radius (:func:`~switchest.analysis._lmi.rounding_allowance`: :math:`n^2 + L`
    terms of size :math:`\\sum_i p_i \\lVert A_i \\rVert_F^2`, the Frobenius norm of that matrix's
    absolute value), so the verdict does not depend on the last bits.

    Up to :math:`n = 32` the :math:`n^2 \\times n^2` matrix is formed and its eigenvalues
    computed; beyond, the spectral radius of the map
    :math:`X \\mapsto \\sum_i p_i A_i X A_i^\\top` is found matrix-free by Arnoldi iteration
    (ARPACK, to a relative ``1e-12``, added to the allowance), in :math:`O(L n^3)` per
    iteration and :math:`O(n^2)` memory.

    Parameters
    ----------
    A : array_like, shape (L, n, n)
    p : array_like, shape (L,)
        Mode probabilities, non-negative, summing to one.

    Returns
    -------
    MeanSquareStability

    Raises
    ------
    numpy.linalg.LinAlgError
        If the iteration for a large :math:`n` does not converge.
    """
    A = _matrix_stack(A, "A", min_ndim=3, max_ndim=3)
    p = check_probability_vector(p, "p", n=A.shape[0])
    L, n = A.shape[0], A.shape[-1]
    size = float(p @ np.sum(A * A, axis=(-2, -1)))  # || sum_i p_i |A_i| kron |A_i| ||_F
    allowance = rounding_allowance(size, n * n + L)
    if n <= _DENSE_KRON_MAX:
        M = np.einsum("i,iab,icd->acbd", p, A, A).reshape(n * n, n * n)
        radius = float(spectral_radius(M))
    else:
        radius = _operator_radius(A, p)
        allowance = allowance + _ARPACK_TOL * radius
    return MeanSquareStability(radius=radius, holds=bool(radius + allowance < 1.0))


_ARPACK_TOL = 1e-12


def _operator_radius(A: np.ndarray, p: np.ndarray) -> float:
    """Spectral radius of :math:`X \\mapsto \\sum_i p_i A_i X A_i^\\top` on :math:`n \\times n`
    matrices, by ARPACK."""
    n = A.shape[-1]
    At = np.ascontiguousarray(np.swapaxes(A, -1, -2))

    def apply(v):
        X = v.reshape(n, n)
        return np.einsum("i,iab->ab", p, A @ X @ At).ravel()

    op = LinearOperator((n * n, n * n), matvec=apply, dtype=float)
    start = np.eye(n).ravel()  # inside the PSD cone, where the dominant eigenvector lies
    try:
        # one BLAS thread: a sequential iteration of n x n products gains little from threads
        # and, on a busy machine, was measured 16x slower with them (n = 200)
        with one_blas_thread():
            values = eigs(op, k=1, which="LM", v0=start, tol=_ARPACK_TOL, return_eigenvectors=False)
    except ArpackError as exc:
        raise np.linalg.LinAlgError(
            f"the spectral radius of the {n * n} x {n * n} second-moment map did not converge: "
            f"{exc}"
        ) from exc
    return float(np.max(np.abs(values)))


# ---------------------------------------------------------------------- helpers
def _decrease(A: np.ndarray, P: cp.Variable, domain: str) -> cp.Expression:
    if domain == "discrete":
        return A.T @ P @ A - P
    return A.T @ P + P @ A


def _verified_decrease(A: np.ndarray, P: np.ndarray, domain: str) -> tuple[np.ndarray, np.ndarray]:
    """Per mode, :math:`-\\lambda_{\\max}(D_i)` and the rounding allowance of that number.

    Each entry of :math:`D_i` is a sum of :math:`2n + 1` products bounded by
    :math:`|A_i|^\\top |P| |A_i| + |P|` (discrete) or :math:`|A_i|^\\top |P| + |P| |A_i|`
    (continuous), and the symmetric eigensolver adds :math:`n \\varepsilon \\lVert D_i \\rVert`:
    :math:`3n + 1` terms of that size (Frobenius).
    """
    n = A.shape[-1]
    At = np.swapaxes(A, -1, -2)
    absA, absP = np.abs(A), np.abs(P)
    if domain == "discrete":
        D = At @ P @ A - P
        size = np.swapaxes(absA, -1, -2) @ absP @ absA + absP
    else:
        D = At @ P + P @ A
        size = np.swapaxes(absA, -1, -2) @ absP + absP @ absA
    return -max_eigenvalue(D), rounding_allowance(np.linalg.norm(size, axis=(-2, -1)), 3 * n + 1)


def _infeasible(status: str, domain: str, note: str) -> LyapunovCertificate:
    return LyapunovCertificate(
        holds=False, P=None, margin=float("nan"), solver_status=status, domain=domain, note=note
    )


def _spectral_bound(A: np.ndarray, rtol: float) -> float:
    """:math:`\\max_i \\lVert A_i \\rVert_2 (1 + \\mathrm{rtol})`, raised by the rounding of the
    singular values."""
    top = float(np.max(np.linalg.norm(A, ord=2, axis=(-2, -1))))
    return top * (1.0 + rtol) + float(rounding_allowance(top, A.shape[-1]))


def _ellipsoid_bound(A: np.ndarray, rtol: float) -> tuple[float, np.ndarray]:
    """Smallest :math:`r` (to ``rtol``) with a verified CQLF of :math:`\\{A_i / r\\}`, and its P."""
    rho = float(np.max(spectral_radius(A)))
    hi = _spectral_bound(A, rtol)
    if hi == 0.0:
        return 0.0, np.eye(A.shape[-1])
    lo = rho
    best = cqlf(A / hi)
    P = best.P if best.holds else np.eye(A.shape[-1])
    for _ in range(_MAX_BISECTIONS):
        if hi - lo <= rtol * hi:
            break
        mid = 0.5 * (lo + hi)
        cert = cqlf(A / mid)
        if cert.holds:
            hi, P = mid, cert.P
        else:
            lo = mid
    return hi, P


def _p_norm(P: np.ndarray):
    """:math:`(W \\mapsto \\lVert W \\rVert_P, \\mathrm{cond})`: the norm induced by
    :math:`\\lVert x \\rVert_P = \\sqrt{x^\\top P x}`, batched, and
    :math:`\\lVert R \\rVert_F \\lVert R^{-1} \\rVert_F` (:math:`P = R^\\top R`), by which it
    magnifies rounding in :math:`W`."""
    R = np.linalg.cholesky(P).T  # P = R' R, ||x||_P = ||R x||
    R_inv = np.linalg.inv(R)
    cond = float(np.linalg.norm(R) * np.linalg.norm(R_inv))
    return (lambda W: np.linalg.norm(R @ W @ R_inv, ord=2, axis=(-2, -1))), cond


def _matrix_stack(value, name: str, *, min_ndim: int, max_ndim: int | None = None) -> np.ndarray:
    arr = float_array(value, name)
    if arr.ndim < min_ndim or (max_ndim is not None and arr.ndim > max_ndim):
        want = f"{min_ndim}" if max_ndim == min_ndim else f"at least {min_ndim}"
        if max_ndim is not None and max_ndim != min_ndim:
            want = f"{min_ndim} to {max_ndim}"
        raise ValueError(f"{name} must have {want} dimensions, got shape {arr.shape}")
    if arr.shape[-1] != arr.shape[-2] or arr.shape[-1] == 0:
        raise ValueError(
            f"{name} must be a stack of non-empty square matrices, got shape {arr.shape}"
        )
    check_finite(arr, name)
    return arr


def _check_domain(domain) -> str:
    if domain not in ("discrete", "continuous"):
        raise ValueError(f"domain must be 'discrete' or 'continuous', got {domain!r}")
    return domain

