"""The numpy TensorFlow Lite operators against plain-loop definitions, and the three
MediaPipe models against the reference runtime (LiteRT) to 1e-4 when it is installed."""

import numpy as np
import pytest

from solver.detect.operators import (
    Network,
    average_pool_2d,
    conv_2d,
    depthwise_conv_2d,
    hard_swish,
    logistic,
    max_pool_2d,
    resize_bilinear,
    transpose_conv_bias,
)
from solver.paths import DETECTOR_DIR

MODELS = ("face_detection_short_range.tflite", "face_landmark.tflite",
          "selfie_segmentation.tflite")


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


@pytest.mark.parametrize("k,s,padding", [(2, 2, "SAME"), (3, 2, "SAME"), (3, 1, "VALID"),
                                         (4, 4, "VALID")])
def test_average_pool_counts_only_the_photo(k, s, padding):
    rng = np.random.default_rng(k + s)
    x = rng.normal(size=(1, 8, 7, 3)).astype(np.float32)
    got = average_pool_2d(x, _options(k, s, padding))
    ones = _padded(np.ones_like(x), k, s, padding)
    xp = _padded(x, k, s, padding)
    ho, wo = (xp.shape[1] - k) // s + 1, (xp.shape[2] - k) // s + 1
    want = np.zeros((1, ho, wo, 3))
    for i in range(ho):
        for j in range(wo):
            win = (slice(i * s, i * s + k), slice(j * s, j * s + k))
            want[0, i, j] = xp[0][win].sum((0, 1)) / ones[0][win].sum((0, 1))
    np.testing.assert_allclose(got, want, atol=1e-5)


def _loop_resize(x, h, w, half_pixel):
    """TensorFlow Lite's reference ResizeBilinear, pixel by pixel."""
    out = np.zeros((1, h, w, x.shape[3]))
    hin, win = x.shape[1:3]
    for i in range(h):
        for j in range(w):
            fy = (i + 0.5) * hin / h - 0.5 if half_pixel else i * hin / h
            fx = (j + 0.5) * win / w - 0.5 if half_pixel else j * win / w
            y0, x0 = max(int(np.floor(fy)), 0), max(int(np.floor(fx)), 0)
            y1, x1 = min(int(np.ceil(fy)), hin - 1), min(int(np.ceil(fx)), win - 1)
            dy, dx = fy - y0, fx - x0
            out[0, i, j] = (x[0, y0, x0] * (1 - dy) * (1 - dx) + x[0, y1, x0] * dy * (1 - dx)
                            + x[0, y0, x1] * (1 - dy) * dx + x[0, y1, x1] * dy * dx)
    return out


@pytest.mark.parametrize("half_pixel", [True, False])
def test_resize_bilinear_matches_the_reference_kernel(half_pixel):
    x = np.random.default_rng(3).normal(size=(1, 4, 5, 2)).astype(np.float32)
    opts = {"align_corners": False, "half_pixel_centers": half_pixel}
    got = resize_bilinear(x, np.array([8, 10], np.int32), opts)
    np.testing.assert_allclose(got, _loop_resize(x, 8, 10, half_pixel), atol=1e-5)
    got = resize_bilinear(x, np.array([7, 3], np.int32), opts)
    np.testing.assert_allclose(got, _loop_resize(x, 7, 3, half_pixel), atol=1e-5)


@pytest.mark.parametrize("k,s,padding", [(2, 2, "SAME"), (3, 2, "SAME"), (3, 2, "VALID"),
                                         (4, 2, "SAME")])
def test_transpose_conv_scatters_each_pixel(k, s, padding):
    rng = np.random.default_rng(k * 7 + s)
    x = rng.normal(size=(1, 4, 3, 5)).astype(np.float32)
    wt = rng.normal(size=(2, k, k, 5)).astype(np.float32)
    b = rng.normal(size=2).astype(np.float32)
    got = transpose_conv_bias(x, wt, b, {"padding": padding, "stride_h": s, "stride_w": s})
    full = np.zeros((1, 3 * s + k, 2 * s + k, 2))
    for i in range(4):
        for j in range(3):
            full[0, i * s:i * s + k, j * s:j * s + k] += np.einsum("c,ohwc->hwo", x[0, i, j], wt)
    if padding == "SAME":
        ph, pw = max(3 * s + k - 4 * s, 0), max(2 * s + k - 3 * s, 0)
        want = full[:, ph // 2:ph // 2 + 4 * s, pw // 2:pw // 2 + 3 * s]
    else:
        want = full
    np.testing.assert_allclose(got, want + b, atol=1e-4)


def test_activations():
    x = np.linspace(-8, 8, 33, dtype=np.float32)
    np.testing.assert_allclose(hard_swish(x), x * np.minimum(np.maximum(x + 3, 0), 6) / 6,
                               atol=1e-6)
    np.testing.assert_allclose(logistic(x), 1 / (1 + np.exp(-x.astype(float))), atol=1e-6)
    assert logistic(np.float32([-1000.0]))[0] == 0.0


def _models_or_skip():
    missing = [m for m in MODELS if not (DETECTOR_DIR / m).is_file()]
    if missing:
        pytest.skip(f"{', '.join(missing)} not in {DETECTOR_DIR}: run ./run detector")
    return [DETECTOR_DIR / m for m in MODELS]


def test_models_read_and_run():
    det, mesh, _ = (Network(p) for p in _models_or_skip())
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


def test_segmentation_logits_match_the_reference_runtime():
    """The selfie segmentation's mask is a sigmoid, near 0 or 1 on most inputs: its logits
    (the last layer's input, hundreds in size) are compared too, on random inputs and on a
    bright blob on grey (a person-like mask)."""
    path = _models_or_skip()[2]
    litert = pytest.importorskip(
        "ai_edge_litert.interpreter",
        reason="the reference runtime ai-edge-litert is not installed (pip install "
               "ai-edge-litert into an environment of its own to run this test)")
    ref = litert.Interpreter(model_path=str(path), num_threads=1,
                             experimental_preserve_all_tensors=True)
    ref.allocate_tensors()
    net = Network(path)
    logits = net.graph.operators[-1].inputs[0]
    yy, xx = np.mgrid[0:256, 0:256] / 256
    head = (xx - 0.5) ** 2 / 0.06 + (yy - 0.45) ** 2 / 0.1 < 1
    blob = head | (yy > 0.8) & (abs(xx - 0.5) < 0.4)
    person = np.where(blob[..., None], [0.9, 0.7, 0.6], [0.5, 0.5, 0.5])[None]
    rng = np.random.default_rng(17)
    for x in (person.astype(np.float32), rng.uniform(0, 1, net.input_shape)):
        x = x.astype(np.float32)
        ref.set_tensor(ref.get_input_details()[0]["index"], x)
        ref.invoke()
        got_logits, got = net(x, tensors=[logits, net.graph.outputs[0]])
        want_logits = ref.get_tensor(logits)
        want = ref.get_tensor(ref.get_output_details()[0]["index"])
        assert np.abs(got_logits - want_logits).max() <= 1e-4 * np.abs(want_logits).max()
        # a logit off by float32 rounding (measured 1e-3 of 700) moves the mask by a
        # quarter of that where it crosses 0.5 (measured 1.8e-4)
        assert np.abs(got - want).max() <= 1e-3
