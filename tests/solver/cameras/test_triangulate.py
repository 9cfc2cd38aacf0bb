"""Triangulation from calibrated views (seed 000 eq. 16) and the ray midpoint (seed 001
eq. 3.5-3.7)."""

import numpy as np
import pytest

from solver import OrthographicCamera
from solver.cameras.triangulate import ray_midpoint, triangulate
from tests.solver.cameras.support import dlt_camera

DIST = np.array([-3e-8, 1e-14, 0.0, 1e-6, -5e-7])


def cameras(distortion=None):
    centres = ([0.0, -1.0, 0.05], [0.8, -0.7, 0.1], [-0.7, -0.8, 0.3])
    return [dlt_camera(c, distortion=distortion) for c in centres]


def observe(cams, x, noise=0.0, rng=None):
    px = np.stack([c.project(x) for c in cams])
    if noise:
        px = px + rng.normal(0, noise, px.shape)
    return px


def test_two_views_exact():
    rng = np.random.default_rng(0)
    cams = cameras()[:2]
    x = rng.uniform(-0.1, 0.1, (50, 3))
    tri = triangulate(cams, observe(cams, x))
    np.testing.assert_allclose(tri.points, x, atol=1e-9)
    assert np.nanmax(np.abs(tri.residuals)) < 1e-6
    assert tri.ray_gap.max() < 1e-9 and tri.ray_distance.max() < 1e-9
    assert (tri.n_views == 2).all()
    # eq. 16 as printed (no reweighting) is exact too
    np.testing.assert_allclose(triangulate(cams, observe(cams, x), iterations=0).points, x,
                               atol=1e-9)


def test_three_views_with_lens_distortion_exact():
    rng = np.random.default_rng(1)
    cams = cameras(DIST)
    x = rng.uniform(-0.1, 0.1, (40, 3))
    tri = triangulate(cams, observe(cams, x))
    np.testing.assert_allclose(tri.points, x, atol=1e-9)


def test_noise_is_reported_as_residuals():
    rng = np.random.default_rng(2)
    cams = cameras()
    x = rng.uniform(-0.1, 0.1, (2000, 3))
    tri = triangulate(cams, observe(cams, x, 0.5, rng))
    err = np.linalg.norm(tri.points - x, axis=1)
    assert np.sqrt((err**2).mean()) < 0.001  # metres, at ~1 m with f = 1500 px
    # 6 equations, 3 unknowns: mean squared residual length = 2 * 0.25 * (6 - 3) / 6 px^2
    assert np.sqrt((tri.rms**2).mean()) == pytest.approx(0.5, rel=0.1)
    assert tri.residuals.shape == (3, 2000, 2)
    assert 1e-5 < np.median(tri.ray_gap) < 1e-3
    assert tri.ray_distance.shape == (3, 2000) and np.median(tri.ray_distance) < 1e-3


def test_missing_views_and_weights():
    rng = np.random.default_rng(3)
    cams = cameras()
    x = rng.uniform(-0.1, 0.1, (6, 3))
    px = observe(cams, x)
    px[0, 0] = np.nan  # point 0 seen by views 1 and 2 only
    px[1:, 1] = np.nan  # point 1 seen by view 0 only
    px[2, 2, 0] += 40.0  # a bad observation of point 2 ...
    w = np.ones((3, 6))
    w[2, 2] = 0.0  # ... that is weighted out
    tri = triangulate(cams, px, weights=w)
    assert list(tri.n_views) == [2, 1, 2, 3, 3, 3]
    assert np.isnan(tri.points[1]).all() and np.isnan(tri.rms[1])
    keep = [0, 2, 3, 4, 5]
    np.testing.assert_allclose(tri.points[keep], x[keep], atol=1e-9)
    assert np.isnan(tri.residuals[0, 0]).all()
    # the weighted-out observation still gets its residual: it is 40 px off
    assert np.linalg.norm(tri.residuals[2, 2]) == pytest.approx(40.0, rel=1e-6)
    # per-view weights work too
    tri2 = triangulate(cams, observe(cams, x), weights=[1.0, 2.0, 0.5])
    np.testing.assert_allclose(tri2.points, x, atol=1e-9)


def test_orthographic_and_perspective_views_mix():
    rng = np.random.default_rng(4)
    front = OrthographicCamera.nominal("orthographic-front", (1000, 1200))
    side = cameras()[1]
    x = rng.uniform(-0.1, 0.1, (20, 3))
    tri = triangulate([front, side], observe([front, side], x))
    np.testing.assert_allclose(tri.points, x, atol=1e-9)
    assert tri.ray_gap.max() < 1e-9


def test_bad_input():
    cams = cameras()
    with pytest.raises(ValueError, match="at least 2 views"):
        triangulate(cams[:1], np.zeros((1, 3, 2)))
    with pytest.raises(ValueError, match="expected shape"):
        triangulate(cams, np.zeros((2, 3, 2)))
    with pytest.raises(ValueError, match="weights"):
        triangulate(cams, np.zeros((3, 4, 2)), weights=[1.0, -1.0, 1.0])


def test_ray_midpoint_known_lines():
    # the x axis, and the line through (0, 0, 1) along y: closest points (0,0,0), (0,0,1)
    mid, gap, a1, a2 = ray_midpoint([[-2.0, 0, 0]], [[1.0, 0, 0]], [[0, -3.0, 1.0]],
                                    [[0, 2.0, 0]])
    np.testing.assert_allclose(mid, [[0, 0, 0.5]], atol=1e-15)
    np.testing.assert_allclose(gap, [1.0])
    np.testing.assert_allclose(a1, [2.0])
    np.testing.assert_allclose(a2, [3.0])
    # parallel lines: no midpoint, but their distance
    mid, gap, _, _ = ray_midpoint([0, 0, 0], [1.0, 0, 0], [0, 2.0, 0], [3.0, 0, 0])
    assert np.isnan(mid).all() and gap[0] == pytest.approx(2.0)
