"""The person's segmentation: its map's geometry on the photo, and on the rendered
sample's profile a mask that holds the head and not the background."""

import numpy as np
import pytest
from PIL import Image

from solver.detect.crop import Square
from solver.detect.operators import Network
from solver.detect.segmentation import INPUT, PersonMask, person_mask, photo_square
from solver.paths import DETECTOR_DIR


def test_the_map_and_the_photo_agree_both_ways():
    rng = np.random.default_rng(5)
    mask = PersonMask(Square((300.0, 410.0), 512.0, 0.3),
                      rng.uniform(0, 1, (INPUT, INPUT)).astype(np.float32),
                      np.zeros((INPUT, INPUT, 3), np.float32))
    assert mask.pixel_size == 2.0
    rc = rng.integers(1, INPUT - 1, size=(50, 2))
    uv = mask.to_photo(rc[:, ::-1])
    np.testing.assert_allclose(mask.at(uv), mask.probability[rc[:, 0], rc[:, 1]], atol=1e-5)
    far = mask.to_photo(np.array([[-5.0, 10.0], [10.0, INPUT + 4.0]]))
    assert (mask.at(far) == 0).all()
    x, y = mask.to_map(uv)
    np.testing.assert_allclose(np.stack([x, y], axis=1), rc[:, ::-1], atol=1e-9)
    # the square's own edge is not inside it; a map pixel in from it is
    edge = mask.to_photo(np.array([[0.0, 100.0], [INPUT - 1.0, 3.0], [1.5, 1.5], [20.0, 30.0]]))
    assert mask.inside(edge).tolist() == [False, False, True, True]
    assert photo_square((1024, 768, 3)) == Square((384.0, 512.0), 1024.0)


def test_the_sample_profile_is_a_person_on_a_background(sample):
    path = DETECTOR_DIR / "selfie_segmentation.tflite"
    if not path.is_file():
        pytest.skip(f"{path} missing: run ./run detector")
    folder, truth = sample
    image = np.asarray(Image.open(folder / "side.png").convert("RGB"), np.float32) / 255
    mask = person_mask(Network(path), image, photo_square(image.shape))
    h, w = image.shape[:2]
    yy, xx = np.mgrid[0:h:4, 0:w:4]
    uv = np.stack([xx.ravel() + 0.5, yy.ravel() + 0.5], axis=1)
    alpha = truth["alpha_side"][yy.ravel(), xx.ravel()] >= 128
    found = mask.at(uv) >= 0.5
    # the rendered person's alpha (head, neck and shirt) against the mask: all but a
    # rim of the map's pixels agree
    assert np.mean(found == alpha) > 0.97
    assert found[alpha].mean() > 0.95 and (~found[~alpha]).mean() > 0.95
