"""Compile the filter kernels before their first use, and tell when numba compiles.

numba compiles a kernel at its first call after install and keeps it on disk (``cache=True``:
``__pycache__`` beside the sources, or ``NUMBA_CACHE_DIR``); later processes load it. The
first compile of the IMM's kernel takes about 40 s of one core, loading it a fraction of a
second.

- :func:`warm_up` calls every kernel once on tiny arrays, through the wrappers the estimators
  call, so what it compiles are the signatures the estimators use. The experiment runner calls
  it before it starts worker processes, which then inherit (fork) or load (spawn) the kernels
  instead of each compiling them. On the first run after an install it has them compiled by
  worker processes side by side, one per core.
- :func:`on_first_compile` calls back when numba starts to compile, and times the compiles.
  numba looks in the on-disk cache first and compiles (broadcasting its ``numba:compile``
  event) only when the cache has no entry for the signature, for this source and this numba:
  the command line announces the wait there and says how long it took, and says nothing when
  the cache is warm.

A kernel module registers its warm-up when it is imported (``_compiled/__init__`` imports
every kernel module, so all have registered before :func:`warm_up` runs)::

    from .warmup import register

    @register
    def _warm_up() -> None:
        my_kernel_run(...)  # tiny arrays, of the dtypes and layouts the estimators pass

This module imports no kernel module at its top, so that they can import it.
"""

from __future__ import annotations

import importlib
import time
from collections.abc import Callable, Iterator
from contextlib import ExitStack, contextmanager

import numpy as np
from numba.core.event import Listener, install_listener, trigger_event

from ..._jit import started_afresh
from ..._threads import cores

__all__ = ["CompileWatch", "on_first_compile", "register", "warm_up"]

_WARM_UPS: list[Callable[[], object]] = []


def register(warm_up: Callable[[], object]) -> Callable[[], object]:
    """Add ``warm_up`` (no arguments: it calls a module's kernels once on tiny arrays) to
    what :func:`warm_up` runs; returns it, so it can decorate the function."""
    _WARM_UPS.append(warm_up)
    return warm_up


def warm_up() -> bool:
    """Call every registered kernel once; return whether any of them was compiled (the on-disk
    cache lacked it) rather than only loaded.

    On a cache this process started afresh (:func:`switchest._jit.started_afresh`: the first
    run after an install or an upgrade) with more than one core to run on, worker processes,
    one per core, first compile the warm-ups side by side into the on-disk cache, taking them
    in the order they were registered (the longest first); this process then loads them. On
    two cores every kernel was compiled in 165 s of wall time instead of 300 in one process.
    """
    compiled = []
    with on_first_compile(lambda: compiled.append(True)):
        _compile_apart()
        for run in _WARM_UPS:
            run()
    return bool(compiled)


_APART = "switchest:compile"
"""The event :func:`warm_up` broadcasts while worker processes compile (numba's own,
``numba:compile``, is heard only in the process that compiles)."""
_APART_DONE: list[bool] = []  # holds True once this process had its kernels compiled apart


def _compile_apart() -> None:
    """The warm-ups compiled into the on-disk cache by worker processes, if the cache was
    started afresh, more than one core is free, and this process has not done so before.
    Without worker processes (none may be started here) this process compiles them alone."""
    workers = min(cores(), len(_WARM_UPS))
    if _APART_DONE or workers < 2 or not started_afresh():
        return
    _APART_DONE.append(True)
    # here, not at the top: every process that filters imports this module, few need a pool
    from concurrent.futures import ProcessPoolExecutor
    from concurrent.futures.process import BrokenProcessPool

    names = [f"{run.__module__}:{run.__qualname__}" for run in _WARM_UPS]
    with trigger_event(_APART):
        try:
            with ProcessPoolExecutor(workers) as pool:
                for _ in pool.map(_warm_up_named, names):
                    pass
        except (OSError, BrokenProcessPool):  # the warm-ups then compile in this process
            return


def _warm_up_named(name: str) -> None:
    """Run the warm-up ``"module:function"`` (in a worker process)."""
    module, function = name.split(":")
    getattr(importlib.import_module(module), function)()


class CompileWatch(Listener):
    """Calls its callback at the start of the first compile it hears of, and adds up the wall
    time spent compiling (a compile inside another counted once), here or, for
    :func:`warm_up`, in its worker processes.

    Attributes
    ----------
    heard : bool
        Whether numba compiled anything while the watch listened.
    seconds : float
        Wall time of those compiles, in seconds.
    """

    def __init__(self, callback: Callable[[], object]):
        self._callback, self._depth, self._started = callback, 0, 0.0
        self.heard, self.seconds = False, 0.0

    def on_start(self, event) -> None:
        if not self.heard:
            self.heard = True
            self._callback()
        if self._depth == 0:
            self._started = time.perf_counter()
        self._depth += 1

    def on_end(self, event) -> None:
        self._depth -= 1
        if self._depth == 0:
            self.seconds += time.perf_counter() - self._started


@contextmanager
def on_first_compile(callback: Callable[[], object]) -> Iterator[CompileWatch]:
    """Call ``callback()`` when numba starts to compile something inside the block (once,
    before the first compile; never if every kernel loads from the cache or memory); the block
    gets the :class:`CompileWatch`, whose ``seconds`` add up the compiles when it ends."""
    watch = CompileWatch(callback)
    with ExitStack() as listening:
        for kind in ("numba:compile", _APART):
            listening.enter_context(install_listener(kind, watch))
        yield watch


# ------------------------------------------------- the warm-ups, the longest to compile first
def _model(L: int = 2) -> tuple[np.ndarray, ...]:
    """``F, G, Qd, C, R``, each ``(L, 1, 1)``: ``L`` modes of one state, input and output."""
    one = np.ones((L, 1, 1))
    return one, np.zeros((L, 1, 1)), one, one, one


def _tiny_switched():
    """A continuous one-state, two-mode system and a record of four samples with a switch."""
    from ...system import SwitchedLinearSystem

    system = SwitchedLinearSystem.continuous([[[-1.0]], [[-2.0]]], [[[1.0]], [[0.5]]],
                                             [[[1.0]], [[1.0]]], Q=[[0.1]], R=[[0.1]])
    t = np.array([0.0, 0.1, 0.2, 0.3])
    return system, t, np.zeros((1, 4, 1)), np.array([[0, 0, 1, 1]])


@register
def _multiple_model() -> None:
    """GPB1's and GPB2's kernels, Kim's smoother (through ``smooth``) and the particle filter's
    kernel (both proposals share it), over a record and one step of a two-mode system."""
    from ..gpb import GPB1Filter, GPB2Filter
    from ..rbpf import RBPFilter

    system, t, y, _ = _tiny_switched()
    transition = np.full((2, 2), 0.5)
    for kind in (GPB1Filter, GPB2Filter):
        f = kind(system, transition, np.zeros(1), np.eye(1))
        f.smooth(y, np.zeros(1), t)
        f.step(f.init((1,)), y[:, 1], np.zeros((1, 1)), dt=0.1)
    pf = RBPFilter(system, transition, np.zeros(1), np.eye(1), particles=4, rng=0)
    pf.run(y, np.zeros(1), t)
    state = pf.step(pf.init((1,)), y[:, 0], np.zeros((1, 1)))
    pf.step(state, y[:, 1], np.zeros((1, 1)), dt=0.1)


@register
def _switch_time() -> None:
    """:class:`~switchest.estimators.SwitchTimeKalmanFilter`'s kernel, over a record (grid
    maximum, refined, marginal) and one step."""
    from ..switch_time import SwitchTimeKalmanFilter

    system, t, y, modes = _tiny_switched()
    for options in ({}, {"refine": True}, {"switch_time": "marginal"}):
        f = SwitchTimeKalmanFilter(system, np.zeros(1), np.eye(1), grid=2, **options)
        f.run(y, np.zeros(1), t, modes=modes)
    f.step(f.init((1,)), y[:, 1], np.zeros((1, 1)), dt=0.1, mode=[1], prev_mode=[0])


@register
def _imm() -> None:
    """:func:`.imm.imm_run` and :func:`.imm.imm_step`: one trial, two samples, two modes."""
    from .imm import imm_run, imm_step

    F, G, Qd, C, R = _model()
    log_transition = np.log(np.full((2, 2), 0.5))
    imm_run(np.zeros((1, 2, 1)), np.zeros((1, 2, 1)), F, G, Qd, np.array([[0, 0], [0, 1]]), C,
            R, log_transition, np.zeros(1), np.eye(1), np.log([0.5, 0.5]))
    imm_step(np.zeros((1, 2, 1)), np.ones((1, 2, 1, 1)), np.log(np.full((1, 2), 0.5)),
             np.zeros((1, 1)), np.zeros((1, 1)), F, G, Qd, np.array([0, 1]), C, R,
             log_transition, predict_first=True)


@register
def _imm_ev1() -> None:
    """:class:`~switchest.estimators.IMMEV1Filter`'s kernel, over a record and one step."""
    from ..imm_ev1 import IMMEV1Filter

    system, t, y, _ = _tiny_switched()
    f = IMMEV1Filter(system, x0=np.zeros(1), P0=np.eye(1), grid=2)
    f.run(y, np.zeros(1), t)
    f.step(f.init((1,)), y[:, 1], np.zeros((1, 1)), dt=0.1)


@register
def _kalman() -> None:
    """:mod:`.kalman`'s filters along given transitions, with computed and with fixed gains,
    over a record and one step: one trial, two samples, one mode."""
    from .kalman import kalman_run, kalman_steady_run, kalman_steady_step, kalman_step

    F, G, Qd, C, R = _model(1)
    y, u, index = np.zeros((1, 2, 1)), np.zeros((1, 2, 1)), np.zeros((1, 2), dtype=np.int64)
    gain = np.full((1, 1, 1), 0.5)
    kalman_run(y, u, F, G, Qd, index, C, R, index, np.zeros(1), np.eye(1))
    kalman_step(np.zeros((1, 1)), np.ones((1, 1, 1)), np.zeros((1, 1)), np.zeros((1, 1)), F, G,
                Qd, C, R, predict_first=True)
    kalman_steady_run(y, u, F, G, index, C, index, gain, Qd, Qd, R, np.zeros(1))
    kalman_steady_step(np.zeros((1, 1)), np.zeros((1, 1)), np.zeros((1, 1)), F, G, C, gain, Qd,
                       Qd, R, predict_first=True)


@register
def _dyadic() -> None:
    """:func:`switchest.dyadic.interval_transitions` (the clairvoyant filter's and the
    simulation's switched intervals): one interval of a one-state, two-mode system."""
    from ...dyadic import DyadicTable, interval_transitions

    one = np.ones((2, 1, 1, 1))
    table = DyadicTable(1.0, 0, one, np.zeros((2, 1, 1, 1)), one, -np.ones((2, 1, 1)),
                        np.ones((2, 1, 1)), np.ones((2, 1, 1)))
    interval_transitions(table, np.array([[0, 1]]), np.array([[0.5]]))
