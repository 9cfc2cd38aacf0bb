"""Triangle rasterisation on a pixel grid (solver/texture/raster.py)."""

import numpy as np

from solver.texture.raster import depth_buffer, first_per_pixel, rasterize


def test_rasterize_square_covers_each_pixel_once_with_exact_barycentrics():
    tri = np.array([[[0, 0], [10, 0], [10, 10]], [[0, 0], [10, 10], [0, 10]]], float) + 3.2
    pixel, t, bary = rasterize(tri, 20, 20)
    uniq, t1, b1 = first_per_pixel(pixel, t, bary)
    # centres i + 0.5 in [3.2, 13.2]: columns/rows 3..12
    assert len(uniq) == 100
    assert set(uniq % 20) == set(range(3, 13)) and set(uniq // 20) == set(range(3, 13))
    pos = np.einsum("nk,nkd->nd", b1, tri[t1])
    np.testing.assert_allclose(pos, np.stack([uniq % 20 + 0.5, uniq // 20 + 0.5], 1),
                               atol=1e-9)


def test_rasterize_batches_and_bands_do_not_change_the_result(monkeypatch):
    import solver.texture.raster as raster_mod

    tri = np.array([[[0, 0], [300, 0], [0, 300]], [[5, 5], [50, 5], [5, 80]],
                    [[10.3, 20.7], [11.1, 20.9], [10.6, 21.8]]], float)
    p1, t1, b1 = rasterize(tri, 400, 400)
    monkeypatch.setattr(raster_mod, "_CHUNK", 1000)  # forces row bands and small batches
    p2, t2, b2 = rasterize(tri, 400, 400)
    o1, o2 = np.lexsort((t1, p1)), np.lexsort((t2, p2))
    np.testing.assert_array_equal(p1[o1], p2[o2])
    np.testing.assert_array_equal(t1[o1], t2[o2])
    np.testing.assert_allclose(b1[o1], b2[o2])
    # each triangle covers about its area in pixel centres
    counts = np.bincount(t1, minlength=3)
    assert abs(counts[0] - 300 * 300 / 2) < 310 and abs(counts[1] - 45 * 75 / 2) < 80


def test_depth_buffer_keeps_the_nearest_triangle():
    tri = np.array([[[0, 0], [8, 0], [0, 8]], [[0, 0], [8, 0], [0, 8]]], float)
    buf = depth_buffer(tri, np.array([[2.0, 2, 2], [1.0, 1, 1]]), 8, 8)
    assert buf[0, 0] == 1.0 and np.isinf(buf[7, 7])
