"""Parallel vs central projection (seed 001, Hashimoto 1984, chapter 2.2.1)."""

import numpy as np
import pytest

from solver import DLTCamera, OrthographicCamera
from solver.cameras.projection_check import (
    check_projection,
    lens_distance,
    min_distance,
    perspective_ratio,
)


def camera_at(distance, focal=1500.0):
    # on the -Y axis looking at the face (+Y), v down = -Z
    r = np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]])
    k = [[focal, 0, 960], [0, focal, 540], [0, 0, 1]]
    return DLTCamera.from_krc(k, r, [0.0, -distance, 0.0], (1920, 1080))


def head(depth=0.1):
    # nearest point (nose) at y = -depth / 2, farthest at +depth / 2
    rng = np.random.default_rng(0)
    x = rng.uniform([-0.07, -depth / 2, -0.11], [0.07, depth / 2, 0.11], (50, 3))
    x[0, 1], x[1, 1] = -depth / 2, depth / 2
    return x


def test_the_seeds_formulas():
    assert perspective_ratio(0.1, 1.0) == pytest.approx(0.1 / 1.1)  # about 9 %
    assert perspective_ratio(0.1, 1.0) == pytest.approx(0.0909, abs=1e-4)
    # eq. 2.3 is eq. 2.2 solved for L
    lmin = min_distance(0.1, 0.01)
    assert lmin == pytest.approx(9.9)
    assert perspective_ratio(0.1, lmin) == pytest.approx(0.01)
    with pytest.raises(ValueError):
        min_distance(0.1, 0.0)


def test_a_head_at_one_metre():
    # nearest point 1 m from the camera, 0.1 m deep: 9 % (the example in the docstring)
    chk = check_projection(camera_at(1.05), head(0.1), view="front")
    assert chk.distance == pytest.approx(1.0)
    assert chk.depth_extent == pytest.approx(0.1)
    assert chk.epsilon == pytest.approx(0.1 / 1.1)
    assert chk.exceeds
    assert "'front'" in chk.message and "9.1 %" in chk.message
    # default epsilon_max: 2 px over the head's image size (~ 350 px at f = 1500)
    assert 0.003 < chk.epsilon_max < 0.008
    assert chk.min_distance == pytest.approx(min_distance(0.1, chk.epsilon_max))


def test_a_distant_telephoto_photo_is_parallel_enough():
    chk = check_projection(camera_at(50.0, focal=60000.0), head(0.1), epsilon_max=0.01)
    assert chk.epsilon == pytest.approx(0.1 / 50.05, rel=1e-6)
    assert not chk.exceeds and chk.message == ""


def test_needs_a_perspective_camera_in_front():
    with pytest.raises(ValueError, match="perspective"):
        check_projection(OrthographicCamera.nominal("orthographic-front", (100, 100)), head())
    with pytest.raises(ValueError, match="behind the camera"):
        check_projection(camera_at(0.02), head(0.1), view="front")


def test_a_lens_tells_how_far_an_orthographic_photo_was_taken():
    # A head photographed 0.6 m away by a 50 mm lens (36 mm across the 1920 px long side),
    # then fitted as a parallel projection: its scale is the lens's magnification there.
    f_px = 50.0 * 1920 / 36.0
    x = head(0.1)
    px = camera_at(0.6, focal=f_px).project(x)
    ortho = OrthographicCamera.nominal("orthographic-front", (1920, 1080)).refit(x, px)
    assert lens_distance(ortho, 50.0) == pytest.approx(0.6, rel=0.03)
    assert lens_distance(ortho, 100.0) == pytest.approx(2 * lens_distance(ortho, 50.0))
    with pytest.raises(ValueError, match="lens_mm"):
        lens_distance(ortho, 0.0)
