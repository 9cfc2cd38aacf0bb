"""Atomic file writing (solver/io/atomic.py): the new file whole, or the old one."""

import os
import stat

import pytest

from solver.io.atomic import check_outputs, write_file_atomic, write_files_atomic


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


def test_a_set_is_written_whole_or_not_at_all(tmp_path):
    a, b = tmp_path / "a.obj", tmp_path / "missing" / "b.png"
    a.write_text("old", encoding="utf-8")
    with pytest.raises(OSError, match=r"No such file or directory: '.*missing/b\.png'"):
        write_files_atomic({a: "new", b: b"png"})
    assert a.read_text(encoding="utf-8") == "old"
    assert os.listdir(tmp_path) == ["a.obj"]  # no temporary left behind
    (tmp_path / "missing").mkdir()
    write_files_atomic({a: "new", b: b"png"})
    assert a.read_text(encoding="utf-8") == "new" and b.read_bytes() == b"png"


def test_a_write_error_names_the_target_not_the_temporary(tmp_path, monkeypatch):
    path = tmp_path / "head.obj"

    def too_large(fd):
        raise OSError(27, "File too large")

    monkeypatch.setattr(os, "fsync", too_large)
    with pytest.raises(OSError) as info:
        write_file_atomic(path, "v 0 0 0\n")
    assert str(info.value) == f"[Errno 27] File too large: '{path}'"
    assert os.listdir(tmp_path) == []


def test_outputs_that_are_inputs_or_each_other_are_refused(tmp_path):
    case = tmp_path / "case.json"
    case.write_text("{}", encoding="utf-8")
    (tmp_path / "link.json").symlink_to(case)
    os.link(case, tmp_path / "hard.json")
    inputs = {"the landmarks file": case}
    for other in (case, tmp_path / "link.json", tmp_path / "hard.json",
                  tmp_path / "sub" / ".." / "case.json"):
        with pytest.raises(ValueError, match=r"--report .*: is the landmarks file \(.*case"
                                             r"\.json\); refusing to overwrite an input"):
            check_outputs({"--out": tmp_path / "h.obj", "--report": other}, inputs)
    with pytest.raises(ValueError, match=r"--report .*x: is also --out \(.*x\)"):
        check_outputs({"--out": tmp_path / "x", "--report": tmp_path / "x"}, inputs)
    with pytest.raises(ValueError, match=r"--report .*Head\.obj: is also --out"):
        check_outputs({"--out": tmp_path / "head.obj", "--report": tmp_path / "Head.obj"})
    with pytest.raises(ValueError, match="is a folder"):
        check_outputs({"--out": tmp_path})
    check_outputs({"--out": tmp_path / "h.obj", "--report": tmp_path / "r.json"}, inputs)
    with pytest.raises(ValueError, match="give the outputs different file names"):
        write_files_atomic({tmp_path / "a": "1", tmp_path / "sub" / ".." / "a": "2"})
    assert not (tmp_path / "a").exists()


def test_saving_landmarks_into_a_missing_folder_names_the_file(tmp_path):
    from solver import LandmarkCase, OrthographicCamera, View, save_landmarks

    cam = OrthographicCamera.nominal("orthographic-front", (100, 100))
    case = LandmarkCase({"front": View("front", None, (100, 100), cam, {"nose_tip": (5, 5)})})
    target = tmp_path / "missing" / "case.json"
    with pytest.raises(OSError) as info:
        save_landmarks(case, target)
    assert str(info.value).endswith(f"No such file or directory: '{target}'")
    assert ".tmp" not in str(info.value)
