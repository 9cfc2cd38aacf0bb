"""The TensorFlow Lite reader: the models' operators and tensors, and bad files refused
with the file named."""

import numpy as np
import pytest

from solver.detect.tflite_file import read_tflite
from solver.paths import DETECTOR_DIR


def test_not_a_model_is_refused(tmp_path):
    bad = tmp_path / "bad.tflite"
    bad.write_bytes(b"\x00" * 64)
    with pytest.raises(ValueError, match="bad.tflite: not a TensorFlow Lite model"):
        read_tflite(bad)
    cut = tmp_path / "cut.tflite"
    cut.write_bytes(b"\xff\xff\x00\x00TFL3" + b"\x00" * 8)
    with pytest.raises(ValueError, match="cut.tflite"):
        read_tflite(cut)


def test_face_mesh_graph():
    path = DETECTOR_DIR / "face_landmark.tflite"
    if not path.is_file():
        pytest.skip(f"{path} missing: run ./run detector")
    g = read_tflite(path)
    ops = [o.op for o in g.operators]
    assert {op: ops.count(op) for op in set(ops)} == {
        "DEQUANTIZE": 113, "CONV_2D": 25, "PRELU": 23, "DEPTHWISE_CONV_2D": 20, "ADD": 20,
        "MAX_POOL_2D": 6, "PAD": 3}
    assert [g.names[i] for i in g.outputs] == ["conv2d_21", "conv2d_31"]
    assert g.shapes[g.inputs[0]] == (1, 192, 192, 3)
    weights = [c for c in g.constants if c is not None and c.dtype == np.float16]
    assert len(weights) == 113 and all(np.isfinite(w).all() for w in weights)


def test_selfie_segmentation_graph():
    path = DETECTOR_DIR / "selfie_segmentation.tflite"
    if not path.is_file():
        pytest.skip(f"{path} missing: run ./run detector")
    g = read_tflite(path)
    ops = [o.op for o in g.operators]
    assert {op: ops.count(op) for op in set(ops)} == {
        "DEQUANTIZE": 110, "CONV_2D": 43, "RELU": 22, "ADD": 14, "HARD_SWISH": 11,
        "DEPTHWISE_CONV_2D": 11, "LOGISTIC": 11, "AVERAGE_POOL_2D": 10, "MUL": 10,
        "RESIZE_BILINEAR": 3, "Convolution2DTransposeBias": 1}
    up = next(o for o in g.operators if o.op == "Convolution2DTransposeBias")
    assert up.options == {"padding": "SAME", "stride_w": 2, "stride_h": 2}
    resize = next(o for o in g.operators if o.op == "RESIZE_BILINEAR")
    assert resize.options == {"align_corners": False, "half_pixel_centers": True}
    assert g.shapes[g.inputs[0]] == (1, 256, 256, 3)
    assert g.shapes[g.outputs[0]] == (1, 256, 256, 1)
