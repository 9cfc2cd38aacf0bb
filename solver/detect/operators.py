"""The TensorFlow Lite operators the MediaPipe face models use, in vectorised numpy
(float32, NHWC, batch 1), and :class:`Network`, which runs a :class:`~.tflite_file.Graph`.

Each operator follows the reference kernels of TensorFlow Lite (``SAME`` padding puts the
odd pixel after, max pooling ignores padded cells), so outputs match the reference
runtime to float32 rounding.
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

    def __call__(self, x):
        """Outputs of the model for input ``x`` (its input shape), as float32 arrays."""
        x = np.asarray(x, np.float32)
        if x.shape != self.input_shape:
            raise ValueError(f"{self.path}: input shape {x.shape}, expected "
                             f"{self.input_shape}")
        t = dict(self.constants)
        t[self.graph.inputs[0]] = x
        for n in self.nodes:
            args = [t[i] if i >= 0 else None for i in n.inputs]
            t[n.outputs[0]] = self._run(n, args)
        return [t[i] for i in self.graph.outputs]

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
