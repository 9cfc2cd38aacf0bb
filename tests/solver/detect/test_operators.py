"""The numpy TensorFlow Lite operators against plain-loop definitions, and the two
MediaPipe models against the reference runtime (LiteRT) to 1e-4 when it is installed."""

import numpy as np
import pytest

from solver.detect.operators import Network, conv_2d, depthwise_conv_2d, max_pool_2d
from solver.paths import DETECTOR_DIR

MODELS = ("face_detection_short_range.tflite", "face_landmark.tflite")


def _padded(x, k, s, padding, value=0.0):
    if padding == "VALID":
        return x
    h, w = x.shape[1:3]
    ph = max((-(-h // s) - 1) * s + k - h, 0)
    pw = max((-(-w // s) - 1) * s + k - w, 0)
    return np.pad(x, ((0, 0), (ph // 2, ph - ph // 2), (pw // 2, pw - pw // 2), (0, 0)),
                  constant_values=value)


def _loop_conv(x, wt, b, s, padding, depthwise=False):
    k = wt.shape[1]
    xp = _padded(x, k, s, padding).astype(float)
    ho, wo = (xp.shape[1] - k) // s + 1, (xp.shape[2] - k) // s + 1
    out = np.zeros((1, ho, wo, wt.shape[3] if depthwise else wt.shape[0]))
    for i in range(ho):
        for j in range(wo):
            patch = xp[0, i * s:i * s + k, j * s:j * s + k]
            if depthwise:
                out[0, i, j] = (patch * wt[0]).sum((0, 1))
            else:
                out[0, i, j] = np.einsum("hwc,ohwc->o", patch, wt)
    return out + b


def _options(k, s, padding, **kw):
    return {"padding": padding, "stride_h": s, "stride_w": s, "dilation_h": 1,
            "dilation_w": 1, "activation": None, "filter_h": k, "filter_w": k, **kw}


@pytest.mark.parametrize("k,s,padding", [(1, 1, "SAME"), (3, 2, "SAME"), (5, 1, "SAME"),
                                         (2, 2, "VALID"), (3, 1, "VALID")])
def test_convolutions_match_loops(k, s, padding):
    rng = np.random.default_rng(k * 10 + s)
    x = rng.normal(size=(1, 7, 6, 4)).astype(np.float32)
    wt = rng.normal(size=(5, k, k, 4)).astype(np.float32)
    b = rng.normal(size=5).astype(np.float32)
    got = conv_2d(x, wt, b, _options(k, s, padding))
    np.testing.assert_allclose(got, _loop_conv(x, wt, b, s, padding), atol=1e-4)
    wd = rng.normal(size=(1, k, k, 4)).astype(np.float32)
    got = depthwise_conv_2d(x, wd, b[:4], _options(k, s, padding))
    np.testing.assert_allclose(got, _loop_conv(x, wd, b[:4], s, padding, True), atol=1e-4)


def test_max_pool_ignores_padding_and_relu_is_fused():
    x = -np.arange(1, 26, dtype=np.float32).reshape(1, 5, 5, 1)
    got = max_pool_2d(x, _options(2, 2, "SAME"))
    assert got.shape == (1, 3, 3, 1)
    assert got[0, 2, 2, 0] == -25.0            # the padded cells (0) never win
    assert got[0, 0, 0, 0] == -1.0
    relu = conv_2d(x, -np.ones((1, 1, 1, 1), np.float32), None,
                   _options(1, 1, "SAME", activation="RELU"))
    np.testing.assert_array_equal(relu, -x)


def _models_or_skip():
    missing = [m for m in MODELS if not (DETECTOR_DIR / m).is_file()]
    if missing:
        pytest.skip(f"{', '.join(missing)} not in {DETECTOR_DIR}: run ./run detector")
    return [DETECTOR_DIR / m for m in MODELS]


def test_models_read_and_run():
    det, mesh = (Network(p) for p in _models_or_skip())
    assert det.input_shape == (1, 128, 128, 3) and mesh.input_shape == (1, 192, 192, 3)
    regressors, scores = det(np.zeros(det.input_shape, np.float32))
    assert regressors.shape == (1, 896, 16) and scores.shape == (1, 896, 1)
    points, flag = mesh(np.full(mesh.input_shape, 0.5, np.float32))
    assert points.shape == (1, 1, 1, 1404) and flag.shape == (1, 1, 1, 1)
    assert np.isfinite(points).all()
    with pytest.raises(ValueError, match="input shape"):
        det(np.zeros((1, 64, 64, 3)))


@pytest.mark.parametrize("model", MODELS)
def test_models_match_the_reference_runtime(model):
    path = dict(zip(MODELS, _models_or_skip(), strict=True))[model]
    litert = pytest.importorskip(
        "ai_edge_litert.interpreter",
        reason="the reference runtime ai-edge-litert is not installed (pip install "
               "ai-edge-litert into an environment of its own to run this test)")
    ref = litert.Interpreter(model_path=str(path), num_threads=1)
    ref.allocate_tensors()
    net = Network(path)
    rng = np.random.default_rng(16)
    for _ in range(3):
        x = rng.uniform(0, 1, net.input_shape).astype(np.float32)
        ref.set_tensor(ref.get_input_details()[0]["index"], x)
        ref.invoke()
        for d, got in zip(ref.get_output_details(), net(x), strict=True):
            want = ref.get_tensor(d["index"])
            # float32 sums in another order: 1e-4 of the output's own scale
            assert np.abs(got - want).max() <= 1e-4 * max(1.0, np.abs(want).max())
