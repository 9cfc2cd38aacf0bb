"""JPEG bytes with an EXIF segment, built in the tests (no binary fixtures): the EXIF
reader's tests and the add-on's photo loading use them."""

import io
import struct

import numpy as np

from solver.io import exif

_FMT = {3: "H", 4: "I"}


def tiff(ifd0, sub=None, order="<"):
    """TIFF bytes with IFD0 ``ifd0`` and, if given, an EXIF sub-IFD ``sub``: each a list
    of (tag, type, values) with type 3 SHORT, 4 LONG, 5 RATIONAL ((num, den) pairs)."""
    mark = b"II" if order == "<" else b"MM"
    ifd0 = list(ifd0)

    def ifd_size(entries):
        return 2 + 12 * len(entries) + 4

    def payload(typ, values):
        if typ == 5:
            return b"".join(struct.pack(order + "II", n, d) for n, d in values)
        return b"".join(struct.pack(order + _FMT[typ], v) for v in values)

    if sub is not None:
        ifd0.append((exif.EXIF_IFD, 4, [0]))  # offset filled below
    start0 = 8
    extra0 = sum(len(payload(t, v)) for _, t, v in ifd0 if len(payload(t, v)) > 4)
    start_sub = start0 + ifd_size(ifd0) + extra0
    if sub is not None:
        ifd0[-1] = (exif.EXIF_IFD, 4, [start_sub])

    def build(entries, start):
        head = struct.pack(order + "H", len(entries))
        tail = b""
        data_at = start + ifd_size(entries)
        for tag, typ, values in entries:
            raw = payload(typ, values)
            count = len(values)
            if len(raw) <= 4:
                field = raw.ljust(4, b"\0")
            else:
                field = struct.pack(order + "I", data_at + len(tail))
                tail += raw
            head += struct.pack(order + "HHI", tag, typ, count) + field
        return head + struct.pack(order + "I", 0) + tail

    out = mark + struct.pack(order + "HI", 42, start0) + build(ifd0, start0)
    if sub is not None:
        assert len(out) == start_sub
        out += build(sub, start_sub)
    return out


def jpeg(tiff_bytes=None, size=(6, 4), pixels=None):
    """A real JPEG (Pillow's encoder) with an APP1 EXIF segment holding ``tiff_bytes``."""
    from PIL import Image

    if pixels is None:
        w, h = size
        pixels = np.zeros((h, w, 3), np.uint8)
    buf = io.BytesIO()
    Image.fromarray(pixels).save(buf, "JPEG", quality=95)
    data = buf.getvalue()
    if tiff_bytes is None:
        return data
    body = b"Exif\x00\x00" + tiff_bytes
    return data[:2] + b"\xff\xe1" + struct.pack(">H", len(body) + 2) + body + data[2:]
