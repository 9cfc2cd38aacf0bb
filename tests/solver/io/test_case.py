"""The landmarks file's data (solver/io/case.py): views and cases as built in code, their
equality, the file version that holds them, photo paths and passpoints."""

from pathlib import Path

import numpy as np

from solver import OrthographicCamera, PinholeCamera
from solver.io.case import LandmarkCase, View, case_version

SIZE = (100, 200)


def ortho():
    return OrthographicCamera.nominal("orthographic-front", SIZE)


def test_view_normalises_what_it_is_given():
    view = View("v", None, np.array([100, 200]), ortho(), {"a": np.array([1, 2])},
                contour=[1.0, 2.0, 3.0, 4.0], passpoints={"p": [5, 6]})
    assert view.size == (100, 200) and view.points == {"a": (1.0, 2.0)}
    assert view.passpoints == {"p": (5.0, 6.0)} and view.contour.shape == (2, 2)
    assert view.camera_kind == "orthographic" and not view.camera_fixed
    hinted = View("h", None, SIZE, None, {}, camera_hints={"kind": "dlt"}, calibrated=True)
    assert hinted.camera_kind == "dlt" and hinted.camera_fixed
    assert hinted.version2_features() == ["camera", "calibrated"]
    assert view.version2_features() == ["passpoints"]


def test_equality_is_that_of_the_stored_file():
    a = View("v", "a.jpg", SIZE, ortho(), {"x": (1.0, float("nan"))})
    b = View("v", "a.jpg", SIZE, ortho(), {"x": (1.0, float("nan"))})
    assert a == b  # NaN points compare equal: the files are the same
    assert a != View("v", "b.jpg", SIZE, ortho(), {"x": (1.0, float("nan"))})
    one, two = LandmarkCase({"v": a}), LandmarkCase({"v": b}, source="elsewhere.json")
    assert one == two  # the source is not stored
    assert one != LandmarkCase({"v": b}, passpoints={"p": [0, 0, 0]})
    assert one != LandmarkCase({"v": b}, extra={"x-note": 1})


def test_case_version_paths_and_counts(tmp_path):
    view = View("v", "photos/front.jpg", SIZE, ortho(), {"x": (1.0, 2.0), "y": (3.0, 4.0)})
    case = LandmarkCase({"v": view}, str(tmp_path / "case.json"))
    assert case_version(case) == case.version == 1 and case.n_points == 2
    assert case.base_dir == tmp_path.resolve()
    assert case.image_path("v") == tmp_path.resolve() / "photos" / "front.jpg"
    assert LandmarkCase({"v": view}).image_path("v") == Path.cwd() / "photos" / "front.jpg"
    view.passpoints = {"p": (1.0, 2.0)}
    case.passpoints = {"p": np.array([0.1, 0.2, 0.3])}
    assert case_version(case) == 2
    names, xyz, uv = case.passpoint_arrays("v")
    assert names == ["p"] and xyz.tolist() == [[0.1, 0.2, 0.3]] and uv.tolist() == [[1.0, 2.0]]


def test_a_camera_as_read_is_written_back_as_read():
    cam = PinholeCamera.look_at([1.1, -1.1, 0.05], [0, 0, 0], SIZE, lens_mm=50).to_dlt()
    # as a file may write it: fewer digits than the camera recomputes
    stored = {**cam.to_dict(), "parameters": [round(b, 6) for b in cam.to_dict()["parameters"]]}
    view = View("v", None, SIZE, cam, {})
    view.keep_camera_as_read(stored)
    assert view.to_dict()["camera"] == stored != cam.to_dict()
    view.camera = PinholeCamera.look_at([1.2, -1.0, 0.0], [0, 0, 0], SIZE, lens_mm=50).to_dlt()
    assert view.to_dict()["camera"] == view.camera.to_dict()  # another camera: its own
