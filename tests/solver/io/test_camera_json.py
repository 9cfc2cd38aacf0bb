"""Cameras as the landmarks file stores them (solver/io/camera_json.py): nominal view
strings, camera objects with parameters, and bad ones."""

import numpy as np
import pytest

from solver import OrthographicCamera, landmarks_to_dict, parse_landmarks
from solver.io.camera_json import (
    camera_from_json,
    camera_object_problems,
    camera_to_json,
    has_parameters,
    is_nominal,
)
from tests.solver.io.support import H, W, assert_rejected


def test_camera_parameters_instead_of_a_string(doc):
    cam = OrthographicCamera.nominal("orthographic-front", (W, H), scale=2500.0,
                                     offset=(380.0, 500.0))
    doc["views"]["front"]["camera"] = cam.to_dict()
    case = parse_landmarks(doc, "case.json")
    x = np.array([[0.02, -0.1, 0.05], [0.0, 0.0, 0.1]])
    np.testing.assert_allclose(case.views["front"].camera.project(x), cam.project(x))
    back = landmarks_to_dict(case)
    assert back["views"]["front"]["camera"]["scale"] == 2500.0
    assert back["views"]["side"]["camera"] == "orthographic-right"


def test_bad_camera_string(doc):
    doc["views"]["side"]["camera"] = "orthographic-rigth"
    assert_rejected(doc, r"case\.json: views\.side\.camera: \"orthographic-rigth\""
                         r" is not one of .*did you mean 'orthographic-right'\?")
    doc["views"]["side"]["camera"] = 3
    assert_rejected(doc, r"views\.side\.camera: 3 matches none of the allowed "
                         r"forms \(expected a string or an object\)")


def test_bad_camera_object(doc):
    doc["views"]["front"]["camera"] = {"kind": "pinhole-from-mars"}
    assert_rejected(doc, r"case\.json: views\.front\.camera: unknown kind "
                         "'pinhole-from-mars'")
    doc["views"]["front"]["camera"] = {"kind": "orthographic", "scale": 1.0}
    assert_rejected(doc, r"views\.front\.camera: .*missing field")
    cam = OrthographicCamera.nominal("orthographic-front", (W + 2, H))
    doc["views"]["front"]["camera"] = cam.to_dict()
    assert_rejected(doc, r"views\.front\.camera: camera size \[770, 1024\] "
                         "differs from the view size")


def test_camera_to_and_from_json():
    nominal = OrthographicCamera.nominal("orthographic-left", (W, H))
    assert camera_to_json(nominal, (W, H)) == "orthographic-left" and is_nominal(nominal, (W, H))
    assert camera_from_json("orthographic-left", (W, H)).view == "orthographic-left"
    moved = OrthographicCamera.nominal("orthographic-left", (W, H), scale=2000.0)
    value = camera_to_json(moved, (W, H))
    assert value == moved.to_dict() and not is_nominal(moved, (W, H))
    back = camera_from_json({k: v for k, v in value.items() if k != "size"}, (W, H))
    assert back.size == (W, H) and back.scale == 2000.0  # the size defaults to the view's
    with pytest.raises(ValueError, match=r"camera size \[10, 10\] differs from the view size"):
        camera_from_json({**value, "size": [10, 10]}, (W, H))
    with pytest.raises(ValueError, match="expected a view name or a camera object"):
        camera_from_json(3, (W, H))


def test_camera_objects_without_parameters():
    assert not has_parameters({"kind": "dlt"}) and not has_parameters({"kind": "pinhole"})
    assert has_parameters({"kind": "dlt", "matrix": []}) and has_parameters({"kind": "ortho"})
    where = ("views", "v", "camera")
    assert camera_object_problems({"kind": "dlt"}, (W, H), where) == []
    assert camera_object_problems({"kind": "dlt", "depth_sign": 1}, (W, H), where) == [
        ("views.v.camera.depth_sign", "given without the camera's 'parameters' (or 'matrix')")]
    assert camera_object_problems({"kind": "pinhole", "lens_mm": float("inf")}, (W, H),
                                  where) == [("views.v.camera.lens_mm", "not a finite number; "
                                              "NaN and infinity are not allowed")]

