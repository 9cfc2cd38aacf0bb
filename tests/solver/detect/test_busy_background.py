"""A busy background taken out of the person's map, on drawn photos and maps."""

import numpy as np
from scipy import ndimage

from solver.detect.busy_background import BUSY_MIN_PX, BUSY_PX, without_busy_background
from solver.detect.crop import Square
from solver.detect.segmentation import INPUT, PersonMask

SIZE = 2 * INPUT                                   # a map pixel is 2 photo pixels
SKIN = np.array([0.85, 0.65, 0.55])


def _blocks(px, seed=0):
    """A photo (SIZE, SIZE, 3) of squares ``px`` photo pixels wide in random colours."""
    rng = np.random.default_rng(seed)
    n = -(-SIZE // px)
    colours = rng.uniform(0.0, 1.0, (n, n, 3))
    return np.repeat(np.repeat(colours, px, axis=0), px, axis=1)[:SIZE, :SIZE]


def _head():
    """The head, a disc of skin shaded from its middle, (SIZE, SIZE) bool and colours."""
    v, u = np.mgrid[0:SIZE, 0:SIZE] + 0.5
    r = np.hypot(u - SIZE / 2, v - SIZE / 2) / (0.3 * SIZE)
    return r < 1, SKIN * (1.0 - 0.2 * np.clip(r, 0, 1) ** 2)[..., None]


def _map(photo, person):
    """A sure map (INPUT, INPUT) of the ``photo``'s ``person`` (SIZE, SIZE) bool, with the
    photo as the model sees it."""
    return PersonMask(Square((SIZE / 2, SIZE / 2), SIZE),
                      person[::2, ::2].astype(np.float32),
                      photo[::2, ::2].astype(np.float32))


def _photo(background):
    head, skin = _head()
    return np.where(head[..., None], skin, background), head


def test_confetti_the_segmentation_took_in_is_taken_out_and_the_head_kept():
    # a square of confetti (8-px squares) beside the head taken in as the person, as
    # MediaPipe's segmentation takes it in before the mouth on a profile
    photo, head = _photo(_blocks(8))
    leak = np.zeros_like(head)
    leak[SIZE // 2:SIZE // 2 + 120, SIZE // 2 + 150:SIZE // 2 + 260] = True
    mask, taken = without_busy_background(_map(photo, head | leak))
    kept = mask.probability >= 0.5
    head_map = head[::2, ::2]
    assert taken > 0 and kept[leak[::2, ::2] & ~head_map].mean() < 0.05
    # the head is kept, but for a strip along its edge narrower than half the window
    deep = ndimage.binary_erosion(head_map, iterations=BUSY_PX // 2 + 1)
    assert kept[deep].all() and kept[head_map].mean() > 0.95


def test_a_plain_wall_hair_and_a_poster_wall_are_left_as_they_were():
    # a grey wall; near-black hair over half the head, its light varying pixel to pixel
    # and a real camera's noise on it (2.5 levels of 255: its chromaticity is noise); a
    # poster wall of squares wider than the window (only their corners are busy)
    rng = np.random.default_rng(1)
    grey = np.full((SIZE, SIZE, 3), 0.45)
    hair = (np.array([0.05, 0.035, 0.03]) * rng.uniform(0.3, 1.7, (SIZE, SIZE, 1))
            + rng.normal(0.0, 0.01, (SIZE, SIZE, 3)))
    photo, head = _photo(grey)
    photo = np.where((head & (np.mgrid[0:SIZE, 0:SIZE][0] < SIZE / 2))[..., None], hair, photo)
    for background in (photo, _photo(_blocks(2 * 2 * BUSY_PX))[0]):
        before = _map(background, head)
        mask, taken = without_busy_background(before)
        assert taken == 0 and mask is before


def test_a_few_busy_pixels_are_left_as_they_were_many_are_taken_out():
    # confetti taken in as the person in a patch of a quarter of BUSY_MIN_PX map pixels,
    # and in one of four times it (the head alone, on a plain wall, is not busy)
    grey = np.full((SIZE, SIZE, 3), 0.45)
    confetti = _blocks(4, seed=2)
    for side, taken_out in ((int(np.sqrt(BUSY_MIN_PX) / 2), False),
                            (int(2 * np.sqrt(BUSY_MIN_PX)), True)):
        patch = np.zeros((SIZE, SIZE), bool)
        patch[20:20 + 2 * side, 20:20 + 2 * side] = True
        photo, head = _photo(np.where(patch[..., None], confetti, grey))
        before = _map(photo, head | patch)
        mask, taken = without_busy_background(before)
        kept = mask.probability >= 0.5
        if taken_out:
            assert taken >= BUSY_MIN_PX and kept[patch[::2, ::2]].mean() < 0.05
        else:
            assert taken == 0 and mask is before
