from __future__ import annotations

import os
from pathlib import Path

import pytest

import ipcsim.atomic as atomic

from ipcsim.atomic import (
    atomic_open,
    atomic_path,
    atomic_write_bytes,
    atomic_write_text,
    is_temporary_name,
    sync_to_disk,
    temporary_path,
)


class Boom(Exception):
    pass


def test_write_bytes_and_text_replace_content(tmp_path):
    target = tmp_path / "a.bin"
    atomic_write_bytes(target, b"old")
    atomic_write_bytes(target, b"\x00new")
    assert target.read_bytes() == b"\x00new"
    text = tmp_path / "b.txt"
    atomic_write_text(text, "line 1\nline 2\n")
    assert text.read_bytes() == b"line 1\nline 2\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.bin", "b.txt"]


def test_temporary_name_is_hidden_in_same_folder(tmp_path):
    tmp = temporary_path(tmp_path / "frame_000001.vtu")
    assert tmp.parent == tmp_path
    assert tmp.name == f".frame_000001.vtu.tmp-{os.getpid()}"
    assert is_temporary_name(tmp.name)
    assert not is_temporary_name("frame_000001.vtu")
    assert not is_temporary_name(".hidden")
    assert not is_temporary_name(".x.tmp-abc")


@pytest.mark.parametrize("mode", ["w", "wb"])
def test_failing_writer_keeps_old_file_and_leaves_no_temporary(tmp_path, mode):
    target = tmp_path / "steps.csv"
    target.write_text("complete old content\n")
    with pytest.raises(Boom):
        with atomic_open(target, mode) as f:
            f.write("half of the new" if mode == "w" else b"half of the new")
            raise Boom
    assert target.read_text() == "complete old content\n"
    assert [p.name for p in tmp_path.iterdir()] == ["steps.csv"]


def test_failing_writer_creates_nothing_when_target_was_absent(tmp_path):
    target = tmp_path / "run.json"
    with pytest.raises(Boom):
        with atomic_path(target) as tmp:
            tmp.write_text("{")
            raise Boom
    assert list(tmp_path.iterdir()) == []


def test_atomic_path_for_a_writer_that_takes_a_file_name(tmp_path):
    target = tmp_path / "out.txt"
    target.write_text("old")
    with atomic_path(target) as tmp:
        assert tmp != target
        tmp.write_text("new")
        assert target.read_text() == "old"  # not visible until the block ends
    assert target.read_text() == "new"
    assert [p.name for p in tmp_path.iterdir()] == ["out.txt"]


def test_atomic_path_refuses_when_writer_wrote_nothing(tmp_path):
    target = tmp_path / "out.txt"
    target.write_text("old")
    with pytest.raises(FileNotFoundError):
        with atomic_path(target):
            pass
    assert target.read_text() == "old"


def test_atomic_open_rejects_append_mode(tmp_path):
    with pytest.raises(ValueError):
        with atomic_open(tmp_path / "x", "a"):
            pass


@pytest.mark.parametrize("syncfs_works", [True, False])
def test_sync_to_disk_uses_one_syncfs_for_many_files(tmp_path, monkeypatch, syncfs_works):
    """Many files go by one syncfs of their file system; a few, or many where syncfs
    is not there, by one fsync each (files gone since are skipped)."""
    calls = {"syncfs": [], "fsync": [], "folder": []}
    monkeypatch.setattr(atomic, "_syncfs",
                        lambda folders: calls["syncfs"].append(sorted(folders)) or syncfs_works)
    monkeypatch.setattr(atomic, "_fsync_file",
                        lambda path: calls["fsync"].append(os.path.basename(path)))
    monkeypatch.setattr(atomic, "_fsync_folder",
                        lambda folder: calls["folder"].append(Path(folder)))
    few = [atomic_write_bytes(tmp_path / f"few{i}", b"x", fsync=False)
           for i in range(atomic.SYNCFS_ABOVE)]
    sync_to_disk(few + [tmp_path / "gone"])
    assert calls["syncfs"] == [[str(tmp_path)]]  # nine paths: more than SYNCFS_ABOVE
    calls = {key: [] for key in calls}
    sync_to_disk(few)
    assert calls["syncfs"] == []
    assert calls["fsync"] == [path.name for path in few] and calls["folder"] == [tmp_path]
    calls = {key: [] for key in calls}
    many = few + [atomic_write_bytes(tmp_path / "one more", b"x", fsync=False)]
    sync_to_disk(many)
    assert calls["syncfs"] == [[str(tmp_path)]]
    assert calls["fsync"] == ([] if syncfs_works else [path.name for path in many])


def test_syncfs_of_a_real_folder(tmp_path):
    atomic_write_bytes(tmp_path / "a", b"data", fsync=False)
    expected = os.uname().sysname == "Linux"
    assert atomic._syncfs({tmp_path}) is expected
    assert atomic._syncfs({tmp_path / "missing"}) is False


def test_write_bytes_that_fails_keeps_the_old_file_and_no_temporary(tmp_path, monkeypatch):
    """A write that fails half way (a full disk) leaves the old content and no temporary
    file; a write the system takes in parts is completed."""
    target = tmp_path / "frame_000001.vtu"
    atomic_write_bytes(target, b"old frame")
    real_write = os.write
    monkeypatch.setattr(os, "write", lambda fd, data: real_write(fd, bytes(data[:3])))
    atomic_write_bytes(target, b"a frame written three bytes at a time", fsync=False)
    assert target.read_bytes() == b"a frame written three bytes at a time"

    def full(fd, data):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "write", full)
    with pytest.raises(OSError, match="No space"):
        atomic_write_bytes(target, b"new frame")
    assert target.read_bytes() == b"a frame written three bytes at a time"
    assert [p.name for p in tmp_path.iterdir()] == ["frame_000001.vtu"]
