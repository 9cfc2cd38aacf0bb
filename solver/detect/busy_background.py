"""A busy background the person's segmentation took in, found by its colours and taken out
of the person's map.

Before confetti, posters or any wall of many colours, MediaPipe's selfie segmentation
takes in patches of the background beside the head, sure that they are the person, and
the outline then runs through them (docs/DECISIONS.md, "A busy background"). There the
photo's colour changes every few pixels over a wide window, as it does nowhere on a
face, on hair or a beard (their texture is one colour, lighter and darker) or on plain
clothes; so the map's pixels where it does are not the person's.
"""

from dataclasses import replace

import numpy as np
from scipy import ndimage

#: The colour's spread at a map pixel: the standard deviation of its two opponent
#: differences (red less green, red and green less blue) over this many map pixels
#: square (3 % of the face's width: the map spans 2.5 faces in 256 pixels).
#: Differences, not shares of the colour's sum: a dark pixel's shares are noise (dark hair
#: in a real photo spreads more in them than confetti does), its differences are small ...
SPREAD_PX = 3
#: ... and the median of that spread over this many map pixels square (9 % of the face's
#: width): wider than the edge between the head and the background (or between hair and
#: skin), whose spread is high only along a line, so the edge itself is not busy.
BUSY_PX = 9
#: A map pixel is busy where that median is over this (RGB in [0, 1]). On the rendered
#: heads' photos the person's pixels over it number 0-2 on dark skin, up to 27 with hair,
#: 59 in a room, 121 beside a wooden door, and 0 on james' two real photos, whose dark hair
#: is noise in a colour's shares (docs/DECISIONS.md, "A busy background taken out of the
#: person's map").
BUSY_SPREAD = 0.08
#: The busy part is taken out only where it is at least this many of the map's pixels
#: (0.9 % of it): a background that leaked in widely. Before a poster wall (squares of one
#: colour as wide as the median's window) only the squares' corners are busy, 135-446
#: pixels of the map, and cutting those out leaves its edge ragged (the fits from them
#: were worse); before confetti 738-9 500.
BUSY_MIN_PX = 600


def busy_pixels(mask):
    """Which pixels of ``mask``'s map (N, N) bool lie where its photo (``PersonMask.photo``)
    is busy: the median of the colour's spread (:data:`SPREAD_PX`) over :data:`BUSY_PX`
    square is over :data:`BUSY_SPREAD`, that is, more than half of the pixels there have a
    spread over it."""
    rgb = np.asarray(mask.photo, np.float64)
    opponent = np.stack([rgb[..., 0] - rgb[..., 1],
                         0.5 * (rgb[..., 0] + rgb[..., 1]) - rgb[..., 2]], axis=-1)
    size = (SPREAD_PX, SPREAD_PX, 1)
    mean = ndimage.uniform_filter(opponent, size)
    square = ndimage.uniform_filter(opponent * opponent, size)
    spread = np.maximum(square - mean * mean, 0.0).sum(axis=2)
    over = (spread > BUSY_SPREAD ** 2).astype(np.float64)
    return ndimage.uniform_filter(over, BUSY_PX) > 0.5


def without_busy_background(mask):
    """``mask`` (a :class:`~.segmentation.PersonMask`) with its person pixels (probability
    at least 0.5) where its photo is busy (:func:`busy_pixels`) set to 0, when there are
    :data:`BUSY_MIN_PX` of them or more; else the mask itself, unchanged. Returns (the
    mask, how many map pixels were taken out)."""
    busy = busy_pixels(mask) & (mask.probability >= 0.5)
    taken = int(busy.sum())
    if taken < BUSY_MIN_PX:
        return mask, 0
    probability = np.where(busy, 0.0, mask.probability).astype(np.float32)
    return replace(mask, probability=probability), taken
