"""Shared helpers of the file tests: valid landmarks documents of both versions, the
version-2 document's mutations that make it invalid, checks of parse errors, and an OBJ
reader of our own to check what the writer wrote."""

import copy
import json
from pathlib import Path

import jsonschema
import numpy as np
import pytest

from solver import (
    DLTCamera,
    LandmarksError,
    OrthographicCamera,
    PinholeCamera,
    load_landmarks,
    parse_landmarks,
    save_landmarks,
)
from solver.cameras.mirror import MirrorPlane, reflected_camera
from solver.io.jsonschema_lite import Validator

W, H = 768, 1024


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
# Our schema validator against jsonschema


def agree(schema, instance):
    ref = jsonschema.Draft202012Validator(schema).is_valid(instance)
    ours = Validator(schema).is_valid(instance)
    assert ref == ours, f"jsonschema says {ref}, ours {ours} for {instance!r}"
    return ours


def random_value(rng, depth=0):
    pool = [None, True, False, 0, 1, -1, 1.0, 1.5, 768, 100001, "", "x", "orthographic-left",
            "headrecon-landmarks", float("nan")]
    r = rng.random()
    if depth < 2 and r < 0.2:
        return [random_value(rng, depth + 1) for _ in range(rng.randrange(4))]
    if depth < 2 and r < 0.35:
        keys = ["kind", "a", "x-a", "size", "points", "camera", "image", "contour"]
        return {rng.choice(keys): random_value(rng, depth + 1) for _ in range(rng.randrange(3))}
    return rng.choice(pool)


def random_mutation(doc, rng):
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
        parent[key] = random_value(rng)
    elif op < 0.8 and isinstance(parent, dict):
        del parent[key]
    elif isinstance(parent, dict):
        parent[rng.choice(["x-new", "new", "kind", "image"])] = random_value(rng)
    else:
        parent.append(random_value(rng))
    return d


# --------------------------------------------------------------------------------------
# Version 2: cameras of any kind at any angle, mirror views, passpoints


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


def problems_of(doc, source=SRC2, **kw):
    """Every problem line of an invalid document (each must name the file)."""
    with pytest.raises(LandmarksError) as info:
        parse_landmarks(doc, source, **kw)
    lines = info.value.messages()
    assert all(line.startswith(f"{source}: ") for line in lines), lines
    return lines


def drop_passpoints(d, view, keep):
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
        lambda d: drop_passpoints(d, "left_mirror", 5),
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
        r"views\.left\.points: 2 usable landmarks; the fit needs at least 4 in this view"),
    "too few landmarks in a mirror view, even with passpoints": (
        lambda d: d["views"]["left_mirror"].update(points=dict(list(
            d["views"]["left_mirror"]["points"].items())[:2])),
        r"views\.left_mirror\.points: 2 usable landmarks; the fit needs at least 3 in this "
        "view"),
    "too few landmarks to self-calibrate a DLT": (
        lambda d: d["views"]["left"].update(camera={"kind": "dlt"}, points=dict(list(
            d["views"]["left"]["points"].items())[:5])),
        r"views\.left\.points: 5 usable landmarks; the fit needs at least 6 in this view"),
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


# --------------------------------------------------------------------------------------
# OBJ files


def read_obj_records(path):
    """Minimal independent OBJ reader: v, vt, faces as (vertex, vt) index lists (0-based),
    and the material in force for each face."""
    v, vt, faces, mats, mtllib = [], [], [], [], None
    material = None
    for line in Path(path).read_text(encoding="utf-8").splitlines():
        parts = line.split()
        if not parts:
            continue
        if parts[0] == "v":
            v.append([float(x) for x in parts[1:4]])
        elif parts[0] == "vt":
            vt.append([float(x) for x in parts[1:3]])
        elif parts[0] == "f":
            corners = [c.split("/") for c in parts[1:]]
            faces.append([(int(c[0]) - 1, int(c[1]) - 1 if len(c) > 1 else -1)
                          for c in corners])
            mats.append(material)
        elif parts[0] == "usemtl":
            material = parts[1]
        elif parts[0] == "mtllib":
            mtllib = parts[1]
    return np.array(v), np.array(vt).reshape(-1, 2), faces, mats, mtllib
