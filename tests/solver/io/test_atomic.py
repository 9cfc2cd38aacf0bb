"""Atomic file writing (solver/io/atomic.py): the new file whole, or the old one."""

import os
import stat

import pytest

from solver.io.atomic import write_file_atomic


def test_writes_text_and_bytes_with_a_plain_files_mode(tmp_path):
    path = tmp_path / "a.txt"
    write_file_atomic(path, "grüße\n")
    assert path.read_bytes() == "grüße\n".encode()
    write_file_atomic(path, b"\x00\x01")
    assert path.read_bytes() == b"\x00\x01"
    umask = os.umask(0)
    os.umask(umask)
    assert stat.S_IMODE(path.stat().st_mode) == 0o666 & ~umask
    assert os.listdir(tmp_path) == ["a.txt"]


def test_a_failed_write_leaves_the_old_file_and_no_temporary(tmp_path, monkeypatch):
    path = tmp_path / "a.txt"
    path.write_text("old", encoding="utf-8")

    def failing_replace(a, b):
        raise OSError("disk full")

    monkeypatch.setattr(os, "replace", failing_replace)
    with pytest.raises(OSError, match="disk full"):
        write_file_atomic(path, "new")
    assert path.read_text(encoding="utf-8") == "old"
    assert os.listdir(tmp_path) == ["a.txt"]
