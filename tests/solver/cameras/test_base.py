"""Cameras: the orthographic camera's projection and its refit (a 2-D similarity), and the
base class's pixels per metre."""

import numpy as np
import pytest

from solver import ORTHO_VIEWS, Camera, OrthographicCamera, camera_from_dict


def _tilted(view, angle, scale, offset, size=(768, 1024)):
    c, s = np.cos(angle), np.sin(angle)
    rot = ORTHO_VIEWS[view].copy()
    rot[:2] = np.array([[c, -s], [s, c]]) @ rot[:2]
    return OrthographicCamera(rot, scale, offset, size, view)


@pytest.mark.parametrize("view", sorted(ORTHO_VIEWS))
def test_refit_recovers_a_known_similarity(view):
    rng = np.random.default_rng(1)
    pts = rng.normal(scale=0.08, size=(30, 3))
    truth = _tilted(view, np.radians(4.0), 2600.0, (380.0, 515.0))
    start = OrthographicCamera.nominal(view, (768, 1024))
    got = start.refit(pts, truth.project(pts))
    assert got.kind == "orthographic" and got.view == view
    assert got.scale == pytest.approx(2600.0, rel=1e-9)
    np.testing.assert_allclose(got.offset, [380.0, 515.0], atol=1e-6)
    np.testing.assert_allclose(got.rotation, truth.rotation, atol=1e-9)
    assert np.degrees(got.in_plane_angle) == pytest.approx(4.0, abs=1e-6)
    # the viewing direction is not a free parameter of a single parallel projection
    np.testing.assert_allclose(got.rotation[2], start.rotation[2], atol=1e-12)
    np.testing.assert_allclose(got.project(pts), truth.project(pts), atol=1e-6)


def test_refit_is_weighted_least_squares():
    rng = np.random.default_rng(2)
    pts = rng.normal(scale=0.08, size=(20, 3))
    truth = _tilted("orthographic-right", -0.03, 2500.0, (300.0, 480.0))
    px = truth.project(pts)
    bad = px.copy()
    bad[3] += (200.0, -150.0)  # a wrong landmark
    start = OrthographicCamera.nominal("orthographic-right", (768, 1024))
    w = np.ones(20)
    w[3] = 0.0
    got = start.refit(pts, bad, w)
    np.testing.assert_allclose(got.project(pts), px, atol=1e-6)
    # with the point weighted in, the fit moves: weights are honoured, not ignored
    assert np.abs(start.refit(pts, bad).project(pts) - px).max() > 1.0
    # noisy pixels: residuals are those of the least-squares similarity
    noisy = px + rng.normal(scale=1.0, size=px.shape)
    fit = start.refit(pts, noisy)
    assert fit.reprojection_error(pts, noisy).mean() < 2.0
    assert fit.scale == pytest.approx(2500.0, rel=0.01)


def test_refit_round_trips_through_dict():
    rng = np.random.default_rng(3)
    pts = rng.normal(scale=0.1, size=(10, 3))
    cam = _tilted("orthographic-front", 0.05, 2700.0, (400.0, 500.0))
    got = OrthographicCamera.nominal("orthographic-front", (768, 1024)).refit(
        pts, cam.project(pts))
    again = camera_from_dict(got.to_dict())
    np.testing.assert_allclose(again.project(pts), got.project(pts), atol=1e-9)


def test_refit_rejects_bad_input():
    cam = OrthographicCamera.nominal("orthographic-front", (768, 1024))
    pts = np.zeros((1, 3))
    with pytest.raises(ValueError, match="at least 2"):
        cam.refit(pts, np.zeros((1, 2)))
    with pytest.raises(ValueError, match="pixels"):
        cam.refit(np.zeros((3, 3)), np.zeros((2, 2)))
    with pytest.raises(ValueError, match="coincide"):
        # points differing only along the viewing direction project onto one pixel
        cam.refit(np.array([[0, 0, 0], [0, 0.1, 0], [0, 0.2, 0.0]]), np.ones((3, 2)))
    with pytest.raises(ValueError, match="weights"):
        cam.refit(np.eye(3), np.ones((3, 2)), weights=[1, -1, 1])
    with pytest.raises(ValueError, match="at least 2 weighted"):
        cam.refit(np.eye(3), np.ones((3, 2)), weights=[1, 0, 0])
    with pytest.raises(ValueError, match="not finite"):
        cam.refit(np.array([[0, 0, np.nan], [1, 0, 0]]), np.ones((2, 2)))


class _Calibrated(Camera):
    """A camera with no free parameters (the base class's refit keeps it)."""

    kind = "test-calibrated"

    def project(self, points):
        return np.asarray(points)[:, :2] * 1000.0

    def jacobian(self, points):
        j = np.zeros((len(points), 2, 3))
        j[:, 0, 0] = j[:, 1, 1] = 1000.0
        return j

    def to_camera(self, points):
        return np.asarray(points)

    def toward_camera(self, points):
        return np.tile([0.0, 0.0, -1.0], (len(points), 1))

    def to_dict(self):
        return {"kind": self.kind}

    @classmethod
    def from_dict(cls, d):
        return cls()


def test_base_refit_keeps_a_calibrated_camera():
    cam = _Calibrated()
    assert cam.min_refit_points == 0
    pts = np.array([[0.1, 0.2, 0.3]])
    assert cam.refit(pts, [[1.0, 2.0]]) is cam
    np.testing.assert_allclose(cam.reprojection_error(pts, [[100.0, 200.0]]), [0.0])
    with pytest.raises(ValueError, match="pixels"):
        cam.refit(pts, np.zeros((2, 2)))


def test_orthographic_jacobian_matches_projection():
    cam = _tilted("orthographic-left", 0.1, 2000.0, (10.0, 20.0))
    x = np.array([[0.01, -0.02, 0.03]])
    jac = cam.jacobian(x)[0]
    d = np.array([1e-4, -2e-4, 3e-4])
    np.testing.assert_allclose(cam.project(x + d) - cam.project(x), (jac @ d)[None], atol=1e-9)


def test_pixels_per_metre_is_the_scale_of_a_parallel_and_f_over_depth_of_a_pinhole():
    from solver import PinholeCamera

    pts = np.array([[0.0, 0.0, 0.0], [0.05, -0.1, 0.08]])
    ortho = _tilted("orthographic-right", 0.2, 2600.0, (380.0, 515.0))
    np.testing.assert_allclose(ortho.pixels_per_metre(pts), [2600.0, 2600.0], rtol=1e-12)
    # a photo reduced to half: half the pixels; halved across only: the rows' RMS
    np.testing.assert_allclose(ortho.pixels_per_metre(pts, (0.5, 0.5)), 1300.0, rtol=1e-12)
    np.testing.assert_allclose(ortho.pixels_per_metre(pts, (0.5, 1.0)),
                               2600.0 * np.sqrt((0.25 + 1.0) / 2.0), rtol=1e-12)
    # a pinhole 1.2 m in front of the head, f = 1500 px: f / depth on its axis
    cam = PinholeCamera.look_at((0.0, -1.2, 0.0), (0.0, 0.0, 0.0), (1920, 1080), f_px=1500.0)
    on_axis = np.array([[0.0, 0.0, 0.0], [0.0, -0.3, 0.0]])
    np.testing.assert_allclose(cam.pixels_per_metre(on_axis), [1250.0, 1500.0 / 0.9],
                               rtol=1e-12)


def test_a_view_s_camera_turned_to_a_yaw():
    """``OrthographicCamera.turned``: the nominal camera of a view looking from another
    yaw about the head's vertical, level; at the views' own yaws their nominal cameras."""
    size = (768, 1024)
    for view, yaw in (("orthographic-right", 90.0), ("orthographic-left", -90.0),
                      ("orthographic-front", 0.0)):
        np.testing.assert_allclose(OrthographicCamera.turned(view, size, yaw).rotation,
                                   ORTHO_VIEWS[view], atol=1e-12)
    cam = OrthographicCamera.turned("orthographic-right", size, 72.0)
    d = cam.rotation[2]
    assert np.degrees(np.arctan2(d[0], d[1])) == pytest.approx(72.0) and d[2] == 0.0
    np.testing.assert_allclose(cam.rotation @ cam.rotation.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(cam.rotation) == pytest.approx(np.linalg.det(ORTHO_VIEWS[
        "orthographic-right"]))
    # the image's v axis stays down the head: a point above the head's centre is above it
    assert cam.project(np.array([[0.0, 0.0, 0.1]]))[0, 1] < cam.offset[1]
