"""bench/bench_corrections.py's cases: the photos-only case detected from the photos asked
(a variant's, with hair), its corrections from the head's own exact landmarks."""

import numpy as np
import pytest

from bench.bench_corrections import GROUPS, corrected_cases, from_photos_errors
from bench.bench_photo_variants import changed
from solver import fit_head, load_landmarks
from solver.detect import Detector
from solver.io.landmark_set import load_landmark_set
from solver.paths import DETECTOR_DIR
from solver.synthetic import skin_error_mm


def test_corrections_of_a_variant_s_photos_place_the_head_s_own_exact_points(
        sample, model, tmp_path):
    if not (DETECTOR_DIR / "face_landmark.tflite").is_file():
        pytest.skip(f"models missing in {DETECTOR_DIR}: run ./run detector")
    folder, _ = sample
    detector = Detector()
    photos = changed(folder, "hair", tmp_path / "hair", detector)
    plain = dict(corrected_cases(folder, model, detector))
    haired = dict(corrected_cases(folder, model, detector, photos))
    assert list(haired) == ["photos", *GROUPS, "profile ears", "every exact"]
    # the photos detected are the variant's: hair moves the front's detected points
    a, b = plain["photos"].views["front"].points, haired["photos"].views["front"].points
    assert set(a) == set(b)
    assert max(np.hypot(*np.subtract(a[n], b[n])) for n in a) > 0.5
    # the corrections are the head's own exact points, whichever photos were detected
    exact = load_landmarks(folder / "sample.json", known_names=model)
    names = [load_landmark_set().ibug[i] for i in GROUPS["jaw"]]
    jaw, placed = haired["jaw"].views["front"], exact.views["front"].points
    assert [jaw.points[n] for n in names] == [placed[n] for n in names]
    assert not set(names) & set(jaw.uncertainty)
    ears = {n: p for n, p in exact.views["side"].points.items() if n.startswith("ear_")}
    assert ears and all(haired["profile ears"].views["right"].points[n] == p
                        for n, p in ears.items())
    assert haired["every exact"].views.keys() == exact.views.keys()


def test_corrections_from_the_photos_fit_are_its_live_refit_and_a_fit_from_its_head(
        sample, model):
    if not (DETECTOR_DIR / "face_landmark.tflite").is_file():
        pytest.skip(f"models missing in {DETECTOR_DIR}: run ./run detector")
    folder, truth = sample
    cases = dict(corrected_cases(folder, model, Detector()))
    photos_fit = fit_head(model, cases["photos"])
    photos = skin_error_mm(model, photos_fit.local_vertices, truth["local_vertices"])
    live, continued = from_photos_errors(model, cases["all 68"], photos_fit,
                                         truth["local_vertices"])
    # both heads follow the corrected points, each its own way: the live refit keeps the
    # photos fit's cameras and outline, the continued fit moves them
    assert np.isfinite([live, continued]).all()
    assert abs(live - photos) > 1e-3 and abs(continued - photos) > 1e-3
    assert abs(live - continued) > 1e-3
    # the case of every exact landmark has other views: no head from the photos fit
    assert np.isnan(from_photos_errors(model, cases["every exact"], photos_fit,
                                       truth["local_vertices"])).all()
