"""The rotated crop: which pixels it samples, and points mapped back."""

import numpy as np

from solver.detect.crop import Square, crop, shrink, shrunk_square, unshrink


def test_crop_rotates_and_maps_back():
    image = np.zeros((60, 80, 3), np.float32)
    image[20:30, 40:50] = 1.0                     # a bright square centred at (45, 25)
    sq = Square((45.0, 25.0), 20.0, np.pi / 2)
    out = crop(image, sq, 20, border="zero")
    # crop pixel (row j, column i) samples the pixel centred at (45 - (j - 10), 25 + i - 10)
    bright = np.zeros((20, 20), bool)
    bright[6:16, 5:15] = True
    np.testing.assert_allclose(out[..., 0], bright.astype(float), atol=1e-6)
    # the crop's x axis runs down the photo
    np.testing.assert_allclose(sq.to_photo(np.array([[20.0, 10.0]]), 20), [[45.0, 35.0]])


def test_a_photo_shrunk_once_crops_as_each_square_would():
    rng = np.random.default_rng(3)
    image = rng.random((300, 420, 3)).astype(np.float32)
    k = 4
    small = shrink(image, k)
    assert small.shape == (75, 105, 3)
    np.testing.assert_allclose(small[2, 3], image[8:12, 12:16].mean((0, 1)), rtol=1e-5)
    for square in (Square((210.0, 150.0), 96.0), Square((96.5, 120.25), 100.0, 0.3)):
        # 96 / 16 / 1.5 = 4: the crop of the photo filters it over the same 4 px blocks
        np.testing.assert_allclose(crop(small, shrunk_square(square, k), 16),
                                   crop(image, square, 16), atol=1e-5)
    # a shrunk pixel's centre is the centre of its block
    np.testing.assert_allclose(unshrink([[2.0, 3.0]], k), [[9.5, 13.5]])
