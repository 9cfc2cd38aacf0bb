"""Which way a detected face looks (solver/detect/view_guess.py), and each point's
uncertainty, on the rendered sample's photos (front, right profile, the profile mirrored
into a left one) and on james' two real three-quarter photos against their calibrated
cameras."""

import json

import numpy as np
import pytest
from PIL import Image

from solver.detect import Detector
from solver.detect.view_guess import (
    MEDIAN_TO_SIGMA,
    ViewGuess,
    beside_front,
    guess_view,
    mesh_yaw_deg,
    placed,
    placed_by_landmarks,
    point_uncertainty,
    points_yaw_deg,
    profile_yaw_deg,
    uncertainty_table,
    yaw_growth,
)
from solver.io.landmark_set import load_landmark_set
from solver.io.photo_lens import DIRECTION_SIGMA_DEG
from solver.paths import DETECTOR_DIR
from tests import ROOT


@pytest.fixture(scope="module")
def detector():
    if not (DETECTOR_DIR / "face_landmark.tflite").is_file():
        pytest.skip(f"models missing in {DETECTOR_DIR}: run ./run detector")
    return Detector()


def _photo(folder, view, truth, mirror=False):
    """(photo uint8, {iBUG number: true (u, v)}) of the sample's ``view``."""
    image = np.asarray(Image.open(folder / f"{view}.png").convert("RGB"))
    number = {n: i for i, n in load_landmark_set().ibug.items()}
    names = json.loads(str(truth["landmark_names"]))[view]
    pts = {number[n]: np.asarray(p, float) for n, p in zip(names, truth[f"exact_{view}"],
                                                            strict=True) if n in number}
    if mirror:
        w = image.shape[1]
        image = image[:, ::-1].copy()
        pts = {i: np.array([w - p[0], p[1]]) for i, p in pts.items()}
    return image, pts


def test_the_sample_photos_are_a_front_and_both_profiles(sample, detector):
    folder, truth = sample
    image, _ = _photo(folder, "front", truth)
    face = detector.detect(image)
    guess = guess_view(face)
    assert guess.name == "front" and abs(guess.yaw_deg) < 8.0 and not guess.profile
    assert guess.camera((384, 512))[0].view == "orthographic-front"
    for mirror, side in ((False, "right"), (True, "left")):
        image, _ = _photo(folder, "side", truth, mirror)
        face = detector.detect(image)
        assert face is not None and face.is_profile, side
        guess = guess_view(face)
        assert guess.name == side and guess.profile and guess.side == side
        camera, hints = guess.camera((384, 512))
        assert camera.view == f"orthographic-{side}" and hints == {}


def test_a_profile_keeps_only_its_trustworthy_points_each_within_its_uncertainty(
        sample, detector):
    folder, truth = sample
    for mirror in (False, True):
        image, pts = _photo(folder, "side", truth, mirror)
        face = detector.detect(image)
        kept = point_uncertainty(face)
        assert sorted(kept) == [31, 34, 52]
        # each kept point's error within 3 of its standard deviations (2-D: 3 sigma ~ 2.5
        # median errors), the points left out mostly farther than that
        for i, sigma in kept.items():
            assert np.linalg.norm(face.ibug[i - 1] - pts[i]) < 3 * sigma, (mirror, i)
        left_out = [np.linalg.norm(face.ibug[i - 1] - pts[i]) / face.face_size
                    for i in pts if i not in kept]
        assert np.median(left_out) > max(uncertainty_table()["profile"].values())


def test_front_points_are_as_far_off_as_their_uncertainty_says(sample, detector):
    folder, truth = sample
    image, pts = _photo(folder, "front", truth)
    face = detector.detect(image)
    sigma = point_uncertainty(face)
    assert sorted(sigma) == list(range(1, 69))
    # the jaw (an outline, and on james under a beard) is the least certain, the mouth and
    # eyes the most; all scale with the face's size
    assert sigma[9] > 3 * sigma[49] and sigma[37] < sigma[20] < sigma[9]
    assert sigma[9] == pytest.approx(uncertainty_table()["front"][9] * face.face_size
                                     * MEDIAN_TO_SIGMA)
    z = np.array([np.linalg.norm(face.ibug[i - 1] - p) / sigma[i] for i, p in pts.items()])
    # errors in standard deviations: of the order of one (median of a 2-D Gaussian: 1.18)
    assert 0.3 < np.median(z) < 2.5, np.median(z)


def _james(folder):
    from bench.realistic_cases import calibrate, face_frame, load_scan

    scan = load_scan(folder)
    image = np.asarray(Image.open(folder / "james.jpg").convert("RGB"))
    half = image.shape[1] // 2
    origin, left, _, forward = face_frame(scan.ibug)
    out = []
    for photo, x0 in (("photo_a", 0), ("photo_b", half)):
        d = calibrate(scan, photo).camera.centre - origin
        out.append((photo, image[:, x0:x0 + half],
                    float(np.degrees(np.arctan2(d @ -left, d @ forward)))))
    return out


def test_james_photos_are_three_quarter_views_at_their_calibrated_yaw(detector):
    from bench.realistic_cases import james_folder

    folder = james_folder(ROOT)
    if not (folder / "james.obj").is_file():
        pytest.skip(f"the scan james is not in {folder} (set HEADRECON_REALDATA)")
    for photo, image, true_yaw in _james(folder):
        guess = guess_view(detector.detect(image))
        side = "right" if true_yaw > 0 else "left"
        assert guess.name == f"three_quarter_{side}", (photo, guess, true_yaw)
        assert abs(guess.yaw_deg - true_yaw) < 4.0, (photo, guess.yaw_deg, true_yaw)
        assert guess.camera((1200, 1600)) == (None, {
            "kind": "pinhole", "direction_prior": [guess.yaw_deg, DIRECTION_SIGMA_DEG]})


def test_a_three_quarter_view_s_points_are_less_certain_the_more_it_is_turned():
    assert yaw_growth(0.0) == yaw_growth(-15.0) == 1.0
    assert yaw_growth(45.0) == pytest.approx(2.0) and yaw_growth(-45.0) == yaw_growth(45.0)
    assert yaw_growth(20.0) < yaw_growth(30.0) < yaw_growth(60.0)


def test_james_three_quarter_points_carry_the_table_grown_by_their_yaw(detector):
    from bench.realistic_cases import james_folder

    folder = james_folder(ROOT)
    if not (folder / "james.obj").is_file():
        pytest.skip(f"the scan james is not in {folder} (set HEADRECON_REALDATA)")
    image = np.asarray(Image.open(folder / "james.jpg").convert("RGB"))
    face = detector.detect(image[:, :image.shape[1] // 2])  # photo_a, 30 degrees
    grow = yaw_growth(mesh_yaw_deg(face.mesh))
    assert 1.3 < grow < 1.7
    sigma = point_uncertainty(face)
    assert sigma[9] == pytest.approx(uncertainty_table()["front"][9] * face.face_size
                                     * MEDIAN_TO_SIGMA * grow)


def test_view_guess_words_and_a_bad_table_names_its_file(tmp_path):
    assert ViewGuess("right", 90.0).describe().startswith("a right profile")
    assert "yaw -31 deg" in ViewGuess("three_quarter_left", -31.0).describe()
    assert ViewGuess("front", 2.0).side is None
    bad = tmp_path / "map.json"
    bad.write_text(json.dumps({"uncertainty": {"front": {"1": 0.1}, "profile": {}}}))
    with pytest.raises(ValueError, match="map.json: uncertainty.front must give every"):
        uncertainty_table(bad)


def test_a_photo_s_camera_is_a_pinhole_of_its_known_lens_held_near_its_yaw():
    from solver import DIRECTION_SIGMA_DEG, OrthographicCamera

    size = (300, 400)
    for guess in (ViewGuess("front", 3.5), ViewGuess("right", 90.0),
                  ViewGuess("three_quarter_left", -31.0)):
        camera, hints = guess.camera(size, 52.0)
        assert camera is None and hints == {"kind": "pinhole", "lens_mm": 52.0,
                                            "direction_prior": [guess.yaw_deg,
                                                                DIRECTION_SIGMA_DEG]}
    # without a lens: the nominal parallel projection of a front or a profile, a
    # three-quarter view's pinhole with its focal length unknown, held near its yaw
    camera, hints = ViewGuess("left", -90.0).camera(size)
    assert isinstance(camera, OrthographicCamera) and camera.view == "orthographic-left"
    assert hints == {}
    assert ViewGuess("three_quarter_right", 40.0).camera(size) == (None, {
        "kind": "pinhole", "direction_prior": [40.0, DIRECTION_SIGMA_DEG]})


def test_a_side_photo_short_of_a_profile_is_read_at_its_yaw(sample, turned_side_sample,
                                                             detector):
    """A side photo 16 degrees short of a profile (the head turned toward the side camera):
    its eyes apart and the mesh seeing a face say so, the yaw comes from the eyes, and its
    orthographic camera is turned to it. An exact profile stays at 90 degrees, and so does
    the turned one where only one of the two says so."""
    from dataclasses import replace

    folder, truth = turned_side_sample
    true = truth["rotation"].T @ np.array([1.0, 0.0, 0.0])  # the side camera, head frame
    true_yaw = np.degrees(np.arctan2(true[0], true[1]))
    turned = detector.detect(_photo(folder, "side", truth)[0])
    guess = guess_view(turned)
    assert guess.name == "right" and abs(guess.yaw_deg - true_yaw) < 6.0, \
        (guess.yaw_deg, true_yaw)
    assert "short of a profile" in guess.describe()
    camera, hints = guess.camera((384, 512))
    d = camera.rotation[2]
    assert hints == {} and camera.view == "orthographic-right"
    assert np.degrees(np.arctan2(d[0], d[1])) == pytest.approx(guess.yaw_deg)
    assert profile_yaw_deg(replace(turned, presence=0.5)) == 90.0
    folder, truth = sample
    square = detector.detect(_photo(folder, "side", truth)[0])
    assert profile_yaw_deg(square) == 90.0
    assert profile_yaw_deg(replace(square, presence=1.0)) == 90.0  # its eyes nearly meet


def test_views_beside_a_front_photo_are_turned_into_its_frame():
    """A front photo on the nominal orthographic camera whose face was measured at 10
    degrees: the fit turns the head by 10, so the other cameras sit at their yaws less 10.
    A profile whose yaw was not measured (90), and the front itself, stay; none passes a
    profile; a front with a lens (a pinhole held near its own yaw) turns nothing."""
    right, quarter = ViewGuess("right", 74.0), ViewGuess("three_quarter_left", -30.0)
    assert right.beside(-16.0) == ViewGuess("right", 90.0)
    assert right.beside(4.0) == ViewGuess("right", 70.0)
    assert quarter.beside(10.0) == ViewGuess("three_quarter_left", -40.0)
    assert ViewGuess("left", -90.0).beside(-12.0) == ViewGuess("left", -90.0)
    assert ViewGuess("left", -85.0).beside(12.0) == ViewGuess("left", -90.0)
    front = ViewGuess("front", 10.0)
    assert front.beside(10.0) == front
    assert beside_front([right, front, quarter], [True, True, False]) == [
        ViewGuess("right", 64.0), front, ViewGuess("three_quarter_left", -40.0)]
    assert beside_front([right, front], [True, False]) == [right, front]
    assert beside_front([right, quarter], [True, True]) == [right, quarter]


def test_a_case_with_a_measured_profile_is_placed_in_the_face_s_frame():
    """A profile read short of 90 degrees places the case in the face's frame: each front
    photo that may be orthographic turned to its own yaw, the rest as they are (a
    three-quarter view a pinhole held near its yaw); without one, the front photo's frame
    (``beside_front``)."""
    right, front = ViewGuess("right", 74.0), ViewGuess("front", -12.0)
    quarter = ViewGuess("three_quarter_left", -20.0)
    out = placed([front, right, quarter, front], [True, True, True, False])
    assert out == [ViewGuess("front", -12.0, turned=True), right, quarter, front]
    camera, hints = out[0].camera((300, 400))
    assert hints == {} and camera.view == "orthographic-front"
    d = camera.rotation[2]
    assert np.degrees(np.arctan2(d[0], d[1])) == pytest.approx(-12.0)
    assert out[2].camera((300, 400))[0] is None  # a pinhole to calibrate, as before
    square = ViewGuess("right", 90.0)
    assert placed([front, square], [True, True]) == beside_front([front, square], [True, True])


def test_landmarks_placed_by_hand_show_the_photo_s_yaw(model):
    """A photo's landmarks (a model head's, through orthographic cameras turned to known
    yaws, 1.5 px of noise) show its yaw within 3 degrees, one of them misplaced too; too
    few landmarks, or unknown names, show none."""
    from solver import OrthographicCamera

    rng = np.random.default_rng(5)
    head = model.identity.instance(rng.normal(size=model.identity.n_coeffs))
    lms = model.landmark_set
    names = [n for n in lms.vertices if lms.has_meaning_in(n, "front")]
    for yaw in (-35.0, -12.0, 0.0, 20.0):
        camera = OrthographicCamera.turned("orthographic-front", (768, 1024), yaw)
        px = camera.project(head[[lms.vertices[n] for n in names]])
        px = px + rng.normal(0.0, 1.5, px.shape)
        found = points_yaw_deg(model, dict(zip(names, px, strict=True)))
        assert abs(found - yaw) < 3.0, (found, yaw)
        misplaced = dict(zip(names, px, strict=True)) | {names[0]: (5.0, 5.0)}
        found = points_yaw_deg(model, misplaced)  # one landmark far off, left out
        assert abs(found - yaw) < 3.0, (found, yaw)
    few = dict(zip(names[:5], px[:5], strict=True))
    assert points_yaw_deg(model, few) is None
    assert points_yaw_deg(model, {f"no such {n}": p for n, p in zip(names, px, strict=True)}) \
        is None


def test_a_side_photo_short_of_a_profile_placed_by_hand_turns_the_cameras(model):
    """A model head's landmarks through a front camera and a side camera 18 degrees short
    of a profile, both given as the nominal cameras a hand-placed case has: the side camera
    is turned to the yaw its landmarks show, with a note; an exact profile, a profile with
    only its middle points, one labelled the other side or a camera given turned stay as
    they are."""
    import dataclasses

    from solver import OrthographicCamera
    from solver.fitting.checks import swap_name
    from solver.synthetic import make_hand_placed_case

    lms, size = model.landmark_set, (768, 1024)
    given, _ = make_hand_placed_case(model, 7, side_deg=72.0, size=size)
    out, notes = placed_by_landmarks(model, given)
    d = out.views["side"].camera.rotation[2]
    assert abs(np.degrees(np.arctan2(d[0], d[1])) - 72.0) < 5.0
    assert len(notes) == 1 and notes[0].startswith("view 'side': its landmarks show a right "
                                                   "profile")
    assert "short of a profile" in notes[0]
    assert np.allclose(given.views["side"].camera.rotation,  # the case given is kept
                       OrthographicCamera.nominal("orthographic-right", size).rotation)
    exact, _ = make_hand_placed_case(model, 7, side_deg=90.0, size=size)
    assert placed_by_landmarks(model, exact) == (exact, [])

    def side(case, **change):
        return dataclasses.replace(case, views={**case.views, "side": dataclasses.replace(
            case.views["side"], **change)})

    middle = side(given, points={n: p for n, p in given.views["side"].points.items()
                                 if abs(model.vertices[lms.vertices[n], 0]) < 0.01})
    assert placed_by_landmarks(model, middle) == (middle, [])
    w = size[0]  # the photo mirrored: a left profile labelled right
    other = side(given, points={swap_name(n): (w - u, v)
                                for n, (u, v) in given.views["side"].points.items()})
    assert placed_by_landmarks(model, other) == (other, [])
    turned = side(given, camera=OrthographicCamera.turned("orthographic-right", size, 80.0))
    assert placed_by_landmarks(model, turned) == (turned, [])
