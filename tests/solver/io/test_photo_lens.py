"""Each orthographic photo's EXIF lens into its view's camera hints, and nothing else."""

import numpy as np
import pytest

from solver import LandmarkCase, OrthographicCamera, View, orthographic_lenses
from solver.io import exif
from tests.solver.io.exif_jpeg import jpeg, tiff


def _view(name, camera, hints=None):
    return View(name, f"{name}.jpg", (90, 120), camera, {"nose_tip": (40.0, 60.0)},
                camera_hints=hints or {})


def test_only_orthographic_photos_with_a_focal_length_get_one(tmp_path):
    phone = jpeg(tiff([], [(exif.FOCAL_35MM, 3, [26])]), pixels=np.zeros((120, 90, 3),
                                                                         np.uint8))
    for name in ("front", "pinhole", "plain"):
        (tmp_path / f"{name}.jpg").write_bytes(phone if name != "plain" else jpeg(
            None, size=(90, 120)))
    front = OrthographicCamera.nominal("orthographic-front", (90, 120))
    case = LandmarkCase({"front": _view("front", front),
                         "pinhole": _view("pinhole", None, {"kind": "pinhole"}),
                         "plain": _view("plain", front),
                         "gone": _view("gone", front),
                         "unnamed": _view("unnamed", front)}, "<test>")
    paths = {n: tmp_path / f"{n}.jpg" for n in ("front", "pinhole", "plain", "gone")}
    paths["unnamed"] = None
    found = orthographic_lenses(case, paths)
    # 26 mm by the diagonal of a 3:4 photo is 27.0 mm across its long side
    assert found == {"front": pytest.approx(27.04, abs=0.01)}
    assert case.views["front"].camera_hints == {"lens_mm": found["front"]}
    assert case.views["pinhole"].camera_hints == {"kind": "pinhole"}
    assert all(case.views[n].camera_hints == {} for n in ("plain", "gone", "unnamed"))


def test_by_default_the_photos_the_case_names(tmp_path):
    (tmp_path / "front.jpg").write_bytes(jpeg(tiff([], [(exif.FOCAL_35MM, 3, [50])]),
                                              pixels=np.zeros((120, 90, 3), np.uint8)))
    front = OrthographicCamera.nominal("orthographic-front", (90, 120))
    case = LandmarkCase({"front": _view("front", front)}, str(tmp_path / "case.json"))
    assert orthographic_lenses(case) == {"front": pytest.approx(52.0, abs=0.01)}
