"""A rotated square of a photo resampled to a model's input (bilinear), and its inverse
for the points a model returns: the one geometry both detection stages share.

Continuous pixel coordinates: the photo's pixel (row r, column c) covers
[c, c + 1) × [r, r + 1), so its centre is (c + 0.5, r + 0.5). The crop's pixel i samples
the photo at ``corner + i * size / n`` in pixel-centre coordinates (OpenCV's warp, which
MediaPipe uses and the models were trained with): with the centre at (i + 0.5) instead,
the mesh came out 2 px (median) from MediaPipe's own on the sample's front photo, with
this rule 0.9 px (docs/DECISIONS.md).
"""

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Square:
    """A square of the photo: ``center`` (u, v) px, side ``size`` px, ``angle`` radians
    (the square's x axis is (cos, sin) in the photo: a tilted face comes out upright)."""

    center: tuple
    size: float
    angle: float = 0.0

    def axes(self):
        c, s = np.cos(self.angle), np.sin(self.angle)
        return np.array([c, s]), np.array([-s, c])

    def to_photo(self, xy, n):
        """Points ``xy`` (P, 2) in an ``n``-pixel crop of this square -> photo pixels."""
        ex, ey = self.axes()
        st = np.asarray(xy, float) / n - 0.5
        return (np.asarray(self.center, float) + self.size * st[:, :1] * ex
                + self.size * st[:, 1:2] * ey)


def shrink(image, k):
    """Mean of k×k blocks (an area filter before bilinear resampling to a much smaller
    crop, so a 1024-px photo is not aliased down to 128 px); the remainder rows and
    columns are dropped. Pixel coordinates map by :func:`shrunk_square` and
    :func:`unshrink`."""
    h, w = image.shape[0] // k, image.shape[1] // k
    out = np.zeros((h, w) + image.shape[2:], np.float32)
    for a in range(k):
        for b in range(k):
            out += image[a:h * k:k, b:w * k:k]
    return out / (k * k)


def shrunk_square(square, k):
    """``square`` in the photo :func:`shrink` makes by ``k``: the crop of one is the
    crop of the other (one photo shrunk once for many squares)."""
    return Square(tuple((np.asarray(square.center, float) + 0.5) / k - 0.5),
                  square.size / k, square.angle)


def unshrink(points, k):
    """Points (..., 2) in a photo shrunk by ``k`` -> in the photo."""
    return np.asarray(points, float) * k + (k - 1) / 2


def crop(image, square, n, border="zero"):
    """The ``square`` of ``image`` (H, W, 3) float32 in [0, 1] resampled to (n, n, 3).

    Parameters
    ----------
    border : {"zero", "edge"}
        Outside the photo: black (the detector's letterbox) or the nearest edge pixel
        (the landmark model's crop, which may reach past the photo).
    """
    k = int(square.size / n / 1.5)
    # Only the part of the photo the square covers (plus a pixel) is filtered.
    corners = square.to_photo(np.array([[0, 0], [n, 0], [0, n], [n, n]]), n)
    h, w = image.shape[:2]
    lo = np.clip(np.floor(corners.min(0)).astype(int) - k - 1, 0, [w, h])
    hi = np.clip(np.ceil(corners.max(0)).astype(int) + k + 1, 0, [w, h])
    lo = lo - lo % max(k, 1)
    offset = lo.astype(float)
    image = image[lo[1]:hi[1], lo[0]:hi[0]]
    scale = 1.0
    if k >= 2:
        image = shrink(image, k)
        scale = 1.0 / k
    idx = np.arange(n, dtype=float)
    jj, ii = np.meshgrid(idx, idx, indexing="ij")
    pts = square.to_photo(np.stack([ii.ravel(), jj.ravel()], axis=1), n)
    pts = (pts + 0.5 - offset) * scale - 0.5
    h, w = image.shape[:2]
    x0 = np.floor(pts[:, 0]).astype(int)
    y0 = np.floor(pts[:, 1]).astype(int)
    fx = (pts[:, 0] - x0)[:, None].astype(np.float32)
    fy = (pts[:, 1] - y0)[:, None].astype(np.float32)

    def at(y, x):
        v = image[np.clip(y, 0, h - 1), np.clip(x, 0, w - 1)]
        if border == "zero":
            v = v * ((x >= 0) & (x < w) & (y >= 0) & (y < h))[:, None]
        return v

    out = ((at(y0, x0) * (1 - fx) + at(y0, x0 + 1) * fx) * (1 - fy)
           + (at(y0 + 1, x0) * (1 - fx) + at(y0 + 1, x0 + 1) * fx) * fy)
    return out.reshape(n, n, -1).astype(np.float32)
