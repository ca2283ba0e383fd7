"""Atomic writes and staged outputs: what a target may be, and a run's files moving into
place together or not at all."""

from __future__ import annotations

import os
import stat
from pathlib import Path

import pytest

from mirrorgraph.errors import InputError
from mirrorgraph.io.atomic import (atomic_path, atomic_write_text, check_output, check_outputs,
                                   staged_outputs)


def listing(folder: Path) -> dict:
    return {p.name: (p.read_bytes() if p.is_file() and not p.is_symlink() else os.lstat(p).st_mode)
            for p in sorted(folder.iterdir())}


def test_staged_outputs_move_into_place_together(tmp_path):
    (tmp_path / "a.txt").write_text("old a")
    with staged_outputs() as stage:
        atomic_write_text(tmp_path / "a.txt", "new a")
        atomic_write_text(tmp_path / "b.txt", "new b")
        assert (tmp_path / "a.txt").read_text() == "old a"      # not yet
        assert not (tmp_path / "b.txt").exists()
        figures = stage.folder(tmp_path / "rep" / "sub")
        (figures / "f.png").write_bytes(b"png")
    assert (tmp_path / "a.txt").read_text() == "new a"
    assert (tmp_path / "b.txt").read_text() == "new b"
    assert (tmp_path / "rep" / "sub" / "f.png").read_bytes() == b"png"
    assert not [p for p in tmp_path.rglob(".*")], "temporaries left"


def test_failed_block_leaves_every_file_as_it_was(tmp_path):
    (tmp_path / "a.txt").write_text("old a")
    (tmp_path / "rep").mkdir()
    (tmp_path / "rep" / "mine.png").write_bytes(b"mine")
    before = listing(tmp_path)
    with pytest.raises(OSError):
        with staged_outputs() as stage:
            atomic_write_text(tmp_path / "a.txt", "new a")
            (stage.folder(tmp_path / "rep") / "f.png").write_bytes(b"png")
            with open(stage.file(tmp_path / "v.mp4"), "wb") as f:
                f.write(b"video")
            raise OSError(28, "No space left on device")
    assert listing(tmp_path) == before
    assert listing(tmp_path / "rep") == {"mine.png": b"mine"}


def test_commit_failing_halfway_puts_back_what_was_there(tmp_path, monkeypatch):
    for name in ("a", "b", "c"):
        (tmp_path / f"{name}.txt").write_text(f"old {name}")
    before = listing(tmp_path)
    real_replace = os.replace
    calls = []

    def flaky(src, dst):
        calls.append(dst)
        if len(calls) == 3 and Path(dst).name == "c.txt":
            raise OSError(5, "Input/output error", str(dst))
        return real_replace(src, dst)

    with pytest.raises(OSError):
        with staged_outputs():
            for name in ("a", "b", "c"):
                atomic_write_text(tmp_path / f"{name}.txt", f"new {name}")
            monkeypatch.setattr(os, "replace", flaky)
    monkeypatch.setattr(os, "replace", real_replace)
    assert listing(tmp_path) == before


def test_symlink_is_written_through(tmp_path):
    (tmp_path / "real.txt").write_text("old")
    (tmp_path / "link.txt").symlink_to("real.txt")
    atomic_write_text(tmp_path / "link.txt", "new")
    assert (tmp_path / "link.txt").is_symlink()
    assert (tmp_path / "real.txt").read_text() == "new"
    (tmp_path / "dangling.txt").symlink_to("made.txt")
    atomic_write_text(tmp_path / "dangling.txt", "made")
    assert (tmp_path / "made.txt").read_text() == "made"


def test_special_files_and_folders_refused(tmp_path):
    os.mkfifo(tmp_path / "pipe")
    (tmp_path / "dir").mkdir()
    (tmp_path / "loop").symlink_to("loop")
    for target, says in ((tmp_path / "pipe", "FIFO"), ("/dev/null", "device"),
                         (tmp_path / "dir", "folder"), (tmp_path / "loop", "loops")):
        with pytest.raises(InputError, match=says):
            atomic_write_text(target, "x")
        with pytest.raises(InputError, match=says):
            check_output(target, field="--out")
    assert stat.S_ISFIFO(os.lstat(tmp_path / "pipe").st_mode)
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]


def test_check_output_names_the_cause(tmp_path):
    (tmp_path / "in.json").write_text("{}")
    (tmp_path / "hard.json").hardlink_to(tmp_path / "in.json")
    cases = [(tmp_path / "nodir" / "x.json", "no such folder"),
             (tmp_path / "in.json", "is the input"), (tmp_path / "hard.json", "is the input"),
             ("-", "standard output"), ("", "empty")]
    for path, says in cases:
        with pytest.raises(InputError, match=says):
            check_output(path, field="--out", inputs=[tmp_path / "in.json"])
    check_output("-", field="--jsonl", stdout_ok=True)
    check_output(tmp_path / "new" / "deeper", field="--report", folder=True)
    with pytest.raises(InputError, match="is a file"):
        check_output(tmp_path / "in.json", field="--report", folder=True)
    with pytest.raises(InputError, match="also the output of --out"):
        check_outputs([(tmp_path / "o.json", "--out"), (tmp_path / "o.json", "--json")])


def test_atomic_path_alone_is_immediate(tmp_path):
    with atomic_path(tmp_path / "x.bin") as tmp:
        tmp.write_bytes(b"1")
    assert (tmp_path / "x.bin").read_bytes() == b"1"
