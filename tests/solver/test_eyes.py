"""The bundled head's eyes (solver/eyes.py): each sclera's vertices, their distance
from the eye's axis and which half faces forward."""

import numpy as np
import pytest

from solver.eyes import IRIS_RADIUS, SCLERA_RANGES, sclera_axis_distance


def test_each_sclera_is_measured_from_its_own_axis(model):
    eyes = sclera_axis_distance(model.vertices)
    assert len(eyes) == 2
    for (idx, r, front), (s0, s1) in zip(eyes, SCLERA_RANGES, strict=True):
        np.testing.assert_array_equal(idx, np.arange(s0, s1 + 1))
        # an eyeball a centimetre or more across the axis, which runs through its front
        assert 0.010 < r.max() < 0.018 and r[front].min() < 0.001
        assert 0.3 < front.mean() < 0.7
        # the iris's ring holds a good share of the front's vertices
        assert 50 < np.count_nonzero(front & (r < IRIS_RADIUS)) < front.sum()
    # the two eyes are mirror images: the same distances
    np.testing.assert_allclose(np.sort(eyes[0][1]), np.sort(eyes[1][1]), atol=2e-4)


def test_a_mesh_that_is_not_the_bundled_head_is_refused():
    with pytest.raises(ValueError, match="ICT head's"):
        sclera_axis_distance(np.zeros((100, 3)))
