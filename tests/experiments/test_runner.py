"""The runner and store: worker-independent results, skipping what is stored, task layouts, claims,
validation of seeds, parameters, workers, store paths and scheduler addresses.

Interruption, SIGKILL and concurrent runs: test_runner_resilience.py.
"""

import json
import multiprocessing
import os
import re
import socket
import sqlite3
import subprocess
import sys
import time
from contextlib import closing
from pathlib import Path

import pytest
from stored_runs import assert_same_results, query

from switchest.experiments import Store, get, names, run_experiment, stored_results, write_report
from switchest.experiments import store as store_module
from switchest.experiments.registry import MAX_BLOCKS, Row
from switchest.experiments.runner import MAX_WORKERS, _plan, execute_task
from switchest.experiments.store import Claimant, task_key


def test_results_do_not_depend_on_the_workers(tmp_path):
    exp = get("shankar-vehicle")
    params = exp.params(quick=True, trials=12, block_size=4)
    one = run_experiment(exp, params, store=Store(tmp_path / "a.sqlite"), workers=1)
    two = run_experiment(exp, params, store=Store(tmp_path / "b.sqlite"), workers=2)
    assert_same_results(one, two)
    distributed = pytest.importorskip("dask.distributed")
    with distributed.LocalCluster(processes=False, n_workers=1, threads_per_worker=1,
                                  dashboard_address=None) as cluster:
        dask = run_experiment(exp, params, store=Store(tmp_path / "c.sqlite"),
                              scheduler=cluster.scheduler_address)
    assert_same_results(one, dask)


def test_stored_tasks_are_skipped(tmp_path):
    exp = get("shankar-vehicle")
    params = exp.params(quick=True, trials=8, block_size=4)
    store = Store(tmp_path / "s.sqlite")
    calls = []
    run_experiment(exp, params, store=store, on_done=lambda d, t: calls.append((d, t)))
    assert calls[0] == (0, len(exp.tasks(params))) and calls[-1][0] == calls[-1][1]
    first = {t.key: t.finished for t in store.tasks(exp.name)}
    again = []
    run_experiment(exp, params, store=store, on_done=lambda d, t: again.append((d, t)))
    assert again == [(len(first), len(first))]  # nothing recomputed
    assert {t.key: t.finished for t in store.tasks(exp.name)} == first


# small sizes of the experiments whose tasks run several variants on one simulated block
VARIANT_RUNS = {
    "shankar-table1": {"duration": 0.05},
    "shankar-vehicle": {},
    "bakeoff": {},
    "lee-detection": {"duration": 3.0, "noise_levels": [0.1], "over_bound": [0.3]},
    "wang-examples": {"horizon": 10},
    "wang-ieee5bus": {},
    "zhang-example1": {},
    "zhang-smartgrid": {},
    "etienne-sync": {},
    "etienne-async": {},
}


@pytest.mark.parametrize("name", sorted(VARIANT_RUNS))
def test_a_variant_gives_the_same_result_alone_as_beside_the_others(name):
    """A task simulates its block once and runs its variants on it: what it stores for a
    variant does not depend on the other variants (none draws from the block's generator
    or leaves state to the next), so a task of one variant on that block agrees."""
    exp = get(name)
    params = exp.params(quick=True, trials=2, block_size=2, **VARIANT_RUNS[name])
    cfg = next(c for c in exp.tasks(params) if "variants" in c)
    seed = [0, cfg["block"]]
    together, _ = execute_task(name, cfg, seed)
    for i in (0, len(cfg["variants"]) - 1):  # the first runs on a fresh block, the last after all
        alone, _ = execute_task(name, {**cfg, "variants": [cfg["variants"][i]]}, seed)
        assert_same_results([(cfg["variants"][i], alone["variants"][0])],
                            [(cfg["variants"][i], together["variants"][i])])


@pytest.mark.parametrize("name", [n for n in names() if "block_size" in get(n).defaults])
def test_every_configuration_runs_on_every_trial_once(name):
    """Blocks cover the trials, the last one the remainder (7 = 3 + 3 + 1; the bake-off once
    dropped it), and every configuration (variant) of an experiment runs on each block."""
    exp = get(name)
    trials = {}
    for task in exp.tasks(exp.params(trials=7, block_size=3)):
        if "trials" not in task:  # not a Monte Carlo task (a certificate, a search)
            continue
        for variant in task.get("variants", [{}]):
            # less the block's own entries: its index, size, variants and whether it is drawn
            cfg = {k: v for k, v in {**task, **variant}.items()
                   if k not in ("block", "trials", "variants", "example")}
            trials.setdefault(json.dumps(cfg, sort_keys=True), []).append(
                (task["block"], task["trials"]))
    assert trials and all(sorted(v) == [(0, 3), (1, 3), (2, 1)] for v in trials.values())


def test_tasks_of_an_earlier_layout_are_not_mixed_in(tmp_path):
    """A store written when every (method, block) was a task of its own holds keys that no task
    of the present layout (a block, all methods) has: a run recomputes, a summary ignores them."""
    exp = get("shankar-vehicle")
    params = exp.params(quick=True)
    store = Store(tmp_path / "s.sqlite")
    (cfg,) = [c for c in exp.tasks(params) if c["block"] == 0]
    common = {k: v for k, v in cfg.items() if k != "variants"}
    for variant in cfg["variants"]:
        old = {**common, **variant}  # the former task's configuration
        store.put(task_key(exp.name, old, [0, 0]), exp.name, old, [0, 0], {"sse": [0.0]}, 0.1)
    assert stored_results(exp, params, store) == ([], len(exp.tasks(params)))
    results = run_experiment(exp, params, store=store)
    assert all("variants" in res for _, res in results)


def test_report_shows_paper_and_measured_values(tmp_path):
    exp = get("shankar-lemma2")
    store = Store(tmp_path / "r.sqlite")
    run_experiment(exp, exp.params(quick=True), store=store)
    page = write_report(store, tmp_path).read_text()
    assert "Lemma 2" in page and "data:image/png;base64," in page
    assert "<th>paper</th>" in page and "largest actual/bound ratio" in page


def test_params_and_rows_validate():
    exp = get("shankar-table1")
    with pytest.raises(ValueError, match="has no parameter"):
        exp.params(bogus=3)
    with pytest.raises(ValueError, match="unknown experiment"):
        get("nope")
    with pytest.raises(ValueError, match="did you mean 'shankar-table1'"):
        get("shankar-table-1")
    assert Row("q", 2.0, 4.0).ratio == 0.5 and Row("q", 2.0).ratio is None
    with pytest.raises(ValueError, match="workers must be a positive int"):
        run_experiment(exp, exp.params(quick=True), store=None, workers=0)


def test_trial_counts_must_be_positive_ints_and_plans_bounded():
    exp = get("shankar-table1")
    for bad in (0, -3):  # once quietly the default 40 trials, or a 17-trial block
        with pytest.raises(ValueError, match=f"trials must be a positive int, got {bad}"):
            exp.params(quick=True, trials=bad)
    with pytest.raises(TypeError, match="trials must be an int, got float"):
        exp.params(trials=2.5)
    with pytest.raises(ValueError, match="block_size must be a positive int, got 0"):
        exp.params(block_size=0)
    with pytest.raises(ValueError, match=rf"trials=100000000 in blocks of block_size=10 makes "
                                         rf"10000000 blocks, more than the {MAX_BLOCKS} a run "
                                         "may plan"):
        exp.params(trials=10**8)  # once a hang while planning
    with pytest.raises(ValueError, match=f"blocks=1000000, more than the {MAX_BLOCKS}"):
        get("shankar-lemma2").params(blocks=10**6)
    assert exp.params(quick=True, trials=None)["trials"] == exp.quick["trials"]  # an unset option
    assert exp.params(trials=MAX_BLOCKS * 10)["trials"] == MAX_BLOCKS * 10  # the limit itself


def test_workers_are_bounded_and_the_pool_by_the_tasks_and_cores(tmp_path):
    exp = get("shankar-lemma2")
    params = exp.params(quick=True)  # 3 tasks
    for bad in (0, MAX_WORKERS + 1, 100_000, True, 2.0):
        with pytest.raises(ValueError, match=f"workers must be a positive int no larger than "
                                             f"{MAX_WORKERS}.*got {bad!r}"):
            run_experiment(exp, params, store=Store(tmp_path / "s.sqlite"), workers=bad)
    seen = []
    run_experiment(exp, params, store=Store(tmp_path / "p.sqlite"), workers=64,
                   on_done=lambda done, total: seen.append(len(multiprocessing.active_children())))
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    size = min(64, 3, cores)
    assert max(seen) == (size if size > 1 else 0)  # one core: in this process


def test_any_non_negative_seed_is_stored_losslessly(tmp_path):
    exp = get("shankar-lemma2")
    params = exp.params(quick=True)
    store = Store(tmp_path / "s.sqlite")
    big = 2**70 + 1  # overflowed SQLite's 64-bit integers; a REAL would round it
    results = run_experiment(exp, params, store=store, seed=big)
    assert store.latest_run(exp.name) == (params, big)
    assert {t.seed[0] for t in store.tasks(exp.name)} == {big}
    assert stored_results(exp, params, store, big) == (results, 0)
    assert query(store.path, "SELECT typeof(seed), seed FROM runs") == [("text", str(big))]
    for bad in (-1, 1.5, True):
        with pytest.raises(ValueError, match=f"seed must be a non-negative int, got {bad!r}"):
            run_experiment(exp, params, store=store, seed=bad)


# the store's tables before claims, owners and seeds as text
EARLIER_SCHEMA = """
CREATE TABLE tasks (key TEXT PRIMARY KEY, experiment TEXT NOT NULL, config TEXT NOT NULL,
                    seed TEXT NOT NULL, result TEXT NOT NULL, elapsed REAL NOT NULL,
                    finished REAL NOT NULL, host TEXT NOT NULL);
CREATE INDEX tasks_by_experiment ON tasks (experiment);
CREATE TABLE runs (experiment TEXT NOT NULL, params TEXT NOT NULL, seed INTEGER NOT NULL,
                   started REAL NOT NULL);
"""


def test_a_store_of_the_earlier_schema_keeps_working(tmp_path):
    exp = get("shankar-lemma2")
    params = exp.params(quick=True)
    new = Store(tmp_path / "new.sqlite")
    results = run_experiment(exp, params, store=new, seed=7)
    old = tmp_path / "old.sqlite"
    rows = query(new.path, "SELECT key, experiment, config, seed, result, elapsed, finished, host "
                           "FROM tasks ORDER BY key LIMIT 2")
    with closing(sqlite3.connect(old)) as con, con:
        con.executescript(EARLIER_SCHEMA)
        con.execute("INSERT INTO runs VALUES (?, ?, 7, 0.0)", (exp.name, json.dumps(params)))
        con.executemany("INSERT INTO tasks VALUES (?, ?, ?, ?, ?, ?, ?, ?)", rows)
    store = Store(old)
    assert store.latest_run(exp.name) == (params, 7)
    assert stored_results(exp, params, store, 7)[1] == 1
    calls = []
    resumed = run_experiment(exp, params, store=store, seed=7, on_done=lambda d, t: calls.append(d))
    assert calls == [2, 3]  # the two stored tasks skipped, the third computed
    assert_same_results(resumed, results)
    run_experiment(exp, params, store=store, seed=2**70 + 1)
    assert store.latest_run(exp.name) == (params, 2**70 + 1)  # lossless in the upgraded table


def test_claims_hold_while_their_run_lives_and_pass_on_when_it_dies(tmp_path, monkeypatch):
    store = Store(tmp_path / "s.sqlite")
    me, other = Claimant.this_run(), Claimant.this_run()  # two runs of this live process
    assert store.claim("a", me) == "claimed"
    assert store.claim("a", me) == "claimed"  # already its own
    assert store.claim("a", other) == "held"
    store.release(me.id)
    assert store.claim("a", other) == "claimed"
    ended = subprocess.Popen([sys.executable, "-c", "pass"])
    ended.wait()
    gone = Claimant("gone", me.host, ended.pid, "")
    reused = Claimant("reused", me.host, me.pid, "the start time of another process")
    for dead in (gone, reused):
        assert store.claim(dead.id, dead) == "claimed"
        assert store.claim(dead.id, me) == "claimed"  # taken over at once
    remote = Claimant("remote", "elsewhere.invalid", 1, "")  # alive until its lease ends
    assert store.claim("b", remote) == "claimed"
    assert store.claim("b", me) == "held"
    monkeypatch.setattr(store_module, "LEASE", 0.2)
    time.sleep(0.3)
    store.heartbeat(remote.id)
    assert store.claim("b", me) == "held"  # renewed in time
    time.sleep(0.3)
    assert store.claim("b", me) == "claimed"  # not renewed: expired
    assert store.put("b", "e", {}, [0, 0], {"x": 1.0}, 0.5, owner=me.id)
    assert store.claim("b", other) == "stored"
    assert query(store.path, "SELECT owner FROM tasks") == [(me.id,)]
    assert ("b",) not in query(store.path, "SELECT key FROM claims")


def test_a_run_waits_for_tasks_another_run_computes(tmp_path):
    exp = get("shankar-lemma2")
    params = exp.params(quick=True)
    configs, seeds, keys = _plan(exp, params, 0)
    store = Store(tmp_path / "s.sqlite")
    other = Claimant.this_run()  # alive: this process
    assert store.claim(keys[1], other) == "claimed"
    calls = []

    def on_done(done, total):
        calls.append(done)
        if calls.count(2) == 3:  # the run polls, reporting progress; the other run now stores
            store.put(keys[1], exp.name, configs[1], seeds[1],
                      *execute_task(exp.name, configs[1], seeds[1]), owner=other.id)

    results = run_experiment(exp, params, store=store, on_done=on_done)
    assert calls[:3] == [0, 1, 2] and calls.count(2) >= 3 and calls[-1] == 3
    owners = dict(query(store.path, "SELECT key, owner FROM tasks"))
    assert owners[keys[1]] == other.id and len(set(owners.values())) == 2  # not computed twice
    assert_same_results(results, run_experiment(exp, params, store=Store(tmp_path / "c.sqlite")))


def test_store_paths_that_cannot_hold_a_store_are_refused(tmp_path):
    with pytest.raises(ValueError, match=rf"store {re.escape(str(tmp_path))} is a folder"):
        Store(tmp_path)
    text = tmp_path / "notes.txt"
    text.write_text("not a database")
    with pytest.raises(ValueError, match="notes.txt is not a SQLite database"):
        Store(text)
    fake = tmp_path / "fake.sqlite"
    fake.write_bytes(b"SQLite format 3\x00" + b"\x13" * 5000)  # the header, then garbage
    with pytest.raises(ValueError, match="fake.sqlite is not a SQLite database"):
        Store(fake)
    with pytest.raises(ValueError, match="notes.txt/s.sqlite: its folder cannot be created"):
        Store(text / "s.sqlite")


def test_a_place_where_no_file_can_be_created_is_refused(tmp_path):
    if os.name == "posix" and os.geteuid() != 0:
        place = tmp_path / "locked"
        place.mkdir(mode=0o500)
    elif sys.platform.startswith("linux"):
        place = Path("/proc")  # root may write anywhere else
    else:
        pytest.skip("needs a folder this user cannot write to")
    where = re.escape(str(place / "s.sqlite"))
    with pytest.raises(ValueError, match=f"store {where} cannot be opened"):
        Store(place / "s.sqlite")


def test_scheduler_addresses_are_checked(tmp_path):
    pytest.importorskip("dask.distributed")
    exp = get("shankar-lemma2")
    params = exp.params(quick=True)
    store = Store(tmp_path / "s.sqlite")
    for bad in ("nonsense", "tcp://host:notaport", "tcp://localhost:99999", "tcp://:8786"):
        with pytest.raises(ValueError, match=f"scheduler must be a Dask scheduler address .*"
                                             f"got {re.escape(repr(bad))}"):
            run_experiment(exp, params, store=store, scheduler=bad)
    with pytest.raises(ValueError, match="scheduler 'http://localhost:8786' is not a usable"):
        run_experiment(exp, params, store=store, scheduler="http://localhost:8786")
    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        address = f"tcp://127.0.0.1:{s.getsockname()[1]}"
    with pytest.raises(ConnectionError, match=f"cannot reach the Dask scheduler at '{address}'"):
        run_experiment(exp, params, store=store, scheduler=address)
    assert store.tasks(exp.name) == []
