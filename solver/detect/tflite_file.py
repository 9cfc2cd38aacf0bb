"""Read a TensorFlow Lite model (a FlatBuffer, schema ``tensorflow/lite/schema/schema.fbs``)
into plain arrays and operator records, so :mod:`.operators` can run it with numpy.

Only what the MediaPipe face and selfie segmentation models use is read: one subgraph,
float32/float16/int32 tensors with their constant data, the options of the operators
listed in ``BUILTIN_OPS`` and MediaPipe's one custom operator in ``CUSTOM_OPS``. Anything
else is refused with a ``ValueError`` naming the file.
"""

import struct
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

# BuiltinOperator codes (schema.fbs) of the operators this reader knows.
BUILTIN_OPS = {0: "ADD", 1: "AVERAGE_POOL_2D", 2: "CONCATENATION", 3: "CONV_2D",
               4: "DEPTHWISE_CONV_2D", 6: "DEQUANTIZE", 14: "LOGISTIC", 17: "MAX_POOL_2D",
               18: "MUL", 19: "RELU", 22: "RESHAPE", 23: "RESIZE_BILINEAR", 34: "PAD",
               54: "PRELU", 117: "HARD_SWISH"}
# Custom operators (MediaPipe's, in the selfie segmentation model) by their custom code.
# Their options are a C struct of int32 (TfLiteTransposeConvParams: padding 1 SAME / 2
# VALID, stride_w, stride_h), not a FlexBuffer.
CUSTOM_OPS = {"Convolution2DTransposeBias": ("padding", "stride_w", "stride_h")}
_CUSTOM_PADDING = {1: "SAME", 2: "VALID"}
# TensorType codes -> numpy dtype.
TENSOR_TYPES = {0: np.float32, 1: np.float16, 2: np.int32}
PADDING = {0: "SAME", 1: "VALID"}
ACTIVATIONS = {0: None, 1: "RELU", 3: "RELU6"}
_POOL = {"padding": (0, "B", 0), "stride_w": (1, "i", 0), "stride_h": (2, "i", 0),
         "filter_w": (3, "i", 0), "filter_h": (4, "i", 0), "activation": (5, "B", 0)}
# Options table fields per operator: name -> (field number, struct format, default).
_OPTIONS = {
    "CONV_2D": {"padding": (0, "B", 0), "stride_w": (1, "i", 0), "stride_h": (2, "i", 0),
                "activation": (3, "B", 0), "dilation_w": (4, "i", 1),
                "dilation_h": (5, "i", 1)},
    "DEPTHWISE_CONV_2D": {"padding": (0, "B", 0), "stride_w": (1, "i", 0),
                          "stride_h": (2, "i", 0), "depth_multiplier": (3, "i", 0),
                          "activation": (4, "B", 0), "dilation_w": (5, "i", 1),
                          "dilation_h": (6, "i", 1)},
    "MAX_POOL_2D": _POOL,
    "AVERAGE_POOL_2D": _POOL,
    "ADD": {"activation": (0, "B", 0)},
    "MUL": {"activation": (0, "B", 0)},
    "RESIZE_BILINEAR": {"align_corners": (2, "?", False), "half_pixel_centers": (3, "?", False)},
    "CONCATENATION": {"axis": (0, "i", 0), "activation": (1, "B", 0)},
}


@dataclass
class Operator:
    """One node: its operator name, input and output tensor indices (-1: absent) and
    options (padding as ``"SAME"``/``"VALID"``, activation as a name or None)."""

    op: str
    inputs: list
    outputs: list
    options: dict = field(default_factory=dict)


@dataclass
class Graph:
    """A model's only subgraph: tensor names, shapes, dtypes, constant data (None for
    activations), the graph inputs and outputs, and the operators in execution order."""

    names: list
    shapes: list
    dtypes: list
    constants: list
    inputs: list
    outputs: list
    operators: list


class _Buf:
    """FlatBuffer access: tables through their vtables, vectors, strings."""

    def __init__(self, data, path):
        self.data = data
        self.path = path

    def u32(self, pos):
        return struct.unpack_from("<I", self.data, pos)[0]

    def check(self, pos, size):
        if pos < 0 or pos + size > len(self.data):
            raise ValueError(f"{self.path}: not a TensorFlow Lite model "
                             f"(offset {pos} outside the file)")

    def field(self, table, number):
        """Position of field ``number`` of the table at ``table``, or None if absent."""
        self.check(table, 4)
        vtable = table - struct.unpack_from("<i", self.data, table)[0]
        self.check(vtable, 4)
        vsize = struct.unpack_from("<H", self.data, vtable)[0]
        slot = 4 + 2 * number
        if slot + 2 > vsize:
            return None
        off = struct.unpack_from("<H", self.data, vtable + slot)[0]
        return table + off if off else None

    def scalar(self, table, number, fmt, default):
        pos = self.field(table, number)
        if pos is None:
            return default
        self.check(pos, struct.calcsize(fmt))
        return struct.unpack_from("<" + fmt, self.data, pos)[0]

    def ref(self, table, number):
        pos = self.field(table, number)
        return None if pos is None else pos + self.u32(pos)

    def vector(self, table, number):
        """(start, length) of a vector field; (0, 0) when absent."""
        pos = self.ref(table, number)
        if pos is None:
            return 0, 0
        self.check(pos, 4)
        return pos + 4, self.u32(pos)

    def ints(self, table, number, dtype="<i4"):
        start, n = self.vector(table, number)
        self.check(start, 4 * n)
        return np.frombuffer(self.data, dtype, n, start).tolist() if n else []

    def tables(self, table, number):
        start, n = self.vector(table, number)
        self.check(start, 4 * n)
        return [start + 4 * i + self.u32(start + 4 * i) for i in range(n)]

    def string(self, table, number):
        start, n = self.vector(table, number)
        self.check(start, n)
        return bytes(self.data[start:start + n]).decode("utf-8", "replace") if n else ""


def _custom_options(fb, operator, op, path):
    """A custom operator's options: its int32 fields (``CUSTOM_OPS``) from the raw bytes."""
    keys = CUSTOM_OPS[op]
    start, n = fb.vector(operator, 5)
    if n != 4 * len(keys):
        raise ValueError(f"{path}: {op} options of {n} bytes, expected {4 * len(keys)}")
    fb.check(start, n)
    values = dict(zip(keys, struct.unpack_from(f"<{len(keys)}i", fb.data, start), strict=True))
    if "padding" in values:
        if values["padding"] not in _CUSTOM_PADDING:
            raise ValueError(f"{path}: {op} padding {values['padding']} is not supported")
        values["padding"] = _CUSTOM_PADDING[values["padding"]]
    return values


def read_tflite(path):
    """The graph of the TensorFlow Lite model at ``path``.

    Returns
    -------
    Graph
        Constant tensors as numpy arrays of their stored dtype (float16 weights stay
        float16 until a DEQUANTIZE node widens them, as in the reference runtime).
    """
    path = Path(path)
    data = path.read_bytes()
    if len(data) < 8 or data[4:8] != b"TFL3":
        raise ValueError(f"{path}: not a TensorFlow Lite model (no TFL3 identifier)")
    fb = _Buf(data, path)
    model = fb.u32(0)
    codes = []
    for oc in fb.tables(model, 1):
        code = max(fb.scalar(oc, 0, "b", 0), fb.scalar(oc, 3, "i", 0))
        if code == 32:
            custom = fb.string(oc, 1)
            codes.append(custom if custom in CUSTOM_OPS else f"custom {custom}")
        else:
            codes.append(BUILTIN_OPS.get(code, f"builtin {code}"))
    subgraphs = fb.tables(model, 2)
    if len(subgraphs) != 1:
        raise ValueError(f"{path}: {len(subgraphs)} subgraphs; only one is supported")
    buffers = fb.tables(model, 4)
    sg = subgraphs[0]
    names, shapes, dtypes, constants = [], [], [], []
    for t in fb.tables(sg, 0):
        shape = tuple(fb.ints(t, 0))
        ttype = fb.scalar(t, 1, "B", 0)
        name = fb.string(t, 3)
        if ttype not in TENSOR_TYPES:
            raise ValueError(f"{path}: tensor {name!r} has type {ttype}, not float32, "
                             f"float16 or int32")
        if fb.field(t, 6) is not None:
            raise ValueError(f"{path}: tensor {name!r} is sparse; not supported")
        dtype = TENSOR_TYPES[ttype]
        b = fb.scalar(t, 2, "I", 0)
        const = None
        if 0 < b < len(buffers):
            start, n = fb.vector(buffers[b], 0)
            if n == 0 and fb.scalar(buffers[b], 1, "Q", 0):
                raise ValueError(f"{path}: tensor {name!r} stores its data outside the "
                                 f"FlatBuffer; not supported")
            if n:
                fb.check(start, n)
                const = np.frombuffer(data, dtype, n // np.dtype(dtype).itemsize,
                                      start).reshape(shape)
        names.append(name)
        shapes.append(shape)
        dtypes.append(dtype)
        constants.append(const)
    operators = []
    for o in fb.tables(sg, 3):
        index = fb.scalar(o, 0, "I", 0)
        if index >= len(codes):
            raise ValueError(f"{path}: operator code {index} out of range")
        op = codes[index]
        if op not in BUILTIN_OPS.values() and op not in CUSTOM_OPS:
            raise ValueError(f"{path}: operator {op} is not supported")
        options = {}
        if op in CUSTOM_OPS:
            options = _custom_options(fb, o, op, path)
        spec = _OPTIONS.get(op)
        if spec:
            table = fb.ref(o, 4)
            for key, (number, fmt, default) in spec.items():
                options[key] = (default if table is None
                                else fb.scalar(table, number, fmt, default))
            if "padding" in options:
                options["padding"] = PADDING[options["padding"]]
            if "activation" in options:
                if options["activation"] not in ACTIVATIONS:
                    raise ValueError(f"{path}: {op} activation {options['activation']} "
                                     f"is not supported")
                options["activation"] = ACTIVATIONS[options["activation"]]
        operators.append(Operator(op, fb.ints(o, 1), fb.ints(o, 2), options))
    return Graph(names, shapes, dtypes, constants, fb.ints(sg, 1), fb.ints(sg, 2),
                 operators)
