"""The SQLite results store: one row per finished task, committed the moment it ends.

A task is identified by a key hashed from the experiment name, its full
configuration and its seed; a re-run skips every key already stored, so an
interrupted sweep (Ctrl-C, ``kill -9``, a lost worker) resumes where it stopped
and loses nothing committed. The database runs in WAL mode with a busy timeout,
and rows are written with ``INSERT OR IGNORE`` in their own transaction, so two
runs writing to one store neither corrupt it nor duplicate a task.
"""

from __future__ import annotations

import hashlib
import json
import socket
import sqlite3
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

__all__ = ["Store", "StoredTask", "task_key"]

_SCHEMA = """
CREATE TABLE IF NOT EXISTS tasks (
    key         TEXT PRIMARY KEY,
    experiment  TEXT NOT NULL,
    config      TEXT NOT NULL,
    seed        TEXT NOT NULL,
    result      TEXT NOT NULL,
    elapsed     REAL NOT NULL,
    finished    REAL NOT NULL,
    host        TEXT NOT NULL
);
CREATE INDEX IF NOT EXISTS tasks_by_experiment ON tasks (experiment);
CREATE TABLE IF NOT EXISTS runs (
    experiment  TEXT NOT NULL,
    params      TEXT NOT NULL,
    seed        INTEGER NOT NULL,
    started     REAL NOT NULL
);
"""


def task_key(experiment: str, config: dict, seed: list[int]) -> str:
    """A stable hash of what determines a task's result."""
    text = json.dumps({"experiment": experiment, "config": config, "seed": seed}, sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:32]


@dataclass(frozen=True)
class StoredTask:
    """One finished task as stored."""

    key: str
    experiment: str
    config: dict
    seed: list[int]
    result: dict
    elapsed: float
    finished: float


class Store:
    """A results store at ``path`` (created on first use, parent folders included)."""

    def __init__(self, path: str | Path):
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        for attempt in range(100):  # switching to WAL takes no busy handler: retry while another run holds it
            try:
                with self._connect() as con:
                    con.execute("PRAGMA journal_mode=WAL")
                    con.executescript(_SCHEMA)
                break
            except sqlite3.OperationalError:
                if attempt == 99:
                    raise
                time.sleep(0.05 * (1 + attempt % 10))

    @contextmanager
    def _connect(self) -> Iterator[sqlite3.Connection]:
        """A short-lived autocommit connection (``timeout``: SQLite's busy timeout), closed on exit."""
        con = sqlite3.connect(self.path, timeout=60.0, isolation_level=None)
        try:
            yield con
        finally:
            con.close()

    def keys(self, experiment: str) -> set[str]:
        """Keys of the tasks of ``experiment`` already stored."""
        with self._connect() as con:
            rows = con.execute("SELECT key FROM tasks WHERE experiment = ?", (experiment,)).fetchall()
        return {r[0] for r in rows}

    def put(self, key: str, experiment: str, config: dict, seed: list[int], result: dict, elapsed: float) -> bool:
        """Commit one finished task; returns False if another run stored it first."""
        with self._connect() as con:
            cur = con.execute(
                "INSERT OR IGNORE INTO tasks VALUES (?, ?, ?, ?, ?, ?, ?, ?)",
                (key, experiment, json.dumps(config, sort_keys=True), json.dumps(seed),
                 json.dumps(result), float(elapsed), time.time(), socket.gethostname()),
            )
            return cur.rowcount == 1

    def tasks(self, experiment: str) -> list[StoredTask]:
        """Every stored task of ``experiment``, in key order."""
        with self._connect() as con:
            rows = con.execute(
                "SELECT key, experiment, config, seed, result, elapsed, finished FROM tasks "
                "WHERE experiment = ? ORDER BY key", (experiment,)
            ).fetchall()
        return [StoredTask(k, e, json.loads(c), json.loads(s), json.loads(r), el, f)
                for k, e, c, s, r, el, f in rows]

    def record_run(self, experiment: str, params: dict, seed: int) -> None:
        """Remember that a run of ``experiment`` with ``params`` and ``seed`` started."""
        with self._connect() as con:
            con.execute("INSERT INTO runs VALUES (?, ?, ?, ?)",
                        (experiment, json.dumps(params, sort_keys=True), int(seed), time.time()))

    def latest_run(self, experiment: str) -> tuple[dict, int] | None:
        """Parameters and seed of the most recent run of ``experiment``, if any."""
        with self._connect() as con:
            row = con.execute("SELECT params, seed FROM runs WHERE experiment = ? ORDER BY started DESC LIMIT 1",
                              (experiment,)).fetchone()
        return None if row is None else (json.loads(row[0]), int(row[1]))

    def experiments(self) -> list[str]:
        """Names of the experiments that have been run into this store."""
        with self._connect() as con:
            rows = con.execute("SELECT DISTINCT experiment FROM runs ORDER BY experiment").fetchall()
        return [r[0] for r in rows]
