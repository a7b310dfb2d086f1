"""The interacting multiple model filter (Blom & Bar-Shalom, 1988).

One Kalman filter per mode; before each prediction their estimates are mixed
with the mode transition probabilities, after each update the mode
probabilities are re-weighted by the filters' likelihoods. Switches are assumed
to happen at the sample instants. Mode probabilities are kept as log-weights.

Outliers: a mode whose filter rejects the measurement (its normalized innovation
squared overflows or exceeds ``gate``, :func:`~switchest.estimators.kalman.kf_update`)
is not updated and gets likelihood zero at that sample; when every mode rejects
it, the sample is treated as missing — no update, the mode probabilities stay the
predicted ones — and it is flagged in ``Estimate.outlier``.

Convention (all of switchest): ``transition[i, j]`` = P(mode j at k+1 | mode i at k);
rows sum to one.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._checks import check_probability_vector, check_row_stochastic, positive_scalar
from .._linalg import log_normalize, mixture_moments, shared
from ..discretize import mode_steps
from .base import Estimate, Estimator
from .kalman import kf_predict, kf_update

__all__ = ["IMMState", "IMMFilter", "imm_mix", "imm_combine"]


@dataclass(frozen=True, eq=False)
class IMMState:
    """Mode-matched posteriors ``x (N, L, n)``, ``P (N, L, n, n)`` and log mode
    probabilities ``log_prob (N, L)``; ``loglik (N,)`` of the last measurement and
    ``outlier (N,)``, True where every mode rejected it."""

    x: np.ndarray
    P: np.ndarray
    log_prob: np.ndarray
    loglik: np.ndarray
    outlier: np.ndarray


def imm_mix(x, P, log_prob, log_transition):
    """IMM interaction step.

    Predicted mode probabilities ``c_j = sum_i pi_ij mu_i``, mixing weights
    ``mu_{i|j} = pi_ij mu_i / c_j``, mixed means ``x0_j = sum_i mu_{i|j} x_i`` and
    covariances ``P0_j = sum_i mu_{i|j} (P_i + (x_i - x0_j)(x_i - x0_j)')``
    (Blom & Bar-Shalom; Bar-Shalom, Li & Kirubarajan §11.6.6). All in log domain
    until the weights are used.

    Returns ``x0 (N, L, n)``, ``P0 (N, L, n, n)`` and ``log c (N, L)``.
    """
    joint = log_prob[..., :, None] + log_transition  # log(pi_ij mu_i), (N, i, j)
    log_w, log_c = log_normalize(joint, axis=-2)  # over predecessors i
    x0, P0 = mixture_moments(np.exp(log_w), x, P)
    return x0, P0, log_c


def imm_combine(x, P, prob):
    """Combined estimate ``x = sum_j mu_j x_j``, ``P = sum_j mu_j (P_j + (x_j - x)(x_j - x)')``.

    The moments of the mixture of the mode-matched posteriors ``x (..., L, n)``,
    ``P (..., L, n, n)`` with weights ``prob (..., L)`` (Bar-Shalom, Li &
    Kirubarajan §11.6.6, the output step of the IMM).
    """
    xc, Pc = mixture_moments(prob[..., :, None], x, P)
    return xc[..., 0, :], Pc[..., 0, :, :]


class IMMFilter(Estimator):
    """Interacting multiple model filter, batched over trials and modes.

    Parameters
    ----------
    system : SwitchedLinearSystem
    transition : array_like, shape (L, L)
        ``transition[i, j]`` = P(mode j at k+1 | mode i at k), rows sum to 1.
    x0, P0 : array_like
        Prior mean and covariance of the state at the first sample (every mode).
    mode_prob0 : array_like, shape (L,), optional
        Prior mode probabilities at the first sample; uniform by default.
    gate : float, optional
        Largest normalized innovation squared ``e' S^-1 e`` a mode-matched filter
        accepts (keyword-only); e.g. ``scipy.stats.chi2.ppf(0.9999, m)``. ``None``
        rejects only measurements whose innovation overflows. A sample every mode
        rejects is treated as missing and flagged in ``Estimate.outlier``.
    """

    def __init__(self, system, transition, x0, P0, mode_prob0=None, *, gate: float | None = None):
        self._set_prior(system, x0, P0)
        self.gate = None if gate is None else positive_scalar(gate, "gate")
        L = system.n_modes
        self.transition = check_row_stochastic(transition, "transition", n=L)
        p0 = np.full(L, 1.0 / L) if mode_prob0 is None else mode_prob0
        self.mode_prob0 = check_probability_vector(p0, "mode_prob0", n=L)
        with np.errstate(divide="ignore"):
            self._log_transition = np.log(self.transition)
            self._log_p0 = np.log(self.mode_prob0)
        self._C, self._R = shared(system.C), shared(system.R)  # one matrix for all modes if they agree

    def init(self, batch_shape=()) -> IMMState:
        """Every mode-matched filter starts from the prior ``(x0, P0)``."""
        L, n = self.system.n_modes, self.system.n_states
        return IMMState(
            x=np.broadcast_to(self.x0, (*batch_shape, L, n)).copy(),
            P=np.broadcast_to(self.P0, (*batch_shape, L, n, n)).copy(),
            log_prob=np.broadcast_to(self._log_p0, (*batch_shape, L)).copy(),
            loglik=np.zeros(batch_shape),
            outlier=np.zeros(batch_shape, dtype=bool),
        )

    def step(self, state: IMMState, y, u=None, *, dt=None) -> IMMState:
        """Mix, predict over ``dt`` (skipped when ``None``), update with ``y (N, m)``."""
        sys = self.system
        x, P, log_c = state.x, state.P, state.log_prob
        if dt is not None:
            x, P, log_c = imm_mix(x, P, state.log_prob, self._log_transition)
            steps = mode_steps(sys, dt)
            if u is None:
                u = np.zeros((*x.shape[:-2], sys.n_inputs))
            x, P = kf_predict(x, P, shared(steps.F), steps.G, u[..., None, :], shared(steps.Qd))
        x, P, ll = kf_update(x, P, y[..., None, :], self._C, self._R, gate=self.gate)
        outlier = np.zeros(ll.shape[:-1], dtype=bool)
        if np.isneginf(ll).any():  # a mode rejected y; if every mode did, it is a missing sample
            outlier = np.all(np.isneginf(ll), axis=-1)
            ll = np.where(outlier[..., None], 0.0, ll)
        log_prob, total = log_normalize(log_c + ll)  # mu_j ∝ c_j Lambda_j
        return IMMState(x, P, log_prob, total, outlier)

    def _output(self, state: IMMState) -> dict[str, np.ndarray]:
        prob = np.exp(state.log_prob)
        x, P = imm_combine(state.x, state.P, prob)
        return {"x": x, "P": P, "mode_prob": prob, "mode": np.argmax(state.log_prob, axis=-1),
                "loglik": state.loglik, "outlier": state.outlier}

    def run(self, y, u=None, t=None) -> Estimate:
        """Filter ``y (..., K, m)``; returns combined ``x``, ``P``, ``mode_prob``, the
        most probable ``mode``, ``loglik`` and the ``outlier`` flags at each sample."""
        y2, u2, t, batch = self._prepare(y, u, t)
        return self._unflatten(self._loop(y2, u2, t), batch)
