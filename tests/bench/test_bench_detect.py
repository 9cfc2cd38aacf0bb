"""bench/bench_detect.py's fit of james from the landmarks detected in its two real photos:
better than the mean head (face RMS against the scan); a photo made larger around its face
(``padded``); a detected point's error in the face's frame (``face_frame_errors``)."""

import numpy as np
import pytest

from bench.bench_detect import face_frame_errors, james_fit_errors, padded
from bench.realistic_cases import james_folder
from solver.detect import Detector
from solver.paths import DETECTOR_DIR
from tests import ROOT


def test_james_from_its_detected_photos_beats_the_mean_head():
    folder = james_folder(ROOT)
    if not (folder / "james.obj").is_file():
        pytest.skip(f"the scan james is not in {folder} (set HEADRECON_REALDATA)")
    if not (DETECTOR_DIR / "face_landmark.tflite").is_file():
        pytest.skip(f"models missing in {DETECTOR_DIR}: run ./run detector")
    errors = james_fit_errors(folder, Detector(), samples=2000)
    assert errors["solver detect's case"] < 0.97 * errors["mean head"], errors


def test_a_padded_photo_keeps_its_pixels_and_moves_its_points():
    image = np.arange(4 * 6 * 3, dtype=np.uint8).reshape(4, 6, 3)
    big, moved = padded(image, {1: (2.0, 1.0)}, 3)
    assert big.shape == (12, 18, 3)
    u, v = (18 - 6) // 2, (12 - 4) // 3
    np.testing.assert_array_equal(big[v:v + 4, u:u + 6], image)
    assert (big[0, 0] == image[2, 2]).all() and (big[-1, -1] == image[2, 2]).all()
    np.testing.assert_allclose(moved[1], [2.0 + u, 1.0 + v])


def test_errors_in_the_face_frame_follow_the_eyes_line_and_the_face_size():
    # a face turned 30 degrees in the photo, eyes 100 px apart: a point detected 2 px
    # toward the subject's left eye and 1 px toward the mouth reads so in any turn
    turn = np.radians(30.0)
    across = np.array([np.cos(turn), np.sin(turn)])
    down = np.array([-across[1], across[0]])
    centre = np.array([300.0, 400.0])
    truth = {i: centre - 50.0 * across for i in range(37, 43)}
    truth.update({i: centre + 50.0 * across for i in range(43, 49)})
    truth[49] = centre - 25.0 * across + 80.0 * down
    truth[55] = centre + 25.0 * across + 80.0 * down
    truth[31] = centre + 40.0 * down
    detected = np.zeros((68, 2))
    for i, p in truth.items():
        detected[i - 1] = p
    detected[30] = truth[31] + 2.0 * across + 1.0 * down
    errors = face_frame_errors(detected, truth)
    np.testing.assert_allclose(errors[31], [2.0 / 80.0 * 100, 1.0 / 80.0 * 100], atol=1e-9)
    np.testing.assert_allclose(errors[37], [0.0, 0.0], atol=1e-9)
