"""BlazeFace's anchors, decoding and weighted suppression, and a face too small for the
whole photo found in its parts."""

import numpy as np
import pytest
from PIL import Image

from solver.detect import Detector
from solver.detect.crop import Square, crop
from solver.detect.detector import DETECTION_MODEL
from solver.detect.face_detection import INPUT, anchors, decode, detect_faces, weighted_nms
from solver.paths import DETECTOR_DIR


def test_anchors_cover_the_two_grids():
    a = anchors()
    assert a.shape == (896, 2)
    np.testing.assert_allclose(a[0], [1 / 32, 1 / 32])
    np.testing.assert_allclose(a[512], [1 / 16, 1 / 16])
    np.testing.assert_allclose(a[-1], [15 / 16, 15 / 16])


def test_weighted_nms_merges_overlaps_by_score():
    raw = np.zeros((896, 16))
    raw[:, 2:4] = 20.0
    logits = np.full(896, -10.0)
    logits[[0, 2]] = [4.0, 2.0]           # two overlapping anchors in one cell row
    boxes, kps, score = decode(raw, logits)
    out = weighted_nms(boxes, kps, score)
    assert len(out) == 1
    box, _, s = out[0]
    w0, w1 = score[0], score[2]
    centre = (boxes[0, :2] * w0 + boxes[2, :2] * w1) / (w0 + w1) + 10 / 128
    np.testing.assert_allclose(box[:2] + 10 / 128, centre)
    assert s == pytest.approx(1 / (1 + np.exp(-4.0)))


@pytest.fixture(scope="module")
def network():
    if not (DETECTOR_DIR / DETECTION_MODEL).is_file():
        pytest.skip(f"models missing in {DETECTOR_DIR}: run ./run detector")
    return Detector().faces_net


def test_a_small_face_is_found_in_parts_of_the_photo(sample, network):
    folder, _ = sample
    photo = np.asarray(Image.open(folder / "front.png").convert("RGB"), np.float32) / 255
    h, w = photo.shape[:2]
    face = detect_faces(network, photo)[0]
    width = face.box[2] - face.box[0]
    assert width > 0.35 * h                      # a portrait's face: found whole
    # the photo a sixth of a 3072 px one: its face 0.07 of that, not found whole
    big = np.zeros((6 * h, 4 * w, 3), np.float32)
    big[:] = photo[2, 2]
    at = np.array([2.5 * w, 1.5 * h])
    big[int(at[1]):int(at[1]) + h, int(at[0]):int(at[0]) + w] = photo
    square = Square((2 * w, 3 * h), 6.0 * h)
    assert not _found_whole(network, big, square)
    found = detect_faces(network, big)
    assert len(found) == 1                       # once, though several parts show it
    small = found[0]
    # as the portrait's face: its box within 3 % of its width, its six points within 10 %
    assert np.abs(small.box - np.tile(at, 2) - face.box).max() < 0.03 * width
    assert np.abs(small.keypoints - at - face.keypoints).max() < 0.1 * width
    assert detect_faces(network, np.full((2048, 1536, 3), 0.5, np.float32)) == []


def _found_whole(network, image, square):
    x = crop(image, square, INPUT, border="zero") * 2 - 1
    return bool(weighted_nms(*decode(*(o[0] for o in network(x[None])))))
