"""The EXIF data of a JPEG photo that a head fit can use: how the photo is turned
(Orientation) and the lens's focal length. Blender ships no EXIF parser and Pillow is not
in Blender, so the APP1 segment's TIFF structure is read here, bounds-checked throughout.

Only the tags below are read; everything else in the file is skipped. A photo that is no
JPEG or has no EXIF gives None; EXIF that cannot be read raises ``ValueError`` from
``parse_exif`` (``read_photo_exif`` turns that into one line naming the file, never an
error, so a bad EXIF never stops a photo from loading).
"""

import dataclasses
import math
import struct
from pathlib import Path

import numpy as np

# Tags (EXIF 2.32 / CIPA DC-008)
ORIENTATION = 0x0112
EXIF_IFD = 0x8769
FOCAL_LENGTH = 0x920A
FOCAL_35MM = 0xA405
FOCAL_PLANE_X_RES = 0xA20E
FOCAL_PLANE_Y_RES = 0xA20F
FOCAL_PLANE_UNIT = 0xA210
PIXEL_X = 0xA002
PIXEL_Y = 0xA003

# FocalPlaneResolutionUnit -> millimetres per unit (2 inch, the default; 3 cm; 4 mm; 5 µm)
UNIT_MM = {2: 25.4, 3: 10.0, 4: 1.0, 5: 0.001}
FULL_FRAME_LONG_MM = 36.0  # the long side the project's "36 mm equivalent" refers to
FULL_FRAME_DIAGONAL_MM = math.hypot(36.0, 24.0)  # what FocalLengthIn35mmFilm is scaled by

_TYPE_SIZE = {1: 1, 2: 1, 3: 2, 4: 4, 5: 8, 7: 1, 9: 4, 10: 8, 11: 4, 12: 8}
_MAX_ENTRIES = 1000  # a real IFD has tens; more means garbage


@dataclasses.dataclass(frozen=True)
class Exif:
    """What the photo's EXIF says (None: the tag is absent or unusable).

    orientation : int
        1-8 as EXIF defines it (1: stored upright; 6: turn 90° clockwise to view).
    focal_length_mm : float
        The lens's real focal length (mm).
    focal_35mm : float
        FocalLengthIn35mmFilm (mm), the camera's own full-frame equivalent (by the
        diagonal, as cameras and phones compute it).
    focal_plane_resolution : (float, float)
        Sensor pixels per ``focal_plane_unit_mm`` across x and y of the stored image.
    focal_plane_unit_mm : float
        Millimetres per unit of the focal plane resolution.
    pixel_size : (int, int)
        PixelXDimension, PixelYDimension: the stored image's size the camera wrote.
    """

    orientation: int = 1
    focal_length_mm: float | None = None
    focal_35mm: float | None = None
    focal_plane_resolution: tuple | None = None
    focal_plane_unit_mm: float | None = None
    pixel_size: tuple | None = None

    def lens_36mm(self, size):
        """The focal length as the project states it: mm on a sensor 36 mm across the
        photo's long side (``PinholeCamera``'s ``lens_mm``), or None when EXIF does not say.

        From FocalLengthIn35mmFilm, rescaled from the diagonal to the long side (equal for
        3:2 photos, 4 % longer for 4:3 phone photos); else from FocalLength and the focal
        plane resolution (the sensor's size).

        Parameters
        ----------
        size : (int, int)
            The photo's stored size (w, h) in pixels (before orientation).
        """
        w, h = (float(s) for s in size)
        if w <= 0 or h <= 0:
            return None
        long_px = max(w, h)
        if self.focal_35mm:
            scale = (FULL_FRAME_LONG_MM / FULL_FRAME_DIAGONAL_MM) * math.hypot(w, h) / long_px
            return float(self.focal_35mm) * scale
        if self.focal_length_mm and self.focal_plane_resolution and self.focal_plane_unit_mm:
            xres, yres = self.focal_plane_resolution
            sensor = self.pixel_size or (w, h)
            # the sensor's long side in mm, from the pixel grid the camera wrote
            long_mm = (sensor[0] / xres if w >= h else sensor[1] / yres) * \
                self.focal_plane_unit_mm
            if long_mm > 0:
                return float(self.focal_length_mm) * FULL_FRAME_LONG_MM / long_mm
        return None


def _jpeg_app1(data):
    """The EXIF payload (TIFF bytes) of a JPEG's APP1 segment, or None."""
    if data[:2] != b"\xff\xd8":
        return None
    i = 2
    while i + 4 <= len(data):
        if data[i] != 0xFF:
            raise ValueError(f"JPEG segment marker expected at byte {i}")
        marker = data[i + 1]
        if marker == 0xFF:  # fill byte
            i += 1
            continue
        if marker in (0xD9, 0xDA):  # end of image, start of scan: no EXIF before the pixels
            return None
        if 0xD0 <= marker <= 0xD7 or marker == 0x01:  # markers without a length
            i += 2
            continue
        (length,) = struct.unpack(">H", data[i + 2:i + 4])
        if length < 2 or i + 2 + length > len(data):
            raise ValueError(f"JPEG segment at byte {i} runs past the end of the file")
        body = data[i + 4:i + 2 + length]
        if marker == 0xE1 and body[:6] == b"Exif\x00\x00":
            return body[6:]
        i += 2 + length
    return None


class _Tiff:
    """Bounds-checked reading of a TIFF structure (EXIF's container)."""

    def __init__(self, data):
        if len(data) < 8:
            raise ValueError("EXIF header is cut short")
        order = data[:2]
        if order == b"II":
            self.end = "<"
        elif order == b"MM":
            self.end = ">"
        else:
            raise ValueError(f"EXIF byte order {order!r} is neither II nor MM")
        self.data = data
        if self.unpack("H", 2)[0] != 42:
            raise ValueError("EXIF header lacks the TIFF mark 42")
        self.first = self.unpack("I", 4)[0]

    def unpack(self, fmt, offset):
        size = struct.calcsize(self.end + fmt)
        if offset < 0 or offset + size > len(self.data):
            raise ValueError(f"EXIF offset {offset} is outside its {len(self.data)} bytes")
        return struct.unpack(self.end + fmt, self.data[offset:offset + size])

    def ifd(self, offset):
        """Entries of the IFD at ``offset``: dict tag -> tuple of values (numbers; a
        rational as a float, None when its denominator is 0)."""
        (n,) = self.unpack("H", offset)
        if n > _MAX_ENTRIES:
            raise ValueError(f"EXIF directory at {offset} claims {n} entries")
        out = {}
        for k in range(n):
            at = offset + 2 + 12 * k
            tag, typ, count = self.unpack("HHI", at)
            size = _TYPE_SIZE.get(typ)
            if size is None or count > 1 << 16:
                continue  # an unknown type or an absurd count: skip the entry
            where = at + 8 if size * count <= 4 else self.unpack("I", at + 8)[0]
            out[tag] = self._values(typ, count, where)
        return out

    def _values(self, typ, count, where):
        if typ in (5, 10):
            fmt = "I" if typ == 5 else "i"
            raw = self.unpack(f"{2 * count}{fmt}", where)
            return tuple(None if d == 0 else n / d for n, d in zip(raw[::2], raw[1::2],
                                                                     strict=True))
        fmt = {1: "B", 2: "B", 3: "H", 4: "I", 7: "B", 9: "i", 11: "f", 12: "d"}[typ]
        return self.unpack(f"{count}{fmt}", where)


def _first(entries, tag):
    """The tag's first value as a positive float, or None."""
    vals = entries.get(tag)
    if not vals or vals[0] is None:
        return None
    v = float(vals[0])
    return v if math.isfinite(v) and v > 0 else None


def _whole(entries, tag, default=None):
    """The tag's first value as a whole number, or ``default`` when it is absent or not
    one (an entry of the wrong type or without values)."""
    v = _first(entries, tag)
    return int(v) if v is not None and v == int(v) else default


def parse_exif(data):
    """The EXIF of a JPEG file's bytes.

    Returns
    -------
    Exif or None
        None when ``data`` is no JPEG or carries no EXIF.

    Raises
    ------
    ValueError
        The EXIF is there but cut short or malformed (the message says where).
    """
    try:
        return _parse(bytes(data))
    except (IndexError, TypeError, OverflowError, struct.error) as e:  # a case not foreseen
        raise ValueError(f"EXIF malformed ({type(e).__name__}: {e})") from None


def _parse(data):
    tiff_bytes = _jpeg_app1(data)
    if tiff_bytes is None:
        return None
    tiff = _Tiff(tiff_bytes)
    ifd0 = tiff.ifd(tiff.first)
    sub = {}
    if EXIF_IFD in ifd0:
        where = _whole(ifd0, EXIF_IFD)
        if where is None:
            raise ValueError("EXIF sub-directory pointer is not an offset")
        sub = tiff.ifd(where)
    orientation = _whole(ifd0, ORIENTATION, 1)
    if not 1 <= orientation <= 8:
        orientation = 1  # outside EXIF's eight: treated as upright
    xres, yres = _first(sub, FOCAL_PLANE_X_RES), _first(sub, FOCAL_PLANE_Y_RES)
    px, py = _first(sub, PIXEL_X), _first(sub, PIXEL_Y)
    unit = _whole(sub, FOCAL_PLANE_UNIT, 2)
    return Exif(
        orientation=orientation,
        focal_length_mm=_first(sub, FOCAL_LENGTH),
        focal_35mm=_first(sub, FOCAL_35MM),
        focal_plane_resolution=(xres, yres) if xres and yres else None,
        focal_plane_unit_mm=UNIT_MM.get(unit) if xres and yres else None,
        pixel_size=(int(px), int(py)) if px and py else None,
    )


def read_photo_exif(path):
    """The EXIF of a photo file, never raising.

    Returns
    -------
    exif : Exif or None
        None for a photo without EXIF (a PNG, a JPEG without it) or with EXIF that
        cannot be read.
    problem : str or None
        One line naming the file when its EXIF could not be read (the photo is then used
        as stored, without a focal hint).
    """
    p = Path(path)
    try:
        with open(p, "rb") as f:
            return parse_exif(f.read()), None
    except (OSError, ValueError) as e:
        return None, f"{p.name}: EXIF not read ({e}); the photo is used as stored, " \
                     "without a focal length"


def photo_lens_mm(path, size):
    """The focal length (mm, 36 mm equivalent across the long side) a photo file's EXIF
    gives, or None (no EXIF, no focal length, or EXIF that cannot be read).

    Parameters
    ----------
    path : str or Path
    size : (int, int)
        The photo's size (w, h) once upright, as a landmarks file gives it.
    """
    exif, _ = read_photo_exif(path)
    if exif is None:
        return None
    return exif.lens_36mm(oriented_size(size, exif.orientation))  # its own inverse


def oriented_size(size, orientation):
    """The size (w, h) of a photo of stored ``size`` once turned upright."""
    w, h = size
    return (h, w) if orientation in (5, 6, 7, 8) else (w, h)


def orient(pixels, orientation):
    """A photo's pixels turned upright as its EXIF Orientation asks.

    Parameters
    ----------
    pixels : ndarray (H, W, ...)
        Row 0 at the top, as stored in the file.
    orientation : int
        1-8 (EXIF); 1 returns ``pixels`` unchanged.

    Returns
    -------
    ndarray (H', W', ...)
        The upright photo (a view of ``pixels`` where numpy allows).
    """
    a = np.asarray(pixels)
    if orientation == 2:
        return a[:, ::-1]
    if orientation == 3:
        return a[::-1, ::-1]
    if orientation == 4:
        return a[::-1]
    if orientation == 5:
        return a.swapaxes(0, 1)
    if orientation == 6:
        return a.swapaxes(0, 1)[:, ::-1]
    if orientation == 7:
        return a[::-1, ::-1].swapaxes(0, 1)
    if orientation == 8:
        return a.swapaxes(0, 1)[::-1]
    return a
