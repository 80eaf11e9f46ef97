"""`grader cache info` and `grader cache prune` on a cache the test fills, the size cap's least
recently used order, and the locks that keep a running batch's entries out of a prune's reach."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from grader.cache import locks, store
from grader.cache.locks import Holds, use_lock
from grader.cli import main as grader_main
from grader.grading.reuse import RecordingCache

DAY = 86400.0


def _build(cache: Path, name: str, size: int, used: float, made: float | None = None) -> Path:
    area = cache / name
    (area / "install").mkdir(parents=True)
    (area / "install" / "blob").write_bytes(os.urandom(size))
    (area / "result.json").write_text("{}")
    os.utime(area / "result.json", (made or used, made or used))
    use_lock(area).touch()
    os.utime(use_lock(area), (used, used))
    return area


def _recording(cache: Path, key: str, size: int, used: float) -> Path:
    entry = cache / "recordings" / key
    (entry / "bag").mkdir(parents=True)
    (entry / "bag" / "x.mcap").write_bytes(os.urandom(size))
    (entry / "source.json").write_text(json.dumps({"submission": "s", "key": key}))
    os.utime(entry / "source.json", (used, used))
    lock = cache / "recordings" / f"{key}.lock"
    lock.touch()
    os.utime(lock, (used, used))
    return entry


@pytest.fixture
def filled(tmp_path: Path) -> Path:
    """Two build areas (one a support build), three recordings, stale and live temporary files;
    used 30, 20, 10, 5, 3 and 1 days ago."""
    cache = tmp_path / "cache"
    now = time.time()
    _build(cache, "a" * 20, 400_000, now - 30 * DAY)
    support = _build(cache, "b" * 20, 300_000, now - 5 * DAY, made=now - 40 * DAY)
    (cache / "packages").mkdir()
    (cache / "packages" / "k1.json").write_text(json.dumps({"name": "ifaces", "root": str(support), "trusted": True}))
    (cache / "packages" / "k2.json").write_text(json.dumps({"name": "gone", "root": str(cache / "gone"), "trusted": True}))
    _recording(cache, "r1", 200_000, now - 20 * DAY)
    _recording(cache, "r2", 200_000, now - 10 * DAY)
    _recording(cache, "r3", 200_000, now - 1 * DAY)
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True,
                          text=True).stdout.strip()
    (cache / f".staging-{dead}-1" / "src").mkdir(parents=True)            # a killed grader's
    (cache / f".staging-{os.getpid()}-2").mkdir()                         # a running one's
    (cache / "cccc.lock").touch()                                          # a lock without its entry
    return cache


def test_info_counts_each_kind(filled: Path, capsys) -> None:
    doc = store.info(filled)
    kinds = doc["kinds"]
    assert {k: v["entries"] for k, v in kinds.items()} == {"build": 1, "support build": 1, "recording": 3,
                                                           "temporary": 2}
    assert 400_000 <= kinds["build"]["bytes"] < 480_000 and 600_000 <= kinds["recording"]["bytes"] < 700_000
    now = time.time()
    assert kinds["recording"]["oldest_use"] == pytest.approx(now - 20 * DAY, abs=60)
    assert kinds["recording"]["newest_use"] == pytest.approx(now - 1 * DAY, abs=60)
    assert grader_main(["cache", "info", "--cache-dir", str(filled)]) == 0
    out = capsys.readouterr().out
    assert "support build        1" in out and "recording            3" in out and "cap 5.0 GB" in out
    assert "last batch: none recorded" in out
    store.record_batch(filled, [{"builds_hit": 1, "builds_missed": 1, "recordings_hit": 3, "recordings_missed": 1,
                                 "packages_reused": 2}], None)
    assert grader_main(["cache", "info", "--cache-dir", str(filled), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["last_batch"]["recordings_hit"] == 3 and doc["entries"] == 7
    grader_main(["cache", "info", "--cache-dir", str(filled)])
    assert "recordings 3/4 (75%) reused" in capsys.readouterr().out


def test_prune_by_last_use_by_age_and_to_a_size(filled: Path, capsys) -> None:
    now = time.time()
    date = time.strftime("%Y-%m-%d", time.localtime(now - 15 * DAY))
    assert grader_main(["cache", "prune", "--unused-since", date, "--dry-run", "--cache-dir", str(filled)]) == 0
    assert "would remove 1 build, 1 recording, 1 temporary" in capsys.readouterr().out
    assert (filled / ("a" * 20)).is_dir()                                 # a dry run removes nothing
    assert grader_main(["cache", "prune", "--unused-since", date, "--cache-dir", str(filled)]) == 0
    assert not (filled / ("a" * 20)).exists() and not (filled / "recordings" / "r1").exists()
    assert not use_lock(filled / ("a" * 20)).exists() and not (filled / "recordings" / "r1.lock").exists()
    assert (filled / f".staging-{os.getpid()}-2").exists()                 # its process still runs
    assert not (filled / "cccc.lock").exists()                             # a lock of nothing goes
    assert not (filled / "packages" / "k2.json").exists() and (filled / "packages" / "k1.json").exists()
    # by age: made more than 35 days ago (the support build, though used 5 days ago)
    assert grader_main(["cache", "prune", "--older-than", "35d", "--cache-dir", str(filled)]) == 0
    assert not (filled / ("b" * 20)).exists() and not (filled / "packages" / "k1.json").exists()
    # to a size: the least recently used go first
    assert grader_main(["cache", "prune", "--max-size", "250k", "--cache-dir", str(filled)]) == 0
    assert not (filled / "recordings" / "r2").exists() and (filled / "recordings" / "r3").is_dir()
    assert store.info(filled)["total_bytes"] <= 250_000
    assert grader_main(["cache", "prune", "--all", "--cache-dir", str(filled)]) == 0
    assert [e.kind for e in store.entries(filled)] == ["temporary"]        # only the live one


def test_prune_needs_a_criterion(filled: Path, capsys) -> None:
    assert grader_main(["cache", "prune", "--cache-dir", str(filled)]) == 2
    assert "say what to prune" in capsys.readouterr().err
    assert grader_main(["cache", "prune", "--max-size", "lots", "--cache-dir", str(filled)]) == 2
    assert "cannot read 'lots' as a size" in capsys.readouterr().err


def test_held_entries_are_never_removed(filled: Path) -> None:
    """A build area a submission holds (its scenarios run its installs) and a recording being
    made or copied (its key's lock) stay, whatever the prune asks; released, they go."""
    area = filled / ("b" * 20)
    recordings = RecordingCache(filled / "recordings")
    inside, leave = threading.Event(), threading.Event()

    def recording_in_use() -> None:
        with recordings.locked("r3"):
            inside.set()
            leave.wait(30)

    worker = threading.Thread(target=recording_in_use)
    worker.start()
    assert inside.wait(30)
    with Holds() as holds:
        holds.hold(use_lock(area))
        done = store.prune(filled, everything=True)
        assert {e.path.name for e in done.busy} == {"b" * 20, "r3"}
        assert area.is_dir() and (filled / "recordings" / "r3").is_dir() and use_lock(area).exists()
        assert not (filled / ("a" * 20)).exists()
        # the cap at the end of a batch skips them too, and says so
        ended = store.end_batch(filled, [], "1")
        assert "held by running batches stay" in ended["message"] and area.is_dir()
    leave.set()
    worker.join()
    assert store.prune(filled, everything=True).busy == []
    assert not area.exists() and not (filled / "recordings" / "r3").exists()


def test_a_lock_unlinked_while_waited_for_is_taken_afresh(tmp_path: Path) -> None:
    """A prune unlinks the lock files of what it removes while holding them: a process that
    waited on the old file must not go on under a lock nobody else can see."""
    path = tmp_path / "x.lock"
    fd = locks.acquire(path)
    got: list[int] = []
    waiter = threading.Thread(target=lambda: got.append(locks.acquire(path)))
    waiter.start()
    time.sleep(0.3)
    path.unlink()               # what the prune does, holding the lock
    locks.release(fd)
    waiter.join(10)
    assert got and os.fstat(got[0]).st_ino == os.stat(path).st_ino
    assert locks.acquire(path, wait=False) is None            # and it does exclude others
    locks.release(got[0])


def test_last_use_survives_concurrent_batches(tmp_path: Path) -> None:
    """Two processes using entries of one cache at once each leave their entries' last use."""
    cache = tmp_path / "cache"
    old = time.time() - 10 * DAY
    areas = [_build(cache, f"{i:020d}", 1000, old) for i in range(6)]
    code = ("import sys; from pathlib import Path; from grader.cache.locks import Holds, use_lock\n"
            "with Holds() as h:\n    for p in sys.argv[1:]: h.hold(use_lock(Path(p)))\n")
    procs = [subprocess.Popen([sys.executable, "-c", code, *map(str, areas[i::2])]) for i in range(2)]
    assert [p.wait(60) for p in procs] == [0, 0]
    uses = {e.path.name: e.last_used for e in store.entries(cache)}
    assert all(uses[a.name] > time.time() - 120 for a in areas), uses


def test_sizes_are_read_like_people_write_them() -> None:
    assert store.parse_size("5G") == 5 * 10**9 and store.parse_size("500MB") == 5 * 10**8
    assert store.parse_size("1.5GiB") == int(1.5 * 2**30) and store.parse_size("0") == 0
    assert store.max_size("0") is None and store.max_size(None) == store.DEFAULT_MAX_SIZE
    with pytest.raises(Exception, match="cannot read 'big' as a size"):
        store.parse_size("big")


def test_the_cap_comes_from_the_environment(monkeypatch) -> None:
    monkeypatch.setenv(store.MAX_SIZE_ENV, "2G")
    assert store.max_size() == 2 * 10**9 and store.max_size("1G") == 10**9


def test_batches_in_threads_of_one_process_each_write_a_whole_last_batch(tmp_path: Path) -> None:
    # the Python API grades labs side by side in threads (tests/e2e/test_lab_fixtures.py): a
    # temporary file named by the process alone was renamed away under another thread
    # (FileNotFoundError in 13 tests when four of five labs had nothing to grade)
    start = threading.Barrier(8)
    errors: list[BaseException] = []

    def one(k: int) -> None:
        start.wait()
        try:
            for _ in range(50):
                store.record_batch(tmp_path, [{"builds_hit": k}], None)
        except BaseException as exc:  # noqa: BLE001 - collected for the assert
            errors.append(exc)

    threads = [threading.Thread(target=one, args=(k,)) for k in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors, errors[:1]
    assert json.loads((tmp_path / "last_batch.json").read_text())["submissions"] == 1
    assert not list(tmp_path.glob(".*.tmp"))
