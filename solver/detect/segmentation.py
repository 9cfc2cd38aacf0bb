"""The person in a photo: MediaPipe's selfie segmentation (``selfie_segmentation.tflite``,
the general 256 × 256 model) on a square of the photo, as a probability map with the
geometry to put its iso-lines back on the photo.

MediaPipe stretches the whole photo to 256 × 256 (values in [0, 1]); here the model sees
a square, so the head is not squeezed, and a square around the head (from the detected
face) gives the outline more of the model's pixels (docs/DECISIONS.md, "The head's
outline").
"""

from dataclasses import dataclass

import numpy as np

from .crop import Square, crop

INPUT = 256


@dataclass
class PersonMask:
    """The model's person probability over a square of the photo.

    Attributes
    ----------
    square : Square
        Where in the photo the map lies.
    probability : ndarray (256, 256) float32
        Row r, column c: the probability at crop pixel (c, r) (``crop``'s rule: pixel i
        samples the photo at ``square.to_photo(i) + 0.5`` in continuous coordinates).
    photo : ndarray (256, 256, 3) float32
        The photo over the same square, as the model saw it (``crop``, the photo's edges
        extended past it), in [0, 1].
    """

    square: Square
    probability: np.ndarray
    photo: np.ndarray

    @property
    def pixel_size(self):
        """Photo pixels per map pixel."""
        return self.square.size / INPUT

    def to_photo(self, xy):
        """Map coordinates (x, y) (P, 2) -> photo pixels (u, v), continuous (a pixel
        (r, c) covers [c, c + 1) × [r, r + 1))."""
        return self.square.to_photo(np.asarray(xy, float).reshape(-1, 2), INPUT) + 0.5

    def inside(self, uv, margin=1.0):
        """Whether photo points ``uv`` (P, 2) lie at least ``margin`` map pixels inside
        the map's square: an iso-line along its edge is the square's, not the person's."""
        x, y = self.to_map(uv)
        return (x >= margin) & (x <= INPUT - 1 - margin) & (y >= margin) \
            & (y <= INPUT - 1 - margin)

    def to_map(self, uv):
        """Photo points ``uv`` (P, 2) -> map coordinates (x (P,), y (P,)), as
        :meth:`to_photo` inverts."""
        ex, ey = self.square.axes()
        d = np.asarray(uv, float).reshape(-1, 2) - 0.5 - np.asarray(self.square.center)
        scale = INPUT / self.square.size
        return d @ ex * scale + INPUT / 2, d @ ey * scale + INPUT / 2

    def at(self, uv):
        """The probability at photo points ``uv`` (P, 2), bilinear; 0 off the map."""
        x, y = self.to_map(uv)
        x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
        fx, fy = x - x0, y - y0
        p = np.pad(self.probability, 1)

        def get(r, c):
            return p[np.clip(r + 1, 0, INPUT + 1), np.clip(c + 1, 0, INPUT + 1)]

        return ((get(y0, x0) * (1 - fx) + get(y0, x0 + 1) * fx) * (1 - fy)
                + (get(y0 + 1, x0) * (1 - fx) + get(y0 + 1, x0 + 1) * fx) * fy)


def person_mask(network, image, square, border="edge"):
    """The person probability over ``square`` of ``image`` (H, W, 3) float32 in [0, 1]
    (the model's input range), past the photo its edges extended (or black: ``border``
    as ``crop`` takes it)."""
    x = crop(image, square, INPUT, border=border)
    (out,) = network(x[None])
    return PersonMask(square, np.asarray(out, np.float32).reshape(INPUT, INPUT), x)


def photo_square(shape):
    """The square holding the whole photo of ``shape`` (H, W, ...), centred."""
    h, w = shape[:2]
    return Square((w / 2, h / 2), float(max(w, h)))
