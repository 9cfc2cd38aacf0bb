"""The landmarks file (solver/io/landmarks_file.py): valid documents of both versions,
schema errors and unreadable files (messages naming file, view and key), ibug aliases, round
trips, atomic saving, the version written."""

import copy
import json
import os
import re

import numpy as np
import pytest

from solver import (
    DLTCamera,
    LandmarkCase,
    OrthographicCamera,
    PinholeCamera,
    View,
    fit_dlt,
    landmarks_to_dict,
    load_landmarks,
    parse_landmarks,
    save_landmarks,
)
from tests.solver.io.support import (
    CUBE,
    CUBE_NAMES,
    HEAD,
    SRC2,
    H,
    W,
    assert_rejected,
    load_written,
    make_doc,
    save_and_load,
    v2_cameras,
)

# --------------------------------------------------------------------------------------
# Reading


def test_valid_document_parses(doc, names, lms):
    case = parse_landmarks(doc, "case.json")
    assert isinstance(case, LandmarkCase) and case.source == "case.json"
    assert list(case.views) == ["front", "side"]
    front, side = case.views["front"], case.views["side"]
    assert front.size == (W, H) and front.image == "front.jpg"
    assert front.points[names[0]] == tuple(doc["views"]["front"]["points"][names[0]])
    assert side.contour.shape == (3, 2) and side.contour[1, 1] == 131.0
    assert front.contour is None
    # the camera strings map to the nominal cameras of solver/cameras.py
    assert isinstance(side.camera, OrthographicCamera) and side.camera.view == "orthographic-right"
    nominal = OrthographicCamera.nominal("orthographic-right", (W, H))
    x = np.array([[0.01, -0.1, 0.05]])
    np.testing.assert_allclose(side.camera.project(x), nominal.project(x))
    assert case.n_points == 8 + 6
    got_names, vertices, pixels = front.arrays(lms)
    assert got_names == names[:8]
    assert vertices.tolist() == [lms.vertex(n) for n in names[:8]]
    np.testing.assert_array_equal(pixels[2], doc["views"]["front"]["points"][names[2]])


def test_ibug_aliases_resolve_and_are_kept_as_written(doc, names, lms):
    number = sorted(lms.ibug)[0]
    canon = lms.ibug[number]
    alias = f"ibug{number:02d}"
    pts = doc["views"]["front"]["points"]
    pts[alias] = pts.pop(canon)
    case = parse_landmarks(doc, "case.json")
    assert alias in case.views["front"].points and canon not in case.views["front"].points
    got_names, vertices, _ = case.views["front"].arrays()
    i = list(case.views["front"].points).index(alias)
    assert got_names[i] == canon and vertices[i] == lms.vertex(canon)
    assert landmarks_to_dict(case)["views"]["front"]["points"][alias] == pts[alias]


def test_unknown_ibug_number(doc):
    doc["views"]["front"]["points"]["ibug99"] = [10.0, 10.0]
    assert_rejected(doc, r"case.json: views.front.points.ibug99: unknown ")


@pytest.mark.parametrize("view,key,pattern", [
    ("front", "size", r"case\.json: views\.front: missing required key 'size'"),
    ("side", "camera", r"case\.json: views\.side: missing required key 'camera'"),
    ("front", "points", r"case\.json: views\.front: missing required key 'points'"),
])
def test_missing_field(doc, view, key, pattern):
    del doc["views"][view][key]
    assert_rejected(doc, pattern)


def test_missing_top_level_fields(doc):
    for key in ("views", "format", "version"):
        d = copy.deepcopy(doc)
        del d[key]
        assert_rejected(d, rf"case\.json: .*{key}")


@pytest.mark.parametrize("view,key,landmark,value,pattern", [
    ("front", "points", 1, [12.0, "540"],
     r"case\.json: views\.front\.points\.<name>\[1\]: expected a number, got string"),
    ("side", "size", None, [768.5, 1024], r"views\.side\.size\[0\]: expected an integer"),
    ("side", "points", 0, [1.0, 2.0, 3.0],
     r"views\.side\.points\.<name>: expected at most 2 items"),
    ("front", "points", None, [[1, 2]], r"views\.front\.points: expected an object, got array"),
    # JSON true is not a number
    ("front", "size", None, [True, 1024],
     r"views\.front\.size\[0\]: expected an integer, got boolean"),
])
def test_wrong_types(doc, names, view, key, landmark, value, pattern):
    """A value of the wrong type, in a view's field or (``landmark``: index into ``names``)
    one landmark of it; ``<name>`` in the pattern stands for that landmark."""
    if landmark is None:
        doc["views"][view][key] = value
    else:
        doc["views"][view][key][names[landmark]] = value
        pattern = pattern.replace("<name>", names[landmark])
    assert_rejected(doc, pattern)


def test_unexpected_key_suggests_the_right_one(doc):
    doc["views"]["front"]["camrea"] = "orthographic-front"
    assert_rejected(doc, r"case\.json: views\.front\.camrea: unexpected key; "
                         r"did you mean 'camera'\?")


def test_x_keys_are_free_and_kept(doc):
    doc["x-tool"] = {"anything": [1, 2]}
    doc["views"]["front"]["x-note"] = "checked by Ada"
    case = parse_landmarks(doc, "case.json")
    back = landmarks_to_dict(case)
    assert back["x-tool"] == {"anything": [1, 2]}
    assert back["views"]["front"]["x-note"] == "checked by Ada"


def test_bad_version_and_format(doc):
    for version in (3, 0, "1", True, None):
        d = dict(doc, version=version)
        assert_rejected(d, r"case\.json: version: unsupported version .*reads "
                           "versions 1 and 2")
    d = dict(doc, format="headrecon-landmark-set")
    assert_rejected(d, r"case\.json: format: expected 'headrecon-landmarks'")
    with pytest.raises(ValueError, match=r"case\.json: expected a JSON object"):
        parse_landmarks([doc], "case.json")


def test_not_json_not_utf8_missing(tmp_path):
    p = tmp_path / "case.json"
    p.write_text('{"format": "headrecon-landmarks", "version": 1,,}', encoding="utf-8")
    with pytest.raises(ValueError, match=r"case\.json: not valid JSON: .*line 1, column"):
        load_landmarks(p)
    p.write_bytes(b'{"format": "\xff\xfe"}')
    with pytest.raises(ValueError, match=r"case\.json: not UTF-8 text \(byte 0xff"):
        load_landmarks(p)
    with pytest.raises(FileNotFoundError, match=r"nothere\.json: no such file"):
        load_landmarks(tmp_path / "nothere.json")
    p.write_text('{"format": "a", "format": "b"}', encoding="utf-8")
    with pytest.raises(ValueError, match=r"case\.json: key 'format' appears twice"):
        load_landmarks(p)


def test_utf8_bom_and_unicode_view_names(tmp_path, doc):
    doc["views"]["Vorderansicht ä"] = doc["views"].pop("front")
    p = tmp_path / "case.json"
    p.write_bytes(b"\xef\xbb\xbf" + json.dumps(doc, ensure_ascii=False).encode("utf-8"))
    case = load_landmarks(p)
    assert "Vorderansicht ä" in case.views


# --------------------------------------------------------------------------------------
# Writing


def test_round_trip(tmp_path, doc):
    a = load_written(tmp_path / "case.json", doc)
    out = tmp_path / "again.json"
    b = save_and_load(a, out)
    assert a == b
    assert landmarks_to_dict(b) == doc
    assert json.loads(out.read_text(encoding="utf-8")) == doc
    # one landmark per line: the file stays readable and diffs well
    text = out.read_text(encoding="utf-8")
    first = next(iter(doc["views"]["front"]["points"]))
    assert re.search(rf'"{first}": \[[\d.]+, [\d.]+\],?\n', text)
    assert sorted(os.listdir(tmp_path)) == ["again.json", "case.json"]  # no temp files
    b.views["front"].points[first] = (1.0, 2.0)
    assert a != b


def test_saving_elsewhere_keeps_images_pointing_at_the_photos(tmp_path, doc):
    (tmp_path / "shoot").mkdir()
    case = load_written(tmp_path / "shoot" / "case.json", doc)
    out = tmp_path / "work" / "copy.json"
    out.parent.mkdir()
    again = save_and_load(case, out)
    assert again.views["front"].image == "../shoot/front.jpg"
    assert again.image_path("front").resolve() == (tmp_path / "shoot" / "front.jpg").resolve()


def test_save_is_atomic_and_refuses_bad_cases(tmp_path, doc, monkeypatch):
    path = tmp_path / "case.json"
    case = load_written(path, doc)
    before = path.read_bytes()
    case.views["front"].points["not_a_landmark"] = (1.0, 1.0)
    with pytest.raises(ValueError, match=r"case\.json: views\.front\.points\.not_a_landmark"):
        save_landmarks(case, path)
    assert path.read_bytes() == before
    del case.views["front"].points["not_a_landmark"]

    def failing_replace(a, b):
        raise OSError("disk full")

    monkeypatch.setattr(os, "replace", failing_replace)
    case.views["front"].points[next(iter(case.views["front"].points))] = (5.0, 5.0)
    with pytest.raises(OSError, match="disk full"):
        save_landmarks(case, path)
    assert path.read_bytes() == before
    assert os.listdir(tmp_path) == ["case.json"]


def test_save_allows_work_in_progress(tmp_path, names):
    cam = OrthographicCamera.nominal("orthographic-front", (W, H))
    case = LandmarkCase({"front": View("front", None, (W, H), cam,
                                       {names[0]: np.array([10.0, 20.0])})})
    path = tmp_path / "wip.json"
    save_landmarks(case, path)
    again = load_landmarks(path, for_fit=False)
    assert again == case
    assert again.views["front"].image is None
    with pytest.raises(ValueError, match=r"views\.front\.points: 1 usable landmark;"):
        load_landmarks(path)


# --------------------------------------------------------------------------------------
# Version 2


def test_version2_document_parses(doc2, names, lms):
    case = parse_landmarks(doc2, SRC2)
    assert case.version == 2
    assert list(case.views) == ["front", "three_quarter", "left", "left_mirror"]
    front, tq, left, mirror = case.views.values()
    cams = v2_cameras()
    # the three-quarter view: a DLT-16 camera, given and kept fixed
    assert isinstance(tq.camera, DLTCamera) and tq.camera.n_params == 16
    assert tq.calibrated is True and tq.camera_fixed and tq.camera_kind == "dlt"
    np.testing.assert_allclose(tq.camera.project(CUBE), cams["three_quarter"].project(CUBE),
                               atol=1e-6)
    assert len(tq.points) == 2  # below the per-view floor: fine, the view has passpoints
    # the left view: a pinhole camera to refine, its options kept
    assert isinstance(left.camera, PinholeCamera) and left.calibrated is False
    assert not left.camera_fixed and left.camera.focal_prior == (35.0, 0.05)
    np.testing.assert_allclose(left.camera.project(HEAD), cams["left"].project(HEAD),
                               atol=1e-9)
    # the mirror view: camera unknown, to be computed from its passpoints
    assert mirror.camera is None and mirror.camera_kind == "dlt"
    assert mirror.camera_hints == {"kind": "dlt"} and mirror.mirror_of == "left"
    assert mirror.calibrated is None and not mirror.camera_fixed
    # the mirror view's landmarks carry the subject's true names: same vertices as direct
    assert mirror.arrays(lms)[1].tolist() == left.arrays(lms)[1].tolist()
    # the orthographic view as in version 1
    assert front.camera.view == "orthographic-front" and front.calibrated is None
    assert front.passpoints == {} and front.mirror_of is None
    assert set(case.passpoints) == set(CUBE_NAMES)
    np.testing.assert_array_equal(case.passpoints["cube_3"], CUBE[3])
    # what the fit (or a calibrate step) does with the passpoints: the DLT of the mirror
    # view is the mirrored camera of the photo
    pnames, xyz, uv = case.passpoint_arrays("left_mirror")
    assert pnames == CUBE_NAMES and xyz.shape == (10, 3) and uv.shape == (10, 2)
    np.testing.assert_array_equal(xyz, CUBE)
    fit = fit_dlt(xyz, uv, mirror.size)
    assert fit.camera.is_mirrored
    np.testing.assert_allclose(fit.camera.project(HEAD), cams["left_mirror"].project(HEAD),
                               atol=0.01)


def test_version2_round_trip(tmp_path, doc2):
    a = load_written(tmp_path / "case2.json", doc2)
    out = tmp_path / "again.json"
    b = save_and_load(a, out)
    assert a == b and b.version == 2
    # the file comes back as written: camera numbers are not recomputed (a DLT's b-form
    # would move by a rounding error), passpoints and v2 keys are kept
    assert json.loads(out.read_text(encoding="utf-8")) == doc2
    again = tmp_path / "again2.json"
    save_landmarks(b, again)
    assert again.read_bytes() == out.read_bytes()
    # a camera the fit computed replaces the unknown one and is written from its parameters
    uv = b.passpoint_arrays("left_mirror")
    b.views["left_mirror"].camera = fit_dlt(uv[1], uv[2], (W, H)).camera
    b.views["left_mirror"].calibrated = True
    c = save_and_load(b, out)
    cam = c.views["left_mirror"].camera
    assert isinstance(cam, DLTCamera) and cam.is_mirrored and c.views["left_mirror"].camera_fixed
    np.testing.assert_allclose(cam.project(HEAD), b.views["left_mirror"].camera.project(HEAD),
                               atol=1e-6)
    assert json.loads(out.read_text(encoding="utf-8"))["views"]["left_mirror"]["camera"][
        "parameters"] == pytest.approx(cam.parameters.tolist(), rel=1e-9)
    assert c != a


def test_version1_files_load_and_save_unchanged(tmp_path, doc):
    src = tmp_path / "case.json"
    case = load_written(src, doc)
    assert case.version == 1 and case.passpoints == {}
    for view in case.views.values():  # the version-2 fields keep their defaults
        assert view.calibrated is None and view.mirror_of is None and view.passpoints == {}
        assert view.camera_hints == {} and view.camera_kind == "orthographic"
        assert not view.camera_fixed and view.version2_features() == []
    out, out2 = tmp_path / "a.json", tmp_path / "b.json"
    save_landmarks(case, out)
    save_landmarks(load_landmarks(out), out2)
    assert json.loads(out.read_text(encoding="utf-8")) == doc
    assert out2.read_bytes() == out.read_bytes()
    assert '"version": 1,' in out.read_text(encoding="utf-8")
    # camera objects were allowed in version 1 and keep the file at version 1
    doc["views"]["side"]["camera"] = v2_cameras()["three_quarter"].to_dict()
    save_landmarks(load_written(src, doc), out)
    assert json.loads(out.read_text(encoding="utf-8")) == doc


def test_version_written_is_the_lowest_that_holds_the_case(doc, names):
    case = parse_landmarks(doc, "case.json")
    assert landmarks_to_dict(case)["version"] == 1
    forced = landmarks_to_dict(case, version=2)
    assert forced["version"] == 2 and parse_landmarks(forced, "case.json") == case
    for feature, value in (("calibrated", False), ("mirror_of", "front"),
                           ("passpoints", {"p": (1.0, 2.0)})):
        c = parse_landmarks(doc, "case.json")
        setattr(c.views["side"], feature, value)
        assert c.version == 2 and landmarks_to_dict(c)["version"] == 2
        with pytest.raises(ValueError, match=rf"case\.json: views\.side\.{feature}: needs "
                                             "version 2 of the file"):
            landmarks_to_dict(c, version=1)
    c = parse_landmarks(doc, "case.json")
    c.views["side"].camera = None
    c.views["side"].camera_hints = {"kind": "pinhole"}
    assert c.version == 2
    c = LandmarkCase(case.views, "case.json", passpoints={"p": [0.0, 0.1, 0.2]})
    assert c.version == 2 and landmarks_to_dict(c)["passpoints"] == {"p": [0.0, 0.1, 0.2]}
    with pytest.raises(ValueError, match=r"case\.json: passpoints: needs version 2"):
        landmarks_to_dict(c, version=1)
    with pytest.raises(ValueError, match=r"version: expected one of \[1, 2\], got 3"):
        landmarks_to_dict(case, version=3)


def test_cli_validate_describes_version2_files(tmp_path, doc2, capsys):
    from solver import cli

    path = tmp_path / "case2.json"
    path.write_text(json.dumps(doc2), encoding="utf-8")
    assert cli.main(["validate", str(path)]) == 0
    out = capsys.readouterr().out
    assert out.strip() == (
        f"{path}: OK (version 2; front 8 landmarks, orthographic camera (nominal), refined; "
        "three_quarter 2 landmarks + 10 passpoints, dlt camera given, kept fixed; "
        "left 8 landmarks, pinhole camera given, refined; "
        "left_mirror 8 landmarks + 10 passpoints, dlt camera from passpoints, refined, "
        "mirror image in 'left'; 10 passpoints defined)")
    doc2["views"]["left_mirror"]["mirror_of"] = "lfet"
    path.write_text(json.dumps(doc2), encoding="utf-8")
    assert cli.main(["validate", str(path)]) == 1
    err = capsys.readouterr().err
    assert f"{path}: views.left_mirror.mirror_of: no view named 'lfet'" in err


# --------------------------------------------------------------------------------------
# Per-landmark uncertainty (optional, both versions)


@pytest.mark.parametrize("version", [1, 2])
def test_uncertainty_round_trips_and_is_checked(names, tmp_path, version):
    doc = make_doc(names)
    doc["version"] = version
    first, second = list(doc["views"]["front"]["points"])[:2]
    doc["views"]["front"]["uncertainty"] = {first: 2.5, second: 12.0}
    case = load_written(tmp_path / "case.json", doc)
    assert case.views["front"].uncertainty == {first: 2.5, second: 12.0}
    assert case.views["side"].uncertainty == {}
    again = save_and_load(case, tmp_path / "again.json")
    assert again.views["front"].uncertainty == {first: 2.5, second: 12.0}
    assert "uncertainty" not in json.loads((tmp_path / "again.json").read_text())[
        "views"]["side"]
    bad = copy.deepcopy(doc)
    bad["views"]["front"]["uncertainty"] = {first: 0}
    assert_rejected(bad, rf"views\.front\.uncertainty\.{first}")
    bad["views"]["front"]["uncertainty"] = {names[-1]: 3.0}          # not placed there
    assert_rejected(bad, rf"views\.front\.uncertainty\.{names[-1]}: no such landmark")


def test_depth_round_trips_and_needs_the_points_uncertainty(names, tmp_path):
    doc = make_doc(names)
    first, second = list(doc["views"]["front"]["points"])[:2]
    doc["views"]["front"]["uncertainty"] = {first: 2.5, second: 12.0}
    doc["views"]["front"]["depth"] = {first: -3.25, second: 10.0}
    case = load_written(tmp_path / "case.json", doc)
    assert case.views["front"].depth == {first: -3.25, second: 10.0}
    assert case.views["side"].depth == {}
    again = save_and_load(case, tmp_path / "again.json")
    assert again.views["front"].depth == {first: -3.25, second: 10.0}
    assert "depth" not in json.loads((tmp_path / "again.json").read_text())["views"]["side"]
    bad = copy.deepcopy(doc)
    bad["views"]["front"]["uncertainty"] = {first: 2.5}
    assert_rejected(bad, rf"views\.front\.depth\.{second}: a depth needs the landmark's "
                         "'uncertainty'")
    bad["views"]["front"]["depth"] = {first: "deep"}
    assert_rejected(bad, rf"views\.front\.depth\.{first}")
