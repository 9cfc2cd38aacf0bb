"""Seam feathering over the mesh (solver/texture/seams.py)."""

import numpy as np
import pytest

from solver.texture.seams import edge_graph, seam_fade, tile_seam_difference
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


def test_tiles_meet_where_they_share_vertices_and_their_difference_there_is_measured():
    """Two tiles of one sphere share the vertices where the UVs split: where both give
    those vertices one colour the difference is 0; where one tile is brighter by 0.2 it is
    0.2 at every shared vertex (the length of the colour difference)."""
    from solver.texture.uvs import uv_raster, uv_tiles
    from tests.solver.texture.support import uv_sphere

    m = uv_sphere()
    back = np.repeat(m.loop_uv[m.face_loop_start, 0] < 0.5, m.face_loop_total)
    m.loop_uv[back] += [1.0, 0.0]
    rasters = {t: uv_raster(m, 64, tile=t) for t in uv_tiles(m)}
    assert sorted(rasters) == [1001, 1002]
    even = {t: np.full((64, 64, 3), 0.4) for t in rasters}
    d = tile_seam_difference(rasters, even)
    assert len(d) >= 2 * 22  # both sides' meridians, pole to pole
    np.testing.assert_allclose(d, 0.0, atol=1e-9)
    bright = {1001: even[1001], 1002: np.full((64, 64, 3), 0.4) + [0.2, 0.0, 0.0]}
    np.testing.assert_allclose(tile_seam_difference(rasters, bright), 0.2, atol=1e-6)
    assert len(tile_seam_difference({1001: rasters[1001]}, even)) == 0
