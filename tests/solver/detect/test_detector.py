"""The detector on photos without a face, its input checks, and detected faces as a
landmarks case."""

import numpy as np
import pytest

from solver.detect import DetectedFace, Detector
from solver.detect.detected_case import detected_case
from solver.detect.detector import face_notes, other_faces_note, turn_note
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


@pytest.mark.parametrize("gains", [(0.5, 0.5, 0.5), (0.85, 1.0, 1.15), (1.0, 0.95, 0.8)],
                         ids=["darker", "cool", "warm"])
def test_a_photo_darkened_or_cast_after_it_was_taken_is_detected_as_it_was_shot(sample,
                                                                              gains):
    from PIL import Image

    if not (DETECTOR_DIR / "face_landmark.tflite").is_file():
        pytest.skip(f"models missing in {DETECTOR_DIR}: run ./run detector")
    folder, _ = sample
    d = Detector()
    photo = np.asarray(Image.open(folder / "side.png").convert("RGB"))
    changed = np.clip(photo * np.array(gains), 0, 255).astype(np.uint8)
    face, face_changed = d.detect(photo), d.detect(changed)
    # (a profile's mesh, 22 px from the truth, is not what is kept of it)
    assert np.median(np.linalg.norm(face.mesh[:, :2] - face_changed.mesh[:, :2], axis=1)) < 2.0
    outline, outline_changed = d.outline(photo, face), d.outline(changed, face_changed)
    # its skull's clipped highlight, grey or tinted now, is still the skin's highlight, and
    # the skin at its edge, washed out by the light, still skin: the whole outline is kept
    assert abs(len(outline_changed.points) - len(outline.points)) < 0.03 * len(outline.points)
    t = np.linspace(0, 1, 10, endpoint=False)[:, None, None]
    dense = (outline.points[:-1] * (1 - t) + outline.points[1:] * t).reshape(-1, 2)
    apart = np.linalg.norm(outline_changed.points[:, None] - dense[None], axis=2).min(1)
    assert np.median(apart) < 0.5


@pytest.mark.parametrize("degrees", [45, 90, -45])
def test_a_face_turned_far_in_the_photo_is_read_as_upright(sample, degrees):
    from PIL import Image

    if not (DETECTOR_DIR / "face_landmark.tflite").is_file():
        pytest.skip(f"models missing in {DETECTOR_DIR}: run ./run detector")
    folder, _ = sample
    d = Detector()
    photo = Image.open(folder / "front.png").convert("RGB")
    upright = d.detect(np.asarray(photo))
    fill = tuple(int(c) for c in np.asarray(photo)[2, 2])
    turned = photo.rotate(degrees, Image.BICUBIC, expand=True, fillcolor=fill)
    face = d.detect(np.asarray(turned))
    # the turned photo's points turned back onto the upright photo
    t = np.radians(degrees)
    (w, h), (tw, th) = photo.size, turned.size
    x, y = (face.in_photo(face.ibug) - [tw / 2, th / 2]).T
    back = np.c_[w / 2 + x * np.cos(t) - y * np.sin(t), h / 2 + x * np.sin(t) + y * np.cos(t)]
    off = np.linalg.norm(back - upright.ibug, axis=1) / upright.face_size
    # the first pass alone, its square turned by the detector's eye keypoints: 1.3-1.6 %
    # median and 4-5 % p90
    assert np.median(off) < 0.011 and np.percentile(off, 90) < 0.025


def test_the_subject_is_the_largest_face_not_the_most_confident(sample):
    """A profile photo with a smaller face looking at the camera behind it: the frontal
    face scores higher, the profile is the subject."""
    from PIL import Image

    if not (DETECTOR_DIR / "face_landmark.tflite").is_file():
        pytest.skip(f"models missing in {DETECTOR_DIR}: run ./run detector")
    folder, _ = sample
    d = Detector()
    front = Image.open(folder / "front.png").convert("RGB")
    side = Image.open(folder / "side.png").convert("RGB")
    alone = d.detect(np.asarray(side))
    assert alone.is_profile and alone.others == 0 and other_faces_note(alone) is None
    u0, v0, u1, v1 = d.detect(np.asarray(front)).box
    m = 0.2 * (u1 - u0)
    face = front.crop((int(u0 - m), int(v0 - m), int(u1 + m), int(v1 + 2 * m)))
    face = face.resize((int(face.width * 0.45), int(face.height * 0.45)))
    both = side.copy()
    both.paste(face, (2, 2))                     # in the corner, behind the subject
    found = d.detect(np.asarray(both))
    assert found.is_profile and found.others == 1
    np.testing.assert_allclose(found.box, alone.box, atol=0.02 * alone.face_size)
    assert other_faces_note(found).startswith("1 other, smaller face in the photo")


@pytest.mark.parametrize("view", ["front", "side"])
def test_a_cut_out_photo_is_detected_on_grey_whatever_its_transparency_hides(sample, view):
    """A photo cut out around the person (alpha 0 beyond it) whose transparent pixels hold
    black or white: the same face and outline either way, the outline on the head's true
    silhouette (white under the transparency cut into a bright skull before)."""
    from PIL import Image
    from scipy import ndimage

    if not (DETECTOR_DIR / "face_landmark.tflite").is_file():
        pytest.skip(f"models missing in {DETECTOR_DIR}: run ./run detector")
    folder, truth = sample
    d = Detector()
    photo = np.asarray(Image.open(folder / f"{view}.png").convert("RGB"))
    alpha = truth[f"alpha_{view}"]
    found = []
    for under in (0, 255):
        rgb = photo.copy()
        rgb[alpha == 0] = under
        cut_out = np.dstack([rgb, alpha])
        face = d.detect(cut_out)
        found.append((face, d.outline(cut_out, face)))
    (black, black_outline), (white, white_outline) = found
    np.testing.assert_array_equal(black.ibug, white.ibug)
    np.testing.assert_array_equal(black_outline.points, white_outline.points)
    person = alpha >= 128
    off = ndimage.distance_transform_edt(~(person ^ ndimage.binary_erosion(person)))
    chin = black.box[3]                          # the head's points: above the face box's foot
    head = white_outline.points[white_outline.points[:, 1] < chin]
    u, v = np.round(head).astype(int).T
    assert np.mean(off[v.clip(0, alpha.shape[0] - 1), u.clip(0, alpha.shape[1] - 1)] > 3) < 0.02


@pytest.mark.parametrize("rendered, photo, profile", [
    ("sample", "front.png", False), ("sample", "side.png", True),
    ("three_quarter_sample", "front.png", False), ("three_quarter_sample", "side.png", True),
    ("turned_sample", "front.png", False), ("turned_sample", "side.png", False)])
def test_a_photo_turned_is_detected_upright(request, rendered, photo, profile):
    """A front and three-quarter views at 25 and 45 degrees, turned by one, two and three
    quarter turns: each is detected on the photo turned back upright, so its points are
    the upright photo's, given on the photo as turned (at 45 degrees the mesh sees no face
    upside down: read as a profile there). A profile (the sample's, and the photo 65
    degrees round, read as one) is not turned: its score is no guide."""
    from PIL import Image

    from solver.detect.photo_turn import to_turned, turned

    if not (DETECTOR_DIR / "face_landmark.tflite").is_file():
        pytest.skip(f"models missing in {DETECTOR_DIR}: run ./run detector")
    folder, _ = request.getfixturevalue(rendered)
    d = Detector()
    image = np.asarray(Image.open(folder / photo).convert("RGB"))
    upright = d.detect(image)
    assert upright.is_profile == profile
    assert upright.turn == 0 and upright.given_score is None and turn_note(upright) is None
    if profile:
        return
    h, w = image.shape[:2]
    for k in (1, 2, 3):
        seen = d.detect(turned(image, k))
        assert seen.turn == (4 - k) % 4, k
        assert seen.photo_size == ((h, w) if k % 2 else (w, h))
        assert np.allclose(seen.ibug, upright.ibug) and seen.score == upright.score
        assert np.allclose(seen.in_photo(seen.ibug), to_turned(upright.ibug, k, (w, h)))
        assert seen.given_score < seen.score


def test_a_face_detected_turned_is_said_to_be():
    ibug = np.zeros((68, 2))
    face = DetectedFace(np.zeros((468, 3)), ibug, 0.9, 1.0)
    assert turn_note(face) is None and face_notes(face) == []
    face.turn, face.given_score = 2, 0.71
    assert "the face is upside down in the photo" in turn_note(face)
    assert "0.90 there, 0.71 as given" in turn_note(face)
    face.turn = 1
    assert face_notes(face) == [turn_note(face)]
    assert "a quarter round clockwise" in turn_note(face)
    face.turn = 3
    assert "a quarter round anticlockwise" in turn_note(face)
