"""Helpers for the runner's tests: child runs, store counts and result comparison."""

import json
import sqlite3
import subprocess
import sys
import time
from contextlib import closing
from pathlib import Path

import numpy as np

CHILD = Path(__file__).with_name("runner_child.py")


def start_child(store, name, overrides, *, workers, **extra):
    """``runner_child.py`` running ``name`` (quick, with ``overrides``) into ``store``,
    in a session of its own so that a signal can go to its whole process group."""
    spec = {"name": name, "overrides": overrides, "store": str(store), "workers": workers, **extra}
    return subprocess.Popen([sys.executable, str(CHILD), json.dumps(spec)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, start_new_session=True)


def count_tasks(store) -> int:
    """Rows in the store's task table (0 while it does not exist yet or is busy)."""
    try:
        with closing(sqlite3.connect(store, timeout=5)) as con:
            return con.execute("SELECT COUNT(*) FROM tasks").fetchone()[0]
    except sqlite3.OperationalError:
        return 0


def query(store, sql):
    """The rows of ``sql`` on ``store``, through a connection closed at once (an unclosed one
    lingers until the garbage collector finds it)."""
    with closing(sqlite3.connect(store, timeout=5)) as con:
        return con.execute(sql).fetchall()


def wait_until_stored(proc, store, n, timeout=120.0) -> int:
    """Poll until ``store`` holds ``n`` tasks; fail if ``proc`` ends or time runs out first."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        assert proc.poll() is None, f"the run ended early: {proc.stderr.read().decode()}"
        stored = count_tasks(store)
        if stored >= n:
            return stored
        time.sleep(0.05)
    raise AssertionError(f"{store} did not reach {n} tasks in {timeout} s")


def assert_same_results(a, b):
    """Equal task lists: the same configurations, and results equal to rounding.

    Run times (``elapsed``, at any depth: a task times each of its variants) are dropped.
    The same code on the same machine gives the same numbers, so any tolerance well below
    the statistics' own spread would do; rtol = 1e-12 leaves room only for a reordered
    floating-point sum.
    """
    assert [cfg for cfg, _ in a] == [cfg for cfg, _ in b]
    xs, ys = [], []
    for (cfg, x), (_, y) in zip(a, b, strict=True):
        _numbers(x, y, str(cfg), xs, ys)
    assert xs, "no numbers to compare"
    np.testing.assert_allclose(np.array(ys, dtype=float), np.array(xs, dtype=float),
                               rtol=1e-12, atol=0)


def _numbers(x, y, where, xs, ys):
    """Check that ``x`` and ``y`` have one structure and equal non-numbers; collect the numbers."""
    if isinstance(x, dict):
        assert isinstance(y, dict) and x.keys() == y.keys(), where
        for k in x.keys() - {"elapsed"}:
            _numbers(x[k], y[k], f"{where}[{k!r}]", xs, ys)
    elif isinstance(x, list):
        assert isinstance(y, list) and len(x) == len(y), where
        for i, (u, v) in enumerate(zip(x, y, strict=True)):
            _numbers(u, v, f"{where}[{i}]", xs, ys)
    elif isinstance(x, (int, float)) and not isinstance(x, bool):
        assert isinstance(y, (int, float)) and not isinstance(y, bool), where
        xs.append(x)
        ys.append(y)
    else:
        assert x == y, where
