"""The rotated crop: which pixels it samples, and points mapped back."""

import numpy as np

from solver.detect.crop import Square, crop


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
