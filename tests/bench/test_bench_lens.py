"""bench/bench_lens.py: the cases it fits of a head photographed with a known lens."""

import pytest

from solver import DIRECTION_SIGMA_DEG, OrthographicCamera
from solver.paths import DETECTOR_DIR


def test_head_cases_take_the_photos_with_and_without_their_lens(lens_sample, model):
    if not (DETECTOR_DIR / "face_landmark.tflite").is_file():
        pytest.skip(f"models missing in {DETECTOR_DIR}: run ./run detector")
    from bench.bench_lens import COLUMNS, head_cases
    from solver.detect import Detector

    folder, _ = lens_sample
    cases = dict(head_cases(folder, model, Detector(), sigmas=[3.0]))
    assert list(cases) == [*COLUMNS, "sigma 3 deg"]
    lens, flat = cases["EXIF lens"], cases["orthographic"]
    assert set(lens.views) == set(flat.views) == {"front", "right"}
    for name in lens.views:
        assert lens.views[name].camera is None
        assert lens.views[name].camera_hints["direction_prior"][1] == DIRECTION_SIGMA_DEG
        assert cases["sigma 3 deg"].views[name].camera_hints["direction_prior"][1] == 3.0
        assert isinstance(flat.views[name].camera, OrthographicCamera)
    assert set(cases["every exact"].views) == {"front", "side"}
