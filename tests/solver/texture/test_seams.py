"""Seam feathering over the mesh (solver/texture/seams.py)."""

import numpy as np
import pytest

from solver.texture.seams import edge_graph, seam_fade
from tests.solver.texture.test_shading import _sheet


def test_the_fade_rises_over_its_width_from_the_unseen_vertices():
    points, tris = _sheet(40, 0.2)  # 5 mm edges
    graph = edge_graph(points, tris)
    assert graph.shape == (len(points), len(points))
    np.testing.assert_allclose(graph.max(), np.hypot(0.005, 0.005), rtol=1e-9)
    x = points[:, 0]
    unseen = x < 0.05 - 1e-9  # the last unseen column is x = 0.045
    fade = seam_fade(unseen, graph, 0.02)
    # along the grid's rows the surface distance is x - 0.045: a smoothstep over 2 cm
    t = np.clip((x - 0.045) / 0.02, 0, 1)
    np.testing.assert_allclose(fade, np.where(unseen, 0.0, t * t * (3 - 2 * t)), atol=1e-9)
    band = (fade > 0) & (fade < 1)
    assert band.sum() >= 3 * 41
    np.testing.assert_array_equal(seam_fade(unseen, graph, 0.0), 1.0)
    with pytest.raises(ValueError, match="unseen"):
        seam_fade(unseen[:-1], graph, 0.02)
