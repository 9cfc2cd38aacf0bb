"""The landmarks file: format, every kind of invalid input (messages naming file, view and
key), ibug aliases, round trips, atomic saving, and our schema validator cross-checked
against the reference ``jsonschema`` package."""

import copy
import json
import os
import random
import re

import jsonschema
import numpy as np
import pytest

from solver.cameras import OrthographicCamera, camera_kinds
from solver.cameras.dlt import DLTCamera, fit_dlt
from solver.cameras.mirror import MirrorPlane, reflected_camera
from solver.cameras.pinhole import PinholeCamera
from solver.io.jsonschema_lite import (
    KEYWORDS,
    SchemaKeywordError,
    Validator,
    format_path,
    validate,
)
from solver.io.landmarks_file import (
    MIN_LANDMARKS_PER_VIEW,
    MIN_LANDMARKS_TOTAL,
    SCHEMA_PATH,
    LandmarkCase,
    LandmarksError,
    LandmarkSet,
    View,
    check_case,
    landmarks_to_dict,
    load_landmark_set,
    load_landmarks,
    parse_landmarks,
    save_landmarks,
)

W, H = 768, 1024


@pytest.fixture(scope="module")
def lms():
    return load_landmark_set()


@pytest.fixture(scope="module")
def names(lms):
    """Canonical names to place: landmarks with an ibug number first (for alias tests)."""
    with_ibug = [lms.ibug[k] for k in sorted(lms.ibug)]
    rest = [n for n in lms.names if n not in with_ibug]
    return with_ibug + rest


@pytest.fixture(scope="module")
def schema():
    with open(SCHEMA_PATH, encoding="utf-8") as f:
        return json.load(f)


def make_doc(names, n_front=8, n_side=6):
    """A valid document with landmarks spread inside the image."""
    rng = np.random.default_rng(0)
    pts = rng.uniform([10, 10], [W - 10, H - 10], size=(len(names), 2)).round(2)
    side = rng.uniform([10, 10], [W - 10, H - 10], size=(len(names), 2)).round(2)
    return {
        "format": "headrecon-landmarks",
        "version": 1,
        "views": {
            "front": {"image": "front.jpg", "size": [W, H], "camera": "orthographic-front",
                      "points": {n: pts[i].tolist() for i, n in enumerate(names[:n_front])}},
            "side": {"image": "side.jpg", "size": [W, H], "camera": "orthographic-right",
                     "points": {n: side[i].tolist() for i, n in enumerate(names[:n_side])},
                     "contour": [[140.0, 120.0], [138.5, 131.0], [150.25, 160.0]]},
        },
    }


@pytest.fixture
def doc(names):
    return make_doc(names)


def assert_rejected(doc, pattern):
    """Parsing ``doc`` as case.json fails with a message matching ``pattern`` (re.search)."""
    with pytest.raises(ValueError, match=pattern):
        parse_landmarks(doc, "case.json")


def load_written(path, doc):
    """Write ``doc`` as JSON to ``path`` and load it as a case."""
    path.write_text(json.dumps(doc), encoding="utf-8")
    return load_landmarks(path)


def save_and_load(case, path):
    """Save ``case`` to ``path`` and load it back."""
    save_landmarks(case, path)
    return load_landmarks(path)


def parse_error(doc, source="case.json", **kw):
    with pytest.raises(ValueError) as info:
        parse_landmarks(doc, source, **kw)
    return str(info.value)


# --------------------------------------------------------------------------------------
# The landmark set


def test_landmark_set_has_names_and_ibug_aliases(lms):
    assert len(lms.names) >= MIN_LANDMARKS_TOTAL
    assert lms.ibug, "assets/landmarks.json gives no iBUG numbers"
    for number, name in lms.ibug.items():
        assert 1 <= number <= 68
        assert lms.canonical(f"ibug{number:02d}") == name
        assert lms.vertex(f"ibug{number:02d}") == lms.vertex(name) >= 0
    assert lms.canonical("no_such_landmark") is None
    with pytest.raises(ValueError, match="landmark 'no_such_landmark': unknown"):
        lms.vertex("no_such_landmark")


def test_landmark_set_rejects_bad_entries():
    base = {"format": "headrecon-landmark-set", "version": 1,
            "landmarks": [{"name": "a", "vertex": 1, "ibug": 3}]}
    assert LandmarkSet.from_dict(base).vertex("ibug03") == 1
    bad = copy.deepcopy(base)
    bad["landmarks"].append({"name": "a", "vertex": 2, "ibug": None})
    with pytest.raises(ValueError, match=r"set.json: landmarks\[1\].name: 'a' listed twice"):
        LandmarkSet.from_dict(bad, "set.json")
    bad = copy.deepcopy(base)
    bad["landmarks"].append({"name": "b", "vertex": 2, "ibug": 3})
    with pytest.raises(ValueError, match=r"landmarks\[1\].ibug"):
        LandmarkSet.from_dict(bad, "set.json")
    with pytest.raises(ValueError, match="not a landmark set"):
        LandmarkSet.from_dict({"format": "headrecon-landmarks"}, "set.json")


# --------------------------------------------------------------------------------------
# Valid files


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


def test_known_names_from_a_list_or_model_like_object(doc, names):
    case = parse_landmarks(doc, "case.json", known_names=list(names))
    assert case.views["side"].points
    msg = parse_error(doc, known_names=names[1:])
    assert re.search(rf"case.json: views.front.points.{names[0]}: unknown landmark", msg)

    class ModelLike:
        landmark_info = [{"name": n, "vertex": i} for i, n in enumerate(names)]

    case = parse_landmarks(doc, "case.json", known_names=ModelLike())
    assert case.views["front"].arrays(ModelLike())[1].tolist() == list(range(8))


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


# --------------------------------------------------------------------------------------
# Invalid files: one test per kind, each message naming the file, the view and the key


@pytest.mark.parametrize("typo,name", [("nose_tpi", "nose_tip"), ("ibug1", "ibug01"),
                                       ("Nose_Tip", "nose_tip")])
def test_unknown_landmark_suggests_the_closest_name(doc, typo, name):
    doc["views"]["side"]["points"][typo] = [100.0, 100.0]
    msg = parse_error(doc)
    assert re.match(rf"case\.json: views\.side\.points\.{typo}: unknown landmark; "
                    rf"did you mean '{name}'\?", msg), msg


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
    assert_rejected(doc, rf"case\.json: views\.side\.points: {len(keep)} "
                         rf"landmarks; the fit needs at least "
                         rf"{MIN_LANDMARKS_PER_VIEW} per view")
    # work in progress is fine when not fitting
    assert parse_landmarks(doc, "case.json", for_fit=False).views["side"].points


def test_too_few_landmarks_in_all(doc):
    del doc["views"]["side"]
    pts = doc["views"]["front"]["points"]
    doc["views"]["front"]["points"] = dict(list(pts.items())[:MIN_LANDMARKS_TOTAL - 1])
    assert_rejected(doc, rf"case\.json: views: {MIN_LANDMARKS_TOTAL - 1} "
                         "landmarks in all; the fit needs at least")


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


def test_bad_version_and_format(doc):
    for version in (3, 0, "1", True, None):
        d = dict(doc, version=version)
        assert_rejected(d, r"case\.json: version: unsupported version .*reads "
                           "versions 1 and 2")
    d = dict(doc, format="headrecon-landmark-set")
    assert_rejected(d, r"case\.json: format: expected 'headrecon-landmarks'")
    with pytest.raises(ValueError, match=r"case\.json: expected a JSON object"):
        parse_landmarks([doc], "case.json")


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


# --------------------------------------------------------------------------------------
# Reading files


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
    with pytest.raises(ValueError, match=r"views\.front\.points: 1 landmark;"):
        load_landmarks(path)


def test_check_case_on_a_built_case(names):
    cam = OrthographicCamera.nominal("orthographic-left", (100, 100))
    pts = {names[0]: (10.0, 10.0), names[1]: (float("nan"), 1.0), names[2]: (200.0, 1.0)}
    case = LandmarkCase({"s": View("s", None, (100, 100), cam, pts)})
    problems = dict(check_case(case, for_fit=False))
    assert set(problems) == {f"views.s.points.{names[1]}", f"views.s.points.{names[2]}"}
    assert "outside the 100x100 image" in problems[f"views.s.points.{names[2]}"]


# --------------------------------------------------------------------------------------
# The schema validator, cross-checked against jsonschema


def test_schema_is_a_valid_2020_12_schema_using_supported_keywords(schema):
    jsonschema.Draft202012Validator.check_schema(schema)
    Validator(schema)  # raises SchemaKeywordError on a keyword we do not implement


def _agree(schema, instance):
    ref = jsonschema.Draft202012Validator(schema).is_valid(instance)
    ours = Validator(schema).is_valid(instance)
    assert ref == ours, f"jsonschema says {ref}, ours {ours} for {instance!r}"
    return ours


def test_schema_agrees_with_jsonschema_on_valid_documents(schema, doc):
    assert _agree(schema, doc)
    d = copy.deepcopy(doc)
    d["version"] = 1.0
    d["x-extra"] = None
    d["views"]["side"]["camera"] = {"kind": "orthographic", "anything": [1]}
    d["views"]["side"]["contour"] = []
    d["views"]["front"]["points"] = {}
    assert _agree(schema, d)


INVALID_MUTATIONS = [
    lambda d: d.pop("format"),
    lambda d: d.update(format="headrecon-landmark"),
    lambda d: d.update(version=3),
    lambda d: d.update(version=True),
    lambda d: d.update(views={}),
    lambda d: d.update(views=[]),
    lambda d: d.update(extra=1),
    lambda d: d["views"].update(third=None),
    lambda d: d["views"]["front"].pop("size"),
    lambda d: d["views"]["front"].pop("points"),
    lambda d: d["views"]["front"].pop("camera"),
    lambda d: d["views"]["front"].update(size=[768]),
    lambda d: d["views"]["front"].update(size=[768, 1024, 3]),
    lambda d: d["views"]["front"].update(size=[0, 1024]),
    lambda d: d["views"]["front"].update(size=[768, 200000]),
    lambda d: d["views"]["front"].update(size=[768.5, 1024]),
    lambda d: d["views"]["front"].update(size="768x1024"),
    lambda d: d["views"]["front"].update(image=""),
    lambda d: d["views"]["front"].update(image=5),
    lambda d: d["views"]["front"].update(camera="perspective"),
    lambda d: d["views"]["front"].update(camera={"view": "orthographic-front"}),
    lambda d: d["views"]["front"].update(camera={"kind": ""}),
    lambda d: d["views"]["front"].update(camera=None),
    lambda d: d["views"]["front"].update(camrea="orthographic-front"),
    lambda d: d["views"]["front"].update(points={"a": [1]}),
    lambda d: d["views"]["front"].update(points={"a": [1, None]}),
    lambda d: d["views"]["front"].update(points={"a": {"u": 1, "v": 2}}),
    lambda d: d["views"]["front"].update(points={"a": [True, 2]}),
    lambda d: d["views"]["side"].update(contour=[[1, 2], [3]]),
    lambda d: d["views"]["side"].update(contour={"0": [1, 2]}),
]


@pytest.mark.parametrize("i", range(len(INVALID_MUTATIONS)))
def test_schema_agrees_with_jsonschema_on_invalid_documents(schema, doc, i):
    d = copy.deepcopy(doc)
    INVALID_MUTATIONS[i](d)
    assert not _agree(schema, d)
    # our error sits at (or below) the place jsonschema's best match points to
    best = jsonschema.exceptions.best_match(
        jsonschema.Draft202012Validator(schema).iter_errors(d))
    ours = [e.path for e in validate(d, schema)]
    ref = tuple(best.absolute_path)
    assert any(p[:len(ref)] == ref or ref[:len(p)] == p for p in ours), (ref, ours)


def _random_value(rng, depth=0):
    pool = [None, True, False, 0, 1, -1, 1.0, 1.5, 768, 100001, "", "x", "orthographic-left",
            "headrecon-landmarks", float("nan")]
    r = rng.random()
    if depth < 2 and r < 0.2:
        return [_random_value(rng, depth + 1) for _ in range(rng.randrange(4))]
    if depth < 2 and r < 0.35:
        keys = ["kind", "a", "x-a", "size", "points", "camera", "image", "contour"]
        return {rng.choice(keys): _random_value(rng, depth + 1) for _ in range(rng.randrange(3))}
    return rng.choice(pool)


def _random_mutation(doc, rng):
    d = copy.deepcopy(doc)
    node, parent, key = d, None, None
    for _ in range(rng.randrange(1, 6)):  # walk down a random path
        if isinstance(node, dict) and node:
            parent, key = node, rng.choice(list(node))
        elif isinstance(node, list) and node:
            parent, key = node, rng.randrange(len(node))
        else:
            break
        node = parent[key]
    if parent is None:
        return d
    op = rng.random()
    if op < 0.6:
        parent[key] = _random_value(rng)
    elif op < 0.8 and isinstance(parent, dict):
        del parent[key]
    elif isinstance(parent, dict):
        parent[rng.choice(["x-new", "new", "kind", "image"])] = _random_value(rng)
    else:
        parent.append(_random_value(rng))
    return d


def test_schema_agrees_with_jsonschema_on_random_mutations(schema, doc):
    rng = random.Random(1234)
    n_valid = 0
    for _ in range(400):
        n_valid += _agree(schema, _random_mutation(doc, rng))
    assert 10 < n_valid < 390  # the fuzzing exercised both outcomes


GENERIC_SCHEMA = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "type": "object",
    "required": ["n"],
    "minProperties": 2,
    "properties": {
        "n": {"type": "number", "exclusiveMinimum": 0, "exclusiveMaximum": 10},
        "i": {"type": ["integer", "null"], "minimum": -2, "maximum": 2},
        "e": {"enum": [1, "one", None, [1, 2], {"a": 1}]},
        "c": {"const": False},
        "s": {"type": "string", "minLength": 2, "pattern": "^[a-z]+$"},
        "t": {"type": "array", "prefixItems": [{"type": "string"}, {"type": "boolean"}],
              "items": False},
        "r": {"$ref": "#/$defs/pair"},
        "a": {"anyOf": [{"type": "string"}, {"$ref": "#/$defs/pair"}]},
        "k": {"type": "object", "allOf": [{"required": ["kind"]}, {"minProperties": 1}],
              "if": {"required": ["kind"], "properties": {"kind": {"const": "a"}}},
              "then": {"required": ["x"]},
              "else": {"properties": {"x": {"type": "string"}}}},
    },
    "patternProperties": {"^p_": {"type": "integer"}},
    "additionalProperties": {"type": "boolean"},
    "$defs": {"pair": {"type": "array", "items": {"type": "number"}, "minItems": 2,
                       "maxItems": 2}},
}

GENERIC_CASES = [
    ({"n": 1, "i": 2}, True), ({"n": 1}, False), ({"n": 0, "i": 1}, False),
    ({"n": 10, "i": 1}, False), ({"n": 9.9, "i": None}, True), ({"n": 1, "i": 3}, False),
    ({"n": 1, "i": 1.0}, True), ({"n": 1, "i": 1.5}, False), ({"n": 1, "i": True}, False),
    ({"n": 1, "e": 1.0}, True), ({"n": 1, "e": True}, False), ({"n": 1, "e": [1, 2]}, True),
    ({"n": 1, "e": [2, 1]}, False), ({"n": 1, "e": {"a": 1.0}}, True),
    ({"n": 1, "e": {"a": True}}, False), ({"n": 1, "c": False}, True), ({"n": 1, "c": 0}, False),
    ({"n": 1, "s": "ab"}, True), ({"n": 1, "s": "a"}, False), ({"n": 1, "s": "aB"}, False),
    ({"n": 1, "t": ["a", True]}, True), ({"n": 1, "t": ["a"]}, True),
    ({"n": 1, "t": ["a", 1]}, False), ({"n": 1, "t": ["a", True, 3]}, False),
    ({"n": 1, "r": [1, 2]}, True), ({"n": 1, "r": [1]}, False), ({"n": 1, "r": [1, "2"]}, False),
    ({"n": 1, "a": "x"}, True), ({"n": 1, "a": [1, 2.5]}, True), ({"n": 1, "a": [1]}, False),
    ({"n": 1, "a": 3}, False), ({"n": 1, "p_x": 3}, True), ({"n": 1, "p_x": "3"}, False),
    ({"n": 1, "other": True}, True), ({"n": 1, "other": 1}, False), ({"n": "1", "i": 1}, False),
    ({"n": float("nan"), "i": 1}, True), ([1], False), ("n", False),
    ({"n": 1, "k": {"kind": "a", "x": 1}}, True), ({"n": 1, "k": {"kind": "a"}}, False),
    ({"n": 1, "k": {"kind": "b", "x": "s"}}, True), ({"n": 1, "k": {"kind": "b", "x": 1}}, False),
    ({"n": 1, "k": {"kind": "b"}}, True), ({"n": 1, "k": {"x": "s"}}, False),
    ({"n": 1, "k": {}}, False),
]


@pytest.mark.parametrize("instance,valid", GENERIC_CASES)
def test_every_keyword_agrees_with_jsonschema(instance, valid):
    assert _agree(GENERIC_SCHEMA, instance) is valid


def test_generic_schema_uses_every_implemented_keyword():
    used = set()

    def walk(s):
        if isinstance(s, dict):
            used.update(k for k in s if k in KEYWORDS)
            for v in s.values():
                walk(v)
        elif isinstance(s, list):
            for v in s:
                walk(v)

    walk(GENERIC_SCHEMA)
    assert used == set(KEYWORDS)


def test_unsupported_keywords_and_refs_are_refused():
    with pytest.raises(SchemaKeywordError, match="oneOf"):
        Validator({"properties": {"a": {"oneOf": [{"type": "string"}]}}})
    with pytest.raises(SchemaKeywordError, match="does not resolve"):
        Validator({"$ref": "#/$defs/missing"})
    with pytest.raises(SchemaKeywordError, match="only local"):
        Validator({"$ref": "https://example.com/s.json"})


def test_error_paths_and_messages():
    errs = validate({"views": {"front": {"points": {"nose_tip": [1, "x"]}}}},
                    {"properties": {"views": {"additionalProperties": {"properties": {
                        "points": {"additionalProperties": {"items": {"type": "number"}}}}}}}})
    assert [str(e) for e in errs] == [
        'views.front.points.nose_tip[1]: expected a number, got string "x"']
    assert format_path(()) == ""
    assert format_path(("a", 0, "b c", 'q"')) == 'a[0]["b c"]["q\\""]'


# --------------------------------------------------------------------------------------
# Version 2: cameras of any kind at any angle, mirror views, passpoints

# A calibration object (seed 004 style): corners of a box around the head and two more, not
# in one plane. Names are free; they are never mapped in a mirror view.
CUBE = np.array([[x, y, z] for x in (-0.2, 0.2) for y in (-0.25, 0.15) for z in (-0.25, 0.15)]
                + [[0.0, -0.25, 0.2], [0.2, 0.0, -0.3]])
CUBE_NAMES = [f"cube_{i}" for i in range(len(CUBE))]
SRC2 = "case2.json"


def v2_cameras():
    """The cameras of the version-2 case: an orthographic front photo, a three-quarter view
    through a DLT-16 camera (50 mm lens with distortion), a pinhole at the subject's left
    and that photo's mirror image (one camera and a flat mirror behind the subject)."""
    pin = PinholeCamera.look_at([1.1, -1.1, 0.05], [0, 0, 0], (W, H), lens_mm=50)
    three_quarter = DLTCamera.from_krc(pin.intrinsics, pin.rotation, pin.centre, (W, H),
                                       distortion=[2e-8, 0, 0, 1e-6, -1e-6])
    left = PinholeCamera.look_at([1.6, 0, 0], [0, 0, 0], (W, H), lens_mm=35,
                                 focal_prior=(35.0, 0.05))
    plane = MirrorPlane.from_point_normal([-0.5, 0, 0], [1.0, 0.5, 0])
    return {"front": OrthographicCamera.nominal("orthographic-front", (W, H)),
            "three_quarter": three_quarter, "left": left,
            "left_mirror": reflected_camera(left.to_dlt(), plane)}


HEAD = np.random.default_rng(3).uniform([-0.07, -0.1, -0.1], [0.07, 0.0, 0.1], size=(8, 3))


def make_doc2(names):
    """A valid version-2 document: landmarks of a head-sized point set projected through
    ``v2_cameras``; the mirror view's camera is to be computed from its passpoints."""
    cams = v2_cameras()

    def px(cam, x):
        return np.round(cam.project(x), 3).tolist()

    def pts(view, k=None):
        k = len(HEAD) if k is None else k
        return dict(zip(names[:k], px(cams[view], HEAD[:k]), strict=True))

    def seen(view):
        return dict(zip(CUBE_NAMES, px(cams[view], CUBE), strict=True))

    doc = {
        "format": "headrecon-landmarks",
        "version": 2,
        "views": {
            "front": {"image": "front.jpg", "size": [W, H], "camera": "orthographic-front",
                      "points": pts("front")},
            "three_quarter": {"image": "three_quarter.jpg", "size": [W, H],
                              "camera": cams["three_quarter"].to_dict(), "calibrated": True,
                              "points": pts("three_quarter", 2),
                              "passpoints": seen("three_quarter")},
            "left": {"image": "left.jpg", "size": [W, H], "camera": cams["left"].to_dict(),
                     "calibrated": False, "points": pts("left")},
            "left_mirror": {"image": "left.jpg", "size": [W, H], "camera": {"kind": "dlt"},
                            "mirror_of": "left", "points": pts("left_mirror"),
                            "passpoints": seen("left_mirror")},
        },
        "passpoints": dict(zip(CUBE_NAMES, CUBE.tolist(), strict=True)),
    }
    return json.loads(json.dumps(doc))  # plain JSON types, as a file gives them


@pytest.fixture
def doc2(names):
    return make_doc2(names)


def problems_of(doc, source=SRC2, **kw):
    """Every problem line of an invalid document (each must name the file)."""
    with pytest.raises(LandmarksError) as info:
        parse_landmarks(doc, source, **kw)
    lines = info.value.messages()
    assert all(line.startswith(f"{source}: ") for line in lines), lines
    return lines


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


def _drop_passpoints(d, view, keep):
    pp = d["views"][view]["passpoints"]
    d["views"][view]["passpoints"] = dict(list(pp.items())[:keep])


def _set(view, key, value):
    return lambda d: d["views"][view].__setitem__(key, value)


def _camera_field(view, key, value):
    return lambda d: d["views"][view]["camera"].__setitem__(key, value)


def _extra_mirror_view(d):
    d["views"]["mirror2"] = copy.deepcopy(d["views"]["left_mirror"])
    d["views"]["mirror2"]["mirror_of"] = "left_mirror"


def _flat_passpoints(d):
    for xyz in d["passpoints"].values():
        xyz[2] = 0.0


def _scaled_rotation(view):
    def mutate(d):
        d["views"][view]["camera"]["rotation"][0] = [2.0 * c for c in
                                                     d["views"][view]["camera"]["rotation"][0]]
    return mutate


V2_INVALID = {
    # mirror views
    "mirror_of a missing view": (
        _set("left_mirror", "mirror_of", "lfet"),
        r"views\.left_mirror\.mirror_of: no view named 'lfet' \(views: front, three_quarter, "
        r"left, left_mirror\); did you mean 'left'\?"),
    "mirror_of itself": (_set("left_mirror", "mirror_of", "left_mirror"),
                         r"views\.left_mirror\.mirror_of: names this view itself"),
    "mirror_of a mirror view": (_extra_mirror_view,
                                r"views\.mirror2\.mirror_of: 'left_mirror' is itself a mirror "
                                "view; name the view seen directly"),
    "mirror view of another size": (
        _set("left_mirror", "size", [W, H + 1]),
        r"views\.left_mirror\.size: \[768, 1025\] differs from the size \[768, 1024\] of "
        "'left'"),
    "mirror view in another photo": (
        _set("left_mirror", "image", "other.jpg"),
        r"views\.left_mirror\.image: 'other\.jpg' is not the photo of 'left'"),
    "mirror view with a nominal camera": (
        _set("left_mirror", "camera", "orthographic-left"),
        r"views\.left_mirror\.camera: 'orthographic-left' cannot see a mirror image"),
    "mirror view with a camera that is not mirrored": (
        lambda d: d["views"]["left_mirror"].update(camera=v2_cameras()["left"].to_dict()),
        r"views\.left_mirror\.camera: not mirrored \(rotation determinant \+1\)"),
    # passpoints
    "view passpoint not defined": (
        lambda d: d["views"]["three_quarter"]["passpoints"].update(cube_99=[10.0, 10.0]),
        r"views\.three_quarter\.passpoints\.cube_99: not defined in the top-level "
        r"'passpoints' \(\[x, y, z\] metres\); did you mean 'cube_9'\?"),
    "no top-level passpoints": (
        lambda d: d.pop("passpoints"),
        r"views\.three_quarter\.passpoints: 10 passpoints, but the file defines none: the "
        r"top-level 'passpoints' gives each one's \[x, y, z\] metres"),
    "passpoint outside the image": (
        lambda d: d["views"]["left_mirror"]["passpoints"].update(cube_3=[W + 1.0, 10.0]),
        r"views\.left_mirror\.passpoints\.cube_3: \(769, 10\) lies outside the 768x1024 "
        "image"),
    "passpoint pixel NaN": (
        lambda d: d["views"]["left_mirror"]["passpoints"].update(cube_3=[float("nan"), 1.0]),
        r"views\.left_mirror\.passpoints\.cube_3: not a finite number"),
    "passpoint position NaN": (
        lambda d: d["passpoints"].update(cube_2=[0.0, float("nan"), 0.0]),
        r": passpoints\.cube_2: not a finite number"),
    "passpoint position of 2 numbers": (
        lambda d: d["passpoints"].update(cube_2=[0.0, 0.1]),
        r": passpoints\.cube_2: expected at least 3 items, got 2"),
    "passpoints on an orthographic view": (
        _set("front", "passpoints", {"cube_0": [1.0, 1.0]}),
        r"views\.front\.passpoints: passpoints compute a perspective \(DLT\) camera, and this "
        "view's camera is orthographic"),
    "too few passpoints to compute the camera": (
        lambda d: _drop_passpoints(d, "left_mirror", 5),
        r"views\.left_mirror\.passpoints: 5 passpoints; computing the camera needs at least "
        "6, not all in one plane"),
    "passpoints in one plane": (
        _flat_passpoints,
        r"views\.left_mirror\.passpoints: cannot compute the camera: the 10 passpoints lie in "
        "one plane"),
    # cameras
    "DLT with 12 parameters": (
        lambda d: d["views"]["three_quarter"]["camera"].update(
            parameters=d["views"]["three_quarter"]["camera"]["parameters"][:12]),
        r"views\.three_quarter\.camera\.parameters: an array of 12 items matches none of the "
        r"allowed forms: 11 numbers b1\.\.b11 \(DLT\); 16 numbers b1\.\.b16"),
    "DLT with 10 parameters": (
        lambda d: d["views"]["three_quarter"]["camera"].update(parameters=[1.0] * 10),
        r"views\.three_quarter\.camera\.parameters: an array of 10 items matches none"),
    "DLT parameter NaN": (
        lambda d: d["views"]["three_quarter"]["camera"]["parameters"].__setitem__(
            3, float("nan")),
        r"views\.three_quarter\.camera\.parameters\[3\]: not a finite number"),
    "DLT parameters and matrix": (
        _camera_field("three_quarter", "matrix", np.eye(3, 4).tolist()),
        r"views\.three_quarter\.camera: give 'parameters' \(b1\.\.b11 or b1\.\.b16\) or "
        "'matrix', not both"),
    "DLT depth_sign 2": (_camera_field("three_quarter", "depth_sign", 2),
                         r"views\.three_quarter\.camera\.depth_sign: 2 is not one of 1, -1"),
    "DLT distortion_centre without lens terms": (
        lambda d: d["views"]["three_quarter"]["camera"].update(
            parameters=d["views"]["three_quarter"]["camera"]["parameters"][:11]),
        r"views\.three_quarter\.camera\.distortion_centre: given without lens distortion"),
    "DLT singular": (
        _set("three_quarter", "camera", {"kind": "dlt", "parameters": [0.0] * 11}),
        r"views\.three_quarter\.camera: camera \(dlt\): the matrix's left 3x3 block is "
        "singular"),
    "unknown DLT with depth_sign": (
        _camera_field("left_mirror", "depth_sign", 1),
        r"views\.left_mirror\.camera\.depth_sign: given without the camera's 'parameters'"),
    "unknown kind": (
        _set("left_mirror", "camera", {"kind": "dlp"}),
        r'views\.left_mirror\.camera\.kind: "dlp" is not one of "orthographic", "dlt", '
        r"\"pinhole\"; did you mean 'dlt'\?"),
    "misspelt camera field": (
        lambda d: d["views"]["three_quarter"]["camera"].update(
            paramters=d["views"]["three_quarter"]["camera"].pop("parameters")),
        r"views\.three_quarter\.camera\.paramters: unexpected key; did you mean "
        r"'parameters'\?"),
    "pinhole rotation without centre": (
        lambda d: d["views"]["left"]["camera"].pop("centre"),
        r"views\.left\.camera: camera \(pinhole\): missing field 'centre'"),
    "pinhole rotation not a rotation": (
        _scaled_rotation("left"),
        r"views\.left\.camera: camera \(pinhole\): rotation: not orthonormal"),
    "pinhole focal_px negative": (
        _camera_field("left", "focal_px", -5),
        r"views\.left\.camera\.focal_px: -5 must be greater than 0"),
    "unknown pinhole with a bad focal range": (
        _set("left", "camera", {"kind": "pinhole", "lens_mm": 35, "focal_range_mm": [50, 20]}),
        r"views\.left\.camera: camera \(pinhole\): focal_range_mm must be \(min, max\)"),
    "unknown pinhole of another size": (
        _set("left", "camera", {"kind": "pinhole", "size": [W, H + 2]}),
        r"views\.left\.camera\.size: camera size \[768, 1026\] differs from the view size"),
    "orthographic object without parameters": (
        _set("front", "camera", {"kind": "orthographic"}),
        r"views\.front\.camera: missing required key 'rotation'"),
    "orthographic rotation not a rotation": (
        lambda d: (d["views"]["front"].update(camera=OrthographicCamera.nominal(
            "orthographic-front", (W, H), scale=2000.0).to_dict()), _scaled_rotation("front")(d)),
        r"views\.front\.camera\.rotation: not a rotation \(its rows must be orthonormal\)"),
    "camera size differs": (
        _camera_field("three_quarter", "size", [W + 2, H]),
        r"views\.three_quarter\.camera: camera size \[770, 1024\] differs from the view size"),
    # calibrated
    "calibrated nominal camera": (
        _set("front", "calibrated", True),
        r"views\.front\.calibrated: true, but 'orthographic-front' is a nominal camera"),
    "calibrated without parameters": (
        lambda d: d["views"]["left"].update(camera={"kind": "pinhole"}, calibrated=True),
        r"views\.left\.calibrated: true, but the camera's parameters are not given"),
    "calibrated not a boolean": (
        _set("front", "calibrated", "yes"),
        r'views\.front\.calibrated: expected a boolean, got string "yes"'),
    # landmark counts
    "too few landmarks in a view without passpoints": (
        lambda d: d["views"]["left"].update(points=dict(list(
            d["views"]["left"]["points"].items())[:2])),
        r"views\.left\.points: 2 landmarks; the fit needs at least 3 per view"),
    "too few landmarks in a mirror view, even with passpoints": (
        lambda d: d["views"]["left_mirror"].update(points=dict(list(
            d["views"]["left_mirror"]["points"].items())[:2])),
        r"views\.left_mirror\.points: 2 landmarks; the fit needs at least 3 per view"),
    "too few landmarks to self-calibrate a DLT": (
        lambda d: d["views"]["left"].update(camera={"kind": "dlt"}, points=dict(list(
            d["views"]["left"]["points"].items())[:5])),
        r"views\.left\.points: 5 landmarks; self-calibrating a dlt camera needs at least 6 "
        "per view"),
    # version-2 keys in a version-1 file
    "mirror_of in version 1": (
        lambda d: d.update(version=1),
        r"views\.left_mirror\.mirror_of: a version-2 key in a version-1 file; set "
        r"\"version\": 2"),
    "camera without parameters in version 1": (
        lambda d: (d.update(version=1), [d["views"][v].pop(k, None) for v in d["views"]
                                         for k in ("calibrated", "mirror_of", "passpoints")],
                   d.pop("passpoints")),
        r"views\.left_mirror\.camera: a dlt camera without its parameters needs version 2 "
        r"of the file \(set \"version\": 2\)"),
    "passpoints in version 1": (
        lambda d: d.update(version=1),
        r"case2\.json: passpoints: a version-2 key in a version-1 file"),
}


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
    _drop_passpoints(doc2, "left_mirror", 2)
    doc2["views"]["left"]["points"] = {}
    parse_landmarks(doc2, SRC2, for_fit=False)
    assert problems_of(doc2) == [
        f"{SRC2}: views.left.points: 0 landmarks; the fit needs at least 3 per view",
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


def test_every_camera_kind_round_trips_through_the_schema(schema, doc2):
    """The schema describes exactly what each camera class's to_dict writes."""
    kinds = schema["$defs"]["camera_object"]["properties"]["kind"]["enum"]
    assert sorted(kinds) == camera_kinds()
    look = PinholeCamera.look_at([0.0, -1.5, 0.0], [1.0, -1.5, 0.0], (W, H), lens_mm=50)
    on_plane = DLTCamera.from_krc(look.intrinsics, look.rotation, look.centre, (W, H),
                                  distortion=[1e-8, 0, 0, 0, 0])
    cams = [OrthographicCamera.nominal("orthographic-left", (W, H), scale=2500.0),
            v2_cameras()["left_mirror"],  # DLT-11, mirrored
            v2_cameras()["three_quarter"],  # DLT-16
            on_plane,  # world origin on its principal plane: stored as a matrix
            PinholeCamera.look_at([0.3, -2.0, 0.1], [0, 0, 0], (W, H), lens_mm=85, k1=-0.05,
                                  free_k1=True, free_principal_point=True,
                                  focal_range_mm=None, free_focal=False)]
    assert "matrix" in on_plane.to_dict() and "distortion" in on_plane.to_dict()
    for cam in cams:
        d = copy.deepcopy(doc2)
        d["views"]["left"]["camera"] = cam.to_dict()
        assert _agree(schema, d), cam
        case = parse_landmarks(d, SRC2)
        got = case.views["left"].camera
        assert type(got) is type(cam)
        np.testing.assert_allclose(got.project(HEAD), cam.project(HEAD), atol=1e-6)
        assert landmarks_to_dict(case)["views"]["left"]["camera"] == cam.to_dict()


def test_schema_agrees_with_jsonschema_on_version2_documents(schema, doc2):
    assert _agree(schema, doc2)
    d = copy.deepcopy(doc2)
    d["views"]["left"]["camera"] = {"kind": "pinhole", "lens_mm": 28, "focal_prior": None}
    d["views"]["left_mirror"]["camera"]["x-note"] = 1  # x- keys: only at view and top level
    assert not _agree(schema, d)
    del d["views"]["left_mirror"]["camera"]["x-note"]
    d["views"]["front"]["x-note"] = {"checked": True}
    d["views"]["front"]["passpoints"] = {}
    assert _agree(schema, d)


V2_INVALID_MUTATIONS = [mutate for mutate, _ in V2_INVALID.values()] + [
    lambda d: d["views"]["left"].update(mirror_of=""),
    lambda d: d["views"]["left"].update(mirror_of=5),
    lambda d: d["views"]["front"].update(passpoints={"a": [1]}),
    lambda d: d["views"]["front"].update(passpoints=[[1, 2]]),
    lambda d: d.update(passpoints=[[0, 0, 0]]),
    lambda d: d["views"]["left"]["camera"].update(focal_range_mm=[0, 5]),
    lambda d: d["views"]["left"]["camera"].update(focal_prior="50mm"),
    lambda d: d["views"]["left"]["camera"].update(free_k1=1),
    lambda d: d["views"]["three_quarter"].update(camera={
        "kind": "dlt", "matrix": np.eye(3).tolist()}),
    lambda d: d["views"]["three_quarter"].update(camera={
        "kind": "dlt", "matrix": np.eye(3, 4).tolist(), "distortion": [0, 0, 0, 0]}),
    lambda d: d["views"]["left_mirror"].update(camera={"kind": "dlt", "size": [0, 1]}),
    lambda d: d["views"]["left_mirror"].update(camera={}),
    lambda d: d["views"]["left_mirror"].update(camera={"kind": 5}),
]
# the ones only the semantic checks find (the schema passes them)
_SEMANTIC = {"mirror_of a missing view", "mirror_of itself", "mirror_of a mirror view",
             "mirror view of another size", "mirror view in another photo",
             "mirror view with a nominal camera",
             "mirror view with a camera that is not mirrored", "view passpoint not defined",
             "no top-level passpoints", "passpoint outside the image", "passpoint pixel NaN",
             "passpoint position NaN", "passpoints on an orthographic view",
             "too few passpoints to compute the camera", "passpoints in one plane",
             "DLT parameter NaN", "DLT parameters and matrix",
             "DLT distortion_centre without lens terms", "DLT singular",
             "unknown DLT with depth_sign", "pinhole rotation without centre",
             "pinhole rotation not a rotation", "unknown pinhole with a bad focal range",
             "unknown pinhole of another size", "orthographic rotation not a rotation",
             "camera size differs", "calibrated nominal camera",
             "calibrated without parameters", "too few landmarks in a view without passpoints",
             "too few landmarks in a mirror view, even with passpoints",
             "too few landmarks to self-calibrate a DLT",
             "camera without parameters in version 1"}


@pytest.mark.parametrize("i", range(len(V2_INVALID_MUTATIONS)))
def test_schema_agrees_with_jsonschema_on_invalid_version2_documents(schema, doc2, i):
    d = copy.deepcopy(doc2)
    V2_INVALID_MUTATIONS[i](d)
    semantic = i < len(V2_INVALID) and list(V2_INVALID)[i] in _SEMANTIC
    assert _agree(schema, d) is semantic
    if semantic:
        return
    best = jsonschema.exceptions.best_match(
        jsonschema.Draft202012Validator(schema).iter_errors(d))
    ours = [e.path for e in validate(d, schema)]
    ref = tuple(best.absolute_path)
    assert any(p[:len(ref)] == ref or ref[:len(p)] == p for p in ours), (ref, ours)


def test_schema_agrees_with_jsonschema_on_random_version2_mutations(schema, doc2):
    rng = random.Random(4321)
    n_valid = 0
    for _ in range(400):
        n_valid += _agree(schema, _random_mutation(doc2, rng))
    assert 10 < n_valid < 390


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
