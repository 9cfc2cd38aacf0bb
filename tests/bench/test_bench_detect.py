"""bench/bench_detect.py's fit of james from the landmarks detected in its two real photos:
better than the mean head (face RMS against the scan); a photo made larger around its face
(``padded``)."""

import numpy as np
import pytest

from bench.bench_detect import james_fit_errors, padded
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
