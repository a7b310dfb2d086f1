"""Run an experiment's tasks in-process, on a local process pool or on a Dask cluster.

Every task is seeded from ``numpy.random.SeedSequence(seed, spawn_key=(block,))``
— its trial block, not its position in a queue — so results do not depend on
the number or kind of workers, and every configuration of an experiment sees
the same simulated data for a block. Each finished task is committed to the
store at once; tasks already in the store are skipped.

Runs share a store: a run claims each task before computing it and leaves the
tasks another live run has claimed, then waits for those to reach the store (or
takes them over if their run died). Ctrl-C stops a run at once: what finished is
committed, pool workers are terminated, and :class:`RunInterrupted` tells how
many tasks are stored. Pool workers ignore SIGINT (a terminal sends it to the
whole process group; the runner stops them) and, on Linux, die with their parent
even when it is killed with SIGKILL. Other platforms have no such request: there
the workers of a runner killed with SIGKILL stay, idle, until ended by hand.
"""

from __future__ import annotations

import ctypes
import gc
import os
import signal
import socket
import sqlite3
import sys
import tempfile
import threading
import time
from collections import deque
from collections.abc import Callable, Hashable
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

from .._threads import cores
from .registry import Experiment, Summary, get
from .store import Claimant, Store, StoredTask, process_token, task_key

__all__ = ["run_experiment", "run_quick", "execute_task", "stored_results", "run_tasks",
           "RunInterrupted", "MAX_WORKERS"]

MAX_WORKERS = 256
"""Most local worker processes a run accepts. Each is a Python process of its own (a few
hundred MB), and the pool never exceeds the machine's cores, of which the
largest single machines have a few hundred; a larger number is a typo (``--workers 100000``),
refused rather than quietly cut. Clusters go through ``scheduler``."""

POLL = 0.5
"""Seconds between looks at tasks that other runs are computing."""

HEARTBEAT = 10.0
"""Seconds between renewals of a run's claims; well inside ``store.LEASE``."""

CONNECT_TIMEOUT = 10.0
"""Seconds to wait for a Dask scheduler to answer."""

_PR_SET_PDEATHSIG = 1  # linux/prctl.h


class RunInterrupted(Exception):
    """Ctrl-C stopped a run; every task that had finished is in the store.

    Attributes
    ----------
    experiment : str
        The experiment's name.
    stored : int
        Tasks of this run (same parameters and seed) now in the store.
    total : int
        Tasks of the run in all.
    """

    def __init__(self, experiment: str, stored: int, total: int):
        super().__init__(f"{experiment} interrupted: {stored} of {total} tasks are in the store; "
                         "run it again with the same parameters and seed to resume")
        self.experiment, self.stored, self.total = experiment, stored, total


def execute_task(name: str, config: dict, seed: list[int]) -> tuple[dict, float]:
    """Run one task of experiment ``name`` (importable, so process and Dask workers can call it).

    BLAS is held to one thread: the tasks are the parallelism, and threaded BLAS
    on small matrices under contention is far slower than serial.
    """
    from . import EXPERIMENTS  # noqa: F401  (importing the package registers every experiment)

    experiment = get(name)
    rng = np.random.default_rng(np.random.SeedSequence(seed[0], spawn_key=tuple(seed[1:])))
    start = time.perf_counter()
    # threadpoolctl's own context, not one_blas_thread's cached controller: under Dask's
    # threaded workers the latter held back the results until every task had finished
    with threadpool_limits(1):
        result = experiment.run_task(config, rng)
    return result, time.perf_counter() - start


def run_experiment(
    experiment: Experiment,
    params: dict,
    *,
    store: Store,
    seed: int = 0,
    workers: int = 1,
    scheduler: str | None = None,
    on_done: Callable[[int, int], None] | None = None,
) -> list[tuple[dict, dict]]:
    """Run every task of ``experiment`` not yet in ``store``; return all ``(config, result)``.

    Parameters
    ----------
    experiment : Experiment
    params : dict
        Its parameters (``experiment.params(...)``).
    store : Store
        Where finished tasks are committed, one by one. Other runs of the same
        experiment may use it at the same time: each task is computed by one of them.
    seed : int
        Root seed, any non-negative int.
    workers : int
        1 runs in this process; more use a local process pool of
        ``min(workers, tasks to compute, cores)`` processes. At most :data:`MAX_WORKERS`.
    scheduler : str, optional
        Address of a Dask scheduler (``tcp://host:8786``) to run the tasks on instead;
        needs the ``switchest[dask]`` extra.
    on_done : callable, optional
        ``on_done(finished, total)`` at the start, after each task, and every
        :data:`POLL` seconds while waiting for tasks other runs compute (progress display).

    Raises
    ------
    RunInterrupted
        On Ctrl-C (``KeyboardInterrupt``), within about a second, once the finished
        tasks are committed and the workers stopped.
    ValueError
        For a bad ``seed``, ``workers`` or ``scheduler`` address, or a plan without tasks.
    ConnectionError
        If the Dask scheduler cannot be reached within :data:`CONNECT_TIMEOUT` seconds.
    """
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be a non-negative int, got {seed!r}")
    if isinstance(workers, bool) or not isinstance(workers, int) or not 1 <= workers <= MAX_WORKERS:
        raise ValueError(f"workers must be a positive int no larger than {MAX_WORKERS} (local "
                         f"processes; use a Dask scheduler beyond), got {workers!r}")
    if scheduler is not None:
        _check_scheduler_address(scheduler)
    run = _Run(experiment, params, int(seed), store, on_done)
    run.execute(lambda: _backend(scheduler, workers, len(run.remaining)))
    results, missing = stored_results(experiment, params, store, seed)
    if missing:
        raise RuntimeError(f"{missing} task(s) of {experiment.name} did not reach the store")
    return results


def run_quick(name: str, figures: str | Path, *, seed: int = 0, **overrides) -> Summary:
    """Run the registered experiment ``name`` at its small preset (``switchest run NAME
    --quick``; ``overrides`` shrink or change it further, as :meth:`Experiment.params`) in a
    temporary store, and summarize it, drawing its figures into ``figures``: the gallery's and
    a notebook's way to look at a reproduction without a results store."""
    experiment = get(name)
    params = experiment.params(quick=True, **overrides)
    with tempfile.TemporaryDirectory() as folder:
        results = run_experiment(experiment, params, store=Store(Path(folder) / "results.sqlite"),
                                 seed=seed)
    return experiment.summarize(params, results, Path(figures))


def stored_results(experiment: Experiment, params: dict, store: Store,
                   seed: int = 0) -> tuple[list, int]:
    """The stored ``(config, result)`` pairs of a run, in task order, and how many are missing."""
    configs, _, keys = _plan(experiment, params, seed)
    by_key = {t.key: t.result for t in store.tasks(experiment.name)}
    found = [(cfg, by_key[k]) for cfg, k in zip(configs, keys, strict=True) if k in by_key]
    return found, len(configs) - len(found)


def run_tasks(experiment: Experiment, params: dict, store: Store,
              seed: int = 0) -> list[StoredTask]:
    """The stored tasks of a run (its parameters and seed), with their timings."""
    keys = set(_plan(experiment, params, seed)[2])
    return [t for t in store.tasks(experiment.name) if t.key in keys]


def _plan(experiment: Experiment, params: dict, seed: int):
    """Task configurations, their seeds ``[root, block]`` and their store keys."""
    configs = experiment.tasks(params)
    if not configs:
        raise ValueError(f"{experiment.name} has no tasks with parameters {params}")
    seeds = [[int(seed), int(cfg.get("block", i))] for i, cfg in enumerate(configs)]
    keys = [task_key(experiment.name, cfg, s) for cfg, s in zip(configs, seeds, strict=True)]
    return configs, seeds, keys


class _Run:
    """The tasks of one run: claims them, hands them to a backend, commits what finishes."""

    def __init__(self, experiment: Experiment, params: dict, seed: int, store: Store,
                 on_done: Callable[[int, int], None] | None):
        self.name, self.params, self.seed = experiment.name, params, seed
        self.store, self.on_done = store, on_done
        self.configs, self.seeds, self.keys = _plan(experiment, params, seed)
        stored = store.keys(experiment.name)
        self.remaining = {i for i, k in enumerate(self.keys) if k not in stored}
        self.claimant = Claimant.this_run()
        self.in_flight: dict[Hashable, int] = {}  # backend handle -> task, until committed

    def report(self) -> None:
        if self.on_done:
            self.on_done(len(self.keys) - len(self.remaining), len(self.keys))

    def execute(self, make_backend: Callable[[], _Backend]) -> None:
        """Record the run and compute its remaining tasks; on Ctrl-C or an error, commit
        what finished, stop the workers and release the claims first."""
        backend = None
        try:
            self.store.record_run(self.name, self.params, self.seed)
            self.report()
            if not self.remaining:
                return
            backend = make_backend()
            with _Heartbeat(self.store, self.claimant.id):
                self._loop(backend)
            backend.stop(now=False)
        except BaseException as exc:
            if backend is not None:
                for handle, outcome in backend.finished(list(self.in_flight)):
                    self._commit(handle, outcome, report=False)
                backend.stop(now=True)
            if isinstance(exc, KeyboardInterrupt):
                stored = len(self.store.keys(self.name) & set(self.keys))
                raise RunInterrupted(self.name, stored, len(self.keys)) from None
            raise
        finally:
            self.store.release(self.claimant.id)

    def _loop(self, backend: _Backend) -> None:
        fresh, held = deque(sorted(self.remaining)), []  # never tried; claimed by another run
        retry_at = 0.0
        while self.remaining:  # == fresh + held + in flight
            if not fresh and held and time.monotonic() >= retry_at:
                fresh.extend(held)
                held.clear()
                retry_at = time.monotonic() + POLL
            while fresh and len(self.in_flight) < backend.capacity:
                i = fresh.popleft()
                state = self.store.claim(self.keys[i], self.claimant)
                if state == "claimed":
                    job = (self.name, self.configs[i], self.seeds[i])
                    self.in_flight[backend.submit(i, job)] = i
                elif state == "held":
                    held.append(i)
                else:  # another run stored it
                    self.remaining.discard(i)
                    self.report()
            if self.in_flight:
                for handle, outcome in backend.wait(list(self.in_flight), POLL):
                    self._commit(handle, outcome)
            elif self.remaining:  # the rest is being computed by other runs
                time.sleep(POLL)
                self.report()

    def _commit(self, handle: Hashable, outcome: tuple[dict, float], *,
                report: bool = True) -> None:
        i = self.in_flight[handle]
        result, elapsed = outcome
        self.store.put(self.keys[i], self.name, self.configs[i], self.seeds[i], result, elapsed,
                       owner=self.claimant.id)
        del self.in_flight[handle]  # only now: execute() redoes an interrupted commit
        self.remaining.discard(i)
        if report:
            self.report()


class _Heartbeat:
    """Renews a run's claims every :data:`HEARTBEAT` seconds from a daemon thread."""

    def __init__(self, store: Store, owner: str):
        self._store, self._owner = store, owner
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._beat, name="switchest-heartbeat", daemon=True)

    def _beat(self) -> None:
        while not self._stop.wait(HEARTBEAT):
            try:
                self._store.heartbeat(self._owner)
            except sqlite3.OperationalError:  # store busy past its timeout: the next beat renews
                continue

    def __enter__(self) -> _Heartbeat:
        self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self._stop.set()
        self._thread.join()


class _Backend:
    """Where tasks run: ``submit`` a job, ``wait`` for some to finish, ``stop``."""

    capacity: int  # tasks in flight at once

    def submit(self, i: int, job: tuple) -> Hashable:
        raise NotImplementedError

    def wait(self, handles: list, timeout: float) -> list[tuple[Hashable, tuple[dict, float]]]:
        """``(handle, outcome)`` of tasks finished within ``timeout``; raises a task's error."""
        raise NotImplementedError

    def finished(self, handles: list) -> list[tuple[Hashable, tuple[dict, float]]]:
        """``(handle, outcome)`` of the tasks among ``handles`` that finished without error."""
        raise NotImplementedError

    def stop(self, *, now: bool) -> None:
        """Release the workers; ``now``: without waiting for running tasks."""


class _InProcess(_Backend):
    """Runs each task in this process when it is waited for."""

    capacity = 1

    def __init__(self):
        self._queued: dict[int, tuple] = {}
        self._last: dict[int, tuple[dict, float]] = {}

    def submit(self, i, job):
        self._queued[i] = job
        return i

    def wait(self, handles, timeout):
        (i,) = handles
        self._last = {i: execute_task(*self._queued.pop(i))}
        return list(self._last.items())

    def finished(self, handles):
        return [(i, self._last[i]) for i in handles if i in self._last]


class _Pool(_Backend):
    """A local process pool of ``size`` workers, all started at once."""

    def __init__(self, size: int):
        self.capacity = size
        self._pool = ProcessPoolExecutor(size, initializer=_init_worker,
                                         initargs=(os.getpid(), max(1, cores() // size)))
        # Start the workers now (a fork must not copy the heartbeat thread started next), with
        # every object of this process frozen: the garbage collector of a forked worker must
        # never close a SQLite connection it inherited (one the caller left unclosed, say), as
        # that close checkpoints the store from a stale view and corrupts it.
        gc.freeze()
        try:
            self._pool.submit(int).result()
        finally:
            gc.unfreeze()

    def submit(self, i, job):
        return self._pool.submit(execute_task, *job)

    def wait(self, handles, timeout):
        done, _ = wait(handles, timeout=timeout, return_when=FIRST_COMPLETED)
        return [(f, f.result()) for f in done]

    def finished(self, handles):
        return [(f, f.result()) for f in handles
                if f.done() and not f.cancelled() and f.exception() is None]

    def stop(self, *, now):
        if now:  # ProcessPoolExecutor names its workers only privately (terminate_workers: 3.14)
            for process in list((self._pool._processes or {}).values()):
                process.terminate()
        self._pool.shutdown(wait=not now, cancel_futures=True)


class _Dask(_Backend):
    """A Dask cluster; every claimed task is submitted at once and the scheduler spreads them."""

    capacity = sys.maxsize

    def __init__(self, address: str):
        from dask.distributed import Client

        host_port = _check_scheduler_address(address)
        try:
            if host_port is not None:  # refused or unknown: fail now, not after Dask's retries
                socket.create_connection(host_port, timeout=CONNECT_TIMEOUT).close()
            self._client = Client(address, timeout=CONNECT_TIMEOUT)
        except OSError as exc:
            raise ConnectionError(f"cannot reach the Dask scheduler at {address!r} "
                                  f"within {CONNECT_TIMEOUT:g} s: {exc}") from None
        except ValueError as exc:
            raise ValueError(f"scheduler {address!r} is not a usable Dask address: {exc}") from None

    def submit(self, i, job):
        return self._client.submit(execute_task, *job, pure=False)

    def wait(self, handles, timeout):
        from dask.distributed import wait as dask_wait

        try:
            done, _ = dask_wait(handles, timeout=timeout, return_when=FIRST_COMPLETED)
        except TimeoutError:
            return []
        return [(f, f.result()) for f in done]

    def finished(self, handles):
        return [(f, f.result()) for f in handles if f.status == "finished"]

    def stop(self, *, now):
        self._client.close()  # the scheduler forgets the tasks of a closed client


def _backend(scheduler: str | None, workers: int, tasks: int) -> _Backend:
    if scheduler is not None:
        return _Dask(scheduler)
    size = min(workers, tasks, cores())
    if size == 1:
        return _InProcess()
    return _Pool(size)


def _check_scheduler_address(address: str) -> tuple[str, int] | None:
    """Refuse a malformed Dask address; return ``(host, port)`` where it has them."""
    if not isinstance(address, str):
        raise TypeError(f"scheduler must be an address string, got {type(address).__name__}")
    try:
        from distributed.comm.addressing import parse_address, parse_host_port
    except ImportError as exc:  # pragma: no cover - depends on the optional extra
        raise ImportError("--scheduler needs Dask: pip install 'switchest[dask]'") from exc
    try:
        scheme, location = parse_address(address, strict=False)
        if scheme not in ("tcp", "tls", "ws", "wss"):
            return None  # inproc, ucx: no host:port to check here; Dask checks the rest
        host, port = parse_host_port(location)
    except ValueError as exc:
        raise ValueError(f"scheduler must be a Dask scheduler address such as tcp://host:8786, "
                         f"got {address!r} ({exc})") from None
    if not host or not 0 < port < 65536:
        raise ValueError(f"scheduler must be a Dask scheduler address such as tcp://host:8786, "
                         f"got {address!r} (host {host!r}, port {port})")
    return host, port


def _init_worker(parent: int, threads: int) -> None:
    """Set up a pool worker: ignore Ctrl-C, run the filters' compiled loops on ``threads``
    threads (the worker's share of the cores: :mod:`switchest.estimators.parallel`) and, on
    Linux, die with the process ``parent``.

    ``PR_SET_PDEATHSIG`` sends SIGKILL when the thread that started the worker ends,
    which is the one running the pool; if ``parent`` died before the request took
    effect, nothing would come, hence the check after it.
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    os.environ["SWITCHEST_THREADS"] = str(threads)
    if sys.platform.startswith("linux"):
        libc = ctypes.CDLL(None, use_errno=True)
        if libc.prctl(_PR_SET_PDEATHSIG, ctypes.c_ulong(signal.SIGKILL)) != 0:
            err = ctypes.get_errno()
            raise OSError(err, f"prctl(PR_SET_PDEATHSIG) failed: {os.strerror(err)}")
        if process_token(parent) is None:
            os._exit(1)
