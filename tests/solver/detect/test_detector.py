"""Detection's geometry (anchors, suppression, crops, the iBUG map) and the detector on
photos without a face."""

import numpy as np
import pytest

from solver.detect import Detector, mesh_to_ibug
from solver.detect.crop import Square, crop
from solver.detect.face_detection import anchors, decode, weighted_nms
from solver.detect.ibug_map import ibug_map
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


def test_crop_rotates_and_maps_back():
    image = np.zeros((60, 80, 3), np.float32)
    image[20:30, 40:50] = 1.0                     # a bright square centred at (45, 25)
    sq = Square((45.0, 25.0), 20.0, np.pi / 2)
    out = crop(image, sq, 20, border="zero")
    # crop pixel (row j, column i) samples the pixel centred at (45 - (j - 10), 25 + i - 10)
    bright = np.zeros((20, 20), bool)
    bright[6:16, 5:15] = True
    np.testing.assert_allclose(out[..., 0], bright.astype(float), atol=1e-6)
    # the crop's x axis runs down the photo
    np.testing.assert_allclose(sq.to_photo(np.array([[20.0, 10.0]]), 20), [[45.0, 35.0]])


def test_ibug_map_averages_mesh_points():
    m = ibug_map()
    assert m.shape == (68, 468)
    np.testing.assert_allclose(m.sum(1), 1.0)
    mesh = np.random.default_rng(0).normal(size=(468, 2))
    np.testing.assert_allclose(mesh_to_ibug(mesh)[8], mesh[152])   # iBUG 9: the menton


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
