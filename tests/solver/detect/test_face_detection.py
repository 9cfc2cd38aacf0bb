"""BlazeFace's anchors, decoding and weighted suppression."""

import numpy as np
import pytest

from solver.detect.face_detection import anchors, decode, weighted_nms


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
