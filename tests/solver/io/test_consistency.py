"""Consistency before the fit (solver/io/consistency.py) and the plausible ranges of camera
fields (camera_json.camera_range_problems): each case here once validated and then fitted a
head tens of millimetres off, or failed in the fit with a message naming no view."""

import copy

import numpy as np

from solver import parse_landmarks
from tests.solver.io.support import H, W, parse_error, problems_of

ORTHO_MIRRORED = {"kind": "orthographic", "view": "orthographic-front",
                  "rotation": [[1, 0, 0], [0, 0, -1], [0, -1, 0]], "scale": 2730.0,
                  "offset": [W / 2, H / 2], "size": [W, H]}


def test_a_mirrored_rotation_outside_a_mirror_view_is_refused(doc):
    doc["views"]["front"]["camera"] = ORTHO_MIRRORED
    assert parse_error(doc).startswith("case.json: views.front.camera.rotation: determinant "
                                       "-1, a mirrored camera: only a mirror view")
    doc["views"]["front"]["camera"]["rotation"] = [[1, 0, 0], [0, 0, -1], [0, 0.9, 0]]
    assert "views.front.camera.rotation: not a rotation" in parse_error(doc)


def test_two_views_from_one_direction_are_refused(doc):
    both = copy.deepcopy(doc)
    both["views"]["side"]["camera"] = "orthographic-front"
    assert parse_error(both).startswith(
        "case.json: views.side.camera: looks the same way as view 'front' (both "
        "orthographic-front): two photos from one direction tell nothing of the head's depth")
    both["views"]["front"]["camera"] = both["views"]["side"]["camera"] = "orthographic-right"
    assert "(both orthographic-right)" in parse_error(both)
    turned = copy.deepcopy(doc)  # a fitted front camera turned by 2 degrees is still front
    a = np.radians(2.0)
    rot = np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0]]) @ np.array(
        [[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    turned["views"]["side"]["camera"] = {**ORTHO_MIRRORED, "rotation": rot.tolist()}
    assert "views.side.camera: looks the same way as view 'front' (2.0 degrees apart)" \
        in parse_error(turned)
    doc["views"]["side"]["camera"] = "orthographic-left"  # left and right profiles: fine
    parse_landmarks(doc, "case.json")


def test_landmarks_in_one_place_or_on_a_line_are_refused(doc):
    names = list(doc["views"]["front"]["points"])
    one = copy.deepcopy(doc)
    one["views"]["front"]["points"] = {n: [100.0, 100.0] for n in names}
    assert parse_error(one).startswith(
        f"case.json: views.front.points: all {len(names)} landmarks lie within 2 px of "
        "(100.0, 100.0)")
    line = copy.deepcopy(doc)
    line["views"]["front"]["points"] = {n: [100.0 + 5 * i, 100.0 + 10 * i]
                                        for i, n in enumerate(names)}
    assert parse_error(line).startswith(f"case.json: views.front.points: all {len(names)} "
                                        "landmarks lie on one line")
    parse_landmarks(line, "case.json", for_fit=False)  # work in progress may


def test_pinhole_fields_outside_their_range_name_it(doc2):
    def problem(field, value, view="left"):
        d = copy.deepcopy(doc2)
        d["views"][view]["camera"][field] = value
        return "\n".join(problems_of(d))

    assert "views.left.camera.focal_px: 1e+300 px is outside 56.89..1.422e+05 px, the " \
           "lenses of 2..5000 mm (36 mm equivalent) on this 768x1024 photo" \
        in problem("focal_px", 1e300)
    assert "views.left.camera.principal_point: (100000, 10) lies outside the 768x1024 photo" \
        in problem("principal_point", [1e5, 10.0])
    assert "views.left.camera.k1: 3 is outside -1..1" in problem("k1", 3.0)
    hints = copy.deepcopy(doc2)
    hints["views"]["left"]["camera"] = {"kind": "pinhole", "lens_mm": 1e-9}
    assert "views.left.camera.lens_mm: 1e-09 mm is outside 2..5000 mm" \
        in "\n".join(problems_of(hints))
    hints["views"]["left"]["camera"] = {"kind": "pinhole", "focal_prior": [1e6, 0.05]}
    assert "views.left.camera.focal_prior: [1000000.0, 0.05]: the lens (mm, 36 mm " \
           "equivalent) must be in 2..5000" in "\n".join(problems_of(hints))
