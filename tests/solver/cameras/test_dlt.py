"""DLT-11 / DLT-16 calibration and the DLTCamera interface (seed 000, Mössner 1992)."""

import numpy as np
import pytest

from solver import DLTCamera, fit_dlt
from solver.cameras import Camera, camera_from_dict, camera_kinds
from tests.solver.cameras.support import SIZE, dlt_camera, look_at

# off-centre principal point: the fit must not assume the image centre
K = np.array([[1400.0, 0.0, 980.0], [0.0, 1400.0, 530.0], [0.0, 0.0, 1.0]])
C = np.array([0.15, -0.9, 0.1])
# radial b12..b14 (px^-2, px^-4, px^-6), tangential b15, b16 (px^-1): ~24 px at the corners
DIST = np.array([-4e-8, 2e-14, -3e-21, 1.5e-6, -1e-6])


def camera(distortion=None):
    return dlt_camera(C, k=K, distortion=distortion)


def points_filling_image(cam, n, rng, depth=(0.75, 1.05)):
    """World points whose pixels cover the whole image (so lens terms are observable)."""
    px = rng.uniform([40, 40], [SIZE[0] - 40, SIZE[1] - 40], (n, 2))
    o, d = cam.back_project(cam.distort(px))
    z = rng.uniform(*depth, n)
    return o + d * (z / (d @ cam.rotation[2]))[:, None]


def test_registered_and_is_a_camera():
    assert "dlt" in camera_kinds()
    assert isinstance(camera(), Camera)


def test_dlt11_recovers_known_camera_exactly():
    rng = np.random.default_rng(0)
    cam = camera()
    x = rng.uniform(-0.15, 0.15, (30, 3))
    fit = fit_dlt(x, cam.project(x), SIZE)
    assert fit.n_params == 11 and fit.converged and not fit.fell_back
    assert fit.rms <= 0.01
    assert np.abs(fit.residuals).max() <= 0.01
    k, r, c = fit.camera.decompose()
    np.testing.assert_allclose(k, K, atol=1e-5)
    np.testing.assert_allclose(r, cam.rotation, atol=1e-9)
    np.testing.assert_allclose(c, C, atol=1e-9)
    # seed 000 §4: scaling brings the condition number from thousands to tens
    assert fit.condition < 200 < fit.condition_unscaled
    # the 11 parameters reproduce the camera's b1..b11 (eq. 1)
    np.testing.assert_allclose(fit.camera.parameters, cam.parameters, rtol=1e-7, atol=1e-9)


def test_dlt11_with_half_pixel_noise():
    rng = np.random.default_rng(1)
    cam = camera()
    x = points_filling_image(cam, 40, rng)
    test = points_filling_image(cam, 200, rng)
    fit = fit_dlt(x, cam.project(x) + rng.normal(0, 0.5, (40, 2)), SIZE)
    # residual lengths: about sqrt(2) * 0.5 * sqrt(1 - 11 / 80) = 0.66 px
    assert 0.4 < fit.rms < 0.9
    err = np.linalg.norm(fit.camera.project(test) - cam.project(test), axis=1)
    assert np.sqrt((err**2).mean()) < 0.5
    assert np.linalg.norm(fit.camera.centre - C) < 0.01


@pytest.mark.parametrize("case, match", [
    ("five", "at least 6"),
    ("plane", "lie in one plane"),
    ("one_off_plane", "degenerate"),
    ("shape", "rows for"),
    ("nan", "not finite"),
])
def test_bad_passpoints_raise(case, match):
    rng = np.random.default_rng(2)
    cam = camera()
    x = rng.uniform(-0.15, 0.15, (12, 3))
    if case == "five":
        x = x[:5]
    elif case in ("plane", "one_off_plane"):
        x[:, 1] = 0.0
        if case == "one_off_plane":
            x[0, 1] = 0.1
    px = cam.project(x)
    if case == "shape":
        px = px[:-1]
    if case == "nan":
        px[3, 0] = np.nan
    with pytest.raises(ValueError, match=match):
        fit_dlt(x, px, SIZE)


def test_dlt16_recovers_radial_and_tangential_distortion():
    rng = np.random.default_rng(3)
    cam = camera(DIST)
    x = points_filling_image(cam, 40, rng)
    fit = fit_dlt(x, cam.project(x), SIZE, n_params=16)
    assert fit.n_params == 16 and fit.converged and not fit.fell_back, fit.reason
    assert 1 <= fit.iterations <= 10
    assert fit.rms <= 0.01
    np.testing.assert_allclose(fit.camera.distortion, DIST, rtol=1e-5)
    np.testing.assert_allclose(fit.camera.distortion_centre, K[:2, 2], atol=1e-3)
    test = points_filling_image(cam, 200, rng)
    assert np.abs(fit.camera.project(test) - cam.project(test)).max() <= 0.01
    # the distortion matters: the 11-parameter model cannot follow it
    assert fit_dlt(x, cam.project(x), SIZE).rms > 1.0


def test_dlt16_with_noise_and_the_seeds_centre_rule():
    rng = np.random.default_rng(4)
    cam = camera(DIST)
    x = points_filling_image(cam, 60, rng)
    test = points_filling_image(cam, 200, rng)
    px = cam.project(x) + rng.normal(0, 0.2, (60, 2))
    for rule in ("principal", "eq8"):
        fit = fit_dlt(x, px, SIZE, n_params=16, distortion_centre=rule)
        assert fit.n_params == 16 and fit.converged
        err = np.linalg.norm(fit.camera.project(test) - cam.project(test), axis=1)
        assert np.sqrt((err**2).mean()) < 0.4, rule
    # eq. 8 as printed puts the centre at the image of the world point (b9, b10, b11)
    # of the scaled frame, which is not the principal point
    assert np.linalg.norm(fit.camera.distortion_centre - K[:2, 2]) > 1.0


def test_dlt16_falls_back_to_dlt11_and_says_why():
    rng = np.random.default_rng(5)
    cam = camera(DIST)
    x = points_filling_image(cam, 30, rng)
    px = cam.project(x)
    fit = fit_dlt(x, px, SIZE, n_params=16, itmax=1, tol=1e-15)
    assert fit.fell_back and fit.n_params == 11 and not fit.converged
    assert "did not converge in 1 iterations" in fit.reason
    assert not fit.camera.has_distortion
    np.testing.assert_allclose(fit.camera.matrix, fit_dlt(x, px, SIZE).camera.matrix)
    few = fit_dlt(x[:7], px[:7], SIZE, n_params=16)
    assert few.fell_back and "at least 8" in few.reason


def test_weights_leave_out_a_bad_point():
    rng = np.random.default_rng(6)
    cam = camera()
    x = rng.uniform(-0.15, 0.15, (12, 3))
    px = cam.project(x)
    px[4] += 30.0
    w = np.ones(12)
    w[4] = 0.0
    fit = fit_dlt(x, px, SIZE, weights=w)
    assert fit.rms < 1e-6
    assert np.linalg.norm(fit.residuals[4]) > 30.0
    refit = cam.refit(x, px, weights=w)
    assert isinstance(refit, DLTCamera) and refit.size == SIZE
    np.testing.assert_allclose(refit.project(x[:4]), cam.project(x[:4]), atol=1e-6)


def test_refit_keeps_the_lens_model():
    rng = np.random.default_rng(7)
    cam = camera(DIST)
    x = points_filling_image(cam, 30, rng)
    new = cam.refit(x, cam.project(x))
    assert new.n_params == 16
    np.testing.assert_allclose(new.project(x), cam.project(x), atol=1e-6)


@pytest.mark.parametrize("distortion", [None, DIST])
def test_jacobian_matches_central_differences(distortion):
    rng = np.random.default_rng(8)
    cam = camera(distortion)
    x = points_filling_image(cam, 20, rng)
    jac = cam.jacobian(x)
    assert jac.shape == (20, 2, 3)
    h = 1e-6
    num = np.stack([(cam.project(x + h * e) - cam.project(x - h * e)) / (2 * h)
                    for e in np.eye(3)], axis=2)
    np.testing.assert_allclose(jac, num, rtol=1e-6, atol=1e-3)  # pixels per metre ~ 1e3


def test_frames_rays_and_centre():
    rng = np.random.default_rng(9)
    cam = camera(DIST)
    x = points_filling_image(cam, 15, rng)
    loc = cam.to_camera(x)
    np.testing.assert_allclose(loc[:, 2], cam.depth(x), atol=1e-12)
    assert (loc[:, 2] > 0).all()
    np.testing.assert_allclose(loc, (x - C) @ cam.rotation.T, atol=1e-12)
    t = cam.toward_camera(x)
    np.testing.assert_allclose(np.linalg.norm(t, axis=1), 1.0)
    np.testing.assert_allclose(x + t * np.linalg.norm(C - x, axis=1)[:, None],
                               np.broadcast_to(C, x.shape), atol=1e-12)
    o, d = cam.back_project(cam.project(x))
    along = ((x - o) * d).sum(axis=1)
    assert (along > 0).all()
    np.testing.assert_allclose(o + along[:, None] * d, x, atol=1e-9)
    np.testing.assert_allclose(cam.undistort(cam.project(x)), cam.project_ideal(x), atol=1e-8)


@pytest.mark.parametrize("distortion", [None, DIST])
def test_dict_round_trip(distortion):
    rng = np.random.default_rng(10)
    cam = camera(distortion)
    x = rng.uniform(-0.15, 0.15, (10, 3))
    d = cam.to_dict()
    assert d["kind"] == "dlt" and d["size"] == list(SIZE)
    assert len(d["parameters"]) == (16 if distortion is not None else 11)
    back = camera_from_dict(d)
    assert isinstance(back, DLTCamera)
    np.testing.assert_allclose(back.project(x), cam.project(x), atol=1e-9)
    np.testing.assert_allclose(back.matrix, cam.matrix, atol=1e-12)


def test_origin_behind_or_beside_the_camera():
    rng = np.random.default_rng(11)
    # world origin behind the camera: b9 X + ... + 1 is negative in front
    r = look_at(np.zeros(3), [0, 1, 0])
    behind = DLTCamera.from_krc(K, r, [0, 0.5, 0], SIZE)
    x = rng.uniform(-0.1, 0.1, (10, 3)) + [0, 1.5, 0]
    assert behind.depth_sign == -1 and (behind.depth(x) > 0).all()
    back = camera_from_dict(behind.to_dict())
    np.testing.assert_allclose(back.depth(x), behind.depth(x))
    fit = fit_dlt(x, behind.project(x), SIZE)
    np.testing.assert_allclose(fit.camera.depth(x), behind.depth(x), atol=1e-9)
    # world origin on the principal plane: b-form impossible, the matrix form is used
    beside = DLTCamera.from_krc(K, r, [1.0, 0, 0], SIZE)
    d = beside.to_dict()
    assert "matrix" in d and "parameters" not in d
    np.testing.assert_allclose(camera_from_dict(d).project(x), beside.project(x))


def test_mirrored_camera_is_handled():
    rng = np.random.default_rng(12)
    cam = camera()
    flip = np.diag([-1.0, 1.0, 1.0])  # a reflection of the world in the plane x = 0
    h = np.eye(4)
    h[:3, :3] = flip
    mirrored = cam.transformed(h)
    assert mirrored.is_mirrored and not cam.is_mirrored
    k, r, c = mirrored.decompose()
    assert np.linalg.det(r) == pytest.approx(-1.0)
    np.testing.assert_allclose(k, K, atol=1e-6)
    np.testing.assert_allclose(c, flip @ C, atol=1e-12)
    x = rng.uniform(-0.15, 0.15, (12, 3))
    np.testing.assert_allclose(mirrored.project(x), cam.project(x @ flip), atol=1e-9)
    loc = mirrored.to_camera(x)
    assert (loc[:, 2] > 0).all()
    px = mirrored.project(x)
    np.testing.assert_allclose(loc[:, :2] / loc[:, 2:] @ k[:2, :2].T + k[:2, 2], px, atol=1e-9)
    fit = fit_dlt(x, px, SIZE)
    assert fit.camera.is_mirrored and fit.rms < 1e-6
    np.testing.assert_allclose(camera_from_dict(mirrored.to_dict()).project(x), px)


def test_bad_dicts_name_the_field():
    with pytest.raises(ValueError, match="size"):
        DLTCamera.from_dict({"kind": "dlt", "parameters": [1.0] * 11})
    with pytest.raises(ValueError, match="parameters"):
        DLTCamera.from_dict({"kind": "dlt", "size": [10, 10]})
    with pytest.raises(ValueError, match="11 or 16"):
        DLTCamera.from_dict({"kind": "dlt", "size": [10, 10], "parameters": [1.0] * 12})
