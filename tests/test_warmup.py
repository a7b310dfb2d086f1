"""Warming the compiled kernels: after it, a new process loads every kernel from numba's on-disk
cache and compiles nothing; a compile is announced once, a load never."""

import concurrent.futures
import json
import os
import subprocess
import sys

import pytest
from numba import njit

from switchest.estimators._compiled import warmup

# In a fresh process: warm up, then report every kernel of the compiled engine numba holds a
# signature of, with its cache hits and misses (numba's own account of loading and compiling).
_FRESH_PROCESS = """
import json, sys
from numba.core.dispatcher import Dispatcher
from switchest.estimators._compiled import warmup

compiled = warmup.warm_up()
kernels = {
    f"{name}.{attr}": [sum(value.stats.cache_hits.values()),
                       sum(value.stats.cache_misses.values())]
    for name, module in list(sys.modules.items())
    if name.startswith("switchest.estimators._compiled.")
    for attr, value in vars(module).items()
    if isinstance(value, Dispatcher) and value.signatures
}
print(json.dumps({"compiled": compiled, "kernels": kernels}))
"""


def test_after_warm_up_a_new_process_loads_every_kernel_from_the_cache():
    warmup.warm_up()  # compiles what the cache lacks (minutes after install), else loads
    done = subprocess.run([sys.executable, "-c", _FRESH_PROCESS], capture_output=True,
                          text=True, check=True)
    report = json.loads(done.stdout)
    kernels = report["kernels"]
    assert report["compiled"] is False, kernels
    assert kernels and all(hits >= 1 and misses == 0 for hits, misses in kernels.values()), kernels


def test_a_compile_is_announced_once_and_a_compiled_function_not_at_all():
    @njit  # no on-disk cache: compiled in this process
    def double(x):
        return 2.0 * x

    @njit
    def triple(x):
        return 3.0 * x

    heard = []
    with warmup.on_first_compile(lambda: heard.append("first block")) as first:
        double(1.0)
        triple(1.0)
    with warmup.on_first_compile(lambda: heard.append("second block")) as second:
        double(2.0)  # compiled for float64 already
    assert heard == ["first block"]
    assert first.heard and first.seconds > 0.0
    assert not second.heard and second.seconds == 0.0


def test_warm_up_runs_what_kernel_modules_register_and_says_whether_it_compiled(monkeypatch):
    @njit
    def kernel(x):
        return x + 1.0

    calls = []
    monkeypatch.setattr(warmup, "_WARM_UPS", [])
    warmup.register(lambda: calls.append(kernel(1.0)))
    assert warmup.warm_up() is True
    assert warmup.warm_up() is False
    assert calls == [2.0, 2.0]


# Warm-ups that leave a mark of the process that ran them, for the tests below (worker processes
# find them by module and name, as they find the kernel modules' warm-ups).
_MARKS = []


def _mark_a():
    (_MARKS[0] / f"a-{os.getpid()}").touch()


def _mark_b():
    (_MARKS[0] / f"b-{os.getpid()}").touch()


@pytest.fixture
def fresh_cache_on_two_cores(tmp_path, monkeypatch):
    """The marking warm-ups registered, as if this process had just started its cache afresh
    on two cores; returns the folder of the marks."""
    monkeypatch.setattr(warmup, "_WARM_UPS", [_mark_a, _mark_b])
    monkeypatch.setattr(warmup, "_APART_DONE", [])
    monkeypatch.setattr(warmup, "started_afresh", lambda: True)
    monkeypatch.setattr(warmup, "cores", lambda: 2)
    monkeypatch.setattr(sys.modules[__name__], "_MARKS", [tmp_path])
    return tmp_path


def test_a_fresh_cache_is_compiled_by_worker_processes_once_then_loaded_here(
        fresh_cache_on_two_cores):
    marks_dir = fresh_cache_on_two_cores
    assert warmup.warm_up() is True  # the workers' compile is heard here
    here = os.getpid()
    marks = sorted(p.name for p in marks_dir.iterdir())
    assert f"a-{here}" in marks and f"b-{here}" in marks  # then loaded (here: run) in this one
    workers = {int(name.split("-")[1]) for name in marks} - {here}
    assert len(marks) == 4 and 1 <= len(workers) <= 2, marks
    for mark in marks_dir.iterdir():
        mark.unlink()
    assert warmup.warm_up() is False  # once per process: now every warm-up runs here only
    assert sorted(p.name for p in marks_dir.iterdir()) == [f"a-{here}", f"b-{here}"]


def test_without_worker_processes_the_warm_ups_run_here(fresh_cache_on_two_cores, monkeypatch):
    def no_processes(*args, **kwargs):
        raise OSError("no processes may be started here")

    monkeypatch.setattr(concurrent.futures, "ProcessPoolExecutor", no_processes)
    warmup.warm_up()
    here = os.getpid()
    assert sorted(p.name for p in fresh_cache_on_two_cores.iterdir()) == [f"a-{here}",
                                                                          f"b-{here}"]
