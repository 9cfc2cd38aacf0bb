"""A profile photo with only a traced outline (solver/fitting/contour_start.py and the
fit's use of it)."""

import numpy as np

from solver import LandmarkCase, OrthographicCamera, View, check_case, fit_head
from solver.fitting.contour_start import camera_from_outline
from solver.synthetic import make_case, skin_error_mm


def _outline_only(case, view="right"):
    v = case.views[view]
    return LandmarkCase({**case.views, view: View(view, None, v.size, v.camera, {},
                                                  contour=v.contour)}, case.source)


def test_the_outline_places_the_profile_camera(model):
    case, truth = make_case(model, 5, noise_px=1.0)
    true = truth.cameras["right"]
    chain = truth.world_vertices[model.profile_chain]
    nominal = OrthographicCamera.nominal("orthographic-right", true.size)
    cam, rms = camera_from_outline(nominal, case.views["right"].contour, chain)
    assert abs(cam.scale / true.scale - 1.0) < 0.02
    gap = np.linalg.norm(cam.project(chain) - true.project(chain), axis=1)
    assert np.sqrt(np.mean(gap**2)) < 4.0, gap
    assert rms < 8.0  # the silhouette is not exactly the midsagittal line


def test_a_profile_with_only_its_outline_counts(model):
    """No landmark on the profile photo, only its traced outline: the fit uses it (no
    single-photo warning) and gets the head nearer than from the front photo alone."""
    case, truth = make_case(model, 6, noise_px=1.0)
    only = _outline_only(case)
    assert check_case(only) == []
    err = {}
    for label, c in (("outline", only),
                     ("front", LandmarkCase({"front": case.views["front"]}, case.source))):
        r = fit_head(model, c)
        err[label] = skin_error_mm(model, r.local_vertices, truth.local_vertices)
        if label == "outline":
            assert not any("only photo" in w for w in r.info["warnings"]), r.info["warnings"]
            assert "right" in r.cameras
    assert err["outline"] < 0.8 * err["front"], err


def test_a_profile_without_landmarks_or_outline_is_named(model):
    case, _ = make_case(model, 6, noise_px=1.0)
    v = case.views["right"]
    bare = LandmarkCase({**case.views, "right": View("right", None, v.size, v.camera, {})},
                        case.source)
    problems = check_case(bare)
    assert any("right" in where and "landmark" in msg for where, msg in problems), problems
