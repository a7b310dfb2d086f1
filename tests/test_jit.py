"""The compiled-function cache is emptied when the sources compiled code is built from change."""

from switchest import _jit


def _fill(folder, stamp):
    folder.mkdir(exist_ok=True)
    for name in ("bank.filter_bank-65.py311.nbi", "bank.filter_bank-65.py311.1.nbc"):
        (folder / name).write_bytes(b"cached")
    (folder / "keep.txt").write_text("not numba's")
    if stamp is not None:
        (folder / _jit._STAMP).write_text(stamp)


def test_a_cache_of_other_sources_is_emptied_and_stamped(tmp_path, monkeypatch):
    monkeypatch.setattr(_jit, "_AFRESH", set())
    _fill(tmp_path / "c", stamp="0" * 64)
    _jit._refresh.__wrapped__(str(tmp_path / "c"))
    assert sorted(p.name for p in (tmp_path / "c").iterdir()) == sorted([_jit._STAMP, "keep.txt"])
    assert (tmp_path / "c" / _jit._STAMP).read_text() == _jit._digest()
    assert _jit.started_afresh() and _jit._AFRESH == {str(tmp_path / "c")}


def test_an_unstamped_cache_is_emptied(tmp_path):
    _fill(tmp_path / "c", stamp=None)
    _jit._refresh.__wrapped__(str(tmp_path / "c"))
    assert not list((tmp_path / "c").glob("*.nb*"))


def test_a_cache_of_these_sources_is_kept(tmp_path, monkeypatch):
    monkeypatch.setattr(_jit, "_AFRESH", set())
    _fill(tmp_path / "c", stamp=_jit._digest())
    _jit._refresh.__wrapped__(str(tmp_path / "c"))
    assert len(list((tmp_path / "c").glob("*.nb*"))) == 2
    assert not _jit.started_afresh()


def test_the_digest_covers_every_file_that_compiles():
    covered = {p for pattern in _jit._SOURCES for p in _jit._PACKAGE.glob(pattern)}
    compiling = {p for p in _jit._PACKAGE.rglob("*.py")
                 if any(s in p.read_text() for s in ("from numba", "import numba", "_jit import"))}
    assert compiling <= covered, sorted(str(p) for p in compiling - covered)
    assert len(_jit._digest()) == 64
