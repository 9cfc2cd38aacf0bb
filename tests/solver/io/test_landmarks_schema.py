"""The landmarks file's schema (assets/landmarks.schema.json) validated with our validator,
cross-checked against the reference ``jsonschema`` package on valid, invalid and randomly
mutated documents of both versions."""

import copy
import random

import jsonschema
import numpy as np
import pytest

from solver import DLTCamera, PinholeCamera, landmarks_to_dict, parse_landmarks
from solver.cameras import OrthographicCamera, camera_kinds
from solver.io.consistency import is_mirrored
from solver.io.jsonschema_lite import Validator, validate
from tests.solver.io.support import HEAD, SRC2, V2_INVALID, H, W, agree, random_mutation, v2_cameras

# --------------------------------------------------------------------------------------
# Version 1


def test_schema_is_a_valid_2020_12_schema_using_supported_keywords(schema):
    jsonschema.Draft202012Validator.check_schema(schema)
    Validator(schema)  # raises SchemaKeywordError on a keyword we do not implement


def test_schema_agrees_with_jsonschema_on_valid_documents(schema, doc):
    assert agree(schema, doc)
    d = copy.deepcopy(doc)
    d["version"] = 1.0
    d["x-extra"] = None
    d["views"]["side"]["camera"] = {"kind": "orthographic", "anything": [1]}
    d["views"]["side"]["contour"] = []
    d["views"]["front"]["points"] = {}
    assert agree(schema, d)


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
    assert not agree(schema, d)
    # our error sits at (or below) the place jsonschema's best match points to
    best = jsonschema.exceptions.best_match(
        jsonschema.Draft202012Validator(schema).iter_errors(d))
    ours = [e.path for e in validate(d, schema)]
    ref = tuple(best.absolute_path)
    assert any(p[:len(ref)] == ref or ref[:len(p)] == p for p in ours), (ref, ours)


def test_schema_agrees_with_jsonschema_on_random_mutations(schema, doc):
    rng = random.Random(1234)
    n_valid = 0
    for _ in range(400):
        n_valid += agree(schema, random_mutation(doc, rng))
    assert 10 < n_valid < 390  # the fuzzing exercised both outcomes


# --------------------------------------------------------------------------------------
# Version 2


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
        view = "left_mirror" if is_mirrored(cam) else "left"  # only a mirror view has one
        d["views"][view]["camera"] = cam.to_dict()
        assert agree(schema, d), cam
        case = parse_landmarks(d, SRC2)
        got = case.views[view].camera
        assert type(got) is type(cam)
        np.testing.assert_allclose(got.project(HEAD), cam.project(HEAD), atol=1e-6)
        assert landmarks_to_dict(case)["views"][view]["camera"] == cam.to_dict()


def test_schema_agrees_with_jsonschema_on_version2_documents(schema, doc2):
    assert agree(schema, doc2)
    d = copy.deepcopy(doc2)
    d["views"]["left"]["camera"] = {"kind": "pinhole", "lens_mm": 28, "focal_prior": None}
    d["views"]["left_mirror"]["camera"]["x-note"] = 1  # x- keys: only at view and top level
    assert not agree(schema, d)
    del d["views"]["left_mirror"]["camera"]["x-note"]
    d["views"]["front"]["x-note"] = {"checked": True}
    d["views"]["front"]["passpoints"] = {}
    assert agree(schema, d)


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
    assert agree(schema, d) is semantic
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
        n_valid += agree(schema, random_mutation(doc2, rng))
    assert 10 < n_valid < 390
