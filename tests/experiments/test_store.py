"""The results store read-only (``switchest report``) and a corrupt stored result."""

import sqlite3

import pytest

from switchest.experiments import Store


def test_a_read_only_store_writes_nothing_and_refuses_what_is_not_a_store(tmp_path):
    """Issue 35: ``switchest report`` opened any SQLite file read-write, added its tables and
    switched it to WAL. Read-only, a store is read as it is; a foreign database, or a missing
    file, is refused by name."""
    path = tmp_path / "results.sqlite"
    Store(path).put("k1", "exp", {"a": 1}, [1], {"x": 2.0}, 0.5)
    before = path.read_bytes()
    store = Store(path, read_only=True)
    assert [t.result for t in store.tasks("exp")] == [{"x": 2.0}]
    assert path.read_bytes() == before
    other = tmp_path / "other.sqlite"
    con = sqlite3.connect(other)
    con.execute("CREATE TABLE photos (id INTEGER)")
    con.close()
    with pytest.raises(ValueError, match="is not a switchest results store"):
        Store(other, read_only=True)
    con = sqlite3.connect(other)
    assert [r[0] for r in con.execute("SELECT name FROM sqlite_master")] == ["photos"]
    assert con.execute("PRAGMA journal_mode").fetchone()[0] != "wal"
    con.close()
    with pytest.raises(ValueError, match="does not exist"):
        Store(tmp_path / "absent.sqlite", read_only=True)


def test_a_corrupt_result_names_the_store_and_the_task(tmp_path):
    path = tmp_path / "results.sqlite"
    Store(path).put("k1", "exp", {"a": 1}, [1], {"x": 2.0}, 0.5)
    con = sqlite3.connect(path)
    con.execute("UPDATE tasks SET result = '{broken' WHERE key = 'k1'")
    con.commit()
    con.close()
    with pytest.raises(ValueError, match=r"results\.sqlite: the stored result of task k1"):
        Store(path).tasks("exp")
