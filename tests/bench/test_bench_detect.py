"""bench/bench_detect.py's fit of james from the landmarks detected in its two real photos:
better than the mean head (face RMS against the scan)."""

import pytest

from bench.bench_detect import james_fit_errors
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
