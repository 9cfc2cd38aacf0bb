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


def _dlt_with(cam, focal_px=None, principal_point=None, aim=None):
    """``cam`` (a DLT) with its focal length or principal point replaced; with ``aim``
    (3,) turned about its centre so that point is seen in the photo's centre."""
    from solver import DLTCamera
    from solver.geometry import rotation_between

    k, r, c = cam.decompose()
    new = k.copy()
    if focal_px is not None:
        new[0, 0] = new[1, 1] = focal_px
    if principal_point is not None:
        new[:2, 2] = principal_point
    if aim is not None:
        seen = r @ (np.asarray(aim, dtype=np.float64) - c)
        wanted = np.linalg.solve(new, [cam.size[0] / 2, cam.size[1] / 2, 1.0])
        r = rotation_between(seen / np.linalg.norm(seen),
                             wanted / np.linalg.norm(wanted)) @ r
    return DLTCamera.from_krc(new, r, c, cam.size)


def test_a_dlt_whose_parameters_give_no_plausible_lens_is_refused(doc2):
    """A kept DLT with a focal length of 1e12 px ended the fit in "singular system" naming
    no view; one with its principal point far outside the photo fitted a head hundreds of
    pixels off without a word. Its parameters now meet the pinhole's ranges."""
    from solver import DLTCamera

    cam = DLTCamera.from_dict(doc2["views"]["three_quarter"]["camera"])

    def with_camera(**kw):
        d = copy.deepcopy(doc2)
        d["views"]["three_quarter"]["camera"] = _dlt_with(cam, **kw).to_dict()
        return d

    def problems(**kw):
        return "\n".join(problems_of(with_camera(**kw)))

    assert "case2.json: views.three_quarter.camera: its parameters give a focal length of " \
           "1e+12 x 1e+12 px, outside 56.89..1.422e+05 px, the lenses of 2..5000 mm (36 mm " \
           "equivalent) on this 768x1024 photo" in problems(focal_px=1e12)
    assert "case2.json: views.three_quarter.camera: its parameters put the principal point " \
           "at (1e+05, -3e+04), outside the 768x1024 photo" \
        in problems(principal_point=(1e5, -3e4))
    parse_landmarks(with_camera(focal_px=3000.0, principal_point=(700.0, 20.0)), "case2.json")


def test_passpoints_that_give_no_plausible_camera_are_refused(doc2):
    """A DLT computed from passpoints meets the same ranges as one given."""
    from solver import DLTCamera, parse_landmarks
    from tests.solver.io.support import CUBE, CUBE_NAMES

    d = copy.deepcopy(doc2)
    view = d["views"]["three_quarter"]
    shifted = _dlt_with(DLTCamera.from_dict(view["camera"]), principal_point=(-300.0, 512.0),
                        aim=CUBE.mean(axis=0))
    view["camera"] = {"kind": "dlt"}
    view["passpoints"] = dict(zip(CUBE_NAMES, shifted.project(CUBE).round(3).tolist(),
                                  strict=True))
    assert "case2.json: views.three_quarter.passpoints: cannot compute the camera: the " \
           "camera they give: its parameters put the principal point at (-300, 512), " \
           "outside the 768x1024 photo" in "\n".join(problems_of(d))
    parse_landmarks(doc2, "case2.json")


def test_an_outline_that_places_a_camera_must_trace_a_profile(doc):
    """A profile photo with fewer than 3 landmarks has its camera placed by its traced
    outline alone: a horizontal outline ended the fit in "outline: it has no height"
    naming no view, one within a pixel gave the photo a camera of 8 px per metre and no
    warning."""
    doc["views"]["side"]["points"] = {}
    flat = copy.deepcopy(doc)
    flat["views"]["side"]["contour"] = [[100.0 + 3 * i, 400.0] for i in range(50)]
    assert parse_error(flat) == (
        "case.json: views.side.contour: all 50 points lie on one line (RMS 0 px off it); "
        "with fewer than 3 landmarks this photo's camera is placed by its outline alone, "
        "which must trace the head's profile")
    dot = copy.deepcopy(doc)
    dot["views"]["side"]["contour"] = [[300.0, 400.0], [300.5, 400.4], [300.2, 400.9]]
    assert parse_error(dot).startswith("case.json: views.side.contour: all 3 points lie "
                                       "within 2 px of (300.2, 400.4); with fewer than 3")
    parse_landmarks(dot, "case.json", for_fit=False)  # work in progress may
    # with landmarks the outline does not place the camera, and is not judged here
    names = list(doc["views"]["front"]["points"])[:3]
    flat["views"]["side"]["points"] = {n: [200.0 + 40 * i, 300.0 + 90 * (i % 2)]
                                       for i, n in enumerate(names)}
    parse_landmarks(flat, "case.json")
    # a curved outline places it
    doc["views"]["side"]["contour"] = [[300.0 + 40 * np.sin(t), 100.0 + 250 * t]
                                       for t in np.linspace(0, 3, 40)]
    parse_landmarks(doc, "case.json")
