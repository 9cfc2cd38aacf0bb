"""DLT <-> Blender camera conversion (solver/blender_camera.py)."""

import math

import numpy as np
import pytest

from solver.cameras.blender import (
    blender_to_dlt,
    blender_to_krc,
    dlt_to_blender,
    euler_xyz_from_matrix,
    krc_to_blender,
    matrix_from_euler_xyz,
)
from tests.solver.cameras.support import dlt_camera, look_at

# 50 mm lens, 36 mm sensor, 1920 x 1080, shifted; at (0, -2, 0) rotated 90 deg about X,
# i.e. looking along +Y with +Z up
KNOWN = {"lens": 50.0, "sensor_width": 36.0, "sensor_fit": "AUTO", "shift_x": 0.1,
         "shift_y": -0.05, "resolution_x": 1920, "resolution_y": 1080,
         "location": [0.0, -2.0, 0.0], "rotation_euler": [math.pi / 2, 0.0, 0.0]}


def test_known_blender_camera_by_hand():
    # fx = 50 mm * 1920 px / 36 mm = 2666.67 px; the principal point moves against the
    # shift: cx = 960 - 0.1 * 1920 = 768, cy = 540 + (-0.05) * 1920 = 444 (v down).
    # The point (0.1, 0, 0.05) is 2 m in front, 0.1 m right and 0.05 m up:
    # u = 768 + 2666.67 * 0.1 / 2 = 901.33, v = 444 - 2666.67 * 0.05 / 2 = 377.33.
    cam = blender_to_dlt(KNOWN)
    fx = 50.0 * 1920 / 36.0
    expected = [768 + fx * 0.1 / 2, 444 - fx * 0.05 / 2]
    np.testing.assert_allclose(cam.project([[0.1, 0.0, 0.05]]), [expected], atol=1e-9)
    k, r, c, size = blender_to_krc(KNOWN)
    assert size == (1920, 1080)
    np.testing.assert_allclose(k, [[fx, 0, 768], [0, fx, 444], [0, 0, 1]], atol=1e-9)
    np.testing.assert_allclose(r, [[1, 0, 0], [0, 0, -1], [0, 1, 0]], atol=1e-12)
    np.testing.assert_allclose(c, [0, -2, 0])


@pytest.mark.parametrize("k, size", [
    ([[1400.0, 0, 900.0], [0, 1400.0, 600.0], [0, 0, 1]], (1920, 1080)),  # landscape
    ([[2100.0, 0, 500.0], [0, 2100.0, 1000.0], [0, 0, 1]], (1080, 1920)),  # portrait
    ([[1500.0, 0, 640.0], [0, 1000.0, 380.0], [0, 0, 1]], (1280, 720)),  # fx > fy
    ([[900.0, 0, 640.0], [0, 1300.0, 300.0], [0, 0, 1]], (1280, 720)),  # fx < fy
])
def test_round_trip_reprojects_identically(k, size):
    rng = np.random.default_rng(0)
    c = np.array([0.3, -1.1, 0.2])
    cam = dlt_camera(c, [0, 0, 0.05], k, size)
    params = dlt_to_blender(cam)
    assert params["warnings"] == [] and not params["flip_x"]
    assert params["pixel_aspect_x"] >= 1 and params["pixel_aspect_y"] >= 1
    back = blender_to_dlt(params)
    x = rng.uniform(-0.15, 0.15, (50, 3))
    assert np.abs(back.project(x) - cam.project(x)).max() <= 1e-6
    assert back.size == tuple(size)
    # the same through location + Euler angles instead of matrix_world
    alt = {key: v for key, v in params.items() if key != "matrix_world"}
    assert np.abs(blender_to_dlt(alt).project(x) - cam.project(x)).max() <= 1e-6


def test_blender_axes_and_lens():
    c = np.array([0.0, -1.0, 0.0])
    r = look_at(c, [0, 0, 0])  # looking along +Y, v down = -Z
    params = krc_to_blender(np.diag([1920 * 50 / 36.0, 1920 * 50 / 36.0, 1.0]) +
                            np.array([[0, 0, 960], [0, 0, 540], [0, 0, 0]]), r, c, (1920, 1080))
    assert params["lens"] == pytest.approx(50.0)
    assert params["sensor_fit"] == "HORIZONTAL"
    assert params["shift_x"] == pytest.approx(0.0) and params["shift_y"] == pytest.approx(0.0)
    mw = np.array(params["matrix_world"])
    np.testing.assert_allclose(mw[:3, 2], [0, -1, 0], atol=1e-12)  # local +Z points back
    np.testing.assert_allclose(mw[:3, 1], [0, 0, 1], atol=1e-12)  # local +Y is up
    np.testing.assert_allclose(params["rotation_euler"], [math.pi / 2, 0, 0], atol=1e-12)


def test_skew_and_distortion_are_reported():
    rng = np.random.default_rng(1)
    k = np.array([[1400.0, 2.0, 960.0], [0, 1400.0, 540.0], [0, 0, 1]])
    c = np.array([0.0, -1.0, 0.1])
    cam = dlt_camera(c, k=k, size=(1920, 1080), distortion=[-1e-8, 0, 0, 0, 0])
    params = dlt_to_blender(cam)
    assert params["dropped_skew_px"] == pytest.approx(2.0 * 540 / 1400)
    assert any("skew" in w for w in params["warnings"])
    assert any("distortion" in w for w in params["warnings"])
    back = blender_to_dlt(params)
    x = rng.uniform(-0.1, 0.1, (30, 3))
    px = cam.project_ideal(x)
    inside = ((px > 0) & (px < (1920, 1080))).all(axis=1)
    diff = np.abs(back.project(x[inside]) - px[inside]).max()
    assert 0 < diff <= params["dropped_skew_px"] + 1e-9


def test_mirrored_camera_needs_a_flip():
    rng = np.random.default_rng(2)
    c = np.array([0.2, -1.0, 0.1])
    h = np.diag([-1.0, 1.0, 1.0, 1.0])  # reflection in the plane x = 0
    real = dlt_camera(c, k=[[1500, 0, 900], [0, 1500, 500], [0, 0, 1]], size=(1920, 1080))
    mirrored = real.transformed(h)
    with pytest.raises(ValueError, match="mirrored"):
        dlt_to_blender(mirrored)
    params = dlt_to_blender(mirrored, allow_flip=True)
    assert params["flip_x"]
    x = rng.uniform(-0.1, 0.1, (20, 3))
    # the Blender camera sees the left-right flipped photo ...
    flipped = blender_to_dlt({**params, "flip_x": False})
    px = mirrored.project(x)
    np.testing.assert_allclose(flipped.project(x), np.column_stack([1920 - px[:, 0], px[:, 1]]),
                               atol=1e-6)
    # ... and flip_x brings back the mirrored camera itself
    np.testing.assert_allclose(blender_to_dlt(params).project(x), px, atol=1e-6)


def test_euler_round_trip_and_gimbal_lock():
    rng = np.random.default_rng(3)
    for angles in rng.uniform(-3, 3, (20, 3)):
        r = matrix_from_euler_xyz(angles)
        np.testing.assert_allclose(matrix_from_euler_xyz(euler_xyz_from_matrix(r)), r,
                                   atol=1e-12)
    r = matrix_from_euler_xyz([0.3, math.pi / 2, -0.4])
    np.testing.assert_allclose(matrix_from_euler_xyz(euler_xyz_from_matrix(r)), r, atol=1e-9)


def test_bad_params():
    with pytest.raises(ValueError, match="missing field 'lens'"):
        blender_to_krc({"resolution_x": 10, "resolution_y": 10})
    with pytest.raises(ValueError, match="sensor_fit"):
        blender_to_krc({**KNOWN, "sensor_fit": "DIAGONAL"})


def test_agrees_with_blender_itself():
    bpy = pytest.importorskip("bpy")
    from bpy_extras.object_utils import world_to_camera_view
    from mathutils import Vector

    scene = bpy.context.scene
    data = bpy.data.cameras.new("headrecon_test_camera")
    obj = bpy.data.objects.new("headrecon_test_camera", data)
    scene.collection.objects.link(obj)
    rng = np.random.default_rng(4)
    cases = [KNOWN,
             {**KNOWN, "resolution_x": 1080, "resolution_y": 1920, "shift_y": 0.2,
              "rotation_euler": [1.4, 0.1, 0.2], "location": [0.3, -2.0, 0.1]},
             {**KNOWN, "sensor_fit": "VERTICAL", "sensor_height": 20.0, "lens": 35.0},
             {**KNOWN, "resolution_x": 1200, "resolution_y": 1000, "pixel_aspect_y": 1.5}]
    try:
        for p in cases:
            data.lens = p["lens"]
            data.sensor_width = p.get("sensor_width", 36.0)
            data.sensor_height = p.get("sensor_height", 24.0)
            data.sensor_fit = p["sensor_fit"]
            data.shift_x, data.shift_y = p["shift_x"], p["shift_y"]
            scene.render.resolution_x = p["resolution_x"]
            scene.render.resolution_y = p["resolution_y"]
            scene.render.resolution_percentage = 100
            scene.render.pixel_aspect_x = p.get("pixel_aspect_x", 1.0)
            scene.render.pixel_aspect_y = p.get("pixel_aspect_y", 1.0)
            obj.location = p["location"]
            obj.rotation_mode = "XYZ"
            obj.rotation_euler = p["rotation_euler"]
            bpy.context.view_layer.update()
            rot = np.array(obj.matrix_world.to_3x3())
            local = np.column_stack([rng.uniform(-0.4, 0.4, (8, 2)), -rng.uniform(1, 3, 8)])
            x = np.array(p["location"]) + local @ rot.T
            ndc = np.array([world_to_camera_view(scene, obj, Vector(v))[:2] for v in x])
            expect = np.column_stack([ndc[:, 0] * p["resolution_x"],
                                      (1 - ndc[:, 1]) * p["resolution_y"]])
            got = blender_to_dlt(p).project(x)
            assert np.abs(got - expect).max() < 2e-3  # Blender works in float32
    finally:
        bpy.data.objects.remove(obj)
        bpy.data.cameras.remove(data)
