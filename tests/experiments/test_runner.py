"""The runner and store: worker-independent results, resumption after SIGKILL, shared stores."""

import os
import signal
import sqlite3
import subprocess
import sys
import time

import pytest

from switchest.experiments import Store, get, run_experiment, stored_results, write_report
from switchest.experiments.registry import Row


def without_timing(results):
    """Task results less their run time, the one entry that legitimately differs between runs."""
    return [(cfg, {k: v for k, v in res.items() if k != "elapsed"}) for cfg, res in results]


def rows(experiment, params, store, tmp_path):
    results, missing = stored_results(experiment, params, store)
    assert missing == 0
    return [(r.quantity, r.measured) for r in experiment.summarize(params, results, tmp_path).rows
            if r.unit]  # rows with a unit are measurements; the per-trial timings live in notes


def test_results_do_not_depend_on_the_workers(tmp_path):
    exp = get("shankar-vehicle")
    params = exp.params(quick=True, trials=12, block_size=4)
    one = run_experiment(exp, params, store=Store(tmp_path / "a.sqlite"), workers=1)
    two = run_experiment(exp, params, store=Store(tmp_path / "b.sqlite"), workers=2)
    assert without_timing(one) == without_timing(two)
    distributed = pytest.importorskip("dask.distributed")
    with distributed.LocalCluster(processes=False, n_workers=1, threads_per_worker=1,
                                  dashboard_address=None) as cluster:
        dask = run_experiment(exp, params, store=Store(tmp_path / "c.sqlite"), scheduler=cluster.scheduler_address)
    assert without_timing(one) == without_timing(dask)


def test_stored_tasks_are_skipped_and_blocks_share_data(tmp_path):
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
    # every method of one block saw the same trajectories: identical true-state examples
    examples = [r["example_truth"] for c, r in stored_results(exp, params, store)[0] if c["block"] == 0]
    assert len(examples) > 1 and all(e == examples[0] for e in examples)


def test_sigkill_midway_then_resume_equals_an_uninterrupted_run(tmp_path):
    store_path = tmp_path / "killed.sqlite"
    cmd = [sys.executable, "-m", "switchest", "run", "shankar-table1", "--quick", "--trials", "2",
           "--workers", "1", "--store", str(store_path), "--out", str(tmp_path / "out")]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            env={**os.environ, "PYTHONUNBUFFERED": "1"})
    deadline = time.time() + 120
    stored = 0
    while time.time() < deadline and proc.poll() is None:
        time.sleep(0.2)
        if store_path.exists():
            try:
                with sqlite3.connect(store_path, timeout=5) as con:
                    stored = con.execute("SELECT COUNT(*) FROM tasks").fetchone()[0]
            except sqlite3.OperationalError:
                continue
            if stored >= 2:
                break
    assert proc.poll() is None, "the run finished before it could be killed"
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    exp = get("shankar-table1")
    params = exp.params(quick=True, trials=2)
    store = Store(store_path)
    before = {t.key: t.finished for t in store.tasks(exp.name)}
    assert 2 <= len(before) < len(exp.tasks(params))
    run_experiment(exp, params, store=store)
    after = {t.key: t.finished for t in store.tasks(exp.name)}
    assert all(after[k] == v for k, v in before.items())  # committed tasks were not recomputed
    assert len(after) == len(exp.tasks(params))
    clean = Store(tmp_path / "clean.sqlite")
    run_experiment(exp, params, store=clean)
    assert rows(exp, params, store, tmp_path) == rows(exp, params, clean, tmp_path)


def test_two_runs_writing_one_store(tmp_path):
    store_path = tmp_path / "shared.sqlite"
    cmd = [sys.executable, "-m", "switchest", "run", "shankar-vehicle", "--quick", "--workers", "1",
           "--store", str(store_path), "--out", str(tmp_path / "out")]
    procs = [subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE) for _ in range(2)]
    for p in procs:
        assert p.wait(timeout=300) == 0, p.stderr.read().decode()
    exp = get("shankar-vehicle")
    params = exp.params(quick=True)
    with sqlite3.connect(store_path) as con:
        assert con.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
        count = con.execute("SELECT COUNT(*) FROM tasks").fetchone()[0]
    assert count == len(exp.tasks(params))  # each task once
    assert stored_results(exp, params, Store(store_path))[1] == 0


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
    assert Row("q", 2.0, 4.0).ratio == 0.5 and Row("q", 2.0).ratio is None
    with pytest.raises(ValueError, match="workers must be a positive int"):
        run_experiment(exp, exp.params(quick=True), store=None, workers=0)
