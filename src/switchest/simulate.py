"""Exact, batched simulation of a switched system sampled at given instants.

Between consecutive grid instants the state moves by the exact transition of
:mod:`switchest.discretize` (switches inside the interval included, process
noise drawn from its exact covariance :math:`Q_d`); measurements
:math:`y_k = C(\\sigma(t_k))\\, x(t_k) + v_k`, :math:`v_k \\sim \\mathcal{N}(0, R(\\sigma(t_k)))`
(Shankar et al. eqs (1)-(2)). All trials advance together: the only Python loop
runs over time.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ._checks import (
    as_rng,
    check_finite,
    check_memory,
    check_symmetric_psd,
    float_array,
    positive_scalar,
)
from ._linalg import psd_sqrt
from ._threads import one_blas_thread
from .signals import SwitchingSignal, sample_segments
from .switching import SwitchingModel
from .system import SwitchedLinearSystem

__all__ = ["Trajectory", "simulate", "integrated_output_system"]


@dataclass(frozen=True, eq=False)
class Trajectory:
    """Simulated samples of N trials.

    Attributes
    ----------
    t : ndarray, shape (K,)
        Sample times.
    x : ndarray, shape (N, K, n)
        State at the samples.
    y : ndarray, shape (N, K, m)
        Measurements (NaN marks a missing sample when a user blanks one).
    u : ndarray, shape (N, K, l)
        Input applied on :math:`[t_k, t_{k+1})` (zero-order hold).
    mode : ndarray of int, shape (N, K)
        The mode of each sample, the one its measurement :math:`y_k` is taken in:
        :math:`\\sigma(t_k)` in the ``"sample"`` timing, the mode of the interval into
        :math:`t_k` (the left limit :math:`\\sigma(t_k^-)`, :math:`\\sigma(t_0)` at the first
        sample) in the ``"interval"`` one. The two
        differ only at a switch exactly at a sample instant.
    signals : tuple of SwitchingSignal, length N
        The true switching signal of each trial.
    timing : {"sample", "interval"}
        The timing the data were drawn in, the system's (:attr:`SwitchedLinearSystem.timing`,
        :doc:`/conventions`); a multiple-model filter told it (``data_timing=``) names another
        of its own in a :class:`~switchest.estimators.TimingWarning`.
    t_fine, x_fine, mode_fine : ndarray or None
        The continuous path on a fine grid ``(Kf,)``, ``(N, Kf, n)``, ``(N, Kf)``
        when :func:`simulate` was given ``fine_dt``; the fine grid contains every
        sample time.
    y_fine : ndarray or None
        With ``output="integrated"`` and ``fine_dt``: the integrated output on the
        fine grid ``(N, Kf, m)``.
    """

    t: np.ndarray
    x: np.ndarray
    y: np.ndarray
    u: np.ndarray
    mode: np.ndarray
    signals: tuple[SwitchingSignal, ...]
    timing: str = "sample"
    t_fine: np.ndarray | None = None
    x_fine: np.ndarray | None = None
    mode_fine: np.ndarray | None = None
    y_fine: np.ndarray | None = None

    @property
    def n_trials(self) -> int:
        """Number of trials N."""
        return self.x.shape[0]

    def segments(self) -> tuple[np.ndarray, np.ndarray]:
        """True segment modes ``(N, K-1, S+1)`` and switch offsets ``(N, K-1, S)`` per interval.

        The clairvoyant information (exact switching times) that
        :func:`switchest.discretize.interval` turns into exact transitions.
        """
        _, modes, offsets = sample_segments(self.signals, self.t)
        return modes, offsets

    def switch_times(self) -> np.ndarray:
        """The first true switching instant inside :math:`(t_{k-1}, t_k)` at sample k, ``(N, K)``.

        NaN at sample 0 and where the interval holds no switch: the layout of
        ``Estimate.switch_time``, for :func:`switchest.metrics.switch_time_error`.
        """
        modes, offsets = self.segments()
        out = np.full(self.mode.shape, np.nan)
        if offsets.shape[-1]:
            inside = modes[..., 1] != modes[..., 0]
            out[:, 1:] = np.where(inside, self.t[:-1] + offsets[..., 0], np.nan)
        return out


SignalSource = SwitchingSignal | SwitchingModel | Callable[[np.random.Generator], SwitchingSignal]


@one_blas_thread()
def simulate(
    system: SwitchedLinearSystem,
    signal: SignalSource,
    t,
    x0,
    u=None,
    *,
    trials: int = 1,
    rng=None,
    fine_dt: float | None = None,
    output: str = "sampled",
) -> Trajectory:
    """Simulate ``trials`` independent runs exactly at the sample times ``t``.

    Parameters
    ----------
    system : SwitchedLinearSystem
        Its ``timing`` says which mode a sample records and is measured in: the one that
        starts at it (``"sample"``) or the one that ends there (``"interval"``).
    signal : SwitchingSignal, SwitchingModel or callable
        One signal shared by all trials; or a switching model (anything with a method
        ``sample(rng, t) -> SwitchingSignal``, such as :class:`switchest.switching.Dwell`),
        or a generator ``f(rng) -> SwitchingSignal``, drawn once per trial with that
        trial's own generator (spawned from ``rng``): ``model`` draws as
        ``lambda rng: model.sample(rng, t)`` does.
    t : array_like, shape (K,)
        Strictly increasing sample times (periodic or aperiodic). For a
        discrete-time system they must be spaced by ``system.dt``.
    x0 : array_like, shape (n,), or tuple (mean (n,), cov (n, n))
        Initial state, or the Gaussian it is drawn from (independently per trial).
    u : array_like, optional
        Input held on :math:`[t_k, t_{k+1})`: constant ``(l,)``, per sample ``(K, l)`` or
        per trial ``(trials, K, l)``. Default zero.
    trials : int
        Number of independent runs N.
    rng : Generator, int or None
        Source of all randomness (signals, initial states, noises).
    fine_dt : float, optional
        Also return the path on a fine grid: each sample interval is split into
        :math:`\\lceil (t_{k+1} - t_k) / \\mathrm{fine\\_dt} \\rceil` equal steps (continuous
        systems only).
    output : {"sampled", "integrated"}
        ``"sampled"``: :math:`y_k = C x(t_k) + v_k` with :math:`v_k \\sim \\mathcal{N}(0, R)`.
        ``"integrated"`` (continuous systems): the output is the Ito process
        :math:`dz = C x\\, dt + dv` with :math:`\\mathbb{E}[dv\\, dv^\\top] = R\\, dt` (Wang et al.
        eq. (1), :math:`R = \\Xi \\Xi^\\top`), and :math:`y_k = z(t_k)` with :math:`z(t_0) = 0`.
        It is simulated exactly, as the extra states of
        :math:`d \\begin{bmatrix} x \\\\ z \\end{bmatrix} = \\begin{bmatrix} A & 0 \\\\ C & 0
        \\end{bmatrix} \\begin{bmatrix} x \\\\ z \\end{bmatrix} dt + \\dots` (see
        :func:`integrated_output_system`); an observer uses its increments.

    Returns
    -------
    Trajectory

    Raises
    ------
    ValueError
        Also when the outputs would not fit in memory:
        :math:`N (K (n + m + l + 1) + K_f (n + 1))` floats (:math:`K_f` the fine grid's size)
        against :func:`switchest._checks.memory_limit` (half
        of the physical memory), estimated before anything is drawn.

    Notes
    -----
    BLAS runs on one thread during the call (:func:`switchest._threads.one_blas_thread`):
    threads only slow down its small products, many times over on a busy machine.
    """
    if not isinstance(system, SwitchedLinearSystem):
        raise TypeError(f"system must be a SwitchedLinearSystem, got {type(system).__name__}")
    if (isinstance(trials, (bool, np.bool_)) or not isinstance(trials, (int, np.integer))
            or trials < 1):
        raise ValueError(f"trials must be a positive int, got {trials!r}")
    rng = as_rng(rng)
    t = float_array(t, "t", ndim=1)
    check_finite(t, "t")
    if t.size < 1 or np.any(np.diff(t) <= 0):
        raise ValueError("t must be a non-empty, strictly increasing array of sample times")
    if not system.is_continuous:
        if t.size > 1 and np.any(np.abs(np.diff(t) - system.dt) > 1e-9 * system.dt):
            raise ValueError(f"t must be spaced by the discrete system's dt = {system.dt:g}")
        if fine_dt is not None:
            raise ValueError("fine_dt applies to continuous-time systems only")
    if not isinstance(output, str) or output not in ("sampled", "integrated"):
        raise ValueError(f"output must be 'sampled' or 'integrated', got {output!r}")
    parts = None if fine_dt is None else _fine_parts(t, fine_dt)
    if output == "integrated":
        if not system.is_continuous:
            raise ValueError("output='integrated' applies to continuous-time systems only")
        return _simulate_integrated(system, signal, t, x0, u, trials=trials, rng=rng,
                                    fine_dt=fine_dt)
    _check_size(system, trials, t.size, parts)
    signals = _signals(signal, trials, rng, system.n_modes, t)
    u = _inputs(u, system.n_inputs, t.size, trials)
    x = _initial_states(x0, system.n_states, trials, rng)

    grid, sample_index = t, np.arange(t.size)
    if parts is not None:
        grid, sample_index = _fine_grid(t, parts)
    u_grid = u[:, np.searchsorted(t, grid, side="right") - 1]
    mode_grid, modes, offsets = sample_segments(signals, grid)
    X = _propagate(system, modes, offsets, grid, x, u_grid, rng)
    x_s = X if fine_dt is None else X[:, sample_index]
    mode = mode_grid[:, sample_index]
    if system.timing == "interval":  # the mode of the last segment into t_k (conventions.rst)
        mode[:, 1:] = modes[:, sample_index[1:] - 1, -1]
    y = _measure(system, x_s, mode, rng)
    fine = {}
    if fine_dt is not None:
        fine = dict(t_fine=grid, x_fine=X, mode_fine=mode_grid)
    return Trajectory(t=t, x=x_s, y=y, u=u, mode=mode, signals=tuple(signals),
                      timing=system.timing, **fine)


def integrated_output_system(system: SwitchedLinearSystem) -> SwitchedLinearSystem:
    """The system with its integrated output :math:`z` appended to the state.

    .. math::

        d \\begin{bmatrix} x \\\\ z \\end{bmatrix}
        = \\begin{bmatrix} A & 0 \\\\ C & 0 \\end{bmatrix}
          \\begin{bmatrix} x \\\\ z \\end{bmatrix} dt
        + \\begin{bmatrix} B \\\\ 0 \\end{bmatrix} u\\, dt
        + \\begin{bmatrix} dw \\\\ dv \\end{bmatrix}

    with noise intensity :math:`\\operatorname{blockdiag}(Q, R)`: sampling it exactly gives the
    exact joint law of the state and the Ito output :math:`dz = C x\\, dt + dv` of Wang et al.
    eq. (1).
    """
    if not isinstance(system, SwitchedLinearSystem):
        raise TypeError(f"system must be a SwitchedLinearSystem, got {type(system).__name__}")
    if not system.is_continuous:
        raise ValueError("system must be continuous-time: the integrated output is an Ito integral")
    L, n, m = system.n_modes, system.n_states, system.n_outputs
    A = np.zeros((L, n + m, n + m))
    A[:, :n, :n] = system.A
    A[:, n:, :n] = system.C
    B = np.concatenate([system.B, np.zeros((L, m, system.n_inputs))], axis=1)
    Q = np.zeros((L, n + m, n + m))
    Q[:, :n, :n] = system.Q
    Q[:, n:, n:] = system.R
    C = np.broadcast_to(np.eye(n + m)[n:], (L, m, n + m))
    return SwitchedLinearSystem.continuous(A, B, C, Q=Q, timing=system.timing)


def _simulate_integrated(system, signal, t, x0, u, *, trials, rng, fine_dt) -> Trajectory:
    n, m = system.n_states, system.n_outputs
    aug = integrated_output_system(system)
    mean, cov = _initial_moments(x0, n)
    z0 = np.zeros(m)  # the integrated output starts at 0
    x0_aug = ((np.concatenate([mean, z0]), np.pad(cov, (0, m))) if isinstance(x0, tuple)
              else np.concatenate([mean, z0]))
    traj = simulate(aug, signal, t, x0_aug, u, trials=trials, rng=rng, fine_dt=fine_dt)
    fine = {}
    if fine_dt is not None:
        fine = dict(t_fine=traj.t_fine, x_fine=traj.x_fine[..., :n], mode_fine=traj.mode_fine,
                    y_fine=traj.x_fine[..., n:])
    return Trajectory(t=traj.t, x=traj.x[..., :n], y=traj.x[..., n:], u=traj.u, mode=traj.mode,
                      signals=traj.signals, timing=traj.timing, **fine)


def _propagate(system, modes, offsets, grid, x, u, rng) -> np.ndarray:
    """States at every grid instant ``(N, G, n)``; the loop runs over time only."""
    # imported here: `import switchest` imports this module, and discretize imports scipy
    from .discretize import mode_steps

    N, n = x.shape
    X = np.empty((N, grid.size, n))
    X[:, 0] = x
    per_length: dict[float, np.ndarray] = {}
    switched = _switched_steps(system, modes, offsets, grid)
    for k, h in enumerate(np.diff(grid)):
        # periodic grids repeat one length up to round-off: reuse its per-mode transitions
        key = float(np.format_float_positional(h, precision=13, unique=False, fractional=False))
        if key not in per_length:
            steps = mode_steps(system, h)
            per_length[key] = _stacked_step(steps.F, steps.G, psd_sqrt(steps.Qd))
        # [x, u, z] @ [F'; G'; Qd^(1/2)'] for every mode in one batched product, then pick
        # each trial's mode: L small GEMMs instead of N gathered matrix-vector products
        xuz = np.concatenate([x, u[:, k], rng.standard_normal((N, n))], axis=1)
        x = _pick(np.matmul(xuz, per_length[key]), modes[:, k, 0])
        if k in switched:
            rows, stacked = switched[k]
            x[rows] = (xuz[rows, None, :] @ stacked)[:, 0]
        X[:, k + 1] = x
    return X


def _switched_steps(system, modes, offsets, grid) -> dict[int, tuple[np.ndarray, np.ndarray]]:
    """For each grid interval ``k`` with a switch inside in some trials: those trials and
    their stacked exact steps :math:`[F^\\top; G^\\top; (Q_d^{1/2})^\\top]`.

    All the switched intervals are discretized at once, from the dyadic table of each
    interval length (:func:`switchest.dyadic.interval_transitions`: exact, without a matrix
    exponential per interval); a discrete-time system cannot switch inside a step, and
    :func:`switchest.discretize.segment_transitions` says so.
    """
    from .discretize import segment_transitions
    from .dyadic import dyadic_table, interval_transitions

    if not offsets.shape[-1]:
        return {}
    rows, ks = np.nonzero(np.any(modes[..., 1:] != modes[..., :1], axis=-1))
    if not rows.size:
        return {}
    lengths = np.diff(grid)[ks]
    if not system.is_continuous:  # raises: no switch inside a discrete step
        segment_transitions(system, lengths[0], modes[rows[:1], ks[0]], offsets[rows[:1], ks[0]])
    n, M = system.n_states, rows.size
    F, G, Qd = np.empty((M, n, n)), np.empty((M, n, system.n_inputs)), np.empty((M, n, n))
    for h in np.unique(lengths):
        at = lengths == h
        tr = interval_transitions(dyadic_table(system, h), modes[rows[at], ks[at]],
                                  offsets[rows[at], ks[at]])
        F[at], G[at], Qd[at] = tr.F, tr.G, tr.Qd
    stacked = _stacked_step(F, G, psd_sqrt(Qd))
    order = np.argsort(ks, kind="stable")
    starts = np.flatnonzero(np.diff(ks[order], prepend=-1))
    return {int(ks[order[a]]): (rows[order[a:b]], stacked[order[a:b]])
            for a, b in zip(starts, [*starts[1:], order.size])}


def _measure(system, x, mode, rng) -> np.ndarray:
    """:math:`y_k = C_m x_k + R_m^{1/2} v_k` for every trial and sample, one sample at a time."""
    N, K, _ = x.shape
    stacked = np.concatenate([np.swapaxes(system.C, 1, 2), np.swapaxes(psd_sqrt(system.R), 1, 2)],
                             axis=1)
    y = np.empty((N, K, system.n_outputs))
    for k in range(K):
        xv = np.concatenate([x[:, k], rng.standard_normal((N, system.n_outputs))], axis=1)
        y[:, k] = _pick(np.matmul(xv, stacked), mode[:, k])
    return y


def _pick(per_mode: np.ndarray, mode: np.ndarray) -> np.ndarray:
    """From ``(L, N, d)`` results of every mode, each trial's own ``(N, d)``."""
    return per_mode[mode, np.arange(mode.size)]


def _stacked_step(F, G, Q_sqrt) -> np.ndarray:
    """:math:`[F^\\top; G^\\top; Q_\\mathrm{sqrt}^\\top]` of shape (..., 2n + l, n), so
    ``[x, u, z] @ it`` is one step."""
    return np.concatenate([np.swapaxes(a, -1, -2) for a in (F, G, Q_sqrt)], axis=-2)


def _signals(signal, trials, rng, n_modes, t) -> list[SwitchingSignal]:
    if isinstance(signal, SwitchingSignal):
        return _check_modes([signal] * trials, n_modes)
    if callable(getattr(signal, "sample", None)):
        model_modes = getattr(signal, "n_modes", None)
        if model_modes is not None and model_modes > n_modes:  # refused before any draw
            raise ValueError(f"signal uses mode {model_modes - 1} (a switching model of "
                             f"{model_modes} modes), but the system has modes 0..{n_modes - 1}")
        draw, call = (lambda r: signal.sample(r, t)), "signal.sample(rng, t)"
    elif callable(signal):
        draw, call = signal, "signal(rng)"
    else:
        raise TypeError(
            f"signal must be a SwitchingSignal, a switching model (with sample(rng, t)) or a "
            f"callable rng -> SwitchingSignal, got {type(signal).__name__}"
        )
    signals = [draw(child) for child in rng.spawn(trials)]
    for i, s in enumerate(signals):
        if not isinstance(s, SwitchingSignal):
            raise TypeError(
                f"{call} must return a SwitchingSignal, got {type(s).__name__} for trial {i}"
            )
    return _check_modes(signals, n_modes)


def _check_modes(signals: list[SwitchingSignal], n_modes: int) -> list[SwitchingSignal]:
    top = max(int(s.modes.max()) for s in signals)
    if top >= n_modes:
        raise ValueError(f"signal uses mode {top}, but the system has modes 0..{n_modes - 1}")
    return signals


def _inputs(u, l, K, trials) -> np.ndarray:
    if u is None:
        return np.zeros((trials, K, l))
    u = float_array(u, "u", ndim=(1, 2, 3))
    check_finite(u, "u")
    expected = {1: (l,), 2: (K, l), 3: (trials, K, l)}[u.ndim]
    if u.shape != expected:
        raise ValueError(
            f"u must have shape (l,) = ({l},), (K, l) = ({K}, {l}) or (trials, K, l) = "
            f"({trials}, {K}, {l}), got {u.shape}"
        )
    return np.array(np.broadcast_to(u, (trials, K, l)))


def _initial_moments(x0, n) -> tuple[np.ndarray, np.ndarray]:
    """Validated ``(mean (n,), cov (n, n))`` of the initial state; a vector has zero covariance."""
    if isinstance(x0, tuple):
        if len(x0) != 2:
            raise ValueError(f"x0 as a tuple must be (mean, cov), got {len(x0)} entries")
        mean = float_array(x0[0], "x0 mean", ndim=1)
        cov = float_array(x0[1], "x0 cov", ndim=2)
        if mean.shape != (n,) or cov.shape != (n, n):
            raise ValueError(
                f"x0 must be (mean (n,), cov (n, n)) with n = {n}, got {mean.shape} and {cov.shape}"
            )
        check_finite(mean, "x0 mean")
        check_finite(cov, "x0 cov")
        return mean, check_symmetric_psd(cov, "x0 cov")
    x0 = float_array(x0, "x0", ndim=1)
    if x0.shape != (n,):
        raise ValueError(f"x0 must have shape (n,) = ({n},), got {x0.shape}")
    check_finite(x0, "x0")
    return x0, np.zeros((n, n))


def _initial_states(x0, n, trials, rng) -> np.ndarray:
    mean, cov = _initial_moments(x0, n)
    if isinstance(x0, tuple):  # drawn per trial (a vector x0 draws no random numbers)
        return mean + rng.standard_normal((trials, n)) @ psd_sqrt(cov).T
    return np.broadcast_to(mean, (trials, n)).copy()


def _check_size(system, trials: int, K: int, parts) -> None:
    """Refuse up front outputs that would not fit in memory (before any signal is drawn)."""
    n, m, l = system.n_states, system.n_outputs, system.n_inputs
    Kf = 0.0 if parts is None else float(parts.sum()) + 1  # floats: no overflow
    fine = "" if parts is None else f" and Kf = {Kf:.4g} fine instants"
    check_memory(
        8 * trials * (K * (n + m + l + 1) + Kf * (n + 1)),
        f"simulate with trials = {trials}, K = {K} samples{fine} "
        f"(N (K (n + m + l + 1) + Kf (n + 1)) floats, n = {n}, m = {m}, l = {l})",
    )


def _fine_parts(t, fine_dt) -> np.ndarray:
    """Fine steps per sample interval, :math:`\\lceil (t_{k+1} - t_k) / \\mathrm{fine\\_dt}
    \\rceil` and at least 1.

    Floats, so that an absurd ``fine_dt`` gives a huge count to refuse, not an overflow.
    """
    fine_dt = positive_scalar(fine_dt, "fine_dt")
    return np.maximum(np.ceil(np.diff(t) / fine_dt - 1e-9), 1.0)


def _fine_grid(t, parts) -> tuple[np.ndarray, np.ndarray]:
    """Split each sample interval into ``parts[k]`` equal steps."""
    parts = parts.astype(np.int64)
    pieces = [t[k] + (t[k + 1] - t[k]) * np.arange(p) / p for k, p in enumerate(parts)]
    grid = np.concatenate([*pieces, t[-1:]])
    sample_index = np.concatenate([[0], np.cumsum(parts)])
    return grid, sample_index
