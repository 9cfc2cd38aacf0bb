"""The checks a schema cannot express (solver/io/case_check.py): points inside the image,
finite numbers, a landmark given twice, enough landmarks for a fit, cameras, mirror views
and passpoints; every message names the file, the view and the key."""

import json
import re

import pytest

from solver import (
    MIN_LANDMARKS_PER_VIEW,
    MIN_LANDMARKS_TOTAL,
    LandmarkCase,
    LandmarksError,
    OrthographicCamera,
    View,
    check_case,
    load_landmarks,
    parse_landmarks,
)
from tests.solver.io.support import (
    SRC2,
    V2_INVALID,
    H,
    W,
    assert_rejected,
    drop_passpoints,
    problems_of,
)

# --------------------------------------------------------------------------------------
# Version 1


@pytest.mark.parametrize("point,what", [([W + 0.5, 100.0], "u"), ([100.0, -0.01], "v")])
def test_point_outside_the_image(doc, names, point, what):
    doc["views"]["front"]["points"][names[2]] = point
    assert_rejected(doc, rf"case\.json: views\.front\.points\.{names[2]}: "
                         rf"\(.*\) lies outside the {W}x{H} image")


def test_edges_of_the_image_are_inside(doc, names):
    doc["views"]["front"]["points"][names[0]] = [0, 0]
    doc["views"]["front"]["points"][names[1]] = [W, H]
    parse_landmarks(doc, "case.json")


def test_contour_point_outside_the_image(doc):
    doc["views"]["side"]["contour"].append([10.0, H + 3.0])
    assert_rejected(doc, r"case\.json: views\.side\.contour\[3\]: .*outside")


def test_nan_and_infinity_are_rejected(tmp_path, doc, names):
    # Python's json reads NaN / Infinity although JSON has neither
    text = json.dumps(doc).replace(json.dumps(doc["views"]["side"]["points"][names[3]]),
                                   "[NaN, 12.0]")
    path = tmp_path / "case.json"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(ValueError, match=rf"case\.json: views\.side\.points\.{names[3]}: "
                                         "not a finite number"):
        load_landmarks(path)
    doc["views"]["side"]["contour"][0] = [float("inf"), 1.0]
    assert_rejected(doc, r"views\.side\.contour\[0\]: not a finite number")


def test_duplicate_landmark_through_its_ibug_alias(doc, lms):
    number = sorted(lms.ibug)[0]
    canon = lms.ibug[number]
    doc["views"]["front"]["points"][f"ibug{number:02d}"] = [50.0, 60.0]
    assert_rejected(doc, rf"case\.json: views\.front\.points\.ibug{number:02d}: "
                         rf"the same landmark as '{canon}'")


def test_too_few_landmarks(doc, names):
    keep = names[:MIN_LANDMARKS_PER_VIEW - 1]
    doc["views"]["side"]["points"] = {n: doc["views"]["side"]["points"][n] for n in keep}
    contour = doc["views"]["side"].pop("contour", None)
    assert_rejected(doc, rf"case\.json: views\.side\.points: {len(keep)} "
                         rf"usable landmarks; the fit needs at least "
                         rf"{MIN_LANDMARKS_PER_VIEW} in this view")
    # work in progress is fine when not fitting
    assert parse_landmarks(doc, "case.json", for_fit=False).views["side"].points
    # a profile's traced outline places its camera: then no landmark is needed there
    doc["views"]["side"]["contour"] = contour or [[300.0, 100.0], [320.0, 500.0],
                                                  [310.0, 900.0]]
    doc["views"]["side"]["points"] = {}
    assert parse_landmarks(doc, "case.json").views["side"].contour is not None


def test_too_few_landmarks_in_all(doc):
    del doc["views"]["side"]
    pts = doc["views"]["front"]["points"]
    doc["views"]["front"]["points"] = dict(list(pts.items())[:MIN_LANDMARKS_TOTAL - 1])
    assert_rejected(doc, rf"case\.json: views: {MIN_LANDMARKS_TOTAL - 1} "
                         "usable landmarks in all; the fit needs at least")


def test_too_few_different_landmarks_in_all(doc, names):
    """Three landmarks placed in both photos passed as six and ended the fit in "source:
    needs at least 4 points, got 3" (the thin-plate spline's), naming nothing."""
    three = names[:3]
    for view in doc["views"].values():
        view["points"] = {n: view["points"][n] for n in three}
    assert_rejected(doc, re.escape(
        f"case.json: views: 3 different landmarks in all ({', '.join(sorted(three))}); the "
        "fit needs at least 4 different ones (a landmark placed in several photos counts "
        "once)"))
    doc["views"]["side"]["points"][names[3]] = [200.0, 300.0]
    parse_landmarks(doc, "case.json")


def test_all_problems_are_listed(doc, names):
    doc["views"]["front"]["points"]["nope_one"] = [1.0, 1.0]
    doc["views"]["side"]["points"][names[0]] = [-5.0, 1.0]
    with pytest.raises(LandmarksError) as info:
        parse_landmarks(doc, "case.json")
    err = info.value
    assert isinstance(err, ValueError)
    assert len(err.problems) == 2 and "(and 1 more problem)" in str(err)
    assert "\n" not in str(err)
    lines = err.messages()
    assert lines[0].startswith("case.json: views.front.points.nope_one: unknown landmark")
    assert lines[1].startswith(f"case.json: views.side.points.{names[0]}: (-5, 1) lies outside")


def test_view_names_with_spaces_are_quoted_in_paths(doc):
    doc["views"]["left side"] = doc["views"].pop("side")
    doc["views"]["left side"]["points"]["bogus"] = [1.0, 1.0]
    assert_rejected(doc, r'case\.json: views\["left side"\]\.points\.bogus: ')


def test_check_case_on_a_built_case(names):
    cam = OrthographicCamera.nominal("orthographic-left", (100, 100))
    pts = {names[0]: (10.0, 10.0), names[1]: (float("nan"), 1.0), names[2]: (200.0, 1.0)}
    case = LandmarkCase({"s": View("s", None, (100, 100), cam, pts)})
    problems = dict(check_case(case, for_fit=False))
    assert set(problems) == {f"views.s.points.{names[1]}", f"views.s.points.{names[2]}"}
    assert "outside the 100x100 image" in problems[f"views.s.points.{names[2]}"]


# --------------------------------------------------------------------------------------
# Version 2


@pytest.mark.parametrize("what", list(V2_INVALID))
def test_version2_invalid(doc2, what):
    mutate, pattern = V2_INVALID[what]
    mutate(doc2)
    lines = problems_of(doc2)
    assert any(re.search(pattern, line) for line in lines), lines


def test_passpoint_problems_are_not_repeated(doc2):
    doc2["passpoints"]["cube_2"] = [0.0, float("nan"), 0.0]
    assert problems_of(doc2) == [f"{SRC2}: passpoints.cube_2: not a finite number; NaN and "
                                 "infinity are not allowed"]


def test_calibrated_camera_from_passpoints(doc2):
    # computed from the passpoints, then kept fixed: no parameters needed in the file
    doc2["views"]["left_mirror"]["calibrated"] = True
    case = parse_landmarks(doc2, SRC2)
    assert case.views["left_mirror"].camera is None and case.views["left_mirror"].camera_fixed


def test_version2_draft_needs_no_passpoint_or_landmark_floor(doc2):
    drop_passpoints(doc2, "left_mirror", 2)
    doc2["views"]["left"]["points"] = {}
    parse_landmarks(doc2, SRC2, for_fit=False)
    assert problems_of(doc2) == [
        f"{SRC2}: views.left.points: 0 usable landmarks; the fit needs at least 4 in this "
        "view (4 more)",
        f"{SRC2}: views.left_mirror.passpoints: 2 passpoints; computing the camera needs at "
        "least 6, not all in one plane"]


def test_check_case_on_built_version2_views(names):
    pts = {n: (10.0 + i, 20.0) for i, n in enumerate(names[:4])}
    rot = OrthographicCamera.nominal("orthographic-front", (W, H)).rotation
    views = {
        "a": View("a", None, (W, H), OrthographicCamera(rot, float("nan"), (0, 0), (W, H)), pts),
        "b": View("b", None, (W, H), None, pts),
        "c": View("c", None, (W, H), None, pts, camera_hints={"kind": "orthographic"}),
        "d": View("d", None, (W, H), OrthographicCamera.nominal("orthographic-front", (W, H)),
                  pts, calibrated="yes"),
        "e": View("e", None, (W, H), None, pts, camera_hints={"kind": "fisheye"}),
        "f": View("f", None, (W, H), None, pts, camera_hints={"kind": "dlt"},
                  passpoints={"p": (1.0, 2.0)}),
    }
    case = LandmarkCase(views, passpoints={"p": [0.0, 0.0, float("inf")]})
    problems = dict(check_case(case, for_fit=False))
    assert problems["views.a.camera.scale"].startswith("not a finite number")
    assert problems["views.b.camera"].startswith("no camera")
    assert problems["views.c.camera"].startswith("an orthographic camera without parameters")
    assert problems["views.d.calibrated"] == "expected true or false, got 'yes'"
    assert problems["views.e.camera.kind"] == ("unknown kind 'fisheye'; known: "
                                               "dlt, orthographic, pinhole")
    assert problems["passpoints.p"].startswith("not a finite number")
    assert "views.f.passpoints.p" not in problems  # its pixels are fine
    with pytest.raises(ValueError, match=r"<dict>: views\.a\.passpoints\.q: not defined"):
        LandmarkCase({"a": View("a", None, (W, H), None, {}, passpoints={"q": (1, 1)})}
                     ).passpoint_arrays("a")
