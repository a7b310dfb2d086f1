"""The sub-states and the sampled error system of Wang et al.'s subsystem observers (seed 003).

Model (Wang et al. eq. (1), Assumption 1): :math:`dx = A(\\alpha) x\\, dt`,
:math:`dy = C(\\alpha) x\\, dt + \\Xi(\\alpha)\\, dw`, modes :math:`\\alpha_k` i.i.d. with
probabilities :math:`p` on :math:`[kT, (k+1)T)`; a :class:`SwitchedLinearSystem` holds
:math:`R = \\Xi \\Xi^\\top`. Each mode i observes the sub-state :math:`z^i = F_i x` (§3.1); its
sub-observer runs closed loop with gain :math:`L_i` while :math:`\\alpha_k = i` (eq. (7)) and
open loop otherwise (eq. (14)); :math:`\\hat x = \\Phi \\hat z` with
:math:`\\Phi = (F^\\top F)^{-1} F^\\top`. The error :math:`e_k = \\hat z_k - z_k` obeys
(Theorem 1, eq. (15))

.. math::

    e_{k+1} = \\Lambda(\\alpha_k) e_k + \\Gamma(\\alpha_k) d_k, \\qquad d_k \\sim \\mathcal{N}(0, I)

This module builds that sampled error system exactly (matrix exponentials and the
noise integral of Proposition 1 by Van Loan, through :mod:`switchest.discretize`),
and evaluates it for given gains with the mathematically right quantities:

* the sub-states of every mode (:func:`subsystem_structure`, :func:`substate_gains`);
* :math:`\\Lambda(i)` and :math:`\\Gamma(i)` (:func:`error_dynamics`);
* MS convergence: Theorem 2's :math:`\\gamma = \\mathbb{E} \\lVert \\Lambda_k \\rVert^2 < 1`
  (sufficient), the §5.1/§6 test
  :math:`\\lambda_{\\max}(\\mathbb{E}[\\Lambda_k^\\top \\Lambda_k]) < 1` (sufficient) and the exact
  test :math:`\\rho(\\mathbb{E}[\\Lambda_k \\otimes \\Lambda_k]) < 1` (:func:`ms_convergence`);
* the steady-state second moment (§5.1, eq. (21) corrected) and its transient
  (:func:`steady_state`, :func:`second_moments`).

The design questions (critical interval, gains) are answered in
:mod:`switchest.analysis.subsystem_observers`, which also exports these names.

Gains are given in state coordinates: ``gains[i]`` is ``(n, m)`` with columns in
mode i's observable subspace; the sub-observer uses :math:`L_i = F_i\\, \\mathrm{gains}[i]`.
This makes a gain independent of the (sign-)arbitrary basis :math:`F_i`.

Paper discrepancies (each tested in ``tests/analysis/test_subsystem_observers.py``):

* Theorem 2's :math:`\\gamma = \\mathbb{E} \\lVert \\Lambda_k \\rVert^2` is what the theorem
  states, but the paper's printed gammas (Example 2: :math:`\\max\\{0.9225, 0.6677\\}`) are the
  eigenvalues of :math:`\\mathbb{E}[\\Lambda_k^\\top \\Lambda_k]`; for Example 1's system
  :math:`\\mathbb{E} \\lVert \\Lambda_k \\rVert^2 \\ge p e^{2 a_2 T} + (1 - p) e^{2 a_1 T} > 1` for
  every gain and every :math:`T > 0`, so Theorem 2's test can never certify it.
* Eq. (21), :math:`P^\\top V P - V + \\Psi = 0` with
  :math:`M = \\mathbb{E}[\\Lambda^\\top \\Lambda] = P^\\top P`,
  :math:`\\Psi = \\mathbb{E}[\\Gamma^\\top \\Gamma]`: the second moment obeys
  :math:`V = \\mathbb{E}[\\Lambda V \\Lambda^\\top] + \\mathbb{E}[\\Gamma \\Gamma^\\top]` (a
  generalized Lyapunov equation, solved here); the printed equation agrees with it only when
  the :math:`\\Lambda(i)` are diagonal (the scalar examples).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._checks import (
    check_finite,
    check_probability_vector,
    check_symmetric_psd,
    float_array,
    positive_scalar,
)
from .._linalg import psd_sqrt, symmetrize
from ..discretize import mode_steps
from ..system import SwitchedLinearSystem
from ._lmi import rounding_allowance
from .observability import combined_observability, mode_decompositions
from .stability import ms_stable_iid

__all__ = [
    "ErrorDynamics",
    "MSConvergence",
    "SteadyState",
    "SubsystemStructure",
    "error_dynamics",
    "ms_convergence",
    "second_moments",
    "steady_state",
    "substate_gains",
    "subsystem_structure",
]

_SUBSPACE_TOL = 1e-8  # projector distance below which two observable subspaces are one


# ---------------------------------------------------------------------- results
@dataclass(frozen=True, eq=False)
class SubsystemStructure:
    """The sub-states of Wang et al. §3.1-3.2.

    Attributes
    ----------
    block : ndarray of int, shape (L,)
        Sub-state block on which mode i closes the loop; -1 when mode i observes
        nothing (:math:`n_i = 0`, e.g. every sensor lost).
    F_blocks : tuple of ndarray, each (n_b, n)
        Orthonormal rows: block b estimates :math:`z^b = F_b x` (Wang et al.'s :math:`F_i`).
    F : ndarray, shape (n_s, n)
        :math:`[F_1; \\dots; F_B]`, :math:`z = F x`.
    Phi : ndarray, shape (n, n_s)
        :math:`(F^\\top F)^{-1} F^\\top`, :math:`x = \\Phi z`.
    A22, C2 : tuple of ndarray
        Per mode, :math:`F_b A_i F_b^\\top` ``(n_b, n_b)`` and :math:`C_i F_b^\\top` ``(m, n_b)``:
        the observable pair :math:`(A_{22}^i, C_2^i)` of eq. (6) (empty for ``block = -1``).
    offsets : ndarray of int, shape (B + 1,)
        Block b occupies entries ``offsets[b]:offsets[b+1]`` of :math:`z`.
    shared : bool
        Whether modes with the same observable subspace share one block.
    """

    block: np.ndarray
    F_blocks: tuple[np.ndarray, ...]
    F: np.ndarray
    Phi: np.ndarray
    A22: tuple[np.ndarray, ...]
    C2: tuple[np.ndarray, ...]
    offsets: np.ndarray
    shared: bool

    @property
    def n_blocks(self) -> int:
        """Number of sub-state blocks B."""
        return len(self.F_blocks)

    @property
    def n_substates(self) -> int:
        """:math:`n_s`, the length of :math:`z`."""
        return int(self.offsets[-1])

    def rows(self, b: int) -> slice:
        """Entries of :math:`z` held by block ``b``."""
        return slice(int(self.offsets[b]), int(self.offsets[b + 1]))


@dataclass(frozen=True, eq=False)
class ErrorDynamics:
    """The sampled error system of Wang et al. Theorem 1, equation (15).

    Attributes
    ----------
    T : float
        Switching interval.
    structure : SubsystemStructure
    Lam : ndarray, shape (L, n_s, n_s)
        :math:`\\Lambda(i)`: block row :math:`b(i)` holds :math:`e^{A_c^i T}` in column block
        :math:`b(i)` (closed loop, eq. (13)); every other block row j holds
        :math:`F_j e^{A_i T} \\Phi` (open loop, eq. (14)).
    W : ndarray, shape (L, n_s, n_s)
        :math:`\\Gamma(i) \\Gamma(i)^\\top`:
        :math:`\\int_0^T e^{A_c^i s} L_i R_i L_i^\\top e^{(A_c^i)^\\top s}\\, ds` in block
        :math:`b(i)` (Proposition 1), zero elsewhere.
    Gamma : ndarray, shape (L, n_s, n_s)
        A square root of ``W`` (:math:`Q_k^i` of eq. (13) in its block).
    closed_loop : tuple of ndarray
        :math:`A_c^i = A_{22}^i - L_i C_2^i` per mode (empty for ``block = -1``).
    expAT : ndarray, shape (L, n, n)
        :math:`e^{A_i T}`.
    """

    T: float
    structure: SubsystemStructure
    Lam: np.ndarray
    W: np.ndarray
    Gamma: np.ndarray
    closed_loop: tuple[np.ndarray, ...]
    expAT: np.ndarray


@dataclass(frozen=True)
class MSConvergence:
    """Mean-square convergence tests of the error system (:func:`ms_convergence`).

    ``radius <= moment_bound <= gamma`` always.

    Attributes
    ----------
    gamma : float
        :math:`\\mathbb{E} \\lVert \\Lambda_k \\rVert^2` (Wang et al. Theorem 2).
    gamma_holds : bool
        :math:`\\gamma < 1` beyond rounding: Theorem 2's sufficient condition.
    moment_eigenvalues : ndarray, shape (n_s,)
        Eigenvalues of :math:`M = \\mathbb{E}[\\Lambda_k^\\top \\Lambda_k]
        = \\sum_i p_i \\Lambda(i)^\\top \\Lambda(i)`, descending (the numbers of §6 and of
        Example 2).
    moment_bound : float
        :math:`\\lambda_{\\max}(M)`: :math:`\\mathbb{E} \\lVert e_{k+1} \\rVert^2
        \\le \\lambda_{\\max}(M)\\, \\mathbb{E} \\lVert e_k \\rVert^2 + c`.
    moment_holds : bool
        ``moment_bound < 1`` beyond rounding (sufficient; §5.1 "M is stable").
    radius : float
        :math:`\\rho(\\mathbb{E}[\\Lambda_k \\otimes \\Lambda_k])`
        (:func:`switchest.analysis.ms_stable_iid`).
    holds : bool
        ``radius < 1`` beyond rounding: the error converges in mean square (necessary and
        sufficient, Wang et al. Theorem 1).
    """

    gamma: float
    gamma_holds: bool
    moment_eigenvalues: np.ndarray
    moment_bound: float
    moment_holds: bool
    radius: float
    holds: bool


@dataclass(frozen=True)
class SteadyState:
    """Steady-state second moment of the error (:func:`steady_state`).

    Attributes
    ----------
    V : ndarray, shape (n_s, n_s)
        :math:`\\lim \\mathbb{E}[e_k e_k^\\top]`, solving
        :math:`V = \\sum_i p_i (\\Lambda(i) V \\Lambda(i)^\\top + W(i))`.
    mu : float
        :math:`\\operatorname{tr} V` (Wang et al.'s :math:`\\mu_\\infty`, the MS error of
        :math:`z`).
    V_x : ndarray, shape (n, n)
        :math:`\\Phi V \\Phi^\\top`, the second moment of the state error :math:`\\hat x - x`.
    mu_x : float
        :math:`\\operatorname{tr} V_x`.
    """

    V: np.ndarray
    mu: float
    V_x: np.ndarray
    mu_x: float


# ---------------------------------------------------------------------- structure
def subsystem_structure(
    system: SwitchedLinearSystem, *, shared: bool = True, rtol: float = 1e-7
) -> SubsystemStructure:
    """The observable sub-states of every mode (Wang et al. §3.1-3.2).

    Each mode's Kalman decomposition (:func:`switchest.analysis.kalman_decomposition`)
    gives :math:`F_i` with orthonormal rows spanning its observable subspace.

    Parameters
    ----------
    system : SwitchedLinearSystem
        Continuous time, no input, no process noise (Wang et al. eq. (1)), and
        Assumption 2(b): the modes' observable subspaces span the state space.
    shared : bool
        Wang et al. §3.2 stack one sub-state per mode (``shared=False``). With
        ``shared=True`` (default) modes whose observable subspaces coincide share
        one block, closed loop whenever any of them is active: this is the
        observer §6 analyses (one :math:`4 \\times 4` :math:`\\Lambda(i)` per mode for the 5-bus
        system, whose modes 1-3 are all observable); stacking three copies of :math:`x`
        there diverges at the paper's :math:`T`.
    rtol : float
        Tolerance of the observability decompositions.
    """
    _check_model(system)
    combined = combined_observability(system, rtol=rtol)
    if not combined.holds:
        raise ValueError(
            f"system must satisfy Wang et al. Assumption 2(b) (rank W_S = n = {system.n_states}), "
            f"got rank {combined.rank}"
        )
    decs = mode_decompositions(system, rtol=rtol)
    blocks: list[np.ndarray] = []
    block = np.full(system.n_modes, -1, dtype=np.int64)
    for i, dec in enumerate(decs):
        if dec.n_observable == 0:
            continue
        proj = dec.F.T @ dec.F
        match = [
            b
            for b, Fb in enumerate(blocks)
            if shared
            and Fb.shape[0] == dec.n_observable
            and np.linalg.norm(Fb.T @ Fb - proj, 2) <= _SUBSPACE_TOL
        ]
        if match:
            block[i] = match[0]
        else:
            block[i] = len(blocks)
            blocks.append(dec.F)
    F = np.concatenate(blocks, axis=0)
    offsets = np.concatenate([[0], np.cumsum([Fb.shape[0] for Fb in blocks])]).astype(np.int64)
    A22, C2 = [], []
    for i in range(system.n_modes):
        Fb = blocks[block[i]] if block[i] >= 0 else np.zeros((0, system.n_states))
        A22.append(Fb @ system.A[i] @ Fb.T)  # F_b A_i F_b' (F_b A_i = A22 F_b on the subspace)
        C2.append(system.C[i] @ Fb.T)
    return SubsystemStructure(
        block=block,
        F_blocks=tuple(blocks),
        F=F,
        Phi=np.linalg.solve(F.T @ F, F.T),  # Phi = (F'F)^{-1} F', §3.2
        A22=tuple(A22),
        C2=tuple(C2),
        offsets=offsets,
        shared=bool(shared),
    )


def substate_gains(
    structure: SubsystemStructure, gains, name: str = "gains"
) -> tuple[np.ndarray, ...]:
    """Sub-observer gains :math:`L_i = F_b\\, \\mathrm{gains}[i]` ``(n_b, m)`` from
    state-coordinate gains.

    ``gains (L, n, m)`` must have its columns in each mode's observable subspace
    (:math:`F_b^\\top F_b\\, \\mathrm{gains}[i] = \\mathrm{gains}[i]`; zero for a mode that observes
    nothing),
    since a sub-observer can only correct its own sub-state.
    """
    L, n = structure.block.size, structure.F.shape[1]
    m = structure.C2[0].shape[0]
    gains = float_array(gains, name, ndim=3)
    if gains.shape != (L, n, m):
        raise ValueError(f"{name} must have shape (L, n, m) = ({L}, {n}, {m}), got {gains.shape}")
    check_finite(gains, name)
    out = []
    for i in range(L):
        Fb = structure.F_blocks[structure.block[i]] if structure.block[i] >= 0 else np.zeros((0, n))
        outside = np.linalg.norm(gains[i] - Fb.T @ (Fb @ gains[i]))
        if outside > 1e-8 * max(1.0, np.linalg.norm(gains[i])):
            raise ValueError(
                f"{name}[{i}] must lie in mode {i}'s observable subspace (Wang et al. eq. (7) "
                f"corrects only z^i = F_i x), got a component of norm {outside:.3g} outside it"
            )
        out.append(Fb @ gains[i])
    return tuple(out)


# ---------------------------------------------------------------------- error system
def error_dynamics(
    system: SwitchedLinearSystem,
    gains,
    T: float,
    *,
    structure: SubsystemStructure | None = None,
) -> ErrorDynamics:
    """:math:`\\Lambda(i)` and :math:`\\Gamma(i) \\Gamma(i)^\\top` of Wang et al. Theorem 1, eqs.
    (13)-(15).

    Closed-loop exponentials and Proposition 1's noise integral
    :math:`\\int_0^T e^{A_c s} L R L^\\top e^{A_c^\\top s}\\, ds` come from one batched Van Loan
    exponential (:func:`switchest.discretize.mode_steps`), not from quadrature.

    Parameters
    ----------
    system : SwitchedLinearSystem
    gains : array_like, shape (L, n, m)
        Observer gains in state coordinates (see :func:`substate_gains`).
    T : float
        Switching interval.
    structure : SubsystemStructure, optional
        Defaults to ``subsystem_structure(system)``.
    """
    structure = _structure(system, structure)
    T = positive_scalar(T, "T")
    Ls = substate_gains(structure, gains)
    L, n_s = system.n_modes, structure.n_substates
    closed = tuple(structure.A22[i] - Ls[i] @ structure.C2[i] for i in range(L))  # A_c = A22 - L C2
    lifted_A, lifted_Q = np.zeros((2, L, n_s, n_s))
    for i in range(L):
        if structure.block[i] >= 0:
            r = structure.rows(structure.block[i])
            lifted_A[i, r, r] = closed[i]
            lifted_Q[i, r, r] = Ls[i] @ system.R[i] @ Ls[i].T  # (L_i Xi)(L_i Xi)'
    cl = mode_steps(SwitchedLinearSystem.continuous(lifted_A, Q=lifted_Q), T)
    expAT = mode_steps(system, T).F
    Lam = _open_loop(structure, expAT)
    W = np.zeros((L, n_s, n_s))
    for i in range(L):
        if structure.block[i] >= 0:
            r = structure.rows(structure.block[i])
            Lam[i, r, r] = cl.F[i, r, r]  # e^{A_c^i T}, eq. (13)
            W[i, r, r] = cl.Qd[i, r, r]  # Proposition 1 at t = s = (k+1)T
    W = symmetrize(W)
    return ErrorDynamics(
        T=T, structure=structure, Lam=Lam, W=W, Gamma=psd_sqrt(W), closed_loop=closed, expAT=expAT
    )


def ms_convergence(dyn: ErrorDynamics, p) -> MSConvergence:
    """Theorem 2's test, the §5.1/§6 moment test and the exact MS test.

    :math:`e_{k+1} = \\Lambda_k e_k + \\Gamma_k d_k` converges in mean square iff
    :math:`\\rho(\\sum_i p_i \\Lambda(i) \\otimes \\Lambda(i)) < 1` (the second-moment recursion);
    :math:`\\lambda_{\\max}(\\mathbb{E}[\\Lambda^\\top \\Lambda]) < 1` and Theorem 2's
    :math:`\\mathbb{E} \\lVert \\Lambda \\rVert^2 < 1` are successively stronger sufficient
    conditions. Each verdict asks its value to be below 1 by more than its rounding allowance
    (:func:`~switchest.analysis._lmi.rounding_allowance`: :math:`n_s + L` terms of size
    :math:`\\sum_i p_i \\lVert \\Lambda(i) \\rVert_F^2`), so that it does not depend on the last
    bits.
    """
    p = _probabilities(p, dyn.Lam.shape[0])
    L, n_s = dyn.Lam.shape[0], dyn.Lam.shape[-1]
    norms = np.linalg.norm(dyn.Lam, ord=2, axis=(1, 2))
    gamma = float(p @ norms**2)  # Theorem 2: gamma = E||Lambda_k||^2
    M = symmetrize(np.einsum("i,iba,ibc->ac", p, dyn.Lam, dyn.Lam))  # E[Lambda' Lambda]
    eig = np.linalg.eigvalsh(M)[::-1]
    allowance = rounding_allowance(float(p @ np.sum(dyn.Lam**2, axis=(1, 2))), n_s + L)
    ms = ms_stable_iid(dyn.Lam, p)
    return MSConvergence(
        gamma=gamma,
        gamma_holds=bool(gamma + allowance < 1.0),
        moment_eigenvalues=eig,
        moment_bound=float(eig[0]),
        moment_holds=bool(eig[0] + allowance < 1.0),
        radius=ms.radius,
        holds=ms.holds,
    )


def second_moments(dyn: ErrorDynamics, p, V0, steps: int) -> np.ndarray:
    """:math:`\\mathbb{E}[e_k e_k^\\top]` for :math:`k = 0, \\dots, \\mathrm{steps}` from
    :math:`\\mathbb{E}[e_0 e_0^\\top]` = ``V0``, exactly.

    :math:`V_{k+1} = \\sum_i p_i (\\Lambda(i) V_k \\Lambda(i)^\\top + W(i))` (Wang et al. §5.1:
    :math:`\\Lambda_k`, :math:`e_k`, :math:`d_k` independent).

    Returns
    -------
    ndarray, shape (steps + 1, n_s, n_s)

    Raises
    ------
    ValueError
        If ``V0`` is not a finite symmetric positive semidefinite ``(n_s, n_s)`` matrix
        (a second moment); an eigenvalue below ``-1e-12`` times its largest entry is not
        round-off (:func:`switchest._checks.check_symmetric_psd`).
    """
    p = _probabilities(p, dyn.Lam.shape[0])
    n_s = dyn.Lam.shape[-1]
    V = float_array(V0, "V0", ndim=2)
    if V.shape != (n_s, n_s):
        raise ValueError(f"V0 must have shape (n_s, n_s) = ({n_s}, {n_s}), got {V.shape}")
    check_finite(V, "V0")
    V = check_symmetric_psd(V, "V0")
    if not isinstance(steps, (int, np.integer)) or isinstance(steps, bool) or steps < 0:
        raise ValueError(f"steps must be a non-negative int, got {steps!r}")
    noise = np.einsum("i,iab->ab", p, dyn.W)
    out = [V]
    for _ in range(steps):
        V = np.einsum("i,iab,bc,idc->ad", p, dyn.Lam, V, dyn.Lam) + noise
        out.append(V)
    return np.stack(out)


def steady_state(dyn: ErrorDynamics, p) -> SteadyState:
    """Steady-state second moment of the error: Wang et al. equation (21), corrected.

    Solves

    .. math::

        V = \\sum_i p_i \\Lambda(i) V \\Lambda(i)^\\top + \\sum_i p_i W(i)

    through

    .. math::

        \\Bigl(I - \\sum_i p_i \\Lambda(i) \\otimes \\Lambda(i)\\Bigr) \\operatorname{vec} V
        = \\operatorname{vec}\\Bigl(\\sum_i p_i W(i)\\Bigr).

    The printed :math:`P^\\top V P - V + \\Psi = 0`
    (:math:`P^\\top P = \\mathbb{E}[\\Lambda^\\top \\Lambda]`) gives the same trace only when the
    :math:`\\Lambda(i)` are diagonal.

    Raises
    ------
    ValueError
        When the error system is not MS stable (no steady state).
    """
    p = _probabilities(p, dyn.Lam.shape[0])
    n_s = dyn.Lam.shape[-1]
    ms = ms_stable_iid(dyn.Lam, p)
    if not ms.holds:
        raise ValueError(
            "the error system must be mean-square stable for a steady state, got spectral radius "
            f"{ms.radius:.4g}"
        )
    K = np.einsum("i,iab,icd->acbd", p, dyn.Lam, dyn.Lam).reshape(n_s * n_s, n_s * n_s)
    rhs = np.einsum("i,iab->ab", p, dyn.W).ravel()
    V = symmetrize(np.linalg.solve(np.eye(n_s * n_s) - K, rhs).reshape(n_s, n_s))
    Phi = dyn.structure.Phi
    V_x = symmetrize(Phi @ V @ Phi.T)
    return SteadyState(V=V, mu=float(np.trace(V)), V_x=V_x, mu_x=float(np.trace(V_x)))


# ---------------------------------------------------------------------- helpers
def _check_model(system) -> None:
    if not isinstance(system, SwitchedLinearSystem):
        raise TypeError(f"system must be a SwitchedLinearSystem, got {type(system).__name__}")
    if not system.is_continuous:
        raise ValueError(
            f"system must be continuous-time (Wang et al. eq. (1)), got {system.domain!r}"
        )
    if system.n_inputs:
        raise ValueError(
            f"system must have no input (Wang et al. eq. (1)), got {system.n_inputs} inputs"
        )
    if np.any(system.Q != 0):
        raise ValueError(
            "system must have no process noise (Wang et al. eq. (1): dx = A x dt), got Q != 0"
        )


def _structure(system, structure) -> SubsystemStructure:
    if structure is None:
        return subsystem_structure(system)
    _check_model(system)
    if not isinstance(structure, SubsystemStructure):
        raise TypeError(f"structure must be a SubsystemStructure, got {type(structure).__name__}")
    if structure.block.size != system.n_modes or structure.F.shape[1] != system.n_states:
        raise ValueError(
            f"structure must belong to a system with {system.n_modes} modes and {system.n_states} "
            f"states, got {structure.block.size} modes and {structure.F.shape[1]} states"
        )
    return structure


def _probabilities(p, L: int) -> np.ndarray:
    return check_probability_vector(p, "p", n=L)


def _open_loop(structure: SubsystemStructure, expAT: np.ndarray) -> np.ndarray:
    """:math:`\\Lambda^2 F e^{A_i T} \\Phi` (equation (15)): :math:`F e^{A_i T} \\Phi` with the
    closed-loop block rows zeroed."""
    full = structure.F @ expAT @ structure.Phi  # (..., L, n_s, n_s)
    keep = np.ones((structure.block.size, structure.n_substates))
    for i, b in enumerate(structure.block):
        if b >= 0:
            keep[i, structure.rows(b)] = 0.0
    return full * keep[:, :, None]
