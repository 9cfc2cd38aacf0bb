"""The TensorFlow Lite operators the MediaPipe face and selfie segmentation models use, in
vectorised numpy (float32, NHWC, batch 1), and :class:`Network`, which runs a
:class:`~.tflite_file.Graph`.

Each operator follows the reference kernels of TensorFlow Lite (``SAME`` padding puts the
odd pixel after, pooling ignores padded cells), so outputs match the reference runtime to
float32 rounding.
"""

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from .tflite_file import read_tflite


def _same_pads(size, kernel, stride):
    out = -(-size // stride)
    total = max((out - 1) * stride + kernel - size, 0)
    return total // 2, total - total // 2


def _pad_hw(x, kh, kw, sh, sw, padding, value=0.0):
    if padding == "VALID":
        return x
    top, bottom = _same_pads(x.shape[1], kh, sh)
    left, right = _same_pads(x.shape[2], kw, sw)
    if top == bottom == left == right == 0:
        return x
    return np.pad(x, ((0, 0), (top, bottom), (left, right), (0, 0)), constant_values=value)


def _activate(x, activation):
    if activation == "RELU":
        return np.maximum(x, 0, out=x)
    if activation == "RELU6":
        return np.clip(x, 0, 6, out=x)
    return x


def _out_size(size, kernel, stride):
    return (size - kernel) // stride + 1


def conv_2d(x, weights, bias, options):
    """2-D convolution: ``x`` (1, H, W, I), ``weights`` (O, kh, kw, I), ``bias`` (O,)."""
    _no_dilation(options)
    o, kh, kw, i = weights.shape
    sh, sw = options["stride_h"], options["stride_w"]
    x = _pad_hw(x, kh, kw, sh, sw, options["padding"])
    if kh == kw == 1:
        cols = x[:, ::sh, ::sw, :]
        out = cols.reshape(-1, i) @ weights.reshape(o, i).T
        out = out.reshape(cols.shape[:3] + (o,))
    else:
        ho, wo = _out_size(x.shape[1], kh, sh), _out_size(x.shape[2], kw, sw)
        win = sliding_window_view(x, (kh, kw), axis=(1, 2))[:, :ho * sh:sh, :wo * sw:sw]
        # win: (1, ho, wo, I, kh, kw) against weights (O, kh, kw, I).
        out = np.tensordot(win, weights, axes=((3, 4, 5), (3, 1, 2)))
    if bias is not None:
        out += bias
    return _activate(out.astype(np.float32, copy=False), options["activation"])


def depthwise_conv_2d(x, weights, bias, options):
    """Depthwise convolution, one filter per channel: ``weights`` (1, kh, kw, C)."""
    _no_dilation(options)
    _, kh, kw, c = weights.shape
    if c != x.shape[3]:
        raise ValueError(f"depthwise convolution with multiplier {c // x.shape[3]} "
                         f"is not supported")
    sh, sw = options["stride_h"], options["stride_w"]
    x = _pad_hw(x, kh, kw, sh, sw, options["padding"])
    ho, wo = _out_size(x.shape[1], kh, sh), _out_size(x.shape[2], kw, sw)
    out = np.zeros((x.shape[0], ho, wo, c), np.float32)
    for a in range(kh):
        for b in range(kw):
            out += x[:, a:a + ho * sh:sh, b:b + wo * sw:sw, :] * weights[0, a, b]
    if bias is not None:
        out += bias
    return _activate(out, options["activation"])


def max_pool_2d(x, options):
    """Max pooling; padded cells never win (TensorFlow Lite's rule)."""
    kh, kw = options["filter_h"], options["filter_w"]
    sh, sw = options["stride_h"], options["stride_w"]
    x = _pad_hw(x, kh, kw, sh, sw, options["padding"], value=-np.inf)
    ho, wo = _out_size(x.shape[1], kh, sh), _out_size(x.shape[2], kw, sw)
    out = np.full((x.shape[0], ho, wo, x.shape[3]), -np.inf, np.float32)
    for a in range(kh):
        for b in range(kw):
            np.maximum(out, x[:, a:a + ho * sh:sh, b:b + wo * sw:sw, :], out=out)
    return _activate(out, options["activation"])


def average_pool_2d(x, options):
    """Average pooling; padded cells are not counted (TensorFlow Lite's rule). The
    segmentation model's global pooling (one window over the whole map) is one mean."""
    kh, kw = options["filter_h"], options["filter_w"]
    sh, sw = options["stride_h"], options["stride_w"]
    h, w = x.shape[1:3]
    if options["padding"] == "VALID" and (kh, kw) == (sh, sw) and h % kh == 0 \
            and w % kw == 0:
        blocks = x.reshape(x.shape[0], h // kh, kh, w // kw, kw, x.shape[3])
        return _activate(blocks.mean((2, 4), dtype=np.float32), options["activation"])
    ones = np.ones((1, h, w, 1), np.float32)
    x, ones = _pad_hw(x, kh, kw, sh, sw, options["padding"]), _pad_hw(ones, kh, kw, sh, sw,
                                                                      options["padding"])
    ho, wo = _out_size(x.shape[1], kh, sh), _out_size(x.shape[2], kw, sw)
    total = np.zeros((x.shape[0], ho, wo, x.shape[3]), np.float32)
    count = np.zeros((1, ho, wo, 1), np.float32)
    for a in range(kh):
        for b in range(kw):
            total += x[:, a:a + ho * sh:sh, b:b + wo * sw:sw, :]
            count += ones[:, a:a + ho * sh:sh, b:b + wo * sw:sw, :]
    return _activate(total / count, options["activation"])


def resize_bilinear(x, size, options):
    """Bilinear resize of ``x`` (1, H, W, C) to ``size`` (h, w), TensorFlow Lite's
    coordinates: ``half_pixel_centers`` samples (i + 0.5) · H / h - 0.5, else i · H / h
    (``align_corners``: i · (H - 1) / (h - 1)); samples outside clamp to the edge."""
    out_h, out_w = (int(v) for v in np.asarray(size).ravel())

    def axis(n_in, n_out):
        if options["align_corners"] and n_out > 1:
            pos = np.arange(n_out) * ((n_in - 1) / (n_out - 1))
        elif options["half_pixel_centers"]:
            pos = (np.arange(n_out) + 0.5) * (n_in / n_out) - 0.5
        else:
            pos = np.arange(n_out) * (n_in / n_out)
        pos = np.clip(pos, 0, n_in - 1)
        lo = np.floor(pos).astype(int)
        return lo, np.minimum(lo + 1, n_in - 1), (pos - lo).astype(np.float32)

    y0, y1, fy = axis(x.shape[1], out_h)
    x0, x1, fx = axis(x.shape[2], out_w)
    fx = fx[:, None]
    top = x[:, y0][:, :, x0] * (1 - fx) + x[:, y0][:, :, x1] * fx
    bottom = x[:, y1][:, :, x0] * (1 - fx) + x[:, y1][:, :, x1] * fx
    fy = fy[:, None, None]
    return (top * (1 - fy) + bottom * fy).astype(np.float32)


def transpose_conv_bias(x, weights, bias, options):
    """Transposed convolution plus bias (MediaPipe's custom ``Convolution2DTransposeBias``,
    TensorFlow Lite's TRANSPOSE_CONV with a bias): ``x`` (1, H, W, I), ``weights``
    (O, kh, kw, I); each input pixel spreads its ``weights`` over a kh × kw patch of the
    output at ``stride``; the output is H·stride (``SAME``) or (H - 1)·stride + kh
    (``VALID``), the patches' overhang cut as in TensorFlow Lite (the odd pixel after)."""
    o, kh, kw, i = weights.shape
    sh, sw = options["stride_h"], options["stride_w"]
    n, h, w, _ = x.shape
    full_h, full_w = (h - 1) * sh + kh, (w - 1) * sw + kw
    if options["padding"] == "SAME":
        out_h, out_w = h * sh, w * sw
    else:
        out_h, out_w = full_h, full_w
    top, left = max(full_h - out_h, 0) // 2, max(full_w - out_w, 0) // 2
    # every input pixel times every kernel tap: (n, h, w, kh, kw, O)
    taps = np.tensordot(x, weights, axes=((3,), (3,))).transpose(0, 1, 2, 4, 5, 3)
    full = np.zeros((n, max(full_h, out_h + top), max(full_w, out_w + left), o), np.float32)
    for a in range(kh):
        for b in range(kw):
            full[:, a:a + (h - 1) * sh + 1:sh, b:b + (w - 1) * sw + 1:sw] += taps[:, :, :, a, b]
    out = full[:, top:top + out_h, left:left + out_w]
    if bias is not None:
        out = out + bias
    return out.astype(np.float32, copy=False)


def hard_swish(x):
    """x · relu6(x + 3) / 6."""
    return x * np.clip(x + 3, 0, 6) / 6


def logistic(x):
    """1 / (1 + e^-x), without overflow for large negative x."""
    return (0.5 * (1 + np.tanh(0.5 * x))).astype(np.float32)


def _no_dilation(options):
    if options["dilation_h"] != 1 or options["dilation_w"] != 1:
        raise ValueError("dilated convolutions are not supported")


def _reshape(x, shape_tensor, shape):
    target = shape_tensor if shape_tensor is not None else shape
    return x.reshape(tuple(int(s) for s in np.asarray(target).ravel()))


class Network:
    """A TensorFlow Lite model ready to run: constants widened to float32 once.

    Parameters
    ----------
    path : str or Path
        The ``.tflite`` file.
    """

    def __init__(self, path):
        self.path = path
        g = read_tflite(path)
        self.graph = g
        self.constants = {i: c for i, c in enumerate(g.constants) if c is not None}
        for node in g.operators:       # DEQUANTIZE of a constant: done once, here
            if node.op == "DEQUANTIZE" and node.inputs[0] in self.constants:
                self.constants[node.outputs[0]] = (
                    self.constants[node.inputs[0]].astype(np.float32))
        self.nodes = [n for n in g.operators
                      if not (n.op == "DEQUANTIZE" and n.inputs[0] in self.constants)]
        self.input_shape = g.shapes[g.inputs[0]]

    def __call__(self, x, tensors=None):
        """Outputs of the model for input ``x`` (its input shape), as float32 arrays; or
        the tensors of the given indices (``graph.names``), e.g. a layer inside."""
        x = np.asarray(x, np.float32)
        if x.shape != self.input_shape:
            raise ValueError(f"{self.path}: input shape {x.shape}, expected "
                             f"{self.input_shape}")
        t = dict(self.constants)
        t[self.graph.inputs[0]] = x
        for n in self.nodes:
            args = [t[i] if i >= 0 else None for i in n.inputs]
            t[n.outputs[0]] = self._run(n, args)
        return [t[i] for i in (self.graph.outputs if tensors is None else tensors)]

    def _run(self, n, args):
        op, o = n.op, n.options
        if op == "CONV_2D":
            return conv_2d(args[0], args[1], args[2] if len(args) > 2 else None, o)
        if op == "DEPTHWISE_CONV_2D":
            return depthwise_conv_2d(args[0], args[1], args[2] if len(args) > 2 else None, o)
        if op == "MAX_POOL_2D":
            return max_pool_2d(args[0], o)
        if op == "ADD":
            return _activate(args[0] + args[1], o["activation"])
        if op == "MUL":
            return _activate(args[0] * args[1], o["activation"])
        if op == "AVERAGE_POOL_2D":
            return average_pool_2d(args[0], o)
        if op == "RESIZE_BILINEAR":
            return resize_bilinear(args[0], args[1], o)
        if op == "Convolution2DTransposeBias":
            return transpose_conv_bias(args[0], args[1], args[2] if len(args) > 2 else None,
                                       o)
        if op == "HARD_SWISH":
            return hard_swish(args[0])
        if op == "LOGISTIC":
            return logistic(args[0])
        if op == "RELU":
            return np.maximum(args[0], 0)
        if op == "PRELU":
            x, alpha = args
            return np.where(x >= 0, x, x * alpha)
        if op == "PAD":
            return np.pad(args[0], np.asarray(args[1]).reshape(-1, 2))
        if op == "RESHAPE":
            out_shape = self.graph.shapes[n.outputs[0]]
            return _reshape(args[0], args[1] if len(args) > 1 else None, out_shape)
        if op == "CONCATENATION":
            return _activate(np.concatenate(args, axis=o["axis"]), o["activation"])
        if op == "DEQUANTIZE":
            return args[0].astype(np.float32)
        raise ValueError(f"{self.path}: operator {op} is not supported")
