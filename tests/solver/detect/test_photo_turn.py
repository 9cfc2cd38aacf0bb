"""Quarter turns of a photo and the pixel maps between the turned photo and the photo as
given."""

import numpy as np
import pytest

from solver.cameras import OrthographicCamera
from solver.detect.photo_turn import (
    camera_to_photo,
    quarter_turn,
    to_photo,
    to_turned,
    turned,
    turned_size,
)


@pytest.mark.parametrize("turn", [0, 1, 2, 3])
def test_a_pixel_of_the_turned_photo_maps_to_the_same_pixel_as_given(turn):
    photo = np.zeros((5, 7, 3))
    photo[1, 4] = 1.0  # row 1, column 4: centred on (4.5, 1.5)
    seen = turned(photo, turn)
    row, col = np.argwhere(seen[:, :, 0])[0]
    assert seen.flags.c_contiguous and seen.shape[1::-1] == turned_size((7, 5), turn)
    assert np.allclose(to_photo([[col + 0.5, row + 0.5]], turn, (7, 5)), [[4.5, 1.5]])
    assert np.allclose(to_turned([[4.5, 1.5]], turn, (7, 5)), [[col + 0.5, row + 0.5]])
    # the photo's corners go to the turned photo's corners
    corners = np.array([[0.0, 0.0], [7.0, 0.0], [7.0, 5.0], [0.0, 5.0]])
    w, h = turned_size((7, 5), turn)
    out = to_turned(corners, turn, (7, 5))
    assert sorted(map(tuple, out)) == sorted([(0.0, 0.0), (w, 0.0), (w, h), (0.0, h)])


def test_the_eye_line_s_angle_gives_the_nearest_quarter_turn():
    deg = np.radians
    assert [quarter_turn(deg(a)) for a in (0, 40, -40, 84, -84, 175, -179, 265)] \
        == [0, 0, 0, 1, 3, 2, 2, 3]


@pytest.mark.parametrize("turn", [1, 2, 3])
def test_a_camera_of_the_turned_photo_projects_onto_the_photo_as_given(turn):
    size = (600, 800)
    upright = OrthographicCamera.nominal("orthographic-front", turned_size(size, turn))
    points = np.random.default_rng(0).normal(0.0, 0.1, (20, 3))
    camera = camera_to_photo(upright, turn, size)
    assert camera.size == size
    assert np.allclose(camera.project(points),
                       to_photo(upright.project(points), turn, size))
    assert np.isclose(np.linalg.det(camera.rotation), 1.0)
    # no turn, or no orthographic camera: as it is
    assert camera_to_photo(upright, 0, size) is upright
    assert camera_to_photo(None, turn, size) is None
