"""Atomic output files and run sets: complete files or the earlier ones untouched (issue class 4)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from ipromp_pin import atomic
from ipromp_pin.exceptions import OutputError


def _listing(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir())}


def test_write_text_replaces_and_creates_missing_folders(tmp_path):
    path = tmp_path / "a" / "b" / "out.txt"
    atomic.write_text(path, "one")
    atomic.write_text(path, "two")
    assert path.read_text() == "two"
    assert [p.name for p in path.parent.iterdir()] == ["out.txt"]  # no temporary file left


@pytest.mark.parametrize("failure", ["writer raises", "rename fails"])
def test_failed_write_leaves_the_earlier_file(tmp_path, monkeypatch, failure):
    path = tmp_path / "model.npz"
    path.write_bytes(b"old content")
    if failure == "writer raises":
        with pytest.raises(OutputError, match="No space left"), atomic.replacing(path) as tmp:
            tmp.write_bytes(b"half")
            raise OSError(28, "No space left on device")
    else:

        def refuse(src, dst):
            raise OSError(13, "Permission denied")

        monkeypatch.setattr(os, "replace", refuse)
        with pytest.raises(OutputError, match="model.npz.*Permission denied"):
            atomic.write_bytes(path, b"new content")
    assert path.read_bytes() == b"old content"
    assert _listing(tmp_path) == {"model.npz": b"old content"}


def test_new_file_gets_normal_permissions_and_keeps_an_existing_files(tmp_path):
    path = tmp_path / "x.csv"
    atomic.write_text(path, "a")
    mask = os.umask(0)
    os.umask(mask)
    assert path.stat().st_mode & 0o777 == 0o666 & ~mask
    os.chmod(path, 0o640)
    atomic.write_text(path, "b")
    assert path.stat().st_mode & 0o777 == 0o640


@pytest.mark.parametrize(
    ("make", "check", "message"),
    [
        (lambda p: p.mkdir(), atomic.check_output_file, "it is a folder"),
        (lambda p: p.write_text("x"), atomic.check_output_dir, "it is a file"),
        (lambda p: (p.parent / "f").write_text("x"), None, "is a file, not a folder"),
    ],
)
def test_output_paths_are_checked_before_any_work(tmp_path, make, check, message):
    target = tmp_path / "target"
    make(target)
    if check is None:  # a file where a parent folder should be
        for fn in (atomic.check_output_file, atomic.check_output_dir):
            with pytest.raises(OutputError, match=message):
                fn(tmp_path / "f" / "sub" / "out")
    else:
        with pytest.raises(OutputError, match=message):
            check(target)


def test_read_only_folder_is_refused(tmp_path, monkeypatch):
    # (as root, chmod does not stop writes: the permission check is simulated)
    monkeypatch.setattr(os, "access", lambda path, mode: Path(path) != tmp_path / "ro")
    (tmp_path / "ro").mkdir()
    with pytest.raises(OutputError, match="not writable"):
        atomic.check_output_dir(tmp_path / "ro")
    with pytest.raises(OutputError, match="ro is not writable"):
        atomic.check_output_file(tmp_path / "ro" / "new" / "model.npz")


def test_output_set_commits_everything_together_and_removes_managed_leftovers(tmp_path):
    out = tmp_path / "out"
    with atomic.OutputSet(out, managed=("a.txt", "b.txt", "c.txt")) as s:
        s.write_text("a.txt", "a1")
        s.write_text("b.txt", "b1")
        s.write_text("c.txt", "c1")
        assert not (out / "a.txt").exists()  # nothing visible before the commit
        s.commit()
    (out / "user.txt").write_text("not ours")
    with atomic.OutputSet(out, managed=("a.txt", "b.txt", "c.txt")) as s:
        s.write_text("a.txt", "a2")
        s.stage("b.txt").write_text("b2")  # a writer that takes a path
        files = s.commit()
    assert _listing(out) == {"a.txt": b"a2", "b.txt": b"b2", "user.txt": b"not ours"}
    assert list(files) == ["a.txt", "b.txt"]


def test_output_set_not_committed_changes_nothing(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "a.txt").write_text("old")
    with pytest.raises(RuntimeError), atomic.OutputSet(out, managed=("a.txt",)) as s:
        s.write_text("a.txt", "new")
        raise RuntimeError("the run failed midway")
    assert _listing(out) == {"a.txt": b"old"}


@pytest.mark.parametrize("failing_rename", [1, 2, 3])
def test_output_set_failing_commit_restores_the_earlier_files(tmp_path, monkeypatch, failing_rename):
    out = tmp_path / "out"
    out.mkdir()
    for name in ("a.txt", "b.txt", "old_only.txt"):
        (out / name).write_text(f"old {name}")
    before = _listing(out)
    real_replace = os.replace
    calls = []

    def flaky(src, dst):
        calls.append(dst)
        if len(calls) == failing_rename:
            raise OSError(28, "No space left on device")
        real_replace(src, dst)

    s = atomic.OutputSet(out, managed=("a.txt", "b.txt", "old_only.txt"))
    s.write_text("a.txt", "new a")
    s.write_text("b.txt", "new b")
    monkeypatch.setattr(os, "replace", flaky)
    with pytest.raises(OutputError, match="No space left"):
        s.commit()
    monkeypatch.setattr(os, "replace", real_replace)
    assert _listing(out) == before


def test_output_set_stages_folders(tmp_path):
    out = tmp_path / "out"
    with atomic.OutputSet(out, managed=("bag",)) as s:
        d = s.stage_dir("bag")
        (d / "metadata.yaml").write_text("v1")
        s.commit()
    with atomic.OutputSet(out, managed=("bag",)) as s:
        d = s.stage_dir("bag")
        (d / "data.mcap").write_text("v2")
        s.commit()
    assert sorted(p.name for p in (out / "bag").iterdir()) == ["data.mcap"]
    assert [p.name for p in out.iterdir()] == ["bag"]


def test_output_set_names_are_plain(tmp_path):
    with pytest.raises(ValueError, match="plain file name"):
        atomic.OutputSet(tmp_path, managed=("../escape",))
    s = atomic.OutputSet(tmp_path)
    with pytest.raises(ValueError, match="plain file name"):
        s.stage("sub/x")
    s.write_text("x", "1")
    with pytest.raises(ValueError, match="twice"):
        s.write_text("x", "2")
    s.discard()
    assert list(tmp_path.iterdir()) == []
