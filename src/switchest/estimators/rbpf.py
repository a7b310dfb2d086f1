"""The Rao-Blackwellized particle filter for jump-Markov linear systems.

Each particle carries a mode and the Kalman filter ``(x, P)`` conditional on its mode history:
the modes are sampled, the continuous state is filtered exactly given them (Doucet, de
Freitas, Murphy & Russell 2000, "Rao-Blackwellised particle filtering for dynamic Bayesian
networks", §3; Doucet, Gordon & Krishnamurthy 2001, "Particle filters for state estimation of
jump Markov linear systems", IEEE Trans. Signal Processing 49(3), §III). The modes are a
Markov chain that jumps at the sample instants and advances at every sample. Which interval
the mode :math:`r_k` of sample :math:`k` governs is the ``timing`` (:doc:`/conventions`):

- ``"sample"`` (switchest's convention, that of :func:`switchest.simulate` with
  switches at the samples and of Costa, Fragoso & Marques 2005, eq. (3.1)):
  :math:`x_{k+1} = F(r_k) x_k + G(r_k) u_k + w_k`, :math:`w_k \\sim \\mathcal{N}(0, Q_d(r_k))`,
  :math:`y_k = C(r_k) x_k + v_k`, :math:`v_k \\sim \\mathcal{N}(0, R(r_k))`. A particle
  :math:`(r_{k-1}, \\mathcal{N}(x, P))` is predicted through :math:`r_{k-1}`'s transition, then
  :math:`r_k` is drawn and the update uses :math:`C(r_k)`, :math:`R(r_k)`.
- ``"interval"`` (Bar-Shalom, Li & Kirubarajan 2001, §11.6):
  :math:`x_k = F(r_k) x_{k-1} + G(r_k) u_{k-1} + w`, :math:`y_k = C(r_k) x_k + v`. :math:`r_k` is
  drawn, then the particle is predicted through :math:`r_k`'s transition and updated with
  :math:`C(r_k)`.

With one mode the two are the Kalman filter. :math:`F, G, Q_d` are the exact discretization of a
mode over the interval (:func:`switchest.discretize.mode_steps`); the proposals:

- ``proposal="prior"``: :math:`r_k \\sim \\pi(r_{k-1}, \\cdot)`, weight times the predictive
  likelihood :math:`\\mathcal{N}(y_k; C(r_k) x^-, C(r_k) P^- C(r_k)^\\top + R(r_k))`, Joseph
  update.
- ``proposal="optimal"`` (Doucet, Gordon & Krishnamurthy 2001, §III): every candidate mode's
  predictive likelihood :math:`\\Lambda_r = \\mathcal{N}(y_k; C_r x^-_r, C_r P^-_r C_r^\\top + R_r)`
  (:math:`x^-, P^-` the same for every candidate in the ``"sample"`` timing, predicted through
  the candidate's own transition in the ``"interval"`` timing);
  :math:`r_k \\propto \\pi(r_{k-1}, r) \\Lambda_r`, weight times
  :math:`\\sum_r \\pi(r_{k-1}, r) \\Lambda_r`, the candidate's updated filter kept.

At sample 0 the modes are drawn from ``mode_prob0`` (with the optimal proposal
:math:`\\propto \\mathrm{mode\\_prob0}\\, \\Lambda`), update only. Weights are kept in the log
domain; the particles are resampled (systematic, stratified or multinomial: Douc, Cappé &
Moulines 2005) when the effective sample size :math:`1 / \\sum_p w_p^2` falls below
``ess_threshold * particles``. Outputs: :math:`x = \\sum_p w_p x_p`,
:math:`P = \\sum_p w_p (P_p + (x_p - x)(x_p - x)^\\top)`, mode probabilities the weights summed
per mode, and the log of the unbiased estimate :math:`\\sum_p w_{p,k-1} \\exp(\\mathrm{inc}_p)` of
:math:`p(y_k \\mid y_{0:k-1})`. A missing component of ``y`` (NaN) leaves the observed ones'
marginal likelihood; a fully missing sample does not reweight. A sample no particle's
likelihood is finite for (an overflowing outlier) is treated as missing
and flagged in ``Estimate.outlier``.

Randomness: ``rng`` gives one 64-bit root key when the filter is built; trial ``i`` (in the
flattened batch) gets key ``i`` of the SplitMix64 sequence of the root
(:meth:`RBPFilter.trial_keys`), and every uniform of that trial is a pure function of its key,
the sample index and the draw's index (``uniform`` of ``engine/c/rbpf.c``,
counter-based: Salmon, Moraes, Dror & Shaw 2011). So a run is
reproducible, a trial's result depends on its key alone, not on the batch it ran in (pass the
keys it got, ``keys=``, to run it alone), and streaming with :meth:`RBPFilter.step` reproduces
:meth:`RBPFilter.run`. Both call the compiled kernel of
:mod:`switchest.engine.rbpf`.

Convention (all of switchest): ``transition[i, j]`` =
:math:`\\Pr(\\text{mode } j \\text{ at } k+1 \\mid \\text{mode } i \\text{ at } k)`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .._checks import (
    as_rng,
    check_memory,
    float_array,
    positive_int,
    positive_scalar,
)
from ..discretize import mode_steps, sample_mode_steps
from ..engine import GATED, raise_for_status, warn_for_repairs
from ..engine.rbpf import RESAMPLING, rbpf_run, rbpf_step
from ..engine.rbpf import trial_keys as split_keys
from .base import Estimate, Estimator, _with_mode_model_parameters

__all__ = ["RBPFState", "RBPFilter"]

PROPOSALS = ("prior", "optimal")


@dataclass(frozen=True, eq=False)
class RBPFState:
    """The particles of ``N`` trials after a sample, and what the filter reports for it.

    Attributes
    ----------
    k : int
        Samples processed so far (the index of the next one).
    keys : ndarray of uint64, shape (N,)
        Each trial's random key.
    mode : ndarray of int64, shape (N, Np)
        Each particle's mode.
    x, P : ndarray, shapes (N, Np, n), (N, Np, n, n)
        Each particle's Kalman filter, conditional on its mode history.
    log_weight : ndarray, shape (N, Np)
        Normalized log-weights.
    combined_x, combined_P : ndarray, shapes (N, n), (N, n, n)
        Weighted mean of the particles' filters and the covariance of their mixture: what
        ``run`` reports.
    mode_prob : ndarray, shape (N, L)
        Sum of the weights of the particles in each mode.
    loglik : ndarray, shape (N,)
        Log of the particle estimate of :math:`p(y_k \\mid y_{0:k-1})` (0 when nothing was
        observed).
    outlier : ndarray of bool, shape (N,)
        True where no particle's likelihood was finite: the sample was treated as missing.
    ess : ndarray, shape (N,)
        Effective sample size :math:`1 / \\sum_p w_p^2` before resampling.
    """

    k: int
    keys: np.ndarray
    mode: np.ndarray
    x: np.ndarray
    P: np.ndarray
    log_weight: np.ndarray
    combined_x: np.ndarray
    combined_P: np.ndarray
    mode_prob: np.ndarray
    loglik: np.ndarray
    outlier: np.ndarray
    ess: np.ndarray


@_with_mode_model_parameters
class RBPFilter(Estimator):
    """Rao-Blackwellized particle filter for a jump-Markov linear system, batched over trials.

    Parameters
    ----------
    {mode model parameters}
    particles : int
        Particles per trial (default 1000).
    rng : numpy Generator, int seed, SeedSequence or None
        Source of the root key, drawn once here (None: a fresh one); every run and stream of
        this filter derives its trials' keys from it (:meth:`trial_keys`).
    resample : {"systematic", "stratified", "multinomial"}
        Resampling scheme (Douc, Cappé & Moulines 2005, §2).
    ess_threshold : float in [0, 1]
        Resample after a sample whose effective sample size is below
        ``ess_threshold * particles``: 1 resamples at every sample, 0 never.
    proposal : {"prior", "optimal"}
        Importance distribution of the modes: the transition prior, or the optimal one
        (Doucet, Gordon & Krishnamurthy 2001, §III).
    timing : {"sample", "interval"}, optional
        Which interval the mode of sample :math:`k` governs besides :math:`y_k` (module
        docstring): the one after it, :math:`[t_k, t_{k+1})` (``"sample"``), or the one into it
        (``"interval"``, Bar-Shalom's); ``None`` (the default): the system's ``timing``, and
        another is named in a :class:`~switchest.estimators.TimingWarning`.

    Attributes
    ----------
    root_key : numpy.uint64
        The key drawn from ``rng``, from which every trial's key derives.

    Examples
    --------
    >>> from switchest.models.shankar import BoostTable1
    >>> boost = BoostTable1()  # Shankar et al.'s boost converter, Table I's setting
    >>> traj = boost.simulate(0.01, 3, rng=0)  # 3 trials x 10 ms
    >>> pf = RBPFilter(boost.system(), boost.transition, *boost.prior, particles=200, rng=1)
    >>> est = pf.run(traj.y, boost.input, traj.t)
    >>> est.x.shape, est.mode_prob.shape
    ((3, 21, 2), (3, 21, 2))
    """

    def __init__(self, system, transition, x0, P0, *, mode_prob0=None, particles: int = 1000,
                 rng=None, resample: str = "systematic", ess_threshold: float = 0.5,
                 proposal: str = "prior", timing: str | None = None):
        self._set_prior(system, x0, P0)
        self._set_mode_prior(transition, mode_prob0)
        self.particles = positive_int(particles, "particles")
        self.resample = _one_of(resample, "resample", tuple(RESAMPLING))
        threshold = positive_scalar(ess_threshold, "ess_threshold", allow_zero=True)
        if threshold > 1.0:
            raise ValueError(f"ess_threshold must be in [0, 1], got {ess_threshold!r}")
        self.ess_threshold = threshold
        self.proposal = _one_of(proposal, "proposal", PROPOSALS)
        self._set_timing(timing)
        self.root_key = as_rng(rng).integers(2**64, dtype=np.uint64)

    def trial_keys(self, batch_shape=()) -> np.ndarray:
        """The random keys (uint64, shape ``batch_shape``) that :meth:`run` and :meth:`init`
        give the trials of that batch shape by default: key ``i`` of the flattened batch is
        element ``i`` of the SplitMix64 sequence of :attr:`root_key`."""
        shape = tuple(int(s) for s in batch_shape)
        return split_keys(self.root_key, math.prod(shape)).reshape(shape)

    def init(self, batch_shape=(), *, keys=None) -> RBPFState:
        """Every particle at the prior ``(x0, P0)`` with weight :math:`1 / \\mathrm{particles}`,
        before the first sample; ``keys`` (uint64, ``batch_shape``) default to
        :meth:`trial_keys`."""
        batch = tuple(batch_shape)
        Np, L = self.particles, self.system.n_modes
        self._check_particle_memory(math.prod(batch))
        x, P = self._prior_copies((*batch, Np))
        nothing = np.zeros(batch)
        combined_x, combined_P = self._prior_copies(batch)
        return RBPFState(
            k=0, keys=self._keys(keys, batch), mode=np.zeros((*batch, Np), dtype=np.int64),
            x=x, P=P, log_weight=np.full((*batch, Np), -math.log(Np)),
            combined_x=combined_x, combined_P=combined_P,
            mode_prob=np.broadcast_to(self.mode_prob0, (*batch, L)).copy(), loglik=nothing,
            outlier=np.zeros(batch, dtype=bool), ess=np.full(batch, float(Np)))

    def step(self, state: RBPFState, y, u=None, *, dt=None) -> RBPFState:
        """Predict every particle over ``dt``, sample its mode (the prediction before the draw,
        through the previous mode, in the ``"sample"`` timing; after it, through the new mode,
        in the ``"interval"`` timing) and update it with ``y (..., m)``, reweight and resample
        if due.

        ``dt`` is None at the first sample (modes drawn from ``mode_prob0``, update only) and
        the time since the previous sample after it. One sample of the compiled kernel
        (:func:`~switchest.engine.rbpf.rbpf_step`), the one ``run`` loops over,
        with the same uniforms: stepping through a record reproduces ``run``.
        """
        sys = self.system
        batch = state.keys.shape
        L, n, Np = sys.n_modes, sys.n_states, self.particles
        N = math.prod(batch)
        if (dt is None) != (state.k == 0):
            raise ValueError("dt must be None at the first sample and the time since the "
                             f"previous sample after it; got dt = {dt!r} at sample {state.k}")
        y = float_array(y, "y", masked="nan")
        if y.shape != (*batch, sys.n_outputs):
            raise ValueError(f"y must have shape {(*batch, sys.n_outputs)}, got {y.shape}")
        u = np.zeros((N, sys.n_inputs)) if u is None else np.broadcast_to(
            float_array(u, "u"), (*batch, sys.n_inputs)).reshape(N, -1)
        if dt is None:  # update only: the transition table is not read
            F, G, Qd = np.zeros((L, n, n)), np.zeros((L, n, sys.n_inputs)), np.zeros((L, n, n))
        else:
            steps = mode_steps(sys, positive_scalar(dt, "dt"))
            F, G, Qd = steps.F, steps.G, steps.Qd
        out, (x, P, mode, log_weight) = rbpf_step(
            state.x.reshape(N, Np, n), state.P.reshape(N, Np, n, n), state.mode.reshape(N, Np),
            state.log_weight.reshape(N, Np), y.reshape(N, -1), u, F, G, Qd, np.arange(L), sys.C,
            sys.R, self.transition, self.mode_prob0, state.keys.reshape(N), state.k,
            predict_first=dt is not None, sample_timing=self.timing == "sample",
            optimal=self.proposal == "optimal", scheme=RESAMPLING[self.resample],
            threshold=self.ess_threshold)
        raise_for_status(out.status)
        warn_for_repairs(out)
        return RBPFState(
            k=state.k + 1, keys=state.keys, mode=mode.reshape(*batch, Np),
            x=x.reshape(*batch, Np, n), P=P.reshape(*batch, Np, n, n),
            log_weight=log_weight.reshape(*batch, Np), combined_x=out.x.reshape(*batch, n),
            combined_P=out.P.reshape(*batch, n, n), mode_prob=out.mode_prob.reshape(*batch, L),
            loglik=out.loglik.reshape(batch), outlier=(out.flag == GATED).reshape(batch),
            ess=out.ess.reshape(batch))

    def run(self, y, u=None, t=None, *, keys=None, data_timing: str | None = None) -> Estimate:
        """Filter ``y (..., K, m)``; returns ``x``, ``P``, ``mode_prob``, the most probable
        ``mode``, ``loglik`` and the ``outlier`` flags at each sample.

        ``keys`` (uint64, the batch shape of ``y``) default to :meth:`trial_keys`. The whole
        record runs in the compiled kernel, with one exact transition per mode and distinct
        sampling step (as :class:`~switchest.estimators.IMMFilter`). ``data_timing``, the
        timing ``y`` was drawn in (:attr:`switchest.simulate.Trajectory.timing`), is named in a
        :class:`~switchest.estimators.TimingWarning` when it is not the filter's.
        """
        self._check_data_timing(data_timing)
        return self._run(y, u, t, keys)[0]

    def run_with_ess(self, y, u=None, t=None, *, keys=None,
                     data_timing: str | None = None) -> tuple[Estimate, np.ndarray]:
        """:meth:`run`, and the effective sample size :math:`1 / \\sum_p w_p^2` of every trial and
        sample before resampling (shape ``(..., K)``): a diagnostic of weight degeneracy."""
        self._check_data_timing(data_timing)
        return self._run(y, u, t, keys)

    def _run(self, y, u, t, keys) -> tuple[Estimate, np.ndarray]:
        """:meth:`run_with_ess` after its timing check."""
        y2, u2, t, batch = self._prepare(y, u, t)
        sys = self.system
        self._check_particle_memory(1)
        table, trans = sample_mode_steps(sys, t)
        out = rbpf_run(y2, u2, table.F, table.G, table.Qd, trans, sys.C, sys.R, self.transition,
                       self.x0, self.P0, self.mode_prob0, self._keys(keys, batch).reshape(-1),
                       particles=self.particles, sample_timing=self.timing == "sample",
                       optimal=self.proposal == "optimal", scheme=RESAMPLING[self.resample],
                       threshold=self.ess_threshold)
        raise_for_status(out.status)
        warn_for_repairs(out)
        est = Estimate(x=out.x, P=out.P, mode_prob=out.mode_prob, mode=out.mode,
                       loglik=out.loglik, outlier=out.flag == GATED)
        return self._unflatten(est, batch), out.ess.reshape(*batch, t.size)

    def _keys(self, keys, batch) -> np.ndarray:
        """``keys`` checked against ``batch`` (non-negative integers below :math:`2^{64}`) as
        uint64, or :meth:`trial_keys` when None."""
        if keys is None:
            return self.trial_keys(batch)
        arr = np.asarray(keys)
        if arr.dtype.kind not in "ui":
            raise TypeError(f"keys must be integers (uint64), got dtype {arr.dtype}")
        if arr.shape != tuple(batch):
            raise ValueError(f"keys must have the batch shape {tuple(batch)}, got {arr.shape}")
        if arr.dtype.kind == "i" and arr.size and arr.min() < 0:
            raise ValueError(f"keys must be non-negative, got {arr.min()}")
        return arr.astype(np.uint64)

    def _check_particle_memory(self, trials: int) -> None:
        """Refuse particles whose filters would not fit: ``trials`` trials' worth, and with the
        optimal proposal one predicted filter per candidate mode."""
        n, L, Np = self.system.n_states, self.system.n_modes, self.particles
        copies = trials + 2 + (L if self.proposal == "optimal" else 0)
        check_memory(8 * Np * copies * (n * n + n + 2),
                     f"{type(self).__name__} with particles = {Np} (n^2 + n + 2 floats per "
                     f"particle, n = {n}, for {trials} trial(s) and the kernel's copies)")


def _one_of(value, name: str, choices: tuple[str, ...]) -> str:
    """``value`` if it is one of the strings ``choices``."""
    if not isinstance(value, str):
        raise TypeError(f"{name} must be one of {', '.join(map(repr, choices))}, "
                        f"got {type(value).__name__}")
    if value not in choices:
        raise ValueError(f"{name} must be one of {', '.join(map(repr, choices))}, "
                         f"got {value!r}")
    return value
