"""The SQLite results store: one row per finished task, committed the moment it ends.

A task is identified by a key hashed from the experiment name, its full
configuration and its seed; a re-run skips every key already stored, so an
interrupted sweep (Ctrl-C, ``kill -9``, a lost worker) resumes where it stopped
and loses nothing committed. The database runs in WAL mode with a busy timeout,
and rows are written with ``INSERT OR IGNORE`` in their own transaction, so two
runs writing to one store neither corrupt it nor duplicate a task.

Runs sharing a store also share the work: a run *claims* a task (:meth:`Store.claim`)
before computing it and leaves tasks that another live run has claimed; the claim
of a run that died is taken over. Stores written by earlier versions (no ``claims``
table, an integer ``runs.seed``) are brought up to this schema when opened.
"""

from __future__ import annotations

import hashlib
import json
import os
import socket
import sqlite3
import sys
import time
import uuid
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

__all__ = ["Claimant", "Store", "StoredTask", "task_key", "LEASE"]

LEASE = 60.0
"""Seconds without a heartbeat after which a claim is void whatever its host (runners beat
every few seconds, see ``runner.HEARTBEAT``); on the claimant's own host a dead process is
noticed at once. Clocks of hosts sharing a store must agree to well within this."""

_SCHEMA = """
CREATE TABLE IF NOT EXISTS tasks (
    key         TEXT PRIMARY KEY,
    experiment  TEXT NOT NULL,
    config      TEXT NOT NULL,
    seed        TEXT NOT NULL,
    result      TEXT NOT NULL,
    elapsed     REAL NOT NULL,
    finished    REAL NOT NULL,
    host        TEXT NOT NULL,
    owner       TEXT
);
CREATE INDEX IF NOT EXISTS tasks_by_experiment ON tasks (experiment);
CREATE TABLE IF NOT EXISTS runs (
    experiment  TEXT NOT NULL,
    params      TEXT NOT NULL,
    seed        TEXT NOT NULL,
    started     REAL NOT NULL
);
CREATE TABLE IF NOT EXISTS claims (
    key         TEXT PRIMARY KEY,
    owner       TEXT NOT NULL,
    host        TEXT NOT NULL,
    pid         INTEGER NOT NULL,
    process     TEXT NOT NULL,
    heartbeat   REAL NOT NULL
);
"""

# runs.seed was INTEGER before seeds beyond 2**63 were allowed; TEXT affinity keeps the decimal
# digits of any seed (INTEGER affinity turns text too large for 64 bits into a lossy REAL)
_RUNS_WITH_TEXT_SEED = """
ALTER TABLE runs RENAME TO runs_integer_seed;
CREATE TABLE runs (experiment TEXT NOT NULL, params TEXT NOT NULL, seed TEXT NOT NULL,
                   started REAL NOT NULL);
INSERT INTO runs SELECT experiment, params, CAST(seed AS TEXT), started FROM runs_integer_seed;
DROP TABLE runs_integer_seed;
"""

# SQLite result codes that mean the file cannot serve as a store (not busy/locked: those wait)
_UNUSABLE = {
    sqlite3.SQLITE_CANTOPEN: "cannot be opened",
    sqlite3.SQLITE_NOTADB: "is not a SQLite database",
    sqlite3.SQLITE_CORRUPT: "is corrupt",
    sqlite3.SQLITE_READONLY: "is read-only",
    sqlite3.SQLITE_PERM: "may not be accessed",
    sqlite3.SQLITE_IOERR: "cannot be read or written",
    sqlite3.SQLITE_FULL: "cannot grow: the disk is full",
}


def task_key(experiment: str, config: dict, seed: list[int]) -> str:
    """A stable hash of what determines a task's result."""
    text = json.dumps({"experiment": experiment, "config": config, "seed": seed}, sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:32]


def process_token(pid: int) -> str | None:
    """What identifies the running process ``pid`` beyond its number; None if none runs.

    On Linux its start time (``/proc/PID/stat`` field 22), so that a pid reused by
    a new process does not pass for the old one; a zombie counts as ended. On other
    POSIX systems ``""`` for any running process. Windows offers no check here
    (``os.kill`` would end the process): ``""``, and the :data:`LEASE` alone decides.
    """
    if sys.platform.startswith("linux"):
        try:
            stat = Path(f"/proc/{pid}/stat").read_text()
        except OSError:
            return None
        fields = stat.rsplit(")", 1)[1].split()  # after "pid (comm)": field 3 (state) on
        return None if fields[0] in ("Z", "X") else fields[19]
    if os.name == "posix":
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return None
        except PermissionError:  # it exists, under another user
            pass
    return ""


@dataclass(frozen=True)
class Claimant:
    """A run that claims tasks: ``id`` unique to the run, and the process that runs it."""

    id: str
    host: str
    pid: int
    process: str

    @classmethod
    def this_run(cls) -> Claimant:
        """A new claimant for a run in this process."""
        pid, host = os.getpid(), socket.gethostname()
        return cls(f"{host}:{pid}:{uuid.uuid4().hex[:12]}", host, pid, process_token(pid) or "")

    def alive(self, heartbeat: float, now: float) -> bool:
        """Whether the run may still be computing: its lease holds and, on this host, its
        process is the one that claimed."""
        if now - heartbeat > LEASE:
            return False
        return self.host != socket.gethostname() or process_token(self.pid) == self.process


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
    """A results store at ``path`` (created on first use, parent folders included).

    With ``read_only`` (``switchest report``) the store must exist and hold switchest's
    tables; it is opened read-only: nothing is created, upgraded or switched to WAL.

    Raises
    ------
    ValueError
        If ``path`` is a folder, a file that is not a SQLite database, or a place
        where the store cannot be created or read; with ``read_only``, a missing file or a
        database without switchest's tables; the message names the path.
    """

    def __init__(self, path: str | Path, *, read_only: bool = False):
        self.path = Path(path)
        self.read_only = read_only
        if self.path.is_dir():
            raise ValueError(f"store {self.path} is a folder; expected a SQLite file such as "
                             f"{self.path / 'results.sqlite'}")
        if read_only:
            self._check_tables()
            return
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise ValueError(f"store {self.path}: its folder cannot be created "
                             f"({exc.strerror}: {exc.filename})") from None
        for attempt in range(100):  # switching to WAL takes no busy handler: retry while busy
            try:
                with self._connect() as con:
                    con.execute("PRAGMA journal_mode=WAL")
                    con.executescript(_SCHEMA)
                break
            except sqlite3.OperationalError:
                if attempt == 99:
                    raise
                time.sleep(0.05 * (1 + attempt % 10))
        self._upgrade()

    def _upgrade(self) -> None:
        """Bring a store written by an earlier version to this schema (no write if it is)."""
        def outdated(con: sqlite3.Connection) -> tuple[bool, bool]:
            tasks = {row[1] for row in con.execute("PRAGMA table_info(tasks)")}
            runs = {row[1]: row[2].upper() for row in con.execute("PRAGMA table_info(runs)")}
            return "owner" not in tasks, runs["seed"] != "TEXT"

        with self._connect() as con:
            if not any(outdated(con)):
                return
        with self._transaction() as con:  # check again under the lock: another run may have done it
            no_owner, integer_seed = outdated(con)
            if no_owner:
                con.execute("ALTER TABLE tasks ADD COLUMN owner TEXT")
            if integer_seed:
                for statement in filter(str.strip, _RUNS_WITH_TEXT_SEED.split(";")):
                    con.execute(statement)

    def _check_tables(self) -> None:
        """Refuse a missing file, or a database that lacks the tables a store reads."""
        if not self.path.is_file():
            raise ValueError(f"store {self.path} does not exist")
        with self._connect() as con:
            names = {row[0] for row in con.execute(
                "SELECT name FROM sqlite_master WHERE type = 'table'")}
        missing = sorted({"tasks", "runs"} - names)
        if missing:
            raise ValueError(f"store {self.path} is not a switchest results store (no table "
                             f"{', '.join(missing)}; it has {', '.join(sorted(names)) or 'none'})")

    @contextmanager
    def _connect(self) -> Iterator[sqlite3.Connection]:
        """A short-lived autocommit connection (``timeout``: SQLite's busy timeout), closed on exit.

        SQLite errors that mean the file cannot serve as a store become ``ValueError``
        naming the path; busy and locked errors pass through.
        """
        try:
            con = (sqlite3.connect(f"{self.path.resolve().as_uri()}?mode=ro", uri=True,
                                   timeout=60.0, isolation_level=None) if self.read_only else
                   sqlite3.connect(self.path, timeout=60.0, isolation_level=None))
            try:
                yield con
            finally:
                con.close()
        except sqlite3.DatabaseError as exc:
            problem = _UNUSABLE.get((getattr(exc, "sqlite_errorcode", None) or 0) & 0xFF)
            if problem is None:
                raise
            raise ValueError(f"store {self.path} {problem} "
                             f"({exc}, {exc.sqlite_errorname})") from exc

    @contextmanager
    def _transaction(self) -> Iterator[sqlite3.Connection]:
        """A connection inside one write transaction, committed on a normal exit
        (closing the connection on an exception rolls it back)."""
        with self._connect() as con:
            con.execute("BEGIN IMMEDIATE")
            yield con
            con.execute("COMMIT")

    def keys(self, experiment: str) -> set[str]:
        """Keys of the tasks of ``experiment`` already stored."""
        with self._connect() as con:
            rows = con.execute("SELECT key FROM tasks WHERE experiment = ?",
                               (experiment,)).fetchall()
        return {r[0] for r in rows}

    def put(self, key: str, experiment: str, config: dict, seed: list[int], result: dict,
            elapsed: float, *, owner: str | None = None) -> bool:
        """Commit one finished task, computed by run ``owner``, and drop its claim.

        Returns False if another run stored it first.
        """
        with self._transaction() as con:
            cur = con.execute(
                "INSERT OR IGNORE INTO tasks (key, experiment, config, seed, result, elapsed, "
                "finished, host, owner) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?)",
                (key, experiment, json.dumps(config, sort_keys=True), json.dumps(seed),
                 json.dumps(result), float(elapsed), time.time(), socket.gethostname(), owner),
            )
            con.execute("DELETE FROM claims WHERE key = ?", (key,))
        return cur.rowcount == 1

    def claim(self, key: str, claimant: Claimant) -> Literal["claimed", "stored", "held"]:
        """Claim task ``key`` for ``claimant`` before computing it.

        Returns
        -------
        str
            ``"stored"``: the task is in the store, nothing to compute; ``"claimed"``:
            ``claimant`` holds it now (it was free, already its own, or held by a run
            that is dead); ``"held"``: another live run is computing it. A holder is
            dead when its heartbeat is older than :data:`LEASE` or, on this host, when
            its process has ended.
        """
        with self._transaction() as con:
            if con.execute("SELECT 1 FROM tasks WHERE key = ?", (key,)).fetchone():
                return "stored"
            row = con.execute("SELECT owner, host, pid, process, heartbeat FROM claims "
                              "WHERE key = ?", (key,)).fetchone()
            if row is not None and row[0] != claimant.id:
                holder, heartbeat = Claimant(*row[:4]), row[4]
                if holder.alive(heartbeat, time.time()):
                    return "held"
            con.execute("INSERT OR REPLACE INTO claims VALUES (?, ?, ?, ?, ?, ?)",
                        (key, claimant.id, claimant.host, claimant.pid, claimant.process,
                         time.time()))
        return "claimed"

    def heartbeat(self, owner: str) -> None:
        """Renew the claims of run ``owner`` (a run does so every few seconds)."""
        with self._connect() as con:
            con.execute("UPDATE claims SET heartbeat = ? WHERE owner = ?", (time.time(), owner))

    def release(self, owner: str) -> None:
        """Drop every claim of run ``owner`` (at its end, finished or not)."""
        with self._connect() as con:
            con.execute("DELETE FROM claims WHERE owner = ?", (owner,))

    def tasks(self, experiment: str) -> list[StoredTask]:
        """Every stored task of ``experiment``, in key order."""
        with self._connect() as con:
            rows = con.execute(
                "SELECT key, experiment, config, seed, result, elapsed, finished FROM tasks "
                "WHERE experiment = ? ORDER BY key", (experiment,)
            ).fetchall()
        return [StoredTask(k, e, *(self._decoded(k, name, text) for name, text in
                                   (("config", c), ("seed", s), ("result", r))), el, f)
                for k, e, c, s, r, el, f in rows]

    def _decoded(self, key: str, name: str, text: str):
        """The JSON ``text`` of task ``key``'s column ``name``, or a ValueError naming both
        and the store."""
        try:
            return json.loads(text)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"store {self.path}: the stored {name} of task {key} is corrupt "
                             f"({exc})") from None

    def record_run(self, experiment: str, params: dict, seed: int) -> None:
        """Remember that a run of ``experiment`` with ``params`` and ``seed`` started.

        The seed is kept as its decimal digits: any non-negative int, however large.
        """
        with self._connect() as con:
            con.execute("INSERT INTO runs VALUES (?, ?, ?, ?)",
                        (experiment, json.dumps(params, sort_keys=True), str(int(seed)),
                         time.time()))

    def latest_run(self, experiment: str) -> tuple[dict, int] | None:
        """Parameters and seed of the most recent run of ``experiment``, if any."""
        with self._connect() as con:
            row = con.execute("SELECT params, seed FROM runs WHERE experiment = ? "
                              "ORDER BY started DESC LIMIT 1", (experiment,)).fetchone()
        return None if row is None else (json.loads(row[0]), int(row[1]))

    def experiments(self) -> list[str]:
        """Names of the experiments that have been run into this store."""
        with self._connect() as con:
            rows = con.execute("SELECT DISTINCT experiment FROM runs "
                               "ORDER BY experiment").fetchall()
        return [r[0] for r in rows]
