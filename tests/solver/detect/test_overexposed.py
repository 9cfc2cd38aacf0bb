"""A face the photo clipped to white (solver/detect/overexposed.py): the rendered sample's
front photo as rendered shows none, brightened until its skin clips it is said in the
report; the share counts the face's skin, not its eyes or lips."""

import numpy as np
import pytest
from PIL import Image

from solver.cli import load_photo
from solver.detect import Detector
from solver.detect.detected_case import detect_photos
from solver.detect.detector import face_notes
from solver.detect.overexposed import HOLES, OVEREXPOSED_SHARE, clipped_share, overexposed_note
from solver.geometry import inside_polygon
from solver.paths import DETECTOR_DIR


@pytest.fixture(scope="module")
def detector():
    if not (DETECTOR_DIR / "face_landmark.tflite").is_file():
        pytest.skip(f"models missing in {DETECTOR_DIR}: run ./run detector")
    return Detector()


def test_a_face_brightened_until_it_clips_is_said_to_be_overexposed(sample, detector,
                                                                   tmp_path):
    folder, _ = sample
    photo = np.asarray(Image.open(folder / "front.png").convert("RGB"))
    face = detector.detect(photo)
    assert face.clipped < 0.01 and overexposed_note(face) is None
    bright = np.clip(photo * 1.35, 0, 255).astype(np.uint8)
    Image.fromarray(bright).save(tmp_path / "front.png")
    face = detector.detect(bright)
    assert face.clipped > 2 * OVEREXPOSED_SHARE
    assert any("clipped to white (overexposed)" in n for n in face_notes(face))
    said = []
    detect_photos([(None, tmp_path / "front.png")], detector, load_photo, base_dir=tmp_path,
                  echo=said.append, outlines="none")
    assert any(line.startswith("note: ") and "clipped to white" in line for line in said)


def test_the_share_counts_the_skin_not_the_eyes_or_lips(sample, detector):
    folder, _ = sample
    face = detector.detect(np.asarray(Image.open(folder / "front.png").convert("RGB")))
    h, w = 512, 384
    v, u = np.mgrid[0:h, 0:w]
    pixels = np.column_stack([u.ravel(), v.ravel()]).astype(float)
    scale = np.array([w, h]) / np.array(Image.open(folder / "front.png").size)
    face.ibug = face.ibug * scale                  # the face drawn on a photo of (h, w)
    image = np.empty((h, w, 3), np.float32)
    image[:] = (0.8, 0.6, 0.5)                     # skin
    for hole in HOLES:                             # white eyes and lips: not skin
        image[inside_polygon(pixels, face.ibug[np.array(hole) - 1]).reshape(h, w)] = 1.0
    assert clipped_share(image, face) == 0.0
    nose_u = face.ibug[30, 0]
    image[:, :int(nose_u)] = 1.0                   # the face's one side white
    assert 0.35 < clipped_share(image, face) < 0.65
