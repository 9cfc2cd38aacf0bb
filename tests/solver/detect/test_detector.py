"""The detector on photos without a face, its input checks, and detected faces as a
landmarks case."""

import numpy as np
import pytest

from solver.detect import DetectedFace, Detector
from solver.detect.detected_case import detected_case
from solver.paths import DETECTOR_DIR


def test_no_face_in_a_blank_photo():
    if not (DETECTOR_DIR / "face_landmark.tflite").is_file():
        pytest.skip(f"models missing in {DETECTOR_DIR}: run ./run detector")
    d = Detector()
    assert d.detect(np.full((300, 200, 3), 128, np.uint8)) is None
    with pytest.raises(ValueError, match="shape"):
        d.detect(np.zeros((10, 10)))


def test_missing_models_are_named(tmp_path):
    with pytest.raises(ValueError, match="face_detection_short_range.tflite: missing"):
        Detector(tmp_path)


def test_detected_case_names_points_and_keeps_them_inside(tmp_path):
    ibug = np.tile([50.0, 60.0], (68, 1))
    ibug[0] = [-5.0, 60.0]                       # iBUG 1 outside the photo: left out
    face = DetectedFace(np.zeros((468, 3)), ibug, 0.9, 1.0)
    photo = tmp_path / "photos" / "me.jpg"
    case = detected_case([("me", photo, (100, 120))], [face], base_dir=tmp_path)
    view = case.views["me"]
    assert view.image == "photos/me.jpg" and view.size == (100, 120)
    assert "jaw_1_right" not in view.points and len(view.points) == 67
    assert view.points["nose_tip"] == (50.0, 60.0)
    assert view.camera.view == "orthographic-front"


def test_a_photo_darkened_after_it_was_taken_is_detected_as_it_was_shot(sample):
    from PIL import Image

    if not (DETECTOR_DIR / "face_landmark.tflite").is_file():
        pytest.skip(f"models missing in {DETECTOR_DIR}: run ./run detector")
    folder, _ = sample
    d = Detector()
    photo = np.asarray(Image.open(folder / "side.png").convert("RGB"))
    dark = (photo * 0.5).astype(np.uint8)
    face, face_dark = d.detect(photo), d.detect(dark)
    assert np.median(np.linalg.norm(face.mesh[:, :2] - face_dark.mesh[:, :2], axis=1)) < 1.0
    outline, outline_dark = d.outline(photo, face), d.outline(dark, face_dark)
    # its skull's clipped highlight, now grey, is still skin: the whole outline is kept
    assert abs(len(outline_dark.points) - len(outline.points)) < 0.03 * len(outline.points)
