"""Run an experiment's tasks in-process, on a local process pool or on a Dask cluster.

Every task is seeded from ``numpy.random.SeedSequence(seed, spawn_key=(block,))``
— its trial block, not its position in a queue — so results do not depend on
the number or kind of workers, and every configuration of an experiment sees
the same simulated data for a block. Each finished task is committed to the
store at once; tasks already in the store are skipped.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait

import numpy as np
from threadpoolctl import threadpool_limits

from .registry import Experiment, get
from .store import Store, task_key

__all__ = ["run_experiment", "execute_task", "stored_results"]


def execute_task(name: str, config: dict, seed: list[int]) -> tuple[dict, float]:
    """Run one task of experiment ``name`` (importable, so process and Dask workers can call it).

    BLAS is held to one thread: the tasks are the parallelism, and threaded BLAS
    on small matrices under contention is far slower than serial.
    """
    from . import EXPERIMENTS  # noqa: F401  (importing the package registers every experiment)

    experiment = get(name)
    rng = np.random.default_rng(np.random.SeedSequence(seed[0], spawn_key=tuple(seed[1:])))
    start = time.perf_counter()
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
        Where finished tasks are committed, one by one.
    seed : int
        Root seed.
    workers : int
        1 runs in this process; more use a local process pool of that size.
    scheduler : str, optional
        Address of a Dask scheduler (``tcp://host:8786``) to run the tasks on instead;
        needs the ``switchest[dask]`` extra.
    on_done : callable, optional
        ``on_done(finished, total)`` after each task (progress display).
    """
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be a non-negative int, got {seed!r}")
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ValueError(f"workers must be a positive int, got {workers!r}")
    configs, seeds, keys = _plan(experiment, params, seed)
    store.record_run(experiment.name, params, seed)
    stored = store.keys(experiment.name)
    todo = [i for i, k in enumerate(keys) if k not in stored]
    total, done = len(configs), len(configs) - len(todo)
    if on_done:
        on_done(done, total)

    def commit(i: int, outcome: tuple[dict, float]) -> None:
        nonlocal done
        result, elapsed = outcome
        store.put(keys[i], experiment.name, configs[i], seeds[i], result, elapsed)
        done += 1
        if on_done:
            on_done(done, total)

    jobs = [(experiment.name, configs[i], seeds[i]) for i in todo]
    if scheduler is not None:
        _run_dask(scheduler, todo, jobs, commit)
    elif workers == 1 or len(todo) <= 1:
        for i, job in zip(todo, jobs, strict=True):
            commit(i, execute_task(*job))
    else:
        _run_pool(workers, todo, jobs, commit)
    results, missing = stored_results(experiment, params, store, seed)
    if missing:
        raise RuntimeError(f"{missing} task(s) of {experiment.name} did not reach the store")
    return results


def stored_results(experiment: Experiment, params: dict, store: Store, seed: int = 0) -> tuple[list, int]:
    """The stored ``(config, result)`` pairs of a run, in task order, and how many are missing."""
    configs, _, keys = _plan(experiment, params, seed)
    by_key = {t.key: t.result for t in store.tasks(experiment.name)}
    found = [(cfg, by_key[k]) for cfg, k in zip(configs, keys, strict=True) if k in by_key]
    return found, len(configs) - len(found)


def _plan(experiment: Experiment, params: dict, seed: int):
    """Task configurations, their seeds ``[root, block]`` and their store keys."""
    configs = experiment.tasks(params)
    seeds = [[int(seed), int(cfg.get("block", i))] for i, cfg in enumerate(configs)]
    keys = [task_key(experiment.name, cfg, s) for cfg, s in zip(configs, seeds, strict=True)]
    return configs, seeds, keys


def _run_pool(workers: int, todo: list[int], jobs: list[tuple], commit) -> None:
    with ProcessPoolExecutor(max_workers=workers) as pool:
        pending: dict[Future, int] = {pool.submit(execute_task, *job): i for i, job in zip(todo, jobs, strict=True)}
        try:
            while pending:
                finished, _ = wait(pending, return_when=FIRST_COMPLETED)
                for fut in finished:
                    commit(pending.pop(fut), fut.result())
        except BaseException:
            for fut in pending:
                fut.cancel()
            raise


def _run_dask(address: str, todo: list[int], jobs: Iterable[tuple], commit) -> None:
    try:
        from dask.distributed import Client, as_completed
    except ImportError as exc:  # pragma: no cover - depends on the optional extra
        raise ImportError("--scheduler needs Dask: pip install 'switchest[dask]'") from exc
    with Client(address) as client:
        futures = {client.submit(execute_task, *job, pure=False): i for i, job in zip(todo, jobs, strict=True)}
        for fut in as_completed(futures):
            commit(futures[fut], fut.result())
