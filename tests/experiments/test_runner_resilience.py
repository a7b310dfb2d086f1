"""The runner under Ctrl-C, SIGKILL and a second run on the same store."""

import gc
import json
import multiprocessing
import os
import signal
import sys
import time
from pathlib import Path

import pytest
from stored_runs import assert_same_results, count_tasks, query, start_child, wait_until_stored

from switchest.experiments import RunInterrupted, Store, get, run_experiment, runner, stored_results

LINUX = sys.platform.startswith("linux")
CORES = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
VEHICLE_RUN = {"trials": 8000, "block_size": 1000}  # shankar-vehicle: 8 tasks of about 0.3 s


def claims(store_path):
    return query(store_path, "SELECT COUNT(*) FROM claims")[0][0]


def children(pid):
    """Pids of the live processes whose parent is ``pid`` (Linux /proc)."""
    found = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(fields[1]) == pid and fields[0] not in ("Z", "X"):
                found.append(int(entry.name))
    return found


def running(pid):
    """Whether ``pid`` runs (Linux /proc; a zombie has ended)."""
    try:
        return (Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]) not in "ZX"
    except OSError:
        return False


def interrupt_after(n):
    """An ``on_done`` that presses Ctrl-C once ``n`` tasks are done."""
    def on_done(done, total):
        if done >= n:
            raise KeyboardInterrupt
    return on_done


@pytest.mark.parametrize("where", ["in-process", "pool", "dask"])
def test_ctrl_c_commits_what_finished_and_says_how_much_is_stored(tmp_path, where):
    exp = get("shankar-lemma2")
    params = exp.params(quick=True)  # 3 tasks of a fraction of a second
    store = Store(tmp_path / "s.sqlite")
    options = {"workers": 2 if where == "pool" else 1}
    if where == "dask":
        distributed = pytest.importorskip("dask.distributed")
        cluster = distributed.LocalCluster(processes=False, n_workers=1, threads_per_worker=1,
                                           dashboard_address=None)
        options["scheduler"] = cluster.scheduler_address
    try:
        with pytest.raises(RunInterrupted, match="shankar-lemma2 interrupted: .* of 3") as info:
            run_experiment(exp, params, store=store, on_done=interrupt_after(1), **options)
    finally:
        if where == "dask":
            cluster.close()
    stored = len(store.tasks(exp.name))
    assert (info.value.experiment, info.value.stored, info.value.total) == (exp.name, stored, 3)
    assert 1 <= stored < 3  # the first, and any that finished beside it
    assert claims(store.path) == 0  # released for other runs
    resumed = run_experiment(exp, params, store=store)
    clean = run_experiment(exp, params, store=Store(tmp_path / "clean.sqlite"))
    assert_same_results(resumed, clean)


@pytest.mark.skipif(not LINUX or CORES < 2, reason="reads /proc; needs a pool of 2")
def test_sigint_to_the_process_group_stops_a_pool_run_at_once(tmp_path):
    store = tmp_path / "s.sqlite"
    # 8 tasks of about 4 s on 2 workers: a runner that waited for its running tasks would take
    # seconds longer to stop than the bound below
    proc = start_child(store, "wang-ieee5bus", {"trials": 3200, "block_size": 400}, workers=2)
    wait_until_stored(proc, store, 1)
    workers = children(proc.pid)
    assert len(workers) >= 2
    sent = time.time()
    os.killpg(proc.pid, signal.SIGINT)  # what a terminal's Ctrl-C does
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err.decode()
    report = json.loads(out)
    assert report["caught"] - sent < 2.0  # stopped, with the store up to date, within 2 s
    stored = count_tasks(store)
    assert (report["stored"], report["total"]) == (stored, 8)
    assert 1 <= stored < 8
    assert "Traceback" not in err.decode() and "KeyboardInterrupt" not in err.decode()
    assert not [pid for pid in workers if running(pid)]
    assert claims(store) == 0


@pytest.fixture(scope="module")
def killed(tmp_path_factory):
    """A pool run of shankar-vehicle (8 tasks of about 0.3 s) killed with SIGKILL midway:
    ``(store path, pids of its workers where /proc shows them, tasks stored)``."""
    store = tmp_path_factory.mktemp("killed") / "s.sqlite"
    proc = start_child(store, "shankar-vehicle", VEHICLE_RUN, workers=2)
    wait_until_stored(proc, store, 4)
    workers = children(proc.pid) if LINUX and CORES >= 2 else []
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    return store, workers, count_tasks(store)


@pytest.mark.skipif(not LINUX or CORES < 2, reason="PR_SET_PDEATHSIG is Linux's; needs a pool of 2")
def test_pool_workers_die_with_their_killed_parent(killed):
    _, workers, _ = killed
    assert len(workers) >= 2
    deadline = time.monotonic() + 5
    while any(running(pid) for pid in workers) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not [pid for pid in workers if running(pid)]


def test_resuming_a_killed_run_equals_an_uninterrupted_run(killed, tmp_path):
    store_path, _, stored = killed
    exp = get("shankar-vehicle")
    params = exp.params(quick=True, **VEHICLE_RUN)
    store = Store(store_path)
    before = {t.key: t.finished for t in store.tasks(exp.name)}
    assert 4 <= stored == len(before) < 8
    start = time.monotonic()
    resumed = run_experiment(exp, params, store=store, workers=2)
    # the dead run's claims were taken over at once, not waited on for store.LEASE = 60 s
    assert time.monotonic() - start < 30
    after = {t.key: t.finished for t in store.tasks(exp.name)}
    assert all(after[k] == v for k, v in before.items())  # committed tasks were not recomputed
    assert len(after) == 8 and claims(store_path) == 0  # every task once, no claim left
    clean = run_experiment(exp, params, store=Store(tmp_path / "clean.sqlite"), workers=2)
    assert_same_results(resumed, clean)


def test_two_runs_on_one_store_share_the_work(tmp_path):
    exp = get("shankar-vehicle")
    params = exp.params(quick=True, **VEHICLE_RUN)
    store_path, go = tmp_path / "shared.sqlite", tmp_path / "go"
    Store(store_path)  # created before the runs start, as a shared store would be
    logs = [tmp_path / f"computed{i}" for i in range(2)]
    procs = [start_child(store_path, exp.name, VEHICLE_RUN, workers=1, log=str(log),
                         ready=str(tmp_path / f"ready{i}"), go=str(go))
             for i, log in enumerate(logs)]
    deadline = time.monotonic() + 120
    while not all((tmp_path / f"ready{i}").exists() for i in range(2)):
        assert time.monotonic() < deadline and all(p.poll() is None for p in procs)
        time.sleep(0.05)
    go.touch()  # both start computing together
    for p in procs:
        assert p.wait(timeout=120) == 0, p.stderr.read().decode()
    computed = [log.read_text().split() for log in logs]
    keys = {t.key for t in Store(store_path).tasks(exp.name)}
    assert all(computed)  # both worked ...
    assert sorted(computed[0] + computed[1]) == sorted(keys)  # ... on different tasks, each once
    assert len(keys) == 8 and claims(store_path) == 0
    assert query(store_path, "PRAGMA integrity_check") == [("ok",)]
    by_owner = dict(query(store_path, "SELECT owner, COUNT(*) FROM tasks GROUP BY owner"))
    assert sorted(by_owner.values()) == sorted(len(c) for c in computed)
    shared, missing = stored_results(exp, params, Store(store_path))
    assert missing == 0
    one = run_experiment(exp, params, store=Store(tmp_path / "one.sqlite"), workers=2)
    assert_same_results(shared, one)


class Finalized:
    """Garbage (a reference cycle) that marks ``folder`` with the pid that finalizes it."""

    def __init__(self, folder):
        self.folder, self.cycle = folder, self

    def __del__(self):
        (self.folder / str(os.getpid())).touch()


@pytest.mark.skipif(multiprocessing.get_start_method() != "fork" or CORES < 2,
                    reason="only a forked pool of 2 inherits this process's objects")
def test_forked_workers_never_finalize_what_they_inherit(tmp_path, monkeypatch):
    # An unclosed sqlite3 connection is such garbage (its statement cache refers back to it):
    # closed by a worker's collector, it checkpointed the store from a stale view and corrupted it.
    marks = tmp_path / "marks"
    marks.mkdir()
    original = runner._init_worker

    def collecting(*args):  # a worker whose collector runs at once
        original(*args)
        gc.collect()

    monkeypatch.setattr(runner, "_init_worker", collecting)
    exp = get("shankar-lemma2")
    gc.disable()  # so that only a collection this test asks for finalizes the garbage
    try:
        Finalized(marks)
        run_experiment(exp, exp.params(quick=True), store=Store(tmp_path / "s.sqlite"), workers=2)
        gc.collect()
    finally:
        gc.enable()
    assert [p.name for p in marks.iterdir()] == [str(os.getpid())]  # here, never in a worker
